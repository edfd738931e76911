//! The force kernel: the edge springs of a body in batches of [`LANES`] edges whose endpoints are all
//! distinct, so that one batch goes through one set of SIMD lanes and its scatter needs no ordering;
//! then one pass over the nodes that adds gravity, air, the links and their reactions, measures the
//! body's energy and (for an explicit body) integrates the free nodes.
//!
//! The batches are a greedy colouring of the edges, patched where the edges changed when the body's
//! topology changes (coloured again only after a transection or when the patches leave too many
//! empty lanes), in scratch reserved for the body's limits (no allocation on the tick). The edge forces accumulate per
//! component (structure of arrays, `fx`, `fy`, `fz`), batch after batch in a fixed order; within a
//! batch the lanes touch different nodes. Every lane does the same IEEE operations (add, subtract,
//! multiply, divide, square root, no fused multiply-add) in the same order on every path — AVX on an
//! x86_64 machine that has it, a scalar loop elsewhere or when asked — so the result bits do not
//! depend on the path taken (`tests/kernel.rs` checks them against each other).

use crate::Vec3;
use crate::body::{Body, Edges, TopologyChanges};
use crate::collision::blocks::{BLOCK, NodeBlock, NodeBlocks};
use crate::dynamics::helper::Helper;

/// Edges per batch (one AVX register of `f64`).
pub const LANES: usize = 4;

/// Bodies of at least this many nodes run their edge pass and node pass as units that write
/// disjoint memory, combined in a fixed order: the world's helper thread
/// ([`crate::dynamics::helper`]) can take some, and the bits do not depend on which it took.
pub const SPLIT_NODES: usize = 4096;

/// The node where a split body's node pass cuts (a multiple of the node blocks' size).
fn node_cut(n: usize) -> usize {
    n / 2 / BLOCK * BLOCK
}

/// The edges in batches of [`LANES`] with distinct endpoints, each batch's data side by side. A lane
/// with no edge has node 0 at both ends (no length: no force, no energy), so every batch is full.
#[derive(Clone, Debug, Default)]
pub struct EdgeBatches {
    /// Ends a and b of each lane's edge.
    ends_of: Vec<[[u32; LANES]; 2]>,
    /// Rest length of each lane's edge (m; zero in empty lanes).
    rest: Vec<[f64; LANES]>,
    /// Stiffness and damping of each lane's edge, when they differ between edges (empty otherwise).
    stiffness_damping: Vec<[[f64; LANES]; 2]>,
    /// The stiffness and damping of every edge, when they are all the same (the common case: one
    /// load fewer per batch).
    uniform: Option<(f64, f64)>,
    /// Edge index of each lane (`u32::MAX`: empty).
    edge: Vec<[u32; LANES]>,
    // Colouring scratch: the ends each batch holds, and the batches with room, oldest first.
    ends: Vec<[u32; 2 * LANES]>,
    /// Per node, the open slots (bits) whose batch holds it.
    in_open: Vec<u16>,
    /// The edges as the lanes hold them (ends, and the bits of rest length, stiffness and damping):
    /// what [`EdgeBatches::patch`] compares a changed body's edges with.
    held: HeldEdges,
    /// Lane of each edge (batch × LANES + lane; `u32::MAX`: in no lane).
    lane_of: Vec<u32>,
    /// Empty lanes (batch × LANES + lane), the most recent last.
    holes: Vec<u32>,
    /// Edges a patch places again (changed or new).
    pending: Vec<u32>,
    /// Nodes of the body the batches were made for.
    nodes: usize,
    /// Most edges the scratch has room for.
    edge_capacity: usize,
    /// Topology changes followed by a patch, and full colourings, since the start.
    patched: u64,
    rebuilt: u64,
}

/// A copy of a body's edges, field by field (compared bit for bit).
#[derive(Clone, Debug, Default)]
struct HeldEdges {
    a: Vec<u32>,
    b: Vec<u32>,
    rest: Vec<f64>,
    stiffness: Vec<f64>,
    damping: Vec<f64>,
}

impl HeldEdges {
    fn with_capacity(edges: usize) -> Self {
        Self {
            a: Vec::with_capacity(edges),
            b: Vec::with_capacity(edges),
            rest: Vec::with_capacity(edges),
            stiffness: Vec::with_capacity(edges),
            damping: Vec::with_capacity(edges),
        }
    }

    fn len(&self) -> usize {
        self.a.len()
    }

    /// Holds `edges[from..]` after the first `from`.
    fn extend(&mut self, edges: &Edges, from: usize) {
        self.a.extend_from_slice(&edges.a[from..]);
        self.b.extend_from_slice(&edges.b[from..]);
        self.rest.extend_from_slice(&edges.rest_length[from..]);
        self.stiffness.extend_from_slice(&edges.stiffness[from..]);
        self.damping.extend_from_slice(&edges.damping[from..]);
    }

    /// Holds `edges` (a copy of each array).
    fn copy(&mut self, edges: &Edges) {
        self.a.clear();
        self.b.clear();
        self.rest.clear();
        self.stiffness.clear();
        self.damping.clear();
        self.extend(edges, 0);
    }

    fn set(&mut self, edges: &Edges, k: usize) {
        self.a[k] = edges.a[k];
        self.b[k] = edges.b[k];
        self.rest[k] = edges.rest_length[k];
        self.stiffness[k] = edges.stiffness[k];
        self.damping[k] = edges.damping[k];
    }

    /// Whether edge `k` is as held (no branch: the comparison of all the edges vectorises).
    #[inline(always)]
    fn same(&self, edges: &Edges, k: usize) -> bool {
        let ends = u64::from(self.a[k] ^ edges.a[k]) | u64::from(self.b[k] ^ edges.b[k]);
        let values = (self.rest[k].to_bits() ^ edges.rest_length[k].to_bits())
            | (self.stiffness[k].to_bits() ^ edges.stiffness[k].to_bits())
            | (self.damping[k].to_bits() ^ edges.damping[k].to_bits());
        ends | values == 0
    }
}

/// Empty lanes a patch looks into for an edge before it opens a new batch (the most recent first).
const HOLE_TRIES: usize = 32;

/// Batches with room the colouring keeps looking into (more pack tighter and cost more; at most 16,
/// the bits of a node's slot mask).
pub const OPEN_BATCHES: usize = 16;

/// The slot of least age among the bits of `slots`.
fn oldest(slots: u16, age: &[u64; OPEN_BATCHES]) -> usize {
    let mut best = usize::MAX;
    let mut bits = slots;
    while bits != 0 {
        let slot = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        if best == usize::MAX || age[slot] < age[best] {
            best = slot;
        }
    }
    best
}

impl EdgeBatches {
    /// Scratch for a body of at most `nodes` nodes and `edges` edges.
    pub fn with_capacity(nodes: usize, edges: usize) -> Self {
        Self {
            ends_of: Vec::with_capacity(edges),
            rest: Vec::with_capacity(edges),
            stiffness_damping: Vec::with_capacity(edges),
            uniform: None,
            edge: Vec::with_capacity(edges),
            ends: Vec::with_capacity(edges),
            in_open: Vec::with_capacity(nodes),
            held: HeldEdges::with_capacity(edges),
            lane_of: Vec::with_capacity(edges),
            holes: Vec::with_capacity(edges * LANES),
            pending: Vec::with_capacity(edges),
            nodes: 0,
            edge_capacity: edges,
            patched: 0,
            rebuilt: 0,
        }
    }

    /// Number of batches.
    pub fn len(&self) -> usize {
        self.edge.len()
    }

    /// True when there is no batch.
    pub fn is_empty(&self) -> bool {
        self.edge.is_empty()
    }

    /// Lanes that hold an edge, over all lanes (1 when every batch is full).
    pub fn occupancy(&self) -> f64 {
        if self.edge.is_empty() {
            return 1.0;
        }
        let used = self
            .edge
            .iter()
            .flatten()
            .filter(|&&e| e != u32::MAX)
            .count();
        used as f64 / (self.edge.len() * LANES) as f64
    }

    /// The edge index of each lane of each batch (`u32::MAX` for an empty lane).
    pub fn lanes(&self) -> &[[u32; LANES]] {
        &self.edge
    }

    /// How the batches followed the body's edges since the start: (patches, full colourings).
    pub fn history(&self) -> (u64, u64) {
        (self.patched, self.rebuilt)
    }

    /// Colours `edges` of a body of `nodes` nodes: each edge, in index order, goes to the oldest of
    /// the last [`OPEN_BATCHES`] batches with room that holds neither of its ends, or starts a new
    /// batch. Linear in the edges; allocation-free within the capacity given.
    pub fn rebuild(&mut self, edges: &Edges, nodes: usize) {
        let count = edges.len();
        self.edge.clear();
        self.ends.clear();
        self.in_open.clear();
        self.in_open.resize(nodes, 0);
        // The open batches sit in 16 slots: each slot's batch and age (creation order), and a mask
        // of the slots in use; a node's mask says which open slots hold it, so that the slots that
        // can take an edge are found with two loads and a few bit operations.
        let mut slot_batch = [0usize; OPEN_BATCHES];
        let mut slot_age = [0u64; OPEN_BATCHES];
        let mut open: u16 = 0;
        let mut age = 0u64;
        for k in 0..count {
            let (a, b) = (edges.a[k], edges.b[k]);
            if a as usize >= nodes || b as usize >= nodes || a == b {
                continue;
            }
            let fitting = open & !(self.in_open[a as usize] | self.in_open[b as usize]);
            let slot = if fitting != 0 {
                oldest(fitting, &slot_age)
            } else {
                if open == u16::MAX {
                    // The oldest open batch stays partly empty.
                    let evicted = oldest(open, &slot_age);
                    self.close(slot_batch[evicted], evicted);
                    open &= !(1 << evicted);
                }
                let free = (!open).trailing_zeros() as usize;
                self.edge.push([u32::MAX; LANES]);
                self.ends.push([u32::MAX; 2 * LANES]);
                slot_batch[free] = self.edge.len() - 1;
                slot_age[free] = age;
                age += 1;
                open |= 1 << free;
                free
            };
            let batch = slot_batch[slot];
            let lane = self.edge[batch]
                .iter()
                .position(|&e| e == u32::MAX)
                .unwrap_or(0);
            self.edge[batch][lane] = k as u32;
            self.ends[batch][2 * lane] = a;
            self.ends[batch][2 * lane + 1] = b;
            self.in_open[a as usize] |= 1 << slot;
            self.in_open[b as usize] |= 1 << slot;
            if lane + 1 == LANES {
                self.close(batch, slot);
                open &= !(1 << slot);
            }
        }
        self.ends_of.clear();
        self.rest.clear();
        self.stiffness_damping.clear();
        let same = |x: &[f64]| {
            x.first()
                .is_some_and(|first| x.iter().all(|y| y.to_bits() == first.to_bits()))
        };
        self.uniform = (same(&edges.stiffness) && same(&edges.damping))
            .then(|| (edges.stiffness[0], edges.damping[0]));
        for batch in &self.edge {
            let mut ends = [[0u32; LANES]; 2];
            let mut rest = [0.0; LANES];
            let mut stiffness_damping = [[0.0; LANES]; 2];
            for (lane, &k) in batch.iter().enumerate() {
                if k == u32::MAX {
                    continue;
                }
                let k = k as usize;
                ends[0][lane] = edges.a[k];
                ends[1][lane] = edges.b[k];
                rest[lane] = edges.rest_length[k];
                stiffness_damping[0][lane] = edges.stiffness[k];
                stiffness_damping[1][lane] = edges.damping[k];
            }
            self.ends_of.push(ends);
            self.rest.push(rest);
            if self.uniform.is_none() {
                self.stiffness_damping.push(stiffness_damping);
            }
        }
        // What a patch starts from: the edges as held, each edge's lane, the empty lanes.
        self.held.copy(edges);
        self.lane_of.clear();
        self.lane_of.resize(count, u32::MAX);
        self.holes.clear();
        for (batch, lanes) in self.edge.iter().enumerate() {
            for (lane, &k) in lanes.iter().enumerate() {
                let slot = (batch * LANES + lane) as u32;
                if k == u32::MAX {
                    self.holes.push(slot);
                } else {
                    self.lane_of[k as usize] = slot;
                }
            }
        }
        self.nodes = nodes;
        self.rebuilt += 1;
    }

    /// Follows a change of the body's edges where it happened, instead of colouring them all again:
    /// an edge whose ends, rest length, stiffness or damping changed leaves its lane, and it and the
    /// new edges go into empty lanes of batches that hold neither of their ends (the most recent
    /// [`HOLE_TRIES`] empty lanes), or into new batches. A cut, a subdivision or a tear changes a
    /// few dozen edges: the patch costs a comparison of the edges with the held copy and that many
    /// placements. Returns false, leaving the batches to be built again, when it cannot follow
    /// (edges or nodes removed, no room for a batch) or when empty lanes would be more than an
    /// eighth of the edges. The layout then differs from a fresh colouring's, so the order in which
    /// forces add up at a node does too: it depends on the history of the topology changes, which
    /// a replay repeats, and on nothing else.
    pub fn patch(&mut self, edges: &Edges, nodes: usize) -> bool {
        self.patch_listed(edges, nodes, None)
    }

    /// [`EdgeBatches::patch`] told which springs changed: `listed` (in increasing order) holds
    /// every held spring whose ends or values changed (and may hold others), so only those are
    /// compared with the held copy — no pass over the springs. The same layout as the full
    /// comparison gives.
    pub fn patch_listed(&mut self, edges: &Edges, nodes: usize, listed: Option<&[u32]>) -> bool {
        let held = self.held.len();
        let count = edges.len();
        if count < held || nodes < self.nodes || count > self.edge_capacity {
            return false;
        }
        self.pending.clear();
        let all = 0..held as u32;
        let candidates: &mut dyn Iterator<Item = u32> = match listed {
            Some(listed) => &mut listed.iter().copied().take_while(|&k| (k as usize) < held),
            None => &mut all.into_iter(),
        };
        for k in candidates {
            let k = k as usize;
            if self.held.same(edges, k) {
                continue;
            }
            self.held.set(edges, k);
            let slot = self.lane_of[k];
            if slot != u32::MAX {
                self.empty(slot);
                self.lane_of[k] = u32::MAX;
            }
            self.pending.push(k as u32);
        }
        self.held.extend(edges, held);
        for k in held..count {
            self.lane_of.push(u32::MAX);
            self.pending.push(k as u32);
        }
        // A change of stiffness or damping (a spring cut in two) ends a uniform body's shortcut.
        if let Some((k, c)) = self.uniform
            && self.pending.iter().any(|&e| {
                edges.stiffness[e as usize].to_bits() != k.to_bits()
                    || edges.damping[e as usize].to_bits() != c.to_bits()
            })
        {
            // Every edge still in a lane is unchanged, so it has the uniform values.
            self.uniform = None;
            self.stiffness_damping.clear();
            for lanes in &self.edge {
                let used = lanes.map(|e| e != u32::MAX);
                self.stiffness_damping.push([
                    used.map(|u| if u { k } else { 0.0 }),
                    used.map(|u| if u { c } else { 0.0 }),
                ]);
            }
        }
        for i in 0..self.pending.len() {
            let k = self.pending[i] as usize;
            let (a, b) = (edges.a[k], edges.b[k]);
            if a as usize >= nodes || b as usize >= nodes || a == b {
                continue;
            }
            let tries = self.holes.len().min(HOLE_TRIES);
            let found = (1..=tries)
                .map(|back| self.holes.len() - back)
                .find(|&h| self.takes(self.holes[h] as usize / LANES, a, b));
            let slot = match found {
                Some(h) => self.holes.swap_remove(h),
                None => {
                    if self.edge.len() >= self.edge_capacity {
                        return false;
                    }
                    let batch = self.edge.len();
                    self.edge.push([u32::MAX; LANES]);
                    self.ends_of.push([[0; LANES]; 2]);
                    self.rest.push([0.0; LANES]);
                    if self.uniform.is_none() {
                        self.stiffness_damping.push([[0.0; LANES]; 2]);
                    }
                    for lane in (1..LANES).rev() {
                        self.holes.push((batch * LANES + lane) as u32);
                    }
                    (batch * LANES) as u32
                }
            };
            let (batch, lane) = (slot as usize / LANES, slot as usize % LANES);
            self.edge[batch][lane] = k as u32;
            self.ends_of[batch][0][lane] = a;
            self.ends_of[batch][1][lane] = b;
            self.rest[batch][lane] = edges.rest_length[k];
            if self.uniform.is_none() {
                self.stiffness_damping[batch][0][lane] = edges.stiffness[k];
                self.stiffness_damping[batch][1][lane] = edges.damping[k];
            }
            self.lane_of[k] = slot;
        }
        self.nodes = nodes;
        let followed = self.holes.len() * 8 <= count;
        self.patched += u64::from(followed);
        followed
    }

    /// Empties lane `slot` (node 0 at both ends, no length) and keeps it as a hole.
    fn empty(&mut self, slot: u32) {
        let (batch, lane) = (slot as usize / LANES, slot as usize % LANES);
        self.edge[batch][lane] = u32::MAX;
        self.ends_of[batch][0][lane] = 0;
        self.ends_of[batch][1][lane] = 0;
        self.rest[batch][lane] = 0.0;
        if self.uniform.is_none() {
            self.stiffness_damping[batch][0][lane] = 0.0;
            self.stiffness_damping[batch][1][lane] = 0.0;
        }
        self.holes.push(slot);
    }

    /// Whether batch `batch` holds neither `a` nor `b` in its occupied lanes.
    fn takes(&self, batch: usize, a: u32, b: u32) -> bool {
        let [ends_a, ends_b] = &self.ends_of[batch];
        (0..LANES).all(|lane| {
            self.edge[batch][lane] == u32::MAX
                || (ends_a[lane] != a
                    && ends_a[lane] != b
                    && ends_b[lane] != a
                    && ends_b[lane] != b)
        })
    }

    /// Takes the nodes of `batch` out of open slot `slot`.
    fn close(&mut self, batch: usize, slot: usize) {
        for &node in &self.ends[batch] {
            if node != u32::MAX {
                self.in_open[node as usize] &= !(1 << slot);
            }
        }
    }

    /// Stiffness and damping of the lanes of batch `i`.
    #[inline(always)]
    fn stiffness_damping_of(&self, i: usize) -> [[f64; LANES]; 2] {
        match self.uniform {
            Some((k, c)) => [[k; LANES], [c; LANES]],
            None => self.stiffness_damping[i],
        }
    }
}

/// What the node pass does besides the forces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NodePass {
    /// Forces only (the solver integrates).
    Forces,
    /// Forces, then semi-implicit Euler for every node (no node is held).
    IntegrateAll,
    /// Forces, then semi-implicit Euler for the nodes no tool holds.
    IntegrateFree,
}

/// A node's edge-force accumulator: x, y, z and a zero (N, world frame), aligned to 32 bytes so
/// that the one AVX load and store of a lane's force never straddle two cache lines (a node in
/// two of an unaligned array would).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(32))]
struct Accumulator([f64; 4]);

impl std::ops::Deref for Accumulator {
    type Target = [f64; 4];
    fn deref(&self) -> &[f64; 4] {
        &self.0
    }
}

impl std::ops::DerefMut for Accumulator {
    fn deref_mut(&mut self) -> &mut [f64; 4] {
        &mut self.0
    }
}

/// Per-body scratch of the force stage.
#[derive(Clone, Debug)]
pub struct ForceKernel {
    batches: EdgeBatches,
    /// Edge forces per node: one aligned 32-byte vector a node, so that a lane adds its force to
    /// an end with one vector operation.
    force: Vec<Accumulator>,
    /// The accumulators of the batches across a split body's node cut (see [`SPLIT_NODES`]): zero
    /// but between the edge pass's units and their addition to `force`.
    force_b: Vec<Accumulator>,
    /// A split body's batches by the side of the node cut their ends lie on.
    split: SplitBatches,
    /// Every accumulator of `force` is zero: the node pass clears each one after reading it (the
    /// line is in cache then), so that the next edge pass needs no clearing pass of its own.
    force_clear: bool,
    /// What the last node pass learnt of each block of nodes, when it integrated every node on
    /// the SIMD path (the world keeps them true as the later stages move nodes).
    pub blocks: NodeBlocks,
    /// The body state the batches were built for: (topology version, nodes, edges).
    built_for: Option<(u64, usize, usize)>,
    /// Use the SIMD path when the machine has one.
    simd: bool,
    /// Patches made from a record of the changed springs (no comparison of them all).
    pub listed_patches: u64,
    /// Total mechanical energy of the body at the start of the last step (J): kinetic, elastic
    /// (edges and links) and gravitational, as [`crate::dynamics::guard::body_energy`] defines it.
    pub energy: f64,
    /// Elastic energy of the edge springs at the start of the last step (J).
    pub edge_energy: f64,
    /// The placement of the body frame the last node pass put the homologues with (rotation,
    /// origin): `homologue_in_world = rotation · homologue_in_body + origin`.
    pub homologue_frame: Option<(nalgebra::Matrix3<f64>, Vec3)>,
}

impl ForceKernel {
    /// Scratch for `body` within its limits (its current size when it has none).
    pub fn new(body: &Body) -> Self {
        let (nodes, edges) = if body.limits.nodes == usize::MAX {
            (body.node_count(), body.edges.len())
        } else {
            (body.limits.nodes, body.limits.edges)
        };
        Self {
            batches: EdgeBatches::with_capacity(nodes, edges),
            force: Vec::with_capacity(nodes),
            force_b: Vec::with_capacity(if nodes >= SPLIT_NODES { nodes } else { 0 }),
            split: SplitBatches::with_capacity(if nodes >= SPLIT_NODES {
                (nodes, edges)
            } else {
                (0, 0)
            }),
            force_clear: false,
            blocks: NodeBlocks::with_capacity(nodes),
            built_for: None,
            simd: true,
            listed_patches: 0,
            energy: 0.0,
            edge_energy: 0.0,
            homologue_frame: None,
        }
    }

    /// Chooses the SIMD path (when the machine has it) or the scalar one; both give the same bits.
    pub fn set_simd(&mut self, simd: bool) {
        self.simd = simd;
    }

    /// True when the next pass will take the SIMD path.
    pub fn uses_simd(&self) -> bool {
        self.simd && simd_available()
    }

    /// The batches (rebuilt on the next pass if the body's topology changed since).
    pub fn batches(&self) -> &EdgeBatches {
        &self.batches
    }

    /// Forgets the batches (the next pass rebuilds them) and the node blocks (the body changed).
    pub fn invalidate(&mut self) {
        self.built_for = None;
        self.blocks.drop_all();
    }

    /// Rebuilds the batches for `body` if its topology changed since they were built.
    pub fn refresh(&mut self, body: &Body) {
        self.refresh_with(body, None);
    }

    /// [`ForceKernel::refresh`] with the record of the springs that changed, when there is one:
    /// if it covers every change since the batches were made, only its springs are compared.
    pub fn refresh_with(&mut self, body: &Body, changes: Option<&TopologyChanges>) {
        let stamp = (body.topology_version, body.node_count(), body.edges.len());
        if self.built_for != Some(stamp) {
            let listed = match (self.built_for, changes) {
                (Some((version, ..)), Some(changes))
                    if changes.covers(version, body.topology_version) =>
                {
                    Some(changes.edges())
                }
                _ => None,
            };
            self.listed_patches += u64::from(listed.is_some());
            let patched = self.built_for.is_some()
                && self
                    .batches
                    .patch_listed(&body.edges, body.node_count(), listed);
            if !patched {
                self.batches.rebuild(&body.edges, body.node_count());
            }
            self.built_for = Some(stamp);
        }
    }

    /// The edge pass: spring forces into the accumulators (cleared first) and the springs' energy.
    pub fn edge_forces(&mut self, body: &Body) {
        self.edge_forces_with(body, None);
    }

    /// [`ForceKernel::edge_forces`], a split body's units (see [`SPLIT_NODES`]) shared with
    /// `helper`. Same bits with or without it.
    pub fn edge_forces_with(&mut self, body: &Body, helper: Option<&Helper>) {
        self.refresh(body);
        let n = body.node_count();
        if !self.force_clear || self.force.len() != n {
            self.force.clear();
            self.force.resize(n, Accumulator::default());
        }
        self.force_clear = false;
        self.blocks.drop_all();
        let split = n >= SPLIT_NODES;
        let x = &body.surface.position_in_world[..];
        let v = &body.surface.velocity_in_world[..];
        let simd = self.uses_simd();
        let all = self.batches.ends_of.len();
        if !split {
            let mut energy = [0.0; LANES];
            let f = self.force.as_mut_ptr().cast();
            // SAFETY: `f` holds the body's nodes (resized above), every end of the batches.
            unsafe { edge_part(&self.batches, 0..all, x, v, f, &mut energy, simd) };
            self.edge_energy = lane_sum(&energy);
            return;
        }
        if self.force_b.len() != n {
            self.force_b.clear();
            self.force_b.resize(n, Accumulator::default());
        }
        let cut = node_cut(n);
        let stamp = self.built_for.map(|(version, ..)| (version, n, all, cut));
        // `refresh` above set `built_for`: the stamp is always known here.
        if self.split.made_for != stamp {
            self.split.classify(&self.batches, n, cut);
            self.split.made_for = stamp;
        }
        // Three units: the batches wholly below the node cut and wholly above it, into the
        // accumulators (their nodes differ), and the batches across it, into the second ones.
        let mut energies = [[0.0; LANES]; 3];
        let force = Shared(self.force.as_mut_ptr().cast::<[f64; 4]>());
        let force_b = Shared(self.force_b.as_mut_ptr().cast::<[f64; 4]>());
        let energy = Shared(energies.as_mut_ptr());
        let (batches, units) = (&self.batches, &self.split.units);
        run_units(helper, 3, &|u| {
            let target = if u == 2 { force_b.get() } else { force.get() };
            let list = units[u].iter().map(|&i| i as usize);
            // SAFETY: each unit runs once (`run_units`) and writes its own energy lanes; units 0 and
            // 1 write only the accumulators of nodes below and from the cut (every end of their
            // batches is), unit 2 only the second accumulators; both arrays hold every node.
            unsafe { edge_part(batches, list, x, v, target, &mut *energy.get().add(u), simd) };
        });
        // The second accumulators into the first, at the nodes the crossing batches touch (the
        // others are zero), in node order; they are left cleared.
        for &i in &self.split.crossed {
            let (f, g) = (&mut self.force[i as usize], &mut self.force_b[i as usize]);
            for d in 0..3 {
                f[d] += g[d];
            }
            *g = Accumulator::default();
        }
        let energy: [f64; LANES] =
            std::array::from_fn(|l| (energies[0][l] + energies[1][l]) + energies[2][l]);
        self.edge_energy = lane_sum(&energy);
    }

    /// Adds a force from outside the body (N, world frame) to node `i`'s accumulator.
    pub fn add_external(&mut self, i: usize, force: &Vec3) {
        self.force_clear = false;
        let f = &mut self.force[i];
        f[0] += force.x;
        f[1] += force.y;
        f[2] += force.z;
    }

    /// The node pass after [`ForceKernel::edge_forces`]: every node's force is its springs' plus
    /// m g − γ v plus its link k (h − x) + c (ḣ − v), written to `force_in_world`; the rigid component
    /// gets gravity, air and the links' reactions; the homologues' world positions are refreshed; the
    /// body's energy at the start of the step is measured; and, as `pass` asks, nodes are integrated
    /// (v += Δt F/m, x_next = x + Δt v).
    ///
    /// Nodes go four at a time, each sum (reaction, torque, energies) kept per lane and the lanes
    /// added in a fixed order at the end, so that the SIMD and scalar paths give the same bits.
    pub fn node_pass(&mut self, body: &mut Body, gravity: &Vec3, dt: f64, pass: NodePass) {
        self.node_pass_with(body, gravity, dt, pass, None);
    }

    /// [`ForceKernel::node_pass`], a split body's units (see [`SPLIT_NODES`]) shared with
    /// `helper`. Same bits with or without it.
    pub fn node_pass_with(
        &mut self,
        body: &mut Body,
        gravity: &Vec3,
        dt: f64,
        pass: NodePass,
        helper: Option<&Helper>,
    ) {
        let Body { surface, rigid, .. } = body;
        rigid.reset_forces(gravity);
        let rotation = rigid.world_from_body.to_rotation_matrix();
        let m = rotation.matrix();
        let omega = rigid.angular_velocity_in_world();
        self.homologue_frame = Some((*m, rigid.position_in_world));
        let frame = Frame {
            rotation: [
                [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
                [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
                [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
            ],
            centre: rigid.position_in_world.into(),
            velocity: rigid.velocity_in_world.into(),
            omega: omega.into(),
            gravity: (*gravity).into(),
            dt,
        };
        let n = surface.mass.len();
        let s = &mut *surface;
        let simd = self.uses_simd();
        // Every accumulator the pass reads, it clears (below: `force_clear`).
        self.force_clear = self.force.len() == n;
        // The blocks, when every node is integrated here with SIMD.
        let blocks = pass == NodePass::IntegrateAll;
        let split = n >= SPLIT_NODES;
        let mut nodes = Nodes {
            edge_force: &mut self.force[..n],
            mass: &s.mass[..n],
            inverse_mass: &s.inverse_mass[..n],
            air: &s.air_damping[..n],
            link_stiffness: &s.link_stiffness[..n],
            link_damping: &s.link_damping[..n],
            homologue_in_body: &s.homologue_in_body[..n],
            tool_contact: &s.tool_contact[..n],
            position: &s.position_in_world[..n],
            velocity: &mut s.velocity_in_world[..n],
            next_position: &mut s.next_position_in_world[..n],
            homologue: &mut s.homologue_in_world[..n],
            force: &mut s.force_in_world[..n],
        };
        let blocks = (simd && blocks).then(|| self.blocks.start(n));
        let mut sums = Sums::default();
        if split {
            // Two halves cut at a block boundary, each with its sums, added lane by lane; the
            // first taker (the step's thread) takes the second half.
            let cut = node_cut(n);
            let (nodes_a, nodes_b) = nodes.split_at(cut);
            let (blocks_a, blocks_b) = match blocks {
                Some(blocks) => {
                    let (a, b) = blocks.split_at_mut(cut / BLOCK);
                    (Some(a), Some(b))
                }
                None => (None, None),
            };
            let halves = [
                Once::new((nodes_b, blocks_b, Sums::default())),
                Once::new((nodes_a, blocks_a, Sums::default())),
            ];
            let frame = &frame;
            run_units(helper, 2, &|u| {
                // SAFETY: each unit is run once (`run_units`).
                let (nodes, blocks, sums) = unsafe { halves[u].get() };
                node_part(frame, nodes, pass, sums, blocks.take(), simd);
            });
            let [b, a] = halves.map(Once::into_inner);
            sums = a.2;
            sums.add(&b.2);
        } else {
            node_part(&frame, &mut nodes, pass, &mut sums, blocks, simd);
        }
        let reaction_force = Vec3::new(
            lane_sum(&sums.reaction[0]),
            lane_sum(&sums.reaction[1]),
            lane_sum(&sums.reaction[2]),
        );
        let reaction_torque = Vec3::new(
            lane_sum(&sums.torque[0]),
            lane_sum(&sums.torque[1]),
            lane_sum(&sums.torque[2]),
        );
        self.energy = 0.5 * lane_sum(&sums.kinetic) + 0.5 * lane_sum(&sums.elastic)
            - lane_sum(&sums.potential)
            + self.edge_energy
            + rigid.kinetic_energy()
            - gravity.dot(&rigid.position_in_world) * rigid.mass;
        rigid.force_in_world += reaction_force;
        rigid.torque_in_world += reaction_torque;
    }
}

/// The rigid component's motion and the step's constants, as the node pass reads them.
struct Frame {
    rotation: [[f64; 3]; 3],
    centre: [f64; 3],
    velocity: [f64; 3],
    omega: [f64; 3],
    gravity: [f64; 3],
    dt: f64,
}

/// The per-node arrays the node pass reads and writes.
struct Nodes<'a> {
    /// Read, then cleared for the next edge pass.
    edge_force: &'a mut [Accumulator],
    mass: &'a [f64],
    inverse_mass: &'a [f64],
    air: &'a [f64],
    link_stiffness: &'a [f64],
    link_damping: &'a [f64],
    homologue_in_body: &'a [Vec3],
    tool_contact: &'a [crate::contact::tool::ToolContact],
    position: &'a [Vec3],
    velocity: &'a mut [Vec3],
    next_position: &'a mut [Vec3],
    homologue: &'a mut [Vec3],
    force: &'a mut [Vec3],
}

impl<'a> Nodes<'a> {
    /// Nodes `..cut` and `cut..`.
    fn split_at(self, cut: usize) -> (Nodes<'a>, Nodes<'a>) {
        let (edge_force_a, edge_force_b) = self.edge_force.split_at_mut(cut);
        let (mass_a, mass_b) = self.mass.split_at(cut);
        let (inverse_mass_a, inverse_mass_b) = self.inverse_mass.split_at(cut);
        let (air_a, air_b) = self.air.split_at(cut);
        let (stiffness_a, stiffness_b) = self.link_stiffness.split_at(cut);
        let (damping_a, damping_b) = self.link_damping.split_at(cut);
        let (homologue_in_body_a, homologue_in_body_b) = self.homologue_in_body.split_at(cut);
        let (tool_contact_a, tool_contact_b) = self.tool_contact.split_at(cut);
        let (position_a, position_b) = self.position.split_at(cut);
        let (velocity_a, velocity_b) = self.velocity.split_at_mut(cut);
        let (next_a, next_b) = self.next_position.split_at_mut(cut);
        let (homologue_a, homologue_b) = self.homologue.split_at_mut(cut);
        let (force_a, force_b) = self.force.split_at_mut(cut);
        (
            Nodes {
                edge_force: edge_force_a,
                mass: mass_a,
                inverse_mass: inverse_mass_a,
                air: air_a,
                link_stiffness: stiffness_a,
                link_damping: damping_a,
                homologue_in_body: homologue_in_body_a,
                tool_contact: tool_contact_a,
                position: position_a,
                velocity: velocity_a,
                next_position: next_a,
                homologue: homologue_a,
                force: force_a,
            },
            Nodes {
                edge_force: edge_force_b,
                mass: mass_b,
                inverse_mass: inverse_mass_b,
                air: air_b,
                link_stiffness: stiffness_b,
                link_damping: damping_b,
                homologue_in_body: homologue_in_body_b,
                tool_contact: tool_contact_b,
                position: position_b,
                velocity: velocity_b,
                next_position: next_b,
                homologue: homologue_b,
                force: force_b,
            },
        )
    }
}

/// Per-lane sums of the node pass.
#[derive(Default)]
struct Sums {
    reaction: [[f64; LANES]; 3],
    torque: [[f64; LANES]; 3],
    kinetic: [f64; LANES],
    elastic: [f64; LANES],
    potential: [f64; LANES],
}

impl Sums {
    /// Adds `other`'s sums, lane by lane.
    fn add(&mut self, other: &Sums) {
        let add = |a: &mut [f64; LANES], b: &[f64; LANES]| {
            for (a, b) in a.iter_mut().zip(b) {
                *a += b;
            }
        };
        for d in 0..3 {
            add(&mut self.reaction[d], &other.reaction[d]);
            add(&mut self.torque[d], &other.torque[d]);
        }
        add(&mut self.kinetic, &other.kinetic);
        add(&mut self.elastic, &other.elastic);
        add(&mut self.potential, &other.potential);
    }
}

/// The node pass over `nodes` into `sums`, on the SIMD path when `simd` (the caller checked the
/// machine has it; the blocks are kept only there).
fn node_part(
    frame: &Frame,
    nodes: &mut Nodes,
    pass: NodePass,
    sums: &mut Sums,
    blocks: Option<&mut [NodeBlock]>,
    simd: bool,
) {
    #[cfg(target_arch = "x86_64")]
    if simd {
        // SAFETY: the machine has AVX (`simd` is `ForceKernel::uses_simd`).
        unsafe { avx::node_pass(frame, nodes, pass, sums, blocks) };
        return;
    }
    let _ = (simd, blocks);
    node_blocks(frame, nodes, pass, sums);
}

/// The node pass over every node, block after block of [`LANES`] nodes (the last block partial).
/// Written lane-wise on arrays so that, compiled for AVX, each line is one vector operation; the
/// arithmetic is the same in every lane and on every path.
#[inline(always)]
fn node_blocks(frame: &Frame, nodes: &mut Nodes, pass: NodePass, sums: &mut Sums) {
    let n = nodes.mass.len();
    let full = n - n % LANES;
    let mut i0 = 0;
    while i0 < full {
        node_block::<LANES>(frame, nodes, pass, sums, i0);
        i0 += LANES;
    }
    // The partial last block, one lane at a time into the same lane sums.
    for i in full..n {
        node_block::<1>(frame, nodes, pass, sums, i);
    }
}

/// Nodes `i0 .. i0 + W` (W = LANES, or 1 for the tail, whose lane is `i0 % LANES`).
#[inline(always)]
fn node_block<const W: usize>(
    f: &Frame,
    nodes: &mut Nodes,
    pass: NodePass,
    sums: &mut Sums,
    i0: usize,
) {
    let lane0 = if W == 1 { i0 % LANES } else { 0 };
    let r = &f.rotation;
    let mut x = [[0.0; W]; 3];
    let mut v = [[0.0; W]; 3];
    let mut hb = [[0.0; W]; 3];
    let mut fe = [[0.0; W]; 3];
    let (mut m, mut im, mut air, mut k, mut c) = ([0.0; W], [0.0; W], [0.0; W], [0.0; W], [0.0; W]);
    for l in 0..W {
        let i = i0 + l;
        for d in 0..3 {
            x[d][l] = nodes.position[i][d];
            v[d][l] = nodes.velocity[i][d];
            hb[d][l] = nodes.homologue_in_body[i][d];
            fe[d][l] = nodes.edge_force[i][d];
        }
        nodes.edge_force[i] = Accumulator::default();
        m[l] = nodes.mass[i];
        im[l] = nodes.inverse_mass[i];
        air[l] = nodes.air[i];
        k[l] = nodes.link_stiffness[i];
        c[l] = nodes.link_damping[i];
    }
    let mut arm = [[0.0; W]; 3];
    for d in 0..3 {
        for l in 0..W {
            arm[d][l] = r[d][0] * hb[0][l] + r[d][1] * hb[1][l] + r[d][2] * hb[2][l];
        }
    }
    let mut h = [[0.0; W]; 3];
    let mut hv = [[0.0; W]; 3];
    let w = &f.omega;
    for l in 0..W {
        let cross = [
            w[1] * arm[2][l] - w[2] * arm[1][l],
            w[2] * arm[0][l] - w[0] * arm[2][l],
            w[0] * arm[1][l] - w[1] * arm[0][l],
        ];
        for d in 0..3 {
            h[d][l] = f.centre[d] + arm[d][l];
            hv[d][l] = f.velocity[d] + cross[d];
        }
    }
    let mut link = [[0.0; W]; 3];
    let mut force = [[0.0; W]; 3];
    let mut stretch2 = [0.0; W];
    let mut speed2 = [0.0; W];
    let mut height = [0.0; W];
    for l in 0..W {
        for d in 0..3 {
            let stretch = h[d][l] - x[d][l];
            link[d][l] = stretch * k[l] + (hv[d][l] - v[d][l]) * c[l];
            force[d][l] = fe[d][l] + (f.gravity[d] * m[l] - v[d][l] * air[l]) + link[d][l];
            stretch2[l] += stretch * stretch;
            speed2[l] += v[d][l] * v[d][l];
            height[l] += f.gravity[d] * x[d][l];
        }
    }
    for l in 0..W {
        let s = lane0 + l;
        sums.kinetic[s] += m[l] * speed2[l];
        sums.elastic[s] += k[l] * stretch2[l];
        sums.potential[s] += m[l] * height[l];
        let torque = [
            arm[1][l] * link[2][l] - arm[2][l] * link[1][l],
            arm[2][l] * link[0][l] - arm[0][l] * link[2][l],
            arm[0][l] * link[1][l] - arm[1][l] * link[0][l],
        ];
        for d in 0..3 {
            sums.reaction[d][s] -= link[d][l];
            sums.torque[d][s] -= torque[d];
        }
    }
    for l in 0..W {
        let i = i0 + l;
        nodes.homologue[i] = Vec3::new(h[0][l], h[1][l], h[2][l]);
        nodes.force[i] = Vec3::new(force[0][l], force[1][l], force[2][l]);
        let integrate = match pass {
            NodePass::Forces => false,
            NodePass::IntegrateAll => true,
            NodePass::IntegrateFree => nodes.tool_contact[i].tool == crate::contact::tool::NO_TOOL,
        };
        if integrate {
            let scale = f.dt * im[l];
            let mut velocity = [0.0; 3];
            let mut next = [0.0; 3];
            for d in 0..3 {
                velocity[d] = v[d][l] + force[d][l] * scale;
                next[d] = x[d][l] + velocity[d] * f.dt;
            }
            nodes.velocity[i] = Vec3::from(velocity);
            nodes.next_position[i] = Vec3::from(next);
        }
    }
}

/// True when this machine runs the SIMD path (x86_64 with AVX).
pub fn simd_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// The lanes' partial sums added in lane order (both paths end this way).
fn lane_sum(lanes: &[f64; LANES]) -> f64 {
    (lanes[0] + lanes[1]) + (lanes[2] + lanes[3])
}

/// The batches `list` of the edge pass into the accumulators at `f` and `energy`, on the SIMD path
/// when `simd` (the caller checked the machine has it) and the scalar one otherwise.
///
/// # Safety
/// `f` points to an accumulator for every end of the listed batches, which no other thread reads or
/// writes meanwhile.
#[allow(clippy::too_many_arguments)]
unsafe fn edge_part(
    batches: &EdgeBatches,
    list: impl Iterator<Item = usize>,
    x: &[Vec3],
    v: &[Vec3],
    f: *mut [f64; 4],
    energy: &mut [f64; LANES],
    simd: bool,
) {
    #[cfg(target_arch = "x86_64")]
    if simd {
        // SAFETY: the machine has AVX (`simd` is `ForceKernel::uses_simd`); every index the batches
        // hold is a node of the body (`rebuild` skips edges with an end past the nodes; empty lanes
        // hold node 0, and a body with a batch has nodes), below the arrays' lengths; `f` as the
        // caller guarantees.
        unsafe { avx::edge_pass(batches, list, x, v, f, energy) };
        return;
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = simd;
    // SAFETY: as the caller guarantees.
    unsafe { scalar_edge_pass(batches, list, x, v, f, energy) };
}

/// Runs `work(0) .. work(units − 1)`, each once: on this thread and the helper, each taking the
/// next unit left until none is, or here alone.
fn run_units(helper: Option<&Helper>, units: usize, work: &(dyn Fn(usize) + Sync)) {
    match helper {
        Some(helper) => helper.for_each(units, work),
        None => (0..units).for_each(work),
    }
}

/// A pointer handed to the units of a pass, which write through it where the pass's comments say.
#[derive(Clone, Copy)]
struct Shared<T>(*mut T);

impl<T> Shared<T> {
    /// The pointer (a method, so that a closure captures the whole `Shared`).
    fn get(self) -> *mut T {
        self.0
    }
}

// SAFETY: the units write through it to disjoint memory (see each use).
unsafe impl<T> Send for Shared<T> {}
// SAFETY: as above.
unsafe impl<T> Sync for Shared<T> {}

/// A value a unit of a pass takes alone: each unit index is run once.
struct Once<T>(std::cell::UnsafeCell<T>);

// SAFETY: `get` is called once per value, by the one thread that runs its unit.
unsafe impl<T: Send> Sync for Once<T> {}

impl<T> Once<T> {
    fn new(value: T) -> Self {
        Self(std::cell::UnsafeCell::new(value))
    }

    /// # Safety
    /// Called by one thread only, while no other reference to the value lives.
    #[allow(clippy::mut_from_ref)]
    unsafe fn get(&self) -> &mut T {
        // SAFETY: as the caller guarantees.
        unsafe { &mut *self.0.get() }
    }

    fn into_inner(self) -> T {
        self.0.into_inner()
    }
}

/// A split body's batches (see [`SPLIT_NODES`]) as three units: those whose ends all lie below the
/// node cut, those whose ends all lie at or above it, and those across it; and the nodes the last
/// touch.
#[derive(Clone, Debug, Default)]
struct SplitBatches {
    units: [Vec<u32>; 3],
    /// Nodes some batch across the cut touches, in increasing order.
    crossed: Vec<u32>,
    /// Per node: touched by a batch across the cut (scratch).
    mark: Vec<bool>,
    /// (topology version, nodes, batches, node cut) the units were made for.
    made_for: Option<(u64, usize, usize, usize)>,
}

impl SplitBatches {
    /// Scratch for a body of up to `nodes` nodes and `edges` edges (a batch holds at least one
    /// edge).
    fn with_capacity((nodes, edges): (usize, usize)) -> Self {
        Self {
            units: std::array::from_fn(|_| Vec::with_capacity(edges)),
            crossed: Vec::with_capacity(nodes),
            mark: Vec::with_capacity(nodes),
            made_for: None,
        }
    }

    /// Sorts the batches into the units for a body of `n` nodes cut at `cut`.
    fn classify(&mut self, batches: &EdgeBatches, n: usize, cut: usize) {
        for unit in &mut self.units {
            unit.clear();
        }
        self.crossed.clear();
        self.mark.clear();
        self.mark.resize(n, false);
        for (i, ends) in batches.ends_of.iter().enumerate() {
            // Empty lanes hold node 0: a batch with one counts as touching it.
            let below = ends
                .iter()
                .flatten()
                .filter(|&&e| (e as usize) < cut)
                .count();
            let unit = match below {
                8 => 0,
                0 => 1,
                _ => 2,
            };
            self.units[unit].push(i as u32);
            if unit == 2 {
                for &e in ends.iter().flatten() {
                    self.mark[e as usize] = true;
                }
            }
        }
        for (i, &marked) in self.mark.iter().enumerate() {
            if marked {
                self.crossed.push(i as u32);
            }
        }
    }
}

/// One batch's spring forces, lane by lane: the operations of the SIMD path in the same order.
/// `d = x_b − x_a`, `l = √(d·d)`, `i = l (1 / d·d)`, `m = k (l − L) + c ((v_b − v_a)·d) i`, `F = d (m i)` on
/// a and −F on b; zero where `d·d` is not above the smallest normal number. Energy ½ k (l − L)².
///
/// # Safety
/// `f` points to an accumulator for every end of the listed batches, which no other thread reads or
/// writes meanwhile.
unsafe fn scalar_edge_pass(
    batches: &EdgeBatches,
    list: impl Iterator<Item = usize>,
    x: &[Vec3],
    v: &[Vec3],
    f: *mut [f64; 4],
    energy: &mut [f64; LANES],
) {
    for i in list {
        let (ends, rest) = (&batches.ends_of[i], &batches.rest[i]);
        let [k, c] = batches.stiffness_damping_of(i);
        for lane in 0..LANES {
            let (a, b) = (ends[0][lane] as usize, ends[1][lane] as usize);
            let (rest, k, c) = (rest[lane], k[lane], c[lane]);
            let (dx, dy, dz) = (x[b].x - x[a].x, x[b].y - x[a].y, x[b].z - x[a].z);
            let (ux, uy, uz) = (v[b].x - v[a].x, v[b].y - v[a].y, v[b].z - v[a].z);
            let length2 = dx * dx + dy * dy + dz * dz;
            let length = length2.sqrt();
            let (scale, e) = if length2 > f64::MIN_POSITIVE {
                // 1 / l as l / l²: the square root and the division run side by side.
                let inverse = length * (1.0 / length2);
                let stretch = length - rest;
                let magnitude = k * stretch + c * (ux * dx + uy * dy + uz * dz) * inverse;
                (magnitude * inverse, k * stretch * stretch)
            } else {
                (0.0, 0.0)
            };
            let (px, py, pz) = (dx * scale, dy * scale, dz * scale);
            energy[lane] += 0.5 * e;
            // SAFETY: as the caller guarantees.
            let (fa, fb) = unsafe { (&mut *f.add(a), &mut *f.add(b)) };
            fa[0] += px;
            fa[1] += py;
            fa[2] += pz;
            fb[0] -= px;
            fb[1] -= py;
            fb[2] -= pz;
        }
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) mod avx {
    use super::{BLOCK, EdgeBatches, LANES, NodeBlock};
    use crate::Vec3;
    use crate::collision::tool::Aabb;
    use std::arch::x86_64::*;

    /// Nodes i .. i + 4 of an array of `Vec3` (12 consecutive `f64` at `p`) as three vectors of
    /// x, y and z.
    #[inline(always)]
    pub(crate) unsafe fn load3(p: *const f64) -> [__m256d; 3] {
        unsafe {
            let m03 = _mm256_insertf128_pd::<1>(
                _mm256_castpd128_pd256(_mm_loadu_pd(p)),
                _mm_loadu_pd(p.add(6)),
            );
            let m14 = _mm256_insertf128_pd::<1>(
                _mm256_castpd128_pd256(_mm_loadu_pd(p.add(2))),
                _mm_loadu_pd(p.add(8)),
            );
            let m25 = _mm256_insertf128_pd::<1>(
                _mm256_castpd128_pd256(_mm_loadu_pd(p.add(4))),
                _mm_loadu_pd(p.add(10)),
            );
            [
                _mm256_shuffle_pd::<0b1010>(m03, m14),
                _mm256_shuffle_pd::<0b0101>(m03, m25),
                _mm256_shuffle_pd::<0b1010>(m14, m25),
            ]
        }
    }

    /// The inverse of [`load3`].
    #[inline(always)]
    unsafe fn store3(p: *mut f64, [x, y, z]: [__m256d; 3]) {
        unsafe {
            let m03 = _mm256_shuffle_pd::<0b0000>(x, y);
            let m14 = _mm256_shuffle_pd::<0b1010>(z, x);
            let m25 = _mm256_shuffle_pd::<0b1111>(y, z);
            _mm_storeu_pd(p, _mm256_castpd256_pd128(m03));
            _mm_storeu_pd(p.add(6), _mm256_extractf128_pd::<1>(m03));
            _mm_storeu_pd(p.add(2), _mm256_castpd256_pd128(m14));
            _mm_storeu_pd(p.add(8), _mm256_extractf128_pd::<1>(m14));
            _mm_storeu_pd(p.add(4), _mm256_castpd256_pd128(m25));
            _mm_storeu_pd(p.add(10), _mm256_extractf128_pd::<1>(m25));
        }
    }

    /// The node pass with AVX: every full block of four nodes as vectors, the operations of
    /// [`super::node_block`] in the same order; the partial last block by the scalar code.
    ///
    /// # Safety
    /// The machine must have AVX.
    #[target_feature(enable = "avx")]
    pub(super) unsafe fn node_pass(
        f: &super::Frame,
        nodes: &mut super::Nodes,
        pass: super::NodePass,
        sums: &mut super::Sums,
        mut blocks: Option<&mut [NodeBlock]>,
    ) {
        use super::NodePass;
        let n = nodes.mass.len();
        let full = n - n % LANES;
        let splat = |x: f64| _mm256_set1_pd(x);
        let r = f.rotation.map(|row| row.map(splat));
        let centre = f.centre.map(splat);
        let velocity_of_centre = f.velocity.map(splat);
        let w = f.omega.map(splat);
        let g = f.gravity.map(splat);
        let dt = splat(f.dt);
        let zero = _mm256_setzero_pd();
        let mut reaction = [zero; 3];
        let mut torque_sum = [zero; 3];
        let (mut kinetic, mut elastic, mut potential) = (zero, zero, zero);
        let add = |a, b| _mm256_add_pd(a, b);
        let sub = |a, b| _mm256_sub_pd(a, b);
        let mul = |a, b| _mm256_mul_pd(a, b);
        // The current block, per lane: the box of its start and end positions (`min(p, lo)` is
        // `p < lo ? p : lo`, so a coordinate that is not a number leaves it as it was) and the
        // guard's maxima (`max(a, b)` is `a > b ? a : b`, its comparison) and flag, of the end
        // state: `|v|²` and `|x_end − h|²` as the guard computes them.
        let track = blocks.is_some() && pass == NodePass::IntegrateAll;
        let (empty_lo, empty_hi) = (splat(f64::INFINITY), splat(f64::NEG_INFINITY));
        let (mut lo, mut hi) = ([empty_lo; 3], [empty_hi; 3]);
        let (mut most_speed2, mut most_stretch2, mut bad) = (zero, zero, zero);
        let magnitude = _mm256_castsi256_pd(_mm256_set1_epi64x(i64::MAX));
        let infinity = splat(f64::INFINITY);
        let mut i = 0;
        while i < full {
            // SAFETY: i + 4 <= n, the length of every slice read or written.
            unsafe {
                let x = load3(nodes.position.as_ptr().add(i) as *const f64);
                let v = load3(nodes.velocity.as_ptr().add(i) as *const f64);
                let hb = load3(nodes.homologue_in_body.as_ptr().add(i) as *const f64);
                let fe = {
                    let rows = nodes.edge_force.as_mut_ptr().add(i) as *mut f64;
                    let row = |l: usize| _mm256_loadu_pd(rows.add(4 * l));
                    let (r0, r1, r2, r3) = (row(0), row(1), row(2), row(3));
                    for l in 0..4 {
                        _mm256_storeu_pd(rows.add(4 * l), zero);
                    }
                    // [x0 y0 z0 0], [x1 ...] → [x0 x1 x2 x3], [y...], [z...].
                    transpose3([r0, r1, r2, r3])
                };
                let m = _mm256_loadu_pd(nodes.mass.as_ptr().add(i));
                let im = _mm256_loadu_pd(nodes.inverse_mass.as_ptr().add(i));
                let air = _mm256_loadu_pd(nodes.air.as_ptr().add(i));
                let k = _mm256_loadu_pd(nodes.link_stiffness.as_ptr().add(i));
                let c = _mm256_loadu_pd(nodes.link_damping.as_ptr().add(i));
                let arm = [0, 1, 2].map(|d| {
                    add(
                        add(mul(r[d][0], hb[0]), mul(r[d][1], hb[1])),
                        mul(r[d][2], hb[2]),
                    )
                });
                let cross = [
                    sub(mul(w[1], arm[2]), mul(w[2], arm[1])),
                    sub(mul(w[2], arm[0]), mul(w[0], arm[2])),
                    sub(mul(w[0], arm[1]), mul(w[1], arm[0])),
                ];
                let h = [0, 1, 2].map(|d| add(centre[d], arm[d]));
                let hv = [0, 1, 2].map(|d| add(velocity_of_centre[d], cross[d]));
                let stretch = [0, 1, 2].map(|d| sub(h[d], x[d]));
                let link = [0, 1, 2].map(|d| add(mul(stretch[d], k), mul(sub(hv[d], v[d]), c)));
                let force =
                    [0, 1, 2].map(|d| add(add(fe[d], sub(mul(g[d], m), mul(v[d], air))), link[d]));
                let mut stretch2 = zero;
                let mut speed2 = zero;
                let mut height = zero;
                for d in 0..3 {
                    stretch2 = add(stretch2, mul(stretch[d], stretch[d]));
                    speed2 = add(speed2, mul(v[d], v[d]));
                    height = add(height, mul(g[d], x[d]));
                }
                kinetic = add(kinetic, mul(m, speed2));
                elastic = add(elastic, mul(k, stretch2));
                potential = add(potential, mul(m, height));
                let torque = [
                    sub(mul(arm[1], link[2]), mul(arm[2], link[1])),
                    sub(mul(arm[2], link[0]), mul(arm[0], link[2])),
                    sub(mul(arm[0], link[1]), mul(arm[1], link[0])),
                ];
                for d in 0..3 {
                    reaction[d] = sub(reaction[d], link[d]);
                    torque_sum[d] = sub(torque_sum[d], torque[d]);
                }
                store3(nodes.homologue.as_mut_ptr().add(i) as *mut f64, h);
                store3(nodes.force.as_mut_ptr().add(i) as *mut f64, force);
                if pass != NodePass::Forces {
                    let scale = mul(dt, im);
                    let mut velocity = [0, 1, 2].map(|d| add(v[d], mul(force[d], scale)));
                    let mut next = [0, 1, 2].map(|d| add(x[d], mul(velocity[d], dt)));
                    if pass == NodePass::IntegrateFree {
                        let free = |l: usize| {
                            if nodes.tool_contact[i + l].tool == crate::contact::tool::NO_TOOL {
                                -1i64
                            } else {
                                0
                            }
                        };
                        let mask = _mm256_castsi256_pd(_mm256_set_epi64x(
                            free(3),
                            free(2),
                            free(1),
                            free(0),
                        ));
                        let old_next = load3(nodes.next_position.as_ptr().add(i) as *const f64);
                        for d in 0..3 {
                            velocity[d] = _mm256_blendv_pd(v[d], velocity[d], mask);
                            next[d] = _mm256_blendv_pd(old_next[d], next[d], mask);
                        }
                    }
                    store3(nodes.velocity.as_mut_ptr().add(i) as *mut f64, velocity);
                    store3(nodes.next_position.as_mut_ptr().add(i) as *mut f64, next);
                    if track {
                        for d in 0..3 {
                            lo[d] = _mm256_min_pd(next[d], _mm256_min_pd(x[d], lo[d]));
                            hi[d] = _mm256_max_pd(next[d], _mm256_max_pd(x[d], hi[d]));
                        }
                        let v2 = dot3(velocity, velocity);
                        let s2 = {
                            let d = sub3(next, h);
                            dot3(d, d)
                        };
                        most_speed2 = _mm256_max_pd(v2, most_speed2);
                        most_stretch2 = _mm256_max_pd(s2, most_stretch2);
                        let sum = _mm256_and_pd(_mm256_add_pd(v2, s2), magnitude);
                        bad = _mm256_or_pd(bad, _mm256_cmp_pd::<_CMP_NLT_UQ>(sum, infinity));
                    }
                }
            }
            i += LANES;
            if track && (i % BLOCK == 0 || i == full) {
                if let Some(blocks) = blocks.as_mut() {
                    blocks[(i - 1) / BLOCK] = fold_block(lo, hi, [most_speed2, most_stretch2, bad]);
                }
                (lo, hi) = ([empty_lo; 3], [empty_hi; 3]);
                (most_speed2, most_stretch2, bad) = (zero, zero, zero);
            }
        }
        sums.kinetic = lanes(kinetic);
        sums.elastic = lanes(elastic);
        sums.potential = lanes(potential);
        sums.reaction = reaction.map(|r| lanes(r));
        sums.torque = torque_sum.map(|t| lanes(t));
        for i in full..n {
            super::node_block::<1>(f, nodes, pass, sums, i);
            // The last nodes, one at a time: their block's box grows, and the guard rescans it.
            if track && let Some(b) = blocks.as_mut().and_then(|b| b.get_mut(i / BLOCK)) {
                b.bounds.include(&nodes.position[i]);
                b.bounds.include(&nodes.next_position[i]);
                b.touched = true;
            }
        }
    }

    /// A block from its per-lane least and greatest coordinates and maxima (the lanes folded with
    /// the same comparisons) and flags.
    #[target_feature(enable = "avx")]
    #[inline]
    fn fold_block(
        lo: [__m256d; 3],
        hi: [__m256d; 3],
        [speed2, stretch2, bad]: [__m256d; 3],
    ) -> NodeBlock {
        let least = |l: [f64; LANES]| {
            l.into_iter()
                .fold(f64::INFINITY, |a, l| if l < a { l } else { a })
        };
        let greatest = |l: [f64; LANES]| {
            l.into_iter()
                .fold(f64::NEG_INFINITY, |a, l| if l > a { l } else { a })
        };
        let largest = |l: [f64; LANES]| l.into_iter().fold(0.0, |a, l| if l > a { l } else { a });
        let (lo, hi) = (lo.map(|v| lanes(v)), hi.map(|v| lanes(v)));
        NodeBlock {
            bounds: Aabb {
                min: Vec3::new(least(lo[0]), least(lo[1]), least(lo[2])),
                max: Vec3::new(greatest(hi[0]), greatest(hi[1]), greatest(hi[2])),
            },
            speed2: largest(lanes(speed2)),
            stretch2: largest(lanes(stretch2)),
            bad: _mm256_movemask_pd(bad) != 0,
            touched: false,
        }
    }

    /// Four `Vec3` at the given indices as vectors of x, y and z (also the multi-rate
    /// integrator's spring loop's).
    ///
    /// # Safety
    /// `p` points to an array of `Vec3` with more than every index elements; AVX.
    #[inline(always)]
    pub(crate) unsafe fn gather3(p: *const f64, idx: &[u32; LANES]) -> [__m256d; 3] {
        unsafe {
            let at = |l: usize| p.add(3 * idx[l] as usize);
            let lo = _mm256_insertf128_pd::<1>(
                _mm256_castpd128_pd256(_mm_loadu_pd(at(0))),
                _mm_loadu_pd(at(2)),
            );
            let hi = _mm256_insertf128_pd::<1>(
                _mm256_castpd128_pd256(_mm_loadu_pd(at(1))),
                _mm_loadu_pd(at(3)),
            );
            let z01 = _mm_unpacklo_pd(_mm_load_sd(at(0).add(2)), _mm_load_sd(at(1).add(2)));
            let z23 = _mm_unpacklo_pd(_mm_load_sd(at(2).add(2)), _mm_load_sd(at(3).add(2)));
            [
                _mm256_unpacklo_pd(lo, hi),
                _mm256_unpackhi_pd(lo, hi),
                _mm256_insertf128_pd::<1>(_mm256_castpd128_pd256(z01), z23),
            ]
        }
    }

    /// `p[b] − p[a]` for the four lanes' nodes (`p` an array of `Vec3`), as vectors of x, y and z:
    /// each lane's difference taken on its ends' `[x y z]` (loaded masked: the last node's load
    /// stays in the array), then the four lanes transposed — half the shuffles of gathering both
    /// ends first. The same subtractions as [`sub3`] of two [`gather3`]s: the same bits.
    ///
    /// # Safety
    /// `p` points to an array of `Vec3` with more than every index elements; AVX.
    #[inline(always)]
    pub(crate) unsafe fn gather_difference3(
        p: *const f64,
        a: &[u32; LANES],
        b: &[u32; LANES],
    ) -> [__m256d; 3] {
        unsafe {
            let xyz = _mm256_set_epi64x(0, -1, -1, -1);
            let lane = |l: usize| {
                _mm256_sub_pd(
                    _mm256_maskload_pd(p.add(3 * b[l] as usize), xyz),
                    _mm256_maskload_pd(p.add(3 * a[l] as usize), xyz),
                )
            };
            transpose3([lane(0), lane(1), lane(2), lane(3)])
        }
    }

    /// Four lanes' `[x y z ·]` vectors as vectors of x, y and z (the fourth entries dropped).
    ///
    /// # Safety
    /// AVX.
    #[inline(always)]
    pub(crate) unsafe fn transpose3([r0, r1, r2, r3]: [__m256d; 4]) -> [__m256d; 3] {
        unsafe {
            let t0 = _mm256_unpacklo_pd(r0, r1);
            let t1 = _mm256_unpackhi_pd(r0, r1);
            let t2 = _mm256_unpacklo_pd(r2, r3);
            let t3 = _mm256_unpackhi_pd(r2, r3);
            [
                _mm256_permute2f128_pd::<0x20>(t0, t2),
                _mm256_permute2f128_pd::<0x20>(t1, t3),
                _mm256_permute2f128_pd::<0x31>(t0, t2),
            ]
        }
    }

    /// `b − a`, component by component.
    #[target_feature(enable = "avx")]
    #[inline]
    pub(crate) fn sub3(b: [__m256d; 3], a: [__m256d; 3]) -> [__m256d; 3] {
        [
            _mm256_sub_pd(b[0], a[0]),
            _mm256_sub_pd(b[1], a[1]),
            _mm256_sub_pd(b[2], a[2]),
        ]
    }

    /// The four lanes of `v`, in order.
    #[target_feature(enable = "avx")]
    #[inline]
    pub(crate) fn lanes(v: __m256d) -> [f64; LANES] {
        let mut out = [0.0; LANES];
        // SAFETY: four f64 into an array of four.
        unsafe { _mm256_storeu_pd(out.as_mut_ptr(), v) };
        out
    }

    /// `(x₀y₀ + x₁y₁) + x₂y₂` per lane (the scalar path's order).
    #[target_feature(enable = "avx")]
    #[inline]
    pub(crate) fn dot3(x: [__m256d; 3], y: [__m256d; 3]) -> __m256d {
        _mm256_add_pd(
            _mm256_add_pd(_mm256_mul_pd(x[0], y[0]), _mm256_mul_pd(x[1], y[1])),
            _mm256_mul_pd(x[2], y[2]),
        )
    }

    /// The AVX edge pass: the scalar pass's operations, four lanes at a time.
    ///
    /// # Safety
    /// The machine must have AVX; every index of the batches must be below `x.len()`, `v.len()`
    /// and `f` must point to an accumulator for each, which no other thread reads or writes
    /// meanwhile.
    #[target_feature(enable = "avx")]
    pub unsafe fn edge_pass(
        batches: &EdgeBatches,
        list: impl Iterator<Item = usize>,
        x: &[Vec3],
        v: &[Vec3],
        f: *mut [f64; 4],
        energy: &mut [f64; LANES],
    ) {
        let xp = x.as_ptr() as *const f64;
        let vp = v.as_ptr() as *const f64;
        let fp = f as *mut f64;
        let tiny = _mm256_set1_pd(f64::MIN_POSITIVE);
        let one = _mm256_set1_pd(1.0);
        let half = _mm256_set1_pd(0.5);
        let zero = _mm256_setzero_pd();
        let mut energy_lanes = _mm256_setzero_pd();
        for i in list {
            let (ends, rest) = (&batches.ends_of[i], &batches.rest[i]);
            let [ga, gb] = ends;
            // SAFETY (all loads and stores): indices within the slices, as the caller guarantees.
            let (d, u) = unsafe {
                (
                    gather_difference3(xp, ga, gb),
                    gather_difference3(vp, ga, gb),
                )
            };
            let (rest, k, c) = unsafe {
                let rest = _mm256_loadu_pd(rest.as_ptr());
                match batches.uniform {
                    Some((k, c)) => (rest, _mm256_set1_pd(k), _mm256_set1_pd(c)),
                    None => {
                        let [k, c] = &batches.stiffness_damping[i];
                        (
                            rest,
                            _mm256_loadu_pd(k.as_ptr()),
                            _mm256_loadu_pd(c.as_ptr()),
                        )
                    }
                }
            };
            let length2 = dot3(d, d);
            let length = _mm256_sqrt_pd(length2);
            let valid = _mm256_cmp_pd::<_CMP_GT_OQ>(length2, tiny);
            let inverse = _mm256_mul_pd(length, _mm256_div_pd(one, length2));
            let stretch = _mm256_sub_pd(length, rest);
            let along = dot3(u, d);
            let magnitude = _mm256_add_pd(
                _mm256_mul_pd(k, stretch),
                _mm256_mul_pd(_mm256_mul_pd(c, along), inverse),
            );
            let scale = _mm256_and_pd(_mm256_mul_pd(magnitude, inverse), valid);
            let e = _mm256_and_pd(_mm256_mul_pd(_mm256_mul_pd(k, stretch), stretch), valid);
            energy_lanes = _mm256_add_pd(energy_lanes, _mm256_mul_pd(half, e));
            let (px, py, pz) = (
                _mm256_mul_pd(d[0], scale),
                _mm256_mul_pd(d[1], scale),
                _mm256_mul_pd(d[2], scale),
            );
            // Lanes as [x y z 0] vectors: one add to each end's accumulator.
            let t0 = _mm256_unpacklo_pd(px, py);
            let t1 = _mm256_unpackhi_pd(px, py);
            let t2 = _mm256_unpacklo_pd(pz, zero);
            let t3 = _mm256_unpackhi_pd(pz, zero);
            let lanes = [
                _mm256_permute2f128_pd::<0x20>(t0, t2),
                _mm256_permute2f128_pd::<0x20>(t1, t3),
                _mm256_permute2f128_pd::<0x31>(t0, t2),
                _mm256_permute2f128_pd::<0x31>(t1, t3),
            ];
            let [sa, sb] = ends;
            for (lane, p) in lanes.into_iter().enumerate() {
                unsafe {
                    let a = fp.add(4 * sa[lane] as usize);
                    _mm256_storeu_pd(a, _mm256_add_pd(_mm256_loadu_pd(a), p));
                    let b = fp.add(4 * sb[lane] as usize);
                    _mm256_storeu_pd(b, _mm256_sub_pd(_mm256_loadu_pd(b), p));
                }
            }
        }
        unsafe { _mm256_storeu_pd(energy.as_mut_ptr(), energy_lanes) };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_split_bodys_units_write_disjoint_accumulators() {
        // A scene's mesh, its nodes ordered along a Z curve as every scene's are.
        let text = "[[body]]\nname = \"organ\"\n\
                    mesh = { icosphere = { radius = 0.05, subdivisions = 5 } }\n";
        let scene = crate::scene::parse_scene(text, "split.toml", std::path::Path::new("."))
            .expect("a valid scene");
        let world = crate::world::World::from_scene(&scene);
        let body = &world.bodies[0];
        let n = body.node_count();
        assert!(n >= SPLIT_NODES);
        let mut kernel = ForceKernel::new(body);
        kernel.refresh(body);
        let cut = node_cut(n);
        assert_eq!(cut % BLOCK, 0);
        let mut split = SplitBatches::default();
        split.classify(&kernel.batches, n, cut);
        let batches = &kernel.batches;
        let ends = |i: u32| {
            batches.ends_of[i as usize]
                .iter()
                .flatten()
                .map(|&e| e as usize)
        };
        // Units 0 and 1 touch only their side of the cut; unit 2 crosses it and its nodes are
        // listed; every batch is in one unit.
        assert!(split.units[0].iter().all(|&i| ends(i).all(|e| e < cut)));
        assert!(split.units[1].iter().all(|&i| ends(i).all(|e| e >= cut)));
        for &i in &split.units[2] {
            assert!(ends(i).any(|e| e < cut) && ends(i).any(|e| e >= cut));
            assert!(ends(i).all(|e| split.crossed.binary_search(&(e as u32)).is_ok()));
        }
        let mut all: Vec<u32> = split.units.iter().flatten().copied().collect();
        all.sort_unstable();
        assert!(all.iter().copied().eq(0..batches.ends_of.len() as u32));
        let crossing = split.units[2].len() as f64 / all.len() as f64;
        println!(
            "{n} nodes: {:.1} % of the batches cross the cut",
            100.0 * crossing
        );
        assert!(crossing < 0.1, "{crossing}");
    }
}
