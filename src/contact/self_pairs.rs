//! The triangle pairs of one body that may meet over a tick, for its self-contact (the body's
//! `self_contact` key): a soft organ pressed, dropped or folded must not pass through itself, as it
//! may not pass through another.
//!
//! Two kinds of pairs, found in two ways:
//!
//! - **Far pairs**, triangles with no node within one edge of the other's: listed when their boxes,
//!   in the body's *centred* frame (positions less the nodes' mean), lie within the slack of each
//!   other. A body that falls, slides or turns slowly keeps its list: only its deformation leaves
//!   the slack. Each tick checks that every node's centred start and end lie within
//!   [`SELF_SLACK`] of its box at the listing (then every point of its trajectory does: the
//!   centred position along a straight trajectory is the same blend of the two, and a box grown by
//!   the slack is convex), so that a pair not listed cannot meet; else the body lists again. The
//!   net's stops change the ends: a node stopped short leaves its centred trajectory by up to the
//!   body's mean displacement (a ball landing at 3 m/s moves 3 mm a tick, the slack is 1 mm), so
//!   after each round the nodes the round answered are checked again, and a body one of them left
//!   is listed again (about the nodes' mean as they now end: any straight path of a centre shared
//!   by every node will do) and has every pair tested in the next round.
//! - **Near pairs**, triangles that share a node or have nodes one edge apart: always beside each
//!   other, so their boxes tell nothing. They are listed from the topology alone (again when it
//!   changes), and a tick tests those that are *bent* towards each other (see [`bent`]): normals
//!   more than [`BEND`] apart at the tick's start or at its end, and neither triangle on one side
//!   of the other's plane. A surface creases, and its sheets fold onto each other, only by bending
//!   the faces of the crease through large angles; faces that stay near parallel lie beside each
//!   other on a smooth patch and cannot meet anywhere but at the nodes they share (a normal-cone
//!   argument, as cloth simulators cull self-collisions; it is a criterion, not a proof: a fan of
//!   faces crumpled around one node with every pair within [`BEND`] is not tested). Pairs of
//!   smooth nodes are not looked at (see [`smoothness`]); after each round of the net, the pairs of
//!   the triangles whose nodes it moved are looked at again. Of a near pair, the vertex–face and
//!   edge–edge pairs that share a node are never tested (they meet at that node by construction).

use crate::Room;
use crate::Vec3;
use crate::body::Body;
use crate::collision::bvh::TriangleBvh;

/// How far a node's centred position may leave its box at the listing before the body lists its
/// far pairs again (m).
pub(super) const SELF_SLACK: f64 = 1e-3;

/// The angle between two near triangles' normals (rad) beyond which a tick tests them: 60°.
pub(super) const BEND: f64 = std::f64::consts::FRAC_PI_3;

/// A near pair one of whose triangles lies on one side of the other's plane by more than this many
/// times its nodes' largest motion relative to the body, plus [`RIDGE_MARGIN`], is not tested (see
/// [`bent`]).
const RIDGE_REACH: f64 = 8.0;

/// The least distance (m) from the other's plane of a near pair not tested.
const RIDGE_MARGIN: f64 = 1e-5;

/// Most far pairs a body lists per triangle it may have.
const PAIRS_PER_TRIANGLE: usize = 32;

/// Most near pairs a body lists per triangle it may have (a triangle of a mesh whose nodes have
/// six neighbours has about 35 near triangles, each pair listed once: about 17).
const NEAR_PER_TRIANGLE: usize = 32;

/// One body's self-contact state.
#[derive(Clone, Debug)]
struct SelfBody {
    /// The topology (version, node count, triangle count) the adjacency and lists are for.
    topology: Option<(u64, usize, usize)>,
    /// Each node's neighbours (one edge away), as offsets into `neighbours`.
    offsets: Room<u32>,
    neighbours: Room<u32>,
    /// Each node's triangles, as offsets into `incident`.
    incident_offsets: Room<u32>,
    incident: Room<u32>,
    /// Per triangle, the last triangle whose near pairs it was counted in, plus one.
    stamp: Room<u32>,
    /// The near pairs (first triangle below the second) and whether they are all there.
    near: Room<(u32, u32)>,
    near_complete: bool,
    /// This tick's bent near pairs.
    bent: Room<(u32, u32)>,
    /// Per node, its displacement over the tick relative to the body's nodes' mean (m).
    motion: Room<f64>,
    /// Per near pair, whether it is in `bent`.
    is_bent: Room<bool>,
    /// Per triangle and per node, whether it is smooth this tick (see [`smoothness`]).
    smooth: Room<bool>,
    node_smooth: Room<bool>,
    /// Per triangle, `touch_mark` when a node of it moved in the net's last round.
    touched: Room<u32>,
    /// Per triangle, its near pairs (indices into `near`), as offsets into `pair_index` (empty
    /// when the near pairs are not all listed).
    pair_offsets: Room<u32>,
    pair_index: Room<u32>,
    /// One bit per near pair: those to look at again after a round (see [`bend_moved`]).
    pair_bits: Room<u64>,
    touch_mark: u32,
    /// Per triangle, its unit normal at the tick's start and at its end.
    normals: Room<[Vec3; 2]>,
    /// Per node, its centred box at the listing (lower and upper corners).
    lower: Room<Vec3>,
    upper: Room<Vec3>,
    /// The far pairs (first triangle below the second) and whether they are all there.
    pairs: Room<(u32, u32)>,
    complete: bool,
    /// Whether a listing holds (false: list again this tick).
    listed: bool,
    /// The nodes' mean at the start and the end of this tick.
    centre: [Vec3; 2],
    /// Whether the last round of the net listed the body again (its next round tests every pair).
    retest: bool,
}

impl SelfBody {
    /// Whether the far listing holds for the body's trajectories: every node's centred start and
    /// end (about `centre`) within [`SELF_SLACK`] of its centred box at the listing.
    fn holds(&self, body: &Body) -> bool {
        let s = &body.surface;
        let n = s.position_in_world.len();
        if !self.listed || self.lower.len() != n {
            return false;
        }
        let [c0, c1] = self.centre;
        (0..n).all(|v| {
            within_slack(
                &(s.position_in_world[v] - c0),
                &self.lower[v],
                &self.upper[v],
            ) && within_slack(
                &(s.next_position_in_world[v] - c1),
                &self.lower[v],
                &self.upper[v],
            )
        })
    }
}

/// Whether centred point `p` lies within [`SELF_SLACK`] of the box with corners `lo` and `hi`.
fn within_slack(p: &Vec3, lo: &Vec3, hi: &Vec3) -> bool {
    (0..3).all(|d| p[d] >= lo[d] - SELF_SLACK && p[d] <= hi[d] + SELF_SLACK)
}

/// Every body's self-contact state (no room for the pieces of a cut: a body cut or torn has no
/// self-contact).
#[derive(Clone, Debug)]
pub(super) struct SelfPairs {
    bodies: Vec<SelfBody>,
}

impl SelfPairs {
    /// Room for `bodies` (and none for `spare` bodies yet to come: the pieces of a cut, which has
    /// no self-contact). Bodies without self-contact get no room.
    pub(super) fn new(bodies: &[Body], spare: usize) -> Self {
        let room = |nodes: usize, triangles: usize, edges: usize| SelfBody {
            topology: None,
            offsets: Room::with_capacity(nodes + 1),
            neighbours: Room::with_capacity(2 * edges),
            incident_offsets: Room::with_capacity(nodes + 1),
            incident: Room::with_capacity(3 * triangles),
            stamp: Room::with_capacity(triangles),
            near: Room::with_capacity(NEAR_PER_TRIANGLE * triangles),
            near_complete: true,
            bent: Room::with_capacity(NEAR_PER_TRIANGLE * triangles),
            normals: Room::with_capacity(triangles),
            is_bent: Room::with_capacity(NEAR_PER_TRIANGLE * triangles),
            touched: Room::with_capacity(triangles),
            pair_offsets: Room::with_capacity(triangles + 1),
            pair_index: Room::with_capacity(2 * NEAR_PER_TRIANGLE * triangles),
            pair_bits: Room::with_capacity((NEAR_PER_TRIANGLE * triangles).div_ceil(64)),
            touch_mark: 0,
            smooth: Room::with_capacity(triangles),
            node_smooth: Room::with_capacity(nodes),
            motion: Room::with_capacity(nodes),
            lower: Room::with_capacity(nodes),
            upper: Room::with_capacity(nodes),
            pairs: Room::with_capacity(PAIRS_PER_TRIANGLE * triangles),
            complete: true,
            listed: false,
            centre: [Vec3::zeros(); 2],
            retest: false,
        };
        Self {
            bodies: bodies
                .iter()
                .map(|b| {
                    if !b.params.self_contact_on() {
                        return room(0, 0, 0);
                    }
                    let (nodes, triangles) = b.mesh_capacity();
                    let nodes = nodes.max(b.node_count());
                    room(nodes, triangles, 3 * triangles)
                })
                // (Pieces come only from bodies cut or torn, which have no self-contact.)
                .chain((0..spare).map(|_| room(0, 0, 0)))
                .collect(),
        }
    }

    /// Whether body `k` has its self-contact on.
    pub(super) fn on(bodies: &[Body], k: usize) -> bool {
        bodies.get(k).is_some_and(|b| b.params.self_contact_on())
    }

    /// Brings body `k`'s pairs up to date for this tick, or between two rounds of the net for the
    /// trajectories the rounds left ([`SelfPairs::update_after_round`]) (its adjacency and near pairs when its
    /// topology changed; a new far listing when a node left its slack; the bent near pairs), with
    /// its hierarchy `bvh`; returns false when a list is not complete (a list was full: the pairs
    /// beyond it are not tested).
    pub(super) fn update(&mut self, k: usize, body: &Body, bvh: &mut TriangleBvh) -> bool {
        let Some(state) = self.bodies.get_mut(k) else {
            return false;
        };
        let s = &body.surface;
        let n = s.position_in_world.len();
        let topology = Some((body.topology_version, n, s.triangles.len()));
        if state.topology != topology {
            state.topology = topology;
            state.listed = false;
            adjacency(body, state);
            near_pairs(body, state);
        }
        state.retest = false;
        let near_complete = state.near_complete;
        let mean = |p: &[Vec3]| p.iter().fold(Vec3::zeros(), |sum, x| sum + x) / n.max(1) as f64;
        state.centre = [mean(&s.position_in_world), mean(&s.next_position_in_world)];
        let [c0, c1] = state.centre;
        motion_and_bend(body, state);
        if state.holds(body) {
            return state.complete && near_complete;
        }
        // A new listing: the centred boxes of this tick's trajectories, and the triangle pairs
        // whose boxes grown by the slack meet, found in the hierarchy refitted to them.
        state.lower.clear();
        state.upper.clear();
        state.pairs.clear();
        if n > state.lower.capacity() || state.offsets.len() != n + 1 {
            state.complete = false;
            state.listed = false;
            return false;
        }
        for v in 0..n {
            let (a, b) = (
                s.position_in_world[v] - c0,
                s.next_position_in_world[v] - c1,
            );
            state.lower.push(a.inf(&b));
            state.upper.push(a.sup(&b));
        }
        if !bvh.is_built_for(body.topology_version, s.triangles.len()) {
            bvh.rebuild(&s.triangles, &s.position_in_world);
            bvh.set_built_version(body.topology_version);
        }
        bvh.refit(&s.triangles, &state.lower, &state.upper, SELF_SLACK);
        state.complete = true;
        state.listed = true;
        // One traversal of the hierarchy against itself (where a query per triangle walks it from
        // the root once per triangle), then put in the order those queries gave: by the first
        // triangle, then the second's place in the leaves. (A list that fills up keeps other
        // pairs than the queries kept; it is counted, and its tick's collisions are frozen.)
        let mut pairs = std::mem::take(&mut state.pairs);
        let triangles = &s.triangles;
        state.complete = bvh.self_overlapping_pairs(
            |ta, tb| !near_in_mesh(state, &triangles[ta as usize], &triangles[tb as usize]),
            &mut pairs,
        );
        pairs.sort_unstable_by_key(|&(ta, tb)| (ta, bvh.rank(tb)));
        state.pairs = pairs;
        // A list not complete is made again next tick.
        state.listed = state.complete;
        state.complete && near_complete
    }

    /// Body `k`'s bent near pairs found again with the trajectories the net's round before
    /// shortened (stopping some nodes of a triangle and not others can turn it over).
    /// `answered` holds each node's mark of the last round that answered a collision of it, plus
    /// one; `round` is this round.
    pub(super) fn bend_again(&mut self, k: usize, body: &Body, answered: &[u32], round: usize) {
        if let Some(state) = self.bodies.get_mut(k) {
            bend_moved(body, state, answered, round);
        }
    }

    /// Whether body `k`'s lists hold every pair that may meet.
    pub(super) fn complete(&self, k: usize) -> bool {
        self.bodies
            .get(k)
            .is_some_and(|b| b.complete && b.near_complete)
    }

    /// Body `k`'s far pairs.
    pub(super) fn pairs(&self, k: usize) -> &[(u32, u32)] {
        self.bodies.get(k).map_or(&[], |b| &b.pairs[..])
    }

    /// Body `k`'s near pairs bent beyond [`BEND`] this tick.
    pub(super) fn bent(&self, k: usize) -> &[(u32, u32)] {
        self.bodies.get(k).map_or(&[], |b| &b.bent[..])
    }

    /// Body `k`'s near pairs (all of them, bent or not).
    #[cfg(test)]
    fn near(&self, k: usize) -> &[(u32, u32)] {
        self.bodies.get(k).map_or(&[], |b| &b.near[..])
    }

    /// Whether node `v` of body `k` ending at `end` keeps the far listing: the test
    /// [`SelfPairs::update`] makes of it, exactly.
    fn keeps_listing(&self, k: usize, v: usize, end: &Vec3) -> bool {
        let Some(b) = self.bodies.get(k) else {
            return false;
        };
        if !b.listed || v >= b.lower.len() {
            return false;
        }
        within_slack(&(end - b.centre[1]), &b.lower[v], &b.upper[v])
    }

    /// Whether body `k`'s far listing holds for its trajectories as they now are (see
    /// [`SelfPairs::update`]).
    pub(super) fn holds(&self, k: usize, body: &Body) -> bool {
        self.bodies.get(k).is_some_and(|b| b.holds(body))
    }

    /// After a round of the net: whether a node of body `k` that the round answered (its mark in
    /// `answered` is `round` + 1) ends outside the far listing's slack (stopping a node short moves
    /// its centred end off its centred trajectory, by up to the body's mean displacement, which a
    /// body falling or thrown makes larger than the slack). Such a body is brought up to date
    /// ([`SelfPairs::update`], which lists again about its nodes' mean as they now end, and finds
    /// its bent pairs again); `Some(complete)` then, and every pair of it is to be tested in the
    /// next round. `None` when every such node ends within the slack.
    pub(super) fn update_after_round(
        &mut self,
        k: usize,
        body: &Body,
        bvh: &mut TriangleBvh,
        (answered, round): (&[u32], usize),
    ) -> Option<bool> {
        let s = &body.surface;
        let left = answered
            .iter()
            .enumerate()
            .take(s.next_position_in_world.len())
            .any(|(v, &mark)| {
                mark as usize == round + 1
                    && !self.keeps_listing(k, v, &s.next_position_in_world[v])
            });
        let complete = left.then(|| self.update(k, body, bvh));
        if let Some(state) = self.bodies.get_mut(k) {
            state.retest = left;
        }
        complete
    }

    /// Whether the net's last round listed body `k` again ([`SelfPairs::update_after_round`]):
    /// then every pair of it is tested in this round, whether or not its nodes moved.
    pub(super) fn retest(&self, k: usize) -> bool {
        self.bodies.get(k).is_some_and(|b| b.retest)
    }

    /// Body `k`'s nodes' mean displacement over the tick (as it began; m).
    pub(super) fn shift(&self, k: usize) -> Vec3 {
        self.bodies
            .get(k)
            .map_or(Vec3::zeros(), |b| b.centre[1] - b.centre[0])
    }

    /// How far the nodes `nodes` of body `k` (`body`) move over the tick relative to the body's
    /// nodes' mean, at most (m).
    pub(super) fn relative_motion(&self, k: usize, body: &Body, nodes: &[u32]) -> f64 {
        if self.bodies.get(k).is_none() {
            return f64::INFINITY;
        }
        let shift = self.shift(k);
        nodes
            .iter()
            .map(|&v| relative_displacement(body, v as usize, &shift))
            .fold(0.0, f64::max)
    }
}

/// Whether triangles `a` and `b` share a node or have nodes one edge apart.
fn near_in_mesh(state: &SelfBody, a: &[u32; 3], b: &[u32; 3]) -> bool {
    a.iter().any(|&v| {
        b.contains(&v) || {
            let (from, to) = (
                state.offsets[v as usize] as usize,
                state.offsets[v as usize + 1] as usize,
            );
            state.neighbours[from..to].iter().any(|w| b.contains(w))
        }
    })
}

/// Compressed lists `(offsets, items)` of `n` keys from `pairs` (key, item), in the pairs' order;
/// false (the lists left empty) when they do not fit their room.
fn compressed(
    n: usize,
    pairs: impl Iterator<Item = (u32, u32)> + Clone,
    offsets: &mut Room<u32>,
    items: &mut Room<u32>,
) -> bool {
    offsets.clear();
    items.clear();
    let count = pairs.clone().filter(|&(key, _)| (key as usize) < n).count();
    if n + 1 > offsets.capacity() || count > items.capacity() {
        return false;
    }
    offsets.resize(n + 1, 0);
    for (key, _) in pairs.clone() {
        if (key as usize) < n {
            offsets[key as usize + 1] += 1;
        }
    }
    for v in 0..n {
        offsets[v + 1] += offsets[v];
    }
    items.resize(count, 0);
    // Each key's run from its offset: a cursor per key kept in the offsets themselves (each ends
    // at the next key's start, shifted back afterwards).
    for (key, item) in pairs {
        let key = key as usize;
        if key < n {
            let slot = offsets[key] as usize;
            items[slot] = item;
            offsets[key] += 1;
        }
    }
    for v in (1..=n).rev() {
        offsets[v] = offsets[v - 1];
    }
    offsets[0] = 0;
    true
}

/// Each node's neighbours from the body's edges, and each node's triangles (none for a body with
/// more than the room).
fn adjacency(body: &Body, state: &mut SelfBody) {
    let n = body.node_count();
    let edges = &body.edges;
    let both_ways = edges
        .a
        .iter()
        .zip(&edges.b)
        .filter(|&(&a, &b)| (a as usize) < n && (b as usize) < n)
        .flat_map(|(&a, &b)| [(a, b), (b, a)]);
    compressed(n, both_ways, &mut state.offsets, &mut state.neighbours);
    let triangles = &body.surface.triangles;
    let corners = triangles
        .iter()
        .enumerate()
        .flat_map(|(t, c)| c.map(|v| (v, t as u32)));
    compressed(n, corners, &mut state.incident_offsets, &mut state.incident);
}

/// Lists the body's near pairs: each triangle with every later one that shares a node with it or
/// has a node one edge from one of its own.
fn near_pairs(body: &Body, state: &mut SelfBody) {
    let n = body.node_count();
    let triangles = &body.surface.triangles;
    state.near.clear();
    // (No index until the near pairs are all listed.)
    state.pair_offsets.clear();
    state.pair_bits.clear();
    state.stamp.clear();
    state.near_complete = state.offsets.len() == n + 1
        && state.incident_offsets.len() == n + 1
        && triangles.len() <= state.stamp.capacity();
    if !state.near_complete {
        return;
    }
    state.stamp.resize(triangles.len(), 0);
    state.touched.clear();
    state.touched.resize(triangles.len(), 0);
    let SelfBody {
        offsets,
        neighbours,
        incident_offsets,
        incident,
        stamp,
        near,
        near_complete,
        ..
    } = state;
    let run = |offsets: &Room<u32>, v: u32| {
        offsets[v as usize] as usize..offsets[v as usize + 1] as usize
    };
    for (ta, corners) in triangles.iter().enumerate() {
        let mark = ta as u32 + 1;
        for &c in corners {
            let ring = neighbours[run(offsets, c)].iter();
            for &v in std::iter::once(&c).chain(ring) {
                for &tb in &incident[run(incident_offsets, v)] {
                    if tb as usize <= ta || stamp[tb as usize] == mark {
                        continue;
                    }
                    stamp[tb as usize] = mark;
                    if near.len() == near.capacity() {
                        *near_complete = false;
                        return;
                    }
                    near.push((ta as u32, tb));
                }
            }
        }
    }
    pairs_by_triangle(triangles.len(), state);
}

/// Each triangle's near pairs, as offsets into an index of `near` (each pair under both its
/// triangles, in the order of `near`); none when there is no room.
fn pairs_by_triangle(triangles: usize, state: &mut SelfBody) {
    let SelfBody {
        near,
        pair_offsets,
        pair_index,
        pair_bits,
        ..
    } = state;
    pair_bits.clear();
    let by_triangle = near
        .iter()
        .enumerate()
        .flat_map(|(p, &(a, b))| [(a, p as u32), (b, p as u32)]);
    if compressed(triangles, by_triangle, pair_offsets, pair_index)
        && near.len().div_ceil(64) <= pair_bits.capacity()
    {
        pair_bits.resize(near.len().div_ceil(64), 0);
    } else {
        pair_offsets.clear();
    }
}

/// Whether `state` has an index of each of its `triangles` triangles' near pairs (see
/// [`pairs_by_triangle`]).
fn indexed(state: &SelfBody, triangles: usize) -> bool {
    state.pair_offsets.len() == triangles + 1
        && state.pair_bits.len() == state.near.len().div_ceil(64)
}

/// Visits the near pairs whose bits are set, lowest first, clearing the bits.
fn take_bits(state: &mut SelfBody, mut visit: impl FnMut(&mut SelfBody, usize)) {
    for word in 0..state.pair_bits.len() {
        let mut bits = std::mem::take(&mut state.pair_bits[word]);
        while bits != 0 {
            let p = word * 64 + bits.trailing_zeros() as usize;
            bits &= bits - 1;
            visit(state, p);
        }
    }
}

/// A node's displacement over the tick relative to the body's nodes' mean displacement (as the
/// tick began; `shift`).
fn relative_displacement(body: &Body, v: usize, shift: &Vec3) -> f64 {
    let s = &body.surface;
    (s.next_position_in_world[v] - s.position_in_world[v] - shift).norm()
}

/// A triangle's unit normal with the positions `x` (zero for a triangle with no area).
fn unit_normal(x: &[Vec3], t: &[u32; 3]) -> Vec3 {
    let [a, b, c] = t.map(|v| x[v as usize]);
    (b - a)
        .cross(&(c - a))
        .try_normalize(0.0)
        .unwrap_or_else(Vec3::zeros)
}

/// Each node's relative displacement, each triangle's normals, and the bent near pairs (see
/// [`bent`]), for the whole body.
fn motion_and_bend(body: &Body, state: &mut SelfBody) {
    let s = &body.surface;
    let n = s.position_in_world.len();
    let shift = state.centre[1] - state.centre[0];
    state.motion.clear();
    state.normals.clear();
    state.bent.clear();
    state.is_bent.clear();
    if n > state.motion.capacity()
        || s.triangles.len() > state.normals.capacity()
        || state.near.len() > state.is_bent.capacity()
    {
        state.near_complete = false;
        return;
    }
    state
        .motion
        .extend((0..n).map(|v| relative_displacement(body, v, &shift)));
    state.normals.extend(s.triangles.iter().map(|t| {
        [
            unit_normal(&s.position_in_world, t),
            unit_normal(&s.next_position_in_world, t),
        ]
    }));
    smoothness(body, state);
    if !indexed(state, s.triangles.len()) {
        for p in 0..state.near.len() {
            let (ta, tb) = state.near[p];
            let smooth = |t: u32| state.smooth.get(t as usize) == Some(&true);
            let yes = !(smooth(ta) && smooth(tb)) && bent(body, state, ta, tb);
            state.is_bent.push(yes);
            if yes {
                // (Both lists have the same room; the bent are some of the near.)
                state.bent.push((ta, tb));
            }
        }
        return;
    }
    // The pairs with a triangle that is not smooth, found through the index, in the order of the
    // near pairs (the bits, lowest first): the same pairs as a sweep of all of them.
    state.is_bent.resize(state.near.len(), false);
    for t in 0..s.triangles.len() {
        if state.smooth.get(t) == Some(&true) {
            continue;
        }
        let pairs = state.pair_offsets[t] as usize..state.pair_offsets[t + 1] as usize;
        for &p in &state.pair_index[pairs] {
            state.pair_bits[p as usize / 64] |= 1 << (p % 64);
        }
    }
    take_bits(state, |state, p| {
        let (ta, tb) = state.near[p];
        if bent(body, state, ta, tb) {
            state.is_bent[p] = true;
            state.bent.push((ta, tb));
        }
    });
}

/// Which triangles are *smooth*: each of their nodes' triangles within a quarter of [`BEND`] of
/// an axis of that node (the mean of their normals), at the tick's start and at its end. Two near triangles whose nodes
/// are all smooth are not bent: they share a node, whose triangles lie within half of [`BEND`] of
/// each other, or have nodes one edge apart, which share the triangles on that edge, so that the
/// two lie within a quarter, twice, and a quarter again: [`BEND`] (an angle between normals is a
/// distance on the sphere). A smooth organ at rest looks at none of its near pairs.
fn smoothness(body: &Body, state: &mut SelfBody) {
    let n = body.node_count();
    let triangles = &body.surface.triangles;
    state.smooth.clear();
    state.node_smooth.clear();
    if state.incident_offsets.len() != n + 1
        || n > state.node_smooth.capacity()
        || triangles.len() > state.smooth.capacity()
    {
        let room = state.smooth.capacity();
        state.smooth.resize(triangles.len().min(room), false);
        return;
    }
    // (Rounded down a little: the angles are added as distances, each dot product is rounded.)
    let least = (0.99 * BEND / 4.0).cos();
    for v in 0..n {
        let run = state.incident_offsets[v] as usize..state.incident_offsets[v + 1] as usize;
        let around = &state.incident[run];
        // The axis: the mean of the node's triangles' normals (none: a node of no triangle).
        let sum = |k: usize| {
            around
                .iter()
                .fold(Vec3::zeros(), |sum, &t| sum + state.normals[t as usize][k])
        };
        let axis = [sum(0), sum(1)].map(|a| a.try_normalize(0.0).unwrap_or_else(Vec3::zeros));
        let smooth = around.iter().all(|&t| {
            let normal = &state.normals[t as usize];
            normal[0].dot(&axis[0]) >= least && normal[1].dot(&axis[1]) >= least
        });
        state.node_smooth.push(smooth);
    }
    for t in triangles {
        state
            .smooth
            .push(t.iter().all(|&v| state.node_smooth[v as usize]));
    }
}

/// After a round of the net moved the nodes whose mark in `answered` is `round` or more: their
/// relative displacements and their triangles' normals at the end again, and the near pairs of
/// those triangles that are bent now added to the bent (a pair bent earlier in the tick stays,
/// unless the body was listed again since: its bent pairs were all found again then).
fn bend_moved(body: &Body, state: &mut SelfBody, answered: &[u32], round: usize) {
    let s = &body.surface;
    let n = s.position_in_world.len();
    if answered.len() != n
        || state.motion.len() != n
        || state.normals.len() != s.triangles.len()
        || state.touched.len() != s.triangles.len()
        || state.is_bent.len() != state.near.len()
    {
        motion_and_bend(body, state);
        return;
    }
    let shift = state.centre[1] - state.centre[0];
    state.touch_mark = state.touch_mark.wrapping_add(1).max(1);
    let mark = state.touch_mark;
    let mut any = false;
    // (Each triangle's pairs are found through it when it has an index of them.)
    let indexed = indexed(state, s.triangles.len());
    for (v, &answer) in answered.iter().enumerate() {
        if (answer as usize) < round {
            continue;
        }
        any = true;
        state.motion[v] = relative_displacement(body, v, &shift);
        let run = state.incident_offsets[v] as usize..state.incident_offsets[v + 1] as usize;
        for &t in &state.incident[run] {
            if state.touched[t as usize] != mark && indexed {
                let pairs = state.pair_offsets[t as usize] as usize
                    ..state.pair_offsets[t as usize + 1] as usize;
                for &p in &state.pair_index[pairs] {
                    state.pair_bits[p as usize / 64] |= 1 << (p % 64);
                }
            }
            state.touched[t as usize] = mark;
            state.normals[t as usize][1] =
                unit_normal(&s.next_position_in_world, &s.triangles[t as usize]);
        }
    }
    if !any {
        return;
    }
    // Only the pairs with a touched triangle changed (their nodes' motion, their normals), in the
    // order of the near pairs: through the index, the bits set above, lowest first.
    let look = |state: &mut SelfBody, p: usize| {
        let (ta, tb) = state.near[p];
        if !state.is_bent[p] && bent(body, state, ta, tb) {
            state.is_bent[p] = true;
            state.bent.push((ta, tb));
        }
    };
    if indexed {
        take_bits(state, look);
    } else {
        for p in 0..state.near.len() {
            let (ta, tb) = state.near[p];
            if state.touched[ta as usize] == mark || state.touched[tb as usize] == mark {
                look(state, p);
            }
        }
    }
}

/// Whether near pair (`ta`, `tb`) is bent: its normals more than [`BEND`] apart at the tick's start
/// or at its end, and neither triangle on one side of the other's plane — its nodes that are not
/// the other's all on the same side, at the start and at the end, farther than the pair's nodes
/// can bring them over the tick (a ridge, or a valley still open). A triangle on one side of the
/// other's plane meets it only at the nodes they share, so such a pair cannot cross.
fn bent(body: &Body, state: &SelfBody, ta: u32, tb: u32) -> bool {
    let s = &body.surface;
    let (a, b) = (&state.normals[ta as usize], &state.normals[tb as usize]);
    let most = BEND.cos();
    // (A triangle with no area has a zero normal: tested.)
    if a[0].dot(&b[0]) >= most && a[1].dot(&b[1]) >= most {
        return false;
    }
    let (ca, cb) = (&s.triangles[ta as usize], &s.triangles[tb as usize]);
    let reach = ca
        .iter()
        .chain(cb)
        .map(|&v| state.motion[v as usize])
        .fold(0.0, f64::max);
    // What a node's distance to the other's plane may change by: its own motion, the plane's at
    // that node (its corners' motion, extrapolated beyond the triangle: up to a few times it one
    // edge away) and its turning.
    let margin = RIDGE_REACH * reach + RIDGE_MARGIN;
    // The side of `corners`'s plane (normal `n`, positions `x`) that every node of `others` not
    // in `corners` lies on, beyond the margin (0: no one side).
    let side = |x: &[Vec3], corners: &[u32; 3], n: &Vec3, others: &[u32; 3]| {
        if *n == Vec3::zeros() {
            return 0;
        }
        let origin = x[corners[0] as usize];
        let mut sides = others
            .iter()
            .filter(|v| !corners.contains(v))
            .map(|&v| n.dot(&(x[v as usize] - origin)))
            .map(|d| i32::from(d > margin) - i32::from(d < -margin));
        let first = sides.next().unwrap_or(0);
        if sides.all(|s| s == first) { first } else { 0 }
    };
    let (x0, x1) = (&s.position_in_world, &s.next_position_in_world);
    let shut = |one: i32, other: i32| one != 0 && one == other;
    !(shut(side(x0, ca, &a[0], cb), side(x1, ca, &a[1], cb))
        || shut(side(x0, cb, &b[0], ca), side(x1, cb, &b[1], ca)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::{BodyParams, Placement};
    use crate::scene::mesh::icosphere;

    /// The near pairs listed from the topology are exactly the pairs of triangles that share a
    /// node or have nodes one edge apart (brute force over every pair), each once; a round ball at
    /// rest has none bent and no far pair.
    #[test]
    fn near_pairs_are_the_pairs_within_one_edge_each_once() {
        let params = BodyParams {
            self_contact: true,
            ..BodyParams::default()
        };
        let body = Body::new("b", &icosphere(0.03, 2), &params, &Placement::default());
        let mut pairs = SelfPairs::new(std::slice::from_ref(&body), 0);
        let mut bvh = TriangleBvh::with_capacity(body.mesh_capacity().1);
        assert!(pairs.update(0, &body, &mut bvh));
        let triangles = &body.surface.triangles;
        let linked = |u: u32, v: u32| {
            u == v
                || body
                    .edges
                    .a
                    .iter()
                    .zip(&body.edges.b)
                    .any(|(&a, &b)| (a, b) == (u, v) || (a, b) == (v, u))
        };
        let mut expected = Vec::new();
        for i in 0..triangles.len() {
            for j in i + 1..triangles.len() {
                if triangles[i]
                    .iter()
                    .any(|&u| triangles[j].iter().any(|&v| linked(u, v)))
                {
                    expected.push((i as u32, j as u32));
                }
            }
        }
        let mut listed = pairs.near(0).to_vec();
        listed.sort_unstable();
        assert_eq!(listed, expected);
        // 320 triangles, each with 12 others sharing a node (15 where five meet at a node) and
        // about 22 more one edge away, each pair once (5 550), within the room reserved.
        assert!(listed.len() > 320 * 30 / 2 && listed.len() < 320 * 36 / 2);
        assert!(listed.len() <= NEAR_PER_TRIANGLE * 320);
        assert!(pairs.bent(0).is_empty());
        assert!(pairs.pairs(0).is_empty());
        // Every triangle of the round ball is smooth: no near pair is looked at.
        let smooth = &pairs.bodies[0].smooth;
        assert_eq!(smooth.len(), 320);
        assert!(smooth.iter().all(|&s| s));
        // Each triangle's index names its near pairs, in their order.
        let state = &pairs.bodies[0];
        let near = pairs.near(0);
        assert_eq!(state.pair_offsets.len(), 321);
        for t in 0..320u32 {
            let run = state.pair_offsets[t as usize] as usize
                ..state.pair_offsets[t as usize + 1] as usize;
            let indexed: Vec<u32> = state.pair_index[run].to_vec();
            let wanted: Vec<u32> = (0..near.len() as u32)
                .filter(|&p| near[p as usize].0 == t || near[p as usize].1 == t)
                .collect();
            assert_eq!(indexed, wanted, "triangle {t}");
        }
    }

    /// On a crumpled body, the bent pairs found through the index (of the triangles that are not
    /// smooth; of the triangles a round moved) are those a sweep of every near pair finds, in the
    /// same order.
    #[test]
    fn the_index_finds_the_bent_pairs_a_sweep_finds() {
        let params = BodyParams {
            self_contact: true,
            ..BodyParams::default()
        };
        let mut body = Body::new("b", &icosphere(0.03, 2), &params, &Placement::default());
        // The upper half crumpled, the lower half round (smooth).
        let crumple = |k: usize, p: &Vec3, by: f64| {
            let wobble = ((k * 7919) % 17) as f64 / 16.0 - 0.5;
            if p.z > 0.005 {
                p * (1.0 + by * wobble)
            } else {
                *p
            }
        };
        let s = &mut body.surface;
        for k in 0..s.position_in_world.len() {
            let start = crumple(k, &s.position_in_world[k], 0.2);
            s.next_position_in_world[k] = crumple(k + 3, &start, 0.05);
            s.position_in_world[k] = start;
        }
        let mut pairs = SelfPairs::new(std::slice::from_ref(&body), 0);
        let mut bvh = TriangleBvh::with_capacity(body.mesh_capacity().1);
        pairs.update(0, &body, &mut bvh);
        let state = &mut pairs.bodies[0];
        assert!(indexed(state, body.surface.triangles.len()));
        let through_index = (state.bent.to_vec(), state.is_bent.to_vec());
        assert!(
            through_index.0.len() > 50 && through_index.0.len() < state.near.len() / 2,
            "{} of {} bent: the case tells nothing",
            through_index.0.len(),
            state.near.len()
        );
        assert!(state.pair_bits.iter().all(|&w| w == 0), "bits left set");
        println!(
            "{} of {} near pairs bent; {} of {} triangles smooth",
            through_index.0.len(),
            state.near.len(),
            state.smooth.iter().filter(|&&s| s).count(),
            state.smooth.len()
        );
        assert!(state.smooth.iter().any(|&s| s) && !state.smooth.iter().all(|&s| s));
        // A round moves some nodes: their triangles' pairs are looked at again.
        let n = body.node_count();
        let answered: Vec<u32> = (0..n).map(|v| u32::from(v % 5 == 0)).collect();
        for k in (0..n).step_by(5) {
            body.surface.next_position_in_world[k] =
                (body.surface.position_in_world[k] + body.surface.next_position_in_world[k]) / 2.0;
        }
        let mut with_index = state.clone();
        bend_moved(&body, &mut with_index, &answered, 1);
        assert!(
            with_index.bent.len() > through_index.0.len(),
            "the round changed nothing"
        );
        // The same without the index: a sweep of every near pair.
        let mut swept = state.clone();
        swept.pair_offsets.clear();
        assert!(!indexed(&swept, body.surface.triangles.len()));
        bend_moved(&body, &mut swept, &answered, 1);
        assert_eq!(with_index.bent, swept.bent);
        assert_eq!(with_index.is_bent, swept.is_bent);
        let mut swept = state.clone();
        swept.pair_offsets.clear();
        motion_and_bend(&body, &mut swept);
        let mut again = state.clone();
        motion_and_bend(&body, &mut again);
        assert_eq!(again.bent, swept.bent);
        assert_eq!(again.is_bent, swept.is_bent);
        // (The moved nodes changed the bends: not those of the start.)
        assert_ne!(again.bent.to_vec(), through_index.0);
    }
}
