//! Multi-rate integration (paper §5, "pas de temps à différents grains"; MODEL.md §7): the rigid
//! component and every node whose stability bound allows it keep the big step; the nodes that violate
//! it (light nodes, stiff springs) are sub-stepped with the smallest power-of-two division that
//! satisfies it.
//!
//! Fixed, deterministic exchange schedule: the slow nodes are integrated first over the whole step
//! with the forces of its start; then the fast nodes are integrated in substeps of the finest level,
//! each fast node stepping at its own level (every `2^(L − level)` substeps, with that many substeps'
//! step), its force recomputed from its own current state, its fast neighbours' latest states and
//! the slow neighbours' positions interpolated linearly between the start and the end of the step. The slow nodes feel the
//! fast ones through the forces at the start of the step. With no fast node this is exactly the
//! symplectic scheme.
//!
//! The rigid component is sub-stepped too when its own coupling demands it (issue 12: links so stiff,
//! or a rigid component so light, that its ω·Δt on the links passes the explicit limit — see
//! [`rigid_bounds`]). Then every node is fast: nodes and rigid component advance together in the
//! substeps, each substep computing the link forces and their reactions from the current states, and
//! the rigid component leaves the step already integrated ([`Multirate::rigid_substepped`]). When no
//! node needs sub-stepping and the rigid component alone is past its limit (a very light or heavily
//! damped rigid component), it takes one linearly implicit step of its own against the nodes'
//! end-of-step states instead ([`Multirate::rigid_implicit`]).

use crate::Vec3;
use crate::body::Body;
use crate::collision::obstacle::{Obstacle, beyond};
use crate::contact::obstacle::{point_contact_plane, resolve_point};
use crate::contact::tool::NO_TOOL;
use crate::dynamics::stability::{
    RIGID_TERMS, node_bounds_into, rigid_bounds_from, rigid_terms, stable_at,
};

/// The sums of two sets of rigid terms.
fn add_terms(a: &[f64; RIGID_TERMS], b: &[f64; RIGID_TERMS]) -> [f64; RIGID_TERMS] {
    std::array::from_fn(|k| a[k] + b[k])
}

/// Largest number of halvings of the step.
pub const MAX_LEVEL: u32 = 12;
/// Fraction of the stability limit a node may use.
pub const SAFETY: f64 = 0.9;
/// Fraction of the stability limit the rigid component's coupled mode may use when some nodes are
/// sub-stepped and meet it only once per step.
pub const EXCHANGE_SAFETY: f64 = 0.45;
/// Most springs at one node that [`Multirate::follow`] takes (more: it rebuilds).
const INCIDENT_ROOM: usize = 1024;

/// Scratch and classification of one body.
#[derive(Clone, Debug)]
pub struct Multirate {
    /// Fast nodes, in index order.
    pub fast: Vec<u32>,
    /// Substeps per step of the fast nodes (2^level of the fastest).
    pub substeps: u32,
    /// The rigid component is sub-stepped with the nodes (its coupling passes the explicit limit and
    /// some nodes are sub-stepped).
    pub rigid_substepped: bool,
    /// The rigid component is stepped by a linearly implicit update against the nodes' end-of-step
    /// states (its coupling passes the explicit limit, every node is stable at the step).
    pub rigid_implicit: bool,
    /// With the rigid component sub-stepped: substeps between two updates of the rigid component
    /// (1 unless some node needs a finer step than the rigid component's).
    pub base_stride: u32,
    /// With the rigid component sub-stepped: the nodes that need a finer step than the rigid
    /// component's (light nodes a cut or a subdivision made, ...), finest first, then by index. Each
    /// steps at its own level: node i every `2^(L − level[i])` substeps.
    pub deep: Vec<u32>,
    /// Each node's level (halvings of the step it needs; in rigid mode at least the rigid component's).
    level: Vec<u32>,
    /// Each node's own level (the halvings its own bounds need, before the rigid component's).
    own_level: Vec<u32>,
    /// Nodes at each own level.
    level_count: [u32; MAX_LEVEL as usize + 1],
    /// The body's topology version the classification is for.
    synced_version: u64,
    /// A node's springs (scratch of [`Multirate::follow`]).
    incident: crate::Room<u32>,
    /// The nodes' terms of the rigid component's bounds, summed in a fixed binary tree over the
    /// node slots (leaves from `rigid_width`): a change at a few nodes is summed again along their
    /// paths to the root, and the sums depend on the nodes' terms only, not on the changes'
    /// history.
    rigid_tree: Vec<[f64; RIGID_TERMS]>,
    rigid_width: usize,
    /// Leaves that may hold a node's terms (those past it hold zeros).
    rigid_filled: usize,
    /// Topology changes followed at the nodes they touched.
    pub follows: u64,
    /// Full classifications (at the start, and for changes not followed).
    pub rebuilds: u64,
    /// Followed changes whose classification was made again at the deep nodes only.
    pub near_classifications: u64,
    /// The rigid component's own level at the last classification.
    rigid_level: u32,
    /// Row of each node in the neighbour lists (`u32::MAX`: none).
    row: Vec<u32>,
    /// Where each node was at the start of its current step, for its neighbours' interpolation.
    x_base: Vec<Vec3>,
    deep_force: Vec<Vec3>,
    local: Vec<u32>,
    start: Vec<u32>,
    neighbour: crate::Room<u32>,
    edge: Vec<u32>,
    /// The fast list and neighbour lists [`Multirate::follow`] builds beside the current ones
    /// (swapped in when done).
    fast_spare: crate::Room<u32>,
    start_spare: crate::Room<u32>,
    neighbour_spare: crate::Room<u32>,
    edge_spare: Vec<u32>,
    /// The nodes whose row may have changed: the changed ones and the ends of the changed springs.
    dirty: crate::Room<u32>,
    /// Followed changes whose classification was made again at the changed nodes' rows only (the
    /// rigid component not sub-stepped).
    pub far_classifications: u64,
    x: Vec<Vec3>,
    v: Vec<Vec3>,
    f: Vec<Vec3>,
    homologue_end: Vec<Vec3>,
    bound_stiffness: Vec<f64>,
    bound_damping: Vec<f64>,
    /// Nodes that touched an obstacle during the substeps of this step.
    touched: Vec<bool>,
    /// Per node, the impulse (N s) its springs to nodes stepped finer than it owe it over the
    /// step: what those springs gave the finer ends, negated, less what it took from them at its
    /// own steps (a node not sub-stepped, see [`Multirate::integrate`]; a node coarser than a deep
    /// one, see `integrate_with_rigid`). Zero between steps: each debt is cleared as it is paid.
    owed: Vec<Vec3>,
    /// Forces from outside the body held over the step (attachments), per node (N, world): the
    /// substeps recompute the nodes' own forces, and add these.
    external: Vec<Vec3>,
    /// The part of the sub-stepped links' reaction the rigid component has not received yet (N and
    /// N·m, as a force over one update of the rigid component): the links of nodes stepped between
    /// its updates pull with forces it did not see when it moved. It takes them at its next update,
    /// so the links' impulses on the nodes and on the rigid component stay equal and opposite.
    carried_force: Vec3,
    carried_torque: Vec3,
    /// The rigid component's centre at the start and the end of its current update (m, world).
    centre_interval: [Vec3; 2],
    /// Whether the springs of a base step are computed four at a time with AVX (the same
    /// operations per spring and the same order of the sums, so the same bits as one at a time).
    simd: bool,
}

impl Multirate {
    /// Classifies the nodes of `body` for step `dt` and sizes the scratch.
    pub fn new(body: &Body, dt: f64) -> Self {
        Self::with_room(body, dt, 0)
    }

    /// Like [`Multirate::new`], with room reserved for `extra_nodes` more nodes (three edges each), so
    /// that [`Multirate::rebuild`] after a subdivision allocates nothing.
    pub fn with_room(body: &Body, dt: f64, extra_nodes: usize) -> Self {
        let n = body.node_count() + extra_nodes;
        let m = body.edges.len() + 3 * extra_nodes;
        let mut multirate = Self {
            fast: Vec::with_capacity(n),
            substeps: 1,
            rigid_substepped: false,
            rigid_implicit: false,
            base_stride: 1,
            deep: Vec::with_capacity(n),
            level: Vec::with_capacity(n),
            own_level: Vec::with_capacity(n),
            level_count: [0; MAX_LEVEL as usize + 1],
            synced_version: 0,
            incident: crate::Room::with_capacity(INCIDENT_ROOM),
            rigid_tree: vec![[0.0; RIGID_TERMS]; 2 * n.next_power_of_two()],
            rigid_width: n.next_power_of_two(),
            rigid_filled: 0,
            follows: 0,
            rebuilds: 0,
            near_classifications: 0,
            rigid_level: 0,
            row: Vec::with_capacity(n),
            x_base: Vec::with_capacity(n),
            deep_force: Vec::with_capacity(n),
            local: Vec::with_capacity(n),
            start: Vec::with_capacity(n + 1),
            neighbour: crate::Room::with_capacity(2 * m),
            edge: Vec::with_capacity(2 * m),
            fast_spare: crate::Room::with_capacity(n),
            start_spare: crate::Room::with_capacity(n + 1),
            neighbour_spare: crate::Room::with_capacity(2 * m),
            edge_spare: Vec::with_capacity(2 * m),
            dirty: crate::Room::with_capacity(n + 1),
            far_classifications: 0,
            x: Vec::with_capacity(n),
            v: Vec::with_capacity(n),
            f: Vec::with_capacity(n),
            homologue_end: Vec::with_capacity(n),
            bound_stiffness: Vec::with_capacity(n),
            bound_damping: Vec::with_capacity(n),
            touched: Vec::with_capacity(n),
            owed: Vec::with_capacity(n),
            external: Vec::with_capacity(n),
            carried_force: Vec3::zeros(),
            carried_torque: Vec3::zeros(),
            centre_interval: [Vec3::zeros(); 2],
            simd: crate::dynamics::kernel::simd_available(),
        };
        multirate.rebuild(body, dt);
        multirate
    }

    /// Uses the AVX spring loop when the machine has AVX and `simd` is true (the scalar loop
    /// otherwise); both give the same bits.
    pub fn set_simd(&mut self, simd: bool) {
        self.simd = simd && crate::dynamics::kernel::simd_available();
    }

    /// Adds a force from outside the body (an attachment's) on `node` for the next step; the
    /// caller also adds it to the node's `force_in_world` and clears it after the step.
    pub fn add_external_force(&mut self, node: usize, force: &Vec3) {
        if let Some(f) = self.external.get_mut(node) {
            *f += force;
        }
    }

    /// Whether node `i` takes last tick's contact forces into its substeps: a fast node, unless the
    /// rigid component is sub-stepped with the nodes. (There the rigid component feels the carried
    /// force through the links within the step, and a 5 kg organ laid on a 1.3 kg one settled
    /// over seconds instead of ringing down: 7.2e-5 J at 4.5 s against 4.0e-6 without it.)
    pub fn carries_contact_forces_to(&self, i: usize) -> bool {
        !self.rigid_substepped && self.fast.binary_search(&(i as u32)).is_ok()
    }

    /// [`Self::carries_contact_forces_to`], for a node no tool holds, of non-zero inverse mass.
    fn sub_steps(&self, body: &Body, i: usize) -> bool {
        let s = &body.surface;
        self.carries_contact_forces_to(i)
            && s.tool_contact.get(i).is_some_and(|c| c.tool == NO_TOOL)
            && s.inverse_mass[i] != 0.0
    }

    /// Adds last tick's contact forces on the sub-stepped nodes of `body` (node, force in N: see
    /// `BodyContactScratch::carried_on`) to their outside forces for this step's substeps.
    pub fn carry_contact_forces(
        &mut self,
        body: &Body,
        carried: impl Iterator<Item = (usize, Vec3)>,
    ) {
        for (i, force) in carried {
            if i < body.surface.mass.len() && self.sub_steps(body, i) {
                self.add_external_force(i, &force);
            }
        }
    }

    /// After the step, takes back the forces [`Self::carry_contact_forces`] added (`carried`, the
    /// same list): each node's velocity and end position change by the impulse's opposite (the
    /// force over the step), so that over the tick the node took the contact's impulse once, from
    /// this tick's response; its outside force is cleared.
    pub fn take_back_contact_forces(
        &mut self,
        body: &mut Body,
        carried: impl Iterator<Item = (usize, Vec3)>,
        dt: f64,
    ) {
        for (i, force) in carried {
            if i < body.surface.mass.len() && self.sub_steps(body, i) {
                self.clear_external_force(i);
                let s = &mut body.surface;
                let dv = force * (dt * s.inverse_mass[i]);
                s.velocity_in_world[i] -= dv;
                s.next_position_in_world[i] -= dv * dt;
            }
        }
    }

    /// Clears the outside force on `node`.
    pub fn clear_external_force(&mut self, node: usize) {
        if let Some(f) = self.external.get_mut(node) {
            *f = Vec3::zeros();
        }
    }

    /// Classifies the nodes again after the body's topology changed, reusing the scratch (allocates
    /// nothing while the body stays within the room reserved).
    pub fn rebuild(&mut self, body: &Body, dt: f64) {
        let s = &body.surface;
        let n = s.mass.len();
        self.external.clear();
        self.external.resize(n, Vec3::zeros());
        node_bounds_into(body, &mut self.bound_stiffness, &mut self.bound_damping);
        self.own_level.clear();
        self.level_count = [0; MAX_LEVEL as usize + 1];
        for i in 0..n {
            let level = self.level_of(body, i, dt);
            self.own_level.push(level);
            self.level_count[level as usize] += 1;
        }
        self.synced_version = body.topology_version;
        self.rebuilds += 1;
        self.sum_rigid_terms(body);
        self.classify(body, dt);
    }

    /// The first part of the classification (and the scratch's sizes) in which `self` and `other`
    /// differ, if any: what [`Multirate::follow`] must give as [`Multirate::rebuild`] does.
    pub fn differs_from(&self, other: &Self) -> Option<&'static str> {
        let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        let lengths = |m: &Self| {
            [
                m.x.len(),
                m.v.len(),
                m.f.len(),
                m.homologue_end.len(),
                m.x_base.len(),
                m.deep_force.len(),
                m.touched.len(),
                m.external.len(),
            ]
        };
        let parts = [
            ("fast", self.fast == other.fast),
            ("deep", self.deep == other.deep),
            ("level", self.level == other.level),
            ("own level", self.own_level == other.own_level),
            ("level count", self.level_count == other.level_count),
            (
                "pace",
                (
                    self.substeps,
                    self.base_stride,
                    self.rigid_substepped,
                    self.rigid_implicit,
                ) == (
                    other.substeps,
                    other.base_stride,
                    other.rigid_substepped,
                    other.rigid_implicit,
                ),
            ),
            ("local", self.local == other.local),
            ("row", self.row == other.row),
            (
                "neighbour lists",
                (&self.start, &self.neighbour, &self.edge)
                    == (&other.start, &other.neighbour, &other.edge),
            ),
            (
                "bounds",
                bits(&self.bound_stiffness) == bits(&other.bound_stiffness)
                    && bits(&self.bound_damping) == bits(&other.bound_damping),
            ),
            ("outside forces", self.external == other.external),
            (
                "rigid sums",
                bits(&self.rigid_tree[1]) == bits(&other.rigid_tree[1]),
            ),
            ("touched", self.touched == other.touched),
            ("scratch sizes", lengths(self) == lengths(other)),
        ];
        parts.iter().find(|(_, same)| !same).map(|(name, _)| *name)
    }

    /// The body's topology version this classification is for.
    pub fn synced_version(&self) -> u64 {
        self.synced_version
    }

    /// Follows a change of the body's topology where it happened instead of passing over the mesh:
    /// `changed` (in increasing order) holds every node whose mass, link, air damping or springs
    /// changed, and every new node, `edges` every spring rewritten or added (a node at its end may
    /// have a new neighbour on it); `incident(v, out)` puts node `v`'s springs into `out` in index
    /// order (false when it cannot). Only those nodes' bounds and levels are computed again — the
    /// same sums in the same order as [`Multirate::rebuild`], so the same classification; when a
    /// node cannot be followed so, the rebuild is made instead. Allocation-free.
    pub fn follow(
        &mut self,
        body: &Body,
        dt: f64,
        changed: &[u32],
        edges: &[u32],
        incident: &mut dyn FnMut(u32, &mut Vec<u32>) -> bool,
    ) {
        let s = &body.surface;
        let e = &body.edges;
        let n = s.mass.len();
        let before = self.own_level.len();
        let new_nodes = n.saturating_sub(before);
        let every_new_node_listed = n >= before
            && changed.len() >= new_nodes
            && changed[changed.len() - new_nodes..]
                .iter()
                .zip(before..n)
                .all(|(&v, i)| v as usize == i);
        if !every_new_node_listed || self.bound_stiffness.len() != before || n > self.rigid_width {
            self.rebuild(body, dt);
            return;
        }
        // Outside forces are zero between steps (their callers clear them after each step).
        self.external.resize(n, Vec3::zeros());
        self.bound_stiffness.resize(n, 0.0);
        self.bound_damping.resize(n, 0.0);
        self.own_level.resize(n, 0);
        for &v in changed {
            let i = v as usize;
            if !incident(v, &mut self.incident) {
                self.rebuild(body, dt);
                return;
            }
            let mut stiffness = s.link_stiffness[i];
            let mut damping = s.link_damping[i] + s.air_damping[i];
            for &k in &self.incident {
                stiffness += 2.0 * e.stiffness[k as usize];
                damping += 2.0 * e.damping[k as usize];
            }
            self.bound_stiffness[i] = stiffness;
            self.bound_damping[i] = damping;
            if i < before {
                self.level_count[self.own_level[i] as usize] -= 1;
            }
            let level = self.level_of(body, i, dt);
            self.own_level[i] = level;
            self.level_count[level as usize] += 1;
            self.set_rigid_terms(i, rigid_terms(body, i));
        }
        self.synced_version = body.topology_version;
        self.follows += 1;
        if self.classify_near(body, dt, changed, before, incident) {
            self.near_classifications += 1;
        } else if self.classify_far(body, dt, changed, edges, before, incident) {
            self.far_classifications += 1;
        } else {
            self.classify(body, dt);
        }
    }

    /// Sums every node's rigid terms in the tree (the slots past the nodes hold zeros). A body
    /// grown past the tree's room gets a wider tree (at a rebuild, outside the tick's pools).
    fn sum_rigid_terms(&mut self, body: &Body) {
        let n = body.surface.mass.len();
        if n > self.rigid_width {
            self.rigid_width = n.next_power_of_two();
            self.rigid_tree = vec![[0.0; RIGID_TERMS]; 2 * self.rigid_width];
            self.rigid_filled = 0;
        }
        // Leaves past `filled` and the sums over them only are zero already: only the leaves that
        // are or were nodes, and the sums above them, are written.
        let width = self.rigid_width;
        let used = n.max(self.rigid_filled);
        self.rigid_filled = n;
        if used == 0 {
            return;
        }
        for i in 0..used {
            self.rigid_tree[width + i] = if i < n {
                rigid_terms(body, i)
            } else {
                [0.0; RIGID_TERMS]
            };
        }
        let (mut first, mut last) = (width, width + used - 1);
        while first > 1 {
            (first, last) = (first / 2, last / 2);
            for at in first..=last {
                self.rigid_tree[at] =
                    add_terms(&self.rigid_tree[2 * at], &self.rigid_tree[2 * at + 1]);
            }
        }
    }

    /// Sets node `i`'s rigid terms and sums its path to the root again.
    fn set_rigid_terms(&mut self, i: usize, terms: [f64; RIGID_TERMS]) {
        self.rigid_filled = self.rigid_filled.max(i + 1);
        let mut at = self.rigid_width + i;
        self.rigid_tree[at] = terms;
        while at > 1 {
            at /= 2;
            self.rigid_tree[at] = add_terms(&self.rigid_tree[2 * at], &self.rigid_tree[2 * at + 1]);
        }
    }

    /// The finest own level of any node.
    fn own_level_max(&self) -> u32 {
        (0..=MAX_LEVEL)
            .rev()
            .find(|&l| self.level_count[l as usize] > 0)
            .unwrap_or(0)
    }

    /// The halvings of the step the rigid component needs against the surface on all its links
    /// (and its air), with `level_max` the finest own level of a node. Met once per step by
    /// sub-stepped nodes, the exchange is explicit and holds only to about half the explicit limit
    /// (scenes/stress/stiff.toml diverged at ω·Δt = 1.39 of 1.98): then the rigid component joins
    /// the substeps.
    fn rigid_level_for(&self, body: &Body, dt: f64, level_max: u32) -> u32 {
        let mut rigid_level = 0;
        if !body.rigid.fixed {
            let bounds = rigid_bounds_from(body, &self.rigid_tree[1]);
            let safety = if level_max > 0 {
                EXCHANGE_SAFETY
            } else {
                SAFETY
            };
            while rigid_level < MAX_LEVEL
                && !bounds.iter().all(|&(stiffness, damping, inverse_mass)| {
                    stable_at(
                        stiffness,
                        damping,
                        inverse_mass,
                        dt / (1u32 << rigid_level) as f64,
                        safety,
                    )
                })
            {
                rigid_level += 1;
            }
        }
        rigid_level
    }

    /// [`Multirate::classify`] where only the nodes `changed` (increasing; the new nodes from
    /// `before` among them) changed level, for a body whose rigid component is sub-stepped before
    /// and after at the same pace: every node is fast, and only the deep nodes (finer than the
    /// rigid component) and their neighbour lists (from `incident`) are made again. Returns false,
    /// having changed nothing the full classification does not make again, when that does not
    /// apply.
    fn classify_near(
        &mut self,
        body: &Body,
        dt: f64,
        changed: &[u32],
        before: usize,
        incident: &mut dyn FnMut(u32, &mut Vec<u32>) -> bool,
    ) -> bool {
        let n = body.surface.mass.len();
        let level_max = self.own_level_max();
        let rigid_level = self.rigid_level_for(body, dt, level_max);
        if !self.rigid_substepped
            || level_max == 0
            || rigid_level == 0
            || rigid_level != self.rigid_level
            || self.level.len() != before
        {
            return false;
        }
        // Every node steps at least at the rigid component's pace.
        self.fast.extend(before as u32..n as u32);
        self.level.resize(n, 0);
        for &v in changed {
            self.level[v as usize] = self.own_level[v as usize].max(rigid_level);
        }
        let level_max = level_max.max(rigid_level);
        self.base_stride = 1 << (level_max - rigid_level);
        self.substeps = 1 << level_max;
        self.local.extend(before as u32..n as u32);
        // The deep nodes, finest first then by index, and their rows.
        self.row.resize(n, u32::MAX);
        for &i in &self.deep {
            self.row[i as usize] = u32::MAX;
        }
        self.deep.retain(|i| changed.binary_search(i).is_err());
        let level = &self.level;
        self.deep.extend(
            changed
                .iter()
                .copied()
                .filter(|&v| level[v as usize] > rigid_level),
        );
        self.deep
            .sort_unstable_by_key(|&i| (u32::MAX - level[i as usize], i));
        let count = self.deep.len();
        self.start.clear();
        self.start.push(0);
        self.neighbour.clear();
        self.edge.clear();
        let e = &body.edges;
        for r in 0..count {
            let i = self.deep[r];
            self.row[i as usize] = r as u32;
            if !incident(i, &mut self.incident)
                || self.neighbour.len() + self.incident.len() > self.neighbour.capacity()
            {
                return false;
            }
            for &k in &self.incident {
                let (a, b) = (e.a[k as usize], e.b[k as usize]);
                self.neighbour.push(if a == i { b } else { a });
                self.edge.push(k);
            }
            self.start.push(self.neighbour.len() as u32);
        }
        self.size_scratch(n);
        true
    }

    /// [`Multirate::classify`] where only the nodes `changed` (increasing; the new nodes from
    /// `before` among them) changed level or springs and the springs `edges` changed, for a body
    /// whose rigid component is not sub-stepped before and after: the fast nodes are those of a
    /// level above 0, in index order, each with its row of springs; the rows of the fast nodes
    /// neither changed nor at an end of a changed spring are copied, the others made from
    /// `incident`. Returns false, having changed nothing the full
    /// classification does not make again, when that does not apply.
    fn classify_far(
        &mut self,
        body: &Body,
        dt: f64,
        changed: &[u32],
        edges: &[u32],
        before: usize,
        incident: &mut dyn FnMut(u32, &mut Vec<u32>) -> bool,
    ) -> bool {
        let n = body.surface.mass.len();
        let level_max = self.own_level_max();
        let rigid_level = self.rigid_level_for(body, dt, level_max);
        if self.rigid_substepped
            || changed.len() + 2 * edges.len() > self.dirty.capacity()
            || (rigid_level > 0 && level_max > 0)
            || self.level.len() != before
            || self.start.len() != self.fast.len() + 1
            || n > self.fast_spare.capacity()
            || n >= self.start_spare.capacity()
        {
            return false;
        }
        let e = &body.edges;
        self.dirty.clear();
        self.dirty.extend_from_slice(changed);
        for &k in edges {
            self.dirty.push(e.a[k as usize]);
            self.dirty.push(e.b[k as usize]);
        }
        self.dirty.sort_unstable();
        self.dirty.dedup();
        let dirty = std::mem::take(&mut self.dirty);
        let merged = self.merge_rows(e, &dirty, incident);
        self.dirty = dirty;
        if !merged {
            return false;
        }
        self.rigid_level = rigid_level;
        self.rigid_implicit = rigid_level > 0 && level_max == 0;
        self.base_stride = 1;
        self.substeps = 1 << level_max;
        self.level.resize(n, 0);
        for &v in changed {
            self.level[v as usize] = self.own_level[v as usize];
        }
        // The old fast nodes' places forgotten, the new ones set (a node's row is its place).
        self.local.resize(n, u32::MAX);
        self.row.resize(n, u32::MAX);
        for &i in &self.fast {
            self.local[i as usize] = u32::MAX;
            self.row[i as usize] = u32::MAX;
        }
        std::mem::swap(&mut self.fast, &mut self.fast_spare);
        std::mem::swap(&mut self.start, &mut self.start_spare);
        std::mem::swap(&mut self.neighbour, &mut self.neighbour_spare);
        std::mem::swap(&mut self.edge, &mut self.edge_spare);
        for (r, &i) in self.fast.iter().enumerate() {
            self.local[i as usize] = r as u32;
            self.row[i as usize] = r as u32;
        }
        self.size_scratch(n);
        true
    }

    /// The fast list and rows into the spares, merged in index order from the old fast nodes not
    /// in `dirty` (row copied) and the `dirty` ones of a level above 0 (row from `incident`);
    /// false when the room or the index fails.
    fn merge_rows(
        &mut self,
        e: &crate::body::Edges,
        dirty: &[u32],
        incident: &mut dyn FnMut(u32, &mut Vec<u32>) -> bool,
    ) -> bool {
        self.fast_spare.clear();
        self.start_spare.clear();
        self.start_spare.push(0);
        self.neighbour_spare.clear();
        self.edge_spare.clear();
        let (mut k, mut c) = (0, 0);
        loop {
            let old = self.fast.get(k).copied();
            let next = dirty.get(c).copied();
            if let Some(i) = old.filter(|&i| next.is_none_or(|v| i < v)) {
                let (a, b) = (self.start[k] as usize, self.start[k + 1] as usize);
                if self.neighbour_spare.len() + (b - a) > self.neighbour_spare.capacity() {
                    return false;
                }
                self.neighbour_spare
                    .extend_from_slice(&self.neighbour[a..b]);
                self.edge_spare.extend_from_slice(&self.edge[a..b]);
                self.fast_spare.push(i);
                self.start_spare.push(self.neighbour_spare.len() as u32);
                k += 1;
                continue;
            }
            let Some(v) = next else {
                break;
            };
            if old == Some(v) {
                k += 1;
            }
            c += 1;
            if self.own_level[v as usize] == 0 {
                continue;
            }
            if !incident(v, &mut self.incident)
                || self.neighbour_spare.len() + self.incident.len()
                    > self.neighbour_spare.capacity()
            {
                return false;
            }
            for &s in &self.incident {
                let (a, b) = (e.a[s as usize], e.b[s as usize]);
                self.neighbour_spare.push(if a == v { b } else { a });
                self.edge_spare.push(s);
            }
            self.fast_spare.push(v);
            self.start_spare.push(self.neighbour_spare.len() as u32);
        }
        true
    }

    /// The halvings of the step node `i` needs for its bounds (at most [`MAX_LEVEL`]).
    fn level_of(&self, body: &Body, i: usize, dt: f64) -> u32 {
        let mut level = 0;
        while level < MAX_LEVEL
            && !stable_at(
                self.bound_stiffness[i],
                self.bound_damping[i],
                body.surface.inverse_mass[i],
                dt / (1u32 << level) as f64,
                SAFETY,
            )
        {
            level += 1;
        }
        level
    }

    /// From the nodes' own levels: the fast and deep nodes, the rigid component's pace, the
    /// neighbour lists and the scratch.
    fn classify(&mut self, body: &Body, dt: f64) {
        let n = body.surface.mass.len();
        self.fast.clear();
        self.deep.clear();
        self.level.clear();
        let mut level_max = self.own_level_max();
        for i in 0..n {
            let level = self.own_level[i];
            if level > 0 {
                self.fast.push(i as u32);
            }
            self.level.push(level);
        }
        // The rigid component against the surface on all its links (and its air). Met once per step
        // by sub-stepped nodes, the exchange is explicit and holds only to about half the explicit
        // limit (scenes/stress/stiff.toml diverged at ω·Δt = 1.39 of 1.98): then the rigid
        // component joins the substeps.
        let rigid_level = self.rigid_level_for(body, dt, level_max);
        self.rigid_level = rigid_level;
        // With no node sub-stepped the rigid component alone is past its limit: one implicit update
        // of its six unknowns replaces the substeps its coupling (often its link damping) would need.
        self.rigid_implicit = rigid_level > 0 && level_max == 0;
        self.rigid_substepped = rigid_level > 0 && level_max > 0;
        self.base_stride = 1;
        if self.rigid_substepped {
            // Every node steps at least at the rigid component's pace; the nodes that need a finer
            // step than that (deep) take it between the rigid component's updates, each at its own.
            self.fast.clear();
            self.fast.extend(0..n as u32);
            self.base_stride = 1 << (level_max.max(rigid_level) - rigid_level);
            level_max = level_max.max(rigid_level);
            for level in &mut self.level {
                *level = (*level).max(rigid_level);
            }
            for l in (rigid_level + 1..=level_max).rev() {
                for i in 0..n {
                    if self.level[i] == l {
                        self.deep.push(i as u32);
                    }
                }
            }
        }
        self.substeps = 1 << level_max;
        self.local.clear();
        self.local.resize(n, u32::MAX);
        for (k, &i) in self.fast.iter().enumerate() {
            self.local[i as usize] = k as u32;
        }
        // Incident edges (CSR, in edge order) of the nodes stepped alone between the others: the
        // fast nodes, or with the rigid component sub-stepped the deep ones. Row r is the r-th of
        // them; `row` maps a node to its row.
        self.row.clear();
        self.row.resize(n, u32::MAX);
        let rows: &[u32] = if self.rigid_substepped {
            &self.deep
        } else {
            &self.fast
        };
        for (r, &i) in rows.iter().enumerate() {
            self.row[i as usize] = r as u32;
        }
        let count = rows.len();
        let e = &body.edges;
        self.start.clear();
        self.start.resize(count + 1, 0);
        if count > 0 {
            for k in 0..e.len() {
                for node in [e.a[k], e.b[k]] {
                    let r = self.row[node as usize];
                    if r != u32::MAX {
                        self.start[r as usize + 1] += 1;
                    }
                }
            }
            for r in 0..count {
                self.start[r + 1] += self.start[r];
            }
        }
        let slots = self.start[count] as usize;
        self.neighbour.clear();
        self.neighbour.resize(slots, 0);
        self.edge.clear();
        self.edge.resize(slots, 0);
        if count > 0 {
            // Fill each row's slots from the back, `start[r + 1]` (the end of row r's slots)
            // serving as the cursor: it counts down to the first slot of row r.
            for k in (0..e.len()).rev() {
                for (me, other) in [(e.b[k], e.a[k]), (e.a[k], e.b[k])] {
                    let r = self.row[me as usize];
                    if r == u32::MAX {
                        continue;
                    }
                    let r = r as usize;
                    self.start[r + 1] -= 1;
                    let at = self.start[r + 1] as usize;
                    self.neighbour[at] = other;
                    self.edge[at] = k as u32;
                }
            }
            // Now `start[r + 1]` is where row r's slots begin: shift down by one.
            for r in 0..count {
                self.start[r] = self.start[r + 1];
            }
            self.start[count] = slots as u32;
        }
        self.size_scratch(n);
    }

    /// Sizes the step's scratch to `n` nodes and the fast and deep lists. Every entry of it is
    /// written before it is read in a step (and `touched` is all false between steps), so what it
    /// held before does not matter: only the sizes change.
    fn size_scratch(&mut self, n: usize) {
        self.touched.resize(n, false);
        self.owed.resize(n, Vec3::zeros());
        let deep = self.deep.len();
        self.x_base
            .resize(if deep > 0 { n } else { 0 }, Vec3::zeros());
        self.deep_force.resize(deep, Vec3::zeros());
        let m = self.fast.len();
        for buffer in [
            &mut self.x,
            &mut self.v,
            &mut self.f,
            &mut self.homologue_end,
        ] {
            buffer.resize(m, Vec3::zeros());
        }
    }

    /// Integrates the free nodes of `body` over `dt` (forces already accumulated): slow nodes in one
    /// step (unless `slow_nodes_integrated`: the force stage's node pass did it), fast nodes in
    /// substeps. Allocates nothing.
    ///
    /// When the rigid component is sub-stepped, contact with the `obstacles` is resolved in the
    /// substeps too (a contact projected once per step would store ½ k (v Δt)² in the stiff links it
    /// compresses, far more than the motion it stops), the obstacles' forces added to `reactions`;
    /// `reach` holds each obstacle's `ObstacleShape::reach_in_world` for this step (a node ending
    /// beyond it is not tested against that obstacle; an obstacle without an entry is tested).
    pub fn integrate(
        &mut self,
        body: &mut Body,
        dt: f64,
        gravity: &Vec3,
        (obstacles, reach): (&[Obstacle], &[Option<[Vec3; 2]>]),
        reactions: &mut [Vec3],
        slow_nodes_integrated: bool,
    ) -> usize {
        if self.rigid_substepped {
            return self.integrate_with_rigid(body, dt, gravity, (obstacles, reach), reactions);
        }
        if !slow_nodes_integrated {
            self.owe_start_of_step_pulls(body, dt);
            self.integrate_slow_nodes(&mut body.surface, dt);
        }
        if self.rigid_implicit {
            // Every node is slow here (see `rebuild`): nothing is left to sub-step.
            step_rigid_implicitly(body, dt, gravity);
            return 0;
        }
        if self.fast.is_empty() {
            return 0;
        }
        let (centre, end_centre) = self.start_substeps(body, dt);
        // Each fast node steps at its own level: node i every `stride = 2^(L − level[i])` substeps,
        // with a step of `stride · h` (one stiff node does not drag every fast node down to its
        // step). Its fast neighbours enter with their latest states.
        for step in 0..self.substeps {
            self.substep_forces(
                body,
                (step, dt),
                gravity,
                (centre, end_centre),
                slow_nodes_integrated,
            );
            self.substep_move(&body.surface, step, dt);
        }
        let s = &mut body.surface;
        for (k, &i) in self.fast.iter().enumerate() {
            let i = i as usize;
            if s.tool_contact[i].tool != NO_TOOL {
                continue;
            }
            s.velocity_in_world[i] = self.v[k];
            s.next_position_in_world[i] = self.x[k];
        }
        if !slow_nodes_integrated {
            self.pay_owed(s, dt);
        }
        0
    }

    /// A spring between a sub-stepped node and one that is not gives the first, over its
    /// substeps, forces from the second's interpolated trajectory, and the second the force of
    /// the start-of-step state for the whole step: not equal and opposite impulses once the
    /// spring changes over the step (a lone deforming body lost momentum so). The second is
    /// owed the difference, given it after the substeps. Here, what it takes at the start (the
    /// force stage's, to rounding), from the states before the step.
    fn owe_start_of_step_pulls(&mut self, body: &Body, dt: f64) {
        let (s, e) = (&body.surface, &body.edges);
        for (k, &i) in self.fast.iter().enumerate() {
            let i = i as usize;
            if s.tool_contact[i].tool != NO_TOOL {
                continue;
            }
            let (x, v) = (s.position_in_world[i], s.velocity_in_world[i]);
            for at in self.start[k] as usize..self.start[k + 1] as usize {
                let j = self.neighbour[at] as usize;
                if self.local[j] != u32::MAX {
                    continue;
                }
                let (xj, vj) = (s.position_in_world[j], s.velocity_in_world[j]);
                if let Some(pull) = spring_pull(e, self.edge[at] as usize, &x, &v, &xj, &vj) {
                    self.owed[j] += pull * dt;
                }
            }
        }
    }

    /// The free nodes that are not sub-stepped, in one step of `dt` on the step's forces.
    fn integrate_slow_nodes(&self, s: &mut crate::body::Surface, dt: f64) {
        for i in 0..s.mass.len() {
            if self.local[i] != u32::MAX || s.tool_contact[i].tool != NO_TOOL {
                continue;
            }
            let velocity = s.velocity_in_world[i] + s.force_in_world[i] * (dt * s.inverse_mass[i]);
            s.velocity_in_world[i] = velocity;
            s.next_position_in_world[i] = s.position_in_world[i] + velocity * dt;
        }
    }

    /// Before the substeps: the rigid component takes what the fast nodes' links gave the nodes
    /// last step beyond its start-of-step force; the fast nodes' states are copied in, with their
    /// homologues at the end of the step (where the rigid component will be: its forces are
    /// known, so the homologues move with it through the substeps instead of waiting a step); and
    /// the start-of-step link forces the rigid component took are carried, to be corrected by what
    /// the substeps apply. The rigid component's centre at the start and at the end of the step.
    fn start_substeps(&mut self, body: &mut Body, dt: f64) -> (Vec3, Vec3) {
        body.rigid.force_in_world += std::mem::take(&mut self.carried_force);
        body.rigid.torque_in_world += std::mem::take(&mut self.carried_torque);
        let s = &body.surface;
        let mut rigid_end = body.rigid.clone();
        rigid_end.integrate(dt);
        let end_rotation = rigid_end.world_from_body.to_rotation_matrix();
        let start_rotation = body.rigid.world_from_body.to_rotation_matrix();
        let centre = body.rigid.position_in_world;
        let velocity_of_centre = body.rigid.velocity_in_world;
        let omega = body.rigid.angular_velocity_in_world();
        for (k, &i) in self.fast.iter().enumerate() {
            let i = i as usize;
            self.x[k] = s.position_in_world[i];
            self.v[k] = s.velocity_in_world[i];
            self.homologue_end[k] =
                rigid_end.position_in_world + end_rotation * s.homologue_in_body[i];
            if s.tool_contact[i].tool == NO_TOOL {
                let arm = start_rotation * s.homologue_in_body[i];
                let link = (centre + arm - s.position_in_world[i]) * s.link_stiffness[i]
                    + (velocity_of_centre + omega.cross(&arm) - s.velocity_in_world[i])
                        * s.link_damping[i];
                self.carried_force += link;
                self.carried_torque += arm.cross(&link);
            }
        }
        (centre, rigid_end.position_in_world)
    }

    /// Substep `step`'s force on each fast node due then (gravity, outside forces, air, its link
    /// to the homologue moving with the rigid component, its springs to its neighbours at their
    /// latest states or, for nodes not sub-stepped, on their interpolated trajectories), the
    /// rigid component's reaction carried, and what the nodes not sub-stepped are owed.
    fn substep_forces(
        &mut self,
        body: &Body,
        (step, dt): (u32, f64),
        gravity: &Vec3,
        (centre, end_centre): (Vec3, Vec3),
        slow_nodes_integrated: bool,
    ) {
        let (s, e) = (&body.surface, &body.edges);
        let h = dt / self.substeps as f64;
        let fraction = step as f64 / self.substeps as f64;
        for (k, &i) in self.fast.iter().enumerate() {
            let i = i as usize;
            let stride = self.substeps >> self.level[i];
            if s.tool_contact[i].tool != NO_TOOL || step % stride != 0 {
                continue;
            }
            let (x, v) = (self.x[k], self.v[k]);
            let (start, end) = (s.homologue_in_world[i], self.homologue_end[k]);
            let homologue = start + (end - start) * fraction;
            let homologue_velocity = (end - start) / dt;
            let link = (homologue - x) * s.link_stiffness[i]
                + (homologue_velocity - v) * s.link_damping[i];
            // The rigid component's reaction over this substep (a force over the step).
            let share = stride as f64 / self.substeps as f64;
            let centre_now = centre + (end_centre - centre) * fraction;
            self.carried_force -= link * share;
            self.carried_torque -= (homologue - centre_now).cross(&link) * share;
            let mut force = gravity * s.mass[i] + self.external[i] - v * s.air_damping[i] + link;
            for at in self.start[k] as usize..self.start[k + 1] as usize {
                let j = self.neighbour[at] as usize;
                let edge = self.edge[at] as usize;
                let (xj, vj) = match self.local[j] {
                    u32::MAX => {
                        let (a, b) = (s.position_in_world[j], s.next_position_in_world[j]);
                        (a + (b - a) * fraction, (b - a) / dt)
                    }
                    l => (self.x[l as usize], self.v[l as usize]),
                };
                if let Some(pull) = spring_pull(e, edge, &x, &v, &xj, &vj) {
                    force += pull;
                    if self.local[j] == u32::MAX && !slow_nodes_integrated {
                        self.owed[j] -= pull * (h * stride as f64);
                    }
                }
            }
            self.f[k] = force;
        }
    }

    /// Substep `step`'s motion of the fast nodes due then, on the forces just taken.
    fn substep_move(&mut self, s: &crate::body::Surface, step: u32, dt: f64) {
        let h = dt / self.substeps as f64;
        for (k, &i) in self.fast.iter().enumerate() {
            let i = i as usize;
            let stride = self.substeps >> self.level[i];
            if s.tool_contact[i].tool != NO_TOOL || step % stride != 0 {
                continue;
            }
            let own = h * stride as f64;
            self.v[k] += self.f[k] * (own * s.inverse_mass[i]);
            self.x[k] += self.v[k] * own;
        }
    }

    /// What the nodes not sub-stepped are owed (each once: its debt is cleared as it is paid), as
    /// a change of their end velocity over the step.
    fn pay_owed(&mut self, s: &mut crate::body::Surface, dt: f64) {
        for k in 0..self.fast.len() {
            for at in self.start[k] as usize..self.start[k + 1] as usize {
                let j = self.neighbour[at] as usize;
                if self.local[j] != u32::MAX {
                    continue;
                }
                let held = s.tool_contact[j].tool != NO_TOOL;
                let end = (
                    &mut s.velocity_in_world[j],
                    &mut s.next_position_in_world[j],
                );
                pay_owed(&mut self.owed[j], held, s.inverse_mass[j], end, dt);
            }
        }
    }

    /// Every node and the rigid component together in substeps (the rigid component's coupling
    /// demands it). Nodes held by a tool follow their imposed trajectory, their links still pulling
    /// the rigid component. Leaves the rigid component integrated over the step.
    fn integrate_with_rigid(
        &mut self,
        body: &mut Body,
        dt: f64,
        gravity: &Vec3,
        (obstacles, reach): (&[Obstacle], &[Option<[Vec3; 2]>]),
        reactions: &mut [Vec3],
    ) -> usize {
        let Body {
            surface: s,
            edges: e,
            rigid,
            ..
        } = body;
        let n = s.mass.len();
        for i in 0..n {
            self.x[i] = s.position_in_world[i];
            self.v[i] = s.velocity_in_world[i];
        }
        let h = dt / self.substeps as f64;
        // The rigid component and the nodes its pace keeps stable step every `stride` substeps; the
        // deep nodes at their own pace in between (`step_deep`).
        let stride = self.base_stride;
        let h_base = dt / (self.substeps / stride) as f64;
        let deep = !self.deep.is_empty();
        for step in 0..self.substeps {
            let fraction = step as f64 / self.substeps as f64;
            if step % stride != 0 {
                self.step_deep(
                    s,
                    e,
                    gravity,
                    dt,
                    step,
                    fraction,
                    (obstacles, reach),
                    reactions,
                );
                continue;
            }
            // Held nodes are where the tool takes them.
            for i in 0..n {
                if s.tool_contact[i].tool != NO_TOOL {
                    let (a, b) = (s.position_in_world[i], s.next_position_in_world[i]);
                    self.x[i] = a + (b - a) * fraction;
                    self.v[i] = (b - a) / dt;
                }
            }
            rigid.reset_forces(gravity);
            let world_from_body = rigid.world_from_body.to_rotation_matrix();
            let centre = rigid.position_in_world;
            let omega = rigid.angular_velocity_in_world();
            // The deep nodes' links of the last interval, which the rigid component has not felt.
            let (mut reaction_force, mut reaction_torque) = (
                std::mem::take(&mut self.carried_force),
                std::mem::take(&mut self.carried_torque),
            );
            let finest = self.substeps.trailing_zeros();
            for i in 0..n {
                let (x, v) = (self.x[i], self.v[i]);
                let arm = world_from_body * s.homologue_in_body[i];
                let link = (centre + arm - x) * s.link_stiffness[i]
                    + (rigid.velocity_in_world + omega.cross(&arm) - v) * s.link_damping[i];
                // A deep node applies this force for its own step only (its later steps in the
                // interval are `step_deep`'s, which carry their reactions).
                let weight = if deep && s.tool_contact[i].tool == NO_TOOL {
                    (1u32 << (finest - self.level[i])) as f64 / stride as f64
                } else {
                    1.0
                };
                reaction_force -= link * weight;
                reaction_torque -= arm.cross(&link) * weight;
                self.f[i] = gravity * s.mass[i] + self.external[i] - v * s.air_damping[i] + link;
            }
            add_spring_forces(e, &self.x, &self.v, &mut self.f, self.simd);
            if deep {
                // A spring from a deep node to a coarser one: both take its force now, the coarser
                // for its whole (longer) step; the deep node takes it again at each of its later
                // steps, from the other's interpolated path, which the coarser never sees. The
                // coarser node is owed the difference (see `step_deep`), paid after the substeps.
                for (k, &d) in self.deep.iter().enumerate() {
                    let d = d as usize;
                    if s.tool_contact[d].tool != NO_TOOL {
                        continue;
                    }
                    let own = h * (1u32 << (finest - self.level[d])) as f64;
                    for at in self.start[k] as usize..self.start[k + 1] as usize {
                        let j = self.neighbour[at] as usize;
                        if self.level[j] >= self.level[d] {
                            continue;
                        }
                        let theirs = h * (1u32 << (finest - self.level[j])) as f64;
                        let (x, v, xj, vj) = (self.x[d], self.v[d], self.x[j], self.v[j]);
                        if let Some(pull) = spring_pull(e, self.edge[at] as usize, &x, &v, &xj, &vj)
                        {
                            self.owed[j] += pull * (theirs - own);
                        }
                    }
                }
                self.x_base[..n].copy_from_slice(&self.x[..n]);
            }
            for i in 0..n {
                if s.tool_contact[i].tool != NO_TOOL {
                    continue;
                }
                let step = if deep {
                    h * (1u32 << (finest - self.level[i])) as f64
                } else {
                    h_base
                };
                let start = self.x[i];
                self.v[i] += self.f[i] * (step * s.inverse_mass[i]);
                self.x[i] += self.v[i] * step;
                if meet_obstacles(
                    &start,
                    (&mut self.x[i], &mut self.v[i]),
                    (s.mass[i], step, dt),
                    (obstacles, reach),
                    reactions,
                ) {
                    self.touched[i] = true;
                }
            }
            rigid.force_in_world += reaction_force;
            rigid.torque_in_world += reaction_torque;
            if deep {
                // The deep nodes' homologues over the interval: from where the rigid component is
                // to where it will be.
                for &i in &self.deep {
                    let i = i as usize;
                    self.homologue_end[i] = centre + world_from_body * s.homologue_in_body[i];
                }
            }
            rigid.integrate(h_base);
            self.centre_interval = [centre, rigid.position_in_world];
            if deep {
                let world_from_body = rigid.world_from_body.to_rotation_matrix();
                for &i in &self.deep {
                    let i = i as usize;
                    // `f` is free until the next base step: it keeps the interval's start.
                    self.f[i] = self.homologue_end[i];
                    self.homologue_end[i] =
                        rigid.position_in_world + world_from_body * s.homologue_in_body[i];
                }
            }
        }
        // What the coarser neighbours of the deep nodes are owed, as a change of their end
        // velocity over the step (each once: its debt is cleared as it is paid).
        for k in 0..self.deep.len() {
            for at in self.start[k] as usize..self.start[k + 1] as usize {
                let j = self.neighbour[at] as usize;
                let held = s.tool_contact[j].tool != NO_TOOL;
                let end = (&mut self.v[j], &mut self.x[j]);
                pay_owed(&mut self.owed[j], held, s.inverse_mass[j], end, dt);
            }
        }
        for i in 0..n {
            if s.tool_contact[i].tool != NO_TOOL {
                continue;
            }
            s.velocity_in_world[i] = self.v[i];
            s.next_position_in_world[i] = self.x[i];
        }
        let mut touched = 0;
        for flag in &mut self.touched {
            touched += usize::from(*flag);
            *flag = false;
        }
        touched
    }

    /// Substep `step` between two updates of the rigid component: the deep nodes whose own step
    /// starts here (those of level ≥ L − trailing zeros of `step`) step, reading their neighbours
    /// where they are (if they step now too) or interpolated over their own current step, and their
    /// homologue interpolated between the rigid component's updates.
    #[allow(clippy::too_many_arguments)]
    fn step_deep(
        &mut self,
        s: &crate::body::Surface,
        e: &crate::body::Edges,
        gravity: &Vec3,
        dt: f64,
        step: u32,
        fraction: f64,
        (obstacles, reach): (&[Obstacle], &[Option<[Vec3; 2]>]),
        reactions: &mut [Vec3],
    ) {
        let finest = self.substeps.trailing_zeros();
        let h = dt / self.substeps as f64;
        let stride = self.base_stride;
        let h_base = h * stride as f64;
        let phase_base = (step % stride) as f64 / stride as f64;
        let lowest = finest - step.trailing_zeros();
        let active = self
            .deep
            .iter()
            .take_while(|&&i| self.level[i as usize] >= lowest)
            .count();
        // Forces of the nodes stepping now (the homologue's start is in `f`, its end in
        // `homologue_end`), then their update.
        for k in 0..active {
            let i = self.deep[k] as usize;
            if s.tool_contact[i].tool != NO_TOOL {
                continue;
            }
            let (x, v) = (self.x[i], self.v[i]);
            let (start, end) = (self.f[i], self.homologue_end[i]);
            let homologue = start + (end - start) * phase_base;
            let homologue_velocity = (end - start) / h_base;
            let link = (homologue - x) * s.link_stiffness[i]
                + (homologue_velocity - v) * s.link_damping[i];
            // Its reaction, for the rigid component's next update (a force over one update).
            let weight = (1u32 << (finest - self.level[i])) as f64 / stride as f64;
            let [c0, c1] = self.centre_interval;
            let arm = homologue - (c0 + (c1 - c0) * phase_base);
            self.carried_force -= link * weight;
            self.carried_torque -= arm.cross(&link) * weight;
            let mut force = gravity * s.mass[i] + self.external[i] - v * s.air_damping[i] + link;
            for at in self.start[k] as usize..self.start[k + 1] as usize {
                let j = self.neighbour[at] as usize;
                let edge = self.edge[at] as usize;
                let xj = if self.level[j] >= lowest {
                    self.x[j]
                } else {
                    let own = 1u32 << (finest - self.level[j]);
                    let phase = (step % own) as f64 / own as f64;
                    let (a, b) = (self.x_base[j], self.x[j]);
                    a + (b - a) * phase
                };
                let vj = self.v[j];
                if let Some(pull) = spring_pull(e, edge, &x, &v, &xj, &vj) {
                    force += pull;
                    // Owed to a coarser neighbour (see `integrate_with_rigid`): stepping now, it
                    // takes this force for its whole step, this node for its own; else it takes
                    // none of this one.
                    if self.level[j] < self.level[i] {
                        let own = h * (1u32 << (finest - self.level[i])) as f64;
                        self.owed[j] += if self.level[j] >= lowest {
                            pull * (h * (1u32 << (finest - self.level[j])) as f64 - own)
                        } else {
                            -pull * own
                        };
                    }
                }
            }
            self.deep_force[k] = force;
        }
        for k in 0..active {
            let i = self.deep[k] as usize;
            if s.tool_contact[i].tool != NO_TOOL {
                // Held nodes are where the tool takes them.
                let (a, b) = (s.position_in_world[i], s.next_position_in_world[i]);
                self.x[i] = a + (b - a) * fraction;
                self.v[i] = (b - a) / dt;
                continue;
            }
            let own = h * (1u32 << (finest - self.level[i])) as f64;
            let start = self.x[i];
            self.x_base[i] = start;
            self.v[i] += self.deep_force[k] * (own * s.inverse_mass[i]);
            self.x[i] += self.v[i] * own;
            if meet_obstacles(
                &start,
                (&mut self.x[i], &mut self.v[i]),
                (s.mass[i], own, dt),
                (obstacles, reach),
                reactions,
            ) {
                self.touched[i] = true;
            }
        }
    }
}

/// The force spring `edge` puts on its end at `x` (velocity `v`) from its other end at `xj` (`vj`);
/// `None` for coincident ends.
#[inline(always)]
/// Every spring's force on its two ends, added to `f` in the order of the springs: `f[a] +=`, then
/// `f[b] −=`, spring after spring (what [`spring_pull`] gives, one spring at a time). With `simd`
/// (the caller checked AVX) four springs are computed side by side with the same operations and
/// their forces added in the same order, so the bits are the same.
fn add_spring_forces(e: &crate::body::Edges, x: &[Vec3], v: &[Vec3], f: &mut [Vec3], simd: bool) {
    let mut from = 0;
    #[cfg(target_arch = "x86_64")]
    if simd {
        // SAFETY: `simd` is only set where the machine has AVX (`Multirate::set_simd`); the edges'
        // ends index the node arrays (a body's invariant, checked by the slicing below).
        from = unsafe { avx::add_spring_forces(e, x, v, f) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = simd;
    for k in from..e.len() {
        let (a, b) = (e.a[k] as usize, e.b[k] as usize);
        let Some(force) = spring_pull(e, k, &x[a], &v[a], &x[b], &v[b]) else {
            continue;
        };
        f[a] += force;
        f[b] -= force;
    }
}

#[cfg(target_arch = "x86_64")]
mod avx {
    use crate::Vec3;
    use crate::dynamics::kernel::avx::{dot3, gather_difference3};
    use std::arch::x86_64::*;

    /// The springs in blocks of four, as [`super::spring_pull`] computes one: d = x_b − x_a,
    /// l = √((dx² + dy²) + dz²), 1/l, m = k (l − L) + ((c ((u·d))) · 1/l) with u = v_b − v_a and the
    /// dot products summed in the same order, force = d · (m · 1/l); then, spring after spring, the
    /// force added to its first end and taken from its second (none when l ≤ `f64::MIN_POSITIVE`).
    /// Returns how many springs it did (the rest, fewer than four, are the caller's).
    ///
    /// # Safety
    /// The machine must have AVX.
    #[target_feature(enable = "avx")]
    pub(super) unsafe fn add_spring_forces(
        e: &crate::body::Edges,
        x: &[Vec3],
        v: &[Vec3],
        f: &mut [Vec3],
    ) -> usize {
        let blocks = e.len() / 4;
        let tiny = _mm256_set1_pd(f64::MIN_POSITIVE);
        let one = _mm256_set1_pd(1.0);
        let (xp, vp) = (x.as_ptr() as *const f64, v.as_ptr() as *const f64);
        for block in 0..blocks {
            let k0 = 4 * block;
            let a: [u32; 4] = std::array::from_fn(|l| e.a[k0 + l]);
            let b: [u32; 4] = std::array::from_fn(|l| e.b[k0 + l]);
            assert!(
                a.iter().chain(&b).all(|&i| {
                    let i = i as usize;
                    i < x.len() && i < v.len() && i < f.len()
                }),
                "a spring's end is not a node"
            );
            // SAFETY: every index is below the lengths, checked just above.
            let (d, u) = unsafe {
                (
                    gather_difference3(xp, &a, &b),
                    gather_difference3(vp, &a, &b),
                )
            };
            let length2 = dot3(d, d);
            let length = _mm256_sqrt_pd(length2);
            let inverse = _mm256_div_pd(one, length);
            let along = dot3(u, d);
            // SAFETY: k0 + 4 ≤ e.len(), the length of each of these arrays.
            let (k, c, rest) = unsafe {
                (
                    _mm256_loadu_pd(e.stiffness[k0..k0 + 4].as_ptr()),
                    _mm256_loadu_pd(e.damping[k0..k0 + 4].as_ptr()),
                    _mm256_loadu_pd(e.rest_length[k0..k0 + 4].as_ptr()),
                )
            };
            let magnitude = _mm256_add_pd(
                _mm256_mul_pd(k, _mm256_sub_pd(length, rest)),
                _mm256_mul_pd(_mm256_mul_pd(c, along), inverse),
            );
            let scale = _mm256_mul_pd(magnitude, inverse);
            // Not (l ≤ tiny): true for NaN too, as the scalar test `l <= tiny` is false for it.
            let valid = _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_NLE_UQ>(length, tiny));
            let (px, py, pz) = (
                _mm256_mul_pd(d[0], scale),
                _mm256_mul_pd(d[1], scale),
                _mm256_mul_pd(d[2], scale),
            );
            // Each lane's (x, y) as one 128-bit vector, its z alone.
            let t0 = _mm256_unpacklo_pd(px, py);
            let t1 = _mm256_unpackhi_pd(px, py);
            let xy = [
                _mm256_castpd256_pd128(t0),
                _mm256_castpd256_pd128(t1),
                _mm256_extractf128_pd::<1>(t0),
                _mm256_extractf128_pd::<1>(t1),
            ];
            let mut z = [0.0f64; 4];
            // SAFETY: a store into a local array of four.
            unsafe { _mm256_storeu_pd(z.as_mut_ptr(), pz) };
            let fp = f.as_mut_ptr() as *mut f64;
            for l in 0..4 {
                if valid & (1 << l) == 0 {
                    continue;
                }
                // SAFETY: a[l], b[l] < f.len() (checked above): 3 f64 from 3·index are inside `f`.
                // The same additions as `f[a] += force; f[b] -= force`, component by component.
                unsafe {
                    let fa = fp.add(3 * a[l] as usize);
                    _mm_storeu_pd(fa, _mm_add_pd(_mm_loadu_pd(fa), xy[l]));
                    *fa.add(2) += z[l];
                    let fb = fp.add(3 * b[l] as usize);
                    _mm_storeu_pd(fb, _mm_sub_pd(_mm_loadu_pd(fb), xy[l]));
                    *fb.add(2) -= z[l];
                }
            }
        }
        4 * blocks
    }
}

/// Pays a node what its springs to finer-stepped nodes owe it (`owed`, N s, cleared), as a change of
/// its end `velocity` and of its end `position` over the step; nothing to a node a tool holds.
fn pay_owed(
    owed: &mut Vec3,
    held: bool,
    inverse_mass: f64,
    (velocity, position): (&mut Vec3, &mut Vec3),
    dt: f64,
) {
    let owed = std::mem::replace(owed, Vec3::zeros());
    if owed == Vec3::zeros() || held {
        return;
    }
    let change = owed * inverse_mass;
    *velocity += change;
    *position += change * dt;
}

fn spring_pull(
    e: &crate::body::Edges,
    edge: usize,
    x: &Vec3,
    v: &Vec3,
    xj: &Vec3,
    vj: &Vec3,
) -> Option<Vec3> {
    let d = xj - x;
    let length = d.norm();
    if length <= f64::MIN_POSITIVE {
        return None;
    }
    let inverse_length = 1.0 / length;
    let magnitude = e.stiffness[edge] * (length - e.rest_length[edge])
        + e.damping[edge] * (vj - v).dot(&d) * inverse_length;
    Some(d * (magnitude * inverse_length))
}

/// Backward Euler on the rigid component's velocity and angular velocity alone, the nodes taken at
/// their end-of-step positions and velocities (already integrated), the links linearised in the rigid
/// motion: with e = X + a − x' and w = h k + c per link,
///
/// (M/h + ν M + Σ w) V' − (Σ w [a]×) ω' = M V/h + M g − Σ (k e − c v')
/// (Σ w [a]×) V' + (I_w/h + ν I_w + Σ w (|a|² I − a aᵀ)) ω' = I_w ω/h − Σ a × (k e − c v')
///
/// (a symmetric positive definite 6×6 system; the gyroscopic term is left out, as in the explicit
/// update). Leaves in the rigid component's force and torque what
/// its own semi-implicit update needs to reach V' and I_w ω'.
fn step_rigid_implicitly(body: &mut Body, h: f64, gravity: &Vec3) {
    use nalgebra::{Matrix3, Matrix6, Vector6};
    let Body {
        surface: s, rigid, ..
    } = body;
    if rigid.fixed {
        return;
    }
    let skew = |a: &Vec3| Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0);
    let world_from_body = rigid.world_from_body.to_rotation_matrix();
    let inertia = rigid.inertia_in_world();
    let velocity = rigid.velocity_in_world;
    let omega = rigid.angular_velocity_in_world();
    let air = 1.0 + h * rigid.air_viscosity;
    let mut translation = Matrix3::identity() * (rigid.mass * air / h);
    let mut rotation = inertia * (air / h);
    let mut coupling = Matrix3::zeros();
    // Air is in the matrix (implicit); gravity and the links' pull at the nodes' end states here.
    let mut force = rigid.mass * velocity / h + gravity * rigid.mass;
    let mut torque = inertia * omega / h;
    for i in 0..s.mass.len() {
        let arm = world_from_body * s.homologue_in_body[i];
        let w = h * s.link_stiffness[i] + s.link_damping[i];
        let stretch = rigid.position_in_world + arm - s.next_position_in_world[i];
        let pull = stretch * s.link_stiffness[i] - s.velocity_in_world[i] * s.link_damping[i];
        translation += Matrix3::identity() * w;
        rotation += (Matrix3::identity() * arm.norm_squared() - arm * arm.transpose()) * w;
        coupling += skew(&arm) * w;
        force -= pull;
        torque -= arm.cross(&pull);
    }
    let mut a = Matrix6::zeros();
    a.fixed_view_mut::<3, 3>(0, 0).copy_from(&translation);
    a.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-coupling));
    a.fixed_view_mut::<3, 3>(3, 0).copy_from(&coupling);
    a.fixed_view_mut::<3, 3>(3, 3).copy_from(&rotation);
    let b = Vector6::new(force.x, force.y, force.z, torque.x, torque.y, torque.z);
    let Some(solution) = a.lu().solve(&b) else {
        return;
    };
    let new_velocity = Vec3::new(solution[0], solution[1], solution[2]);
    let new_omega = Vec3::new(solution[3], solution[4], solution[5]);
    rigid.force_in_world = (new_velocity - velocity) * (rigid.mass / h);
    rigid.torque_in_world = inertia * (new_omega - omega) / h;
}

/// A node's substep from `start` to `x` (its velocity `v`, over `step` of the tick `dt`) met
/// against the obstacles it may end inside (beyond an obstacle's `reach` it cannot): each contact
/// corrects `x` and `v` and adds its reaction (the node's `mass`) to `reactions`. True when one
/// touched it.
fn meet_obstacles(
    start: &Vec3,
    (x, v): (&mut Vec3, &mut Vec3),
    (mass, step, dt): (f64, f64, f64),
    (obstacles, reach): (&[Obstacle], &[Option<[Vec3; 2]>]),
    reactions: &mut [Vec3],
) -> bool {
    let mut touched = false;
    for (o, (obstacle, reaction)) in obstacles.iter().zip(reactions.iter_mut()).enumerate() {
        if reach
            .get(o)
            .copied()
            .flatten()
            .is_some_and(|r| beyond(x, &r))
        {
            continue;
        }
        if let Some(plane) = point_contact_plane(obstacle, start, x) {
            let incoming = *v;
            (*v, *x) = resolve_point(start, incoming, &plane, obstacle, step);
            *reaction += (*v - incoming) * (mass / dt);
            touched = true;
        }
    }
    touched
}
