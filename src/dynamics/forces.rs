//! The forces of MODEL.md §2 on a body's nodes and rigid component: gravity, air viscosity, the
//! zero-rest-length damped links (and their reactions on the rigid component), the damped edge springs.
//!
//! Reads the start-of-step state, writes `force_in_world` of every node, the rigid component's force
//! and torque, and the homologues' world positions (scratch, reused by later stages).

use crate::Vec3;
use crate::body::Body;

/// Accumulates every internal and volume force of `body` for the current state.
pub fn accumulate_body_forces(body: &mut Body, gravity: &Vec3) {
    let Body {
        surface,
        edges,
        rigid,
        ..
    } = body;
    rigid.reset_forces(gravity);

    // Volume forces on the nodes: m g − γ v.
    for ((force, velocity), (mass, air)) in surface
        .force_in_world
        .iter_mut()
        .zip(&surface.velocity_in_world)
        .zip(surface.mass.iter().zip(&surface.air_damping))
    {
        *force = gravity * *mass - velocity * *air;
    }

    // Links: F_link(i) = k_i (h_i − x_i) + c_i (ḣ_i − v_i), ḣ_i = V + ω × (h_i − X); the rigid
    // component takes −F_link(i) and the torque −(h_i − X) × F_link(i).
    let world_from_body = rigid.world_from_body.to_rotation_matrix();
    let centre = rigid.position_in_world;
    let velocity_of_centre = rigid.velocity_in_world;
    let omega = rigid.angular_velocity_in_world();
    let mut reaction_force = Vec3::zeros();
    let mut reaction_torque = Vec3::zeros();
    for i in 0..surface.homologue_in_body.len() {
        let arm = world_from_body * surface.homologue_in_body[i];
        let homologue = centre + arm;
        let homologue_velocity = velocity_of_centre + omega.cross(&arm);
        let link = (homologue - surface.position_in_world[i]) * surface.link_stiffness[i]
            + (homologue_velocity - surface.velocity_in_world[i]) * surface.link_damping[i];
        surface.homologue_in_world[i] = homologue;
        surface.force_in_world[i] += link;
        reaction_force -= link;
        reaction_torque -= arm.cross(&link);
    }
    rigid.force_in_world += reaction_force;
    rigid.torque_in_world += reaction_torque;

    // Edge springs: k (|d| − L) u + c ((v_b − v_a)·u) u on a, the opposite on b, with d = x_b − x_a
    // and u = d / |d|; written as d · (magnitude / |d|) so one division serves both.
    let x = &surface.position_in_world[..];
    let v = &surface.velocity_in_world[..];
    let f = &mut surface.force_in_world[..];
    let ends = edges.a.iter().zip(&edges.b);
    let constants = edges
        .rest_length
        .iter()
        .zip(&edges.stiffness)
        .zip(&edges.damping);
    for ((&a, &b), ((&rest, &k), &c)) in ends.zip(constants) {
        let (a, b) = (a as usize, b as usize);
        let d = x[b] - x[a];
        let length = d.norm();
        if length <= f64::MIN_POSITIVE {
            // Coincident ends: no direction to push along.
            continue;
        }
        let inverse_length = 1.0 / length;
        let magnitude = k * (length - rest) + c * (v[b] - v[a]).dot(&d) * inverse_length;
        let force = d * (magnitude * inverse_length);
        f[a] += force;
        f[b] -= force;
    }
}
