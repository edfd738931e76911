//! Cutting (MODEL.md §6): a blade's swept segment splits the surface along its path, tick by tick.
//!
//! One cut step takes the quadrilateral the blade's cutting segment swept during the tick (start
//! segment a₀b₀, end segment a₁b₁, split into the triangles a₀b₀b₁ and a₀b₁a₁) and:
//!
//! 1. **Crossings.** Every surface edge that passes through the swept quad is crossed at a fraction t.
//!    The crossing *snaps* to an end of the edge when that node lies within the fidelity tolerance of
//!    the quad (max(`tolerance`, a quarter of the edge's rest length)); otherwise the edge is *split*
//!    there (a new node at the crossing point: the paper's mass rule, momentum kept, the spring cut
//!    in two springs in series). Snapped splits never fall within a quarter of an edge's end, which
//!    bounds the shapes. A blade whose segment does not start where its last step ended (it jumped)
//!    starts a new cut: its old tips are not joined.
//! 2. **Templates.** Each triangle with split edges is replaced by children that keep its orientation
//!    (one split: two children; two: a corner triangle and the better diagonal of the quad; three: four
//!    children). When the best choice would still leave a child sharper than the quality bound
//!    (min(`min_angle`, half the smallest angle of the original mesh)), the triangle's remaining edge
//!    is split at its middle as well, and the choice made again. Before that, a path split whose
//!    triangles would be too sharp *snaps* to the nearer end of its edge when that end lies within
//!    the fidelity tolerance of the local edge length (the longest side of the triangles on the
//!    edge) rather than of the edge's own length, and a split node whose
//!    triangles would be too sharp *slides* along its edge (within ¾ of the fidelity tolerance of the
//!    swept quad for a path node; anywhere in the edge's middle 60 % for a quality split): a path
//!    that cuts a corner off just beyond the snapping distance otherwise leaves a short edge with a
//!    needle on each side. After the templates, an inner edge of a created triangle still below the
//!    bound is *flipped* when that raises the smallest angle of its two triangles (never a path or
//!    boundary edge, never across a crease; the spring takes the new edge's rest length).
//! 3. **Path.** In each crossed triangle the cut joins its two path points (snapped corners, split
//!    nodes, and the tip the blade left last tick); that edge of the new mesh is *opened*.
//! 4. **Opening.** Around every node of an opened edge the triangles are grouped by the edges that stay
//!    whole; every group but the first gets a copy of the node (same position and velocity, its share
//!    of the mass and of the link in proportion to the group's rest area, the same homologue). An
//!    opened edge becomes two lips, each a spring of half the stiffness on its own side.
//!
//! Mass and momentum are conserved by construction; kinetic energy is unchanged (copies move with the
//! node). Everything works in fixed scratch sized when the cutter is built: a cut step allocates
//! nothing, and refuses (and counts) a step the body's reserved room cannot take.

use super::explicit::MassMover;
use super::refine::min_angle_deg;
use super::rest_index::RestIndex;
use super::transect::Transector;
use super::{find_edge, mass_fractions};
use crate::Vec3;
pub use crate::body::count_boundary_edges;
pub use crate::body::settings::CuttingSettings;
use crate::body::{Body, NewNode, TopologyChanges};
use crate::collision::tool::{Aabb, closest_point_on_triangle};

/// Counters of a body's cuts since the start.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CutCounters {
    /// Ticks on which a cut changed the mesh.
    pub steps: u64,
    /// Edges split at a crossing (or in the middle, for quality).
    pub splits: u64,
    /// Node copies made to open the surface.
    pub copies: u64,
    /// Edges opened into two lips.
    pub opened_edges: u64,
    /// Cut steps refused: the reserved room was used up or too many edges were crossed at once.
    pub refused: u64,
    /// Triangles the cuts created or rewrote (template children, flipped pairs).
    pub created_triangles: u64,
    /// Created triangles below the quality bound and below the smallest angle of the triangle they
    /// came from (counted, never hidden).
    pub quality_misses: u64,
    /// Created triangles below the quality bound that keep a corner angle of a triangle already
    /// below it (one adaptive subdivision made, say): no split of that triangle can do better.
    pub quality_inherited: u64,
    /// Splits made for quality taken back before the step applied them (the path crossing that
    /// called for one snapped since, and it only divided a corner).
    pub quality_splits_dropped: u64,
    /// Splits made for quality the path was led through (a path leaving a corner close along one
    /// of its sides goes along it to the split and on).
    pub quality_splits_on_path: u64,
    /// Transections of this body (it separated into bodies).
    pub transections: u64,
    /// Caps closing the openings of transections.
    pub caps: u64,
    /// Openings a transection left open (no room, or not a simple loop).
    pub caps_refused: u64,
    /// Cap triangles below the quality bound.
    pub cap_quality_misses: u64,
    /// Blade steps that looked only at the springs near the blade (the rest-frame index).
    pub local_steps: u64,
    /// Parts searches spared: the body was one part and every copy since was joined to its
    /// origin again by the search round the cut or along a boundary loop (or a separation of the
    /// body was refused).
    pub parts_searches_spared: u64,
    /// Parts searches made (a pass over the body's springs: after an opening whose copies could
    /// not all be shown joined to their origins, and when the body did separate).
    pub parts_searches: u64,
    /// Parts searches that found the body one part (a pass the search round the cut and the
    /// loop walk could not spare: a slit that closed a boundary loop of its own, say).
    pub parts_searches_one_part: u64,
    /// Copies joined to their origins along a boundary loop (the search round the cut gave up).
    pub rejoins_by_loop: u64,
    /// Steps whose copies could not all be shown joined to their origins (the parts search then
    /// passes over the body).
    pub rejoins_failed: u64,
    /// Blade steps that ended at the box of the nodes (the blade away from the body): no work.
    pub away_ticks: u64,
    /// Blade steps that passed over the body's nodes (the blade's box meets the nodes' box).
    pub passes: u64,
}

/// Most edges one cut step may cross (a bound on the tick's cost).
pub const MAX_CROSSINGS: usize = 256;
/// Most triangles around one node that can be opened.
const MAX_FAN: usize = 64;
/// Rounds of quality splits per step.
const QUALITY_ROUNDS: usize = 4;
/// Fractions tried for a split made for quality.
const QUALITY_FRACTIONS: [f64; 5] = [0.5, 0.4, 0.6, 0.33, 0.67];
/// Most triangles one step creates or rewrites (four children per affected triangle, flips).
const MAX_CREATED: usize = 20 * MAX_CROSSINGS;
/// Rounds of edge flips per step.
const FLIP_ROUNDS: usize = 4;
/// Least cosine between the rest normals of two triangles whose shared edge may be flipped: no flip
/// across a crease (it would cut the crease's corner off the shape).
const FLIP_FLATNESS: f64 = 0.9;
/// Steps (fractions of the edge) and their count each way when a split slides for quality, and the
/// range of fractions a split may take.
const SLIDE_STEP: f64 = 0.02;
const SLIDE_STEPS: usize = 12;
const SLIDE_RANGE: (f64, f64) = (0.2, 0.8);
/// Springs and nodes one tick's record of changes holds (more: the followers pass over the mesh).
const CHANGE_ROOM: usize = 4096;
/// Rounding allowed when a created triangle is held to its parent's smallest angle (degrees).
const FLOOR_ROUNDING_DEG: f64 = 1e-6;
/// Least fraction of an edge from its ends at which a crossing may split it.
const MIN_SPLIT_FRACTION: f64 = 0.05;
/// Least share of a node's mass (before normalising) a copy made to open the surface takes.
const MIN_COPY_SHARE: f64 = 0.1;
/// Most tips kept per blade.
const MAX_TIPS: usize = 8;
/// Most (node, triangle) entries of the fans round a step's path.
const FAN_ROOM: usize = 16 * MAX_CROSSINGS;
/// Most nodes the search joining a step's copies to their origins visits before it gives up (and
/// the parts search passes over the body).
const REJOIN_BUDGET: usize = 512;
/// Most boundary steps the walks along the loops through a step's copies take (more: the parts
/// search passes over the body).
const WALK_BUDGET: usize = 2048;

#[derive(Clone, Copy, Debug)]
enum Choice {
    Snap(u32),
    Split,
}

/// The next node along the boundary from `u`: the end `b` of the triangle side u→b that no triangle
/// traverses b→u (the triangles round `u` from the index); `None` when `u` is not on the boundary.
fn boundary_successor(index: &mut RestIndex, body: &Body, u: u32) -> Option<u32> {
    let mark = index.begin();
    let at = RestIndex::point(&body.surface.homologue_in_body[u as usize]);
    index.collect_triangles(body, &at, mark, |_, t| t.contains(&u));
    let triangles = &body.surface.triangles;
    let after = |t: &[u32; 3], v: u32| {
        let k = t.iter().position(|&x| x == v)?;
        Some(t[(k + 1) % 3])
    };
    let found = &index.found;
    found.iter().find_map(|&t| {
        let b = after(&triangles[t as usize], u)?;
        let twin = found
            .iter()
            .any(|&o| after(&triangles[o as usize], b) == Some(u));
        (!twin).then_some(b)
    })
}

/// How far back over the tick's motion a blade's swept quad reaches (see [`Cutter::cut`]).
const BACK_REACH: f64 = 0.25;

/// One crossed edge (or one split for quality).
#[derive(Clone, Copy, Debug)]
struct Crossing {
    a: u32,
    b: u32,
    edge: u32,
    t: f64,
    /// Where along the edge the blade's sweep crossed it (`t` before any slide; for a split made
    /// for quality, its fraction).
    crossed: f64,
    choice: Choice,
    /// The node the crossing becomes: the snapped end or the new node.
    node: u32,
    /// Whether the path passes here (false for a split made for quality only).
    on_path: bool,
}

/// A triangle the step replaces.
#[derive(Clone, Copy, Debug)]
struct Affected {
    triangle: u32,
    corners: [u32; 3],
    /// Crossing on edge (0,1), (1,2), (2,0).
    crossing: [Option<u16>; 3],
    /// The path edge inside this triangle, if any (nodes of the new mesh).
    path: Option<(u32, u32)>,
    /// For two splits: use the diagonal from the split on the first split edge to the far corner.
    diagonal_from_first: bool,
}

/// The tips a blade left in a body: path ends inside triangles, where the next step goes on.
#[derive(Clone, Debug, Default)]
pub struct Tips {
    nodes: [u32; MAX_TIPS],
    len: usize,
}

impl Tips {
    fn push(&mut self, node: u32) {
        if self.len < MAX_TIPS && !self.nodes[..self.len].contains(&node) {
            self.nodes[self.len] = node;
            self.len += 1;
        }
    }

    fn contains(&self, node: u32) -> bool {
        self.nodes[..self.len].contains(&node)
    }

    /// Forgets every tip (after a renumbering).
    pub fn clear(&mut self) {
        self.len = 0;
    }
}

/// What one cut step did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CutStep {
    /// Edges the swept quad crossed.
    pub crossings: u32,
    /// Edges split.
    pub splits: u32,
    /// Node copies made.
    pub copies: u32,
    /// Edges opened.
    pub opened: u32,
    /// Whether the mesh changed.
    pub changed: bool,
    /// Whether the step was refused (room or crossing bound).
    pub refused: bool,
    /// Nodes of the body within the swept region's box (counted only for a body with a resistance).
    pub nodes_near: u32,
}

/// What the world knows of a body's nodes at the cut stage (see [`Cutter::cut_within`]).
#[derive(Clone, Copy, Debug)]
pub struct NodeExtent {
    /// The box of the node positions (world frame): every node inside it.
    pub bounds: Aabb,
    /// A placement of the body frame (rotation and origin: a rest place `h` sits at
    /// `rotation · h + origin` in the world) and a distance within which every node lies of its rest
    /// place so placed (m); from the tick's homologues and the guard's pass.
    pub frame: Option<(nalgebra::Matrix3<f64>, Vec3, f64)>,
}

/// The cutting state of one body: settings, counters and fixed scratch.
#[derive(Clone, Debug)]
pub struct Cutter {
    /// Settings from the scene.
    pub settings: CuttingSettings,
    /// The springs and nodes the cuts and tears changed since the world began the record (at its
    /// cut stage): what the force kernel and the solver follow instead of passing over the mesh.
    pub changes: TopologyChanges,
    /// Smallest angle a created triangle may have (degrees).
    pub quality_bound_deg: f64,
    /// Counters since the start.
    pub counters: CutCounters,
    /// Smallest angle among the triangles the cuts created (degrees; 180 when none).
    pub smallest_created_angle_deg: f64,
    /// Smallest angle of a cap triangle (degrees; 180 when none).
    pub smallest_cap_angle_deg: f64,
    /// Tick at whose end the mesh last changed by a cut (0: never).
    pub changed_at: u64,
    /// Longest rest edge of the mesh (m): cuts only make shorter ones.
    longest: f64,
    /// Tips left by each tool.
    pub tips: Vec<Tips>,
    /// Whether each tool has pressed through (resistance reached) and cuts.
    pub through: Vec<bool>,
    /// Ticks each tool has been away from the body while through.
    pub away: Vec<u32>,
    /// Each tool's cutting segment at the end of its last step (world frame): a step that does not
    /// start where the last one ended is a jump, and the blade's tips are forgotten.
    last_end: Vec<Option<[Vec3; 2]>>,
    stamp: u32,
    /// Each node's side code against this step's blade box (`Aabb::outcode`): an edge whose two
    /// ends share a side cannot cross the blade's sweep.
    node_side: Vec<u8>,
    node_stamp: Vec<u32>,
    cut_stamp: Vec<u32>,
    /// Nodes near this step's crossings (their ends, the blade's tips): the triangles around them
    /// are the only ones a step looks at.
    near_stamp: Vec<u32>,
    candidates: Vec<u32>,
    copy_origin: Vec<u32>,
    crossings: Vec<Crossing>,
    split_rest: Vec<Vec3>,
    affected: Vec<Affected>,
    path_edges: crate::Room<(u32, u32)>,
    /// Where this step's own path edges start in `path_edges` (those before are pending ones).
    new_path_from: usize,
    /// Path edges not opened yet (a slit of one edge cannot open): kept for the next steps.
    pending: crate::Room<(u32, u32)>,
    fan: Vec<(u32, u32)>,
    /// Scratch of the transection (parts, caps), with marks on this step's path.
    pub transector: Transector,
    /// Set when a cut step opened edges: the world then looks for parts.
    pub check_parts: bool,
    copies: Vec<u32>,
    /// Triangles this step created (template children, and the triangles flips rewrote), each with
    /// the least angle it is held to: min(bound, smallest angle of the triangle it came from) — a
    /// child keeps its parent's corner angles.
    created: Vec<(u32, f64)>,
    /// Whether blades cut this body (`cutting` on; a cutter may serve tearing alone).
    pub blades: bool,
    /// Tearing, when on (it opens the surface with this cutter).
    pub tearer: Option<super::tear::Tearer>,
    /// Where the body's triangles and springs are in its rest frame (none for a body whose rest
    /// shape flows: plasticity): a step looks there instead of passing over the mesh.
    pub index: Option<RestIndex>,
    /// Nodes a step met (side codes), marked with the step's stamp.
    side_stamp: Vec<u32>,
    /// Nodes a walk along a boundary loop met, marked with the walk's stamp.
    loop_stamp: Vec<u32>,
    /// Scratch: the nodes of the path, each once.
    path_nodes: crate::Room<u32>,
    /// Scratch: the nodes whose stiffness and damping diagonals a step may have changed.
    touched: crate::Room<u32>,
    /// The body's node count when the step began.
    nodes_at_start: usize,
    /// The body is known to be one part (its springs join every node): a parts search found one,
    /// and every opening since joined each copy it made to its origin again.
    pub connected: bool,
    /// A transection of this body was refused (more parts than [`super::transect::MAX_PARTS`] or
    /// than spares left): the parts search is not made again.
    pub separation_refused: bool,
    /// Scratch of the search that joins a copy to its origin.
    queue: crate::Room<u32>,
    /// Mass moves that give the changed nodes the least mass their explicit scheme carries.
    pub mass_mover: MassMover,
}

/// Distance from `p` to the swept quad (two triangles).
fn quad_distance(p: &Vec3, quad: &[Vec3; 4]) -> f64 {
    let [a0, b0, b1, a1] = quad;
    let c1 = closest_point_on_triangle(p, a0, b0, b1);
    let c2 = closest_point_on_triangle(p, a0, b1, a1);
    (p - c1).norm().min((p - c2).norm())
}

/// Fraction along the segment p→q where it passes through triangle (a, b, c), if it does.
fn segment_triangle(p: &Vec3, q: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> Option<f64> {
    let d = q - p;
    let e1 = b - a;
    let e2 = c - a;
    let h = d.cross(&e2);
    let det = e1.dot(&h);
    let scale = e1.norm() * e2.norm() * d.norm();
    if det.abs() <= 1e-12 * scale || scale <= 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let s = p - a;
    let u = inv * s.dot(&h);
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qv = s.cross(&e1);
    let v = inv * d.dot(&qv);
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = inv * e2.dot(&qv);
    (0.0..=1.0).contains(&t).then_some(t)
}

/// Smallest angle of the original mesh of `body` (degrees), from the homologues.
pub fn smallest_angle_deg(body: &Body) -> f64 {
    let h = &body.surface.homologue_in_body;
    body.surface
        .triangles
        .iter()
        .map(|t| min_angle_deg(&t.map(|v| h[v as usize])))
        .fold(180.0, f64::min)
}

impl Cutter {
    /// The cutting state of `body` for `tools` tools, with scratch for its reserved room.
    pub fn new(body: &Body, settings: CuttingSettings, tools: usize) -> Self {
        let capacity = body.mesh_capacity().0.max(body.node_count());
        let bound = settings.min_angle_deg.min(0.5 * smallest_angle_deg(body));
        let mut cutter = Self {
            settings,
            changes: TopologyChanges::with_capacity(CHANGE_ROOM, CHANGE_ROOM),
            quality_bound_deg: bound,
            counters: CutCounters::default(),
            smallest_created_angle_deg: 180.0,
            smallest_cap_angle_deg: 180.0,
            changed_at: 0,
            longest: body.edges.rest_length.iter().fold(0.0f64, |m, &l| m.max(l))
                / (1.0 - settings.prestress),
            tips: vec![Tips::default(); tools],
            through: vec![false; tools],
            away: vec![0; tools],
            last_end: vec![None; tools],
            stamp: 0,
            node_side: vec![0; capacity],
            node_stamp: vec![0; capacity],
            cut_stamp: vec![0; capacity],
            near_stamp: vec![0; capacity],
            candidates: Vec::with_capacity(
                body.mesh_capacity().1.max(body.surface.triangles.len()),
            ),
            copy_origin: Vec::with_capacity(capacity),
            crossings: Vec::with_capacity(MAX_CROSSINGS),
            split_rest: Vec::with_capacity(MAX_CROSSINGS),
            affected: Vec::with_capacity(4 * MAX_CROSSINGS),
            path_edges: crate::Room::with_capacity(8 * MAX_CROSSINGS),
            new_path_from: 0,
            pending: crate::Room::with_capacity(4 * MAX_CROSSINGS),
            fan: Vec::with_capacity(FAN_ROOM),
            copies: Vec::with_capacity(4 * MAX_CROSSINGS),
            created: Vec::with_capacity(MAX_CREATED),
            transector: Transector::with_capacity(capacity, body.mesh_capacity().1),
            check_parts: false,
            blades: body.params.cutting.is_some(),
            tearer: body
                .params
                .tearing
                .map(|t| super::tear::Tearer::new(body, t)),
            index: body.params.plasticity.is_none().then(|| {
                let (_, triangles) = body.mesh_capacity();
                let edges = if body.limits.edges == usize::MAX {
                    body.edges.len() + 3 * (triangles - body.surface.triangles.len().min(triangles))
                } else {
                    body.limits.edges
                };
                RestIndex::with_capacity(triangles, edges)
            }),
            side_stamp: vec![0; capacity],
            loop_stamp: vec![0; capacity],
            path_nodes: crate::Room::with_capacity(16 * MAX_CROSSINGS),
            touched: crate::Room::with_capacity(3 * MAX_CREATED + 16 * MAX_CROSSINGS),
            nodes_at_start: 0,
            connected: false,
            separation_refused: false,
            queue: crate::Room::with_capacity(REJOIN_BUDGET + 1),
            mass_mover: MassMover::with_capacity(capacity),
        };
        // Whether the body is one part, known from the start (a pass at setup): its first opening
        // needs no parts search when the search round the cut joins its copies again.
        let (n, t) = (body.node_count(), body.surface.triangles.len());
        if cutter.transector.fits(n, t) {
            cutter.connected = cutter.transector.find_parts(body) == 1;
        }
        cutter
    }

    /// [`Cutter::hold_least_mass`] at every node of the body (after a transection). Returns the
    /// nodes changed (fed or softened).
    pub fn hold_least_mass_everywhere(&mut self, body: &mut Body, h: f64) -> u64 {
        // The index only when some node needs feeding (it is built again at the next cut anyway).
        if !self.mass_mover.find_light(body, h) {
            return 0;
        }
        if !self.sync_index(body) {
            self.mass_mover.counters.unchecked += body.node_count() as u64;
            return 0;
        }
        match self.index.as_mut() {
            Some(index) => self.mass_mover.hold_light(body, h, index),
            None => 0,
        }
    }

    /// Gives the nodes the tick's sealed record lists at least the mass semi-implicit Euler
    /// carries at step `h`, moving mass to them from the nodes round them (see
    /// [`super::explicit`]); the donors join the record. Returns the nodes changed (fed or softened).
    pub fn hold_least_mass(&mut self, body: &mut Body, h: f64) -> u64 {
        match self.index.as_mut() {
            Some(index) if index.is_valid_for(body) => {
                self.mass_mover.hold(body, h, &mut self.changes, index)
            }
            _ => {
                self.mass_mover.counters.unchecked += self.changes.nodes().len() as u64;
                0
            }
        }
    }

    /// Brings the rest-frame index up to the body (built again after a change the cutter did not
    /// make). Whether it can be used.
    fn sync_index(&mut self, body: &Body) -> bool {
        let cell = self.longest;
        self.index.as_mut().is_some_and(|i| i.sync(body, cell))
    }

    /// The index, when it describes the body as it is.
    fn index_for(&mut self, body: &Body) -> Option<&mut RestIndex> {
        self.index.as_mut().filter(|i| i.is_valid_for(body))
    }

    /// The spring between `a` and `b` (the first one a pass over the springs would meet).
    fn edge_between(&mut self, body: &Body, a: u32, b: u32) -> Option<usize> {
        match self.index_for(body) {
            Some(index) => index.find_edge(body, a, b),
            None => find_edge(body, a, b),
        }
    }

    fn triangle_changed(&mut self, body: &Body, t: u32) {
        if let Some(index) = self.index.as_mut() {
            index.triangle_changed(body, t);
        }
    }

    fn edge_changed(&mut self, body: &Body, k: u32) {
        self.changes.edge(k);
        if let Some(index) = self.index.as_mut() {
            index.edge_changed(body, k);
        }
    }

    /// Whether a pending path edge (a slit waiting to open) ends at `a` or `b`.
    pub fn pending_at(&self, a: u32, b: u32) -> bool {
        self.pending
            .iter()
            .any(|&(p, q)| p == a || p == b || q == a || q == b)
    }

    /// The path edges the last step (cut or tear) made, as node pairs of the mesh (each opened
    /// into two lips, or kept pending); empty after a step that cut nothing.
    pub fn last_path_edges(&self) -> &[(u32, u32)] {
        &self.path_edges[self.new_path_from.min(self.path_edges.len())..]
    }

    /// Adds a transection's figures to the counters.
    pub fn transection_counts(&mut self, t: &crate::topology::transect::Transection) {
        if t.parts < 2 {
            return;
        }
        self.counters.transections += 1;
        self.counters.caps += t.caps as u64;
        self.counters.caps_refused += t.caps_refused as u64;
        self.counters.cap_quality_misses += t.cap_quality_misses as u64;
        self.smallest_cap_angle_deg = self.smallest_cap_angle_deg.min(t.smallest_cap_angle_deg);
    }

    /// Follows a renumbering of the body's nodes (a transection): tips and pending path edges are
    /// forgotten. Allocation-free.
    pub fn renumbered(&mut self) {
        for tips in &mut self.tips {
            tips.clear();
        }
        if let Some(index) = self.index.as_mut() {
            index.invalidate();
        }
        self.pending.clear();
        self.transector.clear_marks();
    }

    /// Starts afresh on a new piece of a body: no tips, no counts, blades not through.
    pub fn restart(&mut self) {
        self.renumbered();
        self.connected = false;
        self.separation_refused = false;
        self.counters = CutCounters::default();
        self.smallest_created_angle_deg = 180.0;
        self.through.fill(false);
        self.away.fill(0);
    }

    fn next_stamp(&mut self) -> u32 {
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            self.node_stamp.iter_mut().for_each(|s| *s = 0);
            self.cut_stamp.iter_mut().for_each(|s| *s = 0);
            self.near_stamp.iter_mut().for_each(|s| *s = 0);
            self.side_stamp.iter_mut().for_each(|s| *s = 0);
            self.loop_stamp.iter_mut().for_each(|s| *s = 0);
            self.stamp = 1;
        }
        self.stamp
    }

    fn tolerance(&self, rest_length: f64) -> f64 {
        self.settings.tolerance.max(0.25 * rest_length)
    }

    /// Cuts `body` along the quad the blade of tool `tool` swept: `start` and `end` are its cutting
    /// segment at the start and the end of the tick (world frame, the body's end-of-tick positions).
    pub fn cut(
        &mut self,
        body: &mut Body,
        tool: usize,
        start: [Vec3; 2],
        end: [Vec3; 2],
    ) -> CutStep {
        self.cut_within(body, tool, start, end, None)
    }

    /// [`NodeExtent`] of `body` measured now by a pass over its nodes (its rigid component's
    /// placement): what the world hands [`Cutter::cut_within`],
    /// for callers that step a body themselves.
    pub fn measure_extent(body: &Body) -> NodeExtent {
        let r = &body.rigid;
        let rotation = *r.world_from_body.to_rotation_matrix().matrix();
        let origin = r.position_in_world;
        let s = &body.surface;
        let mut bounds = Aabb::empty();
        let mut reach = 0.0f64;
        for (x, h) in s.position_in_world.iter().zip(&s.homologue_in_body) {
            bounds.include(x);
            reach = reach.max((x - (rotation * h + origin)).norm());
        }
        NodeExtent {
            bounds,
            frame: Some((rotation, origin, reach)),
        }
    }

    /// [`Cutter::cut`], given what is known of the body's nodes (the world has it from the
    /// divergence guard's pass, [`crate::dynamics::guard::Guard::node_bounds`], and the tick's
    /// homologues): a blade whose swept box misses the box of the nodes is away from the body, and
    /// the step ends at no cost at all instead of a pass over the nodes — the same answer, since
    /// every node then lies beyond one side of the blade's box. With a frame and reach, the springs
    /// the blade may cross are taken from the rest-frame index near the blade's box carried into
    /// the body frame and grown by the reach, instead of from a pass over every node and spring —
    /// again the same answer: a node within the blade's box lies within the reach of its rest place.
    /// `extent` must hold every node of `body`.
    pub fn cut_within(
        &mut self,
        body: &mut Body,
        tool: usize,
        start: [Vec3; 2],
        end: [Vec3; 2],
        extent: Option<&NodeExtent>,
    ) -> CutStep {
        let mut step = CutStep::default();
        self.new_path_from = self.path_edges.len();
        let quad = self.swept_quad(tool, start, end);
        let area = 0.5
            * ((quad[1] - quad[0]).cross(&(quad[2] - quad[0])).norm()
                + (quad[2] - quad[0]).cross(&(quad[3] - quad[0])).norm());
        let size = (quad[1] - quad[0]).norm().max((quad[2] - quad[3]).norm());
        let stamp = self.next_stamp();
        let n = body.node_count();
        self.nodes_at_start = n;
        if self.node_stamp.len() < n {
            // Cannot happen within the reserved room; refuse rather than grow on the tick.
            return self.refuse(step);
        }
        let mut bounds = Aabb::empty();
        for p in &quad {
            bounds.include(p);
        }
        bounds.inflate(self.tolerance(self.longest));
        // The blade's box misses the box of the nodes: every node lies beyond one of its sides, as
        // the pass below would find (none inside, a side they all share), so the step stops here.
        if extent.is_some_and(|e| !e.bounds.overlaps(&bounds)) {
            self.counters.away_ticks += 1;
            return step;
        }
        let local = self.springs_near(body, &bounds, extent);
        let (shared_sides, inside) = self.sides(body, &bounds, local, stamp);
        // Only a blade that pressed through a resistance asks whether it is still near the body.
        if self.settings.resistance > 0.0 {
            step.nodes_near = inside;
        }
        if area <= 1e-14 * size * size.max(1e-9) || size <= 0.0 {
            return step;
        }
        // Every node on one side of the box: no edge crosses the sweep, and no crack tip (a node)
        // is within the tolerance of it, so the step has nothing to do.
        if !local && shared_sides != 0 {
            return step;
        }
        // 1. Crossings.
        if !self.find_crossings(body, &quad, local) {
            return self.refuse(step);
        }
        step.crossings = self.crossings.len() as u32;
        if self.crossings.is_empty() && !self.fronts_meet(body, tool, &quad) {
            return step;
        }
        // 2. Templates, with quality splits.
        self.plan(body, tool, stamp, &quad);
        if !self.room_for_plan(body, n) {
            return self.refuse(step);
        }
        // Create the split nodes and split their springs.
        for c in 0..self.crossings.len() {
            if matches!(self.crossings[c].choice, Choice::Split) {
                self.split_edge(body, c);
                step.splits += 1;
            }
        }
        // Rewrite the triangles.
        let prestress = self.settings.prestress;
        self.created.clear();
        for i in 0..self.affected.len() {
            let a = self.affected[i];
            self.apply_template(body, &a, prestress);
        }
        // 3. Path edges, and tips for the next step.
        self.lay_path();
        // Edge flips where a created triangle is below the quality bound; the figures of quality.
        self.flip_for_quality(body, prestress);
        self.count_created_quality(body);
        self.collect_tips(tool);
        // 4. Open the surface along the path.
        self.open_path(body, &mut step);
        step
    }

    /// `step`, refused and counted.
    fn refuse(&mut self, mut step: CutStep) -> CutStep {
        step.refused = true;
        self.counters.refused += 1;
        step
    }

    /// The quad the blade of `tool` swept from its segment `start` to `end`, reaching back over a
    /// quarter of the tick's motion into the last one's: the body moves too, and an edge whose
    /// crossing sat on the line between two ticks' quads could slip back out of both (the
    /// crossings of the last tick are split or snapped, so only snaps onto the path can come
    /// again). A blade that jumped (its segment does not start where the last step left it: a
    /// pose glitch, or a blade set down elsewhere) starts a new cut: joining its old tips would
    /// open tissue it never swept.
    fn swept_quad(&mut self, tool: usize, start: [Vec3; 2], end: [Vec3; 2]) -> [Vec3; 4] {
        if let Some(last) = self.last_end.get_mut(tool) {
            let jumped = last.is_some_and(|l| {
                (l[0] - start[0]).norm().max((l[1] - start[1]).norm()) > self.settings.tolerance
            });
            if jumped && let Some(tips) = self.tips.get_mut(tool) {
                tips.clear();
            }
            *last = Some(end);
        }
        let back = |s: Vec3, e: Vec3| s - (e - s) * BACK_REACH;
        let start = [back(start[0], end[0]), back(start[1], end[1])];
        [start[0], start[1], end[1], end[0]]
    }

    /// Whether the springs to look at are those near the blade's box `bounds` in the rest frame
    /// (collected into the index's `found`: with `extent`'s frame and an index in step with the
    /// body), rather than all of them.
    fn springs_near(&mut self, body: &Body, bounds: &Aabb, extent: Option<&NodeExtent>) -> bool {
        let indexed = self.sync_index(body);
        let Some((rotation, origin, reach)) = extent.and_then(|e| e.frame).filter(|_| indexed)
        else {
            self.counters.passes += 1;
            return false;
        };
        let mut rest = Aabb::empty();
        for corner in 0..8 {
            let c = Vec3::from([0, 1, 2].map(|k| {
                if (corner >> k) & 1 == 0 {
                    bounds.min[k]
                } else {
                    bounds.max[k]
                }
            }));
            rest.include(&(rotation.transpose() * (c - origin)));
        }
        // Grown by the reach, and for the rounding of the placements (here and of the homologues).
        rest.inflate(reach + 1e-9 * (1.0 + rest.max.abs().max() + rest.min.abs().max()));
        if let Some(index) = self.index.as_mut() {
            let mark = index.begin();
            index.collect_edges(body, &rest, mark, |_, _, _| true);
            index.finish();
        }
        self.counters.local_steps += 1;
        true
    }

    /// Each node's side of the blade's box (`node_side`), the sides they all share and how many
    /// are in it: over the ends of the springs near the blade (`local`), or over every node.
    fn sides(&mut self, body: &Body, bounds: &Aabb, local: bool, stamp: u32) -> (u8, u32) {
        let x = &body.surface.position_in_world;
        let mut shared_sides = u8::MAX;
        let mut inside = 0u32;
        if local {
            let found = &self.index.as_ref().expect("indexed").found;
            let e = &body.edges;
            for &k in found {
                for v in [e.a[k as usize], e.b[k as usize]] {
                    let v = v as usize;
                    if self.side_stamp[v] != stamp {
                        self.side_stamp[v] = stamp;
                        let side = bounds.outcode(&x[v], &x[v]);
                        self.node_side[v] = side;
                        inside += u32::from(side == 0);
                    }
                }
            }
            // Every node with a side of 0 is an end of a spring found (no node is without one).
            // Whether they all share a side is not known: the crossings are looked for among the
            // springs found, which is what a shared side would have spared.
        } else {
            let n = body.node_count();
            for (side, p) in self.node_side[..n].iter_mut().zip(&x[..n]) {
                *side = bounds.outcode(p, p);
                shared_sides &= *side;
                inside += u32::from(*side == 0);
            }
        }
        (shared_sides, inside)
    }

    /// The springs (near the blade, with `local`, or all) that cross `quad`, into `crossings`,
    /// each to be split or snapped to an end; false when there are more than the room for them.
    fn find_crossings(&mut self, body: &Body, quad: &[Vec3; 4], local: bool) -> bool {
        self.crossings.clear();
        self.split_rest.clear();
        let x = &body.surface.position_in_world;
        let edges = &body.edges;
        let count = if local {
            self.index.as_ref().expect("indexed").found.len()
        } else {
            edges.len()
        };
        for i in 0..count {
            let k = if local {
                self.index.as_ref().expect("indexed").found[i] as usize
            } else {
                i
            };
            let (a, b) = (edges.a[k], edges.b[k]);
            // The same as `bounds.outcode(xa, xb) != 0`, from the codes of `sides`.
            if self.node_side[a as usize] & self.node_side[b as usize] != 0 {
                continue;
            }
            let (xa, xb) = (x[a as usize], x[b as usize]);
            let Some(t) = segment_triangle(&xa, &xb, &quad[0], &quad[1], &quad[2])
                .or_else(|| segment_triangle(&xa, &xb, &quad[0], &quad[2], &quad[3]))
            else {
                continue;
            };
            if self.crossings.len() == MAX_CROSSINGS {
                return false;
            }
            let tol = self.tolerance(edges.rest_length[k]);
            let (da, db) = (quad_distance(&xa, quad), quad_distance(&xb, quad));
            // A crossing within MIN_SPLIT_FRACTION of an end snaps to it whatever the distance:
            // only an edge stretched far past its rest length (a body diverging before its
            // guard acts) puts the end out of the tolerance there, and a split so near an end
            // would leave a needle in the rest shape.
            let choice = if (da <= tol && da <= db) || t < MIN_SPLIT_FRACTION {
                Choice::Snap(a)
            } else if db <= tol || t > 1.0 - MIN_SPLIT_FRACTION {
                Choice::Snap(b)
            } else {
                Choice::Split
            };
            self.crossings.push(Crossing {
                a,
                b,
                edge: k as u32,
                t,
                crossed: t,
                choice,
                node: match choice {
                    Choice::Snap(v) => v,
                    Choice::Split => u32::MAX,
                },
                on_path: true,
            });
        }
        true
    }

    /// The plan of the step from its crossings: snaps along edges, the numbered splits, the
    /// affected triangles and their templates, with quality splits, snaps and slides over up to
    /// [`QUALITY_ROUNDS`] rounds; then the splits that serve nothing dropped and the quality
    /// splits the path should go through promoted.
    fn plan(&mut self, body: &Body, tool: usize, stamp: u32, quad: &[Vec3; 4]) {
        self.snap_along_edges(tool);
        // Number the planned split nodes; the triangles around the crossings and tips.
        self.number_splits(body);
        self.select_candidates(body, tool, stamp, 0);
        for _round in 0..QUALITY_ROUNDS {
            self.collect_affected(body, tool, stamp, quad);
            if self.snap_for_quality(body, quad) {
                self.snap_along_edges(tool);
                self.number_splits(body);
                self.collect_affected(body, tool, stamp, quad);
            }
            if self.slide_splits(body, quad) {
                self.collect_affected(body, tool, stamp, quad);
            }
            let before = self.crossings.len();
            if !self.add_quality_splits(body) {
                break;
            }
            self.select_candidates(body, tool, stamp, before);
            self.number_splits(body);
        }
        self.collect_affected(body, tool, stamp, quad);
        // A split made for quality in an earlier round may serve nothing any more (the path
        // crossing that called for it snapped since) and only divide a corner.
        while self.drop_needless_split(body) {
            self.number_splits(body);
            self.collect_affected(body, tool, stamp, quad);
        }
        // A path leaving a corner close along one of its edges, with a quality split on that edge
        // near the blade: the path goes through the split instead.
        self.promote_quality_splits(body, quad);
    }

    /// Whether `body` (of `n` nodes at the step's start) and the scratch have room for the plan:
    /// nodes for splits and copies, triangles and edges for the templates and lips.
    fn room_for_plan(&self, body: &Body, n: usize) -> bool {
        let splits = self
            .crossings
            .iter()
            .filter(|c| matches!(c.choice, Choice::Split))
            .count();
        let path = self.affected.iter().filter(|a| a.path.is_some()).count();
        let new_triangles: usize = self
            .affected
            .iter()
            .map(|a| a.crossing.iter().filter(|c| self.is_split(**c)).count())
            .sum();
        let need_nodes = splits + 2 * path + 2;
        let need_edges = splits + new_triangles + 2 * path + 2;
        let limits = body.limits;
        n + need_nodes <= limits.nodes
            && body.surface.triangles.len() + new_triangles <= limits.triangles
            && body.edges.len() + need_edges <= limits.edges
            && n + need_nodes <= self.node_stamp.len()
    }

    /// The path's edges: those still pending from earlier steps, then this step's, each once.
    fn lay_path(&mut self) {
        self.path_edges.clear();
        self.path_edges.extend_from_slice(&self.pending);
        self.new_path_from = self.pending.len();
        for i in 0..self.affected.len() {
            let a = self.affected[i];
            if let Some(pair) = a.path {
                if pair.0 != pair.1 && !self.path_edges.contains(&pair) {
                    self.path_edges.push(pair);
                }
            }
        }
    }

    /// The smallest corner of the triangles the step created (in the rest shape), and the counts
    /// of those below the quality bound that inherited their parent's corner or missed it.
    fn count_created_quality(&mut self, body: &Body) {
        let h = &body.surface.homologue_in_body;
        for &(t, floor) in &self.created {
            let angle = min_angle_deg(&body.surface.triangles[t as usize].map(|v| h[v as usize]));
            self.smallest_created_angle_deg = self.smallest_created_angle_deg.min(angle);
            self.counters.created_triangles += 1;
            // A child keeping its parent's smallest corner measures it with other roundings.
            let floor = floor - FLOOR_ROUNDING_DEG;
            if angle < self.quality_bound_deg && angle >= floor {
                self.counters.quality_inherited += 1;
            }
            if angle < floor {
                self.counters.quality_misses += 1;
            }
        }
    }

    /// Opens `path_edges` (see [`Cutter::open`]), keeps what cannot open yet pending, marks the path
    /// for the transection and counts the step (its `splits` already set).
    fn open_path(&mut self, body: &mut Body, step: &mut CutStep) {
        let (copies, opened) = self.open(body);
        self.keep_pending(body);
        self.transector.clear_marks();
        for i in 0..self.path_edges.len() {
            let (p, q) = self.path_edges[i];
            self.transector.mark(p);
            self.transector.mark(q);
        }
        for i in 0..self.copies.len() {
            self.transector.mark(self.copies[i]);
        }
        step.copies = copies;
        step.opened = opened;
        step.changed = step.splits > 0 || copies > 0 || opened > 0;
        if step.changed {
            body.topology_version += 1;
            if let Some(index) = self.index.as_mut() {
                index.caught_up(body);
            }
            self.refresh_diagonals(body);
            // A body that was one part still is when every copy is joined to its origin again
            // (then every spring path of before has one now): no parts search needed.
            if copies > 0 && self.connected && !self.copies_rejoined(body) {
                self.connected = false;
            }
            self.counters.steps += 1;
            self.counters.splits += step.splits as u64;
            self.counters.copies += copies as u64;
            self.counters.opened_edges += opened as u64;
        }
    }

    /// Whether every copy this step made is joined to its origin by a path of springs: found by a
    /// search from the copy over the springs the index lists at each node (at most
    /// [`REJOIN_BUDGET`] nodes visited in all), or else along the boundary loop through the copy
    /// (a copy lies on a lip; its origin, on the other lip of the same slit, is on the same loop
    /// unless the slit closed a loop of its own) — each loop walked once, at most [`WALK_BUDGET`]
    /// boundary steps in all. False when both give up or there is no index.
    fn copies_rejoined(&mut self, body: &Body) -> bool {
        let mut visits = 0usize;
        let mut walked = 0usize;
        let base = self.stamp.wrapping_add(1);
        for i in 0..self.copies.len() {
            let (start, goal) = (self.copies[i], self.copy_origin[i]);
            if visits <= REJOIN_BUDGET && self.search_rejoins(body, start, goal, &mut visits) {
                continue;
            }
            if !self.on_one_loop(body, start, goal, base, &mut walked) {
                self.counters.rejoins_failed += 1;
                return false;
            }
            self.counters.rejoins_by_loop += 1;
        }
        true
    }

    /// Whether `goal` lies on the boundary loop through `start` (walked now, its nodes marked with
    /// the walk's stamp, unless a walk of this step — stamps from `base` on — marked `start`
    /// already); `walked` counts the boundary steps of the step's walks.
    fn on_one_loop(
        &mut self,
        body: &Body,
        start: u32,
        goal: u32,
        base: u32,
        walked: &mut usize,
    ) -> bool {
        let g = goal as usize;
        // Walked already this step (stamps from `base` on): the goal is on it or not.
        let mark = self.loop_stamp[start as usize];
        if mark >= base {
            return self.loop_stamp[g] == mark;
        }
        let stamp = self.next_stamp();
        let Some(index) = self.index.as_mut().filter(|x| x.is_valid_for(body)) else {
            return false;
        };
        let mut u = start;
        loop {
            self.loop_stamp[u as usize] = stamp;
            let Some(next) = boundary_successor(index, body, u) else {
                return false;
            };
            if next == start {
                break;
            }
            *walked += 1;
            if *walked > WALK_BUDGET {
                return false;
            }
            u = next;
        }
        self.loop_stamp[g] == stamp
    }

    /// The search from copy `start` to `goal` over the springs (breadth first); `visits` counts the
    /// nodes the step's searches visited, and the search gives up past [`REJOIN_BUDGET`].
    fn search_rejoins(&mut self, body: &Body, start: u32, goal: u32, visits: &mut usize) -> bool {
        let stamp = self.next_stamp();
        let Some(index) = self.index.as_mut().filter(|x| x.is_valid_for(body)) else {
            return false;
        };
        let h = &body.surface.homologue_in_body;
        let (marks, queue) = (&mut self.node_stamp, &mut self.queue);
        queue.clear();
        queue.push(start);
        marks[start as usize] = stamp;
        let mut head = 0;
        let mut reached = false;
        while head < queue.len() && !reached {
            let u = queue[head];
            head += 1;
            *visits += 1;
            if *visits > REJOIN_BUDGET {
                return false;
            }
            let mark = index.begin();
            let at = RestIndex::point(&h[u as usize]);
            index.collect_edges(body, &at, mark, |_, a, b| {
                let w = if a == u {
                    b
                } else if b == u {
                    a
                } else {
                    return false;
                };
                if marks[w as usize] != stamp && queue.len() < queue.capacity() {
                    marks[w as usize] = stamp;
                    queue.push(w);
                    reached |= w == goal;
                }
                false
            });
        }
        reached
    }

    /// The stiffness and damping diagonals (link, air and the springs at each node) of the nodes the
    /// step changed — the corners of the triangles it created, the ends of its crossings, its path,
    /// its copies and new nodes — each summed afresh over its springs in index order (from the
    /// index), as [`Body::refresh_diagonals`] sums them, so the same bits; that pass over every node
    /// and spring when there is no index.
    fn refresh_diagonals(&mut self, body: &mut Body) {
        let n = body.node_count();
        let s = &body.surface;
        let usable = self.index.as_ref().is_some_and(|i| i.is_valid_for(body))
            && s.stiffness_diagonal.len() == n
            && s.damping_diagonal.len() == n;
        if !usable {
            body.refresh_diagonals();
            self.changes.lose();
            return;
        }
        let touched = &mut self.touched;
        touched.clear();
        let mut overflow = false;
        let mut add = |v: u32| {
            if (v as usize) < n {
                if touched.len() < touched.capacity() {
                    touched.push(v);
                } else {
                    overflow = true;
                }
            }
        };
        let triangles = &s.triangles;
        for &(t, _) in &self.created {
            if let Some(corners) = triangles.get(t as usize) {
                corners.iter().for_each(|&v| add(v));
            }
        }
        for c in &self.crossings {
            add(c.a);
            add(c.b);
            add(c.node);
        }
        for &(p, q) in &self.path_edges {
            add(p);
            add(q);
        }
        self.copies.iter().for_each(|&v| add(v));
        (self.nodes_at_start.min(n)..n).for_each(|v| add(v as u32));
        if overflow {
            body.refresh_diagonals();
            self.changes.lose();
            return;
        }
        touched.sort_unstable();
        touched.dedup();
        // The nodes whose mass, links or springs the step changed are among these (the ends of
        // every spring it rewrote, split or flipped, the copies and their origins, the new nodes).
        for &v in touched.iter() {
            self.changes.node(v);
        }
        let index = self.index.as_mut().expect("usable");
        for &v in touched.iter() {
            let i = v as usize;
            index.incident_edges(body, v);
            let s = &body.surface;
            let (mut k, mut c) = (s.link_stiffness[i], s.link_damping[i] + s.air_damping[i]);
            let e = &body.edges;
            for &edge in &index.found {
                k += e.stiffness[edge as usize];
                c += e.damping[edge as usize];
            }
            let s = &mut body.surface;
            s.stiffness_diagonal[i] = k;
            s.damping_diagonal[i] = c;
        }
    }

    /// Opens `edges` (springs that tore: pairs of nodes of the current mesh, each an edge of two
    /// triangles) with the opening of a cut: nodes whose triangles fall apart are copied, opened
    /// springs become two lips. Edges that cannot open yet (a slit of one edge between two inner
    /// nodes) are kept pending, as a cut's are. Allocation-free; refused (and counted) when the
    /// body's reserved room cannot take it.
    pub fn tear(&mut self, body: &mut Body, edges: &[(u32, u32)]) -> CutStep {
        let mut step = CutStep::default();
        let n = body.node_count();
        let paths = edges.len() + self.pending.len();
        let need = 2 * paths + 2;
        if n + need > body.limits.nodes
            || body.edges.len() + need > body.limits.edges
            || n + need > self.node_stamp.len()
            || paths > self.path_edges.capacity()
        {
            step.refused = true;
            self.counters.refused += 1;
            return step;
        }
        self.sync_index(body);
        self.nodes_at_start = n;
        self.path_edges.clear();
        self.path_edges.extend_from_slice(&self.pending);
        self.new_path_from = self.pending.len();
        for &(p, q) in edges {
            // Path edges are (smaller, larger) node pairs.
            let pair = (p.min(q), p.max(q));
            if p != q && !self.path_edges.contains(&pair) {
                self.path_edges.push(pair);
            }
        }
        self.open_path(body, &mut step);
        step
    }

    /// A crossing on an edge from a node the path already goes through (a node another crossing of
    /// this step snapped to, or the crack tip) would make the path run along that edge: in the
    /// triangle they share, the cut would join a corner to a point of one of its own sides, and the
    /// split would only leave needles on both sides of the edge. Such a crossing snaps to that
    /// node: the blade goes on from it.
    fn snap_along_edges(&mut self, tool: usize) {
        for i in 0..self.crossings.len() {
            let c = self.crossings[i];
            if !matches!(c.choice, Choice::Split) {
                continue;
            }
            let on = |v: u32, cutter: &Self| {
                cutter
                    .crossings
                    .iter()
                    .any(|d| matches!(d.choice, Choice::Snap(w) if w == v))
                    || cutter.tips.get(tool).is_some_and(|t| t.contains(v))
            };
            let near = if c.t <= 0.5 { [c.a, c.b] } else { [c.b, c.a] };
            if let Some(&v) = near.iter().find(|&&v| on(v, self)) {
                self.crossings[i].choice = Choice::Snap(v);
                self.crossings[i].node = v;
            }
        }
    }

    /// Whether two tips of `tool` lie within an edge of each other (rest frame) and within the
    /// tolerance of `quad`: two fronts of one blade (the near and far side of a tube) met, and the
    /// last triangle between them is cut although the blade crossed no edge there. Looks at the
    /// tips only.
    fn fronts_meet(&self, body: &Body, tool: usize, quad: &[Vec3; 4]) -> bool {
        let Some(tips) = self.tips.get(tool) else {
            return false;
        };
        let n = body.node_count();
        let nodes = &tips.nodes[..tips.len];
        let tol = self.tolerance(self.longest);
        let near = |v: u32| (v as usize) < n && self.tip_near(body, v, quad, tol);
        nodes.iter().enumerate().any(|(i, &p)| {
            near(p)
                && nodes[i + 1..].iter().any(|&q| {
                    near(q)
                        && (self.rest_of(body, p) - self.rest_of(body, q)).norm() <= self.longest
                })
        })
    }

    fn tip_near(&self, body: &Body, v: u32, quad: &[Vec3; 4], tol: f64) -> bool {
        quad_distance(&body.surface.position_in_world[v as usize], quad) <= tol
    }

    fn is_split(&self, c: Option<u16>) -> bool {
        c.is_some_and(|c| matches!(self.crossings[c as usize].choice, Choice::Split))
    }

    /// Gives every planned split node its number and rest position.
    fn number_splits(&mut self, body: &Body) {
        let n = body.node_count() as u32;
        self.split_rest.clear();
        let h = &body.surface.homologue_in_body;
        for c in &mut self.crossings {
            if matches!(c.choice, Choice::Split) {
                c.node = n + self.split_rest.len() as u32;
                self.split_rest
                    .push(h[c.a as usize] * (1.0 - c.t) + h[c.b as usize] * c.t);
            }
        }
    }

    /// The split nodes of a triangle's crossings (`None` where a side has no crossing or a snap).
    fn splits_of(&self, crossing: [Option<u16>; 3]) -> [Option<u32>; 3] {
        crossing.map(|c| {
            c.and_then(|c| {
                let c = &self.crossings[c as usize];
                matches!(c.choice, Choice::Split).then_some(c.node)
            })
        })
    }

    /// A triangle's quality floor: the bound, or its own smallest angle when that is below it.
    fn floor_of(&self, body: &Body, corners: [u32; 3]) -> f64 {
        let h = &body.surface.homologue_in_body;
        self.quality_bound_deg
            .min(min_angle_deg(&corners.map(|v| h[v as usize])))
    }

    fn rest_of(&self, body: &Body, v: u32) -> Vec3 {
        let n = body.node_count() as u32;
        if v < n {
            body.surface.homologue_in_body[v as usize]
        } else {
            self.split_rest[(v - n) as usize]
        }
    }

    fn crossing_on(&self, a: u32, b: u32) -> Option<u16> {
        self.crossings
            .iter()
            .position(|c| (c.a == a && c.b == b) || (c.a == b && c.b == a))
            .map(|k| k as u16)
    }

    /// The triangles a step may touch: those with a corner at a crossing's end or at a tip of
    /// `tool`, in index order. With `from` > 0, only crossings from `from` on are new (quality
    /// splits, on edges of affected triangles): the selection is made again only if one of them
    /// has neither end in it (the triangle across it could be missing).
    fn select_candidates(&mut self, body: &Body, tool: usize, stamp: u32, from: usize) {
        // The marks are those of the last selection (a mark set between selections would let a
        // second new crossing through on the first one's mark).
        let grew = from == 0
            || self.crossings[from..].iter().any(|c| {
                self.near_stamp[c.a as usize] != stamp && self.near_stamp[c.b as usize] != stamp
            });
        if !grew {
            return;
        }
        for c in &self.crossings {
            self.near_stamp[c.a as usize] = stamp;
            self.near_stamp[c.b as usize] = stamp;
        }
        if let Some(tips) = self.tips.get(tool) {
            for &v in &tips.nodes[..tips.len] {
                if let Some(mark) = self.near_stamp.get_mut(v as usize) {
                    *mark = stamp;
                }
            }
        }
        self.candidates.clear();
        let n = body.node_count();
        if let Some(index) = self.index.as_mut().filter(|i| i.is_valid_for(body)) {
            // The triangles round each marked node, from the index, in index order.
            let h = &body.surface.homologue_in_body;
            let near = &self.near_stamp;
            let mark = index.begin();
            let marked = |v: u32| near[v as usize] == stamp;
            for c in &self.crossings {
                for v in [c.a, c.b] {
                    let at = RestIndex::point(&h[v as usize]);
                    index.collect_triangles(body, &at, mark, |_, t| t.iter().any(|&w| marked(w)));
                }
            }
            if let Some(tips) = self.tips.get(tool) {
                for &v in &tips.nodes[..tips.len] {
                    if (v as usize) < n {
                        let at = RestIndex::point(&h[v as usize]);
                        index.collect_triangles(body, &at, mark, |_, t| {
                            t.iter().any(|&w| marked(w))
                        });
                    }
                }
            }
            index.finish();
            self.candidates.extend_from_slice(&index.found);
            return;
        }
        for (index, t) in body.surface.triangles.iter().enumerate() {
            if t.iter().any(|&v| self.near_stamp[v as usize] == stamp) {
                self.candidates.push(index as u32);
            }
        }
    }

    /// Finds the triangles with a crossing (or a tip of `tool`) and decides their templates and path.
    fn collect_affected(&mut self, body: &Body, tool: usize, stamp: u32, quad: &[Vec3; 4]) {
        for c in &self.crossings {
            self.node_stamp[c.a as usize] = stamp;
            self.node_stamp[c.b as usize] = stamp;
        }
        let tips = self.tips.get(tool).cloned().unwrap_or_default();
        self.affected.clear();
        let n = body.node_count();
        for ci in 0..self.candidates.len() {
            let index = self.candidates[ci] as usize;
            let t = &body.surface.triangles[index];
            let marked = t
                .iter()
                .filter(|&&v| self.node_stamp[v as usize] == stamp)
                .count();
            let has_tip = t.iter().any(|&v| tips.contains(v));
            if marked < 2 && !has_tip {
                continue;
            }
            let crossing = [(0, 1), (1, 2), (2, 0)].map(|(i, j)| self.crossing_on(t[i], t[j]));
            if crossing.iter().all(Option::is_none) && !has_tip {
                continue;
            }
            // Path points: crossings on the path, and tips within tolerance of this quad.
            let mut points = [u32::MAX; 6];
            let mut count = 0;
            let add = |v: u32, points: &mut [u32; 6], count: &mut usize| {
                if !points[..*count].contains(&v) && *count < 6 {
                    points[*count] = v;
                    *count += 1;
                }
            };
            for c in crossing.iter().flatten() {
                let c = &self.crossings[*c as usize];
                if c.on_path {
                    add(c.node, &mut points, &mut count);
                }
            }
            // The crack tip the blade left: the path goes on from it.
            for &v in t {
                if tips.contains(v) && (v as usize) < n {
                    add(v, &mut points, &mut count);
                }
            }
            let splits = crossing.map(|c| {
                c.and_then(|c| {
                    let c = &self.crossings[c as usize];
                    matches!(c.choice, Choice::Split).then_some(c.node)
                })
            });
            let available = |p: u32, q: u32, diag_first: bool| -> bool {
                edge_in_template(*t, splits, diag_first, p, q)
            };
            // Choose the path pair: nearest midpoint to the quad among pairs the template can hold.
            let mut path = None;
            let mut diagonal_from_first = self.best_diagonal(body, *t, splits).unwrap_or(true);
            if count >= 2 {
                let mut best = f64::INFINITY;
                let tol = self.tolerance(self.longest);
                let crossed = |v: u32| {
                    crossing
                        .iter()
                        .flatten()
                        .any(|c| self.crossings[*c as usize].node == v)
                };
                for i in 0..count {
                    for j in i + 1..count {
                        let (p, q) = (points[i], points[j]);
                        // Two tips are joined only where the blade is (fronts meeting).
                        let joined = crossed(p)
                            || crossed(q)
                            || (self.tip_near(body, p, quad, tol)
                                && self.tip_near(body, q, quad, tol));
                        if !joined {
                            continue;
                        }
                        let world_mid = 0.5 * (self.world_of(body, p) + self.world_of(body, q));
                        let d = quad_distance(&world_mid, quad);
                        for diag in [diagonal_from_first, !diagonal_from_first] {
                            if available(p, q, diag) && d < best {
                                best = d;
                                path = Some((p, q, diag));
                                break;
                            }
                        }
                    }
                }
                if let Some((_, _, diag)) = path {
                    diagonal_from_first = diag;
                }
            }
            self.affected.push(Affected {
                triangle: index as u32,
                corners: *t,
                crossing,
                path: path.map(|(p, q, _)| (p.min(q), p.max(q))),
                diagonal_from_first,
            });
        }
    }

    fn world_of(&self, body: &Body, v: u32) -> Vec3 {
        let x = &body.surface.position_in_world;
        if (v as usize) < x.len() {
            x[v as usize]
        } else {
            let c = self
                .crossings
                .iter()
                .find(|c| c.node == v)
                .expect("a planned node");
            x[c.a as usize] * (1.0 - c.t) + x[c.b as usize] * c.t
        }
    }

    /// For two splits, which diagonal gives the better smallest angle (true: from the first split's
    /// node to the far corner); `None` otherwise.
    fn best_diagonal(&self, body: &Body, t: [u32; 3], splits: [Option<u32>; 3]) -> Option<bool> {
        if splits.iter().filter(|s| s.is_some()).count() != 2 {
            return None;
        }
        let q1 = self.template_quality(body, t, splits, true);
        let q2 = self.template_quality(body, t, splits, false);
        Some(q1 >= q2)
    }

    fn template_quality(
        &self,
        body: &Body,
        t: [u32; 3],
        splits: [Option<u32>; 3],
        diagonal_from_first: bool,
    ) -> f64 {
        self.template_quality_with(body, t, splits, diagonal_from_first, Vec3::zeros())
    }

    /// [`Cutter::template_quality`] where node `u32::MAX - 1` stands for a trial split at `trial`.
    fn template_quality_with(
        &self,
        body: &Body,
        t: [u32; 3],
        splits: [Option<u32>; 3],
        diagonal_from_first: bool,
        trial: Vec3,
    ) -> f64 {
        let (children, count) = template_children(t, splits, diagonal_from_first);
        let rest = |v: u32| {
            if v == u32::MAX - 1 {
                trial
            } else {
                self.rest_of(body, v)
            }
        };
        children[..count]
            .iter()
            .map(|c| min_angle_deg(&c.map(rest)))
            .fold(180.0, f64::min)
    }

    /// The smallest angle of the best template of affected triangle `a` that keeps its path.
    fn best_template_quality(&self, body: &Body, a: &Affected) -> f64 {
        let splits = self.splits_of(a.crossing);
        [true, false]
            .map(|d| {
                let keeps = a
                    .path
                    .is_none_or(|(p, q)| edge_in_template(a.corners, splits, d, p, q));
                if keeps {
                    self.template_quality(body, a.corners, splits, d)
                } else {
                    -1.0
                }
            })
            .into_iter()
            .fold(-1.0, f64::max)
    }

    /// Snaps a path split whose templates stay below the quality bound to the nearer end of its edge
    /// when that end lies within the fidelity tolerance of the *local* edge length (the longest side
    /// of the triangles the crossing is on) from the swept quad: a path that passes just beyond an
    /// edge's own snapping distance of a node, across longer triangles, leaves a short edge at
    /// that node with a needle on each side; going through the node keeps the lips as close to the
    /// blade as the fidelity bound asks. Returns whether any snapped.
    fn snap_for_quality(&mut self, body: &Body, quad: &[Vec3; 4]) -> bool {
        let bound = self.quality_bound_deg;
        let mut snapped = false;
        for i in 0..self.affected.len() {
            let a = self.affected[i];
            if self.best_template_quality(body, &a) >= bound {
                continue;
            }
            for c in a.crossing.iter().flatten().map(|c| *c as usize) {
                let crossing = self.crossings[c];
                if !matches!(crossing.choice, Choice::Split) || !crossing.on_path {
                    continue;
                }
                // The longest rest side of the triangles on the crossing's edge.
                let h = &body.surface.homologue_in_body;
                let local = self
                    .affected
                    .iter()
                    .filter(|t| t.crossing.contains(&Some(c as u16)))
                    .flat_map(|t| {
                        let r = t.corners.map(|v| h[v as usize]);
                        [
                            (r[1] - r[0]).norm(),
                            (r[2] - r[1]).norm(),
                            (r[0] - r[2]).norm(),
                        ]
                    })
                    .fold(0.0, f64::max);
                let tol = self.tolerance(local);
                // Each end's distance from the sweep: in the world, or in rest coordinates along
                // the edge from where the blade crossed it (that point is on the swept surface as
                // the rest shape maps it; in a deformed body the two differ, and the fidelity
                // bound is the rest one).
                let x = &body.surface.position_in_world;
                let rest = (h[crossing.a as usize] - h[crossing.b as usize]).norm();
                let (da, db) = (
                    quad_distance(&x[crossing.a as usize], quad).min(crossing.crossed * rest),
                    quad_distance(&x[crossing.b as usize], quad)
                        .min((1.0 - crossing.crossed) * rest),
                );
                let (v, d) = if da <= db {
                    (crossing.a, da)
                } else {
                    (crossing.b, db)
                };
                if d > tol {
                    continue;
                }
                self.crossings[c].choice = Choice::Snap(v);
                self.crossings[c].node = v;
                snapped = true;
            }
        }
        snapped
    }

    /// Slides the path's split nodes along their edges, within ¾ of the fidelity tolerance of the
    /// swept quad, where that raises the smallest angle of the templates around them: a path that
    /// cuts a corner off just beyond the snapping distance leaves a short edge, and moving its ends
    /// apart is what keeps the triangles on it from being needles. Returns whether any moved.
    fn slide_splits(&mut self, body: &Body, quad: &[Vec3; 4]) -> bool {
        let bound = self.quality_bound_deg;
        let n = body.node_count() as u32;
        let mut moved = false;
        for i in 0..self.affected.len() {
            let a = self.affected[i];
            if self.best_template_quality(body, &a) >= bound {
                continue;
            }
            for c in a.crossing.iter().flatten().map(|c| *c as usize) {
                let crossing = self.crossings[c];
                if !matches!(crossing.choice, Choice::Split) {
                    continue;
                }
                // Round a crossing the triangles' floors differ (a parent already below the
                // bound), the margins over them rank the places; elsewhere the smallest angle
                // alone, as the margins would.
                let mixed = self
                    .affected
                    .iter()
                    .filter(|t| t.crossing.contains(&Some(c as u16)))
                    .any(|t| {
                        let h = &body.surface.homologue_in_body;
                        min_angle_deg(&t.corners.map(|v| h[v as usize])) < bound
                    });
                let x = &body.surface.position_in_world;
                let h = &body.surface.homologue_in_body;
                let (ia, ib) = (crossing.a as usize, crossing.b as usize);
                let slot = (crossing.node - n) as usize;
                let reach = 0.75 * self.tolerance(body.edges.rest_length[crossing.edge as usize]);
                // With the flips that follow the templates foreseen: a path from a corner whose
                // angle is below twice the bound leaves one side of it below the bound wherever
                // the split is, and the side a flip can mend is the one to give the small angle.
                let quality_at = |cutter: &Self| {
                    let round = cutter
                        .affected
                        .iter()
                        .filter(|t| t.crossing.contains(&Some(c as u16)));
                    if mixed {
                        return round
                            .map(|t| {
                                cutter.template_quality_after_flips(body, t)
                                    - cutter.floor_of(body, t.corners)
                            })
                            .fold(f64::INFINITY, f64::min);
                    }
                    round
                        .map(|t| cutter.template_quality_after_flips(body, t))
                        .fold(180.0, f64::min)
                };
                let mut best = (quality_at(self), crossing.t);
                for k in 1..=SLIDE_STEPS {
                    for sign in [-1.0, 1.0] {
                        let t = crossing.t + sign * k as f64 * SLIDE_STEP;
                        if !(SLIDE_RANGE.0..=SLIDE_RANGE.1).contains(&t) {
                            continue;
                        }
                        if crossing.on_path
                            && quad_distance(&(x[ia] * (1.0 - t) + x[ib] * t), quad) > reach
                        {
                            continue;
                        }
                        self.split_rest[slot] = h[ia] * (1.0 - t) + h[ib] * t;
                        let q = quality_at(self);
                        if q > best.0 + 1e-9 {
                            best = (q, t);
                        }
                    }
                }
                let t = best.1;
                self.split_rest[slot] = h[ia] * (1.0 - t) + h[ib] * t;
                if t != crossing.t {
                    self.crossings[c].t = t;
                    moved = true;
                }
            }
        }
        moved
    }

    /// [`Cutter::best_template_quality`] with each child below the bound taken at the smallest angle
    /// a flip of one of its sides would give it: a side that is a side of the parent (not on the
    /// path) with an unchanged triangle across it, flipped to the child's third corner when that
    /// corner is a planned split node (so no spring joins the two yet) and the flip is one
    /// `flip_for_quality` would make (rest normals that agree, the pair's smallest angle raised).
    fn template_quality_after_flips(&self, body: &Body, a: &Affected) -> f64 {
        let bound = self.quality_bound_deg;
        let splits = self.splits_of(a.crossing);
        let n = body.node_count() as u32;
        let rest = |v: u32| self.rest_of(body, v);
        let mended = |child: [u32; 3]| {
            let quality = min_angle_deg(&child.map(rest));
            if quality >= bound {
                return quality;
            }
            let mut best = quality;
            for k in 0..3 {
                let (u, v, c) = (child[k], child[(k + 1) % 3], child[(k + 2) % 3]);
                if u >= n
                    || v >= n
                    || c < n
                    || a.path
                        .is_some_and(|(p, q)| (p == u && q == v) || (p == v && q == u))
                {
                    continue;
                }
                let Some(across) = self.affected.iter().find(|t| {
                    t.crossing.iter().all(Option::is_none)
                        && t.path.is_none()
                        && (0..3).any(|j| t.corners[j] == v && t.corners[(j + 1) % 3] == u)
                }) else {
                    continue;
                };
                let Some(w) = across.corners.iter().copied().find(|&x| x != u && x != v) else {
                    continue;
                };
                if let Some(after) = flip_gain(rest, child, across.corners, k, w) {
                    best = best.max(after);
                }
            }
            best
        };
        [true, false]
            .map(|d| {
                if !a
                    .path
                    .is_none_or(|(p, q)| edge_in_template(a.corners, splits, d, p, q))
                {
                    return -1.0;
                }
                let (children, count) = template_children(a.corners, splits, d);
                children[..count]
                    .iter()
                    .map(|&child| mended(child))
                    .fold(180.0, f64::min)
            })
            .into_iter()
            .fold(-1.0, f64::max)
    }

    /// The smallest margin of the best templates of the affected triangles round crossing `c` over
    /// their quality floors (the bound, or a parent's smallest angle below it).
    fn margin_round(&self, body: &Body, c: usize) -> f64 {
        self.affected
            .iter()
            .filter(|t| t.crossing.contains(&Some(c as u16)))
            .map(|t| {
                let floor = self.floor_of(body, t.corners);
                self.best_template_quality(body, t) - floor
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// The template of affected triangle `a` with path `(p, q)`: the smallest angle of the better
    /// diagonal that holds the path, and that diagonal (`None` when neither does).
    fn template_keeping(&self, body: &Body, a: &Affected, p: u32, q: u32) -> Option<(f64, bool)> {
        let splits = self.splits_of(a.crossing);
        [true, false]
            .into_iter()
            .filter(|&d| edge_in_template(a.corners, splits, d, p, q))
            .map(|d| (self.template_quality(body, a.corners, splits, d), d))
            .fold(None, |best: Option<(f64, bool)>, (q, d)| match best {
                Some((b, _)) if b >= q => best,
                _ => Some((q, d)),
            })
    }

    /// Where a triangle's path runs from a corner `p` to a split `q` on the opposite side so close
    /// along a side of `p` that its template stays below its floor, and a split made for quality
    /// sits on that side within ¾ of the tolerance of the sweep, the path goes from `p` along the
    /// side to that split and on to `q` (the triangle across the side, which had no path, takes the
    /// first leg) when that raises the smallest margin of the two triangles over their floors.
    fn promote_quality_splits(&mut self, body: &Body, quad: &[Vec3; 4]) {
        for i in 0..self.affected.len() {
            let t = self.affected[i];
            let Some((u, w)) = t.path else {
                continue;
            };
            // p a corner of the triangle, q a split on the opposite side.
            let (p, q) = if t.corners.contains(&u) {
                (u, w)
            } else {
                (w, u)
            };
            if !t.corners.contains(&p) || t.corners.contains(&q) {
                continue;
            }
            let floor_t = self.floor_of(body, t.corners);
            let Some((old_t, _)) = self.template_keeping(body, &t, p, q) else {
                continue;
            };
            if old_t >= floor_t {
                continue;
            }
            for side in 0..3 {
                let Some(cs) = t.crossing[side] else {
                    continue;
                };
                let (a, b) = (t.corners[side], t.corners[(side + 1) % 3]);
                let crossing = self.crossings[cs as usize];
                if (a != p && b != p)
                    || crossing.on_path
                    || !matches!(crossing.choice, Choice::Split)
                {
                    continue;
                }
                // Near the sweep: in the world, or in rest coordinates from the segment between
                // the path's two points (which lies in the swept surface as the rest shape maps
                // it, to within their own distance from it: half the tolerance is left for that).
                let x = &body.surface.position_in_world;
                let at = x[crossing.a as usize] * (1.0 - crossing.t)
                    + x[crossing.b as usize] * crossing.t;
                let tol = self.tolerance(body.edges.rest_length[crossing.edge as usize]);
                let (rp, rq, rs) = (
                    self.rest_of(body, p),
                    self.rest_of(body, q),
                    self.rest_of(body, crossing.node),
                );
                let along =
                    (rq - rp).dot(&(rs - rp)) / (rq - rp).norm_squared().max(f64::MIN_POSITIVE);
                let from_path = (rs - (rp + (rq - rp) * along.clamp(0.0, 1.0))).norm();
                if quad_distance(&at, quad) > 0.75 * tol && from_path > 0.5 * tol {
                    continue;
                }
                let Some(j) = (0..self.affected.len())
                    .find(|&j| j != i && self.affected[j].crossing.contains(&Some(cs)))
                else {
                    continue;
                };
                let n = self.affected[j];
                if n.path.is_some() {
                    continue;
                }
                let floor_n = self.floor_of(body, n.corners);
                let splits_n = self.splits_of(n.crossing);
                let old_n = self.template_quality(body, n.corners, splits_n, n.diagonal_from_first);
                let sn = crossing.node;
                let (Some((new_t, dt)), Some((new_n, dn))) = (
                    self.template_keeping(body, &t, sn, q),
                    self.template_keeping(body, &n, p, sn),
                ) else {
                    continue;
                };
                let before = (old_t - floor_t).min(old_n - floor_n);
                let after = (new_t - floor_t).min(new_n - floor_n);
                if after <= before + 1e-9 {
                    continue;
                }
                self.crossings[cs as usize].on_path = true;
                self.affected[i].path = Some((sn.min(q), sn.max(q)));
                self.affected[i].diagonal_from_first = dt;
                self.affected[j].path = Some((p.min(sn), p.max(sn)));
                self.affected[j].diagonal_from_first = dn;
                self.counters.quality_splits_on_path += 1;
                break;
            }
        }
    }

    /// Removes the first split made for quality (off the path) whose triangles' best templates
    /// stay further above their floors without it; returns whether one went.
    fn drop_needless_split(&mut self, body: &Body) -> bool {
        for c in 0..self.crossings.len() {
            let crossing = self.crossings[c];
            if crossing.on_path || !matches!(crossing.choice, Choice::Split) {
                continue;
            }
            let with = self.margin_round(body, c);
            if with >= 0.0 {
                continue;
            }
            // Off the path, a snap is no split and no path point: the templates as without it.
            self.crossings[c].choice = Choice::Snap(crossing.a);
            let without = self.margin_round(body, c);
            self.crossings[c].choice = Choice::Split;
            if without > with + 1e-9 {
                self.crossings.remove(c);
                self.counters.quality_splits_dropped += 1;
                return true;
            }
        }
        false
    }

    /// Adds a middle split on the unsplit edge of every two-split triangle whose best template is
    /// below the quality bound; returns whether any was added.
    fn add_quality_splits(&mut self, body: &Body) -> bool {
        let mut added = false;
        for i in 0..self.affected.len() {
            let a = self.affected[i];
            let splits = self.splits_of(a.crossing);
            let count = splits.iter().filter(|s| s.is_some()).count();
            if count == 0 || count == 3 {
                continue;
            }
            let quality = self.template_quality(body, a.corners, splits, a.diagonal_from_first);
            if quality >= self.quality_bound_deg {
                continue;
            }
            // Where to split an unsplit edge: the edge and fraction (near its middle) that give
            // this triangle the best smallest angle.
            let mut best = (-1.0, 0usize, 0.5);
            for candidate in 0..3 {
                if splits[candidate].is_some() {
                    continue;
                }
                let (u, v) = (a.corners[candidate], a.corners[(candidate + 1) % 3]);
                let mut trial = splits;
                trial[candidate] = Some(u32::MAX - 1);
                for along in QUALITY_FRACTIONS {
                    let point =
                        self.rest_of(body, u) * (1.0 - along) + self.rest_of(body, v) * along;
                    // Only templates that keep the path through this triangle.
                    let q = [true, false]
                        .map(|d| {
                            let keeps = a
                                .path
                                .is_none_or(|(p, q)| edge_in_template(a.corners, trial, d, p, q));
                            if keeps {
                                self.template_quality_with(body, a.corners, trial, d, point)
                            } else {
                                -1.0
                            }
                        })
                        .into_iter()
                        .fold(-1.0, f64::max);
                    if q > best.0 {
                        best = (q, candidate, along);
                    }
                }
            }
            let (q, k, along) = best;
            if q <= quality {
                continue;
            }
            let (u, v) = (a.corners[k], a.corners[(k + 1) % 3]);
            if self.crossing_on(u, v).is_some() || self.crossings.len() == MAX_CROSSINGS {
                continue;
            }
            let Some(edge) = self.edge_between(body, u, v) else {
                continue;
            };
            self.crossings.push(Crossing {
                a: u,
                b: v,
                edge: edge as u32,
                t: along,
                crossed: along,
                choice: Choice::Split,
                node: u32::MAX,
                on_path: false,
            });
            added = true;
        }
        added
    }

    /// Appends the node of crossing `c` on its edge and cuts the edge's spring in two in series.
    fn split_edge(&mut self, body: &mut Body, c: usize) {
        let Crossing { a, b, edge, t, .. } = self.crossings[c];
        let nu = body.params.air_viscosity;
        let s = &mut body.surface;
        let (ia, ib) = (a as usize, b as usize);
        let w = [1.0 - t, t];
        let fractions = mass_fractions(w, [s.mass[ia], s.mass[ib]]);
        let taken = [fractions[0] * s.mass[ia], fractions[1] * s.mass[ib]];
        let mass = taken[0] + taken[1];
        let weighted = |v: &[Vec3]| (v[ia] * taken[0] + v[ib] * taken[1]) / mass;
        let k_link = s.link_stiffness[ia] * fractions[0] + s.link_stiffness[ib] * fractions[1];
        let c_link = s.link_damping[ia] * fractions[0] + s.link_damping[ib] * fractions[1];
        for (idx, i) in [ia, ib].into_iter().enumerate() {
            s.mass[i] -= taken[idx];
            s.inverse_mass[i] = 1.0 / s.mass[i];
            s.air_damping[i] = nu * s.mass[i];
            s.link_stiffness[i] *= 1.0 - fractions[idx];
            s.link_damping[i] *= 1.0 - fractions[idx];
        }
        // The node is where the blade crossed the edge (MODEL.md §6: at the point itself), so a
        // straight spring cut in two keeps its energy; its velocity is that of the mass it takes
        // (momentum kept, kinetic energy not raised).
        let at = |v: &[Vec3]| v[ia] * w[0] + v[ib] * w[1];
        s.push_node(
            NewNode {
                position_in_world: at(&s.position_in_world),
                next_position_in_world: at(&s.next_position_in_world),
                velocity_in_world: weighted(&s.velocity_in_world),
                mass,
                homologue_in_body: s.homologue_in_body[ia] * w[0] + s.homologue_in_body[ib] * w[1],
                homologue_in_world: s.homologue_in_world[ia] * w[0]
                    + s.homologue_in_world[ib] * w[1],
                plastic_offset_in_body: s.plastic_offset_in_body[ia] * w[0]
                    + s.plastic_offset_in_body[ib] * w[1],
                link_stiffness: k_link,
                link_damping: c_link,
            },
            nu,
        );
        let p = (body.node_count() - 1) as u32;
        debug_assert_eq!(p, self.crossings[c].node);
        let e = &mut body.edges;
        let k = edge as usize;
        let (rest, stiffness, damping) = (e.rest_length[k], e.stiffness[k], e.damping[k]);
        // Edge k keeps its end `e.a[k]`; the other half is a new spring.
        let (near, far, t_near) = if e.a[k] == a {
            (a, b, t)
        } else {
            (b, a, 1.0 - t)
        };
        e.a[k] = near;
        e.b[k] = p;
        e.rest_length[k] = rest * t_near;
        e.stiffness[k] = stiffness / t_near;
        e.damping[k] = damping / t_near;
        let t_far = 1.0 - t_near;
        e.push(p, far, rest * t_far, stiffness / t_far, damping / t_far);
        self.changes.edge(k as u32);
        self.edge_changed(body, (body.edges.len() - 1) as u32);
        // A boundary edge split gives two boundary edges.
        if self.edge_is_boundary(a, b) {
            body.boundary_edges += 1;
        }
    }

    /// Whether edge (a, b) has one triangle (read from the affected triangles, which hold every
    /// triangle of a crossed edge).
    fn edge_is_boundary(&self, a: u32, b: u32) -> bool {
        let users = self
            .affected
            .iter()
            .filter(|t| {
                let c = t.corners;
                (0..3).any(|k| {
                    (c[k] == a && c[(k + 1) % 3] == b) || (c[k] == b && c[(k + 1) % 3] == a)
                })
            })
            .count();
        users == 1
    }

    /// Replaces an affected triangle by its template children and adds their inner edges.
    fn apply_template(&mut self, body: &mut Body, a: &Affected, prestress: f64) {
        let splits = self.splits_of(a.crossing);
        if splits.iter().all(Option::is_none) {
            return;
        }
        let mut children = [[0u32; 3]; 4];
        let mut inner = [(0u32, 0u32); 3];
        let (count, inner_count) = template(
            a.corners,
            splits,
            a.diagonal_from_first,
            &mut children,
            &mut inner,
        );
        let floor = self.floor_of(body, a.corners);
        let triangles = &mut body.surface.triangles;
        triangles[a.triangle as usize] = children[0];
        self.created.push((a.triangle, floor));
        for child in &children[1..count] {
            self.created.push((triangles.len() as u32, floor));
            triangles.push(*child);
        }
        // A child lies within its parent's rest box: only the new ones are told to the index.
        let first_new = body.surface.triangles.len() - (count - 1);
        for t in first_new..body.surface.triangles.len() {
            self.triangle_changed(body, t as u32);
        }
        let (k, c) = (body.params.surface_stiffness, body.params.surface_damping);
        for &(u, v) in &inner[..inner_count] {
            let h = &body.surface.homologue_in_body;
            let rest = (h[u as usize] - h[v as usize]).norm() * (1.0 - prestress);
            body.edges.push(u, v, rest, k, c);
            self.edge_changed(body, (body.edges.len() - 1) as u32);
        }
    }

    /// Flips inner edges (not on the path, not on a boundary, not across a crease) of the created
    /// triangles below the quality bound when the flip raises the smallest angle of the two
    /// triangles sharing the edge; the flipped spring takes the new edge's rest length. A few rounds.
    fn flip_for_quality(&mut self, body: &mut Body, prestress: f64) {
        let bound = self.quality_bound_deg;
        for _round in 0..FLIP_ROUNDS {
            let mut flipped = false;
            for i in 0..self.created.len() {
                let index = self.created[i].0 as usize;
                let t = body.surface.triangles[index];
                let h = &body.surface.homologue_in_body;
                let rest = |v: u32| h[v as usize];
                let quality = min_angle_deg(&t.map(rest));
                if quality >= bound {
                    continue;
                }
                // The best flip among the triangle's three edges: (new quality, edge, neighbour, w).
                let mut best: Option<(f64, usize, usize, u32)> = None;
                for k in 0..3 {
                    let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
                    if self.path_edges.contains(&(a.min(b), a.max(b))) {
                        continue;
                    }
                    // The triangle across a→b (b→a in it), and whether one already joins c to w.
                    let across = |u: &[u32; 3]| (0..3).any(|j| u[j] == b && u[(j + 1) % 3] == a);
                    let found = match self.index_for(body) {
                        Some(index) => index.first_triangle_at(body, a, across),
                        None => body.surface.triangles.iter().position(across),
                    };
                    let Some(n) = found else {
                        continue;
                    };
                    let triangles = &body.surface.triangles;
                    let u = triangles[n];
                    let w = u.iter().copied().find(|&v| v != a && v != b).unwrap_or(a);
                    if w == a || w == c {
                        continue;
                    }
                    let joined = |u: &[u32; 3]| u.contains(&c) && u.contains(&w);
                    let exists = match self.index_for(body) {
                        Some(index) => index.first_triangle_at(body, c, joined).is_some(),
                        None => body.surface.triangles.iter().any(joined),
                    };
                    if exists {
                        continue;
                    }
                    if let Some(after) = flip_gain(rest, t, u, k, w)
                        && best.is_none_or(|(q, ..)| after > q)
                    {
                        best = Some((after, k, n, w));
                    }
                }
                let Some((_, k, n, w)) = best else {
                    continue;
                };
                let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
                let Some(edge) = self.edge_between(body, a, b) else {
                    continue;
                };
                let h = &body.surface.homologue_in_body;
                let length = (h[c as usize] - h[w as usize]).norm() * (1.0 - prestress);
                let neighbour_floor = self.quality_bound_deg.min(min_angle_deg(
                    &body.surface.triangles[n].map(|v| h[v as usize]),
                ));
                let (stiffness, damping) =
                    (body.params.surface_stiffness, body.params.surface_damping);
                let e = &mut body.edges;
                e.a[edge] = c.min(w);
                e.b[edge] = c.max(w);
                e.rest_length[edge] = length;
                e.stiffness[edge] = stiffness;
                e.damping[edge] = damping;
                let triangles = &mut body.surface.triangles;
                triangles[index] = [a, w, c];
                triangles[n] = [w, b, c];
                self.triangle_changed(body, index as u32);
                self.triangle_changed(body, n as u32);
                self.edge_changed(body, edge as u32);
                // The two triangles replace two: both are held to the lower floor of those (the
                // neighbour's own smallest angle where the cut did not create it). The flip raised
                // the smallest angle of the pair; a pair that had a triangle below the bound
                // before the cut need not come above it.
                let created_at = self.created.iter().position(|&(t, _)| t == n as u32);
                let pair_floor = self.created[i]
                    .1
                    .min(created_at.map_or(neighbour_floor, |at| self.created[at].1));
                self.created[i].1 = pair_floor;
                match created_at {
                    Some(at) => self.created[at].1 = pair_floor,
                    None if self.created.len() < MAX_CREATED => {
                        self.created.push((n as u32, pair_floor));
                    }
                    None => {}
                }
                flipped = true;
            }
            if !flipped {
                break;
            }
        }
    }

    fn collect_tips(&mut self, tool: usize) {
        let Some(tips) = self.tips.get_mut(tool) else {
            return;
        };
        // The tips this blade left before: a blade may have several fronts (the near and far side
        // of a tube), each crossing edges on ticks of its own; a tip the path went on from this
        // step is used up.
        let before = tips.clone();
        tips.clear();
        for a in &self.affected {
            if a.path.is_some() {
                continue;
            }
            for c in a.crossing.iter().flatten() {
                let c = &self.crossings[*c as usize];
                if c.on_path {
                    tips.push(c.node);
                }
            }
        }
        for &v in &before.nodes[..before.len] {
            // A slit waiting to open (pending) is the path that led to the tip, not a way on.
            let used = self.affected.iter().any(|a| {
                a.path.is_some_and(|(p, q)| {
                    (p == v || q == v) && !self.pending.contains(&(p.min(q), p.max(q)))
                })
            });
            if !used {
                tips.push(v);
            }
        }
        // A tip the path went through is no longer a tip.
        let mut kept = Tips::default();
        for &v in &tips.nodes[..tips.len] {
            let through = self
                .path_edges
                .iter()
                .filter(|(p, q)| *p == v || *q == v)
                .count();
            if through < 2 {
                kept.push(v);
            }
        }
        *tips = kept;
    }

    /// Keeps the path edges that are still whole edges of the mesh (two triangles on the same two
    /// nodes) for the next steps, within the pending list's room (the newest kept).
    fn keep_pending(&mut self, body: &Body) {
        self.pending.clear();
        let room = self.pending.capacity();
        let skip = self.path_edges.len().saturating_sub(room);
        for &(p, q) in &self.path_edges[skip..] {
            let range = fan_range(&self.fan, p);
            let users = if range.is_empty() {
                0
            } else {
                self.fan[range]
                    .iter()
                    .filter(|(_, t)| {
                        let t = body.surface.triangles[*t as usize];
                        t.contains(&p) && t.contains(&q)
                    })
                    .count()
            };
            if users == 2 {
                self.pending.push((p, q));
            }
        }
    }

    /// Opens the path edges: copies nodes whose triangles fall apart into groups, and splits the
    /// opened springs into lips. Returns (copies, opened edges).
    fn open(&mut self, body: &mut Body) -> (u32, u32) {
        if self.path_edges.is_empty() {
            return (0, 0);
        }
        self.fan.clear();
        let stamp = self.next_stamp();
        for &(p, q) in &self.path_edges {
            self.cut_stamp[p as usize] = stamp;
            self.cut_stamp[q as usize] = stamp;
        }
        // Fans: (node, triangle) for every corner on the path, sorted: from the index round each
        // node of the path, or from a pass over the triangles.
        self.fan.clear();
        self.path_nodes.clear();
        for &(p, q) in &self.path_edges {
            for v in [p, q] {
                if self.path_nodes.len() < self.path_nodes.capacity() {
                    self.path_nodes.push(v);
                }
            }
        }
        self.path_nodes.sort_unstable();
        self.path_nodes.dedup();
        let indexed = self.index.as_ref().is_some_and(|i| i.is_valid_for(body))
            && self.path_nodes.len() < self.path_nodes.capacity();
        if indexed {
            let index = self.index.as_mut().expect("indexed");
            let h = &body.surface.homologue_in_body;
            for &v in &self.path_nodes {
                let mark = index.begin();
                let at = RestIndex::point(&h[v as usize]);
                index.collect_triangles(body, &at, mark, |_, t| t.contains(&v));
                for &t in &index.found {
                    if self.fan.len() < FAN_ROOM {
                        self.fan.push((v, t));
                    }
                }
            }
        } else {
            for (index, t) in body.surface.triangles.iter().enumerate() {
                for &v in t {
                    if self.cut_stamp[v as usize] == stamp && self.fan.len() < FAN_ROOM {
                        self.fan.push((v, index as u32));
                    }
                }
            }
        }
        self.fan.sort_unstable();
        let n_before = body.node_count();
        self.copy_origin.clear();
        self.copies.clear();
        let mut copies = 0;
        let mut start = 0;
        while start < self.fan.len() {
            let v = self.fan[start].0;
            let mut end = start;
            while end < self.fan.len() && self.fan[end].0 == v {
                end += 1;
            }
            if end - start <= MAX_FAN {
                copies += self.split_fan(body, v, start, end);
            }
            start = end;
        }
        // Springs around copied nodes: each follows its triangles; an opened one becomes two lips.
        let mut opened = 0;
        if copies > 0 {
            let n_after = body.node_count();
            let edge_count = body.edges.len();
            // The springs with an end on the path: from the index round each node of the path
            // (copies sit on their origin's rest place), or all of them.
            if indexed {
                let index = self.index.as_mut().expect("indexed");
                let h = &body.surface.homologue_in_body;
                let marks = &self.cut_stamp;
                let mark = index.begin();
                for &v in &self.path_nodes {
                    let at = RestIndex::point(&h[v as usize]);
                    index.collect_edges(body, &at, mark, |_, a, b| {
                        marks[a as usize] == stamp || marks[b as usize] == stamp
                    });
                }
                index.finish();
            }
            let count = if indexed {
                self.index.as_ref().expect("indexed").found.len()
            } else {
                edge_count
            };
            for i in 0..count {
                let k = if indexed {
                    self.index.as_ref().expect("indexed").found[i] as usize
                } else {
                    i
                };
                let (a, b) = (body.edges.a[k], body.edges.b[k]);
                let touched =
                    self.cut_stamp[a as usize] == stamp || self.cut_stamp[b as usize] == stamp;
                if !touched {
                    continue;
                }
                let mut pairs = [(u32::MAX, u32::MAX); 2];
                let mut found = 0;
                let fan_node = if self.cut_stamp[a as usize] == stamp {
                    a
                } else {
                    b
                };
                let range = fan_range(&self.fan, fan_node);
                for &(_, tri) in &self.fan[range] {
                    let t = body.surface.triangles[tri as usize];
                    let origin = |w: u32| -> u32 {
                        if (w as usize) >= n_before && (w as usize) < n_after {
                            self.copy_origin[w as usize - n_before]
                        } else {
                            w
                        }
                    };
                    let ca = t.iter().copied().find(|&w| origin(w) == a);
                    let cb = t.iter().copied().find(|&w| origin(w) == b);
                    if let (Some(ca), Some(cb)) = (ca, cb)
                        && found < 2
                    {
                        pairs[found] = (ca, cb);
                        found += 1;
                    }
                }
                if found == 0 {
                    continue;
                }
                body.edges.a[k] = pairs[0].0;
                body.edges.b[k] = pairs[0].1;
                self.changes.edge(k as u32);
                if found == 2 && pairs[0] != pairs[1] {
                    let e = &mut body.edges;
                    e.stiffness[k] *= 0.5;
                    e.damping[k] *= 0.5;
                    let (rest, stiffness, damping) =
                        (e.rest_length[k], e.stiffness[k], e.damping[k]);
                    e.push(pairs[1].0, pairs[1].1, rest, stiffness, damping);
                    self.edge_changed(body, (body.edges.len() - 1) as u32);
                    opened += 1;
                    body.boundary_edges += 2;
                }
            }
        }
        (copies, opened)
    }

    /// Groups the triangles around `v` (fan entries `start..end`) by the edges that stay whole and
    /// gives every group but the first a copy of `v`. Returns the copies made.
    #[allow(clippy::needless_range_loop)] // fixed-size arrays indexed together
    fn split_fan(&mut self, body: &mut Body, v: u32, start: usize, end: usize) -> u32 {
        let count = end - start;
        let mut parent = [0usize; MAX_FAN];
        for (i, p) in parent.iter_mut().enumerate().take(count) {
            *p = i;
        }
        fn find(parent: &mut [usize; MAX_FAN], mut i: usize) -> usize {
            while parent[i] != i {
                parent[i] = parent[parent[i]];
                i = parent[i];
            }
            i
        }
        let tris = &body.surface.triangles;
        for i in 0..count {
            let ti = tris[self.fan[start + i].1 as usize];
            for j in i + 1..count {
                let tj = tris[self.fan[start + j].1 as usize];
                // Shared edge (v, w), w ≠ v, whole unless it is on the path.
                for &w in &ti {
                    if w == v || !tj.contains(&w) {
                        continue;
                    }
                    let pair = (v.min(w), v.max(w));
                    if !self.path_edges.contains(&pair) {
                        let (ri, rj) = (find(&mut parent, i), find(&mut parent, j));
                        if ri != rj {
                            parent[ri.max(rj)] = ri.min(rj);
                        }
                    }
                }
            }
        }
        let mut roots = [usize::MAX; MAX_FAN];
        let mut groups = 0;
        let mut group_of = [0usize; MAX_FAN];
        for i in 0..count {
            let r = find(&mut parent, i);
            let g = match roots[..groups].iter().position(|&x| x == r) {
                Some(g) => g,
                None => {
                    roots[groups] = r;
                    groups += 1;
                    groups - 1
                }
            };
            group_of[i] = g;
        }
        if groups < 2 {
            return 0;
        }
        // Rest area of each group: mass and link shares.
        let mut area = [0.0f64; MAX_FAN];
        let h = &body.surface.homologue_in_body;
        for i in 0..count {
            let t = tris[self.fan[start + i].1 as usize];
            let [a, b, c] = t.map(|w| h[w as usize]);
            area[group_of[i]] += 0.5 * (b - a).cross(&(c - a)).norm();
        }
        // Each group's share: its rest area's, but at least MIN_COPY_SHARE of the node before the
        // shares are normalised — a copy on a sliver of the fan would otherwise be so light that
        // no integrator's step could hold its springs.
        let total: f64 = area[..groups].iter().sum();
        if total > 0.0 {
            for a in &mut area[..groups] {
                *a = (*a / total).max(MIN_COPY_SHARE);
            }
        }
        let total: f64 = area[..groups].iter().sum();
        let iv = v as usize;
        let nu = body.params.air_viscosity;
        let (m, k_link, c_link) = {
            let s = &body.surface;
            (s.mass[iv], s.link_stiffness[iv], s.link_damping[iv])
        };
        let mut given = 0.0;
        let mut given_k = 0.0;
        let mut given_c = 0.0;
        for g in 1..groups {
            let share = if total > 0.0 {
                area[g] / total
            } else {
                1.0 / groups as f64
            };
            let (mass, k, c) = (m * share, k_link * share, c_link * share);
            given += mass;
            given_k += k;
            given_c += c;
            let s = &mut body.surface;
            let copy_of_v = NewNode {
                position_in_world: s.position_in_world[iv],
                next_position_in_world: s.next_position_in_world[iv],
                velocity_in_world: s.velocity_in_world[iv],
                mass,
                homologue_in_body: s.homologue_in_body[iv],
                homologue_in_world: s.homologue_in_world[iv],
                plastic_offset_in_body: s.plastic_offset_in_body[iv],
                link_stiffness: k,
                link_damping: c,
            };
            s.push_node(copy_of_v, nu);
            let copy = (body.node_count() - 1) as u32;
            self.copy_origin.push(v);
            self.copies.push(copy);
            for i in 0..count {
                if group_of[i] == g {
                    let tri = &mut body.surface.triangles[self.fan[start + i].1 as usize];
                    for w in tri.iter_mut() {
                        if *w == v {
                            *w = copy;
                        }
                    }
                }
            }
        }
        let s = &mut body.surface;
        s.mass[iv] = m - given;
        s.inverse_mass[iv] = 1.0 / s.mass[iv];
        s.air_damping[iv] = nu * s.mass[iv];
        s.link_stiffness[iv] = k_link - given_k;
        s.link_damping[iv] = c_link - given_c;
        (groups - 1) as u32
    }
}

/// The fan entries of node `v` (the fan is sorted by node).
/// The smallest angle of the two triangles a flip of side `k` of triangle `t` (from corner `k` to
/// corner `k + 1`) makes with the triangle `across` it, whose third corner is `w`, when the flip is
/// one to make (rest places from `rest`): the rest normals of the two triangles and of the two new
/// ones agree (no flip across a crease, none that folds: a degenerate triangle's NaN normal agrees
/// with nothing) and the pair's smallest angle rises.
fn flip_gain(
    rest: impl Fn(u32) -> Vec3,
    t: [u32; 3],
    across: [u32; 3],
    k: usize,
    w: u32,
) -> Option<f64> {
    let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
    let normal = |tri: [u32; 3]| {
        let [p, q, r] = tri.map(&rest);
        (q - p).cross(&(r - p)).normalize()
    };
    let (old_t, old_n) = (normal(t), normal(across));
    let (new_1, new_2) = ([a, w, c], [w, b, c]);
    let (n1, n2) = (normal(new_1), normal(new_2));
    let agree = [
        old_t.dot(&old_n) - FLIP_FLATNESS,
        n1.dot(&n2),
        n1.dot(&old_t),
        n1.dot(&old_n),
        n2.dot(&old_t),
        n2.dot(&old_n),
    ];
    if agree.iter().any(|d| d.is_nan() || *d <= 0.0) {
        return None;
    }
    let before = min_angle_deg(&t.map(&rest)).min(min_angle_deg(&across.map(&rest)));
    let after = min_angle_deg(&new_1.map(&rest)).min(min_angle_deg(&new_2.map(&rest)));
    (after > before + 1e-9).then_some(after)
}

fn fan_range(fan: &[(u32, u32)], v: u32) -> std::ops::Range<usize> {
    let start = fan.partition_point(|&(w, _)| w < v);
    let end = fan.partition_point(|&(w, _)| w <= v);
    start..end
}

/// The children of triangle `t` with split nodes `splits` on its edges (0,1), (1,2), (2,0), in its
/// orientation, and the inner edges they add. Returns (children, inner edges).
fn template(
    t: [u32; 3],
    splits: [Option<u32>; 3],
    diagonal_from_first: bool,
    children: &mut [[u32; 3]; 4],
    inner: &mut [(u32, u32); 3],
) -> (usize, usize) {
    let count = splits.iter().filter(|s| s.is_some()).count();
    match count {
        0 => {
            children[0] = t;
            (1, 0)
        }
        1 => {
            let k = splits.iter().position(Option::is_some).expect("one");
            let p = splits[k].expect("one");
            let (v0, v1, v2) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            children[0] = [v0, p, v2];
            children[1] = [p, v1, v2];
            inner[0] = (p, v2);
            (2, 1)
        }
        2 => {
            // The unsplit edge is (k+2, k); splits on (k, k+1) = p and (k+1, k+2) = q.
            let free = splits.iter().position(Option::is_none).expect("one free");
            let k = (free + 1) % 3;
            let (v0, v1, v2) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            let p = splits[k].expect("split");
            let q = splits[(k + 1) % 3].expect("split");
            children[0] = [p, v1, q];
            inner[0] = (p, q);
            if diagonal_from_first {
                children[1] = [v0, p, v2];
                children[2] = [p, q, v2];
                inner[1] = (p, v2);
            } else {
                children[1] = [v0, p, q];
                children[2] = [v0, q, v2];
                inner[1] = (v0, q);
            }
            (3, 2)
        }
        _ => {
            let [s0, s1, s2] = splits.map(|s| s.expect("three"));
            let [v0, v1, v2] = t;
            children[0] = [v0, s0, s2];
            children[1] = [s0, v1, s1];
            children[2] = [s2, s1, v2];
            children[3] = [s0, s1, s2];
            inner[0] = (s0, s1);
            inner[1] = (s1, s2);
            inner[2] = (s2, s0);
            (4, 3)
        }
    }
}

/// The children of [`template`] alone, and how many there are.
fn template_children(
    t: [u32; 3],
    splits: [Option<u32>; 3],
    diagonal_from_first: bool,
) -> ([[u32; 3]; 4], usize) {
    let mut children = [[0u32; 3]; 4];
    let count = template(
        t,
        splits,
        diagonal_from_first,
        &mut children,
        &mut [(0, 0); 3],
    )
    .0;
    (children, count)
}

/// Whether the template of `t` has an edge between `p` and `q`.
fn edge_in_template(
    t: [u32; 3],
    splits: [Option<u32>; 3],
    diagonal_from_first: bool,
    p: u32,
    q: u32,
) -> bool {
    let (children, count) = template_children(t, splits, diagonal_from_first);
    children[..count].iter().any(|c| {
        (0..3).any(|k| (c[k] == p && c[(k + 1) % 3] == q) || (c[k] == q && c[(k + 1) % 3] == p))
    })
}

/// Checks the surface of `body`: every triangle's corners distinct and in range, every directed edge
/// used once (an oriented 2-manifold with boundary), every undirected edge by at most two triangles
/// in opposite directions, no orphan node, every node's fan a single disc or half-disc, no triangle of
/// area below 1e-10 × its longest edge² (rest), every triangle side a spring, the boundary count
/// right. Returns the first problem found.
pub fn check_surface(body: &Body) -> Result<(), String> {
    let s = &body.surface;
    let n = s.position_in_world.len();
    let mut directed: Vec<(u32, u32)> = Vec::with_capacity(3 * s.triangles.len());
    let mut used = vec![false; n];
    for (i, t) in s.triangles.iter().enumerate() {
        if t.iter().any(|&v| v as usize >= n) {
            return Err(format!("triangle {i} has a corner out of range: {t:?}"));
        }
        if t[0] == t[1] || t[1] == t[2] || t[2] == t[0] {
            return Err(format!("triangle {i} repeats a corner: {t:?}"));
        }
        let [a, b, c] = t.map(|v| s.homologue_in_body[v as usize]);
        let area = 0.5 * (b - a).cross(&(c - a)).norm();
        let longest = (b - a)
            .norm_squared()
            .max((c - b).norm_squared())
            .max((a - c).norm_squared());
        if area < 1e-10 * longest {
            return Err(format!("triangle {i} is degenerate: area {area:e}"));
        }
        for k in 0..3 {
            used[t[k] as usize] = true;
            directed.push((t[k], t[(k + 1) % 3]));
        }
    }
    if let Some(v) = used.iter().position(|u| !u) {
        return Err(format!("node {v} is in no triangle"));
    }
    directed.sort_unstable();
    for w in directed.windows(2) {
        if w[0] == w[1] {
            return Err(format!("directed edge {:?} is used twice", w[0]));
        }
    }
    // Each node's fan: the directed edges out of it form chains; a manifold vertex has one chain
    // (a closed cycle or an open path).
    let mut out_of: Vec<Vec<(u32, u32)>> = vec![Vec::new(); n];
    for t in &s.triangles {
        for k in 0..3 {
            // Around node t[k]: the triangle goes from t[k+1] to t[k+2].
            out_of[t[k] as usize].push((t[(k + 1) % 3], t[(k + 2) % 3]));
        }
    }
    for (v, fan) in out_of.iter().enumerate() {
        // Count chain starts: a "from" that is no one's "to".
        let starts = fan
            .iter()
            .filter(|(from, _)| !fan.iter().any(|(_, to)| to == from))
            .count();
        // Walk from a start (or anywhere for a cycle) and count the triangles reached.
        let first = fan
            .iter()
            .find(|(from, _)| !fan.iter().any(|(_, to)| to == from))
            .or(fan.first())
            .copied();
        let mut reached = 0;
        if let Some(mut current) = first {
            reached = 1;
            while reached < fan.len() {
                match fan.iter().find(|(from, _)| *from == current.1) {
                    Some(next) if *next != first.expect("set") => {
                        current = *next;
                        reached += 1;
                    }
                    _ => break,
                }
            }
        }
        if starts > 1 || reached != fan.len() {
            return Err(format!(
                "node {v} is not a manifold vertex ({} triangles, {starts} open chains)",
                fan.len()
            ));
        }
    }
    // Edge springs: ends in range and distinct.
    let e = &body.edges;
    for k in 0..e.len() {
        if e.a[k] as usize >= n || e.b[k] as usize >= n || e.a[k] == e.b[k] {
            return Err(format!("spring {k} has bad ends ({}, {})", e.a[k], e.b[k]));
        }
    }
    // Every side of every triangle has a spring (cuts and tears open the surface along springs).
    let mut springs: Vec<(u32, u32)> = (0..e.len())
        .map(|k| (e.a[k].min(e.b[k]), e.a[k].max(e.b[k])))
        .collect();
    springs.sort_unstable();
    for t in &s.triangles {
        for k in 0..3 {
            let (p, q) = (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]));
            if springs.binary_search(&(p, q)).is_err() {
                return Err(format!("side {p}–{q} of triangle {t:?} has no spring"));
            }
        }
    }
    if count_boundary_edges(&s.triangles) != body.boundary_edges {
        return Err(format!(
            "boundary edge count {} differs from the mesh's {}",
            body.boundary_edges,
            count_boundary_edges(&s.triangles)
        ));
    }
    Ok(())
}
