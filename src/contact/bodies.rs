//! Contact between deformable bodies (paper §5: collisions are found on trajectories).
//!
//! After every other stage has decided where the nodes end the tick, the trajectories of different
//! bodies meet in two stages. Both look first at each body's bounds swept over the tick; where
//! bodies' bounds meet, their candidates come from lists kept from tick to tick (a Verlet list,
//! [`CandidateCache`]): listed from the bodies' hierarchies ([`TriangleBvh`]) only when a node
//! left a slack around where it was at the listing, and checked every tick (and net round) against
//! that tick's triangle boxes — the candidates, in the order, of a traversal of hierarchies refitted
//! every tick, at a cost that follows the contact region and not the bodies' sizes. A resting
//! stack lists once and refits no hierarchy.
//!
//! 1. The **response** ([`respond_to_body_contacts`]): vertex–face and edge–edge contacts within a
//!    skin, answered with inelastic normal impulses and Coulomb friction, equal and opposite on the
//!    two bodies (so the pair's momentum is kept and the forces obey Newton's third law), each
//!    contact of last tick started from last tick's impulses (warm start). A vertex that starts the
//!    tick over a face within the skin stays in contact with it, wherever the integration took the
//!    two; the obstacles under the contacts' nodes are one-sided rows of the same solve. An edge
//!    whose nearest side changed keeps, besides its new contact, a contact with the side it pressed
//!    last tick while that side is within the skin, its normal impulse capped at half of last
//!    tick's (a held contact): the side's nodes are let down over a few ticks, not dropped at once.
//! 2. The **net** ([`resolve_body_collisions`]): the triangle pairs whose boxes meet, and the
//!    narrow phase tests each pair's vertices against the other's face (both ways) and
//!    each edge against the other's edges, with the earliest time of impact. What collides takes an
//!    inelastic impulse along the pair's normal at the impact, on its four nodes' velocities and
//!    end positions together ([`impulse_apart`]: their momentum kept, no kinetic energy added);
//!    after a round with impulses the bounds and lists are brought up to date, since an impulse may
//!    move an end beyond its trajectory. This repeats a few rounds, as moving some nodes can expose
//!    other pairs; then what still collides (or what the impulse cannot answer) stops short of the
//!    impact, at 90 % of the (lower-bound) time of impact along its own trajectory, with the four
//!    nodes' mean velocity, for a few rounds more; what still collides after that is frozen at its start-of-tick position,
//!    where the previous tick left everything apart (in further rounds until nothing collides:
//!    freezing some nodes changes their triangles' trajectories). Primitives that touch at the start of the tick
//!    and separate over it are left alone, so bodies can part. Nodes held by a tool are moved by the
//!    tool only.

use crate::Room;
use crate::Vec3;
use crate::body::Body;
use crate::collision::bvh::{TriangleBvh, owns_side, owns_vertex};
use crate::collision::ccd::{CcdSettings, edge_edge_time_of_impact, vertex_face_time_of_impact};
use crate::collision::obstacle::Obstacle;
use crate::collision::tool::{
    Aabb, closest_point_on_triangle, segment_segment_closest, segment_segment_distance,
};
use crate::contact::self_pairs::SelfPairs;
use crate::contact::tool::NO_TOOL;

#[path = "untangle.rs"]
mod untangle;

/// Contact skin (m): a vertex that ends the tick within this distance of another body's face is in
/// contact with it, and the response keeps it from closing the gap further.
pub const CONTACT_SKIN: f64 = 1e-3;
/// Distance (m) the response keeps between a vertex and the face it rests on: half the skin, far
/// above the collision net's precision, so that resting contact never reaches the net (which stops
/// nodes without friction).
const REST_DISTANCE: f64 = 0.5 * CONTACT_SKIN;
/// Sweeps of the contact solver over the contacts of a tick (in a fixed order). Four hold what
/// eight did (the body-on-body inclined plane within 0.3 %, resting and stacked organs at rest,
/// no node inside another: `tests/body_contact.rs`) at two thirds of the stacked response's cost;
/// two leave more to the collision net and an implicit organ at rest more kinetic energy.
const SOLVER_ITERATIONS: usize = 4;
/// Capacity of the list of faces one vertex's or edge's box meets.
const FOUND_CAPACITY: usize = 4096;
/// Capacity of the contact list (vertex–face contacts between bodies in one tick).
const CONTACT_CAPACITY: usize = 1 << 14;
/// Relative margin over the skin of the cheap tests that turn a candidate down before its closest
/// points are computed.
const EARLY_OUT_MARGIN: f64 = 1e-6;
/// Fraction of the shortfall below the rest distance the end positions are parted by per tick
/// (positions only: no velocity, so no kinetic energy, is added).
const PART_RATE: f64 = 0.2;

/// Margin (m) over the nodes' motion below which the collision net runs the continuous query (far
/// above the query's precision, 1 µm).
const FILTER_MARGIN: f64 = 1e-5;
/// Capacity of the collision net's candidate triangle-pair list.
const PAIR_CAPACITY: usize = 1 << 16;
/// Relative room between the square of a lower bound of a distance (a point's to a plane, or
/// between two lines) and the square of the distance, far above the rounding of either.
const BOUND_ROUNDING: f64 = 1e-6;
/// Room (m) left for rounding when a gap between anchor boxes is weighed against how far the nodes
/// left them (differences of coordinates: far above their rounding for bodies within kilometres of
/// the origin).
const GAP_ROUNDING: f64 = 1e-7;
/// Half-width (m), per axis, of the region a node's trajectory may wander over from its box in its
/// body's anchor (see `CandidateCache::anchor`) before the anchor is taken again: small beside the
/// gaps between the triangles of bodies at rest on each other (a tenth of a millimetre and more),
/// large beside what a resting node moves in a tick.
const ANCHOR_SLACK: f64 = 2.5e-5;
/// Least ticks of the net between two takings of the anchors (see `CandidateCache::anchor`):
/// bodies that keep moving take them, and find their least gaps, once in so many ticks.
const ANCHOR_HELD: u64 = 8;
/// Rounds of the collision net before the remaining collisions are frozen: the first
/// [`IMPULSE_ROUNDS`] answer a collision with an inelastic impulse, the others by stopping short.
const ROUNDS: usize = 8;
/// Rounds of the collision net that answer a collision with an inelastic normal impulse on the
/// pair's four nodes ([`impulse_apart`]); what they leave is stopped short.
const IMPULSE_ROUNDS: usize = 4;
/// Least gap (m) the net's impulse leaves between two primitives along their normal at the end of
/// the tick: ten times the continuous query's precision (1 µm), far below the response's rest
/// distance.
const NET_GAP: f64 = 1e-5;
/// Most rounds of freezing after them: freezing a pair's nodes at their start changes the
/// trajectories of the triangles they belong to, which may meet another body's anew (its nodes
/// moved); each such round freezes those too, until a round finds nothing (every node frozen, the
/// previous tick's state, is apart) or this bound is reached (counted in `frozen` as ever).
const FREEZE_ROUNDS: usize = 16;
/// Most a contact's impulse may move one of its nodes, in times the change of the contact's
/// relative motion it makes. A free node of weight w among nodes a tool holds (which do not move)
/// would move 1/w times it: two organs squeezed by a probe into each other's faces, where a node of
/// weight 1e-6 took 1e6 times the correction and the solve diverged to 1e15 m/s within a tick.
/// Between free nodes whose masses are in a ratio r the most is about 1 at r = 4, 2.4 at r = 25
/// and 6.9 at r = 256 (an edge pair's light node; 8 is reached near r = 350): the bound leaves
/// such contacts as they were up to a ratio of 256. A contact the bound relaxes may also close as
/// fast as its held nodes close it (see where it is prepared in [`respond_to_body_contacts`]).
const MAX_AMPLIFICATION: f64 = 8.0;
/// Fraction of the time of impact a colliding node is allowed to travel.
const STOP_SHORT: f64 = 0.9;

/// What the body–body stage did in one step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BodyContactCounters {
    /// Pairs the broad phase passed to the narrow phase: the response's vertex–face pairs (a vertex
    /// and a face whose boxes over the tick meet within the skin) and edge–edge pairs (two edges
    /// whose ends' boxes at the end of the tick are within the skin), and the net's triangle pairs.
    pub candidate_pairs: u32,
    /// Vertex–face and edge–edge collisions answered.
    pub collisions: u32,
    /// Collisions still found after the rounds ran out, answered by freezing their nodes at their
    /// start-of-tick positions.
    pub frozen: u32,
    /// Collisions answered by an inelastic impulse (the others of `collisions` were stopped short
    /// or frozen).
    pub impulses: u32,
    /// Rounds of the net that answered with impulses, after which the bodies' bounds, largest
    /// motions and candidate lists were brought up to date (an impulse may move an end beyond the
    /// trajectory they were made for).
    pub relisted_rounds: u32,
    /// Broad-phase queries that filled the pair list: the pairs it holds are answered by freezing,
    /// pairs beyond its capacity are not tested (counted so it is never silent).
    pub overflows: u32,
    /// Vertex–face contacts the response solved (before the collision net).
    pub contacts: u32,
    /// Contacts beyond the contact list's capacity (left to the collision net; counted).
    pub contacts_dropped: u32,
    /// Ordered pairs of bodies whose candidates were listed from the hierarchies this tick: by the
    /// response (its entries, and the net's triangle pairs where they were not listed), and by the
    /// net (its triangle pairs alone) where the response's pushes or the net's impulses took a
    /// node out of its slack (the others' were kept from an earlier tick).
    pub listed_pairs: u32,
    /// Times a body with self-contact was brought up to date between two rounds of the net (the
    /// round's stops moved a node's end out of the slack of its far listing; see
    /// `SelfPairs::update_after_round`).
    pub self_listed_again: u32,
    /// Bodies with self-contact whose far listing did not hold for the trajectories the net left
    /// (its last round still answered collisions, with no round after it): pairs of their
    /// triangles may have gone untested.
    pub self_unlisted: u32,
    /// Nodes found inside another body (crossed where the net could not answer, as under a tool
    /// that holds nodes of both), being let out (see `contact/untangle.rs`).
    pub inside_nodes: u32,
    /// Continuous queries of the collision net that spent the box budget
    /// ([`CcdSettings::max_boxes`]): each answered as a hit at the earliest time it had not yet
    /// resolved, an earlier (conservative) time of impact, or a collision where the exact answer
    /// may have been none. Counted so that the bound on a query's time is never silent.
    pub budget_spent: u32,
}

/// A vertex of one body touching a face of another, or an edge touching an edge (or about to,
/// this tick). Side `a` is a vertex (weights 1, 0) or an edge; side `b` a face or an edge (third
/// weight 0). The contact point of each side is the weighted sum of its nodes.
#[derive(Clone, Copy, Debug)]
struct Contact {
    a: [NodeRef; 2],
    wa: [f64; 2],
    b: [NodeRef; 3],
    wb: [f64; 3],
    /// Unit normal from side b towards side a at the end of the tick (at its start for an edge
    /// pair that crossed from within the skin, [`edge_edge_crossed_from_near`]).
    normal: Vec3,
    /// Distance between the two contact points at the end of the tick as integrated (m) (at its
    /// start for such an edge pair).
    distance: f64,
    /// Signed distance along `normal` at the start of the tick (m).
    gap: f64,
    /// Coulomb coefficient of the pair.
    friction: f64,
    /// 1 / effective mass along any direction (1/kg).
    compliance: f64,
    /// Accumulated normal impulse (N·s, ≥ 0) and tangential impulse (N·s) on side a.
    normal_impulse: f64,
    tangent_impulse: Vec3,
    /// Most normal impulse (N·s) the contact may take: infinite but for a held contact (an edge's
    /// contact with a side it pressed last tick that is no longer its nearest, see [`HOLD_SHARE`]).
    cap: f64,
}

impl Contact {
    fn nodes(&self) -> impl Iterator<Item = (NodeRef, f64)> + '_ {
        (0..2)
            .map(|k| (self.a[k], self.wa[k]))
            .chain((0..3).map(|k| (self.b[k], -self.wb[k])))
            .filter(|(_, w)| *w != 0.0)
    }
}

/// A contact's nodes of non-zero weight, in the order of [`Contact::nodes`] (side a's weights, then
/// side b's negated), with their inverse masses and their places in the solver's node list
/// ([`SolverNodes`]): fixed over a tick's solves, so the sweeps read them from one place rather
/// than going through the iterator and the tool check.
#[derive(Clone, Copy, Debug)]
struct ContactNodes {
    count: usize,
    refs: [NodeRef; 5],
    weights: [f64; 5],
    inverse_masses: [f64; 5],
    /// Each weight over the tick (1/s), as the force of an impulse on the node's body takes it.
    weights_per_second: [f64; 5],
    /// Each node's place in the solver's node list.
    slots: [u32; 5],
    /// Normal speed (m/s, ≤ 0) the contact may close its gap at over the tick: down to the rest
    /// distance, no more.
    target_speed: f64,
    /// 1 / compliance (kg): the effective mass along any direction.
    effective_mass: f64,
    /// The work the contact's impulses did on side a's and side b's nodes this tick, in absolute
    /// value (J).
    work: [f64; 2],
    /// The solver's update that last looked at the contact (0: none yet), and whether it changed
    /// nothing then.
    looked: u32,
    idle: bool,
}

impl ContactNodes {
    fn of(bodies: &[Body], c: &Contact, dt: f64) -> Self {
        let mut nodes = ContactNodes {
            count: 0,
            refs: [NodeRef { body: 0, node: 0 }; 5],
            weights: [0.0; 5],
            inverse_masses: [0.0; 5],
            weights_per_second: [0.0; 5],
            slots: [0; 5],
            target_speed: ((REST_DISTANCE - c.gap) / dt).min(0.0),
            effective_mass: 0.0,
            work: [0.0; 2],
            looked: 0,
            idle: false,
        };
        for (r, w) in c.nodes() {
            nodes.refs[nodes.count] = r;
            nodes.weights[nodes.count] = w;
            nodes.weights_per_second[nodes.count] = w / dt;
            nodes.inverse_masses[nodes.count] = inverse_mass_of(bodies, r);
            nodes.count += 1;
        }
        nodes
    }

    /// Side a's point less side b's, from `value` of each node in the solver's list.
    #[inline(always)]
    fn relative(&self, nodes: &[SolverNode], value: impl Fn(&SolverNode) -> Vec3) -> Vec3 {
        let mut sum = Vec3::zeros();
        for i in 0..self.count {
            sum += value(&nodes[self.slots[i] as usize]) * self.weights[i];
        }
        sum
    }
}

/// No place in the solver's node list.
const NO_SLOT: u32 = u32::MAX;

/// A node of the response's contacts as the solver reads and changes it: where it started and ends
/// the tick, its displacement's velocity over the tick, its velocity and inverse mass.
#[derive(Clone, Copy, Debug)]
struct SolverNode {
    r: NodeRef,
    start: Vec3,
    end: Vec3,
    /// (end − start) / Δt when the node was listed, then changed by each impulse's Δv.
    motion: Vec3,
    velocity: Vec3,
    inverse_mass: f64,
    /// Whether a contact of the node took a normal impulse (it ends with its displacement's velocity).
    pushed: bool,
    /// The contacts' force on the node over the tick (N, world), once solved.
    force: Vec3,
    /// The solver's update (see [`solve`]) that last changed the node (0: none yet).
    changed: u32,
}

/// Most obstacle planes one node of the response is held by (a node in a corner of two).
const GROUND_PER_NODE: usize = 2;

/// An obstacle's plane under a node of the response that ends the tick on it or near it (see
/// [`ground_rows`]): the response's impulses may not push the node below the plane (or deeper than it was).
/// The obstacle passes ran before the response and left such nodes on their obstacles; without
/// these rows an organ pressed by another against the table has the nodes between pushed into the
/// table by the response and out again by the next tick's obstacle pass, every tick (a heavy
/// organ on a soft one then jitters and never rests). A one-sided row of the solve, its accumulated
/// impulse ≥ 0 along the plane's normal, the obstacle's side of infinite mass.
#[derive(Clone, Copy, Debug)]
struct GroundRow {
    slot: u32,
    obstacle: u32,
    normal: Vec3,
    /// The least value of `normal · end` the node may end with (m).
    floor: f64,
    /// Accumulated impulse along `normal` (N s).
    impulse: f64,
}

/// The nodes of the response's contacts, each once, side by side. The sweeps read and change this
/// compact list instead of the bodies' arrays (and a node's displacement's velocity is kept up to
/// date by each impulse instead of taken again, with three divisions, from its end and start at
/// each read); the ends and velocities go back to the bodies once the response is done.
#[derive(Clone, Debug)]
struct SolverNodes {
    nodes: Room<SolverNode>,
    /// The obstacles' planes under the listed nodes that rest on them (see [`GroundRow`]).
    ground: Room<GroundRow>,
    /// Per body and node, its place in the list ([`NO_SLOT`]: none; every entry is `NO_SLOT`
    /// between ticks), with room for the body's most nodes.
    slot_of: Vec<Room<u32>>,
}

impl SolverNodes {
    fn new(bodies: &[Body], spare: usize, spare_nodes: usize) -> Self {
        let slot_of: Vec<Room<u32>> = bodies
            .iter()
            .map(|b| Room::with_capacity(b.mesh_capacity().0.max(b.node_count())))
            .chain((0..spare).map(|_| Room::with_capacity(spare_nodes)))
            .collect();
        // Each node at most once.
        let most = slot_of.iter().map(|m| m.capacity()).sum::<usize>();
        Self {
            nodes: Room::with_capacity(most),
            ground: Room::with_capacity(GROUND_PER_NODE * most),
            slot_of,
        }
    }

    /// The place of node `r` (of inverse mass `inverse_mass` for the response) in the lists, listing
    /// it if it is not yet; `None` when the lists are full (they have room for every node of every
    /// body: not expected).
    fn slot(&mut self, bodies: &[Body], (r, inverse_mass): (NodeRef, f64), dt: f64) -> Option<u32> {
        let map = &mut self.slot_of[r.body];
        if map.len() <= r.node {
            // Within the room reserved for the body's most nodes.
            map.resize(bodies[r.body].node_count().max(r.node + 1), NO_SLOT);
        }
        if map[r.node] != NO_SLOT {
            return Some(map[r.node]);
        }
        if self.nodes.len() == self.nodes.capacity() {
            return None;
        }
        let slot = self.nodes.len() as u32;
        map[r.node] = slot;
        let s = &bodies[r.body].surface;
        let (start, end) = (
            s.position_in_world[r.node],
            s.next_position_in_world[r.node],
        );
        self.nodes.push(SolverNode {
            r,
            start,
            end,
            motion: (end - start) / dt,
            velocity: s.velocity_in_world[r.node],
            inverse_mass,
            pushed: false,
            force: Vec3::zeros(),
            changed: 0,
        });
        Some(slot)
    }

    /// The ends and velocities back to the bodies, and the lists emptied.
    fn write_back(&mut self, bodies: &mut [Body]) {
        for n in &self.nodes {
            let s = &mut bodies[n.r.body].surface;
            s.next_position_in_world[n.r.node] = n.end;
            s.velocity_in_world[n.r.node] = n.velocity;
            self.slot_of[n.r.body][n.r.node] = NO_SLOT;
        }
        self.nodes.clear();
        self.ground.clear();
    }
}

/// Scratch memory of the stage, sized when the world is assembled.
#[derive(Clone, Debug)]
pub struct BodyContactScratch {
    /// Per body, whether this tick's response or net moved any of its nodes (reset by
    /// [`respond_to_body_contacts`]; see [`BodyContactScratch::moved`]).
    moved: Room<bool>,
    bvhs: Vec<TriangleBvh>,
    pairs: Room<(u32, u32)>,
    contacts: Room<Contact>,
    /// The nodes of each contact of `contacts` (after the one-per-vertex selection).
    contact_nodes: Room<ContactNodes>,
    /// The contacts' nodes, each once, as the solver reads and moves them.
    solver_nodes: SolverNodes,
    found: Room<u32>,
    /// A body's triangles whose boxes meet another body's bounds (room for the most triangles a
    /// body may have).
    near_triangles: Room<u32>,
    /// A vertex's candidate faces with its distance to each (room for the most triangles a body
    /// may have).
    faces_near: Room<(f64, u32)>,
    /// The faces whose boxes meet one vertex's, before their distances are taken.
    faces_boxed: Room<u32>,
    settings: CcdSettings,
    /// Each body's swept bounds this tick, and whether they meet another body's.
    bounds: Room<Aabb>,
    near: Room<bool>,
    /// What the response left for the collision net this tick (see [`Prepared`]).
    prepared: Prepared,
    /// Each body's swept bounds with no margin, from the response: grown by the ends of tick the
    /// response moved, they hold the net's bounds.
    tight_bounds: Room<Aabb>,
    /// The triangles' boxes over this tick (or net round).
    now: TriangleBoxes,
    /// The response's and the net's candidate pairs, listed again only where bodies moved.
    cache: CandidateCache,
    /// The triangle pairs of each body with self-contact on.
    self_pairs: SelfPairs,
    /// Each body's largest node displacement over the tick (m), at least.
    max_motion: Room<f64>,
    /// Collisions the net's current run answered by an impulse (which may move an end beyond its
    /// trajectory).
    impulses: u32,
    /// Continuous queries of the net's current run that spent the box budget.
    budget_spent: u32,
    /// Per body and node, 1 + the last round of the collision net that answered a collision of
    /// the node this tick (0: none), with room for the body's most nodes (see
    /// [`worth_testing`]).
    answered: Vec<Room<u32>>,
    /// Per body (and room for pieces), whether a mark of `answered` is set: the net's run clears
    /// them first, so that the marks the response reads are those of the net's last run only.
    marked: Vec<bool>,
    /// Nodes found inside another body, let out (see `contact/untangle.rs`).
    untangle: untangle::Untangle,
    /// The force the contact response put on each body this tick (N, world frame): the impulses on
    /// its nodes over the step (those on a node a tool moves go on to the tool). Equal and opposite
    /// between two touching bodies.
    pub forces: Vec<Vec3>,
    /// The work the contact response's impulses did on each body this tick, in absolute value (J):
    /// energy the body may gain from the others (a stack's weight compressing the organ below),
    /// which the divergence guard adds to its budget.
    pub work: Vec<f64>,
    /// Last tick's contacts, in their order, with their accumulated impulses (see [`warm_start`]).
    warm: Room<WarmContact>,
    /// The bodies' topology versions when `warm` was kept.
    warm_versions: Room<u64>,
    /// Where the held contacts begin in `warm`.
    warm_held: usize,
    /// Where the remembered contacts begin in `warm`.
    warm_remembered: usize,
    /// The pairs of primitives the next tick's response takes a contact for whatever its nearest
    /// ones are ([`Remembered`]): the collision net's answers of this tick and this tick's
    /// remembered contacts with the impulses they took.
    remembered: Room<Remembered>,
    /// Per entry of `remembered` (sorted, at the response), whether the response's own contacts
    /// hold the pair already.
    remembered_taken: Room<bool>,
    /// Pairs `remembered` had no room for (added to the next response's dropped contacts).
    remembered_dropped: u32,
    /// Last tick's ground rows that pressed, by node and obstacle (sorted), with their accumulated
    /// impulses: the next tick's rows start from them (see [`ground_rows`]).
    ground_warm: Room<(NodeRef, u32, f64)>,
    /// The contact forces this tick's response put on nodes that are sub-stepped (N, world; one
    /// entry a node, in node order), carried into their next tick's substeps
    /// ([`BodyContactScratch::carried_on`]).
    carried: Room<(NodeRef, Vec3)>,
}

/// A vertex–face or edge–edge pair the collision net answered a collision of (or whose contact,
/// taken for that, pressed last tick): the next tick's response takes a contact for it, whether
/// or not the pair is its vertex's (edge's) nearest, so that the net does not stop the same pair
/// again tick after tick. Its normal impulse may be at most half of last tick's, so the contact
/// fades within a few ticks unless the net answers the pair again. A soft ball landing on an organ: 93 % of the net's answers there were
/// the pair it answered the tick before, which the response's nearest contacts did not hold.
#[derive(Clone, Copy, Debug)]
struct Remembered {
    /// The vertex then the face's corners (in the triangle's order), or the two edges (each in
    /// node order, the lower body's first).
    nodes: [NodeRef; 4],
    /// `nodes` with the face's corners sorted: the pair's key.
    key: [NodeRef; 4],
    vertex_face: bool,
    /// Whether the collision net answered the pair.
    answered: bool,
    /// The normal impulse (N·s) the pair's remembered contact took last tick; infinite for a pair
    /// the net answered.
    last_impulse: f64,
}

impl Remembered {
    fn of(mut nodes: [NodeRef; 4], vertex_face: bool, last_impulse: f64) -> Self {
        let mut key = nodes;
        if vertex_face {
            key[1..].sort_unstable();
        } else {
            if nodes[0] > nodes[1] {
                nodes.swap(0, 1);
            }
            if nodes[2] > nodes[3] {
                nodes.swap(2, 3);
            }
            if nodes[0].body > nodes[2].body {
                nodes = [nodes[2], nodes[3], nodes[0], nodes[1]];
            }
            key = nodes;
        }
        Remembered {
            nodes,
            key,
            vertex_face,
            answered: last_impulse == f64::INFINITY,
            last_impulse,
        }
    }

    /// The pair of a contact of the response.
    fn of_contact(c: &Contact) -> Self {
        let vertex_face = c.a[0] == c.a[1];
        let nodes = if vertex_face {
            [c.a[0], c.b[0], c.b[1], c.b[2]]
        } else {
            [c.a[0], c.a[1], c.b[0], c.b[1]]
        };
        Remembered::of(nodes, vertex_face, c.normal_impulse)
    }

    fn order(&self, other: &Self) -> std::cmp::Ordering {
        (self.vertex_face, self.key).cmp(&(other.vertex_face, other.key))
    }
}

/// A contact of last tick and its accumulated impulses (see [`warm_start`]).
#[derive(Clone, Copy, Debug)]
struct WarmContact {
    a: [NodeRef; 2],
    b: [NodeRef; 3],
    normal_impulse: f64,
    tangent_impulse: Vec3,
}

impl BodyContactScratch {
    /// Builds the hierarchies of every body, with room for each body's triangle capacity, and empty
    /// hierarchies with room for `spare_triangles` triangles for `spare` bodies yet to come (pieces of
    /// a transection).
    pub fn new(bodies: &[Body], spare: usize, spare_triangles: usize) -> Self {
        let mut bvhs: Vec<TriangleBvh> = bodies
            .iter()
            .map(|b| {
                let mut bvh = TriangleBvh::with_capacity(b.mesh_capacity().1);
                bvh.rebuild(&b.surface.triangles, &b.surface.position_in_world);
                bvh.set_built_version(b.topology_version);
                bvh
            })
            .collect();
        bvhs.extend((0..spare).map(|_| {
            let mut bvh = TriangleBvh::with_capacity(spare_triangles);
            bvh.set_built_version(u64::MAX);
            bvh
        }));
        let count = bvhs.len();
        let solver_nodes = SolverNodes::new(bodies, spare, 3 * spare_triangles + 3);
        let most_rows = solver_nodes.ground.capacity();
        let most_nodes = solver_nodes.nodes.capacity();
        // Room for each body's most nodes (at most 3 per triangle, as the hierarchy's own).
        let answered: Vec<Room<u32>> = bodies
            .iter()
            .map(|b| Room::with_capacity(b.mesh_capacity().0.max(b.node_count())))
            .chain((0..spare).map(|_| Room::with_capacity(3 * spare_triangles + 3)))
            .collect();
        // The most triangles a body may have, now or as a piece of a transection.
        let most_triangles = bodies
            .iter()
            .map(|b| b.mesh_capacity().1)
            .chain(std::iter::once(spare_triangles))
            .max()
            .unwrap_or(0);
        Self {
            moved: Room::with_capacity(count),
            bvhs,
            pairs: Room::with_capacity(PAIR_CAPACITY),
            contacts: Room::with_capacity(CONTACT_CAPACITY),
            contact_nodes: Room::with_capacity(CONTACT_CAPACITY),
            solver_nodes,
            found: Room::with_capacity(FOUND_CAPACITY),
            near_triangles: Room::with_capacity(most_triangles),
            faces_near: Room::with_capacity(most_triangles),
            faces_boxed: Room::with_capacity(most_triangles),
            settings: CcdSettings::default(),
            bounds: Room::with_capacity(count),
            near: Room::with_capacity(count),
            prepared: Prepared::Nothing,
            tight_bounds: Room::with_capacity(count),
            now: TriangleBoxes::new(bodies, count, spare_triangles),
            cache: CandidateCache::new(bodies, count, 3 * spare_triangles + 3),
            self_pairs: SelfPairs::new(bodies, spare),
            max_motion: Room::with_capacity(count),
            impulses: 0,
            budget_spent: 0,
            marked: vec![false; answered.len()],
            untangle: untangle::Untangle::new(answered.iter().map(|r| r.capacity())),
            answered,
            forces: vec![Vec3::zeros(); count],
            work: vec![0.0; count],
            warm: Room::with_capacity(CONTACT_CAPACITY),
            warm_versions: Room::with_capacity(count),
            warm_held: 0,
            warm_remembered: 0,
            remembered: Room::with_capacity(CONTACT_CAPACITY),
            remembered_taken: Room::with_capacity(CONTACT_CAPACITY),
            remembered_dropped: 0,
            ground_warm: Room::with_capacity(most_rows),
            carried: Room::with_capacity(most_nodes),
        }
    }
}

impl BodyContactScratch {
    /// After the net: the nodes found inside another body moved out ([`untangle::Untangle::run`]).
    fn let_out(&mut self, bodies: &mut [Body], counters: &mut BodyContactCounters) {
        self.untangle.run(bodies, &mut self.bvhs, &mut self.moved);
        counters.inside_nodes = self.untangle.inside_nodes;
    }

    /// Keeps the response's candidate pairs from tick to tick while the bodies stay within their
    /// slack (`true`, the default), or lists them again every tick (then the net's least gaps,
    /// forgotten at every listing, never pass a pair of bodies over either: the same bits, from
    /// the whole work of every tick).
    pub fn set_candidate_cache(&mut self, keep: bool) {
        self.cache.keep = keep;
    }

    /// The most boxes one continuous query of the net examines (see
    /// [`crate::world::World::set_ccd_max_boxes`]).
    pub fn set_ccd_max_boxes(&mut self, max_boxes: u32) {
        self.settings.max_boxes = max_boxes;
    }

    /// The contact forces last tick's response put on body `k`'s sub-stepped nodes (node, force in
    /// N), in node order; none where the body's topology changed since (`version`: its topology
    /// version now).
    ///
    /// A sub-stepped node takes a contact's impulse at the end of the tick, after substeps that
    /// did not feel the contact: under a load it ends them with a velocity into the contact that its
    /// displacement does not have (by about half its acceleration's change over the tick), which
    /// the response sets back to the displacement's, and that reset, one node's only, does not
    /// keep the pair's momentum (8.5e-2 N s of 1.9 in a collision of two multi-rate bodies). Its
    /// substeps take last tick's contact force instead (`Multirate::carry_contact_forces`), taken
    /// back as an impulse after them, and the response's impulses follow: at rest the node ends
    /// its substeps with the velocity of its displacement, and the reset has little to change
    /// (3.4e-2 N s in that collision; see `Multirate::carries_contact_forces_to` for which nodes).
    pub fn carried_on(&self, k: usize, version: u64) -> impl Iterator<Item = (usize, Vec3)> + '_ {
        let unchanged = self.warm_versions.get(k) == Some(&version);
        let list: &[(NodeRef, Vec3)] = if unchanged { &self.carried } else { &[] };
        let from = list.partition_point(|(r, _)| r.body < k);
        let to = list.partition_point(|(r, _)| r.body <= k);
        list[from..to].iter().map(|&(r, force)| (r.node, force))
    }

    /// Whether this tick's body–body stage ([`respond_to_body_contacts`], then
    /// [`resolve_body_collisions`]) moved a node of body `k` (its end position or velocity): a
    /// body it did not move is as the contact stage left it. True for a body it does not know.
    pub fn moved(&self, k: usize) -> bool {
        self.moved.get(k).copied().unwrap_or(true)
    }

    /// Forgets last tick's contacts and the remembered pairs (no two bodies near).
    fn forget(&mut self) {
        self.warm.clear();
        self.warm_held = 0;
        self.warm_remembered = 0;
        self.remembered.clear();
        self.ground_warm.clear();
    }

    /// Each body's bounds swept over the tick with no margin, whether they meet another body's,
    /// and its largest node displacement ([`bodies_near`]); returns whether any pair meets.
    fn find_bounds(&mut self, bodies: &[Body], group: &[usize]) -> bool {
        bodies_near(
            bodies,
            group,
            (&mut self.bounds, &mut self.near, &mut self.max_motion),
        )
    }
}

/// What the response of this tick leaves for the collision net, which runs right after it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Prepared {
    /// Nothing (the net finds its bounds and refits on its own).
    Nothing,
    /// No two bodies' bounds met within the skin: none meet without it, and nothing moved.
    NoneNear,
    /// Bodies near: `tight_bounds` hold the bounds with no margin before the response moved the
    /// nodes, grown by where it moved them to.
    Listed,
}

/// A node of some body.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct NodeRef {
    body: usize,
    node: usize,
}

fn start_of(bodies: &[Body], r: NodeRef) -> Vec3 {
    bodies[r.body].surface.position_in_world[r.node]
}

fn end_of(bodies: &[Body], r: NodeRef) -> Vec3 {
    bodies[r.body].surface.next_position_in_world[r.node]
}

/// Stops a node at `fraction` of its trajectory, leaving it with `velocity` or, when `None`, with
/// its shortened displacement's (tool-held nodes are left to the tool).
fn stop_at(bodies: &mut [Body], r: NodeRef, fraction: f64, velocity: Option<Vec3>, dt: f64) {
    let s = &mut bodies[r.body].surface;
    if s.tool_contact[r.node].tool != NO_TOOL {
        return;
    }
    let start = s.position_in_world[r.node];
    let end = start + (s.next_position_in_world[r.node] - start) * fraction;
    s.next_position_in_world[r.node] = end;
    s.velocity_in_world[r.node] = velocity.unwrap_or((end - start) / dt);
}

/// Distance between the two primitives and a signed measure of which side of each other they are on
/// (vertex against the face's plane; edges by the orientation of their tetrahedron).
fn distance_and_side(p: &[Vec3; 4], vertex_face: bool) -> (f64, f64) {
    if vertex_face {
        let normal = (p[2] - p[1]).cross(&(p[3] - p[1]));
        (
            (closest_point_on_triangle(&p[0], &p[1], &p[2], &p[3]) - p[0]).norm(),
            (p[0] - p[1]).dot(&normal),
        )
    } else {
        (
            segment_segment_distance(&p[0], &p[1], &p[2], &p[3]),
            (p[1] - p[0]).cross(&(p[3] - p[2])).dot(&(p[2] - p[0])),
        )
    }
}

/// For primitives touching at the start of the tick: true when they part over it — their distance
/// grows and they do not cross. `nodes` is the vertex then the face when `vertex_face`, otherwise
/// edge (0, 1) then edge (2, 3).
fn parting(bodies: &[Body], nodes: &[NodeRef; 4], vertex_face: bool) -> bool {
    let (before, side_before) = distance_and_side(&nodes.map(|r| start_of(bodies, r)), vertex_face);
    let (after, side_after) = distance_and_side(&nodes.map(|r| end_of(bodies, r)), vertex_face);
    let crossed = side_before * side_after < 0.0;
    after > before && !crossed
}

/// Whether triangles `sa` and `sb` (of two bodies, at the start of the tick) are farther apart
/// than `most`: the corners of one all farther than `most` on one side of the other's plane (the
/// plane then parts the triangles, and every point of one is farther than that from the other). Every vertex–face
/// and edge–edge pair of the two then starts farther apart than its nodes move, and
/// [`test_primitive`] would turn each down: one test for the pair instead of one per primitive
/// (a stack's resting triangles are mostly parted so). Compared in squares with the unnormalised
/// normal, with the relative room [`BOUND_ROUNDING`]; a degenerate triangle parts nothing.
#[inline(always)]
fn triangles_apart(sa: &[Vec3; 3], sb: &[Vec3; 3], most: f64) -> bool {
    for (points, face) in [(sa, sb), (sb, sa)] {
        let normal = (face[1] - face[0]).cross(&(face[2] - face[0]));
        let bound = most * most * normal.norm_squared() * (1.0 + BOUND_ROUNDING);
        let d = points.map(|p| (p - face[0]).dot(&normal));
        let one_side =
            (d[0] > 0.0 && d[1] > 0.0 && d[2] > 0.0) || (d[0] < 0.0 && d[1] < 0.0 && d[2] < 0.0);
        if one_side && d.iter().all(|&x| x * x > bound) {
            return true;
        }
    }
    false
}

/// Whether segment `p`–`q` passes through the inside of triangle `t` (not along its plane).
fn segment_pierces(p: &Vec3, q: &Vec3, t: &[Vec3; 3]) -> bool {
    let normal = (t[1] - t[0]).cross(&(t[2] - t[0]));
    let (dp, dq) = ((p - t[0]).dot(&normal), (q - t[0]).dot(&normal));
    if dp * dq >= 0.0 {
        return false;
    }
    // Where the segment meets the plane, against each side: on the inner side of all three.
    let hit = p + (q - p) * (dp / (dp - dq));
    (0..3).all(|k| {
        let (a, b) = (t[k], t[(k + 1) % 3]);
        (b - a).cross(&(hit - a)).dot(&normal) > 0.0
    })
}

/// Whether triangles `a` and `b` cross each other: a side of one passes through the other.
fn triangles_cross(a: &[Vec3; 3], b: &[Vec3; 3]) -> bool {
    (0..3).any(|k| segment_pierces(&a[k], &a[(k + 1) % 3], b))
        || (0..3).any(|k| segment_pierces(&b[k], &b[(k + 1) % 3], a))
}

/// The bodies of `nodes` moved (a collision stopped them; see [`BodyContactScratch::moved`]).
fn mark_moved(moved: &mut [bool], nodes: &[NodeRef; 4]) {
    for r in nodes {
        if let Some(m) = moved.get_mut(r.body) {
            *m = true;
        }
    }
}

/// How the collision net answers the collisions of a round.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Answer {
    /// An inelastic normal impulse on the four nodes ([`impulse_apart`]), or stop short where it
    /// cannot.
    Impulse,
    /// Stop the nodes short of the time of impact, with their mean velocity.
    StopShort,
    /// Stop the nodes at their start.
    Freeze,
}

/// Tests one vertex–face or edge–edge pair; answers a collision as `answer` says. Returns how it
/// answered (`None`: no collision).
fn test_primitive(
    bodies: &mut [Body],
    nodes: [NodeRef; 4],
    (vertex_face, most, common, triangles): (bool, f64, &Vec3, Option<&[[Vec3; 3]; 2]>),
    (settings, obstacles, budget_spent): (&CcdSettings, &[Obstacle], &mut u32),
    answer: Answer,
    dt: f64,
) -> Option<Answer> {
    let s = nodes.map(|r| start_of(bodies, r));
    // First, without square roots or closest points, a pair whose start distance is beyond what
    // the two bodies' nodes move at most: the distance of the vertex to the face's plane (between
    // the edges' lines) is a lower bound of it, and the two bodies' largest displacements bound
    // the reach below from above; the test below turns such a pair down too.
    let (offset, across) = if vertex_face {
        (s[0] - s[1], (s[2] - s[1]).cross(&(s[3] - s[1])))
    } else {
        (s[2] - s[0], (s[1] - s[0]).cross(&(s[3] - s[2])))
    };
    let along = offset.dot(&across);
    if along * along > most * most * across.norm_squared() * (1.0 + BOUND_ROUNDING) {
        return None;
    }
    let e = nodes.map(|r| end_of(bodies, r));
    // Two primitives that start farther apart than their nodes move over the tick cannot meet:
    // every point of a face (edge) moves by at most its nodes' largest displacement. This skips
    // the search for resting contacts the response keeps apart. The same bound first on the
    // plane's (lines') distance, with no closest points: a body whose nodes move fast in one place
    // (a light organ under a heavy one) leaves the bodies' bound above loose everywhere else.
    let motion = [0, 1, 2, 3].map(|k| (e[k] - s[k] - common).norm());
    let reach = if vertex_face {
        motion[0] + motion[1].max(motion[2]).max(motion[3])
    } else {
        motion[0].max(motion[1]) + motion[2].max(motion[3])
    };
    let nearest = reach + FILTER_MARGIN;
    if along * along > nearest * nearest * across.norm_squared() * (1.0 + BOUND_ROUNDING) {
        return None;
    }
    let start_distance = if vertex_face {
        (closest_point_on_triangle(&s[0], &s[1], &s[2], &s[3]) - s[0]).norm()
    } else {
        segment_segment_distance(&s[0], &s[1], &s[2], &s[3])
    };
    if start_distance > reach + FILTER_MARGIN {
        return None;
    }
    let hit = if vertex_face {
        vertex_face_time_of_impact(
            &s[0], &s[1], &s[2], &s[3], &e[0], &e[1], &e[2], &e[3], settings,
        )
    } else {
        edge_edge_time_of_impact(
            &s[0], &s[1], &s[2], &s[3], &e[0], &e[1], &e[2], &e[3], settings,
        )
    };
    let hit = hit?;
    *budget_spent += u32::from(hit.exhausted);
    // The two bodies' triangles this pair is tested through cross each other at the start of the
    // tick: the crossing is there already, and this one moves it (or undoes it): let through.
    if triangles.is_some_and(|[a, b]| triangles_cross(a, b)) {
        return None;
    }
    if hit.time_of_impact == 0.0 && parting(bodies, &nodes, vertex_face) {
        // Touching at the start and parting: left alone, so bodies can separate.
        return None;
    }
    if answer == Answer::Impulse
        && impulse_apart(
            bodies,
            &nodes,
            vertex_face,
            (&s, &e),
            (hit.time_of_impact, obstacles),
            dt,
        )
    {
        return Some(Answer::Impulse);
    }
    let freeze = answer == Answer::Freeze;
    let fraction = if freeze {
        0.0
    } else {
        STOP_SHORT * hit.time_of_impact
    };
    // The positions stop short; the velocities become the nodes' mass-weighted mean (a perfectly
    // inelastic collision of the four), so that the net, like the response, changes the two
    // bodies' momenta by equal and opposite amounts. (Each stopped with its own displacement's
    // velocity, two bodies colliding head-on at 2 m/s each way, in zero gravity, came apart with
    // their total momentum reversed: the net stopped the heavy organ's nodes as often as the
    // light one's.)
    // Four nodes of one body (its self-contact) take the velocities of their own shortened
    // displacements: the body's momentum is not at stake between its own nodes, and a velocity
    // left unchanged by a displacement the stop cut short is work the springs do with no motion.
    // (With the mean velocity, the shipped liver's folds, held by the net at every tick, gained
    // 1.2 J in 25 ticks, until the guard restored it.)
    let own = nodes.iter().all(|r| r.body == nodes[0].body);
    let together = if own {
        None
    } else {
        mean_velocity(bodies, &nodes)
    };
    for r in nodes {
        stop_at(bodies, r, fraction, together, dt);
    }
    Some(if freeze {
        Answer::Freeze
    } else {
        Answer::StopShort
    })
}

/// Answers a collision of the pair `nodes` (start and end positions `s`, `e`; time of impact
/// `toi`, a fraction of the tick) with an impulse along the pair's normal at the time of impact, on
/// the nodes' velocities and end positions alike (a velocity change Δv moves the end by Δt Δv): the
/// pair's relative normal displacement over the tick may close its gap at the start down to
/// [`NET_GAP`] and no more. The impulse on each node is its weight in the pair (the vertex 1, the
/// face's nodes minus their barycentric weights at the point of impact; the edges' nodes their
/// weights at the nearest points, one edge's minus) times its inverse mass, so the four nodes'
/// momentum does not change; it only slows the approach (never pushes apart faster than the nodes
/// came together), so their kinetic energy does not grow. A pair that starts closer than
/// [`NET_GAP`] is parted to it by the same weights on the end positions only (no velocity: no
/// energy). Returns false, moving nothing, where the normal is not defined (degenerate
/// primitives, parallel edges met end on), where a tool holds every node, where the impulse would
/// move a node more than [`MAX_AMPLIFICATION`] times the change of the gap, or where the linear
/// estimate sees no approach to answer: the caller stops the nodes short instead.
fn impulse_apart(
    bodies: &mut [Body],
    nodes: &[NodeRef; 4],
    vertex_face: bool,
    (s, e): (&[Vec3; 4], &[Vec3; 4]),
    (toi, obstacles): (f64, &[Obstacle]),
    dt: f64,
) -> bool {
    let p: [Vec3; 4] = std::array::from_fn(|k| s[k] + (e[k] - s[k]) * toi);
    let (weights, normal) = if vertex_face {
        let q = closest_point_on_triangle(&p[0], &p[1], &p[2], &p[3]);
        let Some(b) = barycentric(&q, &p[1], &p[2], &p[3]) else {
            return false;
        };
        (
            [1.0, -b[0], -b[1], -b[2]],
            (p[2] - p[1]).cross(&(p[3] - p[1])),
        )
    } else {
        let (a, b) = segment_segment_closest(&p[0], &p[1], &p[2], &p[3]);
        let w = [1.0 - a, a, b - 1.0, -b];
        let (da, db) = (p[1] - p[0], p[3] - p[2]);
        let cross = da.cross(&db);
        // Edges nearly parallel: the direction between their nearest points at the start.
        let normal = if cross.norm_squared() > 1e-6 * da.norm_squared() * db.norm_squared() {
            cross
        } else {
            (0..4).map(|k| s[k] * w[k]).sum::<Vec3>()
        };
        (w, normal)
    };
    let length = normal.norm();
    let usable = length > f64::MIN_POSITIVE && length.is_finite();
    if !usable {
        return false;
    }
    let mut n = normal / length;
    let mut gap = (0..4).map(|k| s[k].dot(&n) * weights[k]).sum::<f64>();
    let mut approach = (0..4)
        .map(|k| (e[k] - s[k]).dot(&n) * weights[k])
        .sum::<f64>();
    // The side the pair starts on (where it starts within the query's precision of touching, the
    // side it comes from).
    if gap < 0.0 && gap.abs() > 0.1 * NET_GAP || (gap.abs() <= 0.1 * NET_GAP && approach > 0.0) {
        n = -n;
        gap = -gap;
        approach = -approach;
    }
    // The relative normal displacement kept: the approach, down to the gap less NET_GAP.
    let kept = approach.max(-(gap - NET_GAP).max(0.0));
    // And the end positions parted up to NET_GAP, with no velocity.
    let parted = (NET_GAP - (gap + kept)).max(0.0);
    let (by_velocity, by_position) = (kept - approach, parted);
    let change = by_velocity + by_position;
    if !(change.is_finite() && change > 0.0) {
        return false;
    }
    let mut inverse = nodes.map(|r| inverse_mass_of(bodies, r));
    // A node the impulse would move towards an obstacle and behind its surface is held by it
    // (the obstacle takes its share, as a tool does): taken as fixed, and the shares found again.
    // (Held when it ended within the skin, or held to the surface only and moved along it, the
    // net met more pairs anew: over the 18 drops of two balls 2 951 and 3 163 frozen collisions
    // against 595, and 0.022 and 0.016 J gained against 0.002.)
    for _ in 0..4 {
        let effective = (0..4)
            .map(|k| weights[k] * weights[k] * inverse[k])
            .sum::<f64>();
        if !(effective.is_finite() && effective > 0.0) {
            return false;
        }
        let share: [f64; 4] = std::array::from_fn(|k| weights[k] * inverse[k] / effective);
        if share.iter().any(|s| s.abs() > MAX_AMPLIFICATION) {
            return false;
        }
        let mut held = false;
        for k in 0..4 {
            if inverse[k] == 0.0 {
                continue;
            }
            let towards = n * (share[k] * change);
            let end = end_of(bodies, nodes[k]) + towards;
            if obstacles.iter().any(|o| {
                o.shape
                    .plane_within(&end, 0.0)
                    .is_some_and(|plane| towards.dot(&plane.normal_in_world) < 0.0)
            }) {
                inverse[k] = 0.0;
                held = true;
            }
        }
        if held {
            continue;
        }
        for k in 0..4 {
            if inverse[k] == 0.0 {
                continue;
            }
            let r = nodes[k];
            let surface = &mut bodies[r.body].surface;
            surface.velocity_in_world[r.node] += n * (share[k] * by_velocity / dt);
            surface.next_position_in_world[r.node] += n * (share[k] * change);
        }
        return true;
    }
    false
}

/// The mass-weighted mean velocity of a collision's nodes, `None` when a tool holds one of them.
fn mean_velocity(bodies: &[Body], nodes: &[NodeRef; 4]) -> Option<Vec3> {
    let (mut momentum, mut mass) = (Vec3::zeros(), 0.0);
    for r in nodes {
        let s = &bodies[r.body].surface;
        if s.tool_contact[r.node].tool != NO_TOOL {
            return None;
        }
        momentum += s.velocity_in_world[r.node] * s.mass[r.node];
        mass += s.mass[r.node];
    }
    Some(momentum / mass)
}

/// Whether the collision net must test the pair of primitives of `nodes` in `round`: always in the
/// first round (and when `skipping` is off: no room to follow the answers); afterwards only when a
/// collision of one of its nodes was answered in the round before or in this one so far. Otherwise
/// its nodes' trajectories are those it was tested with in the round before, by induction back to
/// the first round (a pair a later round lists was listed by the earlier ones: stopping short only
/// shrinks the boxes), and it did not collide on them: the test would answer no again, so skipping
/// it changes nothing, to the bit.
fn worth_testing(
    answered: &[Room<u32>],
    nodes: &[NodeRef; 4],
    round: usize,
    skipping: bool,
) -> bool {
    round == 0
        || !skipping
        || nodes
            .iter()
            .any(|r| answered[r.body][r.node] as usize >= round)
}

/// [`worth_testing`] for every primitive pair of two triangles of one body at once (`answered`:
/// that body's marks): false when none of their nodes was answered in the round before or in this
/// one so far.
fn worth_testing_pair(
    answered: &[u32],
    [a, b]: [[u32; 3]; 2],
    round: usize,
    skipping: bool,
) -> bool {
    round == 0
        || !skipping
        || a.iter().chain(&b).any(|&v| {
            answered
                .get(v as usize)
                .is_none_or(|&m| m as usize >= round)
        })
}

/// Records that `round` answered a collision of `nodes` (when `hit`; whether or not it could move
/// them: a tool holds some); returns 1 when it did.
fn mark_answered(
    (answered, marked): (&mut [Room<u32>], &mut [bool]),
    nodes: &[NodeRef; 4],
    round: usize,
    hit: bool,
) -> u32 {
    if !hit {
        return 0;
    }
    for r in nodes {
        if let Some(mark) = answered[r.body].get_mut(r.node) {
            marked[r.body] = true;
            *mark = round as u32 + 1;
        }
    }
    1
}

/// A body's marks of [`worth_testing`] for `n` nodes, none answered; false when there is no room
/// for them (then every round tests every pair).
fn clear_marks(answered: &mut Room<u32>, n: usize) -> bool {
    answered.clear();
    let fits = n <= answered.capacity();
    if fits {
        answered.resize(n, 0);
    }
    fits
}

/// Adds `pair` to the pairs the next tick's response remembers, or counts it when there is no room.
fn remember((remembered, dropped): (&mut Room<Remembered>, &mut u32), pair: Remembered) {
    if remembered.len() < remembered.capacity() {
        remembered.push(pair);
    } else {
        *dropped += 1;
    }
}

/// Finds and answers collisions between the trajectories of different bodies. Bodies with the same
/// `group` (the pieces of one transected body, whose caps start where they were cut apart) are not
/// tested against each other.
///
/// Rounds, until one answers nothing: each pair of bodies whose bounds meet
/// ([`net_body_pair`]), then each body with self-contact on against itself ([`net_self_pairs`]);
/// after a round with impulses the bounds and lists are made again ([`relist_after_impulses`],
/// [`relist_self_pairs`]). The last rounds freeze what they find.
pub fn resolve_body_collisions(
    bodies: &mut [Body],
    group: &[usize],
    obstacles: &[Obstacle],
    scratch: &mut BodyContactScratch,
    dt: f64,
) -> BodyContactCounters {
    let mut counters = BodyContactCounters::default();
    scratch.clear_last_marks();
    let prepared = std::mem::replace(&mut scratch.prepared, Prepared::Nothing);
    scratch.impulses = 0;
    scratch.budget_spent = 0;
    // Bodies whose surface may not pass through itself, tested whether or not another is near.
    let self_on = (0..bodies.len()).any(|k| SelfPairs::on(bodies, k));
    if prepared == Prepared::NoneNear && !self_on {
        scratch.let_out(bodies, &mut counters);
        return counters;
    }
    let mut skipping = false;
    let last = ROUNDS + FREEZE_ROUNDS;
    for round in 0..=last {
        let freeze = round >= ROUNDS;
        if round == 0 {
            match first_round(bodies, group, scratch, (prepared, self_on), &mut counters) {
                Some(skip) => skipping = skip,
                None => break,
            }
        }
        scratch.now.begin(bodies);
        let mut answered = 0;
        let rule = (round, skipping, freeze);
        for i in 0..bodies.len() {
            for j in i + 1..bodies.len() {
                answered += net_body_pair(
                    bodies,
                    (group, obstacles),
                    scratch,
                    [i, j],
                    rule,
                    dt,
                    &mut counters,
                );
            }
        }
        for k in 0..bodies.len() {
            if SelfPairs::on(bodies, k) {
                answered += net_self_pairs(bodies, obstacles, scratch, k, rule, dt, &mut counters);
            }
        }
        counters.collisions += answered;
        if freeze {
            counters.frozen += answered;
        }
        if answered == 0 {
            break;
        }
        let impulses = std::mem::take(&mut scratch.impulses);
        counters.impulses += impulses;
        if impulses > 0 && round < last {
            relist_after_impulses(bodies, group, scratch, &mut skipping, &mut counters);
        }
        // (After the last round there is none to list again for: counted below.)
        if round < last {
            relist_self_pairs(bodies, scratch, round, &mut counters);
        }
    }
    counters.budget_spent = scratch.budget_spent;
    scratch.let_out(bodies, &mut counters);
    // Checked, where the net moved anything: the far listings hold for the trajectories as they
    // end (not when the last round still answered collisions, with no round after it to list
    // again).
    if counters.collisions > 0 {
        for k in 0..bodies.len() {
            if SelfPairs::on(bodies, k) && !scratch.self_pairs.holds(k, &bodies[k]) {
                counters.self_unlisted += 1;
            }
        }
    }
    counters
}

impl BodyContactScratch {
    /// Clears the collision net's last run's marks (read by this tick's response), whatever this
    /// run does.
    fn clear_last_marks(&mut self) {
        for (marks, marked) in self.answered.iter_mut().zip(self.marked.iter_mut()) {
            if std::mem::take(marked) {
                marks.iter_mut().for_each(|mark| *mark = 0);
            }
        }
    }
}

/// The net's first round's bounds, marks and kept triangle pairs; `None` when no two bodies are
/// near and none has self-contact on (nothing to test), else whether the rounds can pass over the
/// pairs none of whose nodes moved (room to follow which nodes' collisions they answer).
fn first_round(
    bodies: &[Body],
    group: &[usize],
    scratch: &mut BodyContactScratch,
    (prepared, self_on): (Prepared, bool),
    counters: &mut BodyContactCounters,
) -> Option<bool> {
    // The bounds of the first round hold for the later ones as long as they only stop short
    // (which only shortens trajectories); after a round with impulses they are found again.
    let any = if prepared == Prepared::Listed {
        // The response's bounds with no margin, grown by the ends it moved: they hold every
        // node's trajectory now, so a pair of bodies whose bounds do not meet has no triangle
        // boxes that meet either.
        scratch.bounds.clear();
        scratch.bounds.extend_from_slice(&scratch.tight_bounds);
        scratch.near.iter_mut().for_each(|n| *n = false);
        mark_near(group, &scratch.bounds, &mut scratch.near)
    } else {
        scratch.find_bounds(bodies, group)
    };
    if !any && !self_on {
        return None;
    }
    let mut skipping = true;
    // (`near` has an entry per body there is; `answered` also has room for the pieces
    // transections and tears may make.)
    for (k, answered) in scratch.answered.iter_mut().enumerate() {
        if scratch.near.get(k) == Some(&true) || SelfPairs::on(bodies, k) {
            skipping &= clear_marks(answered, bodies[k].node_count());
        }
    }
    // The kept triangle pairs, checked again: the response moved nodes, which may have left their
    // slack. Later rounds check them again after impulses (`relist_after_impulses`); stops only
    // shorten trajectories, within the same boxes.
    scratch.cache.list(
        bodies,
        group,
        (&scratch.bounds, &scratch.near),
        ListCall::Net,
        &mut scratch.bvhs,
        (&mut scratch.near_triangles, &mut scratch.found),
        counters,
    );
    Some(skipping)
}

/// One round of the net for bodies `i` and `j` (`i < j`): the kept triangle pairs whose boxes meet
/// this round, each tested; returns the collisions answered. `rule`: the round, whether pairs none
/// of whose nodes moved are passed over, and whether what is found is frozen.
fn net_body_pair(
    bodies: &mut [Body],
    (group, obstacles): (&[usize], &[Obstacle]),
    scratch: &mut BodyContactScratch,
    [i, j]: [usize; 2],
    (round, skipping, freeze): (usize, bool, bool),
    dt: f64,
    counters: &mut BodyContactCounters,
) -> u32 {
    if group.get(i).is_some_and(|g| group.get(j) == Some(g))
        || !scratch.bounds[i].overlaps(&scratch.bounds[j])
    {
        return 0;
    }
    let pair = i * scratch.cache.slots + j;
    let listed = scratch.cache.listed[pair];
    if listed == NOT_LISTED {
        return 0;
    }
    let complete = listed != LISTED_IN_PART;
    // The kept pairs whose boxes meet this round: the pairs, in the order, of a traversal of the
    // hierarchies refitted to this round's trajectories.
    scratch.pairs.clear();
    let cache = &mut scratch.cache;
    let (start, end) = cache.pair_ranges[pair];
    let kept = &cache.pairs[cache.current][start as usize..end as usize];
    let gaps = &mut cache.pair_gaps[cache.current][start as usize..end as usize];
    // The two bodies' triangle boxes of this tick lie within their anchor boxes grown by their
    // excursions from them: when the least gap of the pairs' anchor boxes exceeds the two
    // excursions (with room for rounding), no boxes meet.
    let net_tick = cache.net_ticks;
    // (An excursion is infinite for a body with no anchor that holds.)
    let anchored = [i, j].map(|k| cache.anchor_excursion[k] <= ANCHOR_SLACK);
    let anchored_at = [i, j].map(|k| cache.anchored_at[k]);
    let least = &mut cache.least_gaps[pair];
    let apart = cache.anchor_excursion[i] + cache.anchor_excursion[j] + GAP_ROUNDING;
    let held = anchored == [true; 2] && anchored_at == [least.1; 2];
    if held && least.0 > apart {
        return 0;
    }
    // Both anchors taken this tick: this round's boxes are the anchor boxes, and the least gap is
    // found with them, and each triangle pair's.
    let fresh = round == 0 && anchored == [true; 2] && anchored_at == [net_tick; 2];
    // Else, while they hold, the triangle pairs whose own gap exceeds the excursions are passed
    // over (not a number: not known, taken).
    let by_pair_gap = held && !fresh;
    let (mut least_now, mut unordered) = (f64::INFINITY, false);
    // (Consecutive pairs often share their first triangle: its box is taken once.)
    let mut box_a = (u32::MAX, Aabb::empty());
    for (&(ta, tb), pair_gap) in kept.iter().zip(gaps.iter_mut()) {
        if by_pair_gap && *pair_gap > apart {
            continue;
        }
        if ta != box_a.0 {
            box_a = (ta, scratch.now.of(i, ta as usize, &bodies[i]));
        }
        let box_b = scratch.now.of(j, tb as usize, &bodies[j]);
        if fresh {
            let gap = box_a.1.gap(&box_b);
            unordered |= gap.is_nan();
            least_now = least_now.min(gap);
            *pair_gap = gap;
        }
        if box_a.1.overlaps(&box_b) {
            scratch.pairs.push((ta, tb));
        }
    }
    if fresh {
        // (A gap that is not a number leaves the least one unknown.)
        *least = (if unordered { f64::NAN } else { least_now }, net_tick);
    }
    counters.candidate_pairs += scratch.pairs.len() as u32;
    // What the two bodies' nodes move over the tick at most: primitives that start farther apart
    // do not meet (see `test_primitive`).
    let most = scratch.max_motion[i] + scratch.max_motion[j] + FILTER_MARGIN;
    let mut answered = 0;
    for k in 0..scratch.pairs.len() {
        let (ta, tb) = scratch.pairs[k];
        answered += test_triangle_pair(
            bodies,
            scratch,
            [(i, ta), (j, tb)],
            (most, Vec3::zeros(), obstacles),
            (round, skipping, freeze || !complete, false),
            dt,
        );
    }
    answered
}

/// One round of the net for body `k` (self-contact on) against itself: its pairs (listed again at
/// the first round where its nodes left their slack) whose boxes meet this round, each tested;
/// returns the collisions answered. `rule` as for [`net_body_pair`].
fn net_self_pairs(
    bodies: &mut [Body],
    obstacles: &[Obstacle],
    scratch: &mut BodyContactScratch,
    k: usize,
    (round, skipping, freeze): (usize, bool, bool),
    dt: f64,
    counters: &mut BodyContactCounters,
) -> u32 {
    if round == 0 {
        if !scratch
            .self_pairs
            .update(k, &bodies[k], &mut scratch.bvhs[k])
        {
            counters.overflows += 1;
        }
    } else {
        scratch
            .self_pairs
            .bend_again(k, &bodies[k], &scratch.answered[k], round);
    }
    let complete = scratch.self_pairs.complete(k);
    // (Listed again after the round before: every pair, as in a first round.)
    let skipping = skipping && !scratch.self_pairs.retest(k);
    let far = scratch.self_pairs.pairs(k).len();
    let mut answered = 0;
    for p in 0..far + scratch.self_pairs.bent(k).len() {
        let (ta, tb) = if p < far {
            scratch.self_pairs.pairs(k)[p]
        } else {
            scratch.self_pairs.bent(k)[p - far]
        };
        // After the first round, a pair none of whose nodes moved since the round before is
        // passed over (each of its tests would be: see `worth_testing`).
        let triangles = &bodies[k].surface.triangles;
        let (a, b) = (triangles[ta as usize], triangles[tb as usize]);
        if !worth_testing_pair(&scratch.answered[k], [a, b], round, skipping) {
            continue;
        }
        let box_a = scratch.now.of(k, ta as usize, &bodies[k]);
        if !box_a.overlaps(&scratch.now.of(k, tb as usize, &bodies[k])) {
            continue;
        }
        counters.candidate_pairs += 1;
        // What the two may close by: twice the most either's nodes move apart from the body's
        // nodes' mean (a body falling or sliding as a whole closes nothing).
        let nodes = [a[0], a[1], a[2], b[0], b[1], b[2]];
        let motion = scratch.self_pairs.relative_motion(k, &bodies[k], &nodes);
        // Every vertex and side of the two triangles, not only those each owns: the pair of a
        // vertex's (side's) owner and this face may be a near pair not bent, or a far pair not
        // listed, where this one is.
        answered += test_triangle_pair(
            bodies,
            scratch,
            [(k, ta), (k, tb)],
            (
                2.0 * motion + FILTER_MARGIN,
                scratch.self_pairs.shift(k),
                obstacles,
            ),
            (round, skipping, freeze || !complete, true),
            dt,
        );
    }
    answered
}

/// After a round with impulses, which may have moved ends beyond the trajectories the round's
/// bounds, motion bounds and lists were made for (stopping short only shortens them): all made
/// again for the next round. The pairs the next round passes over are still those none of whose
/// nodes moved: their trajectories are the first round's, which had sound lists.
fn relist_after_impulses(
    bodies: &[Body],
    group: &[usize],
    scratch: &mut BodyContactScratch,
    skipping: &mut bool,
    counters: &mut BodyContactCounters,
) {
    counters.relisted_rounds += 1;
    if !scratch.find_bounds(bodies, group) {
        return;
    }
    for (k, answered) in scratch.answered.iter_mut().enumerate() {
        // A body near another only now: none of its nodes was answered yet.
        let n = bodies.get(k).map_or(0, Body::node_count);
        if scratch.near.get(k) == Some(&true) && answered.len() != n {
            *skipping &= clear_marks(answered, n);
        }
    }
    scratch.cache.list(
        bodies,
        group,
        (&scratch.bounds, &scratch.near),
        ListCall::NetAgain,
        &mut scratch.bvhs,
        (&mut scratch.near_triangles, &mut scratch.found),
        counters,
    );
}

/// Each body with self-contact on whose stops in `round` took a node's end out of its far
/// listing's slack: listed again, and all its pairs tested in the next round.
fn relist_self_pairs(
    bodies: &[Body],
    scratch: &mut BodyContactScratch,
    round: usize,
    counters: &mut BodyContactCounters,
) {
    for k in 0..bodies.len() {
        if !SelfPairs::on(bodies, k) {
            continue;
        }
        if let Some(complete) = scratch.self_pairs.update_after_round(
            k,
            &bodies[k],
            &mut scratch.bvhs[k],
            (&scratch.answered[k], round),
        ) {
            counters.self_listed_again += 1;
            if !complete {
                counters.overflows += 1;
            }
        }
    }
}

/// Tests triangle `ta` of body `i` against `tb` of body `j` (`i` may be `j`: two triangles of one
/// body, whose vertex–face and edge–edge pairs that share a node are not tested): each vertex
/// against the other's face and each side against the other's sides, through the one triangle
/// that owns it (all of them with `every`), after the filters on their start distance against
/// `most` (m: what the two may close by over the tick) and their own nodes' motion, less `common`
/// (zero between bodies; a body's mean displacement for its own pairs: two primitives that move
/// alike do not close). What collides stops short (or is frozen, with `freeze`); returns how many
/// collisions it answered.
fn test_triangle_pair(
    bodies: &mut [Body],
    scratch: &mut BodyContactScratch,
    [(i, ta), (j, tb)]: [(usize, u32); 2],
    (most, common, obstacles): (f64, Vec3, &[Obstacle]),
    (round, skipping, overflow_freeze, every): (usize, bool, bool, bool),
    dt: f64,
) -> u32 {
    let mut answered = 0;
    let fa = bodies[i].surface.triangles[ta as usize].map(|v| NodeRef {
        body: i,
        node: v as usize,
    });
    let fb = bodies[j].surface.triangles[tb as usize].map(|v| NodeRef {
        body: j,
        node: v as usize,
    });
    let starts = |f: [NodeRef; 3]| f.map(|r| start_of(bodies, r));
    let (sa, sb) = (starts(fa), starts(fb));
    if triangles_apart(&sa, &sb, most) {
        return 0;
    }
    // Again with what these six nodes move (a body that moves fast in one place
    // leaves the bodies' bound loose everywhere else).
    let moved = |f: [NodeRef; 3], s: &[Vec3; 3]| {
        (0..3)
            .map(|c| (end_of(bodies, f[c]) - s[c] - common).norm_squared())
            .fold(0.0, f64::max)
            .sqrt()
    };
    let local = moved(fa, &sa) + moved(fb, &sb) + FILTER_MARGIN;
    if local < most && triangles_apart(&sa, &sb, local) {
        return 0;
    }
    // (Two bodies' triangles: a collision between them is let through where they cross already.)
    let starts = [sa, sb];
    let crossing = (i != j).then_some(&starts);
    // Each vertex and side through the one triangle that owns it: every
    // vertex–face and edge–edge pair is tested once.
    let (oa, ob) = if every {
        (u8::MAX, u8::MAX)
    } else {
        (
            scratch.bvhs[i].owned(ta as usize),
            scratch.bvhs[j].owned(tb as usize),
        )
    };
    for (vertices, owned, face) in [(fa, oa, fb), (fb, ob, fa)] {
        for (c, v) in vertices.into_iter().enumerate() {
            if owned & owns_vertex(c) == 0 {
                continue;
            }
            let nodes = [v, face[0], face[1], face[2]];
            if face.contains(&v) {
                continue;
            }
            answered += test_and_answer(
                bodies,
                scratch,
                (nodes, true),
                (most, &common, obstacles, crossing),
                (round, skipping, overflow_freeze),
                dt,
            );
        }
    }
    for ea in 0..3 {
        if oa & owns_side(ea) == 0 {
            continue;
        }
        for eb in 0..3 {
            if ob & owns_side(eb) == 0 {
                continue;
            }
            let nodes = [fa[ea], fa[(ea + 1) % 3], fb[eb], fb[(eb + 1) % 3]];
            if nodes[..2].iter().any(|r| nodes[2..].contains(r)) {
                continue;
            }
            answered += test_and_answer(
                bodies,
                scratch,
                (nodes, false),
                (most, &common, obstacles, crossing),
                (round, skipping, overflow_freeze),
                dt,
            );
        }
    }

    answered
}

/// One vertex–face (`vertex_face`: the vertex, then the face) or edge–edge pair of `nodes`, unless
/// the round need not test it ([`worth_testing`]): tested, and a collision stopped short (see
/// [`test_primitive`]), its nodes marked moved and answered, the pair remembered for the next
/// tick's response; returns 1 when it answered a collision.
fn test_and_answer(
    bodies: &mut [Body],
    scratch: &mut BodyContactScratch,
    (nodes, vertex_face): ([NodeRef; 4], bool),
    (most, common, obstacles, triangles): (f64, &Vec3, &[Obstacle], Option<&[[Vec3; 3]; 2]>),
    (round, skipping, overflow_freeze): (usize, bool, bool),
    dt: f64,
) -> u32 {
    if !worth_testing(&scratch.answered, &nodes, round, skipping)
        || scratch.untangle.lets_cross(&nodes, vertex_face)
    {
        return 0;
    }
    let answer = if overflow_freeze {
        Answer::Freeze
    } else if round < IMPULSE_ROUNDS {
        Answer::Impulse
    } else {
        Answer::StopShort
    };
    let answered = test_primitive(
        bodies,
        nodes,
        (vertex_face, most, common, triangles),
        (&scratch.settings, obstacles, &mut scratch.budget_spent),
        answer,
        dt,
    );
    // (An impulse may move an end beyond its trajectory: the round's bounds and lists are
    // brought up to date before the next.)
    scratch.impulses += u32::from(answered == Some(Answer::Impulse));
    let hit = answered.is_some();
    if hit {
        scratch.untangle.seed(&nodes, vertex_face);
        mark_moved(&mut scratch.moved, &nodes);
        remember(
            (&mut scratch.remembered, &mut scratch.remembered_dropped),
            Remembered::of(nodes, vertex_face, f64::INFINITY),
        );
    }
    mark_answered(
        (&mut scratch.answered, &mut scratch.marked),
        &nodes,
        round,
        hit,
    )
}

/// Barycentric weights of `q` (a point of the triangle's plane) in triangle (a, b, c).
fn barycentric(q: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> Option<[f64; 3]> {
    let (v0, v1, v2) = (b - a, c - a, q - a);
    let (d00, d01, d11) = (v0.dot(&v0), v0.dot(&v1), v1.dot(&v1));
    let (d20, d21) = (v2.dot(&v0), v2.dot(&v1));
    let denominator = d00 * d11 - d01 * d01;
    if denominator <= f64::EPSILON * d00 * d11 || !denominator.is_finite() {
        return None;
    }
    let v = (d11 * d20 - d01 * d21) / denominator;
    let w = (d00 * d21 - d01 * d20) / denominator;
    Some([1.0 - v - w, v, w])
}

/// The face's corners at the end of the tick, its unnormalised normal and the vertex's end, unless
/// the vertex ends farther than the skin in front of the face's plane ([`in_reach`]).
#[inline(always)]
fn vertex_face_ahead(
    bodies: &[Body],
    v: NodeRef,
    face: [NodeRef; 3],
) -> Option<([Vec3; 3], Vec3, Vec3)> {
    let end = face.map(|r| end_of(bodies, r));
    let pe = end_of(bodies, v);
    let normal = in_reach(&pe, &end)?;
    Some((end, normal, pe))
}

/// The unnormalised normal of the face with corners `end`, unless the point `pe` is farther than the
/// skin in front of its plane: then neither near (the face is no nearer than its plane) nor crossed
/// (it ends in front), whatever the closest point (the margin is far above the rounding of either
/// measure). Compared in squares with the unnormalised normal, before its square root and
/// division: a pair that this and the test on the unit normal would decide differently lies within
/// rounding of the margin, beyond the skin, where the whole test turns it down as well.
#[inline(always)]
fn in_reach(pe: &Vec3, end: &[Vec3; 3]) -> Option<Vec3> {
    let normal = (end[1] - end[0]).cross(&(end[2] - end[0]));
    let ahead = (pe - end[0]).dot(&normal);
    let reach = CONTACT_SKIN * (1.0 + EARLY_OUT_MARGIN);
    if ahead > 0.0 && ahead * ahead > reach * reach * normal.norm_squared() {
        return None;
    }
    Some(normal)
}

/// Where vertex `v` stands against face `face` (of another body) at the end of the tick, when it
/// may be in contact with it: the face's corners, its unit normal, the vertex, its nearest point
/// on the face and their distance. `None` when the vertex ends farther than the skin in front of
/// the face's plane (or the face has no normal): no contact then.
#[inline(always)]
fn vertex_face_nearest(
    bodies: &[Body],
    v: NodeRef,
    face: [NodeRef; 3],
) -> Option<([Vec3; 3], Vec3, Vec3, Vec3, f64)> {
    let (end, normal, pe) = vertex_face_ahead(bodies, v, face)?;
    let length = normal.norm();
    if length <= f64::MIN_POSITIVE || !length.is_finite() {
        return None;
    }
    let face_normal = normal / length;
    if (pe - end[0]).dot(&face_normal) > CONTACT_SKIN * (1.0 + EARLY_OUT_MARGIN) {
        return None;
    }
    let q = closest_point_on_triangle(&pe, &end[0], &end[1], &end[2]);
    let distance = (pe - q).norm();
    Some((end, face_normal, pe, q, distance))
}

/// The distance [`vertex_face_nearest`] gives, or `None` where its first test ([`in_reach`])
/// turns the pair down; pairs it keeps that the whole test turns down are left to that test.
#[inline(always)]
fn vertex_face_distance(bodies: &[Body], v: NodeRef, face: [NodeRef; 3]) -> Option<f64> {
    face_distance(&end_of(bodies, v), &face.map(|r| end_of(bodies, r)))
}

/// [`vertex_face_distance`] of the point `pe` and the face with corners `end`.
#[inline(always)]
fn face_distance(pe: &Vec3, end: &[Vec3; 3]) -> Option<f64> {
    in_reach(pe, end)?;
    let q = closest_point_on_triangle(pe, &end[0], &end[1], &end[2]);
    Some((pe - q).norm())
}

/// Whether vertex `v` starts the tick over the face with corners `start` (their positions at the
/// start of the tick), on or in front of its plane within the skin: a contact that holds already,
/// whatever the integration did over the tick. A light organ's nodes under a heavy
/// one are thrown up by their links by more than the skin each tick (1.3 mm at 10:1) and end
/// beside the vertex's foot, where neither the end's distance nor the crossing over the face
/// catches them; the collision net stopped them instead, every tick (97 collisions a tick), and
/// its stops let the heavy organ creep off.
fn started_near(bodies: &[Body], v: NodeRef, start: &[Vec3; 3]) -> bool {
    let ps = start_of(bodies, v);
    let normal = (start[1] - start[0]).cross(&(start[2] - start[0]));
    if (ps - start[0]).dot(&normal) < 0.0 {
        return false;
    }
    let length = normal.norm();
    if length <= f64::MIN_POSITIVE {
        return false;
    }
    let unit = normal / length;
    let ahead = (ps - start[0]).dot(&unit);
    if ahead > CONTACT_SKIN {
        return false;
    }
    // Over the face, not beside it.
    let foot = ps - unit * ahead;
    barycentric(&foot, &start[0], &start[1], &start[2]).is_some_and(|w| on_face(&w))
}

/// Whether barycentric weights `w` put their point on the face (its sides included, to rounding).
fn on_face(w: &[f64; 3]) -> bool {
    w.iter().all(|&x| x >= -1e-9)
}

/// Whether barycentric weights `w` put their point inside the face (off its sides and corners, by
/// more than rounding): a contact there pushes along the face's normal.
fn inside_face(w: &[f64; 3]) -> bool {
    w.iter().all(|&x| x > 1e-9)
}

/// The contact of vertex `v` with face `face` (of another body), if the vertex ends the tick within
/// the skin of the face, or crossed its plane over the tick inside it, or started the tick over it
/// within the skin ([`started_near`]). Its distance is the one
/// [`vertex_face_nearest`] gives.
fn vertex_face_contact(bodies: &[Body], v: NodeRef, face: [NodeRef; 3]) -> Option<Contact> {
    let (end, face_normal, pe, q, distance) = vertex_face_nearest(bodies, v, face)?;
    let start = face.map(|r| start_of(bodies, r));
    let weights = barycentric(&q, &end[0], &end[1], &end[2])?;
    // Nearest a side or corner of the face (and outside it): the contact pushes along the line to
    // that point, not along the face's normal (which would catch a vertex passing under an edge).
    let normal = if !inside_face(&weights) && distance > 1e-12 && (pe - q).dot(&face_normal) > 0.0 {
        (pe - q) / distance
    } else {
        face_normal
    };
    let gap = (start_of(bodies, v)
        - (start[0] * weights[0] + start[1] * weights[1] + start[2] * weights[2]))
        .dot(&normal);
    let side = (pe - q).dot(&normal);
    let near = distance <= CONTACT_SKIN && side >= -CONTACT_SKIN;
    // Crossed the face over the tick: in front of it at the start, behind it at the end, and over
    // the face itself (its foot on the plane inside the triangle), not beside it.
    let foot = pe - face_normal * (pe - end[0]).dot(&face_normal);
    let crossed = gap >= 0.0
        && side < 0.0
        && barycentric(&foot, &end[0], &end[1], &end[2]).is_some_and(|w| on_face(&w));
    // Or over the face and within the skin of it at the start of the tick: a contact that holds.
    if !(near || crossed || started_near(bodies, v, &start)) || gap < -CONTACT_SKIN {
        return None;
    }
    Some(Contact {
        a: [v, v],
        wa: [1.0, 0.0],
        b: face,
        wb: weights,
        normal,
        distance,
        gap,
        friction: 0.0,
        compliance: 0.0,
        normal_impulse: 0.0,
        tangent_impulse: Vec3::zeros(),
        cap: f64::INFINITY,
    })
}

/// A vertex whose contact with a body starts the tick closer than this to it (m) is pressed onto
/// it: it may take contacts with more faces of the body than its nearest ([`crossed_too`]).
const PRESSED_GAP: f64 = 0.5 * REST_DISTANCE;
/// Most contacts a pressed vertex takes with faces of one body besides its nearest.
const MORE_FACES: usize = 2;
/// Least angle between the normals of two contacts of one vertex with one body, as the largest
/// cosine: nearly coplanar faces hold the vertex as one does.
const SAME_NORMAL_COSINE: f64 = 0.999;

/// The contact of vertex `v`, pressed onto another body (its nearest face's contact, of normal
/// `first_normal`, started the tick closer than [`PRESSED_GAP`]), with another face `face` of that
/// body, when the vertex ended the tick behind that face, over its inside, with a contact
/// ([`vertex_face_contact`]) whose normal is not (nearly) the first one's. One contact per vertex
/// and body holds a vertex on a surface; a vertex pressed into a fold of a soft organ pressed flat
/// (two default-parameter organs stacked, the lower one squashed to a few millimetres) lies on two
/// or three faces at once, and the impulses and the parting of its one contact pushed it through
/// the others: the collision net stopped it at its start, every tick (21 collisions a tick), and
/// the organs never came to rest.
fn crossed_too(
    bodies: &[Body],
    v: NodeRef,
    face: [NodeRef; 3],
    first_normal: &Vec3,
) -> Option<Contact> {
    let c = vertex_face_contact(bodies, v, face)?;
    // Over the inside: the contact's normal is the face's.
    let behind = (end_of(bodies, v) - end_of(bodies, face[0])).dot(&c.normal) < 0.0;
    (inside_face(&c.wb) && behind && c.normal.dot(first_normal) < SAME_NORMAL_COSINE).then_some(c)
}

/// Faces of another body a vertex is checked against at once (one AVX register of `f64`).
const LANES_OF_FACES: usize = 4;

/// Sides of another body an edge is checked against at once (one AVX register of `f64`).
const LANES_OF_SIDES: usize = 4;

/// Edge `a` of a body at the end of the tick, with what the tests of its pairs share: taken once per
/// edge rather than once per pair.
struct EdgeAtEnd {
    refs: [NodeRef; 2],
    a0: Vec3,
    a1: Vec3,
    /// `a1 − a0` and its square length.
    d1: Vec3,
    length2: f64,
    /// The corners of the box of its ends.
    low: Vec3,
    high: Vec3,
}

impl EdgeAtEnd {
    /// Whether the box of the ends `b0`, `b1` of another edge is farther from the edge's than the
    /// skin along an axis: the edges are then too (the nearest points' distance is at least that
    /// gap), and not in contact.
    #[inline(always)]
    fn apart(&self, b0: &Vec3, b1: &Vec3) -> bool {
        let reach = CONTACT_SKIN * (1.0 + EARLY_OUT_MARGIN);
        let (low_b, high_b) = (b0.inf(b1), b0.sup(b1));
        (0..3).fold(false, |apart, k| {
            apart | (low_b[k] - self.high[k] > reach) | (self.low[k] - high_b[k] > reach)
        })
    }

    fn of(bodies: &[Body], refs: [NodeRef; 2]) -> Self {
        let (a0, a1) = (end_of(bodies, refs[0]), end_of(bodies, refs[1]));
        let d1 = a1 - a0;
        Self {
            refs,
            a0,
            a1,
            d1,
            length2: d1.norm_squared(),
            low: a0.inf(&a1),
            high: a0.sup(&a1),
        }
    }
}

/// The contact of edge `a` with edge `b` (of another body) where their nearest points are inside
/// both (nearest at an end, it is a vertex's contact) and within the skin at the end of the tick.
/// The normal is the line between the nearest points, turned to where `a` was at the start.
///
/// What [`edge_edge_contact`] takes of the edge and a segment (b0, b1) before its divisions, in the
/// operations and order of [`crate::collision::tool::segment_segment_closest`]: `e = |b1 − b0|²`,
/// `f`, `b`, and the first parameter's numerator and denominator.
struct NearestOnLines {
    e: f64,
    f: f64,
    b: f64,
    numerator: f64,
    denominator: f64,
}

/// [`NearestOnLines`] of the edge and the segment (b0, b1), or `None` where the nearest points are
/// at an end of either: a degenerate edge or segment, or the first parameter's numerator not
/// between 0 and its denominator (the parameter would be clamped to an end; rounding is monotone,
/// so the quotient is then ≤ 0 or ≥ 1).
#[inline(always)]
fn nearest_on_lines(edge: &EdgeAtEnd, b0: &Vec3, b1: &Vec3) -> Option<NearestOnLines> {
    let d1 = edge.d1;
    let d2 = b1 - b0;
    let r = edge.a0 - b0;
    let a = edge.length2;
    let e = d2.norm_squared();
    let tiny = f64::MIN_POSITIVE;
    if a <= tiny || e <= tiny {
        return None;
    }
    let f = d2.dot(&r);
    let c = d1.dot(&r);
    let b = d1.dot(&d2);
    let denominator = a * e - b * b;
    let numerator = b * f - c * e;
    if !((denominator > 0.0) & (numerator > 0.0) & (numerator < denominator)) {
        return None;
    }
    Some(NearestOnLines {
        e,
        f,
        b,
        numerator,
        denominator,
    })
}

/// Where nearest points of the edge and the segment (b0, b1) inside both (farther than
/// [`EDGE_INNER`] from their ends, in parameter) are within the skin: their parameters `s`
/// (edge) and `t` (segment), the points and their distance. `None` otherwise.
#[inline(always)]
fn nearest_within_skin(
    edge: &EdgeAtEnd,
    b0: &Vec3,
    b1: &Vec3,
) -> Option<(f64, f64, Vec3, Vec3, f64)> {
    let NearestOnLines {
        e,
        f,
        b,
        numerator,
        denominator,
    } = nearest_on_lines(edge, b0, b1)?;
    let inner = EDGE_INNER..=1.0 - EDGE_INNER;
    let s = numerator / denominator;
    if !inner.contains(&s) {
        return None;
    }
    // The second, unless it is clamped to an end (then the first is at an end too, or not
    // inside the second's).
    let t = (b * s + f) / e;
    if !inner.contains(&t) {
        return None;
    }
    let pa = edge.a0 + (edge.a1 - edge.a0) * s;
    let pb = b0 + (b1 - b0) * t;
    let distance = (pa - pb).norm();
    if distance > CONTACT_SKIN {
        return None;
    }
    Some((s, t, pa, pb, distance))
}

/// Nearest points of two edges closer to an end than this (in parameter) are a vertex's contact.
const EDGE_INNER: f64 = 1e-6;

/// `b0`, `b1`: the ends of `b` at the end of the tick, whose box the caller found within the skin
/// of the edge's ([`EdgeAtEnd::apart`]). The nearest points are those of
/// [`crate::collision::tool::segment_segment_closest`], with its operations in its order (so its
/// bits), taken only as far as they can be inside both: a degenerate edge, or nearest points at an
/// end of either, give no contact. Most pairs of a stack are turned down before any division, by
/// the first parameter's numerator, `b f − c e`, not between 0 and its denominator (the parameter
/// would be clamped to an end; rounding is monotone, so the quotient is then ≤ 0 or ≥ 1).
fn edge_edge_contact(
    bodies: &[Body],
    edge: &EdgeAtEnd,
    b: [NodeRef; 2],
    (b0, b1): (Vec3, Vec3),
) -> Option<Contact> {
    let near = nearest_within_skin(edge, &b0, &b1)?;
    edge_edge_contact_at(bodies, edge, b, (b0, b1), near)
}

/// [`edge_edge_contact`] from the nearest points [`nearest_within_skin`] gives: their parameters
/// `s` (edge) and `t` (side), the points and their distance.
#[inline(always)]
fn edge_edge_contact_at(
    bodies: &[Body],
    edge: &EdgeAtEnd,
    b: [NodeRef; 2],
    (b0, b1): (Vec3, Vec3),
    (s, t, pa, pb, distance): (f64, f64, Vec3, Vec3, f64),
) -> Option<Contact> {
    let (a0, a1) = (edge.a0, edge.a1);
    let a = edge.refs;
    let start_a = start_of(bodies, a[0]) * (1.0 - s) + start_of(bodies, a[1]) * s;
    let start_b = start_of(bodies, b[0]) * (1.0 - t) + start_of(bodies, b[1]) * t;
    let before = start_a - start_b;
    // The line between the nearest points; when they (nearly) meet, the common perpendicular.
    let mut normal = if distance > 1e-9 {
        (pa - pb) / distance
    } else {
        let n = (a1 - a0).cross(&(b1 - b0));
        let length = n.norm();
        if length <= f64::MIN_POSITIVE {
            return None;
        }
        n / length
    };
    if normal.dot(&before) < 0.0 {
        normal = -normal;
    }
    let gap = before.dot(&normal);
    if gap < -CONTACT_SKIN {
        return None;
    }
    Some(edge_pair_contact(a, b, (s, t), normal, distance, gap))
}

/// The contact of edge `a` at parameter `s` with edge `b` at `t`, before the solve.
fn edge_pair_contact(
    a: [NodeRef; 2],
    b: [NodeRef; 2],
    (s, t): (f64, f64),
    normal: Vec3,
    distance: f64,
    gap: f64,
) -> Contact {
    Contact {
        a,
        wa: [1.0 - s, s],
        b: [b[0], b[1], b[1]],
        wb: [1.0 - t, t, 0.0],
        normal,
        distance,
        gap,
        friction: 0.0,
        compliance: 0.0,
        normal_impulse: 0.0,
        tangent_impulse: Vec3::zeros(),
        cap: f64::INFINITY,
    }
}

/// The contact of edge `a` with edge `b` (of another body) that started the tick within the skin
/// of each other, their nearest points then inside both, and crossed over it (their tetrahedron's
/// orientation turned) to end farther apart than the skin: [`edge_edge_contact`] looks at the end
/// of the tick only, and such a pair was left to the collision net. Where a 5 kg organ presses a
/// 0.06 kg one flat, a heavy node pulled by its link ran through the light one's edges by 3 mm a
/// tick, and the net froze it at its start every tick, still carrying 5 m/s (the collision's mean
/// velocity): 80 collisions a tick, 2.6 ms a tick. The weights and the normal are those of the
/// nearest points at the start, the normal turned to where `a` was; `distance` is that start
/// distance.
fn edge_edge_crossed_from_near(
    bodies: &[Body],
    a: [NodeRef; 2],
    b: [NodeRef; 2],
) -> Option<Contact> {
    let (a0, a1) = (start_of(bodies, a[0]), start_of(bodies, a[1]));
    let (b0, b1) = (start_of(bodies, b[0]), start_of(bodies, b[1]));
    let (d1, d2) = (a1 - a0, b1 - b0);
    let across = d1.cross(&d2);
    let side_start = across.dot(&(b0 - a0));
    let (e0, e1) = (end_of(bodies, a[0]), end_of(bodies, a[1]));
    let (f0, f1) = (end_of(bodies, b[0]), end_of(bodies, b[1]));
    let side_end = (e1 - e0).cross(&(f1 - f0)).dot(&(f0 - e0));
    // Turned: their product below zero (not a number: not turned).
    let turned = side_start * side_end < 0.0;
    if !turned {
        return None;
    }
    // Ending within the skin of each other, the pair is [`edge_edge_contact`]'s (taking these too
    // left single ticks of 1.2e-5 J in a flattened organ at rest under another). Nearest inside
    // both at the end as at the start: the lines' orientation also turns where the edges pass
    // beside each other, or round an end.
    let inner = EDGE_INNER..=1.0 - EDGE_INNER;
    let (s, t) = crate::collision::tool::segment_segment_closest(&e0, &e1, &f0, &f1);
    if ((e0 + (e1 - e0) * s) - (f0 + (f1 - f0) * t)).norm() <= CONTACT_SKIN
        || !inner.contains(&s)
        || !inner.contains(&t)
    {
        return None;
    }
    let (s, t) = crate::collision::tool::segment_segment_closest(&a0, &a1, &b0, &b1);
    if !inner.contains(&s) || !inner.contains(&t) {
        return None;
    }
    let before = (a0 + d1 * s) - (b0 + d2 * t);
    let distance = before.norm();
    if distance > CONTACT_SKIN {
        return None;
    }
    let normal = if distance > 1e-9 {
        before / distance
    } else {
        let length = across.norm();
        if length <= f64::MIN_POSITIVE {
            return None;
        }
        // b on the side of `across`: a is on the other.
        across * (-side_start.signum() / length)
    };
    let gap = before.dot(&normal);
    Some(edge_pair_contact(a, b, (s, t), normal, distance, gap))
}

/// A body's nodes four at a time: their points as three vectors of four coordinates each, lane `l`
/// of vector `v` holding coordinate `(4 v + l) mod 3`.
#[cfg(target_arch = "x86_64")]
mod wide {
    use crate::Vec3;
    use crate::dynamics::kernel::avx::{dot3, gather3, lanes, sub3};
    use std::arch::x86_64::*;

    /// Four sides of another body against `edge`, with the scalar code's first checks and its
    /// operations (so its answers): bit `l` of `within` when side `l` (ends `positions[b0[l]]`,
    /// `positions[b1[l]]`) has its ends' box within the skin of the edge's (not
    /// [`super::EdgeAtEnd::apart`]), of `through` when, besides, its nearest points with the edge
    /// may be inside both (the checks of [`super::edge_edge_contact`] before its division: the
    /// side not degenerate, the first parameter's numerator between 0 and its denominator, the
    /// parameters inside both and the nearest points within the skin, [`super::nearest_within_skin`]);
    /// bit `l`
    /// of `unordered` when a coordinate is not a number (the scalar code decides those: the vector
    /// minimum does not skip it as `f64::min` does). The edge must not be degenerate.
    ///
    /// # Safety
    /// The machine must have AVX; every node must be below `positions.len()`.
    #[target_feature(enable = "avx")]
    pub(super) unsafe fn edge_sides(
        edge: &super::EdgeAtEnd,
        positions: &[Vec3],
        b0: [u32; 4],
        b1: [u32; 4],
    ) -> SidesAnswer {
        let p = positions.as_ptr() as *const f64;
        // SAFETY: indices below the slice's length, as the caller guarantees.
        let (e0, e1) = unsafe { (gather3(p, &b0), gather3(p, &b1)) };
        let splat = |v: &Vec3| [v.x, v.y, v.z].map(|x| _mm256_set1_pd(x));
        let (a0, d1) = (splat(&edge.a0), splat(&edge.d1));
        let (low_a, high_a) = (splat(&edge.low), splat(&edge.high));
        let reach = _mm256_set1_pd(super::CONTACT_SKIN * (1.0 + super::EARLY_OUT_MARGIN));
        let mut unordered = _mm256_setzero_pd();
        let mut apart = _mm256_setzero_pd();
        for k in 0..3 {
            unordered = _mm256_or_pd(unordered, _mm256_cmp_pd::<_CMP_UNORD_Q>(e0[k], e1[k]));
            let (low_b, high_b) = (_mm256_min_pd(e0[k], e1[k]), _mm256_max_pd(e0[k], e1[k]));
            apart = _mm256_or_pd(
                apart,
                _mm256_or_pd(
                    _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_sub_pd(low_b, high_a[k]), reach),
                    _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_sub_pd(low_a[k], high_b), reach),
                ),
            );
        }
        let d2 = sub3(e1, e0);
        let r = sub3(a0, e0);
        let a = _mm256_set1_pd(edge.length2);
        let e = dot3(d2, d2);
        let f = dot3(d2, r);
        let c = dot3(d1, r);
        let b = dot3(d1, d2);
        let denominator = _mm256_sub_pd(_mm256_mul_pd(a, e), _mm256_mul_pd(b, b));
        let numerator = _mm256_sub_pd(_mm256_mul_pd(b, f), _mm256_mul_pd(c, e));
        let zero = _mm256_setzero_pd();
        let inside = _mm256_and_pd(
            _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_GT_OQ>(e, _mm256_set1_pd(f64::MIN_POSITIVE)),
                _mm256_cmp_pd::<_CMP_GT_OQ>(denominator, zero),
            ),
            _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_GT_OQ>(numerator, zero),
                _mm256_cmp_pd::<_CMP_LT_OQ>(numerator, denominator),
            ),
        );
        let within = _mm256_andnot_pd(apart, _mm256_set1_pd(f64::from_bits(u64::MAX)));
        // The answer when no side goes through (its parameters and distances not read).
        let none_through = SidesAnswer {
            within: _mm256_movemask_pd(within) as u32,
            through: 0,
            unordered: _mm256_movemask_pd(unordered) as u32,
            s: [0.0; 4],
            t: [0.0; 4],
            distance: [0.0; 4],
        };
        // No side past these checks: the divisions below, whose answers would not be read, are
        // skipped.
        if _mm256_movemask_pd(_mm256_and_pd(within, inside)) == 0 {
            return none_through;
        }
        // The parameters inside both, and the nearest points within the skin (the lanes turned
        // down above may divide by zero: their answers are not used).
        let (low, high) = (
            _mm256_set1_pd(super::EDGE_INNER),
            _mm256_set1_pd(1.0 - super::EDGE_INNER),
        );
        let inner = |x: __m256d| {
            _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_GE_OQ>(x, low),
                _mm256_cmp_pd::<_CMP_LE_OQ>(x, high),
            )
        };
        let s = _mm256_div_pd(numerator, denominator);
        // The second parameter's numerator x = b s + f: where x < e ε / 2 or x > e (1 − ε / 2)
        // (ε = `EDGE_INNER`; both products rounded), the parameter x / e, rounded, is below ε or
        // above 1 − ε (the margin ε / 2 is ten orders above the roundings): the side is turned
        // down. No side left: the second division and the square root are skipped.
        let x = _mm256_add_pd(_mm256_mul_pd(b, s), f);
        let below = _mm256_mul_pd(e, _mm256_set1_pd(0.5 * super::EDGE_INNER));
        let above = _mm256_mul_pd(e, _mm256_set1_pd(1.0 - 0.5 * super::EDGE_INNER));
        let may = _mm256_and_pd(
            _mm256_cmp_pd::<_CMP_NLT_UQ>(x, below),
            _mm256_cmp_pd::<_CMP_NGT_UQ>(x, above),
        );
        let left = _mm256_and_pd(_mm256_and_pd(within, inside), _mm256_and_pd(inner(s), may));
        if _mm256_movemask_pd(left) == 0 {
            return none_through;
        }
        let t = _mm256_div_pd(x, e);
        let pa: [__m256d; 3] =
            std::array::from_fn(|k| _mm256_add_pd(a0[k], _mm256_mul_pd(d1[k], s)));
        let pb: [__m256d; 3] =
            std::array::from_fn(|k| _mm256_add_pd(e0[k], _mm256_mul_pd(d2[k], t)));
        let gap = sub3(pa, pb);
        let distance = _mm256_sqrt_pd(dot3(gap, gap));
        let near = _mm256_cmp_pd::<_CMP_NGT_UQ>(distance, _mm256_set1_pd(super::CONTACT_SKIN));
        let inside = _mm256_and_pd(
            _mm256_and_pd(inside, near),
            _mm256_and_pd(inner(s), inner(t)),
        );
        SidesAnswer {
            through: _mm256_movemask_pd(_mm256_and_pd(within, inside)) as u32,
            s: lanes(s),
            t: lanes(t),
            distance: lanes(distance),
            ..none_through
        }
    }

    /// What [`edge_sides`] answers for four sides: bits `within`, `through` and `unordered` (lane
    /// `l` at bit `l`), and per lane the nearest points' parameters on the edge (`s`) and on the
    /// side (`t`) and their distance, those of [`super::nearest_within_skin`] to the bit where
    /// `through` is set.
    pub(super) struct SidesAnswer {
        pub within: u32,
        pub through: u32,
        pub unordered: u32,
        pub s: [f64; 4],
        pub t: [f64; 4],
        pub distance: [f64; 4],
    }

    /// Four faces of another body against the vertex that ends the tick at `pe`, with the scalar
    /// code's operations (so its bits): lane `l` is the face with corners `positions[corners[c][l]]`
    /// (c = 0, 1, 2). Answers each lane's distance ([`super::face_distance`]'s: the closest point
    /// of [`crate::collision::tool::closest_point_on_triangle`], its regions taken as masks in the
    /// order of its tests, the first that holds chosen), bit `l` of `kept` where that is `Some`
    /// (the vertex within reach of the face's plane, [`super::in_reach`]), and of `scalar` where
    /// the scalar code must answer: a coordinate that is not a number (which of two such a vector
    /// operation passes on may differ), or a degenerate triangle (the scalar code's nearest corner).
    ///
    /// # Safety
    /// The machine must have AVX; every corner must be below `positions.len()`.
    #[target_feature(enable = "avx")]
    pub(super) unsafe fn vertex_faces(
        pe: &Vec3,
        positions: &[Vec3],
        corners: [[u32; 4]; 3],
    ) -> ([f64; 4], u32, u32) {
        let ptr = positions.as_ptr() as *const f64;
        // SAFETY: indices below the slice's length, as the caller guarantees.
        let [a, b, c] = corners.map(|k| unsafe { gather3(ptr, &k) });
        let p = [pe.x, pe.y, pe.z].map(|x| _mm256_set1_pd(x));
        let zero = _mm256_setzero_pd();
        let unord = |x, y| _mm256_cmp_pd::<_CMP_UNORD_Q>(x, y);
        let le = |x, y| _mm256_cmp_pd::<_CMP_LE_OQ>(x, y);
        let ge = |x, y| _mm256_cmp_pd::<_CMP_GE_OQ>(x, y);
        let gt = |x, y| _mm256_cmp_pd::<_CMP_GT_OQ>(x, y);
        let and = |x, y| _mm256_and_pd(x, y);
        let mut unordered = zero;
        for k in 0..3 {
            unordered = _mm256_or_pd(
                unordered,
                _mm256_or_pd(unord(a[k], b[k]), unord(c[k], p[k])),
            );
        }
        // The reach of the face's plane (`in_reach`): the normal as nalgebra's cross product.
        let ab = sub3(b, a);
        let ac = sub3(c, a);
        let cross = |x: [__m256d; 3], y: [__m256d; 3]| {
            let m = |i: usize, j: usize| _mm256_mul_pd(x[i], y[j]);
            [
                _mm256_sub_pd(m(1, 2), m(2, 1)),
                _mm256_sub_pd(m(2, 0), m(0, 2)),
                _mm256_sub_pd(m(0, 1), m(1, 0)),
            ]
        };
        let normal = cross(ab, ac);
        let ap = sub3(p, a);
        let ahead = dot3(ap, normal);
        let reach = super::CONTACT_SKIN * (1.0 + super::EARLY_OUT_MARGIN);
        let beyond = and(
            gt(ahead, zero),
            gt(
                _mm256_mul_pd(ahead, ahead),
                _mm256_mul_pd(_mm256_set1_pd(reach * reach), dot3(normal, normal)),
            ),
        );
        // Every face out of reach (as the scalar code finds them, coordinates all numbers): no
        // distance is read, and none is computed.
        if _mm256_movemask_pd(beyond) == 0b1111 && _mm256_movemask_pd(unordered) == 0 {
            return ([0.0; 4], 0, 0);
        }
        // The closest point's regions, in the scalar code's order.
        let d1 = dot3(ab, ap);
        let d2 = dot3(ac, ap);
        let at_a = and(le(d1, zero), le(d2, zero));
        let bp = sub3(p, b);
        let d3 = dot3(ab, bp);
        let d4 = dot3(ac, bp);
        let at_b = and(ge(d3, zero), le(d4, d3));
        let vc = _mm256_sub_pd(_mm256_mul_pd(d1, d4), _mm256_mul_pd(d3, d2));
        let on_ab = and(and(le(vc, zero), ge(d1, zero)), le(d3, zero));
        let cp = sub3(p, c);
        let d5 = dot3(ab, cp);
        let d6 = dot3(ac, cp);
        let at_c = and(ge(d6, zero), le(d5, d6));
        let vb = _mm256_sub_pd(_mm256_mul_pd(d5, d2), _mm256_mul_pd(d1, d6));
        let on_ac = and(and(le(vb, zero), ge(d2, zero)), le(d6, zero));
        let va = _mm256_sub_pd(_mm256_mul_pd(d3, d6), _mm256_mul_pd(d5, d4));
        let (d43, d56) = (_mm256_sub_pd(d4, d3), _mm256_sub_pd(d5, d6));
        let on_bc = and(and(le(va, zero), ge(d43, zero)), ge(d56, zero));
        let along = |o: [__m256d; 3], d: [__m256d; 3], t: __m256d| -> [__m256d; 3] {
            std::array::from_fn(|k| _mm256_add_pd(o[k], _mm256_mul_pd(d[k], t)))
        };
        // Each lane's region, the first whose test holds; inside the face where none does.
        let not = |x| _mm256_andnot_pd(x, _mm256_castsi256_pd(_mm256_set1_epi64x(-1)));
        let mut taken = at_a;
        let mut first = |mask| {
            let only = _mm256_andnot_pd(taken, mask);
            taken = _mm256_or_pd(taken, mask);
            only
        };
        let (at_b, on_ab, at_c, on_ac, on_bc) = (
            first(at_b),
            first(on_ab),
            first(at_c),
            first(on_ac),
            first(on_bc),
        );
        let inside = not(taken);
        // One division for the point on a side (its parameter) or inside (the first barycentric
        // weight), with each region's numerator and denominator; a second for the other weight.
        let denominator = _mm256_add_pd(_mm256_add_pd(va, vb), vc);
        let pick = |inner, ab_, ac_, bc_| {
            _mm256_blendv_pd(
                _mm256_blendv_pd(_mm256_blendv_pd(inner, ab_, on_ab), ac_, on_ac),
                bc_,
                on_bc,
            )
        };
        let numerator = pick(vb, d1, d2, d43);
        let below = pick(
            denominator,
            _mm256_sub_pd(d1, d3),
            _mm256_sub_pd(d2, d6),
            _mm256_add_pd(d43, d56),
        );
        let t = _mm256_div_pd(numerator, below);
        let w = _mm256_div_pd(vc, denominator);
        let bc = sub3(c, b);
        let origin: [__m256d; 3] = std::array::from_fn(|k| _mm256_blendv_pd(a[k], b[k], on_bc));
        let direction: [__m256d; 3] = std::array::from_fn(|k| {
            _mm256_blendv_pd(_mm256_blendv_pd(ab[k], ac[k], on_ac), bc[k], on_bc)
        });
        let on_line = along(origin, direction, t);
        let within = along(on_line, ac, w);
        let q: [__m256d; 3] = std::array::from_fn(|k| {
            let q = _mm256_blendv_pd(on_line[k], within[k], inside);
            let q = _mm256_blendv_pd(q, a[k], at_a);
            let q = _mm256_blendv_pd(q, b[k], at_b);
            _mm256_blendv_pd(q, c[k], at_c)
        });
        let magnitude = _mm256_andnot_pd(_mm256_set1_pd(-0.0), denominator);
        let degenerate = and(inside, le(magnitude, _mm256_set1_pd(f64::MIN_POSITIVE)));
        let gap = sub3(p, q);
        let distance = _mm256_sqrt_pd(dot3(gap, gap));
        let scalar = _mm256_or_pd(unordered, degenerate);
        (
            lanes(distance),
            (!_mm256_movemask_pd(beyond) & 0b1111) as u32,
            _mm256_movemask_pd(scalar) as u32,
        )
    }

    /// The coordinate of lane `l` of vector `v` of a block.
    const AXIS: [[usize; 4]; 3] = [[0, 1, 2, 0], [1, 2, 0, 1], [2, 0, 1, 2]];

    /// The least and greatest coordinates of the points of `start` and `end` per axis, and the
    /// largest displacement along each, as the scalar code finds them (minimum and maximum are
    /// exact, in any order); `None` where a coordinate is not a number (the vector minimum does
    /// not skip it as `f64::min` does). Each slice holds a multiple of four points.
    ///
    /// # Safety
    /// The machine must have AVX.
    #[target_feature(enable = "avx")]
    pub(super) unsafe fn sweep(
        start: &[Vec3],
        end: &[Vec3],
    ) -> Option<([f64; 3], [f64; 3], [f64; 3])> {
        let n = start.len().min(end.len()) / 4 * 4;
        let (p, q) = (start.as_ptr() as *const f64, end.as_ptr() as *const f64);
        let magnitude = _mm256_set1_pd(-0.0);
        let mut low = [_mm256_set1_pd(f64::INFINITY); 3];
        let mut high = [_mm256_set1_pd(f64::NEG_INFINITY); 3];
        let mut most = [_mm256_setzero_pd(); 3];
        let mut unordered = _mm256_setzero_pd();
        for block in 0..n / 4 {
            for v in 0..3 {
                // SAFETY: a Vec3 is three f64 in a row (nalgebra's column storage), so the n points
                // are 3 n f64; this reads 4 of them at 12 block + 4 v < 3 n.
                let (a, b) = unsafe {
                    (
                        _mm256_loadu_pd(p.add(12 * block + 4 * v)),
                        _mm256_loadu_pd(q.add(12 * block + 4 * v)),
                    )
                };
                unordered = _mm256_or_pd(unordered, _mm256_cmp_pd::<_CMP_UNORD_Q>(a, b));
                low[v] = _mm256_min_pd(low[v], _mm256_min_pd(a, b));
                high[v] = _mm256_max_pd(high[v], _mm256_max_pd(a, b));
                most[v] = _mm256_max_pd(most[v], _mm256_andnot_pd(magnitude, _mm256_sub_pd(b, a)));
            }
        }
        if _mm256_movemask_pd(unordered) != 0 {
            return None;
        }
        let (mut lower, mut upper, mut largest) =
            ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3], [0.0f64; 3]);
        for v in 0..3 {
            let (l, h, m) = (lanes(low[v]), lanes(high[v]), lanes(most[v]));
            for lane in 0..4 {
                let axis = AXIS[v][lane];
                lower[axis] = lower[axis].min(l[lane]);
                upper[axis] = upper[axis].max(h[lane]);
                largest[axis] = largest[axis].max(m[lane]);
            }
        }
        Some((lower, upper, largest))
    }

    /// Whether every point of `start` and `end` lies within `slack` of the box from `lower` to
    /// `upper` of the same node: the comparisons of the scalar code (a coordinate that is not a
    /// number is outside). Each slice holds the same multiple of four points.
    ///
    /// # Safety
    /// The machine must have AVX.
    #[target_feature(enable = "avx")]
    pub(super) unsafe fn within(
        [start, end]: [&[Vec3]; 2],
        [lower, upper]: [&[Vec3]; 2],
        slack: f64,
    ) -> bool {
        let n = start.len().min(end.len()).min(lower.len()).min(upper.len()) / 4 * 4;
        let pointers = [start, end, lower, upper].map(|x| x.as_ptr() as *const f64);
        let slack = _mm256_set1_pd(slack);
        let mut inside = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
        for block in 0..n / 4 {
            for v in 0..3 {
                // SAFETY: as in `sweep`, 4 f64 at 12 block + 4 v < 3 n of each slice.
                let [p, q, lo, hi] =
                    pointers.map(|x| unsafe { _mm256_loadu_pd(x.add(12 * block + 4 * v)) });
                let (lo, hi) = (_mm256_sub_pd(lo, slack), _mm256_add_pd(hi, slack));
                let ge = |x, y| _mm256_cmp_pd::<_CMP_GE_OQ>(x, y);
                let le = |x, y| _mm256_cmp_pd::<_CMP_LE_OQ>(x, y);
                let both = _mm256_and_pd(
                    _mm256_and_pd(ge(p, lo), le(p, hi)),
                    _mm256_and_pd(ge(q, lo), le(q, hi)),
                );
                inside = _mm256_and_pd(inside, both);
            }
        }
        _mm256_movemask_pd(inside) == 0b1111
    }

    /// How far the points of `start` and `end` lie outside the box from `lower` to `upper` of the
    /// same node at most (0 when inside), as the scalar code finds it (the same differences; the
    /// maximum is exact in any order); infinite where a difference is not a number. Each slice
    /// holds the same multiple of four points.
    ///
    /// # Safety
    /// The machine must have AVX.
    #[target_feature(enable = "avx")]
    pub(super) unsafe fn excursion(
        [start, end]: [&[Vec3]; 2],
        [lower, upper]: [&[Vec3]; 2],
    ) -> f64 {
        let n = start.len().min(end.len()).min(lower.len()).min(upper.len()) / 4 * 4;
        let pointers = [start, end, lower, upper].map(|x| x.as_ptr() as *const f64);
        let mut most = _mm256_setzero_pd();
        let mut unordered = _mm256_setzero_pd();
        for block in 0..n / 4 {
            for v in 0..3 {
                // SAFETY: as in `sweep`, 4 f64 at 12 block + 4 v < 3 n of each slice.
                let [p, q, lo, hi] =
                    pointers.map(|x| unsafe { _mm256_loadu_pd(x.add(12 * block + 4 * v)) });
                let (below_p, above_p) = (_mm256_sub_pd(lo, p), _mm256_sub_pd(p, hi));
                let (below_q, above_q) = (_mm256_sub_pd(lo, q), _mm256_sub_pd(q, hi));
                unordered = _mm256_or_pd(
                    unordered,
                    _mm256_or_pd(
                        _mm256_cmp_pd::<_CMP_UNORD_Q>(below_p, above_p),
                        _mm256_cmp_pd::<_CMP_UNORD_Q>(below_q, above_q),
                    ),
                );
                most = _mm256_max_pd(
                    most,
                    _mm256_max_pd(
                        _mm256_max_pd(below_p, above_p),
                        _mm256_max_pd(below_q, above_q),
                    ),
                );
            }
        }
        if _mm256_movemask_pd(unordered) != 0 {
            return f64::INFINITY;
        }
        lanes(most).into_iter().fold(0.0, f64::max)
    }
}

/// Inverse mass of a node for the contact response: 0 for a node a tool moves.
fn inverse_mass_of(bodies: &[Body], r: NodeRef) -> f64 {
    let s = &bodies[r.body].surface;
    if s.tool_contact[r.node].tool != NO_TOOL {
        0.0
    } else {
        s.inverse_mass[r.node]
    }
}

/// Adds contact `c` to the list, or counts it dropped when the list is full.
fn push_contact(contacts: &mut Vec<Contact>, counters: &mut BodyContactCounters, c: Contact) {
    if contacts.len() == contacts.capacity() {
        counters.contacts_dropped += 1;
    } else {
        contacts.push(c);
    }
}

/// The vertex–face contacts of body `i`'s vertices named in `vertices` (a run of the pair's
/// candidate list, each vertex with the faces of body `j` it may touch): each vertex's nearest face
/// with a contact, tested nearest first (one it started the tick behind taken only if no other
/// gives a contact), and, for a vertex pressed onto body `j`, a contact with each other face it
/// ended crossed over (a fold pressed flat, [`crossed_too`]).
fn vertex_face_contacts(
    bodies: &[Body],
    (i, j): (usize, usize),
    vertices: (u32, u32),
    scratch: &mut BodyContactScratch,
    counters: &mut BodyContactCounters,
    simd: bool,
) {
    let entries = &scratch.cache.entries[scratch.cache.current];
    let sj = &bodies[j].surface;
    let now = &mut scratch.now;
    let mut k = vertices.0 as usize;
    while k < vertices.1 as usize {
        let v = entries[k].feature[0];
        let mut swept = swept_box(&bodies[i], &[v as usize]);
        swept.inflate(CONTACT_SKIN);
        let vertex = NodeRef {
            body: i,
            node: v as usize,
        };
        // The faces the vertex may touch with its distance to each, then the whole test
        // on them nearest first (ties by the face's nodes) until one gives a contact: the
        // contact that testing them all and keeping the nearest would keep.
        let faces = &mut scratch.faces_near;
        faces.clear();
        let boxed = &mut scratch.faces_boxed;
        boxed.clear();
        while k < vertices.1 as usize && entries[k].feature[0] == v {
            let t = entries[k].other[0];
            k += 1;
            if !now.of(j, t as usize, &bodies[j]).overlaps(&swept) {
                continue;
            }
            counters.candidate_pairs += 1;
            // Room for every triangle of the body (see `new`), each listed once.
            if boxed.len() < boxed.capacity() {
                boxed.push(t);
            } else {
                counters.overflows += 1;
            }
        }
        let mut keep = |faces: &mut Room<(f64, u32)>, distance: Option<f64>, t: u32| {
            if let Some(distance) = distance {
                if faces.len() < faces.capacity() {
                    faces.push((distance, t));
                } else {
                    counters.overflows += 1;
                }
            }
        };
        // Four faces at a time (the scalar code's operations, so its distances); a last
        // batch of fewer repeats its last face in the other lanes, whose answers are not
        // read.
        let mut m = 0;
        #[cfg(target_arch = "x86_64")]
        if simd {
            let pe = end_of(bodies, vertex);
            let positions = &sj.next_position_in_world;
            while m < boxed.len() {
                let lanes = (boxed.len() - m).min(LANES_OF_FACES);
                // (Plain loops: nested `array::from_fn` compiled to a call per row
                // and its copy through the stack.)
                let mut corners = [[0u32; LANES_OF_FACES]; 3];
                for l in 0..LANES_OF_FACES {
                    let triangle = sj.triangles[boxed[m + l.min(lanes - 1)] as usize];
                    for c in 0..3 {
                        corners[c][l] = triangle[c];
                    }
                }
                // SAFETY: the machine has AVX (checked when `simd` was set); the corners
                // are nodes of body j (its triangles at its current topology).
                let (distances, kept, scalar) =
                    unsafe { wide::vertex_faces(&pe, positions, corners) };
                for (l, &distance) in distances.iter().enumerate().take(lanes) {
                    let t = boxed[m + l];
                    let distance = if scalar & (1 << l) != 0 {
                        vertex_face_distance(bodies, vertex, face_of(sj, j, t as usize))
                    } else {
                        (kept & (1 << l) != 0).then_some(distance)
                    };
                    keep(faces, distance, t);
                }
                m += lanes;
            }
        }
        for &t in &boxed[m..] {
            let distance = vertex_face_distance(bodies, vertex, face_of(sj, j, t as usize));
            keep(faces, distance, t);
        }
        let mut first: Option<Contact> = None;
        let mut behind: Option<Contact> = None;
        while !faces.is_empty() {
            let mut nearest = 0;
            for m in 1..faces.len() {
                let (d, t) = faces[m];
                let (dn, tn) = faces[nearest];
                if d.total_cmp(&dn)
                    .then_with(|| face_of(sj, j, t as usize).cmp(&face_of(sj, j, tn as usize)))
                    .is_lt()
                {
                    nearest = m;
                }
            }
            let (_, t) = faces.swap_remove(nearest);
            if let Some(c) = vertex_face_contact(bodies, vertex, face_of(sj, j, t as usize)) {
                // The nearest face with a contact is passed over for the next one when
                // the vertex started the tick behind it (on the inside of its plane), and
                // taken only if no other gives a contact. Where a soft organ is pressed
                // flat its two sheets lie closer than the skin: a vertex resting on the
                // upper sheet, pushed a little into it over the tick, ends nearer the
                // lower sheet, behind which it also is. Its contact with that sheet pushed it out
                // through the upper one, and the collision net stopped it at its start
                // every tick (19 a tick in two default organs stacked), so that the
                // organs never came to rest. (Passing over every face the vertex started
                // behind, for the nearest it started in front of, left single ticks of
                // 1.6e-5 J in that pair; passing over the nearest only, 8.5e-6 J.)
                if c.gap < 0.0 && behind.is_none() {
                    behind = Some(c);
                    continue;
                }
                first = Some(c);
                break;
            }
        }
        if first.is_none() {
            first = behind;
        }
        if let Some(c) = first {
            push_contact(&mut scratch.contacts, counters, c);
        }
        // A vertex pressed onto the other body that also ended crossed over the inside of
        // other faces of it (a fold of a surface pressed flat): a contact with each.
        if let Some(first) = first.filter(|c| c.gap < PRESSED_GAP) {
            let mut extra = 0;
            for &(distance, t) in faces.iter() {
                if extra == MORE_FACES {
                    break;
                }
                if distance >= REST_DISTANCE {
                    continue;
                }
                let face = face_of(sj, j, t as usize);
                if let Some(c) = crossed_too(bodies, vertex, face, &first.normal) {
                    push_contact(&mut scratch.contacts, counters, c);
                    extra += 1;
                }
            }
        }
    }
}

/// The edge–edge contacts of body `i`'s edges named in `edges` (a run of the pair's candidate
/// list, each edge with the sides of body `j` it may touch): each edge's nearest side within the
/// skin, and a side it crossed from within the skin where the net answered its nodes last tick.
fn edge_edge_contacts(
    bodies: &[Body],
    (i, j): (usize, usize),
    edges: (u32, u32),
    scratch: &mut BodyContactScratch,
    counters: &mut BodyContactCounters,
    simd: bool,
) {
    let entries = &scratch.cache.entries[scratch.cache.current];
    let sj = &bodies[j].surface;
    // Each edge against the sides its list names: a side that could be in contact (within
    // the skin at the end of the tick) has its ends' box within the skin of the edge's, so
    // within the boxes the list was made from; `edge_edge_contact` turns the others down
    // by their ends' boxes first.
    let mut k = edges.0 as usize;
    while k < edges.1 as usize {
        let feature = entries[k].feature;
        let (ea, eb) = (feature[0] as usize, feature[1] as usize);
        let a = sorted([NodeRef { body: i, node: ea }, NodeRef { body: i, node: eb }]);
        let edge = EdgeAtEnd::of(bodies, a);
        let mut best: Option<Contact> = None;
        let first = k;
        while k < edges.1 as usize && entries[k].feature == feature {
            k += 1;
        }
        let sides = &entries[first..k];
        let positions = &sj.next_position_in_world;
        // Four sides at a time through the first checks (the scalar code's operations,
        // so the same answers): only the sides they let through take the whole test.
        let mut m = 0;
        #[cfg(target_arch = "x86_64")]
        if simd && edge.length2 > f64::MIN_POSITIVE {
            while m < sides.len() {
                // The last batch may hold fewer sides: its other lanes repeat the last
                // side and their answers are not read.
                let lanes = (sides.len() - m).min(LANES_OF_SIDES);
                let mut ends = [[0u32; LANES_OF_SIDES]; 2];
                for l in 0..LANES_OF_SIDES {
                    let side = sides[m + l.min(lanes - 1)].other;
                    ends[0][l] = side[0];
                    ends[1][l] = side[1];
                }
                // SAFETY: the machine has AVX (checked when `simd` was set); the nodes
                // are nodes of body j (listed from its triangles at its current topology).
                let answer = unsafe { wide::edge_sides(&edge, positions, ends[0], ends[1]) };
                let (within, through, unordered) =
                    (answer.within, answer.through, answer.unordered);
                for l in 0..lanes {
                    if unordered & (1 << l) != 0 {
                        // A coordinate that is not a number: the scalar code's checks.
                        let b = sides[m + l].other.map(|v| NodeRef {
                            body: j,
                            node: v as usize,
                        });
                        let ends = (positions[b[0].node], positions[b[1].node]);
                        if !edge.apart(&ends.0, &ends.1) {
                            counters.candidate_pairs += 1;
                            if let Some(c) = edge_edge_contact(bodies, &edge, b, ends) {
                                keep_nearer(&mut best, c);
                            }
                        }
                        continue;
                    }
                    if within & (1 << l) == 0 {
                        continue;
                    }
                    counters.candidate_pairs += 1;
                    if through & (1 << l) == 0 {
                        continue;
                    }
                    let side = sides[m + l].other;
                    let b = side.map(|v| NodeRef {
                        body: j,
                        node: v as usize,
                    });
                    let ends = (positions[b[0].node], positions[b[1].node]);
                    // The nearest points as the scalar code finds them (its operations,
                    // so its bits), from the lane's parameters and distance.
                    let (s, t) = (answer.s[l], answer.t[l]);
                    let near = (
                        s,
                        t,
                        edge.a0 + (edge.a1 - edge.a0) * s,
                        ends.0 + (ends.1 - ends.0) * t,
                        answer.distance[l],
                    );
                    if let Some(c) = edge_edge_contact_at(bodies, &edge, b, ends, near) {
                        keep_nearer(&mut best, c);
                    }
                }
                m += lanes;
            }
        }
        for candidate in &sides[m..] {
            let b = candidate.other.map(|v| NodeRef {
                body: j,
                node: v as usize,
            });
            let ends = (end_of(bodies, b[0]), end_of(bodies, b[1]));
            if edge.apart(&ends.0, &ends.1) {
                continue;
            }
            counters.candidate_pairs += 1;
            if let Some(c) = edge_edge_contact(bodies, &edge, b, ends) {
                keep_nearer(&mut best, c);
            }
        }
        // Sides the edge started within the skin of and crossed over the tick
        // ([`edge_edge_crossed_from_near`]), looked for where the collision net answered
        // a collision of the edge's nodes in its last run, the tick before (it clears its
        // marks as it starts; the body's topology the same since, so that they name the
        // same nodes): the response takes over what the net would stop again. (Such a
        // contact ends beyond the skin, `best` within it: never the same side.)
        let mut crossed: Option<Contact> = None;
        let net_answered = |r: NodeRef| {
            same_topology(&scratch.warm_versions, bodies, r.body)
                && scratch
                    .answered
                    .get(r.body)
                    .and_then(|marks| marks.get(r.node))
                    .is_some_and(|&mark| mark > 0)
        };
        if net_answered(a[0]) || net_answered(a[1]) {
            for candidate in sides {
                let b = candidate.other.map(|v| NodeRef {
                    body: j,
                    node: v as usize,
                });
                if let Some(c) = edge_edge_crossed_from_near(bodies, a, b) {
                    keep_nearer(&mut crossed, c);
                }
            }
        }
        for c in [best, crossed].into_iter().flatten() {
            push_contact(&mut scratch.contacts, counters, c);
        }
    }
}

/// Held contacts: an edge whose contact pressed a side last tick, and whose nearest side is
/// another now, keeps a contact with that side too while it is within the skin, its normal
/// impulse capped at a share of last tick's (and so on, tick after tick, while that side is not
/// the nearest: the cap halves each tick). Each edge keeps one contact, with its nearest side
/// (and one with a side it crossed from within the skin, `edge_edge_crossed_from_near`);
/// edges are tested from one body only, so a node of the other body whose sides an edge of this
/// one held up lost its support at once when the edge's nearest side changed, fell 0.1 mm under
/// its own springs within the tick and was caught at the next (single ticks of 1.7e-5 J in a
/// resting organ). Held at full strength, or as hard contacts, such sides over-constrain a
/// squashed soft organ; a cap that decays hands the support over. Last tick's contacts come in
/// the order of this tick's lists (see `warm_start`): the two runs of last tick's list (the
/// nearest contacts, then the held ones) are each walked alongside this tick's contacts.
fn held_contacts(
    bodies: &[Body],
    scratch: &mut BodyContactScratch,
    counters: &mut BodyContactCounters,
) {
    let held_from = scratch.contacts.len();
    let unchanged = |k: usize| same_topology(&scratch.warm_versions, bodies, k);
    for part in [
        0..scratch.warm_held,
        scratch.warm_held..scratch.warm_remembered,
    ] {
        let mut cursor = 0;
        for w in &scratch.warm[part] {
            // (Impulses are never below zero nor not a number.)
            if w.a[0] == w.a[1]
                || w.normal_impulse <= 0.0
                || !unchanged(w.a[0].body)
                || !unchanged(w.b[0].body)
            {
                continue;
            }
            let nearest = next_match(&scratch.contacts[..held_from], &mut cursor, |c| {
                c.a == w.a && c.b[0].body == w.b[0].body
            });
            if nearest.is_none() {
                continue;
            }
            // An edge has up to two contacts this tick, side by side (its nearest side, then one it
            // crossed from within the skin), the one matched among them: the side held must be
            // neither.
            let this_tick = &scratch.contacts[..held_from];
            let matched = cursor - 1;
            let same_side = |k: usize| this_tick.get(k).is_some_and(|c| c.a == w.a && c.b == w.b);
            if (matched.saturating_sub(1)..=matched + 1).any(same_side) {
                continue;
            }
            let edge = EdgeAtEnd::of(bodies, w.a);
            let b = [w.b[0], w.b[1]];
            let ends = (end_of(bodies, b[0]), end_of(bodies, b[1]));
            if edge.length2 <= f64::MIN_POSITIVE || edge.apart(&ends.0, &ends.1) {
                continue;
            }
            if let Some(mut c) = edge_edge_contact(bodies, &edge, b, ends) {
                c.cap = HOLD_SHARE * w.normal_impulse;
                push_contact(&mut scratch.contacts, counters, c);
            }
        }
    }
}

/// Remembered contacts: a contact for each pair the collision net answered last tick, or whose
/// remembered contact pressed last tick, that the contacts above do not hold already (else the
/// net stops the same pair again: of a soft ball's landing on an organ, 93 % of the net's
/// answers were the pair it answered the tick before, 7 765 answers over the landing against 2
/// now). A pair the net answered may take any impulse; one whose remembered contact pressed
/// last tick at most [`HOLD_SHARE`] of what it took then (its support handed over, as a held
/// contact's), and one whose remembered contact took nothing, which the net answered again,
/// none: the contact only parts its positions. (With no cap the pressed pairs held too much:
/// 43 net collisions a tick where a 5 kg organ crushes a 0.06 kg one, single ticks of 1.6e-5 J
/// in a stack at rest; those the net answered again taken at full strength, 62 a tick.) In the
/// order of the pairs' keys.
fn remembered_contacts(
    bodies: &[Body],
    scratch: &mut BodyContactScratch,
    counters: &mut BodyContactCounters,
) {
    let remembered = &mut scratch.remembered;
    remembered.sort_unstable_by(|x, y| {
        x.order(y)
            .then_with(|| x.last_impulse.total_cmp(&y.last_impulse))
    });
    // (The least impulse of a pair listed twice: a remembered contact the net answered again.)
    remembered.dedup_by(|later, earlier| {
        let same = later.order(earlier).is_eq();
        if same {
            earlier.answered |= later.answered;
        }
        same
    });
    let taken = &mut scratch.remembered_taken;
    taken.clear();
    taken.resize(remembered.len(), false);
    if !remembered.is_empty() {
        for c in scratch.contacts.iter() {
            let pair = Remembered::of_contact(c);
            if let Ok(k) = remembered.binary_search_by(|r| r.order(&pair)) {
                taken[k] = true;
            }
        }
    }
    let known = |k: usize| k < bodies.len() && same_topology(&scratch.warm_versions, bodies, k);
    for (r, &taken) in remembered.iter().zip(taken.iter()) {
        let idle = r.last_impulse == 0.0 && !r.answered;
        if taken || idle || !known(r.nodes[0].body) || !known(r.nodes[3].body) {
            continue;
        }
        let contact = if r.vertex_face {
            vertex_face_contact(bodies, r.nodes[0], [r.nodes[1], r.nodes[2], r.nodes[3]])
        } else {
            let (a, b) = ([r.nodes[0], r.nodes[1]], [r.nodes[2], r.nodes[3]]);
            let edge = EdgeAtEnd::of(bodies, a);
            let ends = (end_of(bodies, b[0]), end_of(bodies, b[1]));
            let near = edge.length2 > f64::MIN_POSITIVE && !edge.apart(&ends.0, &ends.1);
            near.then(|| edge_edge_contact(bodies, &edge, b, ends))
                .flatten()
                .or_else(|| edge_edge_crossed_from_near(bodies, a, b))
        };
        if let Some(mut c) = contact {
            c.cap = HOLD_SHARE * r.last_impulse;
            push_contact(&mut scratch.contacts, counters, c);
        }
    }
}

/// Keeps this tick's contacts: one per vertex (or edge) and other body, the nearest (a vertex
/// pressed into a fold takes up to two more, see `crossed_too`, an edge one more with a side it
/// crossed from within the skin, `edge_edge_crossed_from_near`), in a fixed order:
/// the order the lists name the vertices and edges in, pair of bodies after pair. Each vertex
/// (edge) of a body is named in one run of its pair's list (through the one triangle that owns
/// it), and the lists keep the order of a traversal of the hierarchies whose descent does not
/// depend on the boxes (lists made at another tick, or every tick, name a subsequence of the
/// same order): the same contacts in the same order, whenever the lists were made.
///
/// Each contact takes its pair's friction, its nodes (in the solver's list) and its compliance; a
/// contact whose nodes the list has no room for is dropped (counted). Returns where the held and
/// the remembered contacts now start (`held_from` and `remembered_from` before).
fn keep_contacts(
    bodies: &[Body],
    scratch: &mut BodyContactScratch,
    counters: &mut BodyContactCounters,
    (held_from, remembered_from): (usize, usize),
    dt: f64,
) -> (usize, usize) {
    scratch.contact_nodes.clear();
    let solver_nodes = &mut scratch.solver_nodes;
    let mut kept = 0;
    let mut held_kept = usize::MAX;
    let mut remembered_kept = usize::MAX;
    // The pair's coefficient, taken once for each run of contacts of the same pair of bodies.
    let mut pair_friction = ((usize::MAX, usize::MAX), 0.0);
    for k in 0..scratch.contacts.len() {
        // In place, each contact and its nodes (the two are copied only where one before was
        // dropped).
        let c = &mut scratch.contacts[k];
        let (a, b) = (c.a[0].body, c.b[0].body);
        if pair_friction.0 != (a, b) {
            pair_friction = (
                (a, b),
                (bodies[a].params.friction * bodies[b].params.friction).sqrt(),
            );
        }
        c.friction = pair_friction.1;
        // (The kept contacts' nodes are listed: this contact's go in at `kept`.)
        scratch.contact_nodes.push(ContactNodes::of(bodies, c, dt));
        let nodes = &mut scratch.contact_nodes[kept];
        // A contact whose free nodes have small weights (the heavy ones held by a tool) would move
        // them by many times the relative motion it corrects: its compliance is raised so that no
        // node moves by more than [`MAX_AMPLIFICATION`] times it (see the constant). The solve's
        // fixed point is the same; such a contact is relaxed, each update correcting a part of
        // its relative motion (left partly open after the sweeps, for the net), and its parting
        // of the positions is weaker alike.
        let (mut compliance, mut most_moved) = (0.0, 0.0f64);
        for i in 0..nodes.count {
            let (w, inverse_mass) = (nodes.weights[i], nodes.inverse_masses[i]);
            compliance += w * w * inverse_mass;
            most_moved = most_moved.max(w.abs() * inverse_mass);
        }
        c.compliance = compliance.max(most_moved / MAX_AMPLIFICATION);
        let relaxed = c.compliance > compliance;
        nodes.effective_mass = 1.0 / c.compliance;
        let mut listed = true;
        for i in 0..nodes.count {
            match solver_nodes.slot(bodies, (nodes.refs[i], nodes.inverse_masses[i]), dt) {
                Some(slot) => nodes.slots[i] = slot,
                None => listed = false,
            }
        }
        if !listed {
            scratch.contact_nodes.pop();
            counters.contacts_dropped += 1;
            continue;
        }
        if relaxed {
            // Such a contact's held nodes carry most of its weight on both sides: their approach
            // is the tool's motion (a node held anew is put onto the tool's surface within the
            // tick), which its free nodes of small weight could undo only by moving many times
            // faster. They are kept from adding to that approach, no more: the contact may close
            // as fast as its held nodes close it. (Asked to stop the whole approach, the free
            // nodes of such contacts between two organs' nodes held on one probe were thrown at
            // 15–20 m/s, eight times — `MAX_AMPLIFICATION` — the held nodes' approach of about
            // 2 m/s; now 2.4 m/s at most:
            // `a_probe_crushing_one_organ_into_another_drives_no_node_to_the_guard`.)
            let mut held = Vec3::zeros();
            for i in 0..nodes.count {
                if nodes.inverse_masses[i] == 0.0 {
                    held += solver_nodes.nodes[nodes.slots[i] as usize].motion * nodes.weights[i];
                }
            }
            nodes.target_speed = nodes.target_speed.min(held.dot(&c.normal));
        }
        if k >= held_from && held_kept == usize::MAX {
            held_kept = kept;
        }
        if k >= remembered_from && remembered_kept == usize::MAX {
            remembered_kept = kept;
        }
        if kept != k {
            scratch.contacts[kept] = scratch.contacts[k];
        }
        kept += 1;
    }
    scratch.contacts.truncate(kept);
    (held_kept.min(kept), remembered_kept.min(kept))
}

/// What the solved impulses do: each contact's force and work on its bodies; the pushed nodes'
/// velocities; positions closer than the rest distance parted; no node parted into an obstacle,
/// whose rows' impulses are its reactions; the bounds and largest motions the net starts from;
/// the obstacle rows' impulses for the next warm start; the sub-stepped nodes' forces for their
/// next substeps; the bodies moved.
fn apply_impulses(
    scratch: &mut BodyContactScratch,
    reactions: &mut [Vec3],
    sub_stepped: impl Fn(usize, usize) -> bool,
    dt: f64,
) {
    let solver_nodes = &mut scratch.solver_nodes;
    // Each contact's force on the nodes of each side over the tick (its accumulated impulse with
    // their weights) and the work its impulses did, on their bodies.
    for (c, nodes) in scratch.contacts.iter().zip(&scratch.contact_nodes) {
        let impulse = c.normal * c.normal_impulse + c.tangent_impulse;
        for i in 0..nodes.count {
            let force = impulse * nodes.weights_per_second[i];
            scratch.forces[nodes.refs[i].body] += force;
            solver_nodes.nodes[nodes.slots[i] as usize].force += force;
        }
        scratch.work[c.a[0].body] += nodes.work[0];
        scratch.work[c.b[0].body] += nodes.work[1];
    }
    // A node the response pushed ends the tick with its displacement's velocity, (end − start) / Δt
    // (symplectic Euler's own relation): the velocity a sub-stepped node ended its sub-steps
    // with, into the contact or along it, would otherwise stay in it without moving it — kinetic
    // energy that is not motion, pushed back every tick. Not a node whose substeps took last
    // tick's contact forces (`sub_stepped`, see `carried_on`): its substeps already met the
    // contact, and it keeps its velocity with the impulses' changes, as a node not sub-stepped
    // does — a reset, not shared by the other side of its contacts, changed the pair's momentum
    // (0.4–1.8 % of it in a collision at 1–2 m/s; 0.001–0.18 % without it).
    for (c, nodes) in scratch.contacts.iter().zip(&scratch.contact_nodes) {
        if c.normal_impulse > 0.0 {
            for &slot in &nodes.slots[..nodes.count] {
                solver_nodes.nodes[slot as usize].pushed = true;
            }
        }
    }
    for n in solver_nodes.nodes.iter_mut() {
        if n.pushed && n.inverse_mass != 0.0 && !sub_stepped(n.r.body, n.r.node) {
            n.velocity = (n.end - n.start) / dt;
        }
    }
    // Positions closer than the rest distance at the end of the tick are parted by a fraction of
    // the shortfall, shared like an impulse (the pair's mass-weighted centre does not move).
    for (c, nodes) in scratch.contacts.iter().zip(&scratch.contact_nodes) {
        if c.compliance <= 0.0 {
            continue;
        }
        let gap = nodes
            .relative(&solver_nodes.nodes, |n| n.end)
            .dot(&c.normal);
        if gap >= REST_DISTANCE {
            continue;
        }
        let push = c.normal * (PART_RATE * (REST_DISTANCE - gap) * nodes.effective_mass);
        for i in 0..nodes.count {
            let slot = nodes.slots[i] as usize;
            let n = &mut solver_nodes.nodes[slot];
            if n.inverse_mass != 0.0 {
                n.end += push * nodes.weights[i] * n.inverse_mass;
            }
        }
    }
    // The parting does not push a node into an obstacle either (the obstacle takes that share);
    // the rows' impulses are the obstacles' reactions.
    for row in solver_nodes.ground.iter() {
        let n = &mut solver_nodes.nodes[row.slot as usize];
        let below = row.floor - row.normal.dot(&n.end);
        if below > 0.0 {
            n.end += row.normal * below;
        }
        if let Some(reaction) = reactions.get_mut(row.obstacle as usize) {
            *reaction += row.normal * (row.impulse / dt);
        }
    }
    // The ends of tick the response moved (its displacement impulses and the parting: nodes of
    // its contacts that a tool does not hold), for the net's hierarchies and bounds.
    for n in &solver_nodes.nodes {
        if n.inverse_mass == 0.0 {
            continue;
        }
        let (r, end) = (n.r, n.end);
        scratch.tight_bounds[r.body].include(&end);
        let motion = (end - n.start).norm();
        let largest = &mut scratch.max_motion[r.body];
        *largest = largest.max(motion);
    }
    scratch.ground_warm.clear();
    for row in solver_nodes.ground.iter() {
        if row.impulse > 0.0 {
            let r = solver_nodes.nodes[row.slot as usize].r;
            scratch.ground_warm.push((r, row.obstacle, row.impulse));
        }
    }
    scratch
        .ground_warm
        .sort_unstable_by_key(|&(r, obstacle, _)| (r, obstacle));
    // The sub-stepped nodes' contact forces, for their next substeps (see `carried_on`).
    for n in solver_nodes.nodes.iter() {
        if n.inverse_mass != 0.0
            && n.force != Vec3::zeros()
            && sub_stepped(n.r.body, n.r.node)
            && scratch.carried.len() < scratch.carried.capacity()
        {
            scratch.carried.push((n.r, n.force));
        }
    }
    scratch.carried.sort_unstable_by_key(|&(r, _)| r);
    for n in solver_nodes.nodes.iter() {
        if let Some(moved) = scratch.moved.get_mut(n.r.body) {
            *moved = true;
        }
    }
}

/// This tick's contacts kept for the next tick: the impulses for its warm start, the held and
/// remembered runs, the remembered pairs, the topology they were made on.
fn remember_for_next_tick(
    bodies: &[Body],
    scratch: &mut BodyContactScratch,
    (held_kept, remembered_kept): (usize, usize),
) {
    // This tick's impulses for the next tick's warm start, in the contacts' order.
    scratch.warm.clear();
    for c in scratch.contacts.iter() {
        scratch.warm.push(WarmContact {
            a: c.a,
            b: c.b,
            normal_impulse: c.normal_impulse,
            tangent_impulse: c.tangent_impulse,
        });
    }
    scratch.warm_held = held_kept;
    scratch.warm_remembered = remembered_kept;
    // The remembered contacts with the impulses they took, for the next tick (the net adds its
    // answers of this tick).
    scratch.remembered.clear();
    for c in &scratch.contacts[remembered_kept..] {
        remember(
            (&mut scratch.remembered, &mut scratch.remembered_dropped),
            Remembered::of_contact(c),
        );
    }
    scratch.warm_versions.clear();
    scratch
        .warm_versions
        .extend(bodies.iter().map(|b| b.topology_version));
}

/// The contact response between bodies: every vertex that ends the tick within the skin of another
/// body's face (or crossed it) gets an inelastic normal impulse and a Coulomb friction impulse,
/// the opposite of each shared by the face's three nodes with their barycentric weights — so the
/// linear momentum of the pair does not change and the forces on the two bodies are equal and
/// opposite. Solved by sweeps over the contacts in a fixed order with accumulated impulses (normal
/// ≥ 0, tangential within μ times the normal; μ = √(μ_a μ_b) from the two bodies' `friction`). A
/// vertex may close the gap it had at the start of the tick down to half the skin and no more (or
/// as fast as the nodes a tool holds close it, for a contact [`MAX_AMPLIFICATION`] relaxes); end
/// positions closer than that are parted by a fifth of the shortfall (positions only). The impulses
/// act on the displacements over the tick and the end velocities alike, and a node they pushed ends
/// with its displacement's velocity (but a node for which `sub_stepped` is true: its substeps took
/// last tick's contact forces, which it is given back for its next substeps, and it keeps its
/// velocity). An edge whose nearest side changed keeps a held contact with
/// the side it pressed last tick, its normal impulse capped at [`HOLD_SHARE`] of last tick's. A
/// node on an obstacle (within the skin of it) may not be
/// pushed into it: the obstacle is a one-sided row of the same solve ([`GroundRow`]), and its
/// impulses are added to `reactions`. Run before the collision net ([`resolve_body_collisions`]),
/// which still guarantees no pass-through.
pub fn respond_to_body_contacts(
    bodies: &mut [Body],
    group: &[usize],
    (obstacles, reactions): (&[Obstacle], &mut [Vec3]),
    scratch: &mut BodyContactScratch,
    sub_stepped: impl Fn(usize, usize) -> bool,
    dt: f64,
) -> BodyContactCounters {
    let mut counters = BodyContactCounters::default();
    scratch.moved.clear();
    scratch.moved.resize(bodies.len(), false);
    // (Last tick's were carried into this tick's substeps.)
    scratch.carried.clear();
    scratch.forces.clear();
    scratch.forces.resize(bodies.len(), Vec3::zeros());
    scratch.work.clear();
    scratch.work.resize(bodies.len(), 0.0);
    scratch.prepared = Prepared::NoneNear;
    counters.contacts_dropped += std::mem::take(&mut scratch.remembered_dropped);
    if bodies.len() < 2 {
        scratch.forget();
        return counters;
    }
    scratch.contacts.clear();
    // The bounds with no margin (kept for the net), then grown by the skin: the bodies near within
    // the skin are those whose grown bounds meet.
    scratch.find_bounds(bodies, group);
    scratch.tight_bounds.clear();
    scratch.tight_bounds.extend_from_slice(&scratch.bounds);
    for (k, aabb) in scratch.bounds.iter_mut().enumerate() {
        aabb.inflate(CONTACT_SKIN);
        scratch.near[k] = false;
    }
    if !mark_near(group, &scratch.bounds, &mut scratch.near) {
        scratch.forget();
        return counters;
    }
    // Each vertex of a body near another once against that body's faces, each edge once against
    // its edges: the candidates are the other body's triangles whose swept boxes meet the vertex's
    // (edge's) swept box grown by the skin — a vertex (edge) within the skin of a face (edge) at
    // the end of the tick has its swept box within the skin of that face's (edge's) box, and a
    // vertex that crossed the inside of a face over the tick has a swept box meeting the face's.
    // (A vertex ending deeper than the skin behind a face it did not cross inside is left to the
    // collision net, which stops it: no pass-through either way.) The pairs that may meet are
    // listed from the hierarchies only when a body moved out of the slack of its last listing
    // ([`CandidateCache`]), and each listed pair is checked with this tick's boxes: the same
    // candidates as a query of the hierarchies every tick, and the same contacts.
    scratch.cache.list(
        bodies,
        group,
        (&scratch.bounds, &scratch.near),
        ListCall::Response,
        &mut scratch.bvhs,
        (&mut scratch.near_triangles, &mut scratch.found),
        &mut counters,
    );
    scratch.now.begin(bodies);
    scratch.prepared = Prepared::Listed;
    let simd = crate::dynamics::kernel::simd_available();
    let slots = scratch.cache.slots;
    for i in 0..bodies.len() {
        for j in 0..bodies.len() {
            if i == j
                || group.get(i).is_some_and(|g| group.get(j) == Some(g))
                || !scratch.bounds[i].overlaps(&scratch.bounds[j])
            {
                continue;
            }
            let pair = i * slots + j;
            if scratch.cache.listed[pair] == NOT_LISTED {
                continue;
            }
            debug_assert!(!scratch.cache.entries_due[pair], "entries listed");
            let [vertices, edges] = scratch.cache.ranges[pair];
            vertex_face_contacts(bodies, (i, j), vertices, scratch, &mut counters, simd);
            edge_edge_contacts(bodies, (i, j), edges, scratch, &mut counters, simd);
        }
    }
    let held_from = scratch.contacts.len();
    held_contacts(bodies, scratch, &mut counters);
    let remembered_from = scratch.contacts.len();
    remembered_contacts(bodies, scratch, &mut counters);
    let (held_kept, remembered_kept) = keep_contacts(
        bodies,
        scratch,
        &mut counters,
        (held_from, remembered_from),
        dt,
    );
    let solver_nodes = &mut scratch.solver_nodes;
    counters.contacts = scratch.contacts.len() as u32;
    // The obstacles the contacts' nodes rest on, which the impulses may not push them into.
    counters.overflows += ground_rows(
        solver_nodes,
        obstacles,
        (&scratch.ground_warm, |k| {
            same_topology(&scratch.warm_versions, bodies, k)
        }),
        dt,
    );
    // Warm start: a contact that was there last tick, between the same nodes of bodies whose
    // topology did not change, starts from last tick's impulses (its tangential one on this
    // tick's tangent plane, within the cone): a resting stack's solve then starts where the last
    // one ended instead of from nothing, so a few sweeps carry a heavy organ's weight through a
    // light one's nodes (without it, its unfinished solves leave gaps below the rest distance
    // each tick, and the parting, which knows no friction, lets the heavy organ creep off).
    warm_start(
        (&mut scratch.contacts, &mut scratch.contact_nodes),
        (&scratch.warm, &scratch.warm_versions),
        bodies,
        solver_nodes,
        dt,
    );
    // The displacements over the tick (where the nodes end: no approach past the rest distance,
    // no slip where friction holds; the impulses change the end velocities alike). Each impulse
    // changes the pair's momentum by equal and opposite amounts.
    solve(
        solver_nodes,
        (&mut scratch.contacts, &mut scratch.contact_nodes),
        dt,
    );
    apply_impulses(scratch, reactions, &sub_stepped, dt);
    scratch.solver_nodes.write_back(bodies);
    remember_for_next_tick(bodies, scratch, (held_kept, remembered_kept));
    counters
}

/// Lists a [`GroundRow`] for each listed node the response may move that ends the tick on an
/// obstacle, behind it or near it (a plane within the skin plus twice the largest displacement of a
/// listed node the response may move, a box within the skin; at most [`GROUND_PER_NODE`] a node, in the order
/// of the nodes then of the obstacles); returns how many did not fit.
///
/// Each row starts from the impulse the same node's row on the same obstacle ended last tick with
/// (`warm`, sorted; none where the node's body changed its topology since, `unchanged`), applied to
/// the node, as the contacts start from theirs ([`warm_start`]). The solve's sweeps pass over the
/// contacts, then the rows: an organ pressing another flat on the table pushes the lower one's
/// nodes into it at each sweep, their rows push them back, and each sweep closes about half of what
/// is left between the two organs' nodes. Started from nothing, the rows had to carry the upper
/// organ's weight anew every tick, and four sweeps left its nodes over the flattened organ closing
/// on it at up to 23 mm/s: they kept that velocity (the parting moved them back, not the velocity),
/// kinetic energy that was no motion, and the pair never rested (up to 35 µJ at 3 to 10 s).
fn ground_rows(
    solver_nodes: &mut SolverNodes,
    obstacles: &[Obstacle],
    (warm, unchanged): (&[(NodeRef, u32, f64)], impl Fn(usize) -> bool),
    dt: f64,
) -> u32 {
    let mut overflows = 0;
    let SolverNodes { nodes, ground, .. } = solver_nodes;
    if obstacles.is_empty() {
        return 0;
    }
    // A node beyond the skin can be pushed onto the obstacle by the impulses too: by about what
    // the nodes it touches move over the tick (a heavy organ pressing a light one flat against the
    // table pushed nodes up to 3 mm under it, from above the skin). Nodes within twice the largest
    // motion of a listed node get a row; it stays idle unless the impulses reach the plane.
    // (A box's nearest face is taken within the skin only: farther, beside its rim, it is no floor.)
    let fastest = nodes
        .iter()
        .filter(|n| n.inverse_mass != 0.0)
        .map(|n| n.motion.norm_squared())
        .fold(0.0, f64::max)
        .sqrt();
    let plane_reach = CONTACT_SKIN + 2.0 * fastest * dt;
    for (slot, n) in nodes.iter().enumerate() {
        if n.inverse_mass == 0.0 {
            continue;
        }
        let mut rows = 0;
        for (k, obstacle) in obstacles.iter().enumerate() {
            let reach = if obstacle.shape.as_plane().is_some() {
                plane_reach
            } else {
                CONTACT_SKIN
            };
            let Some(plane) = obstacle.shape.plane_within(&n.end, reach) else {
                continue;
            };
            if rows == GROUND_PER_NODE || ground.len() == ground.capacity() {
                overflows += 1;
                continue;
            }
            rows += 1;
            let normal = plane.normal_in_world;
            let floor = normal.dot(&plane.point_in_world).min(normal.dot(&n.end));
            // Warm start: last tick's impulse of the same node on the same obstacle.
            let impulse = if unchanged(n.r.body) {
                warm.binary_search_by(|w| (w.0, w.1).cmp(&(n.r, k as u32)))
                    .map_or(0.0, |at| warm[at].2)
            } else {
                0.0
            };
            ground.push(GroundRow {
                slot: slot as u32,
                obstacle: k as u32,
                normal,
                floor,
                impulse,
            });
        }
    }
    // The warm impulses applied once every row is listed (the rows are taken at the ends as
    // the obstacle passes left them).
    for row in ground.iter() {
        if row.impulse > 0.0 {
            let n = &mut nodes[row.slot as usize];
            let dv = row.normal * (row.impulse * n.inverse_mass);
            n.end += dv * dt;
            n.motion += dv;
            n.velocity += dv;
        }
    }
    overflows
}

/// How far ahead of the last match [`warm_start`] looks for a contact of last tick.
const WARM_WINDOW: usize = 16;

/// Whether body `k` has the topology version it had in `versions` (last tick's): its node indices
/// still name the same nodes.
fn same_topology(versions: &[u64], bodies: &[Body], k: usize) -> bool {
    versions.get(k) == Some(&bodies[k].topology_version)
}

/// The first entry of `list` among the [`WARM_WINDOW`] from `*cursor` on that `matches`, the
/// cursor moved past it: a walk of last tick's contacts alongside this tick's, which come in the
/// same relative order (see [`warm_start`]).
fn next_match<'a, T>(
    list: &'a [T],
    cursor: &mut usize,
    matches: impl Fn(&T) -> bool,
) -> Option<&'a T> {
    let ahead = &list[(*cursor).min(list.len())..(*cursor + WARM_WINDOW).min(list.len())];
    let found = ahead.iter().position(matches)?;
    *cursor += found + 1;
    Some(&ahead[found])
}

/// Share of last tick's normal impulse a held contact may take (see the response's held
/// contacts): the support of a side an edge no longer has nearest goes in halves. (A quarter:
/// single ticks of 8e-6 and 1.2e-5 J in the pressed pair of `tests/body_contact.rs`, against
/// 6.7e-6 and 5.2e-6 J at a half.)
const HOLD_SHARE: f64 = 0.5;

/// Scales `tangent` back into the Coulomb cone of the limit `limit`: `tangent × min(limit /
/// |tangent|, 1)`, which is `tangent` to the bit inside (limit / |tangent| ≥ 1, or not a number:
/// 0 / 0). Two cases skip the square root and the division, with the same bits:
/// - no limit (no normal impulse, no friction) and a length above zero: limit / |tangent| is the
///   limit itself, a zero of its sign, and so is its minimum with 1 (a contact within the skin that
///   does not press, most of a stack's updates);
/// - well inside: the square, a normal number, below the limit's by a relative room far above the
///   rounding of the squares and the square root (a sticking contact's usual case). A square below
///   the normal numbers may have lost the relative precision, and one that overflowed is not well
///   inside whatever the limit: the whole computation then.
#[inline(always)]
fn within_cone(tangent: &mut Vec3, limit: f64) {
    let square = tangent.norm_squared();
    if limit == 0.0 && square > 0.0 {
        *tangent *= limit;
    } else if !((f64::MIN_POSITIVE..=f64::MAX).contains(&square)
        && square <= limit * limit * (1.0 - BOUND_ROUNDING))
    {
        // (nalgebra's norm: the square root of this square.)
        let size = square.sqrt();
        *tangent *= (limit / size).min(1.0);
    }
}

/// Starts each contact that was in last tick's list `warm` (the same nodes on both sides, of bodies
/// whose topology versions are those of `versions`) from last tick's accumulated impulses, applied
/// to its nodes: the normal one as it was, the tangential one on this tick's tangent plane and
/// within the friction cone of the normal one. The contacts that stay come in the same relative
/// order from tick to tick (the order of the candidate lists), so last tick's list is walked
/// alongside this one, each contact looked for among the next [`WARM_WINDOW`] entries after the
/// last match (a contact not found there starts from nothing, as every contact did before).
fn warm_start(
    (contacts, contact_nodes): (&mut [Contact], &mut [ContactNodes]),
    (warm, versions): (&[WarmContact], &[u64]),
    bodies: &[Body],
    solver_nodes: &mut SolverNodes,
    dt: f64,
) {
    let unchanged = |k: usize| same_topology(versions, bodies, k);
    let mut next = 0;
    for (c, nodes) in contacts.iter_mut().zip(contact_nodes.iter_mut()) {
        if c.compliance <= 0.0 || !unchanged(c.a[0].body) || !unchanged(c.b[0].body) {
            continue;
        }
        let Some(&last) = next_match(warm, &mut next, |w| w.a == c.a && w.b == c.b) else {
            continue;
        };
        let normal_impulse = last.normal_impulse.min(c.cap);
        let mut tangent_impulse =
            last.tangent_impulse - c.normal * c.normal.dot(&last.tangent_impulse);
        within_cone(&mut tangent_impulse, c.friction * normal_impulse);
        c.normal_impulse = normal_impulse;
        c.tangent_impulse = tangent_impulse;
        let impulse = c.normal * normal_impulse + tangent_impulse;
        if impulse != Vec3::zeros() {
            apply_impulse(solver_nodes, nodes, &impulse, (0, dt));
        }
    }
}

/// Half-width (m), per axis, of the region a node's trajectory may wander over from the box it had
/// when the response last listed its body's candidate pairs, before they are listed again.
const CANDIDATE_SLACK: f64 = 2.5e-4;
/// Capacity of the response's candidate list (a feature of one body against a triangle of another).
const CANDIDATE_CAPACITY: usize = 1 << 16;
/// A body that took a new reference on this many ticks in a row takes the next with no slack (its
/// pairs listed every tick while it moves so fast, as a query every tick would, where a larger reach
/// would only cost more), and every [`RETRY_EVERY`]-th tick of such a run tries the slack again.
const FAST_STREAK: u32 = 3;
/// Ticks between tries of the slack for a body that keeps leaving it (see [`FAST_STREAK`]).
const RETRY_EVERY: u32 = 32;
/// Margin of a body's triangles' boxes in the hierarchy fitted to its reference, and of its
/// vertices' and edges' boxes beyond the skin in its queries, per metre of its slack: two boxes
/// that meet within the two bodies' slacks (and rounding) meet once each is grown by its margin.
const LIST_MARGIN_PER_SLACK: f64 = 1.5;

/// A pair of bodies' candidates not listed.
const NOT_LISTED: u8 = 0;
/// Listed, and held while the two bodies stay within their slack.
const LISTED: u8 = 1;
/// Listed for this tick only (a body with no reference): used this tick, listed again the next.
const LISTED_FOR_NOW: u8 = 2;
/// Listed in part (a list was full; counted as an overflow): used this tick, listed again the next.
const LISTED_IN_PART: u8 = 3;

/// A vertex (`[v, v]`) or an edge (`[a, b]`, a < b) of one body and a triangle of another whose
/// boxes may meet within the skin.
#[derive(Clone, Copy, Debug, Default)]
struct Candidate {
    feature: [u32; 2],
    /// For a vertex, the triangle (and 0); for an edge, the two nodes of a side of a triangle that
    /// owns it, the smaller first.
    other: [u32; 2],
}

/// The candidate pairs of the response and of the net, kept from tick to tick (a Verlet list). Each
/// body keeps the box of each node's trajectory when its pairs were last listed (its *reference*);
/// the pairs of two bodies are listed from hierarchies fitted to their references, grown by the
/// skin (the response's) and three times the slack, and hold while every node's trajectory stays
/// within the slack of its reference box: two boxes of this tick (a vertex's or edge's grown by the
/// skin, a triangle's) then meet only if their references, grown by the skin and twice the slack,
/// meet (the third slack covers rounding, far above it). A body whose nodes left their slack (or
/// whose topology changed) takes a new reference and its pairs are listed again; a resting stack
/// lists once. The net's rounds only shorten trajectories, within the same boxes. The pairs are
/// checked with this tick's boxes ([`TriangleBoxes`]) where they are used, so the candidates are
/// those of queries of hierarchies refitted every tick; the net's triangle pairs keep the order of a
/// traversal of the two hierarchies (which does not depend on the boxes: a traversal of boxes that
/// meet less gives a subsequence).
#[derive(Clone, Debug)]
struct CandidateCache {
    /// Per body, the lower and upper corners of each node's reference box (room for its most
    /// nodes), and the topology version and node count of the reference (`None`: none taken, or
    /// no room, when the body's trajectories serve as its boxes and are listed again every tick).
    lower: Vec<Room<Vec3>>,
    upper: Vec<Room<Vec3>>,
    reference: Vec<Option<(u64, usize)>>,
    /// Per body, the slack of its reference (m): [`CANDIDATE_SLACK`], or 0 for a body that left it
    /// on several ticks in a row.
    slack: Vec<f64>,
    /// Per body, the name of its reference (a count of the references taken, never 0), which its
    /// hierarchy carries while fitted to it (see [`Self::refit_for_listing`]).
    generation: Vec<u64>,
    generations: u64,
    /// Per body, the boxes of its nodes' trajectories on a recent tick of the net (its *anchor*;
    /// the near bodies' are taken together, see [`Self::list`]), with the topology version and
    /// node count it holds for (`None`: none, or no room), the net's tick it was taken on, and
    /// how far this tick's trajectories leave it (as of the net's listing; infinite when
    /// unknown, or once it was left by more than [`ANCHOR_SLACK`], which `anchor_left` marks).
    /// The net weighs its pairs of bodies' least gaps against it ([`Self::least_gaps`]).
    anchor_lower: Vec<Room<Vec3>>,
    anchor_upper: Vec<Room<Vec3>>,
    anchor: Vec<Option<(u64, usize)>>,
    anchored_at: Vec<u64>,
    anchor_excursion: Vec<f64>,
    anchor_left: Vec<bool>,
    /// The net's ticks (its listings) so far, and the last the anchors were taken on.
    net_ticks: u64,
    anchor_tick: Option<u64>,
    /// Per body, whether its pairs are to be listed again this tick, and on how many ticks in a row
    /// (up to this one) they were.
    renewed: Vec<bool>,
    streak: Vec<u32>,
    /// Per ordered pair of bodies (i × `slots` + j): whether its candidates are listed
    /// ([`LISTED`]; [`LISTED_FOR_NOW`] or, when a list was full, [`LISTED_IN_PART`]: used this
    /// tick, listed again the next), their ranges (vertices of i, then edges of i when j > i) in
    /// the list in use, and when i < j the range of its triangle pairs (the net's) in theirs.
    listed: Vec<u8>,
    /// Per ordered pair of bodies: listed by the net without its response's entries (their ranges
    /// empty), which the response's next call lists (see [`Self::relist`]).
    entries_due: Vec<bool>,
    ranges: Vec<[(u32, u32); 2]>,
    pair_ranges: Vec<(u32, u32)>,
    /// Per pair of bodies (i < j), the least gap between the boxes of its triangle pairs (the
    /// net's) in the two bodies' anchors, and the net's tick both anchors were taken on (not a
    /// number when its pairs were listed since). A triangle's box of a later tick lies within its
    /// anchor box grown by its body's excursion from the anchor: while neither anchor is taken
    /// again, a pair of bodies whose least gap exceeds their two excursions has no triangle boxes
    /// that meet, and the net passes it over.
    least_gaps: Vec<(f64, u64)>,
    /// The lists in use (grouped by pair, then by feature) and the ones a new listing is written
    /// to: the response's candidates, and the net's triangle pairs (whose boxes may meet, in the
    /// order of the hierarchies' traversal).
    entries: [Room<Candidate>; 2],
    pairs: [Room<(u32, u32)>; 2],
    /// Beside each triangle pair of `pairs`, the gap between the two triangles' anchor boxes,
    /// found with the pair of bodies' least gap (not a number until then): while the anchors hold,
    /// a triangle pair whose gap exceeds the two excursions has boxes that do not meet.
    pair_gaps: [Room<f64>; 2],
    current: usize,
    /// The bodies the tables have room for.
    slots: usize,
    /// False: every near body takes a new reference every tick (its pairs listed every tick).
    keep: bool,
}

impl CandidateCache {
    fn new(bodies: &[Body], slots: usize, spare_nodes: usize) -> Self {
        let room = |k: usize| {
            bodies
                .get(k)
                .map_or(spare_nodes, |b| b.mesh_capacity().0.max(b.node_count()))
        };
        Self {
            lower: (0..slots).map(|k| Room::with_capacity(room(k))).collect(),
            upper: (0..slots).map(|k| Room::with_capacity(room(k))).collect(),
            reference: vec![None; slots],
            slack: vec![0.0; slots],
            generation: vec![0; slots],
            generations: 0,
            anchor_lower: (0..slots).map(|k| Room::with_capacity(room(k))).collect(),
            anchor_upper: (0..slots).map(|k| Room::with_capacity(room(k))).collect(),
            anchor: vec![None; slots],
            anchored_at: vec![0; slots],
            anchor_excursion: vec![f64::INFINITY; slots],
            anchor_left: vec![false; slots],
            net_ticks: 0,
            anchor_tick: None,
            renewed: vec![false; slots],
            streak: vec![0; slots],
            listed: vec![NOT_LISTED; slots * slots],
            entries_due: vec![false; slots * slots],
            ranges: vec![[(0, 0); 2]; slots * slots],
            pair_ranges: vec![(0, 0); slots * slots],
            least_gaps: vec![(f64::NAN, 0); slots * slots],
            entries: [
                Room::with_capacity(CANDIDATE_CAPACITY),
                Room::with_capacity(CANDIDATE_CAPACITY),
            ],
            pairs: [
                Room::with_capacity(PAIR_CAPACITY),
                Room::with_capacity(PAIR_CAPACITY),
            ],
            pair_gaps: [
                Room::with_capacity(PAIR_CAPACITY),
                Room::with_capacity(PAIR_CAPACITY),
            ],
            current: 0,
            slots,
            keep: true,
        }
    }

    /// Whether every node of body `k` has its trajectory this tick within the slack of its
    /// reference box (and the topology is the reference's).
    fn holds(&self, k: usize, body: &Body) -> bool {
        let s = &body.surface;
        if !Self::holds_for(self.reference[k], body) {
            return false;
        }
        within_slack(
            [&s.position_in_world, &s.next_position_in_world],
            [&self.lower[k], &self.upper[k]],
            self.slack[k],
            crate::dynamics::kernel::simd_available(),
        )
    }

    /// Whether boxes taken at `held` (a topology version and node count) are for `body`'s topology.
    fn holds_for(held: Option<(u64, usize)>, body: &Body) -> bool {
        held == Some((body.topology_version, body.surface.position_in_world.len()))
    }

    /// Body `k`'s trajectories this tick as its anchor (none when there is no room for them).
    fn anchor(&mut self, k: usize, body: &Body) {
        self.anchored_at[k] = self.net_ticks;
        self.anchor_left[k] = false;
        self.anchor[k] =
            boxes_of_trajectories(body, (&mut self.anchor_lower[k], &mut self.anchor_upper[k]));
        self.anchor_excursion[k] = if self.anchor[k].is_some() {
            0.0
        } else {
            f64::INFINITY
        };
    }

    /// Body `k`'s trajectories this tick as its reference (none when there is no room for them).
    fn renew(&mut self, k: usize, body: &Body) {
        let streak = self.streak[k];
        self.slack[k] = if streak >= FAST_STREAK && streak % RETRY_EVERY != 0 {
            0.0
        } else {
            CANDIDATE_SLACK
        };
        self.reference[k] = boxes_of_trajectories(body, (&mut self.lower[k], &mut self.upper[k]));
        self.generations += 1;
        self.generation[k] = self.generations;
    }

    /// Brings the lists up to date for the pairs of bodies near each other (`bounds` meet):
    /// bodies whose nodes left their slack take a new reference, and the pairs of such bodies, the
    /// pairs listed in part, and the near pairs not listed yet, are listed from the hierarchies
    /// refitted to the references (grown by their margins). The hierarchies are the references':
    /// this tick's boxes come from [`TriangleBoxes`].
    ///
    /// `call` says who calls: the response (first of the tick), the net's first round, or the net
    /// between two rounds after impulses moved ends ([`ListCall::NetAgain`]: the anchors'
    /// excursions are measured again, the anchors not taken again, the tick not counted).
    #[allow(clippy::too_many_arguments)]
    fn list(
        &mut self,
        bodies: &[Body],
        group: &[usize],
        (bounds, near): (&[Aabb], &[bool]),
        call: ListCall,
        bvhs: &mut [TriangleBvh],
        (near_triangles, found): (&mut Vec<u32>, &mut Vec<u32>),
        counters: &mut BodyContactCounters,
    ) {
        let n = bodies.len().min(self.slots);
        let first_of_tick = call == ListCall::Response;
        if call == ListCall::Net {
            self.net_ticks += 1;
        }
        self.renew_references(&bodies[..n], near, first_of_tick);
        if call == ListCall::Net {
            self.take_anchors(&bodies[..n], near);
        }
        let pairs_of = |i: usize, j: usize| pair_to_list(group, bounds, i, j);
        // The response's entries are listed by the response only: the net's calls list the
        // triangle pairs alone (see `relist`).
        let entries = first_of_tick;
        if !self.unlist_renewed(n, pairs_of, entries) {
            return;
        }
        self.refit_for_listing(&bodies[..n], bvhs, pairs_of, entries);
        self.relist(
            &bodies[..n],
            (pairs_of, entries),
            bvhs,
            (near_triangles, found),
            counters,
        );
    }

    /// Whether ordered pair `i`, `j` (one `pairs_of` asks for) is to be listed: not listed, or,
    /// with `entries` (the response's call), listed by the net without its entries.
    fn to_list(&self, (i, j): (usize, usize), entries: bool) -> bool {
        let pair = i * self.slots + j;
        self.listed[pair] == NOT_LISTED || (entries && self.entries_due[pair])
    }

    /// Per body near another: its references renewed where they no longer hold (or when they are
    /// not kept), how far the net's anchor was left, and (at the tick's first call) the streak of
    /// ticks renewed.
    fn renew_references(&mut self, bodies: &[Body], near: &[bool], first_of_tick: bool) {
        for (k, body) in bodies.iter().enumerate() {
            self.renewed[k] =
                near[k] && (!self.keep || self.reference[k].is_none() || !self.holds(k, body));
            // How far the net's anchor was left (unknown for a body not near another, none of
            // whose pairs is used this tick; an anchor once left by more than its slack is not
            // weighed again until it is taken again).
            self.anchor_excursion[k] = f64::INFINITY;
            if near[k]
                && !first_of_tick
                && !self.anchor_left[k]
                && Self::holds_for(self.anchor[k], body)
            {
                let anchor = [&self.anchor_lower[k][..], &self.anchor_upper[k][..]];
                self.anchor_excursion[k] = excursion(
                    [
                        &body.surface.position_in_world,
                        &body.surface.next_position_in_world,
                    ],
                    anchor,
                    crate::dynamics::kernel::simd_available(),
                );
                self.anchor_left[k] = self.anchor_excursion[k] > ANCHOR_SLACK;
            }
            if first_of_tick {
                self.streak[k] = if self.renewed[k] {
                    self.streak[k].saturating_add(1)
                } else {
                    0
                };
            }
            if self.renewed[k] {
                self.renew(k, body);
            }
        }
    }

    /// The net's anchors, all near bodies' on the same tick (a pair's least gap is found with both
    /// anchors): taken again when one is not for its body's topology or was left by more than its
    /// slack, at most every [`ANCHOR_HELD`] ticks (bodies that move on have no use for them; an
    /// anchor left by more is still sound, only looser).
    fn take_anchors(&mut self, bodies: &[Body], near: &[bool]) {
        let n = bodies.len();
        // (Infinite for an anchor that does not hold for the body's topology, or none.)
        let wanted = (0..n).any(|k| near[k] && self.anchor_excursion[k] > ANCHOR_SLACK);
        if wanted
            && self
                .anchor_tick
                .is_none_or(|tick| self.net_ticks - tick >= ANCHOR_HELD)
        {
            self.anchor_tick = Some(self.net_ticks);
            for k in (0..n).filter(|&k| near[k]) {
                self.anchor(k, &bodies[k]);
            }
        }
    }

    /// Unlists the pairs of a renewed body, and those listed only for now or in part; returns
    /// whether any pair `pairs_of` asks for is left to list (with `entries`, also one whose
    /// entries are due).
    fn unlist_renewed(
        &mut self,
        n: usize,
        pairs_of: impl Fn(usize, usize) -> bool,
        entries: bool,
    ) -> bool {
        let mut any = false;
        for i in 0..n {
            for j in 0..n {
                let pair = i * self.slots + j;
                if self.renewed[i] || self.renewed[j] || self.listed[pair] > LISTED {
                    self.listed[pair] = NOT_LISTED;
                    self.entries_due[pair] = false;
                }
                any |= self.to_list((i, j), entries) && pairs_of(i, j);
            }
        }
        any
    }

    /// The hierarchies of the bodies of the pairs to list, refitted to their references (rebuilt
    /// first for a body whose topology changed).
    fn refit_for_listing(
        &self,
        bodies: &[Body],
        bvhs: &mut [TriangleBvh],
        pairs_of: impl Fn(usize, usize) -> bool,
        entries: bool,
    ) {
        let n = bodies.len();
        let to_list = |i: usize, j: usize| self.to_list((i, j), entries) && pairs_of(i, j);
        for (k, (body, bvh)) in bodies.iter().zip(bvhs.iter_mut()).enumerate() {
            let wanted = (0..n).any(|o| to_list(k, o) || to_list(o, k));
            if !wanted {
                continue;
            }
            let s = &body.surface;
            if !bvh.is_built_for(body.topology_version, s.triangles.len()) {
                bvh.rebuild(&s.triangles, &s.position_in_world);
                bvh.set_built_version(body.topology_version);
            }
            // A hierarchy still fitted to the body's reference (its pairs with another body
            // listed again, its own reference kept) is not fitted again: the same boxes. (Without
            // a reference the body's trajectories serve, which change every tick.)
            let tag = match self.reference[k] {
                Some(_) => self.generation[k],
                None => 0,
            };
            if tag != 0 && bvh.fit_tag() == tag {
                continue;
            }
            let (lower, upper) =
                reference_boxes(self.reference[k], &self.lower[k], &self.upper[k], body);
            bvh.refit(
                &s.triangles,
                lower,
                upper,
                LIST_MARGIN_PER_SLACK * self.slack[k],
            );
            bvh.set_fit_tag(tag);
        }
    }

    /// New lists into the other of the two buffers: the pairs that hold, copied; the others that
    /// `pairs_of` asks for, listed (each pair of bodies' vertex and edge entries, and once per
    /// pair, `i < j`, the net's triangle pairs).
    ///
    /// The entries are the response's, which reads them once a tick, before the net: with
    /// `entries` false (the net's calls) a pair is listed without them (its ranges empty, its
    /// entries due), and the response's next call lists them, from the same references and
    /// hierarchies fitted to them (a pair whose body took a new reference since is listed whole
    /// again), so the same entries in the same place of the list. Where the response's pushes
    /// take a body out of its slack, its pairs' entries were listed twice in the tick, the second
    /// time for nothing: in the laparoscopy scene, most of its dearest ticks' cost.
    fn relist(
        &mut self,
        bodies: &[Body],
        (pairs_of, entries): (impl Fn(usize, usize) -> bool, bool),
        bvhs: &mut [TriangleBvh],
        (near_triangles, found): (&mut Vec<u32>, &mut Vec<u32>),
        counters: &mut BodyContactCounters,
    ) {
        let slots = self.slots;
        let current = self.current;
        let [first, second] = &mut self.entries;
        let (used, next) = if current == 0 {
            (&*first, second)
        } else {
            (&*second, first)
        };
        let [first_pairs, second_pairs] = &mut self.pairs;
        let (used_pairs, next_pairs) = if current == 0 {
            (&*first_pairs, second_pairs)
        } else {
            (&*second_pairs, first_pairs)
        };
        let [first_gaps, second_gaps] = &mut self.pair_gaps;
        let (used_gaps, next_gaps) = if current == 0 {
            (&*first_gaps, second_gaps)
        } else {
            (&*second_gaps, first_gaps)
        };
        next.clear();
        next_pairs.clear();
        next_gaps.clear();

        for (i, body) in bodies.iter().enumerate() {
            for (j, body_j) in bodies.iter().enumerate() {
                let pair = i * slots + j;
                let due = entries && self.entries_due[pair] && pairs_of(i, j);
                if self.listed[pair] == LISTED {
                    if !due {
                        let mut ranges = self.ranges[pair];
                        for range in &mut ranges {
                            let start = next.len() as u32;
                            next.extend_from_slice(&used[range.0 as usize..range.1 as usize]);
                            *range = (start, next.len() as u32);
                        }
                        self.ranges[pair] = ranges;
                    }
                    let range = self.pair_ranges[pair];
                    let start = next_pairs.len() as u32;
                    next_pairs.extend_from_slice(&used_pairs[range.0 as usize..range.1 as usize]);
                    next_gaps.extend_from_slice(&used_gaps[range.0 as usize..range.1 as usize]);
                    self.pair_ranges[pair] = (start, next_pairs.len() as u32);
                    if !due {
                        continue;
                    }
                }
                if !pairs_of(i, j) {
                    continue;
                }
                // The response's entries, or (in the net's calls) their ranges left empty.
                let mut complete = true;
                if entries {
                    let (lower_i, upper_i) =
                        reference_boxes(self.reference[i], &self.lower[i], &self.upper[i], body);
                    let (lower_j, upper_j) =
                        reference_boxes(self.reference[j], &self.lower[j], &self.upper[j], body_j);
                    complete &= list_pair(
                        (i, j, body),
                        (
                            (lower_i, upper_i),
                            OtherReference {
                                triangles: &body_j.surface.triangles,
                                lower: lower_j,
                                upper: upper_j,
                                margin: LIST_MARGIN_PER_SLACK * self.slack[j],
                            },
                        ),
                        bvhs,
                        // A vertex's (edge's) box grown by the skin and its body's margin,
                        // against triangle boxes grown by theirs. (The skin with the margin of
                        // the cheap tests, which let an edge through to be counted up to that
                        // far: listed with no slack, a side 1e-6 of the skin beyond it went
                        // uncounted.)
                        CONTACT_SKIN * (1.0 + EARLY_OUT_MARGIN)
                            + LIST_MARGIN_PER_SLACK * self.slack[i],
                        (near_triangles, found),
                        next,
                        &mut self.ranges[pair],
                    );
                } else {
                    let at = next.len() as u32;
                    self.ranges[pair] = [(at, at); 2];
                }
                self.entries_due[pair] = !entries;
                counters.listed_pairs += 1;
                if due {
                    // Only the entries were due: the triangle pairs were copied above.
                    if !complete {
                        self.listed[pair] = LISTED_IN_PART;
                        counters.overflows += 1;
                    }
                    continue;
                }
                // The net's triangle pairs, once per pair of bodies (i < j).
                let start = next_pairs.len() as u32;
                if i < j {
                    let (left, right) = bvhs.split_at_mut(j);
                    complete &= left[i].overlapping_pairs(&right[0], next_pairs);
                }
                // (Both lists have the same room.)
                next_gaps.resize(next_pairs.len(), f64::NAN);
                self.pair_ranges[pair] = (start, next_pairs.len() as u32);
                self.least_gaps[pair] = (f64::NAN, 0);
                // Bodies with no reference are listed again next tick.
                self.listed[pair] = if !complete {
                    LISTED_IN_PART
                } else if self.reference[i].is_some() && self.reference[j].is_some() {
                    LISTED
                } else {
                    LISTED_FOR_NOW
                };
                if !complete {
                    counters.overflows += 1;
                }
            }
        }
        self.current = 1 - self.current;
    }
}

/// Whether bodies `i` and `j` are a pair to list: two bodies, not of one group (pieces of one
/// transected body), whose bounds meet.
fn pair_to_list(group: &[usize], bounds: &[Aabb], i: usize, j: usize) -> bool {
    i != j && group.get(i).is_none_or(|g| group.get(j) != Some(g)) && bounds[i].overlaps(&bounds[j])
}

/// Who asks [`CandidateCache::list`] to bring the lists up to date.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ListCall {
    /// The response, first of the tick.
    Response,
    /// The collision net's first round.
    Net,
    /// The collision net between two rounds, after impulses moved ends.
    NetAgain,
}

/// Each body's triangles' boxes over this tick (or net round), taken when first asked for and kept
/// until [`TriangleBoxes::begin`]: the boxes a refit with no margin gives (the minima and maxima of
/// the corners' start and end positions), for the triangles the kept candidates name.
#[derive(Clone, Debug)]
struct TriangleBoxes {
    boxes: Vec<Room<Aabb>>,
    /// Per body and triangle, the stamp its box was taken at (0: never).
    stamps: Vec<Room<u32>>,
    stamp: u32,
}

impl TriangleBoxes {
    fn new(bodies: &[Body], slots: usize, spare_triangles: usize) -> Self {
        let room = |k: usize| {
            bodies
                .get(k)
                .map_or(spare_triangles, |b| b.mesh_capacity().1)
        };
        Self {
            boxes: (0..slots).map(|k| Room::with_capacity(room(k))).collect(),
            stamps: (0..slots).map(|k| Room::with_capacity(room(k))).collect(),
            stamp: 0,
        }
    }

    /// Forgets every box (the trajectories changed), and makes room for the bodies' triangles.
    fn begin(&mut self, bodies: &[Body]) {
        self.stamp = self.stamp.wrapping_add(1);
        for (k, body) in bodies.iter().enumerate().take(self.stamps.len()) {
            let count = body.surface.triangles.len();
            let (boxes, stamps) = (&mut self.boxes[k], &mut self.stamps[k]);
            if self.stamp == 0 || stamps.len() != count {
                stamps.clear();
                boxes.clear();
                if count <= stamps.capacity() && count <= boxes.capacity() {
                    stamps.resize(count, 0);
                    boxes.resize(count, Aabb::empty());
                }
            }
        }
        if self.stamp == 0 {
            self.stamp = 1;
        }
    }

    /// Triangle `t` of body `k` swept over the tick.
    #[inline]
    fn of(&mut self, k: usize, t: usize, body: &Body) -> Aabb {
        let s = &body.surface;
        let compute = || {
            let mut aabb = Aabb::empty();
            for &v in &s.triangles[t] {
                let v = v as usize;
                aabb.merge(&Aabb::of_pair(
                    &s.position_in_world[v],
                    &s.next_position_in_world[v],
                ));
            }
            aabb
        };
        match self.stamps.get_mut(k).and_then(|stamps| stamps.get_mut(t)) {
            Some(stamp) if *stamp == self.stamp => self.boxes[k][t],
            Some(stamp) => {
                *stamp = self.stamp;
                let aabb = compute();
                self.boxes[k][t] = aabb;
                aabb
            }
            None => compute(),
        }
    }
}

/// Writes the boxes of `body`'s nodes' trajectories this tick into `lower` and `upper`, and returns
/// the topology version and node count they hold for (`None`, and nothing written, when there is no
/// room for them).
fn boxes_of_trajectories(
    body: &Body,
    (lower, upper): (&mut Room<Vec3>, &mut Room<Vec3>),
) -> Option<(u64, usize)> {
    let s = &body.surface;
    let n = s.position_in_world.len();
    lower.clear();
    upper.clear();
    if n > lower.capacity() || n > upper.capacity() {
        return None;
    }
    for (p, q) in s.position_in_world.iter().zip(&s.next_position_in_world) {
        lower.push(p.inf(q));
        upper.push(p.sup(q));
    }
    Some((body.topology_version, n))
}

/// A body's boxes: the corners of its reference (`lower`, `upper`) when it has one, otherwise this
/// tick's trajectories.
fn reference_boxes<'a>(
    reference: Option<(u64, usize)>,
    lower: &'a [Vec3],
    upper: &'a [Vec3],
    body: &'a Body,
) -> (&'a [Vec3], &'a [Vec3]) {
    match reference {
        Some(_) => (lower, upper),
        None => (
            &body.surface.position_in_world,
            &body.surface.next_position_in_world,
        ),
    }
}

/// Body j's triangles and the corners of its nodes' reference boxes, with the margin its
/// hierarchy's boxes are grown by, as [`list_pair`] takes them.
struct OtherReference<'a> {
    triangles: &'a [[u32; 3]],
    lower: &'a [Vec3],
    upper: &'a [Vec3],
    margin: f64,
}

/// Lists body i's vertices against body j's triangles (and, when j > i, its edges against the
/// sides of j's triangles, each side once, through the triangle that owns it, where the side's own
/// box meets the edge's), from the boxes the two hierarchies are fitted to and body i's boxes
/// `lower`–`upper`, grown by `reach`, into `out`; the ranges written into `ranges`. False when a
/// list was full (incomplete).
fn list_pair(
    (i, j, body): (usize, usize, &Body),
    ((lower, upper), reference_j): ((&[Vec3], &[Vec3]), OtherReference),
    bvhs: &mut [TriangleBvh],
    reach: f64,
    (near_triangles, found): (&mut Vec<u32>, &mut Vec<u32>),
    out: &mut Vec<Candidate>,
    ranges: &mut [(u32, u32); 2],
) -> bool {
    let mut complete = true;
    let Some(other) = bvhs[j].bounds() else {
        *ranges = [(out.len() as u32, out.len() as u32); 2];
        return true;
    };
    let mut grown = other;
    grown.inflate(reach);
    near_triangles.clear();
    complete &= bvhs[i].query(&grown, near_triangles);
    let triangles = &body.surface.triangles;
    let box_of = |nodes: &[usize]| {
        let mut aabb = Aabb::empty();
        for &v in nodes {
            aabb.include(&lower[v]);
            aabb.include(&upper[v]);
        }
        aabb.inflate(reach);
        aabb
    };
    let push = |out: &mut Vec<Candidate>, c: Candidate| {
        if out.len() == out.capacity() {
            false
        } else {
            out.push(c);
            true
        }
    };
    for part in 0..2 {
        let start = out.len() as u32;
        if part == 1 && j < i {
            ranges[1] = (start, start);
            continue;
        }
        for &t in near_triangles.iter() {
            let owned = bvhs[i].owned(t as usize);
            let corners = triangles[t as usize];
            for c in 0..3 {
                let (feature, nodes) = if part == 0 {
                    if owned & owns_vertex(c) == 0 {
                        continue;
                    }
                    let v = corners[c];
                    ([v, v], [v as usize, v as usize])
                } else {
                    if owned & owns_side(c) == 0 {
                        continue;
                    }
                    let (a, b) = (corners[c], corners[(c + 1) % 3]);
                    let (a, b) = (a.min(b), a.max(b));
                    ([a, b], [a as usize, b as usize])
                };
                let aabb = box_of(&nodes);
                if !aabb.overlaps(&other) {
                    continue;
                }
                found.clear();
                complete &= bvhs[j].query(&aabb, found);
                for &triangle in found.iter() {
                    if part == 0 {
                        complete &= push(
                            out,
                            Candidate {
                                feature,
                                other: [triangle, 0],
                            },
                        );
                        continue;
                    }
                    // An edge against the sides the triangle owns (each side of body j once) whose
                    // own boxes meet its: a side's box, from its two nodes' reference boxes grown
                    // by the margin the hierarchy's are, lies within its triangle's.
                    let owned = bvhs[j].owned(triangle as usize);
                    let corners_j = reference_j.triangles[triangle as usize];
                    for side in 0..3 {
                        let (na, nb) =
                            (corners_j[side] as usize, corners_j[(side + 1) % 3] as usize);
                        let mut side_box = Aabb::empty();
                        for v in [na, nb] {
                            side_box.include(&reference_j.lower[v]);
                            side_box.include(&reference_j.upper[v]);
                        }
                        side_box.inflate(reference_j.margin);
                        if owned & owns_side(side) != 0 && side_box.overlaps(&aabb) {
                            complete &= push(
                                out,
                                Candidate {
                                    feature,
                                    other: [na.min(nb) as u32, na.max(nb) as u32],
                                },
                            );
                        }
                    }
                }
            }
        }
        ranges[part] = (start, out.len() as u32);
    }
    complete
}

/// Each body's bounds swept over the tick (start and end positions), whether they meet those of
/// another body not of its group, and its nodes' largest displacement over the tick. Returns
/// whether any pair meets. One pass over the nodes: bodies apart cost this and nothing more.
fn bodies_near(
    bodies: &[Body],
    group: &[usize],
    (bounds, near, max_motion): (&mut Vec<Aabb>, &mut Vec<bool>, &mut Vec<f64>),
) -> bool {
    bounds.clear();
    near.clear();
    max_motion.clear();
    for b in bodies {
        let (aabb, largest) = sweep(
            &b.surface.position_in_world,
            &b.surface.next_position_in_world,
        );
        bounds.push(aabb);
        near.push(false);
        max_motion.push(largest);
    }
    mark_near(group, bounds, near)
}

/// Marks in `near` the bodies whose `bounds` meet those of another body not of their group;
/// returns whether any pair meets.
fn mark_near(group: &[usize], bounds: &[Aabb], near: &mut [bool]) -> bool {
    let mut any = false;
    for i in 0..bounds.len() {
        for j in i + 1..bounds.len() {
            if group.get(i).is_some_and(|g| group.get(j) == Some(g))
                || !bounds[i].overlaps(&bounds[j])
            {
                continue;
            }
            near[i] = true;
            near[j] = true;
            any = true;
        }
    }
    any
}

/// The box of `nodes` of `body` over the tick (start and end positions).
/// Whether every point of `start` and `end` lies within `slack` of its node's box from `lower` to
/// `upper` (plain comparisons, no early exit; a coordinate that is not a number is outside): four
/// nodes at a time with AVX when `simd` (the machine must have it), the rest one at a time.
fn within_slack(
    [start, end]: [&[Vec3]; 2],
    [lower, upper]: [&[Vec3]; 2],
    slack: f64,
    simd: bool,
) -> bool {
    let n = start.len();
    if end.len() != n || lower.len() != n || upper.len() != n {
        return false;
    }
    let mut done = 0;
    let mut inside = true;
    #[cfg(not(target_arch = "x86_64"))]
    let _ = simd;
    #[cfg(target_arch = "x86_64")]
    if simd {
        done = n - n % 4;
        // SAFETY: the machine has AVX; the four slices hold n ≥ done points each.
        inside = unsafe {
            wide::within(
                [&start[..done], &end[..done]],
                [&lower[..done], &upper[..done]],
                slack,
            )
        };
    }
    let slack = Vec3::repeat(slack);
    for (((p, q), lo), hi) in start[done..]
        .iter()
        .zip(&end[done..])
        .zip(&lower[done..])
        .zip(&upper[done..])
    {
        let (lo, hi) = (lo - slack, hi + slack);
        // Plain comparisons, no early exit (NaN: outside).
        for d in 0..3 {
            inside &= (p[d] >= lo[d]) & (p[d] <= hi[d]) & (q[d] >= lo[d]) & (q[d] <= hi[d]);
        }
    }
    inside
}

/// How far the points of `start` and `end` lie outside their node's box from `lower` to `upper` at
/// most, along any axis (0 when every point is inside; infinite where a difference is not a
/// number, or the slices differ in length): four nodes at a time with AVX when `simd` (the machine
/// must have it), the rest one at a time, the same answer.
fn excursion([start, end]: [&[Vec3]; 2], [lower, upper]: [&[Vec3]; 2], simd: bool) -> f64 {
    let n = start.len();
    if end.len() != n || lower.len() != n || upper.len() != n {
        return f64::INFINITY;
    }
    let mut done = 0;
    let mut most = 0.0f64;
    #[cfg(not(target_arch = "x86_64"))]
    let _ = simd;
    #[cfg(target_arch = "x86_64")]
    if simd {
        done = n - n % 4;
        // SAFETY: the machine has AVX; the four slices hold n ≥ done points each.
        most = unsafe {
            wide::excursion(
                [&start[..done], &end[..done]],
                [&lower[..done], &upper[..done]],
            )
        };
    }
    let mut unordered = false;
    for (((p, q), lo), hi) in start[done..]
        .iter()
        .zip(&end[done..])
        .zip(&lower[done..])
        .zip(&upper[done..])
    {
        for d in 0..3 {
            for x in [lo[d] - p[d], p[d] - hi[d], lo[d] - q[d], q[d] - hi[d]] {
                unordered |= x.is_nan();
                most = most.max(x);
            }
        }
    }
    if unordered { f64::INFINITY } else { most }
}

/// The box of the points of `start` and `end` (a body's nodes over the tick) and a bound above
/// every node's displacement (m): the length of the vector of the largest displacement along each
/// axis — at least each node's own length, computed the same way, and only the collision net's
/// first filter reads it (a looser bound lets more pairs on to its exact second filter).
fn sweep(start: &[Vec3], end: &[Vec3]) -> (Aabb, f64) {
    sweep_on(start, end, crate::dynamics::kernel::simd_available())
}

/// [`sweep`], four nodes at a time with AVX when `simd` (the machine must have it), else one at a
/// time: the same answer.
fn sweep_on(start: &[Vec3], end: &[Vec3], simd: bool) -> (Aabb, f64) {
    let n = start.len().min(end.len());
    let mut aabb = Aabb::empty();
    let mut largest = Vec3::zeros();
    let mut done = 0;
    #[cfg(not(target_arch = "x86_64"))]
    let _ = simd;
    #[cfg(target_arch = "x86_64")]
    if simd {
        // SAFETY: the machine has AVX; both slices hold n ≥ the points given.
        if let Some((lower, upper, most)) =
            unsafe { wide::sweep(&start[..n - n % 4], &end[..n - n % 4]) }
        {
            done = n - n % 4;
            aabb.min = Vec3::from(lower);
            aabb.max = Vec3::from(upper);
            largest = Vec3::from(most);
        }
    }
    for (p, q) in start[done..n].iter().zip(&end[done..n]) {
        aabb.min = aabb.min.inf(&p.inf(q));
        aabb.max = aabb.max.sup(&p.sup(q));
        largest = largest.sup(&(q - p).abs());
    }
    (aabb, largest.norm())
}

fn swept_box(body: &Body, nodes: &[usize]) -> Aabb {
    let s = &body.surface;
    let mut aabb = Aabb::empty();
    for &v in nodes {
        aabb.include(&s.position_in_world[v]);
        aabb.include(&s.next_position_in_world[v]);
    }
    aabb
}

/// Sweeps over `contacts` in order with accumulated impulses (normal ≥ 0, tangential within the
/// Coulomb cone): a contact may close its gap down to the rest distance over a step and no more,
/// and does not slip where friction holds. On the solver's node lists (no division but the cone's).
fn solve(nodes_of: &mut SolverNodes, lists: (&mut [Contact], &mut [ContactNodes]), dt: f64) {
    #[cfg(target_arch = "x86_64")]
    if crate::dynamics::kernel::simd_available() {
        // SAFETY: the machine has AVX (checked just above).
        unsafe { solve_with_avx(nodes_of, lists, dt) };
        return;
    }
    solve_sweeps(nodes_of, lists, dt);
}

/// [`solve_sweeps`] compiled with AVX (three-component vectors in one register where the compiler
/// finds them; no fused multiply–add, so the same operations and bits as without): about 1.3 µs
/// less in a stack of two 162-node organs (81 contacts), 38.4 → 37.0 µs for the body-contact
/// stage, best of six interleaved runs. The machine must have AVX.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn solve_with_avx(
    nodes_of: &mut SolverNodes,
    lists: (&mut [Contact], &mut [ContactNodes]),
    dt: f64,
) {
    solve_sweeps(nodes_of, lists, dt);
}

#[inline(always)]
fn solve_sweeps(
    nodes_of: &mut SolverNodes,
    (contacts, contact_nodes): (&mut [Contact], &mut [ContactNodes]),
    dt: f64,
) {
    // Updates are numbered; a contact whose last update changed nothing, and none of whose nodes
    // changed since, would change nothing again (the same inputs, to the bit): it is passed over.
    let mut update = 0u32;
    for _ in 0..SOLVER_ITERATIONS {
        for (c, nodes) in contacts.iter_mut().zip(contact_nodes.iter_mut()) {
            if c.compliance <= 0.0 {
                continue;
            }
            if nodes.idle
                && nodes.slots[..nodes.count]
                    .iter()
                    .all(|&k| nodes_of.nodes[k as usize].changed < nodes.looked)
            {
                continue;
            }
            update += 1;
            nodes.looked = update;
            let relative = nodes.relative(&nodes_of.nodes, |n| n.motion);
            // Normal: close the gap down to the rest distance, no more (closer than that: stop
            // closing; the positions are parted afterwards).
            let normal_speed = relative.dot(&c.normal);
            let accumulated = (c.normal_impulse
                + (nodes.target_speed - normal_speed) * nodes.effective_mass)
                .max(0.0)
                .min(c.cap);
            let normal_change = accumulated - c.normal_impulse;
            c.normal_impulse = accumulated;
            // Friction: stop the tangential slip, within the Coulomb cone of the normal impulse.
            // The compliance is the same along every direction, so the normal impulse's change
            // leaves the slip as it was: the slip and the impulse that stops it are taken from the
            // relative motion alone, side by side with the normal impulse.
            let slip = relative - c.normal * normal_speed;
            let mut tangent = c.tangent_impulse - slip * nodes.effective_mass;
            within_cone(&mut tangent, c.friction * c.normal_impulse);
            let tangent_change = tangent - c.tangent_impulse;
            c.tangent_impulse = tangent;
            nodes.idle = normal_change == 0.0 && tangent_change == Vec3::zeros();
            let impulse = c.normal * normal_change + tangent_change;
            if impulse == Vec3::zeros() {
                continue;
            }
            apply_impulse(nodes_of, nodes, &impulse, (update, dt));
        }
        // The obstacles under the nodes take what would push them in.
        let SolverNodes {
            nodes: listed,
            ground,
            ..
        } = nodes_of;
        for row in ground.iter_mut() {
            let n = &mut listed[row.slot as usize];
            let deficit = row.floor - row.normal.dot(&n.end);
            let accumulated = (row.impulse + deficit / (n.inverse_mass * dt)).max(0.0);
            let change = accumulated - row.impulse;
            if change == 0.0 {
                continue;
            }
            row.impulse = accumulated;
            update += 1;
            let dv = row.normal * (change * n.inverse_mass);
            n.changed = update;
            n.end += dv * dt;
            n.motion += dv;
            n.velocity += dv;
        }
    }
}

/// Applies `impulse` to a contact's side a and, opposite, to side b, with their weights: the end
/// velocities change, and the end positions with them; the work it does on each side is added to
/// the contact's. A node a tool moves takes no share (its motion is the tool's): the contact's
/// force on it goes on to the tool.
#[inline(always)]
fn apply_impulse(
    nodes_of: &mut SolverNodes,
    nodes: &mut ContactNodes,
    impulse: &Vec3,
    (update, dt): (u32, f64),
) {
    for i in 0..nodes.count {
        let (w, inverse_mass) = (nodes.weights[i], nodes.inverse_masses[i]);
        let slot = nodes.slots[i] as usize;
        // Side a's nodes come first, with positive weights.
        let n = &mut nodes_of.nodes[slot];
        nodes.work[usize::from(w < 0.0)] += (impulse * w).dot(&n.velocity).abs();
        if inverse_mass == 0.0 {
            continue;
        }
        let dv = impulse * (w * inverse_mass);
        n.changed = update;
        n.end += dv * dt;
        n.motion += dv;
        n.velocity += dv;
    }
}

/// Keeps in `best` the nearer of it and `c` (ties by the other side's nodes): one contact per
/// vertex (or edge) and other body.
fn keep_nearer(best: &mut Option<Contact>, c: Contact) {
    let nearer = best.as_ref().is_none_or(|b| {
        c.distance
            .total_cmp(&b.distance)
            .then(c.b.cmp(&b.b))
            .is_lt()
    });
    if nearer {
        *best = Some(c);
    }
}

/// Triangle `t` of body `j` (surface `s`) as node references.
#[inline]
fn face_of(s: &crate::body::Surface, j: usize, t: usize) -> [NodeRef; 3] {
    s.triangles[t].map(|w| NodeRef {
        body: j,
        node: w as usize,
    })
}

/// The pair with its smaller node first.
fn sorted(e: [NodeRef; 2]) -> [NodeRef; 2] {
    if e[1] < e[0] { [e[1], e[0]] } else { e }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A body thrown through another within one tick: the stage stops the crossing nodes and says
    /// it moved those two bodies and not a third far away (the world drops the node blocks of the
    /// bodies it moved). It fails with the response's marks left out; the net's marks (the same
    /// rule where it stops nodes) are not reached here, as the response answers the crossing.
    #[test]
    fn the_stage_marks_the_bodies_whose_nodes_it_moved_and_only_them() {
        use crate::body::{BodyParams, Placement};
        use crate::scene::mesh::icosphere;
        let mut bodies: Vec<Body> = [-0.05, 0.05, 1.0]
            .iter()
            .map(|&x| {
                let place = Placement {
                    position_in_world: Vec3::new(x, 0.0, 0.0),
                    ..Placement::default()
                };
                Body::new("b", &icosphere(0.03, 1), &BodyParams::default(), &place)
            })
            .collect();
        let dt = 1e-3;
        for (k, body) in bodies.iter_mut().enumerate() {
            let s = &mut body.surface;
            let motion = if k == 0 {
                Vec3::new(0.1, 0.0, 0.0)
            } else {
                Vec3::zeros()
            };
            for i in 0..s.position_in_world.len() {
                s.next_position_in_world[i] = s.position_in_world[i] + motion;
                s.velocity_in_world[i] = motion / dt;
            }
        }
        let group = [0, 1, 2];
        let mut scratch = BodyContactScratch::new(&bodies, 0, 0);
        let response = respond_to_body_contacts(
            &mut bodies,
            &group,
            (&[], &mut []),
            &mut scratch,
            |_, _| false,
            dt,
        );
        assert!(response.contacts > 0, "{response:?}");
        assert!(scratch.moved(0) && scratch.moved(1) && !scratch.moved(2));
        resolve_body_collisions(&mut bodies, &group, &[], &mut scratch, dt);
        assert!(scratch.moved(0) && scratch.moved(1) && !scratch.moved(2));
        // No node of the far body moved.
        let s = &bodies[2].surface;
        assert!((0..s.mass.len()).all(|i| s.next_position_in_world[i] == s.position_in_world[i]));
    }

    /// Points spread over a few centimetres from a seed (a linear congruential sequence).
    fn points(seed: u64, n: usize) -> Vec<Vec3> {
        let mut state = seed;
        let mut next = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 0.04 - 0.02
        };
        (0..n).map(|_| Vec3::new(next(), next(), next())).collect()
    }

    #[test]
    fn triangles_cross_where_a_side_passes_through_the_other_and_not_where_they_touch() {
        let v = Vec3::new;
        let flat = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)];
        // Upright through the middle of the flat one: its sides pass through it.
        let through = [v(0.2, 0.2, -0.5), v(0.3, 0.2, 0.5), v(0.2, 0.3, 0.5)];
        assert!(triangles_cross(&flat, &through));
        assert!(triangles_cross(&through, &flat));
        // Through it the other way: a side of the flat one pierces the upright one.
        let across = [v(0.5, -0.5, -0.5), v(0.5, -0.5, 0.5), v(0.5, 2.0, 0.0)];
        assert!(triangles_cross(&flat, &across));
        // Resting on it (a corner on its plane), beside it, and above it: no crossing.
        let resting = [v(0.2, 0.2, 0.0), v(0.3, 0.2, 0.5), v(0.2, 0.3, 0.5)];
        let beside = [v(2.0, 2.0, -0.5), v(2.1, 2.0, 0.5), v(2.0, 2.1, 0.5)];
        let above = flat.map(|p| p + v(0.0, 0.0, 1e-6));
        for other in [resting, beside, above] {
            assert!(!triangles_cross(&flat, &other) && !triangles_cross(&other, &flat));
        }
    }

    #[test]
    fn triangles_parted_by_a_plane_have_every_primitive_pair_farther_apart() {
        // Random triangles a few centimetres across, and bounds from 0 to 2 cm: where the test
        // says apart, every vertex–face and edge–edge distance of the pair is beyond the bound.
        let (mut apart, mut boxes_within) = (0, 0);
        let extent = |t: &[Vec3; 3], k: usize| {
            let values = t.map(|v| v[k]);
            (
                values[0].min(values[1]).min(values[2]),
                values[0].max(values[1]).max(values[2]),
            )
        };
        for seed in 0..4000u64 {
            let p = points(seed, 6);
            let (a, b) = ([p[0], p[1], p[2]], [p[3], p[4], p[5]]);
            let most = 0.02 * (seed % 97) as f64 / 96.0;
            if !triangles_apart(&a, &b, most) {
                continue;
            }
            apart += 1;
            let mut least = f64::INFINITY;
            for (corners, face) in [(&a, &b), (&b, &a)] {
                for q in corners {
                    let nearest = closest_point_on_triangle(q, &face[0], &face[1], &face[2]);
                    least = least.min((nearest - q).norm());
                }
            }
            for i in 0..3 {
                for j in 0..3 {
                    let (a0, a1, b0, b1) = (&a[i], &a[(i + 1) % 3], &b[j], &b[(j + 1) % 3]);
                    least = least.min(segment_segment_distance(a0, a1, b0, b1));
                }
            }
            assert!(
                least > most,
                "seed {seed}: parted at {most} m but {least} m apart"
            );
            // Pairs whose boxes come within the bound: what boxes alone would not part.
            let gap = (0..3)
                .map(|k| {
                    let ((la, ha), (lb, hb)) = (extent(&a, k), extent(&b, k));
                    (lb - ha).max(la - hb)
                })
                .fold(f64::NEG_INFINITY, f64::max);
            boxes_within += usize::from(gap <= most);
        }
        assert!(
            apart > 400 && boxes_within > 100,
            "{apart} pairs parted, {boxes_within} of them with boxes within the bound"
        );
        // Crossing triangles are not parted; the same moved 10 m up are, below 10 m.
        let a = [Vec3::zeros(), Vec3::x(), Vec3::y()];
        let b = [
            Vec3::new(0.2, 0.2, -1.0),
            Vec3::new(0.2, 0.2, 1.0),
            Vec3::new(0.5, 0.1, 0.0),
        ];
        assert!(!triangles_apart(&a, &b, 0.0) && !triangles_apart(&b, &a, 0.0));
        let up = b.map(|v| v + Vec3::new(0.0, 0.0, 10.0));
        assert!(triangles_apart(&a, &up, 8.9) && !triangles_apart(&a, &up, 9.1));
        // A degenerate triangle's plane parts nothing; the other's may part it (a point 1 m up).
        let flat = [Vec3::new(0.0, 0.0, 1.0); 3];
        assert!(!triangles_apart(&flat, &flat, 0.0));
        assert!(triangles_apart(&a, &flat, 0.9) && !triangles_apart(&a, &flat, 1.1));
    }

    /// The edge from `a0` to `a1` (nodes 0 and 1 of body 0), as [`EdgeAtEnd::of`] takes it.
    #[cfg(target_arch = "x86_64")]
    fn edge_from(a0: Vec3, a1: Vec3) -> EdgeAtEnd {
        EdgeAtEnd {
            refs: [0, 1].map(|node| NodeRef { body: 0, node }),
            a0,
            a1,
            d1: a1 - a0,
            length2: (a1 - a0).norm_squared(),
            low: a0.inf(&a1),
            high: a0.sup(&a1),
        }
    }

    #[test]
    fn four_sides_at_a_time_answer_the_first_checks_and_nearest_points_as_one_at_a_time() {
        #[cfg(target_arch = "x86_64")]
        {
            if !crate::dynamics::kernel::simd_available() {
                eprintln!("no AVX on this machine: the scalar code alone runs");
                return;
            }
            // Edges and sides within a few millimetres of each other (the skin is 1 mm), some
            // degenerate, some parallel, one coordinate not a number now and then.
            let (mut within, mut through, mut unordered) = (0, 0, 0);
            for seed in 0..3000u64 {
                let mut p = points(seed, 10);
                for q in p.iter_mut() {
                    *q *= 0.15;
                }
                match seed % 7 {
                    0 => p[1] = p[0],
                    1 => p[3] = p[2] + (p[1] - p[0]) * 0.5,
                    2 => p[5].y = f64::NAN,
                    _ => {}
                }
                let edge = edge_from(p[0], p[1]);
                if edge.length2.is_nan() || edge.length2 <= f64::MIN_POSITIVE {
                    continue;
                }
                let positions = &p[2..];
                let b0 = [0, 2, 4, 6];
                let b1 = [1, 3, 5, 7];
                // SAFETY: AVX checked above; indices below 8.
                let answer = unsafe { wide::edge_sides(&edge, positions, b0, b1) };
                let masks = [answer.within, answer.through, answer.unordered];
                for l in 0..4 {
                    let (e0, e1) = (positions[b0[l] as usize], positions[b1[l] as usize]);
                    let bit = 1 << l;
                    if masks[2] & bit != 0 {
                        assert!(
                            e0.iter().chain(e1.iter()).any(|x| x.is_nan()),
                            "seed {seed}"
                        );
                        unordered += 1;
                        continue;
                    }
                    let near = !edge.apart(&e0, &e1);
                    let nearest = nearest_within_skin(&edge, &e0, &e1).filter(|_| near);
                    let inside = nearest.is_some();
                    assert_eq!(masks[0] & bit != 0, near, "seed {seed}, lane {l}");
                    assert_eq!(masks[1] & bit != 0, inside, "seed {seed}, lane {l}");
                    // Where the side goes through, the lane's nearest points are the scalar
                    // code's, to the bit (the contact is built from them).
                    if let Some((s, t, _, _, distance)) = nearest {
                        let bits = |x: [f64; 3]| x.map(f64::to_bits);
                        assert_eq!(
                            bits([answer.s[l], answer.t[l], answer.distance[l]]),
                            bits([s, t, distance]),
                            "seed {seed}, lane {l}"
                        );
                    }
                    within += usize::from(near);
                    through += usize::from(inside);
                }
            }
            assert!(
                within > 4000 && through > 1000 && unordered > 300,
                "{within} within, {through} through, {unordered} not a number"
            );
        }
    }

    /// The sides' nearest points at parameters next to the ends' margins (`EDGE_INNER` and
    /// 1 − `EDGE_INNER`, and the half margins the four-side kernel turns sides down by before its
    /// second division): the kernel answers as the scalar code, lane by lane, on either side of
    /// each margin.
    #[test]
    fn four_sides_at_a_time_answer_as_one_at_a_time_next_to_the_ends_margins() {
        #[cfg(target_arch = "x86_64")]
        {
            if !crate::dynamics::kernel::simd_available() {
                eprintln!("no AVX on this machine: the scalar code alone runs");
                return;
            }
            // The edge along x at height 0.5 mm, crossing the y axis at its middle; each side
            // along y, through the origin at parameter t.
            let edge = edge_from(Vec3::new(-1e-3, 0.0, 5e-4), Vec3::new(1e-3, 0.0, 5e-4));
            let mut parameters = Vec::new();
            for margin in [EDGE_INNER, 0.5 * EDGE_INNER] {
                for relative in [-1e-3, -1e-9, 0.0, 1e-9, 1e-3] {
                    let t = margin * (1.0 + relative);
                    parameters.extend([t, 1.0 - t]);
                }
            }
            let (mut through, mut turned_down) = (0, 0);
            // Four sides of one parameter at a time (sides of several lengths): a batch the
            // kernel may turn down whole before its second division.
            for &t in &parameters {
                let mut positions = Vec::new();
                for l in 0..4 {
                    let length = 2e-3 * (1.0 + l as f64 * 0.37);
                    positions.push(Vec3::new(0.0, -t * length, 0.0));
                    positions.push(Vec3::new(0.0, (1.0 - t) * length, 0.0));
                }
                // SAFETY: AVX checked above; indices below 8.
                let answer =
                    unsafe { wide::edge_sides(&edge, &positions, [0, 2, 4, 6], [1, 3, 5, 7]) };
                for l in 0..4 {
                    let (e0, e1) = (positions[2 * l], positions[2 * l + 1]);
                    let scalar = nearest_within_skin(&edge, &e0, &e1);
                    assert_eq!(answer.within & (1 << l) != 0, !edge.apart(&e0, &e1));
                    assert_eq!(
                        answer.through & (1 << l) != 0,
                        scalar.is_some(),
                        "t = {t:e}, lane {l}"
                    );
                    if scalar.is_some() {
                        through += 1;
                    } else {
                        turned_down += 1;
                    }
                }
            }
            // Both answers on either side of the margins.
            assert!(
                through >= 16 && turned_down >= 32,
                "{through} through, {turned_down} not"
            );
        }
    }

    #[test]
    fn the_cone_check_without_a_square_root_gives_the_bits_of_the_plain_one() {
        // The plain check: the length and the factor taken every time.
        let plain = |t: Vec3, limit: f64| t * (limit / t.norm()).min(1.0);
        let same = |a: &Vec3, b: &Vec3| {
            a.iter()
                .zip(b.iter())
                .all(|(x, y)| x.to_bits() == y.to_bits())
        };
        let directions = points(7, 64);
        let mut checked = 0;
        for (k, d) in directions.iter().enumerate() {
            let d = *d;
            if d.norm() == 0.0 {
                continue;
            }
            // Lengths at the limit, next to it on both sides by a few ulps and by the room of the
            // check, well inside and well outside, and the limits of the numbers.
            let limit = 1e-3 * (1.0 + k as f64);
            let unit = d / d.norm();
            let mut lengths = vec![0.0, 0.5 * limit, 2.0 * limit, limit];
            for f in [1.0 - 2e-6, 1.0 - 1e-6, 1.0 - 5e-7, 1.0 + 1e-6] {
                lengths.push(limit * f);
            }
            let mut up = limit;
            let mut down = limit;
            for _ in 0..4 {
                up = up.next_up();
                down = down.next_down();
                lengths.push(up);
                lengths.push(down);
            }
            for length in lengths {
                let t = unit * length;
                let mut fast = t;
                within_cone(&mut fast, limit);
                assert!(same(&fast, &plain(t, limit)), "{t:?} against {limit}");
                checked += 1;
            }
        }
        for (t, limit) in [
            (Vec3::new(1e-200, 0.0, 0.0), 1e-200),
            (Vec3::new(1e-160, 1e-160, 0.0), 1e-160),
            (Vec3::new(3.0, 4.0, 0.0), 0.0),
            (Vec3::new(f64::NAN, 0.0, 0.0), 1.0),
            (Vec3::new(1.0, 0.0, 0.0), f64::INFINITY),
            (Vec3::new(1e300, 1e300, 0.0), 1e300),
        ] {
            let mut fast = t;
            within_cone(&mut fast, limit);
            let expected = plain(t, limit);
            assert!(
                same(&fast, &expected)
                    || (fast.iter().any(|x| x.is_nan()) && expected.iter().any(|x| x.is_nan())),
                "{t:?} against {limit}"
            );
            checked += 1;
        }
        assert!(checked > 1000);
    }

    #[test]
    fn four_faces_at_a_time_give_the_distances_of_one_at_a_time() {
        #[cfg(target_arch = "x86_64")]
        {
            if !crate::dynamics::kernel::simd_available() {
                eprintln!("no AVX on this machine: the scalar code alone runs");
                return;
            }
            // A vertex and four triangles within a few centimetres (every region of the closest
            // point), some degenerate, a corner not a number now and then, and the vertex just
            // above, on or below the last face half the time (within the skin, on either side).
            let (mut kept, mut turned_down, mut scalar) = (0, 0, 0);
            let mut at_corner = 0;
            for seed in 0..4000u64 {
                let mut p = points(seed, 13);
                match seed % 8 {
                    0 => p[1] = p[0],
                    1 => p[5] = p[3] + (p[4] - p[3]) * 0.5,
                    2 => p[7].z = f64::NAN,
                    3 => p[12] = p[9],
                    _ => {}
                }
                if seed % 2 == 1 {
                    let normal = (p[10] - p[9]).cross(&(p[11] - p[9])).normalize();
                    let offset = (seed % 7) as f64 * 3e-4 - 9e-4;
                    p[12] = p[9] + (p[10] - p[9]) * 0.3 + (p[11] - p[9]) * 0.4 + normal * offset;
                }
                let corners = [[0, 3, 6, 9], [1, 4, 7, 10], [2, 5, 8, 11]];
                // SAFETY: AVX checked above; indices below 13.
                let (distances, kept_bits, scalar_bits) =
                    unsafe { wide::vertex_faces(&p[12], &p, corners) };
                for l in 0..4 {
                    let end = [0, 1, 2].map(|c| p[corners[c][l] as usize]);
                    let bit = 1 << l;
                    if scalar_bits & bit != 0 {
                        // Left to the scalar code: a coordinate not a number, or a triangle
                        // with no area.
                        let normal = (end[1] - end[0]).cross(&(end[2] - end[0]));
                        assert!(
                            end.iter()
                                .chain([&p[12]])
                                .any(|q| q.iter().any(|x| x.is_nan()))
                                || normal.norm() < 1e-12,
                            "seed {seed}, lane {l}"
                        );
                        scalar += 1;
                        continue;
                    }
                    assert!(
                        !end.iter().any(|q| q.iter().any(|x| x.is_nan())),
                        "seed {seed}, lane {l}: a corner not a number is the scalar code's"
                    );
                    let expected = face_distance(&p[12], &end);
                    assert_eq!(
                        kept_bits & bit != 0,
                        expected.is_some(),
                        "seed {seed}, lane {l}"
                    );
                    match expected {
                        Some(d) => {
                            assert_eq!(
                                distances[l].to_bits(),
                                d.to_bits(),
                                "seed {seed}, lane {l}"
                            );
                            kept += 1;
                            at_corner += usize::from(end.iter().any(|c| (p[12] - c).norm() == d));
                        }
                        None => turned_down += 1,
                    }
                }
            }
            assert!(
                kept > 6000 && turned_down > 3000 && scalar >= 500 && at_corner > 1000,
                "{kept} kept, {turned_down} turned down, {scalar} left to the scalar code, \
                 {at_corner} nearest a corner"
            );
        }
    }

    #[test]
    fn the_sweep_and_the_excursion_answer_four_nodes_at_a_time_as_one_at_a_time() {
        if !crate::dynamics::kernel::simd_available() {
            eprintln!("no AVX on this machine: only the scalar path runs");
            return;
        }
        let mut checked = [0usize; 2];
        for n in [0, 1, 3, 4, 5, 8, 13, 64, 161] {
            for seed in 0..8u64 {
                let start = points(seed, n);
                let mut end: Vec<Vec3> = start
                    .iter()
                    .zip(points(seed + 100, n))
                    .map(|(p, d)| p + d * 0.05)
                    .collect();
                if seed == 7 && n > 0 {
                    end[n / 2].y = f64::NAN;
                }
                let (wide, scalar) = (sweep_on(&start, &end, true), sweep_on(&start, &end, false));
                assert_eq!(wide.0.min.map(f64::to_bits), scalar.0.min.map(f64::to_bits));
                assert_eq!(wide.0.max.map(f64::to_bits), scalar.0.max.map(f64::to_bits));
                assert_eq!(wide.1.to_bits(), scalar.1.to_bits());
                // The bound is above every node's displacement (a node with a coordinate that is
                // not a number has none).
                for (p, q) in start.iter().zip(&end) {
                    let motion = (q - p).norm();
                    assert!(motion.is_nan() || motion <= wide.1, "{n} {seed}");
                }
                // Boxes around each node that hold it, or miss it by a little on one axis.
                for slack in [0.0, 2.5e-4] {
                    let lower: Vec<Vec3> = start.iter().zip(&end).map(|(p, q)| p.inf(q)).collect();
                    let mut upper: Vec<Vec3> =
                        start.iter().zip(&end).map(|(p, q)| p.sup(q)).collect();
                    for (k, u) in upper.iter_mut().enumerate() {
                        if (k as u64 + seed) % 37 == 5 {
                            u[k % 3] -= slack + 1e-6;
                        }
                    }
                    let ask = |simd| excursion([&start, &end], [&lower, &upper], simd);
                    assert_eq!(
                        ask(true).to_bits(),
                        ask(false).to_bits(),
                        "{n} {seed} {slack}"
                    );
                    let e = ask(false);
                    // The answer is the largest distance outside a box: every point is within it,
                    // and a point leaves its box by that much (none for a point that is not a
                    // number, infinite then).
                    let outside = |p: &Vec3, lo: &Vec3, hi: &Vec3| {
                        (0..3).fold(0.0f64, |m, d| m.max(lo[d] - p[d]).max(p[d] - hi[d]))
                    };
                    let most = start
                        .iter()
                        .zip(&end)
                        .zip(lower.iter().zip(&upper))
                        .map(|((p, q), (lo, hi))| outside(p, lo, hi).max(outside(q, lo, hi)))
                        .fold(0.0f64, f64::max);
                    if seed == 7 && n > 0 {
                        assert_eq!(e, f64::INFINITY);
                    } else {
                        assert_eq!(e.to_bits(), most.to_bits(), "{n} {seed} {slack}");
                    }
                    checked[(e <= slack) as usize] += 1;
                }
            }
        }
        // Both answers were met.
        assert!(checked[0] > 10 && checked[1] > 10, "{checked:?}");
    }
}
