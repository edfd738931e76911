//! Plasticity by moving homologues (MODEL.md §7, the paper's §4.3 after Terzopoulos & Fleischer):
//! a link stretched past `yield` lets its homologue flow towards its node, so the rigid component's
//! rest shape takes a permanent set.
//!
//! The rule per second: with `d` the link's stretch (the node's distance from its homologue) and
//! `e = d − yield` the excess, the homologue moves towards the node at the speed `creep · e` while
//! `e > 0`, and never further than `max` from its original place. Integrated over one tick with the
//! node held where it is, the excess decays as `e(t) = e₀ exp(−creep · t)`, so a tick moves the
//! homologue by `e₀ (1 − exp(−creep Δt))`: the exact solution of the rule over the tick, which makes
//! the permanent set the same at every Δt for the same motion of the nodes (and is stable at any
//! `creep`).

use crate::Vec3;
use crate::body::Body;
pub use crate::body::settings::PlasticitySettings;

/// Lets the homologues of `body` flow for one tick (after the positions and the rigid component are
/// committed); `fraction` is [`PlasticitySettings::tick_fraction`]. Returns how many homologues
/// moved. Touches every node once, allocates nothing.
pub fn flow(body: &mut Body, settings: &PlasticitySettings, fraction: f64) -> u32 {
    let s = &mut body.surface;
    let r = &body.rigid;
    let body_from_world = r.world_from_body.inverse().to_rotation_matrix();
    let max_squared = settings.max * settings.max;
    let mut moved = 0;
    for i in 0..s.position_in_world.len() {
        let node_in_body = body_from_world * (s.position_in_world[i] - r.position_in_world);
        let towards_node = node_in_body - s.homologue_in_body[i];
        let stretch = towards_node.norm();
        if stretch <= settings.yield_stretch || !stretch.is_finite() {
            continue;
        }
        let step = towards_node * ((stretch - settings.yield_stretch) * fraction / stretch);
        let original = s.homologue_in_body[i] - s.plastic_offset_in_body[i];
        let mut offset = s.plastic_offset_in_body[i] + step;
        let reach = offset.norm_squared();
        if reach > max_squared {
            if s.plastic_offset_in_body[i].norm_squared() >= max_squared {
                // Already at the limit: no further flow.
                continue;
            }
            offset *= settings.max / reach.sqrt();
        }
        s.plastic_offset_in_body[i] = offset;
        s.homologue_in_body[i] = original + offset;
        moved += 1;
    }
    moved
}

/// Largest plastic set of any node of `body` (m): how far its homologues have flowed.
pub fn largest_set(body: &Body) -> f64 {
    body.surface
        .plastic_offset_in_body
        .iter()
        .map(Vec3::norm)
        .fold(0.0, f64::max)
}
