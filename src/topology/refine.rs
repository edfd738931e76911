//! Refinement driven by contact (paper §5): where the surface between the nodes a tool holds cuts
//! into the tool — a probe finer than the mesh pressed between nodes, or the chord between two held
//! nodes across a curved tool — a node is inserted at the deepest point (inside the triangle, or on
//! its edge when the point is near one) and the tool takes hold of it at once. Refinement goes on,
//! one node per tool per tick, until the surface follows the tool within the tolerance; then the
//! triangles around the held nodes are bisected on their longest edge down to the contact zone's
//! edge length (`zone_edge`, by default 1.6 times the tool's radius), so that the dent, not only the
//! contact point, is resolved. Limits: depth (a new node is one deeper than its deepest corner),
//! shortest rest edge, smallest angle of a new triangle ([`MIN_ANGLE_DEG`]), lightest node
//! ([`MIN_MASS_FRACTION`]), and the reserved pool.
//!
//! Coarsening: once no tool has held the newest inserted node for the configured delay, it is
//! removed (newest first, so every removal restores exactly what its insertion changed).

use super::{
    InsertionLog, POOL_NODES, SubdivisionSettings, coarsen_last, subdivide_edge, subdivide_face,
};
use crate::Vec3;
use crate::body::Body;
use crate::collision::tool::{closest_point_on_triangle, segment_triangle_distance, tool_reach};
use crate::contact::tool::{JawHold, NO_TOOL, ToolContact};
use crate::tool::Tool;

/// Barycentric weight under which the contact point is taken to lie on the opposite edge.
pub const EDGE_SNAP: f64 = 0.2;

/// Lightest node a refinement may leave, as a fraction of the body's mean node mass at start: the
/// paper's mass rule takes a share from the corners at every split, so a corner split again and again
/// grows ever lighter (and faster). A floor keeps the multi-rate sub-stepping bounded (ω grows as
/// 1/√m: at 1/64 of the mean mass, three more halvings of the step than the body needs at start).
pub const MIN_MASS_FRACTION: f64 = 1.0 / 64.0;

/// Smallest angle a refinement may create in a triangle (degrees, at rest); insertions that would
/// go below are refused (and counted).
pub const MIN_ANGLE_DEG: f64 = 12.0;

/// Counters of a body's refinement.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RefinementCounters {
    /// Nodes inserted inside a triangle.
    pub face_splits: u64,
    /// Nodes inserted on an edge.
    pub edge_splits: u64,
    /// Inserted nodes removed again.
    pub coarsened: u64,
    /// Refinements a limit refused (depth, edge length, angle, pool).
    pub refused: u64,
}

/// The refinement state of one body.
#[derive(Clone, Debug)]
pub struct Refinement {
    /// Settings from the scene.
    pub settings: SubdivisionSettings,
    /// What was inserted, newest last.
    pub log: InsertionLog,
    /// Refinement depth of every node (0 for the original mesh).
    depth: Vec<u8>,
    /// Tick at which each inserted node was last held by a tool.
    last_held: Vec<u64>,
    /// Counters since the start.
    pub counters: RefinementCounters,
    /// Tick at whose end the mesh last changed (0: never).
    pub changed_at: u64,
    /// Lightest node mass a split may leave (kg).
    min_mass: f64,
}

/// What to insert.
#[derive(Clone, Copy, Debug)]
enum Split {
    Face { triangle: usize, w: [f64; 3] },
    Edge { a: u32, b: u32, t: f64 },
}

impl Refinement {
    /// State for `body`, with room for [`POOL_NODES`] insertions.
    pub fn new(body: &Body, settings: SubdivisionSettings) -> Self {
        let mut depth =
            Vec::with_capacity(body.mesh_capacity().0.max(body.node_count() + POOL_NODES));
        depth.resize(body.node_count(), 0);
        Self {
            settings,
            log: InsertionLog::default(),
            depth,
            last_held: Vec::with_capacity(POOL_NODES),
            counters: RefinementCounters::default(),
            changed_at: 0,
            min_mass: MIN_MASS_FRACTION * body.surface_mass() / body.node_count().max(1) as f64,
        }
    }

    /// Makes the refined mesh permanent (after a cut changed the body): nothing inserted so far will
    /// be coarsened, and nodes the cut added get depth 0.
    pub fn commit(&mut self, body: &Body) {
        self.log.clear();
        self.last_held.clear();
        self.depth.resize(body.node_count(), 0);
    }

    /// Starts again on a body whose nodes were renumbered (a transection): nothing to coarsen, every
    /// node at depth 0, counters kept. Allocation-free within the reserved room.
    pub fn renumbered(&mut self, body: &Body) {
        self.log.clear();
        self.last_held.clear();
        self.depth.clear();
        self.depth.resize(body.node_count(), 0);
    }

    /// Nodes inserted and not yet removed.
    pub fn inserted_nodes(&self) -> usize {
        self.log.len()
    }

    /// Refinement depth of a node.
    pub fn depth_of(&self, node: usize) -> u8 {
        self.depth.get(node).copied().unwrap_or(0)
    }

    /// Inserts at most one node per tool where the surface, at the end of the tick, cuts deepest
    /// into the tool (deeper than the tolerance), and lets the tool hold it; returns how many nodes
    /// were inserted.
    /// Tools whose bit is set in `skip` (bit k for tool k) are left out: blades cutting the body.
    pub fn refine_at_tools(
        &mut self,
        body: &mut Body,
        tools: &[Tool],
        skip: u64,
        tick: u64,
        dt: f64,
    ) -> u32 {
        let mut inserted = 0;
        for (tool_index, tool) in tools.iter().enumerate() {
            if tool_index < 64 && skip & (1 << tool_index) != 0 {
                continue;
            }
            let Some((split, part)) = self
                .cut_split(body, tool, tool_index as u32)
                .or_else(|| self.sizing_split(body, tool, tool_index as u32))
            else {
                continue;
            };
            if self.too_light(body, split) {
                self.counters.refused += 1;
                continue;
            }
            let result = match split {
                Split::Face { triangle, w } => subdivide_face(
                    body,
                    &mut self.log,
                    triangle,
                    w,
                    self.settings.rule,
                    self.settings.min_edge,
                ),
                Split::Edge { a, b, t } => subdivide_edge(
                    body,
                    &mut self.log,
                    a,
                    b,
                    t,
                    self.settings.rule,
                    self.settings.min_edge,
                ),
            };
            let Ok(p) = result else {
                self.counters.refused += 1;
                continue;
            };
            match split {
                Split::Face { .. } => self.counters.face_splits += 1,
                Split::Edge { .. } => self.counters.edge_splits += 1,
            }
            let corner_depth = match split {
                Split::Face { triangle, .. } => {
                    let t = body.surface.triangles[triangle];
                    t.iter()
                        .filter(|&&v| v != p)
                        .map(|&v| self.depth[v as usize])
                        .max()
                }
                Split::Edge { a, b, .. } => {
                    Some(self.depth[a as usize].max(self.depth[b as usize]))
                }
            };
            self.depth.push(corner_depth.unwrap_or(0) + 1);
            self.last_held.push(tick);
            self.changed_at = tick;
            inserted += 1;
            // A new node inside the tool (at the deepest cut, always) is held by it from now on, on
            // its surface.
            let s = &mut body.surface;
            let p = p as usize;
            let capsule = &tool.parts_end[part];
            let inside = s.next_position_in_world[p];
            if capsule.signed_distance(&inside) < 0.0 {
                let away = (inside - capsule.closest_on_segment(&inside))
                    .try_normalize(1e-15)
                    .unwrap_or(Vec3::z());
                let (on_surface, _) = capsule.project_to_surface(&inside, &away);
                s.tool_contact[p] = ToolContact {
                    tool: tool_index as u32,
                    part: part as u32,
                    point_in_tool: tool.pose.to_tool(&on_surface),
                    // Between the jaws of a grasper that holds: held with them.
                    grasp: (tool.grasping
                        && part < 2
                        && crate::contact::tool::between_jaws(
                            tool,
                            part,
                            &tool.pose.to_tool(&on_surface),
                            0.5 * tool.jaw,
                        ))
                    .then(|| JawHold::on_part(part, 0.5 * tool.jaw.max(0.0))),
                };
                // A position correction, like the projection of a penetrating node: the node keeps
                // the velocity its corners gave it (momentum), it does not fly out of the tool.
                s.next_position_in_world[p] = on_surface;
                s.position_in_world[p] = on_surface - s.velocity_in_world[p] * dt;
            }
        }
        inserted
    }

    /// Where the surface cuts deepest into the tool: the split that puts a node there, and the tool
    /// part. Counts a refusal when a limit stops it.
    fn cut_split(&mut self, body: &Body, tool: &Tool, tool_index: u32) -> Option<(Split, usize)> {
        let (triangle, part) = self.deepest_cut(body, tool, tool_index)?;
        let capsule = &tool.parts_end[part];
        let tri = body.surface.triangles[triangle];
        let [a, b, c] = tri.map(|v| body.surface.next_position_in_world[v as usize]);
        // The triangle's point deepest in the capsule (alternating closest points).
        let mut on_axis = capsule.closest_on_segment(&((a + b + c) / 3.0));
        let mut q = closest_point_on_triangle(&on_axis, &a, &b, &c);
        for _ in 0..2 {
            on_axis = capsule.closest_on_segment(&q);
            q = closest_point_on_triangle(&on_axis, &a, &b, &c);
        }
        let w = barycentric(&q, &a, &b, &c)?;
        let split = if w.iter().filter(|&&x| x < EDGE_SNAP).count() >= 2 {
            // Near a corner: only a cut deep enough along its edges is worth a node.
            corner_split(body, triangle, w, capsule, self.settings.tolerance)?
        } else {
            let Some(split) = choose_split(body, triangle, w) else {
                self.counters.refused += 1;
                return None;
            };
            split
        };
        Some((split, part))
    }

    /// Whether the split would leave a node lighter than the floor.
    fn too_light(&self, body: &Body, split: Split) -> bool {
        let m = &body.surface.mass;
        let check = |corners: &[u32], w: &[f64]| {
            let first: f64 = corners
                .iter()
                .zip(w)
                .map(|(&c, &wk)| wk * m[c as usize])
                .sum();
            let second: f64 = corners
                .iter()
                .zip(w)
                .map(|(&c, &wk)| wk * wk * m[c as usize])
                .sum();
            let r = 1.0 / (1.0 + second / first);
            let taken: f64 = corners
                .iter()
                .zip(w)
                .map(|(&c, &wk)| r * wk * m[c as usize])
                .sum();
            taken < self.min_mass
                || corners
                    .iter()
                    .zip(w)
                    .any(|(&c, &wk)| (1.0 - r * wk) * m[c as usize] < self.min_mass)
        };
        match split {
            Split::Face { triangle, w } => {
                let sum: f64 = w.iter().sum();
                check(&body.surface.triangles[triangle], &w.map(|x| x / sum))
            }
            Split::Edge { a, b, t } => check(&[a, b], &[1.0 - t, t]),
        }
    }

    /// Sizing of the contact zone, once the surface follows the tool: among the triangles with a
    /// corner the tool holds, the one with the longest rest edge, when longer than the zone edge
    /// (`zone_edge`, or 1.6 times the radius of the tool part holding that corner), is bisected on that
    /// edge. So the dent around a contact is meshed at about the tool's size, not only at the point.
    fn sizing_split(
        &mut self,
        body: &Body,
        tool: &Tool,
        tool_index: u32,
    ) -> Option<(Split, usize)> {
        let s = &body.surface;
        let h = &s.homologue_in_body;
        let longest_edge = |tri: &[u32; 3]| {
            (0..3)
                .map(|k| {
                    let (a, b) = (tri[k], tri[(k + 1) % 3]);
                    ((h[b as usize] - h[a as usize]).norm(), a, b)
                })
                .max_by(|x, y| x.0.total_cmp(&y.0))
                .unwrap_or((0.0, tri[0], tri[1]))
        };
        let mut best: Option<(f64, u32, u32, usize)> = None;
        for tri in &s.triangles {
            let Some(&held) = tri
                .iter()
                .find(|&&v| s.tool_contact[v as usize].tool == tool_index)
            else {
                continue;
            };
            let part = s.tool_contact[held as usize].part as usize;
            let target = match self.settings.zone_edge {
                Some(edge) => edge,
                None if part < tool.part_count => 1.6 * tool.parts_end[part].radius,
                None => continue,
            };
            if tri
                .iter()
                .map(|&v| self.depth[v as usize])
                .max()
                .unwrap_or(0)
                >= self.settings.max_depth
            {
                continue;
            }
            let (length, a, b) = longest_edge(tri);
            if length > target.max(2.0 * self.settings.min_edge)
                && best.is_none_or(|(l, ..)| length > l)
            {
                best = Some((length, a, b, part));
            }
        }
        let (_, a, b, part) = best?;
        match edge_split(body, a, b, 0.5) {
            Some(split) => Some((split, part)),
            None => {
                self.counters.refused += 1;
                None
            }
        }
    }

    /// The refinable triangle whose surface cuts deepest into the tool (beyond the tolerance), and
    /// the tool part it cuts.
    fn deepest_cut(&self, body: &Body, tool: &Tool, tool_index: u32) -> Option<(usize, usize)> {
        let reach = tool_reach(tool, 0.0);
        let s = &body.surface;
        let x = &s.next_position_in_world;
        let mut deepest: Option<(f64, usize, usize)> = None;
        for (t, tri) in s.triangles.iter().enumerate() {
            let [a, b, c] = tri.map(|v| x[v as usize]);
            let lo = a.inf(&b).inf(&c);
            let hi = a.sup(&b).sup(&c);
            if !reach.overlaps_segment(&lo, &hi) {
                continue;
            }
            if tri
                .iter()
                .map(|&v| self.depth[v as usize])
                .max()
                .unwrap_or(0)
                >= self.settings.max_depth
            {
                continue;
            }
            let held_here = held_from_outside(body, tool, tool_index, tri).is_some();
            for (k, part) in tool.parts_end[..tool.part_count].iter().enumerate() {
                let cut = part.radius - segment_triangle_distance(&part.a, &part.b, &a, &b, &c);
                if cut <= self.settings.tolerance || deepest.is_some_and(|(d, _, _)| cut <= d) {
                    continue;
                }
                // A cut growing from a contact the tool holds from outside, or one by a tool that was
                // on the triangle's outer side at the start of the tick. A tool inside the tissue (it
                // slipped in where a split was refused) meets the surface from within on its way
                // out: a node inserted there would be held on the wrong side of the tool and dragged.
                if !held_here {
                    let x0 = &s.position_in_world;
                    let [a0, b0, c0] = tri.map(|v| x0[v as usize]);
                    let outward = (b0 - a0).cross(&(c0 - a0));
                    let axis = tool.parts_start[k].closest_on_segment(&((a0 + b0 + c0) / 3.0));
                    if (axis - a0).dot(&outward) <= 0.0 {
                        continue;
                    }
                }
                {
                    deepest = Some((cut, t, k));
                }
            }
        }
        deepest.map(|(_, t, k)| (t, k))
    }

    /// Marks the inserted nodes a tool holds, and removes the newest ones no tool has held for the
    /// delay; returns how many were removed.
    pub fn coarsen(&mut self, body: &mut Body, tick: u64, dt: f64) -> u32 {
        let delay = (self.settings.coarsen_after_s / dt).round() as u64;
        let original = self.depth.len() - self.last_held.len();
        for (k, held) in self.last_held.iter_mut().enumerate() {
            if body.surface.tool_contact[original + k].tool != NO_TOOL {
                *held = tick;
            }
        }
        let mut removed = 0;
        while let Some(&held) = self.last_held.last() {
            let node = self.depth.len() - 1;
            if body.surface.tool_contact[node].tool != NO_TOOL || tick.saturating_sub(held) < delay
            {
                break;
            }
            if coarsen_last(body, &mut self.log).is_none() {
                break;
            }
            self.depth.pop();
            self.last_held.pop();
            self.counters.coarsened += 1;
            self.changed_at = tick;
            removed += 1;
        }
        removed
    }
}

/// A corner of `tri` the tool holds from outside: the tool's outward normal at the corner (from its
/// axis to the node) points into the tissue, against the triangle's outward normal. (A tool that
/// pushes the surface from inside — one leaving tissue it slipped into — holds nodes the other way;
/// refining around those would tent the surface out after it.)
fn held_from_outside(body: &Body, tool: &Tool, tool_index: u32, tri: &[u32; 3]) -> Option<u32> {
    let s = &body.surface;
    let x = &s.next_position_in_world;
    let [a, b, c] = tri.map(|v| x[v as usize]);
    let outward = (b - a).cross(&(c - a));
    tri.iter().copied().find(|&v| {
        let contact = s.tool_contact[v as usize];
        if contact.tool != tool_index || contact.part as usize >= tool.part_count {
            return false;
        }
        let p = x[v as usize];
        let part = &tool.parts_end[contact.part as usize];
        (p - part.closest_on_segment(&p)).dot(&outward) < 0.0
    })
}

/// Where to insert for a contact at weights `w` in `triangle`: inside it, or on the edge the point
/// is near; `None` when the point is near a corner (the corner itself meets the tool) or when every
/// choice would create a triangle sharper than [`MIN_ANGLE_DEG`].
fn choose_split(body: &Body, triangle: usize, w: [f64; 3]) -> Option<Split> {
    let t = body.surface.triangles[triangle];
    let h = &body.surface.homologue_in_body;
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| w[i].total_cmp(&w[j]));
    let (smallest, second) = (order[0], order[1]);
    if w[second] < EDGE_SNAP {
        return None;
    }
    let rest_p =
        |w: [f64; 3]| h[t[0] as usize] * w[0] + h[t[1] as usize] * w[1] + h[t[2] as usize] * w[2];
    if w[smallest] >= EDGE_SNAP {
        let p = rest_p(w);
        let [a, b, c] = t.map(|v| h[v as usize]);
        if [[a, b, p], [b, c, p], [c, a, p]]
            .iter()
            .all(|tri| min_angle_deg(tri) >= MIN_ANGLE_DEG)
        {
            return Some(Split::Face { triangle, w });
        }
    }
    // On the edge opposite the smallest weight, in the triangle's direction i → j.
    let (i, j) = ((smallest + 1) % 3, (smallest + 2) % 3);
    edge_split(body, t[i], t[j], w[j] / (w[i] + w[j]))
}

/// A split of the edge a→b (directed as in one of its triangles) at fraction `along` from a, if no
/// new triangle would be sharper than [`MIN_ANGLE_DEG`].
fn edge_split(body: &Body, a: u32, b: u32, along: f64) -> Option<Split> {
    let tris = &body.surface.triangles;
    let h = &body.surface.homologue_in_body;
    let directed = |x: u32, y: u32| {
        tris.iter()
            .find(|tri| (0..3).any(|k| tri[k] == x && tri[(k + 1) % 3] == y))
    };
    let c = *directed(a, b)?.iter().find(|&&v| v != a && v != b)?;
    let d = *directed(b, a)?.iter().find(|&&v| v != a && v != b)?;
    let p = h[a as usize] * (1.0 - along) + h[b as usize] * along;
    let [ha, hb, hc, hd] = [a, b, c, d].map(|v| h[v as usize]);
    let children = [[ha, p, hc], [p, hb, hc], [hb, p, hd], [p, ha, hd]];
    children
        .iter()
        .all(|tri| min_angle_deg(tri) >= MIN_ANGLE_DEG)
        .then_some(Split::Edge { a, b, t: along })
}

/// When the deepest point is near a corner (a node the tool holds, typically, with the triangle
/// rising from it through the tool): a split of whichever of the corner's two edges cuts deeper
/// into the capsule, at its deepest point (kept [`EDGE_SNAP`] away from both ends), if deeper than
/// `tolerance`.
fn corner_split(
    body: &Body,
    triangle: usize,
    w: [f64; 3],
    capsule: &crate::tool::CapsulePart,
    tolerance: f64,
) -> Option<Split> {
    let t = body.surface.triangles[triangle];
    let x = &body.surface.next_position_in_world;
    let k = (0..3).max_by(|&i, &j| w[i].total_cmp(&w[j]))?;
    let mut best: Option<(f64, usize, f64)> = None;
    for j in [(k + 1) % 3, (k + 2) % 3] {
        let (from, to) = (x[t[k] as usize], x[t[j] as usize]);
        for step in 0..=6 {
            let along = EDGE_SNAP + (1.0 - 2.0 * EDGE_SNAP) * step as f64 / 6.0;
            let point = from.lerp(&to, along);
            let cut = capsule.radius - (point - capsule.closest_on_segment(&point)).norm();
            if cut > tolerance && best.is_none_or(|(c, _, _)| cut > c) {
                best = Some((cut, j, along));
            }
        }
    }
    let (_, j, along) = best?;
    if j == (k + 1) % 3 {
        edge_split(body, t[k], t[j], along)
    } else {
        // The triangle runs j → k on this edge.
        edge_split(body, t[j], t[k], 1.0 - along)
    }
}

/// Smallest interior angle of a triangle (degrees).
pub fn min_angle_deg(tri: &[Vec3; 3]) -> f64 {
    let mut smallest = 180.0f64;
    for k in 0..3 {
        let (p, q, r) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
        let (u, v) = (q - p, r - p);
        let denominator = u.norm() * v.norm();
        if denominator <= f64::MIN_POSITIVE {
            return 0.0;
        }
        let cos = (u.dot(&v) / denominator).clamp(-1.0, 1.0);
        smallest = smallest.min(crate::math::acos(cos).to_degrees());
    }
    smallest
}

/// Barycentric weights of `p` in triangle (a, b, c), or `None` for a degenerate triangle.
pub(crate) fn barycentric(p: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> Option<[f64; 3]> {
    let (v0, v1, v2) = (b - a, c - a, p - a);
    let (d00, d01, d11) = (v0.dot(&v0), v0.dot(&v1), v1.dot(&v1));
    let (d20, d21) = (v2.dot(&v0), v2.dot(&v1));
    let denominator = d00 * d11 - d01 * d01;
    if denominator.abs() <= f64::MIN_POSITIVE {
        return None;
    }
    let v = (d11 * d20 - d01 * d21) / denominator;
    let w = (d00 * d21 - d01 * d20) / denominator;
    Some([1.0 - v - w, v, w].map(|x| x.max(0.0)))
}
