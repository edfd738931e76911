//! Nodes found inside another body, let out.
//!
//! The collision net keeps trajectories from crossing; it cannot undo a crossing that is already
//! there. One comes where no answer of the net can move the nodes: a tool holds them (a probe
//! crushing one organ into another holds nodes of both on its sphere, and drags them through each
//! other's surfaces). Left alone, such organs stay crossed after the tool lets go, for good, and
//! the net answers their crossed parts every tick (tens of collisions a tick, ticks of
//! milliseconds).
//!
//! So the nodes of the net's collisions are looked at after its rounds (and, tick after tick,
//! those found before): a node deeper than the contact skin behind its nearest face of another
//! body whose surface is closed (no cut lips), and inside it by the winding number of that body's
//! surface, is *inside* that body. While it is, the net lets its vertex–face and edge–edge pairs
//! with that body cross (each such crossing takes it out, or moves a crossing that is there
//! already), and after the net it is moved out along the face's normal (its end position only),
//! by at most [`MOST_PUSH`] a tick. It stays flagged while it is behind its nearest face and the
//! winding number does not put it outside. (The net also lets through a collision between two
//! triangles of two bodies that cross each other at the start of the tick: see
//! `triangles_cross` in `bodies.rs`. Together they undo a crossing where no node is deep inside,
//! a side of one organ through a fold of the other.)
//!
//! Bounded: at most [`MOST_CHECKS`] nodes looked at a tick and [`MOST_WINDING_TRIANGLES`]
//! triangles summed for winding numbers (a node is not flagged anew when the other body's surface
//! does not fit what is left), in a fixed order; nothing allocated. In a contact without a crossing
//! nothing is flagged and the figures are the same bits.

use super::{Body, CONTACT_SKIN, NodeRef, REST_DISTANCE, barycentric, end_of, inverse_mass_of};
use crate::collision::bvh::TriangleBvh;
use crate::collision::tool::{Aabb, closest_point_on_triangle};
use crate::{Room, Vec3};

/// A node inside no other body.
const NOT_INSIDE: u32 = u32::MAX;

/// Most nodes looked at a tick (those flagged first, then the net's).
const MOST_CHECKS: usize = 512;

/// Most nodes of the net's collisions kept a tick for a look.
const MOST_SEEDS: usize = 4096;

/// How far from a node its nearest face is looked for (m): a node deeper than this inside another
/// body is not found (until it comes within reach).
const REACH: f64 = 5e-3;

/// Most a node inside another body is moved out in a tick (m; 0.5 m/s).
const MOST_PUSH: f64 = 5e-4;

/// Triangles a node's search may meet.
const MOST_FOUND: usize = 1024;

/// Most triangles a tick's winding numbers go over (about 0.3 ms).
const MOST_WINDING_TRIANGLES: usize = 1 << 14;

/// The flags and their scratch (room reserved for each body's most nodes).
#[derive(Clone, Debug)]
pub(super) struct Untangle {
    /// Per body and node, the body it is inside (`NOT_INSIDE`: none).
    inside: Vec<Room<u32>>,
    /// The bodies' topology versions the flags were taken at.
    versions: Room<u64>,
    /// The flagged nodes, (body, node), in the order they were found.
    flagged: Room<[u32; 2]>,
    /// The next tick's flagged nodes.
    kept: Room<[u32; 2]>,
    /// Nodes of this tick's net collisions with the other body: (body, node, other).
    seeds: Room<[u32; 3]>,
    found: Room<u32>,
    /// Triangles this run's winding numbers may still go over.
    winding_budget: usize,
    /// Nodes inside another body after the last run.
    pub(super) inside_nodes: u32,
}

/// Where a node stands against another body: the outward normal at its nearest point and its
/// distance behind it (negative: in front).
struct Nearest {
    normal: Vec3,
    depth: f64,
}

impl Untangle {
    /// Room for `nodes` nodes in each of the bodies' slots (`capacities`).
    pub(super) fn new(capacities: impl Iterator<Item = usize>) -> Self {
        let inside: Vec<Room<u32>> = capacities.map(Room::with_capacity).collect();
        let most: usize = inside.iter().map(|r| r.capacity()).sum();
        Self {
            versions: Room::with_capacity(inside.len()),
            inside,
            flagged: Room::with_capacity(most),
            kept: Room::with_capacity(most),
            seeds: Room::with_capacity(MOST_SEEDS),
            found: Room::with_capacity(MOST_FOUND),
            winding_budget: 0,
            inside_nodes: 0,
        }
    }

    /// Whether the pair of `nodes` (a vertex–face or edge–edge pair of two bodies) has a node
    /// inside the pair's other body: its crossing is let through.
    pub(super) fn lets_cross(&self, nodes: &[NodeRef; 4], vertex_face: bool) -> bool {
        !self.flagged.is_empty()
            && with_other_body(nodes, vertex_face).any(|(r, other)| self.is_inside(r, other))
    }

    /// Whether node `r` is flagged inside body `other`.
    pub(super) fn is_inside(&self, r: NodeRef, other: usize) -> bool {
        self.inside
            .get(r.body)
            .and_then(|flags| flags.get(r.node))
            .is_some_and(|&o| o as usize == other)
    }

    /// Keeps the nodes of a collision the net answered (pairs of two bodies) for a look after the
    /// net.
    pub(super) fn seed(&mut self, nodes: &[NodeRef; 4], vertex_face: bool) {
        for (r, other) in with_other_body(nodes, vertex_face) {
            if self.seeds.len() < self.seeds.capacity() {
                self.seeds
                    .push([r.body as u32, r.node as u32, other as u32]);
            }
        }
    }

    /// Drops the flags of bodies whose topology changed (their node numbers may name other nodes)
    /// and sizes the flags to the bodies' nodes.
    fn follow_topology(&mut self, bodies: &[Body]) {
        let n = bodies.len().min(self.inside.len());
        self.versions.truncate(n);
        while self.versions.len() < n {
            self.versions.push(u64::MAX);
        }
        let mut dropped = false;
        for (k, body) in bodies.iter().enumerate().take(n) {
            let flags = &mut self.inside[k];
            let count = body.node_count().min(flags.capacity());
            if self.versions[k] != body.topology_version || flags.len() != count {
                dropped |= flags.iter().any(|&o| o != NOT_INSIDE);
                flags.clear();
                flags.resize(count, NOT_INSIDE);
                self.versions[k] = body.topology_version;
            }
        }
        if dropped {
            let inside = &self.inside;
            self.flagged.retain(|&[b, v]| {
                inside[b as usize]
                    .get(v as usize)
                    .is_some_and(|&o| o != NOT_INSIDE)
            });
        }
    }

    /// After the net's rounds: the flagged nodes and the net's collisions looked at, those inside
    /// another body flagged and moved out towards its surface, the others' flags dropped.
    pub(super) fn run(
        &mut self,
        bodies: &mut [Body],
        bvhs: &mut [TriangleBvh],
        moved: &mut [bool],
    ) {
        self.follow_topology(bodies);
        // The seeds in a fixed order, each once.
        self.seeds.sort_unstable();
        self.seeds.dedup();
        self.kept.clear();
        self.winding_budget = MOST_WINDING_TRIANGLES;
        let mut checks = 0;
        let (flagged, seeds) = (
            std::mem::take(&mut *self.flagged),
            std::mem::take(&mut *self.seeds),
        );
        for [b, v] in flagged.iter().copied() {
            let other = self.inside[b as usize][v as usize];
            self.inside[b as usize][v as usize] = NOT_INSIDE;
            let r = NodeRef {
                body: b as usize,
                node: v as usize,
            };
            if checks >= MOST_CHECKS {
                // Not looked at this tick: kept as it was.
                self.flag(r, other);
                continue;
            }
            checks += 1;
            if let Some(nearest) = self.nearest(bodies, bvhs, r, other as usize)
                && nearest.depth > 0.0
                && self.winding(bodies, r, other as usize) != Some(false)
            {
                self.flag(r, other);
                push_out(bodies, r, &nearest, moved);
            }
        }
        for &[b, v, other] in seeds.iter() {
            if checks >= MOST_CHECKS {
                break;
            }
            let r = NodeRef {
                body: b as usize,
                node: v as usize,
            };
            let Some(&flag) = self.inside.get(r.body).and_then(|f| f.get(r.node)) else {
                continue;
            };
            if flag != NOT_INSIDE {
                continue;
            }
            checks += 1;
            if let Some(nearest) = self.nearest(bodies, bvhs, r, other as usize)
                && nearest.depth > CONTACT_SKIN
                && self.winding(bodies, r, other as usize) == Some(true)
            {
                self.flag(r, other);
                push_out(bodies, r, &nearest, moved);
            }
        }
        // Back into their rooms (the lists were taken, not dropped: nothing allocated).
        *self.flagged = flagged;
        *self.seeds = seeds;
        self.flagged.clear();
        self.seeds.clear();
        std::mem::swap(&mut self.flagged, &mut self.kept);
        self.inside_nodes = self.flagged.len() as u32;
    }

    /// Whether node `r`'s end position is inside body `other` by the winding number of its surface
    /// (exact for a closed surface, folded or not), or `None` when this run's budget of triangles
    /// does not cover that body's. The nearest face's side alone is not enough: where a surface is
    /// pressed flat or folds in a collision a node can be behind its nearest face and outside.
    fn winding(&mut self, bodies: &[Body], r: NodeRef, other: usize) -> Option<bool> {
        let s = &bodies[other].surface;
        if s.triangles.len() > self.winding_budget {
            return None;
        }
        self.winding_budget -= s.triangles.len();
        let p = end_of(bodies, r);
        let x = &s.next_position_in_world;
        let mut angle = 0.0;
        for t in &s.triangles {
            let [a, b, c] = t.map(|v| x[v as usize] - p);
            let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
            let volume = a.dot(&b.cross(&c));
            let below = la * lb * lc + a.dot(&b) * lc + b.dot(&c) * la + c.dot(&a) * lb;
            angle += 2.0 * volume.atan2(below);
        }
        // The solid angle over 4π: 1 inside, 0 outside.
        Some(angle > 2.0 * std::f64::consts::PI)
    }

    fn flag(&mut self, r: NodeRef, other: u32) {
        if self.kept.len() < self.kept.capacity() {
            self.inside[r.body][r.node] = other;
            self.kept.push([r.body as u32, r.node as u32]);
        }
    }

    /// Node `r`'s nearest face of body `other` within [`REACH`] of its end position, when that
    /// body's surface is closed; the side from the face's normal where the nearest point is inside
    /// the face, from the mean of the normals of the faces as near where it is on a side or corner.
    fn nearest(
        &mut self,
        bodies: &[Body],
        bvhs: &mut [TriangleBvh],
        r: NodeRef,
        other: usize,
    ) -> Option<Nearest> {
        let body = bodies.get(other)?;
        if body.boundary_edges != 0 || other == r.body {
            return None;
        }
        let bvh = bvhs.get_mut(other)?;
        if !bvh.is_built_for(body.topology_version, body.surface.triangles.len()) {
            return None;
        }
        let p = end_of(bodies, r);
        let mut reach = Aabb::of_pair(&p, &p);
        reach.inflate(REACH);
        self.found.clear();
        bvh.query(&reach, &mut self.found);
        let s = &body.surface;
        let x = &s.next_position_in_world;
        let corners = |t: u32| s.triangles[t as usize].map(|v| x[v as usize]);
        let mut best: Option<(f64, u32, Vec3)> = None;
        for &t in self.found.iter() {
            let [a, b, c] = corners(t);
            let q = closest_point_on_triangle(&p, &a, &b, &c);
            let d2 = (p - q).norm_squared();
            if best.is_none_or(|(d, u, _)| d2 < d || (d2 == d && t < u)) {
                best = Some((d2, t, q));
            }
        }
        let (d2, t, q) = best?;
        if d2 > REACH * REACH {
            return None;
        }
        let unit = |[a, b, c]: [Vec3; 3]| {
            let n = (b - a).cross(&(c - a));
            let l = n.norm();
            (l > f64::MIN_POSITIVE && l.is_finite()).then(|| n / l)
        };
        let [a, b, c] = corners(t);
        let within = barycentric(&q, &a, &b, &c).is_some_and(|w| w.iter().all(|&x| x > 1e-9));
        let normal = if within {
            unit([a, b, c])?
        } else {
            // On a side or corner: the faces as near (to rounding) share the point.
            let mut sum = Vec3::zeros();
            for &u in self.found.iter() {
                let [a, b, c] = corners(u);
                let d = (p - closest_point_on_triangle(&p, &a, &b, &c)).norm_squared();
                if d <= d2 * (1.0 + 1e-9) + 1e-24
                    && let Some(n) = unit([a, b, c])
                {
                    sum += n;
                }
            }
            let l = sum.norm();
            if !(l > f64::MIN_POSITIVE && l.is_finite()) {
                return None;
            }
            sum / l
        };
        let depth = -(p - q).dot(&normal);
        depth.is_finite().then_some(Nearest { normal, depth })
    }
}

/// Each node of a pair of two bodies (the vertex, then the face's nodes; or the two edges') with
/// the pair's other body; none for a pair within one body.
fn with_other_body(
    nodes: &[NodeRef; 4],
    vertex_face: bool,
) -> impl Iterator<Item = (NodeRef, usize)> + '_ {
    let (a, b) = (nodes[0].body, nodes[3].body);
    let split = if vertex_face { 1 } else { 2 };
    nodes
        .iter()
        .enumerate()
        .filter(move |_| a != b)
        .map(move |(k, &r)| (r, if k < split { b } else { a }))
}

/// Moves node `r` (inside another body) out along `nearest`'s normal by the depth and the rest
/// distance, at most [`MOST_PUSH`]: its end position only (its velocity, and so the momentum and
/// the kinetic energy, unchanged). The node alone: pushing the face's corners the other way too
/// drove a face the probe pinned a node under deeper tick after tick, until the guard found the
/// organ stretched (ten guard events in the hard press at 4.5 cm). A node a tool holds is the
/// tool's.
fn push_out(bodies: &mut [Body], r: NodeRef, nearest: &Nearest, moved: &mut [bool]) {
    if inverse_mass_of(bodies, r) == 0.0 {
        return;
    }
    let change = (nearest.depth + REST_DISTANCE).min(MOST_PUSH);
    if let Some(m) = moved.get_mut(r.body) {
        *m = true;
    }
    bodies[r.body].surface.next_position_in_world[r.node] += nearest.normal * change;
}
