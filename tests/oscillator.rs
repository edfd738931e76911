//! A single node linked to a fixed rigid component: the discrete recurrence of the scheme, and the
//! analytic damped oscillator within the scheme's O(Δt) error.

use palpa::Vec3;
use palpa::body::{Body, BodyParams, Placement};
use palpa::scene::WorldParams;
use palpa::scene::mesh::SurfaceMesh;
use palpa::world::World;

const MASS: f64 = 0.01; // kg
const K: f64 = 40.0; // N/m
const C: f64 = 0.05; // N·s/m
const X0: f64 = 0.01; // m, initial displacement along x

fn single_node_world(dt: f64) -> World {
    let mesh = SurfaceMesh {
        positions_in_body: vec![Vec3::zeros()],
        triangles: vec![],
    };
    let params = BodyParams {
        surface_mass: MASS,
        link_stiffness: K,
        link_damping: C,
        fixed: true,
        ..BodyParams::default()
    };
    // The reference scheme, explicitly: the integrator refactor must not change it.
    let mut world = World::new(WorldParams {
        gravity: Vec3::zeros(),
        dt,
        air_viscosity: 0.0,
        integrator: palpa::dynamics::Integrator::Symplectic,
        helper_thread: true,
        face_contact: true,
    });
    let mut body = Body::new("node", &mesh, &params, &Placement::default());
    body.surface.position_in_world[0] = Vec3::new(X0, 0.0, 0.0);
    world.add_body(body);
    world
}

#[test]
fn single_linked_node_matches_the_discrete_recurrence_to_1e_12() {
    let dt = 0.001;
    let mut world = single_node_world(dt);
    let (mut x, mut v) = (X0, 0.0);
    let mut worst: f64 = 0.0;
    for _ in 0..2000 {
        world.step();
        v += dt * (-K * x - C * v) / MASS;
        x += dt * v;
        let node = world.bodies[0].surface.position_in_world[0];
        worst = worst
            .max((node.x - x).abs())
            .max(node.y.abs())
            .max(node.z.abs());
    }
    assert!(worst < 1e-12, "node off the recurrence by {worst} m");
    // The rigid component is fixed: it did not move.
    assert_eq!(world.bodies[0].rigid.position_in_world, Vec3::zeros());
}

/// Largest deviation from the analytic damped oscillator over 1 s.
fn analytic_error(dt: f64) -> f64 {
    let mut world = single_node_world(dt);
    let omega0 = (K / MASS).sqrt();
    let zeta = C / (2.0 * (K * MASS).sqrt());
    let omega_d = omega0 * (1.0 - zeta * zeta).sqrt();
    let steps = (1.0 / dt).round() as u32;
    let mut worst: f64 = 0.0;
    for n in 1..=steps {
        world.step();
        let t = n as f64 * dt;
        let exact = X0
            * (-zeta * omega0 * t).exp()
            * ((omega_d * t).cos() + zeta * omega0 / omega_d * (omega_d * t).sin());
        worst = worst.max((world.bodies[0].surface.position_in_world[0].x - exact).abs());
    }
    worst
}

#[test]
fn single_linked_node_follows_the_analytic_damped_oscillator_to_first_order() {
    // ω0 = 63 rad/s (10 Hz), ζ = 0.04: ten lightly damped periods in 1 s.
    let e1 = analytic_error(0.001);
    let e2 = analytic_error(0.0005);
    let e4 = analytic_error(0.00025);
    // First order: semi-implicit Euler's positions lag the exact motion by about half a step, so the
    // leading error is (Δt/2)·max|v| = ω0 Δt X0 / 2, and it halves with Δt.
    let omega0_dt = (K / MASS).sqrt() * 0.001;
    assert!(e1 < 0.6 * omega0_dt * X0, "error {e1} m at 1 ms");
    for (coarse, fine) in [(e1, e2), (e2, e4)] {
        let ratio = coarse / fine;
        assert!(
            (1.7..2.3).contains(&ratio),
            "error ratio {ratio} for a halved step (expected ~2)"
        );
    }
    eprintln!("analytic error: {e1:e} m at 1 ms, {e2:e} at 0.5 ms, {e4:e} at 0.25 ms");
}
