//! No node lighter than its explicit scheme can carry: after a cut or a tear, a node whose mass is
//! below the least its scheme steps stably takes mass from the nodes round it.
//!
//! A cut makes light, stiff nodes: a node copied to open the surface takes only a share of its
//! origin's mass (in proportion to the rest area of its side), and a spring cut in two near an end
//! leaves a short piece k/t stiff (and c/t damped). Cutting the same place again divides again: a
//! few passes of a blade can leave a node ten thousand times lighter than its neighbours. The
//! multi-rate scheme sub-steps such a node, down to a step of Δt / 2^[`MAX_LEVEL`]; a node lighter
//! than that step carries would diverge. Explicit finite-element codes keep their step with mass
//! scaling; here mass is *moved*, not added, so the body's mass stays what it was to rounding.
//!
//! The limit. With the node's Gershgorin sums K (stiffness) and C₀ + ν m (damping, ν m the air's),
//! [`crate::dynamics::stability::stable_at`] holds at step h with safety s iff
//! K h² / m ≤ s² (4 − 2 h C / m), that is m ≥ m_min = (K h² / (4 s²) + h C₀ / 2) / (1 − h ν / 2).
//!
//! The move. A node below its m_min takes the deficit from the nodes round it — those its springs
//! join it to first, the next ring only when they cannot give it all, at most [`MAX_RINGS`] rings —
//! each giving in proportion to what it holds above its own m_min and never more than
//! [`DONOR_SHARE`] of that (a donor stays within its own limit, with room). The mass carries its
//! momentum: the receiver's velocity becomes the mass-weighted mean (an inelastic merge), the
//! donor's is unchanged, so linear momentum is conserved and kinetic energy does not rise. The
//! receiver's and donors' inverse mass and air damping (ν m) follow; links, homologues and springs
//! do not change. Where the nodes round it cannot give enough, the node takes what they can and is
//! counted (`short`).
//!
//! The last resort. A chip of a few light nodes cut off whole (a transection's smallest piece, a
//! millimetre across) has no heavier node round it: its nodes stay short. Such a node's springs and
//! link are then made softer and less damped by the factor that brings its least mass down to its
//! mass (m_min is linear in K and C₀), and counted (`softened`). Positions, velocities and masses
//! do not change: momentum and kinetic energy are kept, and the elastic energy can only fall.

use crate::body::Body;
use crate::body::changes::TopologyChanges;
use crate::dynamics::stability::node_bounds_into;
use crate::topology::rest_index::RestIndex;

pub use crate::dynamics::multirate::{MAX_LEVEL, SAFETY};

/// Most of its mass above its own m_min a node gives in one move.
pub const DONOR_SHARE: f64 = 0.5;
/// Rings of springs round a light node the donors are sought in (the nearest first).
pub const MAX_RINGS: usize = 3;
/// Most springs at one node a move looks at (more: the node is counted unchecked).
const MAX_DEGREE: usize = 64;
/// Most donors one node takes mass from.
const MAX_DONORS: usize = 256;
/// Fraction of the ratio (mass / least mass) a short node's springs are softened by.
const SOFTEN_MARGIN: f64 = 0.999;

/// What the mass moves did, over the body's life.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MassMoveCounters {
    /// Changed nodes checked against their least mass.
    pub checked: u64,
    /// Nodes that were below it and took mass from the nodes round them.
    pub fed: u64,
    /// Mass moved, kg.
    pub moved_kg: f64,
    /// Nodes left below it (the nodes round them had not enough above theirs).
    pub short: u64,
    /// Nodes not checked (more springs than the scratch holds, or the rest-frame index stale).
    pub unchecked: u64,
    /// Nodes left short whose springs and link were softened to what their mass carries.
    pub softened: u64,
}

/// Scratch and counters of the mass moves (reserved up front; no allocation on the tick).
#[derive(Clone, Debug)]
pub struct MassMover {
    /// Donors sought round the node being fed, ring by ring, and what each can give.
    donors: Vec<(u32, f64)>,
    /// The round each node was last met in (one round per fed node).
    stamp: Vec<u32>,
    round: u32,
    /// Scratch of [`MassMover::find_light`]: each node's Gershgorin sums (stiffness, damping with
    /// the air's) and the nodes below their least mass.
    stiffness: crate::Room<f64>,
    damping: Vec<f64>,
    light: Vec<u32>,
    /// What the moves did.
    pub counters: MassMoveCounters,
}

/// The least mass of a node with stiffness sum `k`, damping sum `c0` (air excluded) and air
/// viscosity `nu` that semi-implicit Euler carries at step `h` with safety `safety`.
pub fn least_stable_mass(k: f64, c0: f64, nu: f64, h: f64, safety: f64) -> f64 {
    (k * h * h / (4.0 * safety * safety) + 0.5 * h * c0) / (1.0 - 0.5 * h * nu).max(f64::EPSILON)
}

/// The finest step the multi-rate scheme takes within a step `dt`.
pub fn finest_step(dt: f64) -> f64 {
    dt / f64::from(1u32 << MAX_LEVEL)
}

/// Node `v`'s Gershgorin sums (stiffness, damping without the air) from its springs.
fn sums(body: &Body, v: usize, springs: &[u32]) -> (f64, f64) {
    let s = &body.surface;
    let e = &body.edges;
    let (mut k, mut c) = (s.link_stiffness[v], s.link_damping[v]);
    for &spring in springs {
        k += 2.0 * e.stiffness[spring as usize];
        c += 2.0 * e.damping[spring as usize];
    }
    (k, c)
}

impl MassMover {
    /// Scratch for a body of at most `capacity` nodes.
    pub fn with_capacity(capacity: usize) -> Self {
        Self {
            donors: Vec::with_capacity(MAX_DONORS),
            stamp: vec![0; capacity],
            round: 0,
            stiffness: crate::Room::with_capacity(capacity),
            damping: Vec::with_capacity(capacity),
            light: Vec::with_capacity(capacity),
            counters: MassMoveCounters::default(),
        }
    }

    /// Node `v`'s least mass at `h` and its mass, its springs left in `index.found`; `None` when
    /// they cannot be listed (more than the scratch holds, or the index stale).
    fn need_and_mass(body: &Body, v: u32, h: f64, index: &mut RestIndex) -> Option<(f64, f64)> {
        if !index.incident_edges(body, v) || index.found.len() > MAX_DEGREE {
            return None;
        }
        let need = Self::floor(body, v as usize, &index.found, h);
        Some((need, body.surface.mass[v as usize]))
    }

    /// The least mass node `v` (its springs `springs`) may hold when stepped at `h`.
    fn floor(body: &Body, v: usize, springs: &[u32], h: f64) -> f64 {
        let (k, c0) = sums(body, v, springs);
        least_stable_mass(k, c0, body.params.air_viscosity, h, SAFETY)
    }

    /// Gives each node of the sealed record `changes` (changed by a cut or a tear) at least the
    /// mass semi-implicit Euler carries at step `h`, moving mass to it from the nodes round it
    /// where it has less; the donors join the record (sealed again). Springs come from the
    /// rest-frame index (`index`, describing the body as it is). Returns the nodes changed.
    pub fn hold(
        &mut self,
        body: &mut Body,
        h: f64,
        changes: &mut TopologyChanges,
        index: &mut RestIndex,
    ) -> u64 {
        let mut fed = 0;
        for n in 0..changes.nodes().len() {
            let v = changes.nodes()[n];
            fed += u64::from(self.hold_node(body, h, v, index, Some(changes)));
        }
        if fed > 0 {
            changes.seal(body.topology_version);
        }
        fed
    }

    /// The nodes of the body below their least mass at step `h`, into [`MassMover::light`]: one
    /// pass over the springs and one over the nodes (after a transection, whose caps take their
    /// mass from the rims and add springs there; on that tick only). Whether there are any.
    pub fn find_light(&mut self, body: &Body, h: f64) -> bool {
        let n = body.node_count();
        self.light.clear();
        if n > self.stiffness.capacity() {
            return false;
        }
        node_bounds_into(body, &mut self.stiffness, &mut self.damping);
        let s = &body.surface;
        let nu = body.params.air_viscosity;
        for v in 0..n {
            // The bounds' damping holds the air's (ν m); the least mass takes it apart.
            let c0 = self.damping[v] - s.air_damping[v];
            if s.mass[v] < least_stable_mass(self.stiffness[v], c0, nu, h, SAFETY) {
                self.light.push(v as u32);
            }
        }
        !self.light.is_empty()
    }

    /// [`MassMover::hold`] at the nodes [`MassMover::find_light`] found. Returns the nodes changed.
    pub fn hold_light(&mut self, body: &mut Body, h: f64, index: &mut RestIndex) -> u64 {
        let mut fed = 0;
        for k in 0..self.light.len() {
            let v = self.light[k];
            fed += u64::from(self.hold_node(body, h, v, index, None));
        }
        fed
    }

    /// Feeds node `v` if it is below its least mass (the donors into `changes`, when given), and
    /// softens it where the nodes round it cannot give enough; whether it changed.
    fn hold_node(
        &mut self,
        body: &mut Body,
        h: f64,
        v: u32,
        index: &mut RestIndex,
        mut changes: Option<&mut TopologyChanges>,
    ) -> bool {
        let vi = v as usize;
        if vi >= body.node_count() || vi >= self.stamp.len() {
            return false;
        }
        self.counters.checked += 1;
        let Some((need, mass)) = Self::need_and_mass(body, v, h, index) else {
            self.counters.unchecked += 1;
            return false;
        };
        if mass >= need {
            return false;
        }
        let deficit = need - mass;
        let total = self.seek_donors(body, v, h, deficit, index);
        let take = deficit.min(total);
        if take < deficit {
            self.counters.short += 1;
        }
        if take > 0.0 {
            self.feed(body, v, take, total, changes.as_deref_mut());
        }
        let softened = take < deficit && self.soften(body, v, h, index, changes);
        take > 0.0 || softened
    }

    /// Moves `take` kg to node `v` from the donors found (each in proportion to what it can give,
    /// `total` in all), with its momentum.
    fn feed(
        &mut self,
        body: &mut Body,
        v: u32,
        take: f64,
        total: f64,
        mut changes: Option<&mut TopologyChanges>,
    ) {
        let nu = body.params.air_viscosity;
        let vi = v as usize;
        let s = &mut body.surface;
        let mut momentum = s.velocity_in_world[vi] * s.mass[vi];
        let mut received = s.mass[vi];
        for &(j, give) in &self.donors {
            if give <= 0.0 {
                continue;
            }
            let ju = j as usize;
            let delta = take * (give / total);
            momentum += s.velocity_in_world[ju] * delta;
            received += delta;
            s.mass[ju] -= delta;
            s.inverse_mass[ju] = 1.0 / s.mass[ju];
            s.air_damping[ju] = nu * s.mass[ju];
            if let Some(changes) = changes.as_deref_mut() {
                changes.node(j);
            }
        }
        s.mass[vi] = received;
        s.inverse_mass[vi] = 1.0 / received;
        s.air_damping[vi] = nu * received;
        s.velocity_in_world[vi] = momentum / received;
        self.counters.fed += 1;
        self.counters.moved_kg += take;
    }

    /// Node `v`, still below its least mass at `h` after the nodes round it gave what they could
    /// (a chip of a few light nodes cut off whole has no heavier neighbour), has its springs and
    /// link made softer and less damped by the factor that brings its least mass to its mass: the
    /// least mass is linear in the stiffness and damping sums. Positions, velocities and masses do
    /// not change, so momentum is kept, kinetic energy too, and the elastic energy can only fall.
    /// The springs' other ends join the record (their bounds fell).
    fn soften(
        &mut self,
        body: &mut Body,
        v: u32,
        h: f64,
        index: &mut RestIndex,
        mut changes: Option<&mut TopologyChanges>,
    ) -> bool {
        let vi = v as usize;
        let Some((need, mass)) = Self::need_and_mass(body, v, h, index) else {
            return false;
        };
        if need <= mass || !need.is_finite() {
            return false;
        }
        // A little under the ratio, so that the rounding of the sums keeps the node within.
        let factor = SOFTEN_MARGIN * mass / need;
        let e = &mut body.edges;
        for &spring in &index.found {
            let k = spring as usize;
            e.stiffness[k] *= factor;
            e.damping[k] *= factor;
            if let Some(changes) = changes.as_deref_mut() {
                changes.edge(spring);
                changes.node(e.a[k]);
                changes.node(e.b[k]);
            }
        }
        let s = &mut body.surface;
        s.link_stiffness[vi] *= factor;
        s.link_damping[vi] *= factor;
        if let Some(changes) = changes {
            changes.node(v);
        }
        self.counters.softened += 1;
        true
    }

    /// The donors round node `v`, ring by ring until they can give `deficit` (into `donors`, each
    /// with what it can give); returns what they can give in all.
    fn seek_donors(
        &mut self,
        body: &Body,
        v: u32,
        h: f64,
        deficit: f64,
        index: &mut RestIndex,
    ) -> f64 {
        self.round = self.round.wrapping_add(1);
        if self.round == 0 {
            self.stamp.fill(0);
            self.round = 1;
        }
        let round = self.round;
        self.stamp[v as usize] = round;
        self.donors.clear();
        let mut total = 0.0;
        // The previous ring (none yet: the node itself).
        let mut ring: Option<std::ops::Range<usize>> = None;
        for _ in 0..MAX_RINGS {
            let start = self.donors.len();
            let sources = ring.as_ref().map_or(1, |r| r.len());
            for source in 0..sources {
                let u = ring.as_ref().map_or(v, |r| self.donors[r.start + source].0);
                if !index.incident_edges(body, u) || index.found.len() > MAX_DEGREE {
                    continue;
                }
                for &spring in &index.found {
                    let (a, b) = (body.edges.a[spring as usize], body.edges.b[spring as usize]);
                    let j = if a == u { b } else { a };
                    let ju = j as usize;
                    if ju >= self.stamp.len()
                        || self.stamp[ju] == round
                        || self.donors.len() == MAX_DONORS
                    {
                        continue;
                    }
                    self.stamp[ju] = round;
                    self.donors.push((j, 0.0));
                }
            }
            // What each can give: a share of its mass above its own least mass.
            for d in start..self.donors.len() {
                let j = self.donors[d].0;
                let give = if index.incident_edges(body, j) && index.found.len() <= MAX_DEGREE {
                    let own = Self::floor(body, j as usize, &index.found, h);
                    DONOR_SHARE * (body.surface.mass[j as usize] - own).max(0.0)
                } else {
                    0.0
                };
                self.donors[d].1 = give;
                total += give;
            }
            if total >= deficit || start == self.donors.len() {
                break;
            }
            ring = Some(start..self.donors.len());
        }
        total
    }
}
