//! Contact of surface nodes with fixed obstacles, with Coulomb friction (MODEL.md §4).
//!
//! Runs after the nodes were integrated: each node's trajectory goes from its start-of-step position to
//! its predicted end position. A node whose end lies inside an obstacle loses its velocity into the
//! surface (an inelastic contact, normal impulse `m Δv_n`); friction then acts on its tangential
//! velocity with the Coulomb cone of that impulse — it sticks (tangential velocity cancelled) when the
//! impulse needed is inside the static cone `μ_s m Δv_n`, and otherwise slides with its tangential speed
//! reduced by `μ_k Δv_n`. The end position is recomputed from the corrected velocity and finally
//! projected onto the surface, so no node ends a step inside an obstacle.

use crate::Vec3;
use crate::body::Surface;
use crate::collision::blocks::{BLOCK, NodeBlock, NodeBlocks};
use crate::collision::obstacle::{ContactPlane, Obstacle, beyond};

/// Resolves every node of `surface` against every obstacle (obstacles in scene order, each node
/// against them in that order); returns how many node–obstacle contacts were found this step.
///
/// `reactions[k]` accumulates the force obstacle `k` exerts on the nodes (N): the momentum its contacts
/// changed, divided by the step.
///
/// With `blocks` (the node pass's, whose boxes hold every trajectory), the blocks that lie wholly
/// outside an obstacle are skipped ([`misses`]), and the nodes it moved join their blocks.
pub fn resolve_nodes_against_obstacles(
    surface: &mut Surface,
    obstacles: &[Obstacle],
    reactions: &mut [Vec3],
    dt: f64,
    mut blocks: Option<&mut NodeBlocks>,
) -> usize {
    let mut contacts = 0;
    let n = surface.position_in_world.len();
    for (obstacle, reaction) in obstacles.iter().zip(reactions.iter_mut()) {
        let plane = obstacle.shape.as_plane();
        let reach = obstacle.shape.reach_in_world();
        for k in 0..n.div_ceil(BLOCK) {
            if let Some(b) = blocks.as_ref().and_then(|b| b.bounds(n))
                && misses(plane.as_ref(), reach.as_ref(), &b[k])
            {
                continue;
            }
            let nodes = k * BLOCK..((k + 1) * BLOCK).min(n);
            // The nodes the obstacle moves join their block.
            let mut moved = |surface: &Surface, i: usize| {
                if let Some(blocks) = blocks.as_mut() {
                    blocks.include(surface, i);
                }
            };
            match &plane {
                // The common case gets a tight loop: one dot product per node.
                Some(plane) => {
                    for i in nodes {
                        if plane.signed_distance(&surface.next_position_in_world[i]) < 0.0 {
                            *reaction += resolve_node(surface, i, plane, obstacle, dt);
                            contacts += 1;
                            moved(surface, i);
                        }
                    }
                }
                None => {
                    let shape = &obstacle.shape;
                    for i in nodes {
                        let end = surface.next_position_in_world[i];
                        // Most nodes end far from a box: six comparisons, no rotation.
                        if reach.as_ref().is_some_and(|reach| beyond(&end, reach)) {
                            continue;
                        }
                        let start = surface.position_in_world[i];
                        if let Some(plane) = shape.contact_plane(&start, &end) {
                            *reaction += resolve_node(surface, i, &plane, obstacle, dt);
                            contacts += 1;
                            moved(surface, i);
                        }
                    }
                }
            }
        }
    }
    contacts
}

/// No node of `block` can meet an obstacle with this half-space `plane` or box `reach` (as
/// [`ObstacleShape::as_plane`] and [`ObstacleShape::reach_in_world`] give them): the block's box
/// lies outside. Never for a block with a value that is not finite. For a half-space, the box's
/// corner deepest along the normal is above the surface by more than rounding can account for
/// (1 nm for every metre of the coordinates' size): every end position in the box then gives a
/// signed distance above 0. For a box, the block's box is beyond the reach on some axis (the
/// comparisons of [`beyond`], which then holds for every node of the block).
///
/// [`ObstacleShape::as_plane`]: crate::collision::obstacle::ObstacleShape::as_plane
/// [`ObstacleShape::reach_in_world`]: crate::collision::obstacle::ObstacleShape::reach_in_world
pub fn misses(plane: Option<&ContactPlane>, reach: Option<&[Vec3; 2]>, block: &NodeBlock) -> bool {
    if block.bad {
        return false;
    }
    let b = &block.bounds;
    match (plane, reach) {
        (Some(plane), _) => {
            let n = &plane.normal_in_world;
            let corner = Vec3::from_fn(|k, _| if n[k] >= 0.0 { b.min[k] } else { b.max[k] });
            let size = b.min.amax().max(b.max.amax()) + plane.point_in_world.amax() + 1.0;
            plane.signed_distance(&corner) > 1e-9 * size
        }
        (None, Some([lower, upper])) => (0..3).any(|k| b.max[k] < lower[k] || b.min[k] > upper[k]),
        (None, None) => false,
    }
}

/// Node `i` ends the step below `plane`: inelastic normal response, Coulomb friction, end position
/// recomputed from the corrected velocity and projected onto the surface. Returns the contact force
/// (N): the node's momentum change over the step.
fn resolve_node(
    surface: &mut Surface,
    i: usize,
    plane: &ContactPlane,
    obstacle: &Obstacle,
    dt: f64,
) -> Vec3 {
    let incoming = surface.velocity_in_world[i];
    let (velocity, end) =
        resolve_point(&surface.position_in_world[i], incoming, plane, obstacle, dt);
    surface.velocity_in_world[i] = velocity;
    surface.next_position_in_world[i] = end;
    (velocity - incoming) * (surface.mass[i] / dt)
}

/// A point moving from `start` with `velocity` over `dt` ends below `plane`: inelastic normal
/// response, Coulomb friction, end recomputed from the corrected velocity and projected onto the
/// surface. Returns the corrected velocity and end position (the multi-rate integrator calls it in
/// its substeps).
pub fn resolve_point(
    start: &Vec3,
    incoming: Vec3,
    plane: &ContactPlane,
    obstacle: &Obstacle,
    dt: f64,
) -> (Vec3, Vec3) {
    let normal = plane.normal_in_world;
    let mut velocity = incoming;
    let normal_speed = velocity.dot(&normal);
    if normal_speed < 0.0 {
        let normal_dv = -normal_speed;
        velocity += normal * normal_dv;
        velocity = apply_coulomb_friction(
            velocity,
            &normal,
            normal_dv,
            obstacle.static_friction,
            obstacle.friction,
        );
    }
    let mut end = start + velocity * dt;
    let depth = plane.signed_distance(&end);
    if depth < 0.0 {
        end -= normal * depth;
    }
    (velocity, end)
}

/// The contact plane of a point moving from `start` to `end` against `obstacle`, if it ends inside.
pub fn point_contact_plane(obstacle: &Obstacle, start: &Vec3, end: &Vec3) -> Option<ContactPlane> {
    match obstacle.shape.as_plane() {
        Some(plane) => (plane.signed_distance(end) < 0.0).then_some(plane),
        None => obstacle.shape.contact_plane(start, end),
    }
}

/// Coulomb friction on a velocity whose normal part was just cancelled by a normal velocity change
/// `normal_dv` (≥ 0): stick inside the static cone, otherwise slide with a kinetic decrement.
pub fn apply_coulomb_friction(
    velocity: Vec3,
    normal: &Vec3,
    normal_dv: f64,
    static_friction: f64,
    kinetic_friction: f64,
) -> Vec3 {
    let tangential = velocity - normal * velocity.dot(normal);
    let speed = tangential.norm();
    if speed <= static_friction * normal_dv {
        velocity - tangential
    } else {
        velocity - tangential * ((kinetic_friction * normal_dv).min(speed) / speed)
    }
}
