//! Whether a run stays healthy, by the criteria of the stability work (README, "Integrators and
//! stability"): nothing non-finite, the energy within its budget (initial energy plus the work of
//! the tools, plus the guard's slack), no node further from its homologue than the body's size, no
//! node below an obstacle — and the divergence guard never having to act. Used by the stress test
//! and by `palpa-report`'s stability maps.

use crate::Vec3;
use crate::dynamics::guard::{ENERGY_SLACK, ENERGY_SLACK_J, body_energy};
use crate::world::World;

/// What a run did, over all its bodies.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Assessment {
    /// Ticks stepped.
    pub ticks: u64,
    /// Times the divergence guard restored a body.
    pub guard_events: u64,
    /// Largest energy above the budget seen (J; negative: always within).
    pub worst_energy_excess: f64,
    /// Largest node-to-homologue distance over the body's size.
    pub worst_stretch_ratio: f64,
    /// Smallest node-to-obstacle signed distance (m; +∞ without obstacles).
    pub worst_gap: f64,
    /// No position or velocity ever became non-finite.
    pub finite: bool,
}

impl Assessment {
    /// Within every bound, without the guard.
    pub fn passes(&self) -> bool {
        self.finite && self.guard_events == 0 && self.healthy()
    }

    /// Within every bound (the guard may have acted to keep it so).
    pub fn healthy(&self) -> bool {
        self.worst_energy_excess <= 0.0
            && self.worst_stretch_ratio <= 1.0
            && self.worst_gap >= -1e-6
    }
}

/// Steps `world` for `seconds` and assesses the run (energy every 10 ticks). Stops early when a
/// state becomes non-finite.
pub fn assess(world: &mut World, seconds: f64) -> Assessment {
    let gravity = world.params.gravity;
    let sizes: Vec<f64> = world
        .bodies
        .iter()
        .map(|b| {
            let xs = &b.surface.homologue_in_body;
            let lo = xs.iter().fold(Vec3::repeat(f64::INFINITY), |a, p| a.inf(p));
            let hi = xs
                .iter()
                .fold(Vec3::repeat(f64::NEG_INFINITY), |a, p| a.sup(p));
            (hi - lo).norm()
        })
        .collect();
    let mut budget: Vec<f64> = world
        .bodies
        .iter()
        .map(|b| body_energy(b, &gravity))
        .collect();
    let guard_start: u64 = world.guards.iter().map(|g| g.events).sum();
    let steps = (seconds / world.params.dt).round() as u64;
    let mut run = Assessment {
        ticks: 0,
        guard_events: 0,
        worst_energy_excess: f64::NEG_INFINITY,
        worst_stretch_ratio: 0.0,
        worst_gap: f64::INFINITY,
        finite: true,
    };
    for k in 0..steps {
        world.step();
        run.ticks += 1;
        let work: f64 = world
            .tools
            .iter()
            .map(|t| {
                (t.feedback
                    .force_in_world
                    .dot(&(t.pose.position_in_world - t.previous_pose.position_in_world)))
                .abs()
            })
            .filter(|w| w.is_finite())
            .sum();
        for (b, body) in world.bodies.iter().enumerate() {
            if !body.is_finite() {
                run.finite = false;
            }
            budget[b] += work;
            if k % 10 == 0 {
                let e = body_energy(body, &gravity);
                let allowed = budget[b] + ENERGY_SLACK * budget[b].abs() + ENERGY_SLACK_J;
                run.worst_energy_excess = run.worst_energy_excess.max(e - allowed);
            }
            let s = &body.surface;
            for (x, h) in s.position_in_world.iter().zip(&s.homologue_in_world) {
                run.worst_stretch_ratio = run.worst_stretch_ratio.max((x - h).norm() / sizes[b]);
            }
            if let Some(gap) = world.min_obstacle_gap(body) {
                run.worst_gap = run.worst_gap.min(gap);
            }
        }
        if !run.finite {
            break;
        }
    }
    run.guard_events = world.guards.iter().map(|g| g.events).sum::<u64>() - guard_start;
    run
}
