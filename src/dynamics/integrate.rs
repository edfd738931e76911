//! Integrators. The paper's scheme (MODEL.md §3): semi-implicit (symplectic) Euler — velocity first,
//! then position with the new velocity.
//!
//! Node integration writes end-of-step positions into `next_position_in_world`, leaving the
//! start-of-step positions in place so contact stages see whole trajectories; [`commit_positions`]
//! then swaps the two buffers.

use crate::body::Surface;
use crate::contact::tool::NO_TOOL;

/// v += Δt F/m; x_next = x + Δt v, for every node.
pub fn integrate_nodes_symplectic(surface: &mut Surface, dt: f64) {
    for i in 0..surface.position_in_world.len() {
        let velocity = surface.velocity_in_world[i]
            + surface.force_in_world[i] * (dt * surface.inverse_mass[i]);
        surface.velocity_in_world[i] = velocity;
        surface.next_position_in_world[i] = surface.position_in_world[i] + velocity * dt;
    }
}

/// The same for the nodes no tool holds (the contact stage moves the others).
pub fn integrate_free_nodes_symplectic(surface: &mut Surface, dt: f64) {
    for i in 0..surface.position_in_world.len() {
        if surface.tool_contact[i].tool != NO_TOOL {
            continue;
        }
        let velocity = surface.velocity_in_world[i]
            + surface.force_in_world[i] * (dt * surface.inverse_mass[i]);
        surface.velocity_in_world[i] = velocity;
        surface.next_position_in_world[i] = surface.position_in_world[i] + velocity * dt;
    }
}

/// Makes the end-of-step positions current (an O(1) swap of the two buffers).
pub fn commit_positions(surface: &mut Surface) {
    std::mem::swap(
        &mut surface.position_in_world,
        &mut surface.next_position_in_world,
    );
}
