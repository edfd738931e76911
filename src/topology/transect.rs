//! Transection: when a cut separates a body's surface into parts, each part becomes a body of its own.
//!
//! After a cut step that opened edges, the parts are found by a union–find over the edge springs
//! (nodes joined by a spring are in the same part). When there are two or more:
//!
//! 1. **Caps.** Every boundary loop through a node of this step's path is closed by a cap in its rest
//!    shape: rings of nodes scaled towards the loop's centre (each ring resampled from the loop by arc
//!    length, about one edge length apart, node counts falling with the radius, as in a hexagonal
//!    disc), joined by strips that follow the arc-length fraction around the loop, and a fan at the
//!    centre. Cap triangles traverse the rim edges the other way round from the surface's triangles, so
//!    the closed part is oriented outwards as the surface was.
//!    The cap's springs are born at rest (at their present lengths).
//! 2. **Masses.** Every cap node is a convex combination of its loop's nodes (the loop's mean and the
//!    two rim nodes it was resampled between, scaled towards the mean): its rest place, its place and
//!    its velocity are those combinations, and it takes its mass from the loop's nodes with the same
//!    weights (the part's surface density times its rest area, scaled down if a rim node would give
//!    more than half its mass), and link stiffness and damping in proportion. The part's mass, centre
//!    of mass and momentum do not change; its kinetic, link and spring energies do not grow.
//! 3. **Bodies.** The part with the largest surface mass stays in the body (its nodes renumbered in
//!    order); every other part moves into a spare body reserved up front.
//! 4. **Rigid components.** Each part gets a share of the rigid mass in proportion to its surface mass,
//!    its frame's origin at the centre of mass of its nodes' rest places (so the rigid centre of mass
//!    does not move), the inertia about it of the solid its closed rest surface encloses, the parent's
//!    orientation; homologues are re-expressed in the new frame (their world positions do not move).
//!    Velocities follow the parent's rigid motion at the new origins, so that the linear momentum is
//!    the parent's exactly; the angular momentum left over from the parent's is shared by mass.
//!
//! Scratch is sized with the body's reserved room: a transection allocates nothing. Its cost is that of
//! a pass over the body's edges and a sort of its half-edges (only on ticks where a cut opened edges,
//! and the sort only when the surface did fall apart).

use crate::Vec3;
use crate::body::{Body, NewNode, RigidComponent};
use nalgebra::Matrix3;

/// Most parts one transection may produce.
pub const MAX_PARTS: usize = 8;

/// Nodes of cap ring may not be fewer than this (a smaller ring is the centre).
const MIN_RING: usize = 3;

const NONE: u32 = u32::MAX;

/// A cap triangle whose rest area is below this times its longest edge squared is degenerate (the
/// bound `check_surface` holds every triangle to, with a margin).
const DEGENERATE: f64 = 1e-8;

/// What a transection did (see [`Transector::separate`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Transection {
    /// Parts found (1: the surface holds together).
    pub parts: usize,
    /// The part the body keeps.
    pub kept: usize,
    /// Caps built.
    pub caps: u32,
    /// Loops left open (no room, or not a simple loop).
    pub caps_refused: u32,
    /// Cap triangles whose smallest angle is below `min_angle` (degrees).
    pub cap_quality_misses: u32,
    /// Smallest angle of a cap triangle (degrees; 180 when none).
    pub smallest_cap_angle_deg: f64,
}

/// Fixed scratch of the transection of one body.
#[derive(Clone, Debug)]
pub struct Transector {
    parent: crate::Room<u32>,
    /// Part of every node.
    pub part: crate::Room<u32>,
    new_index: Vec<u32>,
    marked_list: crate::Room<u32>,
    half_edges: crate::Room<(u64, u32, u32)>,
    next: Vec<u32>,
    visited: Vec<bool>,
    loop_nodes: Vec<u32>,
    arc: Vec<f64>,
    ring: Vec<u32>,
    ring_next: Vec<u32>,
    cap_area: crate::Room<f64>,
    /// Where each cap node sits among its loop's nodes (same index as `cap_area`).
    cap_source: Vec<CapSource>,
    /// Mass each node of the loop being capped gives to its cap (kg, by position in the loop).
    loop_demand: Vec<f64>,
    /// Surface mass per rest area of every part before its caps (kg/m²).
    part_density: [f64; MAX_PARTS],
    cap_nodes_from: usize,
    parts: usize,
    part_mass: [f64; MAX_PARTS],
}

/// A cap node as a convex combination of the nodes of its loop (`n` of them): weight `(1 − scale)/n`
/// on every loop node (the loop's mean), plus `scale · (1 − u)` on loop node `a` and `scale · u` on
/// loop node `b` (positions in the loop). Its rest place, world place, velocity, mass and link are
/// all drawn from the loop with these weights.
#[derive(Clone, Copy, Debug, Default)]
struct CapSource {
    scale: f64,
    a: u32,
    b: u32,
    u: f64,
}

/// Largest fraction of its mass (and link) a loop node gives to its cap.
const MAX_RIM_SHARE: f64 = 0.5;

/// Union–find root with path halving.
fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let grand = parent[parent[i as usize] as usize];
        parent[i as usize] = grand;
        i = grand;
    }
    i
}

fn triangle_area(a: &Vec3, b: &Vec3, c: &Vec3) -> f64 {
    0.5 * (b - a).cross(&(c - a)).norm()
}

/// Volume, first moment and second moment (∫ x xᵀ) of the solid a closed oriented surface encloses
/// (divergence theorem over tetrahedra from the origin).
pub fn solid_moments(positions: &[Vec3], triangles: &[[u32; 3]]) -> (f64, Vec3, Matrix3<f64>) {
    let mut volume = 0.0;
    let mut first = Vec3::zeros();
    let mut second = Matrix3::zeros();
    for t in triangles {
        let [a, b, c] = t.map(|v| positions[v as usize]);
        let det = a.dot(&b.cross(&c));
        volume += det / 6.0;
        let s = a + b + c;
        first += s * (det / 24.0);
        second += (a * a.transpose() + b * b.transpose() + c * c.transpose() + s * s.transpose())
            * (det / 120.0);
    }
    (volume, first, second)
}

/// Inertia tensor of a uniform solid of `mass` with the given moments, about the point `about`.
fn inertia_about(
    volume: f64,
    first: &Vec3,
    second: &Matrix3<f64>,
    mass: f64,
    about: &Vec3,
) -> Matrix3<f64> {
    let density = mass / volume;
    // ∫ (x − c)(x − c)ᵀ = S − c mᵀ − m cᵀ + V c cᵀ.
    let shifted = (second - about * first.transpose() - first * about.transpose()
        + about * about.transpose() * volume)
        * density;
    Matrix3::identity() * shifted.trace() - shifted
}

impl Transector {
    /// Scratch for a body of at most `nodes` nodes and `triangles` triangles.
    pub fn with_capacity(nodes: usize, triangles: usize) -> Self {
        Self {
            parent: crate::Room::with_capacity(nodes),
            part: crate::Room::with_capacity(nodes),
            new_index: Vec::with_capacity(nodes),
            marked_list: crate::Room::with_capacity(nodes),
            half_edges: crate::Room::with_capacity(3 * triangles),
            next: Vec::with_capacity(nodes),
            visited: Vec::with_capacity(nodes),
            loop_nodes: Vec::with_capacity(nodes),
            arc: Vec::with_capacity(nodes + 1),
            ring: Vec::with_capacity(nodes),
            ring_next: Vec::with_capacity(nodes),
            cap_area: crate::Room::with_capacity(nodes),
            cap_source: Vec::with_capacity(nodes),
            loop_demand: Vec::with_capacity(nodes),
            part_density: [0.0; MAX_PARTS],
            cap_nodes_from: 0,
            parts: 0,
            part_mass: [0.0; MAX_PARTS],
        }
    }

    /// Whether the scratch can serve a body of `nodes` nodes.
    pub fn fits(&self, nodes: usize, triangles: usize) -> bool {
        nodes <= self.parent.capacity() && 3 * triangles <= self.half_edges.capacity()
    }

    /// Marks a node of the cut path of this step (caps close the loops through marked nodes); marks
    /// past the scratch's room are dropped.
    pub fn mark(&mut self, node: u32) {
        if self.marked_list.len() < self.marked_list.capacity() {
            self.marked_list.push(node);
        }
    }

    /// Forgets the marks.
    pub fn clear_marks(&mut self) {
        self.marked_list.clear();
    }

    /// Finds the parts of the surface: nodes joined by edge springs. Returns how many (each node's
    /// part in [`Transector::part`], numbered in order of their first node).
    pub fn find_parts(&mut self, body: &Body) -> usize {
        let n = body.node_count();
        self.parent.clear();
        self.parent.extend(0..n as u32);
        let e = &body.edges;
        for k in 0..e.len() {
            let (ra, rb) = (
                find(&mut self.parent, e.a[k]),
                find(&mut self.parent, e.b[k]),
            );
            if ra != rb {
                let (lo, hi) = (ra.min(rb), ra.max(rb));
                self.parent[hi as usize] = lo;
            }
        }
        self.part.clear();
        self.part.resize(n, NONE);
        let mut parts = 0u32;
        for v in 0..n as u32 {
            let r = find(&mut self.parent, v);
            if self.part[r as usize] == NONE {
                self.part[r as usize] = parts;
                parts += 1;
            }
            self.part[v as usize] = self.part[r as usize];
        }
        self.parts = parts as usize;
        self.parts
    }

    /// Boundary half-edges of the surface: `next[a] = b` for every triangle edge a→b that no triangle
    /// traverses b→a. Returns the number of boundary edges.
    fn boundary_next(&mut self, body: &Body) -> u32 {
        let n = body.node_count();
        self.half_edges.clear();
        for t in &body.surface.triangles {
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                let key = ((a.min(b) as u64) << 32) | a.max(b) as u64;
                self.half_edges.push((key, a, b));
            }
        }
        self.half_edges.sort_unstable();
        self.next.clear();
        self.next.resize(n, NONE);
        let mut count = 0;
        let mut k = 0;
        while k < self.half_edges.len() {
            let mut j = k + 1;
            while j < self.half_edges.len() && self.half_edges[j].0 == self.half_edges[k].0 {
                j += 1;
            }
            if j - k == 1 {
                let (_, a, b) = self.half_edges[k];
                if self.next[a as usize] == NONE {
                    self.next[a as usize] = b;
                }
                count += 1;
            }
            k = j;
        }
        count
    }

    /// Where node `v` of the body went in the last [`Transector::separate`] that kept part `kept`:
    /// `(0, index)` in the body itself, `(1 + j, index)` in the j-th spare; `None` for a node the
    /// separation did not number (a cap node, or past the mesh it split).
    pub fn new_place(&self, v: u32, kept: usize) -> Option<(usize, u32)> {
        let (&part, &index) = (self.part.get(v as usize)?, self.new_index.get(v as usize)?);
        let part = part as usize;
        Some(if part == kept {
            (0, index)
        } else {
            (1 + part - usize::from(part > kept), index)
        })
    }

    /// Caps the open loops through marked nodes, splits the surface mass of each part between its
    /// nodes and caps, and moves every part but the heaviest into `spares` (in part order; one spare
    /// per part past the first). `min_angle` (degrees) is the quality bound counted for cap triangles.
    /// Returns what was done; `parts` < 2 when nothing changed. The caller has checked that there are
    /// enough spares.
    pub fn separate(
        &mut self,
        body: &mut Body,
        spares: &mut [Option<&mut Body>],
        min_angle: f64,
        gravity: &Vec3,
    ) -> Transection {
        let mut result = Transection {
            parts: self.parts,
            smallest_cap_angle_deg: 180.0,
            ..Transection::default()
        };
        if self.parts < 2
            || self.parts > MAX_PARTS
            || spares.iter().flatten().count() + 1 < self.parts
        {
            return result;
        }
        self.measure_parts(body);
        // 1. Caps (each takes its mass, velocity and links from its own loop).
        self.cap_loops(body, min_angle, &mut result);
        // The parent's rigid origin is off its surface's centre of mass by `offset` (rounding, or
        // masses moved by cuts and subdivision); every piece keeps that offset, so that the rigid
        // centre of mass stays where it was.
        let offset = surface_centre_of_mass(body);
        // 2. Parts into bodies: the heaviest stays.
        let kept = (0..self.parts)
            .max_by(|&a, &b| {
                self.part_mass[a]
                    .total_cmp(&self.part_mass[b])
                    .then(b.cmp(&a))
            })
            .unwrap_or(0);
        result.kept = kept;
        let parent_rigid = body.rigid.clone();
        let slot_of = self.move_parts(body, spares, kept);
        // 3. Rigid components.
        self.share_rigid(body, spares, &slot_of, (&parent_rigid, &offset), gravity);
        // Boundary counts of every piece.
        for &slot in &slot_of[..self.parts] {
            let Some(piece) = part_body(body, spares, slot) else {
                continue;
            };
            piece.boundary_edges = self.boundary_next(piece);
            piece.topology_version += 1;
            piece.refresh_diagonals();
        }
        result
    }

    /// Each part's surface mass before the caps, and its surface density (over its rest area): the
    /// caps' mass target.
    fn measure_parts(&mut self, body: &Body) {
        let n0 = body.node_count();
        self.part_mass = [0.0; MAX_PARTS];
        for v in 0..n0 {
            self.part_mass[self.part[v] as usize] += body.surface.mass[v];
        }
        let mut part_area = [0.0f64; MAX_PARTS];
        let h = &body.surface.homologue_in_body;
        for t in &body.surface.triangles {
            part_area[self.part[t[0] as usize] as usize] +=
                triangle_area(&h[t[0] as usize], &h[t[1] as usize], &h[t[2] as usize]);
        }
        let parts = 0..self.parts;
        for ((density, mass), area) in self.part_density[parts.clone()]
            .iter_mut()
            .zip(&self.part_mass[parts.clone()])
            .zip(&part_area[parts])
        {
            *density = if *area > 0.0 { mass / area } else { 0.0 };
        }
    }

    /// Walks each open loop of the boundary through a marked node and caps it (a loop that does not
    /// close, or of fewer than three nodes, is refused), counted in `result`.
    fn cap_loops(&mut self, body: &mut Body, min_angle: f64, result: &mut Transection) {
        let n0 = body.node_count();
        self.boundary_next(body);
        self.visited.clear();
        self.visited.resize(n0, false);
        self.cap_nodes_from = n0;
        self.cap_area.clear();
        self.cap_source.clear();
        for i in 0..self.marked_list.len() {
            let s = self.marked_list[i];
            if (s as usize) >= n0 || self.visited[s as usize] || self.next[s as usize] == NONE {
                continue;
            }
            // Walk the loop.
            self.loop_nodes.clear();
            let mut v = s;
            let mut closed = false;
            while self.loop_nodes.len() <= n0 {
                self.loop_nodes.push(v);
                self.visited[v as usize] = true;
                v = self.next[v as usize];
                if v == s {
                    closed = true;
                    break;
                }
                if v == NONE || self.visited[v as usize] {
                    break;
                }
            }
            if !closed || self.loop_nodes.len() < 3 {
                result.caps_refused += 1;
                continue;
            }
            if self.cap_loop(body, min_angle, result) {
                result.caps += 1;
            } else {
                result.caps_refused += 1;
            }
        }
    }

    /// Copies every part but `kept` (nodes renumbered in order, its triangles and edges) into its
    /// spare, and keeps part `kept` in `body`; returns each part's spare slot (`usize::MAX` for the
    /// kept part).
    fn move_parts(
        &mut self,
        body: &mut Body,
        spares: &mut [Option<&mut Body>],
        kept: usize,
    ) -> [usize; MAX_PARTS] {
        let n1 = body.node_count();
        let mut counts = [0u32; MAX_PARTS];
        self.new_index.clear();
        for v in 0..n1 {
            let p = self.part[v] as usize;
            self.new_index.push(counts[p]);
            counts[p] += 1;
        }
        let mut slot_of = [usize::MAX; MAX_PARTS];
        let mut next_slot = 0;
        for (p, slot) in slot_of.iter_mut().enumerate().take(self.parts) {
            if p != kept {
                *slot = next_slot;
                next_slot += 1;
            }
        }
        for spare in spares.iter_mut().flatten() {
            clear_mesh(spare);
        }
        for v in 0..n1 {
            let p = self.part[v] as usize;
            if p != kept
                && let Some(piece) = slot(spares, slot_of[p])
            {
                copy_node(
                    &body.surface,
                    v,
                    &mut piece.surface,
                    body.params.air_viscosity,
                );
            }
        }
        for t in &body.surface.triangles {
            let p = self.part[t[0] as usize] as usize;
            if p != kept
                && let Some(piece) = slot(spares, slot_of[p])
            {
                piece
                    .surface
                    .triangles
                    .push(t.map(|v| self.new_index[v as usize]));
            }
        }
        for k in 0..body.edges.len() {
            let e = &body.edges;
            let p = self.part[e.a[k] as usize] as usize;
            if p != kept
                && let Some(piece) = slot(spares, slot_of[p])
            {
                piece.edges.push(
                    self.new_index[e.a[k] as usize],
                    self.new_index[e.b[k] as usize],
                    e.rest_length[k],
                    e.stiffness[k],
                    e.damping[k],
                );
            }
        }
        self.compact(body, kept as u32);
        slot_of
    }

    /// The parent's rigid component shared between the pieces (in `body` and the spares of
    /// `slot_of`): mass in proportion to their surface mass, each rebased on its own nodes keeping
    /// the parent's `offset`, velocities from the parent's motion, and the angular momentum left
    /// over shared by mass; a piece freed from a fixed body starts where its links and weight
    /// balance.
    #[allow(clippy::needless_range_loop)] // per-part arrays indexed together
    fn share_rigid(
        &self,
        body: &mut Body,
        spares: &mut [Option<&mut Body>],
        slot_of: &[usize; MAX_PARTS],
        (parent_rigid, offset): (&RigidComponent, &Vec3),
        gravity: &Vec3,
    ) {
        let mut origins = [Vec3::zeros(); MAX_PARTS];
        let mut rigid_mass = [0.0f64; MAX_PARTS];
        let surface_total: f64 = self.part_mass[..self.parts].iter().sum();
        let mut weighted_origin = Vec3::zeros();
        for p in 0..self.parts {
            rigid_mass[p] = parent_rigid.mass * self.part_mass[p] / surface_total;
        }
        for p in 0..self.parts {
            let Some(piece) = part_body(body, spares, slot_of[p]) else {
                continue;
            };
            origins[p] = rebase_rigid(piece, parent_rigid, rigid_mass[p], offset);
            weighted_origin += origins[p] * rigid_mass[p];
        }
        weighted_origin /= parent_rigid.mass;
        let omega = parent_rigid.angular_velocity_in_world();
        let rotation = parent_rigid.world_from_body;
        let mut angular = Vec3::zeros();
        for p in 0..self.parts {
            let Some(piece) = part_body(body, spares, slot_of[p]) else {
                continue;
            };
            let r = &mut piece.rigid;
            r.velocity_in_world = parent_rigid.velocity_in_world
                + omega.cross(&(rotation * (origins[p] - weighted_origin)));
            r.angular_momentum_in_world = r.inertia_in_world() * omega;
            if r.fixed {
                r.velocity_in_world = Vec3::zeros();
                r.angular_momentum_in_world = Vec3::zeros();
            }
            angular += r.angular_momentum_in_world
                + (r.position_in_world - parent_rigid.position_in_world)
                    .cross(&(r.velocity_in_world * r.mass));
        }
        if !parent_rigid.fixed {
            let left = parent_rigid.angular_momentum_in_world - angular;
            for p in 0..self.parts {
                let Some(piece) = part_body(body, spares, slot_of[p]) else {
                    continue;
                };
                if !piece.rigid.fixed {
                    piece.rigid.angular_momentum_in_world +=
                        left * (rigid_mass[p] / parent_rigid.mass);
                }
            }
        }
        // A piece freed from a fixed body: its rigid component was held with the body, so its place
        // is free to choose; it starts where its links and its weight balance.
        if parent_rigid.fixed {
            for p in 0..self.parts {
                if let Some(piece) = part_body(body, spares, slot_of[p])
                    && !piece.rigid.fixed
                {
                    settle_freed_rigid(piece, gravity);
                }
            }
        }
    }

    /// Keeps the nodes, triangles and edges of part `kept` in the body, renumbered in order.
    fn compact(&mut self, body: &mut Body, kept: u32) {
        let n = body.node_count();
        let s = &mut body.surface;
        let mut w = 0;
        for v in 0..n {
            if self.part[v] != kept {
                continue;
            }
            if w != v {
                s.position_in_world[w] = s.position_in_world[v];
                s.next_position_in_world[w] = s.next_position_in_world[v];
                s.velocity_in_world[w] = s.velocity_in_world[v];
                s.force_in_world[w] = s.force_in_world[v];
                s.mass[w] = s.mass[v];
                s.inverse_mass[w] = s.inverse_mass[v];
                s.air_damping[w] = s.air_damping[v];
                s.homologue_in_body[w] = s.homologue_in_body[v];
                s.homologue_in_world[w] = s.homologue_in_world[v];
                s.plastic_offset_in_body[w] = s.plastic_offset_in_body[v];
                s.link_stiffness[w] = s.link_stiffness[v];
                s.link_damping[w] = s.link_damping[v];
                s.tool_contact[w] = s.tool_contact[v];
            }
            w += 1;
        }
        while s.position_in_world.len() > w {
            s.pop_node();
        }
        let mut wt = 0;
        for i in 0..s.triangles.len() {
            let t = s.triangles[i];
            if self.part[t[0] as usize] == kept {
                s.triangles[wt] = t.map(|v| self.new_index[v as usize]);
                wt += 1;
            }
        }
        s.triangles.truncate(wt);
        let e = &mut body.edges;
        let mut we = 0;
        for k in 0..e.len() {
            if self.part[e.a[k] as usize] == kept {
                e.a[we] = self.new_index[e.a[k] as usize];
                e.b[we] = self.new_index[e.b[k] as usize];
                e.rest_length[we] = e.rest_length[k];
                e.stiffness[we] = e.stiffness[k];
                e.damping[we] = e.damping[k];
                we += 1;
            }
        }
        while e.len() > we {
            e.pop();
        }
    }

    /// Closes the loop in `loop_nodes` (boundary direction) with rings and a centre; false (and the
    /// mesh unchanged) when the body has no room or the loop encloses no area.
    fn cap_loop(&mut self, body: &mut Body, min_angle: f64, result: &mut Transection) -> bool {
        let n = self.loop_nodes.len();
        let h = &body.surface.homologue_in_body;
        // Rest arc length and centre.
        self.arc.clear();
        self.arc.push(0.0);
        let mut centre = Vec3::zeros();
        let mut area_vector = Vec3::zeros();
        for i in 0..n {
            let (a, b) = (
                h[self.loop_nodes[i] as usize],
                h[self.loop_nodes[(i + 1) % n] as usize],
            );
            let last = self.arc[i];
            self.arc.push(last + (b - a).norm());
            centre += a;
            area_vector += a.cross(&b);
        }
        centre /= n as f64;
        let perimeter = self.arc[n];
        if perimeter <= 0.0 || area_vector.norm() <= 1e-12 * perimeter * perimeter {
            return false;
        }
        let spacing = perimeter / n as f64;
        let radius = self
            .loop_nodes
            .iter()
            .map(|&v| (h[v as usize] - centre).norm())
            .sum::<f64>()
            / n as f64;
        let rings_total = ((radius / (spacing * 0.866)).round() as usize).max(1);
        // Ring sizes (outer loop excluded): n (1 − k/K) nodes, at least MIN_RING.
        let mut new_nodes = 1;
        let mut new_triangles = 0;
        let mut outer = n;
        for k in 1..rings_total {
            let count = ((n as f64) * (1.0 - k as f64 / rings_total as f64)).round() as usize;
            if count < MIN_RING {
                break;
            }
            new_nodes += count;
            new_triangles += outer + count;
            outer = count;
        }
        new_triangles += outer;
        let new_edges = new_nodes + new_triangles;
        if !body.has_room(new_nodes, new_triangles, new_edges)
            || self.cap_area.len() + new_nodes > self.cap_area.capacity()
            || body.node_count() + new_nodes > self.part.capacity()
        {
            return false;
        }
        let part = self.part[self.loop_nodes[0] as usize];
        let first_cap_node = body.node_count();
        let first_edge = body.edges.len();
        let (k_edge, c_edge) = (body.params.surface_stiffness, body.params.surface_damping);
        let nu = body.params.air_viscosity;
        let centre_world = {
            let x = &body.surface.position_in_world;
            self.loop_nodes.iter().map(|&v| x[v as usize]).sum::<Vec3>() / n as f64
        };
        // Current ring: the loop itself.
        self.ring.clear();
        self.ring.extend_from_slice(&self.loop_nodes);
        let mut ring_is_loop = true;
        let first_triangle = body.surface.triangles.len();
        for k in 1..=rings_total {
            let scale = 1.0 - k as f64 / rings_total as f64;
            let count = ((n as f64) * scale).round() as usize;
            self.ring_next.clear();
            if k < rings_total && count >= MIN_RING {
                // Resample the loop at `count` equal arc lengths, scaled towards the centre.
                let mut j = 0;
                for l in 0..count {
                    let target = perimeter * l as f64 / count as f64;
                    while j + 1 < n && self.arc[j + 1] <= target {
                        j += 1;
                    }
                    let u = ((target - self.arc[j]) / (self.arc[j + 1] - self.arc[j]).max(1e-300))
                        .clamp(0.0, 1.0);
                    let (a, b) = (
                        self.loop_nodes[j] as usize,
                        self.loop_nodes[(j + 1) % n] as usize,
                    );
                    let s = &body.surface;
                    let rest = s.homologue_in_body[a].lerp(&s.homologue_in_body[b], u);
                    let world = s.position_in_world[a].lerp(&s.position_in_world[b], u);
                    let node = self.push_cap_node(
                        body,
                        centre + (rest - centre) * scale,
                        centre_world + (world - centre_world) * scale,
                        nu,
                        part,
                        CapSource {
                            scale,
                            a: j as u32,
                            b: ((j + 1) % n) as u32,
                            u,
                        },
                    );
                    self.ring_next.push(node);
                }
                // Ring edges.
                for l in 0..count {
                    let (a, b) = (self.ring_next[l], self.ring_next[(l + 1) % count]);
                    push_rest_edge(body, a, b, k_edge, c_edge);
                }
                // Strip between the current ring and the next.
                let m = self.ring.len();
                let (mut j, mut l) = (0usize, 0usize);
                while j < m || l < count {
                    let outer_next = (j + 1) as f64 / m as f64;
                    let inner_next = (l + 1) as f64 / count as f64;
                    let outer_frac = if ring_is_loop {
                        self.arc[(j + 1).min(n)] / perimeter
                    } else {
                        outer_next
                    };
                    let advance_outer = l == count || (j < m && outer_frac <= inner_next);
                    let (a_j, b_l) = (self.ring[j % m], self.ring_next[l % count]);
                    if advance_outer {
                        let a_next = self.ring[(j + 1) % m];
                        self.push_cap_triangle(body, [a_next, a_j, b_l]);
                        push_rest_edge(body, a_next, b_l, k_edge, c_edge);
                        j += 1;
                    } else {
                        let b_next = self.ring_next[(l + 1) % count];
                        self.push_cap_triangle(body, [b_l, b_next, a_j]);
                        push_rest_edge(body, b_next, a_j, k_edge, c_edge);
                        l += 1;
                    }
                }
                // Each strip triangle added one rung; the last is the first triangle's starting
                // rung (ring[0]–ring_next[0]), created only then: m + count rungs, all distinct.
                std::mem::swap(&mut self.ring, &mut self.ring_next);
                ring_is_loop = false;
            } else {
                // The centre, fanned to the current ring.
                let centre_node =
                    self.push_cap_node(body, centre, centre_world, nu, part, CapSource::default());
                let m = self.ring.len();
                for l in 0..m {
                    let (a, b) = (self.ring[l], self.ring[(l + 1) % m]);
                    self.push_cap_triangle(body, [b, a, centre_node]);
                    push_rest_edge(body, a, centre_node, k_edge, c_edge);
                }
                break;
            }
        }
        // A loop that folds back on itself (a slit whose two lips meet at copies of one node, the
        // same rest place) can put the cap's centre on the line of a rim edge: a cap with a
        // degenerate triangle is taken back, and the loop left open.
        let degenerate = body.surface.triangles[first_triangle..].iter().any(|t| {
            let [a, b, c] = t.map(|v| body.surface.homologue_in_body[v as usize]);
            let longest = (b - a)
                .norm_squared()
                .max((c - b).norm_squared())
                .max((a - c).norm_squared());
            0.5 * (b - a).cross(&(c - a)).norm() < DEGENERATE * longest
        });
        if degenerate {
            body.surface.triangles.truncate(first_triangle);
            while body.edges.len() > first_edge {
                body.edges.pop();
            }
            while body.node_count() > first_cap_node {
                body.surface.pop_node();
            }
            let kept = first_cap_node - self.cap_nodes_from;
            self.part.truncate(first_cap_node);
            self.cap_area.truncate(kept);
            self.cap_source.truncate(kept);
            return false;
        }
        self.draw_cap_from_loop(body, first_cap_node, part as usize);
        // Quality of the cap, and the rim edges are no longer boundary.
        let h = &body.surface.homologue_in_body;
        for t in &body.surface.triangles[first_triangle..] {
            let angle = crate::topology::refine::min_angle_deg(&t.map(|v| h[v as usize]));
            result.smallest_cap_angle_deg = result.smallest_cap_angle_deg.min(angle);
            if angle < min_angle {
                result.cap_quality_misses += 1;
            }
        }
        true
    }

    /// Appends a cap node of part `part` at rest position `rest` (body frame) and `world`, both the
    /// combination `source` of its loop's; its mass, velocity and link are drawn from the loop once the
    /// cap is built ([`Transector::draw_cap_from_loop`]).
    fn push_cap_node(
        &mut self,
        body: &mut Body,
        rest: Vec3,
        world: Vec3,
        nu: f64,
        part: u32,
        source: CapSource,
    ) -> u32 {
        body.surface.push_node(
            NewNode {
                position_in_world: world,
                next_position_in_world: world,
                velocity_in_world: Vec3::zeros(),
                mass: 1.0,
                homologue_in_body: rest,
                homologue_in_world: world,
                plastic_offset_in_body: Vec3::zeros(),
                link_stiffness: 0.0,
                link_damping: 0.0,
            },
            nu,
        );
        self.part.push(part);
        self.cap_area.push(0.0);
        self.cap_source.push(source);
        (body.node_count() - 1) as u32
    }

    /// Appends a cap triangle and gives a third of its rest area to each of its cap corners.
    fn push_cap_triangle(&mut self, body: &mut Body, t: [u32; 3]) {
        let h = &body.surface.homologue_in_body;
        let area = triangle_area(&h[t[0] as usize], &h[t[1] as usize], &h[t[2] as usize]);
        for v in t {
            if (v as usize) >= self.cap_nodes_from {
                self.cap_area[v as usize - self.cap_nodes_from] += area / 3.0;
            }
        }
        body.surface.triangles.push(t);
    }

    /// Gives the cap nodes from `first` on (the cap of the loop in `loop_nodes`, of part `part`) their
    /// mass, velocity and link, drawn from the loop's nodes with the weights the cap nodes' places
    /// were drawn with ([`CapSource`]). A cap node's target mass is the part's surface density times
    /// its rest area; all targets are scaled down together when a loop node would give more than
    /// [`MAX_RIM_SHARE`] of its mass. A loop node gives its link stiffness and damping in the
    /// proportion it gives its mass.
    ///
    /// Since a cap node's place, rest place and velocity are the same convex combination of the loop's
    /// as the mass it takes from them, the cap changes neither the mass, the centre of mass nor the
    /// momentum of the part; its kinetic and link energies are at most those the loop gave up
    /// (Jensen's inequality, exact when the loop's links are equally stiff per kilogram); its springs
    /// are born at rest. A cap adds no energy.
    fn draw_cap_from_loop(&mut self, body: &mut Body, first: usize, part: usize) {
        let n = self.loop_nodes.len();
        let s = &mut body.surface;
        let from = self.cap_nodes_from;
        let cap_count = s.mass.len() - first;
        self.loop_demand.clear();
        self.loop_demand.resize(n, 0.0);
        let density = self.part_density[part];
        let mut mean_demand = 0.0;
        for c in first..first + cap_count {
            let target = density * self.cap_area[c - from];
            let src = self.cap_source[c - from];
            // The mean's share (on every loop node), then the two nodes it was resampled between.
            mean_demand += target * (1.0 - src.scale) / n as f64;
            self.loop_demand[src.a as usize] += target * src.scale * (1.0 - src.u);
            self.loop_demand[src.b as usize] += target * src.scale * src.u;
        }
        let mut scale: f64 = 1.0;
        // The loop's mean velocity and link stiffness and damping per kilogram.
        let (mut mean_velocity, mut mean_k, mut mean_c) = (Vec3::zeros(), 0.0, 0.0);
        for (j, d) in self.loop_demand.iter_mut().enumerate() {
            let v = self.loop_nodes[j] as usize;
            *d += mean_demand;
            if *d > 0.0 {
                scale = scale.min(MAX_RIM_SHARE * s.mass[v] / *d);
            }
            mean_velocity += s.velocity_in_world[v];
            mean_k += s.link_stiffness[v] / s.mass[v];
            mean_c += s.link_damping[v] / s.mass[v];
        }
        mean_velocity /= n as f64;
        mean_k /= n as f64;
        mean_c /= n as f64;
        let nu = body.params.air_viscosity;
        for c in first..first + cap_count {
            let src = self.cap_source[c - from];
            let mass = scale * density * self.cap_area[c - from];
            let (a, b) = (
                self.loop_nodes[src.a as usize] as usize,
                self.loop_nodes[src.b as usize] as usize,
            );
            let (t, u) = (src.scale, src.u);
            let velocity = mean_velocity * (1.0 - t)
                + (s.velocity_in_world[a] * (1.0 - u) + s.velocity_in_world[b] * u) * t;
            // Node j gives the fraction mass · w_j / m_j of its mass, and as much of its link.
            let per_kg = |q: &[f64]| (q[a] / s.mass[a] * (1.0 - u) + q[b] / s.mass[b] * u) * t;
            let k = mass * (mean_k * (1.0 - t) + per_kg(&s.link_stiffness));
            let damping = mass * (mean_c * (1.0 - t) + per_kg(&s.link_damping));
            s.velocity_in_world[c] = velocity;
            s.mass[c] = mass;
            s.inverse_mass[c] = 1.0 / mass;
            s.air_damping[c] = nu * mass;
            s.link_stiffness[c] = k;
            s.link_damping[c] = damping;
        }
        for (j, &v) in self.loop_nodes.iter().enumerate() {
            let v = v as usize;
            let given = scale * self.loop_demand[j];
            let keep = 1.0 - given / s.mass[v];
            s.link_stiffness[v] *= keep;
            s.link_damping[v] *= keep;
            s.mass[v] -= given;
            s.inverse_mass[v] = 1.0 / s.mass[v];
            s.air_damping[v] = nu * s.mass[v];
        }
    }
}

/// The mass-weighted mean of `body`'s nodes' rest places (body frame).
fn surface_centre_of_mass(body: &Body) -> Vec3 {
    let s = &body.surface;
    let mut first = Vec3::zeros();
    for (h, m) in s.homologue_in_body.iter().zip(&s.mass) {
        first += h * *m;
    }
    first / s.mass.iter().sum::<f64>()
}

/// The body a part goes to: the body itself for the kept part (`slot` = `usize::MAX`), otherwise the
/// spare in `slot`.
fn part_body<'a>(
    body: &'a mut Body,
    spares: &'a mut [Option<&mut Body>],
    slot_index: usize,
) -> Option<&'a mut Body> {
    if slot_index == usize::MAX {
        Some(body)
    } else {
        slot(spares, slot_index)
    }
}

/// The spare in slot `i`, if any.
fn slot<'a>(spares: &'a mut [Option<&mut Body>], i: usize) -> Option<&'a mut Body> {
    spares.get_mut(i)?.as_deref_mut()
}

/// Appends a spring between `a` and `b` at rest at their present distance (a cap is born unstressed).
fn push_rest_edge(body: &mut Body, a: u32, b: u32, stiffness: f64, damping: f64) {
    let x = &body.surface.position_in_world;
    let rest = (x[a as usize] - x[b as usize]).norm();
    body.edges.push(a, b, rest, stiffness, damping);
}

/// Empties a body's mesh (its buffers keep their room).
fn clear_mesh(body: &mut Body) {
    while body.node_count() > 0 {
        body.surface.pop_node();
    }
    body.surface.triangles.clear();
    while !body.edges.is_empty() {
        body.edges.pop();
    }
}

/// Appends node `v` of `from` to `to`, with its whole state (air damping and inverse mass follow the
/// mass; the force is the next tick's to accumulate).
fn copy_node(
    from: &crate::body::Surface,
    v: usize,
    to: &mut crate::body::Surface,
    air_viscosity: f64,
) {
    to.push_node(
        NewNode {
            position_in_world: from.position_in_world[v],
            next_position_in_world: from.next_position_in_world[v],
            velocity_in_world: from.velocity_in_world[v],
            mass: from.mass[v],
            homologue_in_body: from.homologue_in_body[v],
            homologue_in_world: from.homologue_in_world[v],
            plastic_offset_in_body: from.plastic_offset_in_body[v],
            link_stiffness: from.link_stiffness[v],
            link_damping: from.link_damping[v],
        },
        air_viscosity,
    );
    if let Some(contact) = to.tool_contact.last_mut() {
        *contact = from.tool_contact[v];
    }
}

/// Moves the rigid component of a piece just freed from a fixed body (at rest, held until now) to where
/// the pull of its links on it balances its weight, the minimum over its position of link energy plus
/// its potential energy: `X = (Σ kᵢ (xᵢ − R hᵢ) + m g) / Σ kᵢ`. The links' stored energy (a piece torn
/// out of a held organ may be far from its rest place) is released with the tear, not flung at the
/// tool; the energy cannot grow, since the old place was a candidate.
fn settle_freed_rigid(piece: &mut Body, gravity: &Vec3) {
    let s = &mut piece.surface;
    let r = &mut piece.rigid;
    let rotation = r.world_from_body.to_rotation_matrix();
    let mut pull = *gravity * r.mass;
    let mut stiffness = 0.0;
    for i in 0..s.mass.len() {
        let k = s.link_stiffness[i];
        pull += (s.position_in_world[i] - rotation * s.homologue_in_body[i]) * k;
        stiffness += k;
    }
    if stiffness <= 0.0 || !stiffness.is_finite() {
        return;
    }
    let place = pull / stiffness;
    if !place.iter().all(|c| c.is_finite()) {
        return;
    }
    r.position_in_world = place;
    for i in 0..s.mass.len() {
        s.homologue_in_world[i] = place + rotation * s.homologue_in_body[i];
    }
}

/// Gives `piece` (homologues still in the parent's frame) a rigid component of `mass`: origin at the
/// centre of mass of its surface nodes' rest places (as a body's is when it is built) less the
/// parent's `offset` from its own, the inertia about it of the solid its closed rest surface encloses,
/// the parent's orientation and state; re-expresses the homologues. Returns the new origin in the
/// parent's body frame.
///
/// With each piece's rigid mass in proportion to its surface mass, the pieces' rigid centre of mass
/// is then the parent's exactly (the caps take their mass from their loops at their own centre): the
/// rigid mass does not rise or fall.
fn rebase_rigid(piece: &mut Body, parent: &RigidComponent, mass: f64, offset: &Vec3) -> Vec3 {
    let s = &mut piece.surface;
    let (volume, first, second) = solid_moments(&s.homologue_in_body, &s.triangles);
    let surface_mass: f64 = s.mass.iter().sum();
    let mut origin = Vec3::zeros();
    for (h, m) in s.homologue_in_body.iter().zip(&s.mass) {
        origin += h * *m;
    }
    origin = origin / surface_mass - offset;
    // The enclosed solid's inertia, when the piece encloses one: an open piece's moments need not
    // give a positive definite tensor (its "volume" is not a solid's), and then it is not used.
    let solid = (volume > 0.0 && volume.is_finite())
        .then(|| inertia_about(volume, &first, &second, mass, &origin))
        .filter(|inertia| inertia.symmetric_eigenvalues().min() > 0.0);
    let inertia = solid.unwrap_or_else(|| {
        // Not closed (a shred whose opening could not be capped): the inertia of the rigid mass
        // spread as the surface's is (over its homologues), with an isotropic floor of a tenth of its
        // polar part so that a flat or thin shred stays invertible.
        let mut inertia = Matrix3::zeros();
        for (h, m) in s.homologue_in_body.iter().zip(&s.mass) {
            let r = h - origin;
            inertia += (Matrix3::identity() * r.norm_squared() - r * r.transpose()) * *m;
        }
        inertia *= mass / surface_mass;
        let floor = 0.05 * inertia.trace();
        let floor = if floor > 0.0 && floor.is_finite() {
            floor
        } else {
            mass * 1e-6
        };
        inertia + Matrix3::identity() * floor
    });
    for h in &mut s.homologue_in_body {
        *h -= origin;
    }
    let inverse = inertia
        .try_inverse()
        .unwrap_or_else(|| Matrix3::identity() / mass);
    let r = &mut piece.rigid;
    *r = parent.clone();
    r.mass = mass;
    r.inertia_in_body = inertia;
    r.inverse_inertia_in_body = inverse;
    r.position_in_world = parent.position_in_world + parent.world_from_body * origin;
    r.fixed = piece.params.fixed;
    origin
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::{BodyParams, Placement};

    /// A shred whose opening was not capped (an open patch of a sphere) gets a rigid component with
    /// an inertia in kg·m² of its own size, positive definite, not a unit-radius point mass's.
    #[test]
    fn an_open_shred_gets_the_inertia_of_its_own_spread() {
        let mesh = crate::scene::mesh::icosphere(0.01, 1);
        let mut body = Body::new(
            "shred",
            &mesh,
            &BodyParams::default(),
            &Placement::default(),
        );
        // Keep the triangles of the cap z > 0.005 only (the rest of the nodes keep their places).
        let x = body.surface.homologue_in_body.clone();
        body.surface
            .triangles
            .retain(|t| t.iter().all(|&v| x[v as usize].z > 0.005));
        assert!(!body.surface.triangles.is_empty());
        let parent = body.rigid.clone();
        rebase_rigid(&mut body, &parent, 0.01, &Vec3::zeros());
        let inertia = body.rigid.inertia_in_body;
        let eigen = inertia.symmetric_eigenvalues();
        let largest = eigen.max();
        // Nodes lie within 1 cm of the centre: the inertia of 10 g is below 0.01 × (0.02 m)².
        assert!(largest < 0.01 * 0.02 * 0.02, "{inertia}");
        assert!(eigen.min() > 0.0, "{inertia}");
        assert!((body.rigid.inverse_inertia_in_body * inertia - Matrix3::identity()).norm() < 1e-9);
    }
}
