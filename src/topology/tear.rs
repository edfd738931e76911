//! Tearing (MODEL.md §1, an extreme interaction): a surface spring stretched past `strain` (relative to
//! its rest length) for `ticks` ticks in a row breaks, and the surface opens there with the opening
//! of a cut ([`Cutter::tear`]): nodes whose triangles fall apart are copied (each copy its share of
//! the mass and of the link, the same homologue), the spring becomes two lips, and a part that
//! separates becomes a body of its own.
//!
//! Order and bound: every tick the springs past the threshold are ranked by strain (largest first,
//! then by index), and at most `max_per_tick` of them break, so the result is deterministic and the
//! tick bounded. A spring between two inner nodes with no opening next to it cannot open alone (a
//! slit of one edge separates nothing): it breaks together with the most stretched inner spring that
//! continues it from either end, the crack's first two edges. A spring whose two ends a grasper holds
//! does not tear: the jaws keep the tissue between them (their squeeze is no pull). A spring from a
//! held node to a free one (inner or a lip) tears round the grasp: the crack opens the free node's
//! edges to the other corners of the spring's triangles, along the edge of the held node's fan, so
//! that the held tissue comes away whole (opening the spring itself would split the held node into
//! spikes, each hanging from the organ by a triangle whose sides never tear).
//!
//! Mass and momentum are conserved by construction (copies split a node's mass and move with it);
//! the elastic energy of a torn spring stays in its two lips (each of half its stiffness), so a tear
//! adds no energy. Every buffer is sized up front: a tear allocates nothing.

use super::cut::{CutStep, Cutter};
use crate::body::Body;
pub use crate::body::settings::TearingSettings;

/// Counters of a body's tears since the start.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TearCounters {
    /// Springs that broke past the threshold.
    pub breaks: u64,
    /// Springs that broke with them to start a crack (the second edge of a slit).
    pub starts: u64,
    /// Ticks on which a tear changed the mesh.
    pub ticks: u64,
    /// Springs past the threshold left for a later tick (the per-tick bound).
    pub deferred: u64,
    /// Springs from held to free tissue whose break opened the edges round the grasp instead.
    pub rounds: u64,
}

/// The tearing state of one body: settings, counters and fixed scratch.
#[derive(Clone, Debug)]
pub struct Tearer {
    /// Settings from the scene.
    pub settings: TearingSettings,
    /// Counters since the start.
    pub counters: TearCounters,
    /// Ticks each spring has been past the threshold ([`LIP`] for a lip).
    over: crate::Room<u32>,
    /// The springs to break this tick: (strain, spring), largest strain first.
    picked: Vec<(f64, u32)>,
    /// The edges one break opens.
    path: crate::Room<(u32, u32)>,
    /// The cutter's transection count when `over` was last valid.
    transections_seen: u64,
}

/// Mark in `over` of a spring that cannot tear (a lip).
const LIP: u32 = u32::MAX;

impl Tearer {
    /// The tearing state of `body`, with scratch for its reserved room.
    pub fn new(body: &Body, settings: TearingSettings) -> Self {
        let edges = body.limits.edges.max(body.edges.len());
        Self {
            settings,
            counters: TearCounters::default(),
            over: crate::Room::with_capacity(edges),
            picked: Vec::with_capacity(settings.max_per_tick),
            path: crate::Room::with_capacity(3),
            transections_seen: 0,
        }
    }

    /// Ranks the springs of `body` past the threshold and breaks the first `max_per_tick` of them
    /// through `cutter`. Returns what the openings did (summed).
    pub fn step(&mut self, body: &mut Body, cutter: &mut Cutter) -> CutStep {
        let mut total = CutStep::default();
        let edge_count = body.edges.len().min(self.over.capacity());
        if edge_count < self.over.len() || cutter.counters.transections != self.transections_seen {
            // Springs were removed or renumbered (coarsening; a transection, whose caps may add as
            // many springs as the pieces took away): counts and marks start again.
            self.over.clear();
            self.transections_seen = cutter.counters.transections;
        }
        // Cuts and tears append springs and keep the numbers of the others.
        self.over.resize(edge_count, 0);
        self.picked.clear();
        let threshold = self.settings.strain;
        let x = &body.surface.position_in_world;
        let held = &body.surface.tool_contact;
        let e = &body.edges;
        for k in 0..self.over.len() {
            let rest = e.rest_length[k];
            if self.over[k] == LIP || e.stiffness[k] <= 0.0 || rest <= 0.0 {
                continue;
            }
            // Tissue held in a grasper's jaws at both ends is kept by the jaws (their squeeze is not
            // a pull): it tears around the grasp, not inside it.
            if held[e.a[k] as usize].grasp.is_some() && held[e.b[k] as usize].grasp.is_some() {
                self.over[k] = 0;
                continue;
            }
            let length = (x[e.b[k] as usize] - x[e.a[k] as usize]).norm();
            let strain = length / rest - 1.0;
            if strain.is_nan() || strain <= threshold {
                self.over[k] = 0;
                continue;
            }
            self.over[k] = (self.over[k] + 1).min(LIP - 1);
            if self.over[k] >= self.settings.ticks {
                self.rank(strain, k as u32);
            }
        }
        for i in 0..self.picked.len() {
            let k = self.picked[i].1 as usize;
            if k >= body.edges.len() {
                continue;
            }
            let (a, b) = (body.edges.a[k], body.edges.b[k]);
            self.path.clear();
            let held = &body.surface.tool_contact;
            let (held_a, held_b) = (
                held[a as usize].grasp.is_some(),
                held[b as usize].grasp.is_some(),
            );
            if held_a == held_b && triangles_on(body, a, b) != 2 {
                // A lip (of a cut, a tear, a mesh's border), or not a mesh edge: it never tears.
                self.over[k] = LIP;
                continue;
            }
            if held_a != held_b {
                // A spring from held tissue to free tissue (inner or a lip) tears round the grasp:
                // the crack opens the free node's edges to the other corners of the spring's
                // triangles (the held node's fan, on the free side), so that the held patch comes
                // away whole instead of the held node being split into spikes.
                let (g, x) = if held_a { (a, b) } else { (b, a) };
                round_the_grasp(body, g, x, &mut self.path);
                if self.path.is_empty() {
                    // Already open round there: the spring now pulls on the patch only.
                    self.over[k] = 0;
                    continue;
                }
                if self.path.len() == 1 {
                    let (p, q) = self.path[0];
                    if !on_boundary(body, p) && !on_boundary(body, q) && !cutter.pending_at(p, q) {
                        if let Some(next) = continuation(body, p, q) {
                            self.path.push(next);
                            self.counters.starts += 1;
                        }
                    }
                }
                self.counters.rounds += 1;
            } else {
                self.path.push((a, b));
                if !on_boundary(body, a) && !on_boundary(body, b) && !cutter.pending_at(a, b) {
                    if let Some(next) = continuation(body, a, b) {
                        self.path.push(next);
                        self.counters.starts += 1;
                    }
                }
            }
            let step = cutter.tear(body, &self.path);
            if step.refused {
                break;
            }
            self.counters.breaks += 1;
            total.copies += step.copies;
            total.opened += step.opened;
            total.changed |= step.changed;
        }
        if total.changed {
            self.counters.ticks += 1;
            if total.opened > 0 {
                cutter.check_parts = true;
            }
        }
        total
    }

    /// Keeps spring `k` among the `max_per_tick` most strained (ties by index).
    fn rank(&mut self, strain: f64, k: u32) {
        let limit = self.settings.max_per_tick;
        let position = self
            .picked
            .iter()
            .position(|&(s, j)| strain > s || (strain == s && k < j))
            .unwrap_or(self.picked.len());
        if position >= limit {
            self.counters.deferred += 1;
            return;
        }
        if self.picked.len() == limit {
            self.picked.pop();
            self.counters.deferred += 1;
        }
        self.picked.insert(position, (strain, k));
    }
}

/// Number of triangles with both `a` and `b` as corners.
fn triangles_on(body: &Body, a: u32, b: u32) -> usize {
    body.surface
        .triangles
        .iter()
        .filter(|t| t.contains(&a) && t.contains(&b))
        .count()
}

/// Whether `v` is on a boundary: one of its edges has a single triangle.
fn on_boundary(body: &Body, v: u32) -> bool {
    // Around an inner node every directed edge v→w of a triangle is matched by w→v in another.
    let triangles = &body.surface.triangles;
    for t in triangles {
        for corner in 0..3 {
            if t[corner] != v {
                continue;
            }
            let w = t[(corner + 1) % 3];
            let matched = triangles
                .iter()
                .any(|u| (0..3).any(|c| u[c] == w && u[(c + 1) % 3] == v));
            if !matched {
                return true;
            }
        }
    }
    false
}

/// The edges a tear round the grasp opens for the spring from held node `g` to free node `x`: for each
/// triangle on `g`–`x`, the edge from `x` to its third corner, when that corner is free and the edge
/// inner (two triangles on it). Appended to `path`.
fn round_the_grasp(body: &Body, g: u32, x: u32, path: &mut Vec<(u32, u32)>) {
    let held = &body.surface.tool_contact;
    for t in &body.surface.triangles {
        if !(t.contains(&g) && t.contains(&x)) {
            continue;
        }
        let Some(&y) = t.iter().find(|&&v| v != g && v != x) else {
            continue;
        };
        if held[y as usize].grasp.is_none()
            && triangles_on(body, x, y) == 2
            && path.len() < path.capacity()
        {
            path.push((x, y));
        }
    }
}

/// The most strained inner spring at `a` or `b` other than `a`–`b` (two triangles on it, neither end
/// held by a grasper), as the crack's second edge.
fn continuation(body: &Body, a: u32, b: u32) -> Option<(u32, u32)> {
    let x = &body.surface.position_in_world;
    let held = &body.surface.tool_contact;
    let e = &body.edges;
    let mut best: Option<(f64, u32, u32)> = None;
    for k in 0..e.len() {
        let (p, q) = (e.a[k], e.b[k]);
        let touches = p == a || p == b || q == a || q == b;
        let same = (p == a && q == b) || (p == b && q == a);
        if !touches
            || same
            || e.rest_length[k] <= 0.0
            || held[p as usize].grasp.is_some()
            || held[q as usize].grasp.is_some()
        {
            continue;
        }
        let strain = (x[q as usize] - x[p as usize]).norm() / e.rest_length[k] - 1.0;
        if best.is_none_or(|(s, _, _)| strain > s) && triangles_on(body, p, q) == 2 {
            best = Some((strain, p, q));
        }
    }
    best.map(|(_, p, q)| (p, q))
}
