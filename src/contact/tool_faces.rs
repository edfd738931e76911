//! Tool–face contact: a tool pressed on a body's surface *between* its nodes — a probe finer than
//! the mesh, an instrument's shaft laid across a triangle, a jaw across an edge — is met by the
//! triangles themselves, not only by the nodes the paper's contact zone holds (MODEL.md §4). Without
//! it a tool slips between the nodes of a coarse mesh: no force, the surface passing through it.
//!
//! Each tick, after the tools captured the nodes they reach, for each tool part finer than a
//! triangle (see [`FINE`]) that cuts into it from the triangle's outer side (judged at the start of
//! the tick), or comes within a small gap of it (see [`MARGIN`]):
//! - the contact point is the triangle's point closest to the part's axis, with barycentric weights
//!   w, and the triangle must go from the axis towards that point (along its inward normal where the
//!   axis reached it);
//! - the positions: the triangle's free corners (not held by a tool) are moved that way until the
//!   point is a radius from the axis, each by `w_k / m_k` times one multiplier (the smallest
//!   mass-weighted correction). A projection: no velocity changes, so a triangle found deep in the
//!   tool is not thrown out of it;
//! - the velocities: the point's approach to the tool along the direction (less the gap it may
//!   close in the tick) is taken from the corners' velocities the same way (an inelastic contact);
//! - friction: the point's slip on the tool (across the direction) is taken from the corners'
//!   velocities the same way, the friction impulse kept within the Coulomb cone of the normal one
//!   (the body's `friction` against tools, as its held nodes);
//! - a part faster than its diameter: an end of its axis that crossed a triangle over the tick
//!   (from the outer side, the part wholly behind it at the end) makes the triangle go in along its
//!   normal, a radius ahead of that end;
//! - the tool feels the opposite of those impulses, `−(J_n n + J_t) Σ_k w_k / Δt`, at the contact
//!   point.
//!
//! Triangles that share corners are answered together in a few Gauss–Seidel sweeps in triangle
//! order (deterministic); from the second sweep each contact is taken again where the triangle now
//! is (one pushed out near a light corner turns about its heavier ones, and its point deepest in
//! the tool moves). At rest against a still tool the force fed back is the deformation force
//! that pushes the triangles onto it, as for a held node.
//!
//! Held nodes and faces: the corners a tool holds are not moved, and the multiplier of a triangle
//! with held corners is the one of a triangle whose corners all move (the held ones' share not
//! given): a cut near a held corner closes over a few ticks, where taking it all from the free
//! corners' small weights would throw them off the tool (until 2026-12-07 such cuts, three
//! quarters of their weight or more on held corners, were left to the held nodes; with the
//! threshold of [`FINE`] at one, the tool sank between them, or the contact flickered). A node
//! whose triangles a tool pressed in the last tick is not captured by that tool (graspers
//! excepted: their jaws take what they close on): held on the tool's surface, the triangles beside
//! it would rise through a tool finer than them, and the contact would flicker between the node
//! and its faces.
//!
//! Bodies that refine at contact (`subdivision`) answer such cuts the paper's way, with a node
//! inserted there (`crate::topology::refine`); the world runs this stage for the others.
//!
//! The broad phase reads the node pass's blocks: the triangles are taken in chunks of [`CHUNK`]
//! consecutive ones (close in space: a mesh's triangles are sorted by their first corner, its nodes
//! along a space-filling curve), each with the list of node blocks its corners lie in, and a chunk
//! is looked at only when the union of its blocks' boxes meets the tool's. The lists are rebuilt in
//! reserved room when the topology changes; nothing is allocated on the tick.

use crate::body::Surface;
use crate::collision::blocks::{BLOCK, NodeBlock, NodeBlocks};
use crate::collision::tool::{
    Aabb, closest_point_on_triangle, segment_segment_closest, segment_triangle_distance, tool_reach,
};
use crate::contact::tool::NO_TOOL;
use crate::tool::{CapsulePart, Tool, ToolShape};
use crate::{Room, Vec3};

/// Triangles per chunk of the broad phase.
pub const CHUNK: usize = 128;

/// Node blocks a chunk lists; a chunk whose corners lie in more (or in a block past `u16::MAX`) is
/// looked at every tick. (On a 40 962-node sphere, 640 chunks of 128 triangles: their corners lie in
/// 3 to 12 blocks of 64 nodes; with chunks of 32 the loop over the 2 560 chunks alone cost about
/// 20 µs a tick.)
const CHUNK_BLOCKS: usize = 16;

/// A tool part meets a triangle's face when its radius is less than `1 / FINE` of the radius of
/// the circle through the triangle's corners at rest: a tool that fine fits between the corners
/// (one as wide as that circle, or wider, meets a corner before its axis reaches the triangle's
/// plane). Coarser parts are left to the nodes, as in the paper. Until 2026-12-07 the threshold was
/// a half, and a part between half and all of the circle sank between the nodes: a 6 mm probe
/// pressing the bench organ of the body-contact tests held one node while the triangles round it
/// cut 2.3 mm into it, and a 5 mm probe pressed into a soft 642-node organ went through its surface.
const FINE: f64 = 1.0;

/// Gap, as a fraction of the tool part's radius, within which a triangle is in contact before it
/// cuts into the tool (a speculative contact: it may approach by its gap in the tick, no faster),
/// so that a triangle resting on the tool does not drop out of contact every other tick.
const MARGIN: f64 = 0.02;

/// The six bits of a box's sides that meet a reach (see `ToolFaces::broad_phase`).
const ALL_SIDES: u8 = 0b11_1111;

/// Gauss–Seidel sweeps over the triangles in contact with one tool.
const SWEEPS: usize = 3;

/// Most triangles in contact with one tool of one body in a tick; more are counted and left.
pub const MAX_FACE_CONTACTS: usize = 256;

#[derive(Clone, Copy, Debug, Default)]
struct Chunk {
    blocks: [u16; CHUNK_BLOCKS],
    /// Blocks listed; `u8::MAX`: more than [`CHUNK_BLOCKS`] (always looked at).
    count: u8,
}

#[derive(Clone, Copy, Debug, Default)]
struct Hit {
    corners: [u32; 3],
    /// Barycentric weights of the contact point.
    w: [f64; 3],
    /// Inverse masses of the corners the contact may move (0 for a held corner).
    inverse_mass: [f64; 3],
    /// Direction the triangle is pushed (unit, from the tool's axis).
    direction: Vec3,
    /// The tool part met (an index into its parts); `None` for a part that crossed the triangle
    /// within the tick, whose contact stays where the crossing put it.
    part: Option<usize>,
    /// The tool's axis point the contact keeps its distance from (end of the tick).
    axis_point: Vec3,
    /// The distance along `direction` the contact point must keep from `axis_point` (m).
    clearance: f64,
    /// Σ_k w_k² / m_k over the corners the contact may move (1/kg).
    effective_inverse_mass: f64,
    /// Velocity of the tool's point at the contact over the tick (m/s).
    tool_velocity: Vec3,
    /// Σ of the velocity multipliers applied along `direction` (kg·m/s per unit weight: the
    /// normal impulse).
    applied: f64,
    /// Σ of the tangential (friction) impulses applied, per unit weight (kg·m/s), kept within
    /// the Coulomb cone `friction × applied`.
    tangential: Vec3,
    /// The friction reached the cone's edge in the last sweep: the triangle slides on the tool.
    sliding: bool,
}

impl Hit {
    /// The contact taken again from the triangle's current end positions against `part` (the
    /// part it met): its point, weights and direction. A triangle pushed out at a point near a
    /// light corner turns about its heavier ones, and the point of it deepest in the tool is then
    /// elsewhere (on a refined patch, whose inserted nodes take mass from their neighbours, the
    /// triangles kept at one point each sank into the tool by about a millimetre over a press;
    /// round a corner fifty times lighter than the others, 16 µm stay in the tool after a tick).
    fn take_again(&mut self, surface: &Surface, part: &CapsulePart) {
        let x = &surface.next_position_in_world;
        let [a, b, c] = self.corners.map(|v| x[v as usize]);
        let Some(outward) = (b - a).cross(&(c - a)).try_normalize(f64::MIN_POSITIVE) else {
            return;
        };
        let (_, direction, axis_point, q) = closest_contact(part, &a, &b, &c, &outward);
        let Some(w) = weights(&q, &a, &b, &c) else {
            return;
        };
        let effective_inverse_mass: f64 = (0..3)
            .map(|k| w[k] * w[k] * surface.inverse_mass[self.corners[k] as usize])
            .sum();
        if effective_inverse_mass > 0.0 && effective_inverse_mass.is_finite() {
            self.w = w;
            self.direction = direction;
            self.axis_point = axis_point;
            self.effective_inverse_mass = effective_inverse_mass;
        }
    }
}

/// What the face contacts did in a tick (one body, every tool).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FaceCounts {
    /// Triangles a tool pressed between their nodes.
    pub contacts: u32,
    /// Triangles left unanswered because a tool's list was full.
    pub dropped: u32,
    /// Triangles the broad phase kept (their box met a tool's reach), over the tools.
    pub candidates: u32,
}

/// Scratch of the face contacts of one body: the broad phase's chunks and the tick's contacts,
/// reserved for the body's mesh capacity (a copy keeps the room: its lists' capacities are limits
/// the stage reads, and the nodes pressed in the last tick are state the next tick uses).
#[derive(Clone, Debug, Default)]
pub struct ToolFaces {
    chunks: Room<Chunk>,
    /// (topology version, triangles, nodes) the chunks were built for.
    built: Option<(u64, usize, usize)>,
    candidates: Room<u32>,
    hits: Room<Hit>,
    /// For each node, 1 + the index of the tool that pressed a triangle of it in the last tick's
    /// face stage (0: none); nodes past its length: none.
    pressed_by: Vec<u32>,
    /// The nodes marked in `pressed_by`.
    marked: Room<u32>,
    /// Scratch of the broad phase: each node block's sides against the tool's reach.
    sides: Room<u8>,
    /// Scratch of the broad phase, per node: sides of the tool's reach its end position lies
    /// beyond (see `ToolFaces::fill_codes`); valid for the blocks stamped with `generation`.
    codes: Vec<u8>,
    /// Per node block: the broad phase call whose codes its nodes hold.
    stamps: Vec<u64>,
    /// Broad phase calls so far.
    generation: u64,
    /// The largest [`rest_circumradius`] of the body's triangles when the chunks were built: a
    /// tool with no part finer than [`FINE`] of it meets no face (infinite for a degenerate one).
    largest_circumradius: f64,
}

impl ToolFaces {
    /// Room for a body of at most `nodes` nodes and `triangles` triangles.
    pub fn with_capacity((nodes, triangles): (usize, usize)) -> Self {
        Self {
            chunks: Room::with_capacity(triangles.div_ceil(CHUNK)),
            built: None,
            candidates: Room::with_capacity(triangles),
            hits: Room::with_capacity(MAX_FACE_CONTACTS),
            pressed_by: vec![0; nodes],
            marked: Room::with_capacity(3 * MAX_FACE_CONTACTS),
            sides: Room::with_capacity(nodes.div_ceil(BLOCK)),
            codes: vec![0; nodes],
            stamps: vec![0; nodes.div_ceil(BLOCK)],
            generation: 0,
            largest_circumradius: f64::INFINITY,
        }
    }

    /// The body changed in a way its version may not tell (a spare body taken for a
    /// transection): the chunks are built again before their next use, and no node counts as
    /// pressed.
    pub fn invalidate(&mut self) {
        self.built = None;
        self.unmark();
    }

    fn unmark(&mut self) {
        for &v in &self.marked {
            if let Some(p) = self.pressed_by.get_mut(v as usize) {
                *p = 0;
            }
        }
        self.marked.clear();
    }

    /// Whether tool `tool` pressed a triangle with corner `node` in the last face stage: such a
    /// node is not captured by it (the faces carry that contact; holding the node at the tool's
    /// surface would let the triangles beside it cut into the tool).
    fn pressed_by(&self, node: usize, tool: usize) -> bool {
        self.pressed_by
            .get(node)
            .is_some_and(|&p| p == tool as u32 + 1)
    }

    /// Leaves out of `candidates` (nodes the broad phase kept for `tool`, index `tool_index`) the
    /// nodes whose triangles that tool pressed in the last face stage (see [`Self::pressed_by`]);
    /// a grasper's jaws take what they close on, so its candidates are kept.
    pub fn leave_pressed(&self, candidates: &mut Vec<u32>, tool: &Tool, tool_index: usize) {
        if !matches!(tool.shape, ToolShape::Grasper { .. }) {
            candidates.retain(|&i| !self.pressed_by(i as usize, tool_index));
        }
    }

    fn rebuild_if_stale(&mut self, surface: &Surface, version: u64) {
        let key = (
            version,
            surface.triangles.len(),
            surface.position_in_world.len(),
        );
        if self.built == Some(key) {
            return;
        }
        self.largest_circumradius = surface
            .triangles
            .iter()
            .map(|&corners| rest_circumradius(surface, corners))
            .fold(0.0, |largest: f64, r| {
                if r.is_nan() {
                    f64::INFINITY
                } else {
                    largest.max(r)
                }
            });
        self.chunks.clear();
        let triangles = &surface.triangles;
        if triangles.len().div_ceil(CHUNK) > self.chunks.capacity() {
            // More triangles than reserved: no chunks (every triangle is looked at).
            self.built = Some(key);
            return;
        }
        for first in (0..triangles.len()).step_by(CHUNK) {
            let mut chunk = Chunk {
                blocks: [0; CHUNK_BLOCKS],
                count: 0,
            };
            'corners: for tri in &triangles[first..(first + CHUNK).min(triangles.len())] {
                for &v in tri {
                    let Ok(block) = u16::try_from(v as usize / BLOCK) else {
                        chunk.count = u8::MAX;
                        break 'corners;
                    };
                    let count = chunk.count as usize;
                    if chunk.blocks[..count].contains(&block) {
                        continue;
                    }
                    if count == CHUNK_BLOCKS {
                        chunk.count = u8::MAX;
                        break 'corners;
                    }
                    chunk.blocks[count] = block;
                    chunk.count += 1;
                }
            }
            self.chunks.push(chunk);
        }
        self.built = Some(key);
    }

    /// The triangles whose corners' end positions may meet `reach`, in index order, into
    /// `self.candidates`.
    fn broad_phase(&mut self, surface: &Surface, reach: &Aabb, blocks: Option<&[NodeBlock]>) {
        self.candidates.clear();
        let (triangles, x) = (&surface.triangles, &surface.next_position_in_world);
        let candidates = &mut self.candidates;
        let mut among = |range: std::ops::Range<usize>| {
            for t in range {
                let [a, b, c] = triangles[t].map(|v| x[v as usize]);
                if reach.overlaps_segment(&a.inf(&b).inf(&c), &a.sup(&b).sup(&c)) {
                    candidates.push(t as u32);
                }
            }
        };
        let n = triangles.len();
        let chunked = blocks
            .filter(|b| self.chunks.len() == n.div_ceil(CHUNK) && b.len() <= self.sides.capacity());
        let Some(blocks) = chunked else {
            among(0..n);
            return;
        };
        // Each block's sides against the reach, one bit per face of the box: bit 2k when its
        // least coordinate k is at most the reach's greatest, bit 2k + 1 when its greatest is at
        // least the reach's least. The union of some blocks' boxes meets the reach exactly when
        // the bits of the blocks, joined, are all six: a chunk is judged by six bits, not boxes.
        self.sides.clear();
        self.sides.extend(blocks.iter().map(|b| {
            if b.bad {
                return ALL_SIDES;
            }
            let (lo, hi) = (&b.bounds.min, &b.bounds.max);
            let mut bits = 0u8;
            for k in 0..3 {
                bits |= u8::from(lo[k] <= reach.max[k]) << (2 * k);
                bits |= u8::from(hi[k] >= reach.min[k]) << (2 * k + 1);
            }
            bits
        }));
        self.generation += 1;
        let coded = x.len() <= self.codes.len() && blocks.len() <= self.stamps.len();
        for (k, chunk) in self.chunks.iter().enumerate() {
            let range = k * CHUNK..((k + 1) * CHUNK).min(n);
            if chunk.count == u8::MAX {
                among(range);
                continue;
            }
            // The union of the blocks' boxes holds every corner's trajectory, so every triangle's
            // end position: a chunk whose union misses the reach holds no candidate.
            let mut bits = 0u8;
            for &block in &chunk.blocks[..chunk.count as usize] {
                bits |= self.sides.get(block as usize).copied().unwrap_or(ALL_SIDES);
            }
            if bits != ALL_SIDES {
                continue;
            }
            if !coded {
                among(range);
                continue;
            }
            for &block in &chunk.blocks[..chunk.count as usize] {
                fill_codes(
                    &mut self.codes,
                    &mut self.stamps,
                    self.generation,
                    &self.sides,
                    block as usize,
                    x,
                    reach,
                );
            }
            // A triangle whose three corners lie beyond one side of the reach has a box that
            // misses it: the box test is made on the others only (the same candidates).
            let codes = &self.codes[..];
            for (t, tri) in triangles[range.clone()].iter().enumerate() {
                let [a, b, c] = tri.map(|v| codes.get(v as usize).copied().unwrap_or(0));
                if a & b & c == 0 {
                    among(range.start + t..range.start + t + 1);
                }
            }
        }
    }
}

/// The codes of block `block`'s nodes against `reach`, unless this call (`generation`) filled
/// them: bit 2k when the end position's coordinate k is above the reach, 2k + 1 when below. A block
/// whose box meets the reach (its `sides` all six) gets each node's own code; one whose box misses
/// it gets, for each node, the sides its box lies beyond (every node lies beyond them too: a code
/// with fewer bits than the node's own, which only keeps more triangles for the exact test).
fn fill_codes(
    codes: &mut [u8],
    stamps: &mut [u64],
    generation: u64,
    sides: &[u8],
    block: usize,
    x: &[Vec3],
    reach: &Aabb,
) {
    if stamps[block] == generation {
        return;
    }
    stamps[block] = generation;
    let nodes = block * BLOCK..((block + 1) * BLOCK).min(x.len());
    let side = sides.get(block).copied().unwrap_or(ALL_SIDES);
    if side != ALL_SIDES {
        codes[nodes].fill(!side & ALL_SIDES);
        return;
    }
    for i in nodes {
        let p = &x[i];
        let mut code = 0u8;
        for k in 0..3 {
            code |= u8::from(p[k] > reach.max[k]) << (2 * k);
            code |= u8::from(p[k] < reach.min[k]) << (2 * k + 1);
        }
        codes[i] = code;
    }
}

/// The radius of the circle through a triangle's corners at rest (their homologues; m): a ball of
/// that radius or more pressed on the triangle meets a corner before its centre reaches the
/// triangle's plane, a finer one may pass between the corners. Infinite for a degenerate triangle.
fn rest_circumradius(surface: &Surface, corners: [u32; 3]) -> f64 {
    let h = &surface.homologue_in_body;
    let [a, b, c] = corners.map(|v| h[v as usize]);
    let twice_area = (b - a).cross(&(c - a)).norm();
    let product = (b - a).norm() * (c - b).norm() * (a - c).norm();
    if twice_area > 0.0 {
        product / (2.0 * twice_area)
    } else {
        f64::INFINITY
    }
}

/// The closest points of capsule `part`'s axis and triangle (a, b, c): (on the axis, on the
/// triangle).
fn closest_pair(part: &CapsulePart, a: &Vec3, b: &Vec3, c: &Vec3) -> (Vec3, Vec3) {
    let (p, r) = (&part.a, &part.b);
    let normal = (b - a).cross(&(c - a));
    let (dp, dr) = ((p - a).dot(&normal), (r - a).dot(&normal));
    if (dp <= 0.0 && dr >= 0.0) || (dp >= 0.0 && dr <= 0.0) {
        let denominator = dp - dr;
        let crossing = if denominator.abs() > f64::MIN_POSITIVE {
            p + (r - p) * (dp / denominator)
        } else {
            *p
        };
        if within(&crossing, a, b, c, &normal) {
            return (crossing, crossing);
        }
    }
    let mut best = (*p, closest_point_on_triangle(p, a, b, c));
    let mut least = (best.1 - best.0).norm_squared();
    let mut consider = |on_axis: Vec3, on_triangle: Vec3| {
        let d = (on_triangle - on_axis).norm_squared();
        if d < least {
            least = d;
            best = (on_axis, on_triangle);
        }
    };
    consider(*r, closest_point_on_triangle(r, a, b, c));
    for (x, y) in [(a, b), (b, c), (c, a)] {
        let (s, t) = segment_segment_closest(p, r, x, y);
        consider(p + (r - p) * s, x + (y - x) * t);
    }
    best
}

/// Whether `p`, a point of triangle (a, b, c)'s plane (`normal` its (b − a) × (c − a)), lies
/// within the triangle (its sides included).
fn within(p: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3, normal: &Vec3) -> bool {
    (b - a).cross(&(p - a)).dot(normal) >= 0.0
        && (c - b).cross(&(p - b)).dot(normal) >= 0.0
        && (a - c).cross(&(p - c)).dot(normal) >= 0.0
}

/// Where an end of capsule `part`'s axis crossed triangle (a, b, c) (at its end-of-tick place)
/// from its outer side to its inner side over the tick (`start`: the part at the tick's start):
/// (the crossing, in the triangle; that end at the end of the tick).
fn swept_across(
    part: &CapsulePart,
    start: &CapsulePart,
    a: &Vec3,
    b: &Vec3,
    c: &Vec3,
) -> Option<(Vec3, Vec3)> {
    let normal = (b - a).cross(&(c - a));
    [(&start.a, &part.a), (&start.b, &part.b)]
        .into_iter()
        .find_map(|(from, to)| {
            let (d0, d1) = ((from - a).dot(&normal), (to - a).dot(&normal));
            if !(d0 > 0.0 && d1 < 0.0) {
                return None;
            }
            let crossing = from + (to - from) * (d0 / (d0 - d1));
            within(&crossing, a, b, c, &normal).then_some((crossing, *to))
        })
}

/// Barycentric weights of `p` (a point of the triangle), each at least 0, summing to 1.
fn weights(p: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> Option<[f64; 3]> {
    let w = crate::topology::refine::barycentric(p, a, b, c)?;
    let sum = w[0] + w[1] + w[2];
    (sum > 0.0).then(|| w.map(|x| x / sum))
}

/// The contact of capsule `part` (end of the tick; `start` at its start) with triangle `corners`,
/// when it cuts into the capsule from the triangle's outer side: (depth, direction, axis point,
/// contact point).
fn cut_into(
    surface: &Surface,
    corners: [u32; 3],
    part: &CapsulePart,
    start: &CapsulePart,
) -> Option<(f64, Vec3, Vec3, Vec3, bool)> {
    let x = &surface.next_position_in_world;
    let [a, b, c] = corners.map(|v| x[v as usize]);
    let margin = MARGIN * part.radius;
    let far = segment_triangle_distance(&part.a, &part.b, &a, &b, &c) >= part.radius + margin;
    let swept = if far {
        Some(swept_across(part, start, &a, &b, &c)?)
    } else {
        None
    };
    // The tool was on the triangle's outer side at the start of the tick (a tool that slipped
    // into the tissue meets the surface from within: it is not pushed back out through it).
    let x0 = &surface.position_in_world;
    let [a0, b0, c0] = corners.map(|v| x0[v as usize]);
    let outward0 = (b0 - a0).cross(&(c0 - a0));
    let axis0 = start.closest_on_segment(&((a0 + b0 + c0) / 3.0));
    if (axis0 - a0).dot(&outward0) <= 0.0 {
        return None;
    }
    let outward = (b - a).cross(&(c - a)).try_normalize(f64::MIN_POSITIVE)?;
    if let Some((crossing, end)) = swept {
        // Through the triangle within the tick (faster than its diameter): the triangle goes
        // in along its normal until it is a radius ahead of the end of the axis that crossed it.
        let depth = part.radius + (crossing - end).dot(&outward);
        return Some((depth, -outward, end, crossing, true));
    }
    let (depth, direction, axis_point, q) = closest_contact(part, &a, &b, &c, &outward);
    (depth > -margin).then_some((depth, direction, axis_point, q, false))
}

/// The point of triangle (a, b, c) deepest in capsule `part` — the closest pair of the axis and
/// the triangle (the axis's ends against the triangle, its sides against the axis; where the axis
/// crosses the triangle, that point, at distance 0) —, and the direction the triangle must go
/// (`outward` its unit normal): (depth, direction, axis point, contact point).
fn closest_contact(
    part: &CapsulePart,
    a: &Vec3,
    b: &Vec3,
    c: &Vec3,
    outward: &Vec3,
) -> (f64, Vec3, Vec3, Vec3) {
    let (axis_point, q) = closest_pair(part, a, b, c);
    let gap = q - axis_point;
    let distance = gap.norm();
    let direction = if gap.dot(outward) < 0.0 && distance > 1e-12 {
        gap / distance
    } else {
        // The axis reached the triangle or passed it: the triangle goes in, along its normal.
        -*outward
    };
    (part.radius - direction.dot(&gap), direction, axis_point, q)
}

/// Answers every tool's contacts with the triangles of `surface` between their nodes (see the
/// module's documentation). Tools whose bit is set in `skip` (bit k for tool k) are left out
/// (blades cutting the body). `blocks` are the node pass's (their boxes
/// hold every trajectory, or the call looks at every triangle); the nodes moved join them.
/// `rest_flows`: the body's rest shape changes without a new `version` (plasticity), so the
/// triangles' sizes at rest are not known from the last topology change and no tool is skipped
/// for being coarser than all of them. `friction`: the body's Coulomb coefficient against tools.
#[allow(clippy::too_many_arguments)]
pub fn press_faces(
    surface: &mut Surface,
    version: u64,
    rest_flows: bool,
    friction: f64,
    tools: &mut [Tool],
    skip: u64,
    dt: f64,
    mut blocks: Option<&mut NodeBlocks>,
    scratch: &mut ToolFaces,
) -> FaceCounts {
    let mut counts = FaceCounts::default();
    if surface.triangles.is_empty() {
        return counts;
    }
    scratch.rebuild_if_stale(surface, version);
    scratch.unmark();
    let n = surface.position_in_world.len();
    for (index, tool) in tools.iter_mut().enumerate() {
        if tool.part_count == 0 || (index < 64 && skip & (1 << index) != 0) {
            continue;
        }
        // A grasper's jaws take what they close on (nodes held between them); its shaft meets
        // the faces like any tool.
        let grasper = matches!(tool.shape, ToolShape::Grasper { .. });
        // A tool coarser than every triangle of the body (the paper's contact zone answers it)
        // costs no broad phase.
        let finest = (usize::from(grasper) * 2..tool.part_count)
            .map(|k| tool.parts_end[k].radius)
            .fold(f64::INFINITY, f64::min);
        if !rest_flows && finest * FINE >= scratch.largest_circumradius {
            continue;
        }
        // The parts' places at the end of the tick, and their axes' ends at its start: a part
        // faster than its diameter may have passed through a triangle (see `cut_into`).
        let mut reach = tool_reach(tool, MARGIN);
        for part in &tool.parts_start[..tool.part_count] {
            reach.include(&part.a);
            reach.include(&part.b);
        }
        let bounds = blocks.as_ref().and_then(|b| b.bounds(n));
        scratch.broad_phase(surface, &reach, bounds);
        counts.candidates += scratch.candidates.len() as u32;
        scratch.hits.clear();
        for &t in &scratch.candidates {
            let corners = surface.triangles[t as usize];
            let contact = corners.map(|v| surface.tool_contact[v as usize]);
            if contact.iter().any(|c| c.grasp.is_some()) {
                continue;
            }
            let free = contact.map(|c| c.tool == NO_TOOL);
            if !free.iter().any(|&f| f) {
                // Every corner held: a chord between held nodes, theirs to answer.
                continue;
            }
            // The deepest cut over the tool's parts finer than the triangle as meshed (see
            // `FINE`).
            let circumradius = rest_circumradius(surface, corners);
            let mut deepest: Option<(f64, Vec3, Vec3, Vec3, f64, Option<usize>)> = None;
            for k in 0..tool.part_count {
                let part = &tool.parts_end[k];
                if part.radius * FINE >= circumradius || (grasper && k < 2) {
                    continue;
                }
                if let Some((depth, direction, axis_point, q, swept)) =
                    cut_into(surface, corners, part, &tool.parts_start[k])
                    && deepest.is_none_or(|d| depth > d.0)
                {
                    let part_index = (!swept).then_some(k);
                    deepest = Some((depth, direction, axis_point, q, part.radius, part_index));
                }
            }
            let Some((_, direction, axis_point, q, radius, part)) = deepest else {
                continue;
            };
            let x = &surface.next_position_in_world;
            let [a, b, c] = corners.map(|v| x[v as usize]);
            let Some(w) = weights(&q, &a, &b, &c) else {
                continue;
            };
            if scratch.hits.len() == scratch.hits.capacity() {
                counts.dropped += 1;
                continue;
            }
            let inverse_mass =
                [0, 1, 2].map(|k| f64::from(free[k]) * surface.inverse_mass[corners[k] as usize]);
            // The multiplier as if the held corners moved too (their share is not given): a point
            // near a held corner would otherwise take all its correction from the free corners'
            // small weights, which throws them off the tool (and the contact flickers from tick to
            // tick); it closes over a few ticks instead, each free corner corrected as it would
            // be in a triangle whose corners all moved.
            let effective_inverse_mass: f64 = (0..3)
                .map(|k| w[k] * w[k] * surface.inverse_mass[corners[k] as usize])
                .sum();
            let moved = (0..3).any(|k| inverse_mass[k] * w[k] > 0.0);
            if !moved || effective_inverse_mass <= 0.0 || !effective_inverse_mass.is_finite() {
                continue;
            }
            let on_tool = tool.pose.to_tool(&(axis_point + direction * radius));
            scratch.hits.push(Hit {
                corners,
                w,
                inverse_mass,
                direction,
                part,
                axis_point,
                clearance: radius,
                effective_inverse_mass,
                tool_velocity: tool.point_velocity(&on_tool, dt),
                applied: 0.0,
                tangential: Vec3::zeros(),
                sliding: false,
            });
        }
        if scratch.hits.is_empty() {
            continue;
        }
        // Gauss–Seidel over the contacts, in triangle order: first the positions (a projection
        // out of the tool, which changes no velocity: a triangle found deep in the tool is not
        // thrown out of it), then the velocities (the contact point's approach to the tool along
        // the contact's direction taken away: an inelastic contact). Only the second is an impulse:
        // it is what the tool feels.
        for sweep in 0..SWEEPS {
            let mut moved = false;
            for hit in scratch.hits.iter_mut() {
                // The triangles moved in the last sweep (and turned, where their corners'
                // masses differ): the contact is taken again where it now is.
                if sweep > 0
                    && let Some(k) = hit.part
                {
                    hit.take_again(surface, &tool.parts_end[k]);
                }
                let x = &mut surface.next_position_in_world;
                let q = (0..3).fold(Vec3::zeros(), |q, k| {
                    q + x[hit.corners[k] as usize] * hit.w[k]
                });
                let violation = hit.clearance - hit.direction.dot(&(q - hit.axis_point));
                if violation <= 0.0 {
                    continue;
                }
                let lambda = violation / hit.effective_inverse_mass;
                for k in 0..3 {
                    x[hit.corners[k] as usize] +=
                        hit.direction * (lambda * hit.w[k] * hit.inverse_mass[k]);
                }
                moved = true;
            }
            if !moved {
                break;
            }
        }
        for _ in 0..SWEEPS {
            let mut changed = false;
            for hit in scratch.hits.iter_mut() {
                let v = &mut surface.velocity_in_world;
                let at = (0..3).fold(Vec3::zeros(), |q, k| {
                    q + v[hit.corners[k] as usize] * hit.w[k]
                });
                // The gap left after the projection may be closed within the tick, no more.
                let x = &surface.next_position_in_world;
                let q = (0..3).fold(Vec3::zeros(), |q, k| {
                    q + x[hit.corners[k] as usize] * hit.w[k]
                });
                let gap = (hit.direction.dot(&(q - hit.axis_point)) - hit.clearance).max(0.0);
                let relative = at - hit.tool_velocity;
                let approach = -hit.direction.dot(&relative) - gap / dt;
                let mut impulse = Vec3::zeros();
                if approach > 0.0 {
                    let mu = approach / hit.effective_inverse_mass;
                    impulse += hit.direction * mu;
                    hit.applied += mu;
                }
                // Coulomb friction: the impulse that would stop the point's slip on the tool,
                // added to what this contact gave before, kept within the cone of its normal
                // impulse (the slip is across `direction`, which the normal impulse leaves).
                if friction > 0.0 && hit.applied > 0.0 {
                    let slip = relative - hit.direction * hit.direction.dot(&relative);
                    let wanted = hit.tangential - slip / hit.effective_inverse_mass;
                    let cone = friction * hit.applied;
                    let size = wanted.norm();
                    hit.sliding = size > cone;
                    let kept = if hit.sliding {
                        wanted * (cone / size)
                    } else {
                        wanted
                    };
                    impulse += kept - hit.tangential;
                    hit.tangential = kept;
                }
                if impulse == Vec3::zeros() {
                    continue;
                }
                for k in 0..3 {
                    v[hit.corners[k] as usize] += impulse * (hit.w[k] * hit.inverse_mass[k]);
                }
                changed = true;
            }
            if !changed {
                break;
            }
        }
        // The feedback: the opposite of the impulse each contact gave its triangle.
        let x = &surface.next_position_in_world;
        for hit in &scratch.hits {
            if hit.applied <= 0.0 {
                continue;
            }
            // Σ m_k Δv_k = J Σ_k w_k (over the corners it moves), J the impulse per unit weight.
            let moved_weight: f64 = (0..3)
                .filter(|&k| hit.inverse_mass[k] > 0.0)
                .map(|k| hit.w[k])
                .sum();
            let normal = hit.direction * (-hit.applied * moved_weight / dt);
            let tangential = hit.tangential * (-moved_weight / dt);
            let force = normal + tangential;
            let at = (0..3).fold(Vec3::zeros(), |q, k| {
                q + x[hit.corners[k] as usize] * hit.w[k]
            });
            let fb = &mut tool.feedback;
            fb.force_in_world += force;
            fb.torque_in_world += (at - tool.pose.position_in_world).cross(&force);
            fb.contacts += 1;
            fb.faces += 1;
            fb.normal_force += normal.norm();
            fb.friction_force += tangential.norm();
            fb.sliding += u32::from(hit.sliding);
            counts.contacts += 1;
        }
        for hit in &scratch.hits {
            for &v in &hit.corners {
                if let Some(p) = scratch.pressed_by.get_mut(v as usize)
                    && scratch.marked.len() < scratch.marked.capacity()
                {
                    *p = index as u32 + 1;
                    scratch.marked.push(v);
                }
            }
        }
        if let Some(blocks) = blocks.as_mut() {
            for hit in &scratch.hits {
                for k in 0..3 {
                    if hit.inverse_mass[k] > 0.0 {
                        blocks.include(surface, hit.corners[k] as usize);
                    }
                }
            }
        }
    }
    counts
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The broad phase with the nodes' codes keeps exactly the triangles the box test over every
    /// triangle keeps, in the same order: on a crumpled sphere, for reaches of every size.
    #[test]
    fn the_codes_skip_no_candidate() {
        let text =
            "[[body]]\nname = \"b\"\nmesh = { icosphere = { radius = 0.05, subdivisions = 4 } }\n";
        let scene =
            crate::scene::parse_scene(text, "test.toml", std::path::Path::new(".")).expect("scene");
        let mut world = crate::world::World::from_scene(&scene);
        let surface = &mut world.bodies[0].surface;
        let mut state: u64 = 0x9e37_79b9_7f4a_7c15;
        let mut unit = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        // Every node moved by up to 3 mm each way over the tick.
        for i in 0..surface.position_in_world.len() {
            let shift = Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * 0.006;
            surface.next_position_in_world[i] = surface.position_in_world[i] + shift;
        }
        let n = surface.position_in_world.len();
        let mut blocks = NodeBlocks::with_capacity(n);
        let fresh = blocks.start(n);
        for i in 0..n {
            fresh[i / BLOCK]
                .bounds
                .include(&surface.position_in_world[i]);
            fresh[i / BLOCK]
                .bounds
                .include(&surface.next_position_in_world[i]);
        }
        let mut coded = ToolFaces::with_capacity((n, surface.triangles.len()));
        coded.rebuild_if_stale(surface, 0);
        let mut plain = ToolFaces::default();
        let (mut kept, mut tested) = (0, 0);
        for k in 0..400 {
            let x = &surface.next_position_in_world;
            let centre = x[(unit() * n as f64) as usize % n];
            let half = 1e-4 * 10f64.powf(unit() * 3.0) * (1 + k % 3) as f64;
            let mut reach = Aabb::of_pair(&centre, &centre);
            reach.inflate(half);
            coded.broad_phase(surface, &reach, blocks.bounds(n));
            plain.broad_phase(surface, &reach, None);
            assert_eq!(
                coded.candidates.as_slice(),
                plain.candidates.as_slice(),
                "reach {k}"
            );
            kept += coded.candidates.len();
            tested += 1;
        }
        assert!(
            kept > tested,
            "the reaches met triangles ({kept} in {tested})"
        );
    }

    /// A probe pressed 1.2 mm into the triangles round a corner fifty times lighter than
    /// the others: pushed out at one point each, the triangles turn about their heavy corners;
    /// taken again in the later sweeps, their contacts leave none of them in the probe.
    #[test]
    fn triangles_round_a_light_corner_leave_the_probe() {
        let body =
            "[[body]]\nname = \"b\"\nmesh = { icosphere = { radius = 0.05, subdivisions = 1 } }\n";
        let world_of = |text: &str| {
            let scene = crate::scene::parse_scene(text, "test.toml", std::path::Path::new("."))
                .expect("scene");
            crate::world::World::from_scene(&scene)
        };
        let light = 0;
        // The probe's centre 3 mm out along the corner's normal and 3 mm aside: the corner is
        // 0.8 mm in it, and the triangles round it cut in.
        let corner = world_of(body).bodies[0].surface.position_in_world[light];
        let normal = corner.normalize();
        let aside = normal.cross(&Vec3::x()).normalize();
        let centre = corner + normal * 0.003 + aside * 0.003;
        let mut world = world_of(&format!(
            "{body}[[tool]]\nname = \"probe\"\nshape = {{ sphere = {{ radius = 0.005 }} }}\n\
             script = [ {{ t = 0.0, position = [{:?}, {:?}, {:?}] }} ]\n",
            centre.x, centre.y, centre.z
        ));
        let dt = world.params.dt;
        let surface = &mut world.bodies[0].surface;
        surface.mass[light] /= 50.0;
        surface.inverse_mass[light] *= 50.0;
        let tool = &mut world.tools[0];
        tool.begin_tick(0.0);
        tool.begin_tick(0.0);
        let part = tool.parts_end[0];
        let deepest = |surface: &Surface| {
            let x = &surface.next_position_in_world;
            surface
                .triangles
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|v| x[v as usize]);
                    segment_triangle_distance(&part.a, &part.b, &a, &b, &c) - part.radius
                })
                .fold(f64::INFINITY, f64::min)
        };
        let before = deepest(surface);
        let mut faces = ToolFaces::with_capacity((surface.mass.len(), surface.triangles.len()));
        let counts = press_faces(
            surface,
            0,
            false,
            0.0,
            &mut world.tools,
            0,
            dt,
            None,
            &mut faces,
        );
        let after = deepest(&world.bodies[0].surface);
        println!("{counts:?}: deepest cut {before:.3e} m before, {after:.3e} m after");
        assert!(before < -1e-3, "the probe does not cut in: {before}");
        assert!(after > -1e-6, "a triangle left {after} m in the probe");
    }
}
