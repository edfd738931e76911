//! The forces of MODEL.md §2 on a body's nodes and rigid component: gravity, air viscosity, the
//! zero-rest-length damped links (and their reactions on the rigid component), the damped edge springs.
//!
//! Reads the start-of-step state, writes `force_in_world` of every node, the rigid component's force
//! and torque, and the homologues' world positions (scratch, reused by later stages).

use crate::Vec3;
use crate::body::Body;
use crate::dynamics::kernel::{ForceKernel, NodePass};

/// Accumulates every internal and volume force of `body` for the current state (through a
/// [`ForceKernel`] made for the call: it allocates; the world keeps one per body).
pub fn accumulate_body_forces(body: &mut Body, gravity: &Vec3) {
    let mut kernel = ForceKernel::new(body);
    kernel.edge_forces(body);
    kernel.node_pass(body, gravity, 0.0, NodePass::Forces);
}
