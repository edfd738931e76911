//! The rigid component's rotation update against the analytic motion of a torque-free symmetric top.
//!
//! For I₁ = I₂ ≠ I₃ the orientation is known in closed form (with L the constant world angular
//! momentum and L₃ its component on the symmetry axis, constant too):
//!
//! R(t) = exp([L]× t / I₁) · R(0) · exp([e₃]× λ t),   λ = L₃ (1/I₃ − 1/I₁).
//!
//! The test compares the integrated orientation with it over 10 s (about 50 rad of turning), checks the
//! error falls like Δt² (the update is second order in the orientation), and that the rotational energy
//! — recomputed from ω through the orientation — stays put on an asymmetric body. (The previous version
//! checked L recomputed as I ω, which is the stored L whatever the update does, and |q| after the
//! update renormalised it: neither could fail.)

use nalgebra::{Matrix3, UnitQuaternion};
use palpa::Vec3;
use palpa::body::{Placement, RigidComponent};
use palpa::scene::mesh::box_mesh;

/// Largest angle (rad) between the integrated and the analytic orientation over `seconds`.
fn top_error(dt: f64, seconds: f64) -> (f64, f64) {
    // A 0.1 x 0.1 x 0.3 m box: symmetric about z, I₁ = I₂ > I₃.
    let mesh = box_mesh(Vec3::new(0.1, 0.1, 0.3), 0);
    let inertia: Matrix3<f64> = mesh.solid_inertia_about_origin(2.0);
    let (i1, i3) = (inertia[(0, 0)], inertia[(2, 2)]);
    assert!((inertia[(1, 1)] - i1).abs() < 1e-15 * i1, "symmetric top");
    assert!(
        (inertia - Matrix3::from_diagonal(&inertia.diagonal())).norm() < 1e-15,
        "principal axes"
    );
    let placement = Placement {
        angular_velocity_in_world: Vec3::new(3.0, 0.2, 4.0),
        ..Placement::default()
    };
    let mut rigid = RigidComponent::new(2.0, inertia, &placement, 0.0, false);
    let start = rigid.world_from_body;
    let l = rigid.angular_momentum_in_world;
    let l3 = (start.inverse() * l).z;
    let lambda = l3 * (1.0 / i3 - 1.0 / i1);
    let steps = (seconds / dt).round() as u64;
    let (mut worst, mut turned): (f64, f64) = (0.0, 0.0);
    for k in 1..=steps {
        rigid.reset_forces(&Vec3::zeros());
        rigid.integrate(dt);
        let t = k as f64 * dt;
        let analytic = UnitQuaternion::from_scaled_axis(l * (t / i1))
            * start
            * UnitQuaternion::from_scaled_axis(Vec3::z() * (lambda * t));
        worst = worst.max(rigid.world_from_body.angle_to(&analytic));
        turned += rigid.angular_velocity_in_world().norm() * dt;
    }
    (worst, turned)
}

#[test]
fn torque_free_symmetric_top_follows_the_analytic_orientation() {
    let (error, turned) = top_error(1e-3, 10.0);
    let (error_half, _) = top_error(5e-4, 10.0);
    eprintln!(
        "symmetric top over 10 s ({turned:.1} rad): orientation error {error:.3e} rad at 1 ms, \
         {error_half:.3e} rad at 0.5 ms (ratio {:.2})",
        error / error_half
    );
    assert!(turned > 40.0, "it really spun: {turned} rad");
    assert!(error < 1e-3, "orientation error {error} rad after 10 s");
    let ratio = error / error_half;
    assert!(
        (3.5..4.5).contains(&ratio),
        "second order in Δt: halving the step divides the error by {ratio}"
    );
}

#[test]
fn torque_free_asymmetric_rigid_component_keeps_its_rotational_energy() {
    // A 0.1 x 0.2 x 0.3 m box: three distinct principal moments (rotation about the middle axis is
    // unstable, so a wrong ω recovery or orientation update shows in the energy).
    let mesh = box_mesh(Vec3::new(0.1, 0.2, 0.3), 0);
    let inertia = mesh.solid_inertia_about_origin(2.0);
    let placement = Placement {
        angular_velocity_in_world: Vec3::new(3.0, 0.2, 4.0),
        ..Placement::default()
    };
    let mut rigid = RigidComponent::new(2.0, inertia, &placement, 0.0, false);
    let e0 = rigid.kinetic_energy();
    let mut worst_e: f64 = 0.0;
    for _ in 0..10_000 {
        rigid.reset_forces(&Vec3::zeros());
        rigid.integrate(1e-3);
        worst_e = worst_e.max((rigid.kinetic_energy() - e0).abs() / e0);
    }
    eprintln!("asymmetric body over 10 s: rotational energy drift {worst_e:e}");
    assert!(worst_e < 1e-5, "rotational energy drift {worst_e}");
}

#[test]
fn constant_torque_turns_a_sphere_like_the_closed_form() {
    // A body with isotropic inertia under a constant torque along a fixed axis: θ(t) = T t² / (2 I).
    let inertia = Matrix3::identity() * 0.01;
    let mut rigid = RigidComponent::new(1.0, inertia, &Placement::default(), 0.0, false);
    let torque = Vec3::new(0.0, 0.03, 0.0);
    let dt = 1e-3;
    for _ in 0..2000 {
        rigid.reset_forces(&Vec3::zeros());
        rigid.torque_in_world += torque;
        rigid.integrate(dt);
    }
    let t: f64 = 2.0;
    let expected = torque.norm() * t * t / (2.0 * 0.01);
    // Semi-implicit Euler turns by T dt² k(k+1)/2 / I after k steps: one step ahead of the continuous
    // motion, an error of T t dt / (2 I).
    let lead = torque.norm() * t * dt / (2.0 * 0.01);
    let closed_form = UnitQuaternion::from_scaled_axis(Vec3::y() * (expected + lead));
    let off = rigid.world_from_body.angle_to(&closed_form);
    assert!(
        off < 1e-9,
        "{off} rad from the closed form ({expected} rad + a lead of {lead} rad)"
    );
}
