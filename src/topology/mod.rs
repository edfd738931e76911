//! Topology changes of a body's surface (paper §5, MODEL.md §6): adaptive subdivision at a contact
//! point, and coarsening back to the original mesh.
//!
//! A node is inserted inside a triangle (split in three) or on an edge (its two triangles split in
//! two). Its mass is taken from the corners with the paper's rule, so the total is conserved and every
//! mass stays positive: with barycentric weights wₖ and corner masses mₖ, each corner gives
//! aₖ mₖ with aₖ = r wₖ, r = 1 / (1 + Σ wₖ² mₖ / Σ wₖ mₖ) ∈ (0, 1]. The air viscosity follows the mass (it
//! is ν m per node). The new node's homologue is the same barycentric point of the corners' homologues.
//!
//! Where the node goes: at the mass-weighted barycentre Σ aₖ mₖ xₖ / m_P of the corners (its velocity
//! likewise), which keeps the body's centre of mass and linear momentum exactly where they were — it
//! is the contact point itself when the corner masses are equal, and lies inside the triangle always.
//!
//! Springs and links follow a [`SpringRule`]: the paper's two rules (new edges from the triangle's
//! edges, links the barycentric mean of the corners'), or ours, `area`, which keeps the refined patch
//! mechanically the same as the coarse one: edge stiffness from the areas of the triangles beside the
//! edge (k = E Σ A / L², the membrane modulus E of each triangle kept), and link stiffness and damping
//! moved from the corners to the new node in proportion to the area each corner hands over, so the
//! elastic foundation per unit area is unchanged and its total exactly conserved.
//!
//! Every insertion is logged in fixed-size records; [`coarsen_last`] undoes the newest one (masses,
//! links, triangles, edges restored bit for bit; the removed node's momentum handed back to its
//! corners), so coarsening in reverse order of insertion restores the original mesh where nothing
//! else changed. At most [`POOL_NODES`] insertions are held at once; with
//! [`reserve_for_subdivision`] called first, neither operation allocates.

pub mod cut;
pub mod explicit;
pub mod refine;
pub mod rest_index;
pub mod tear;
pub mod transect;

pub use crate::body::settings::{POOL_NODES, SpringRule, SubdivisionSettings};
pub use cut::{Cutter, CuttingSettings};
pub use tear::{Tearer, TearingSettings};

use crate::Vec3;
use crate::body::{Body, NewNode};

/// The paper's mass split: for weights `w` (summing to 1) and corner masses `m`, the fractions
/// aₖ = r wₖ each corner gives to the new node.
pub fn mass_fractions<const N: usize>(w: [f64; N], m: [f64; N]) -> [f64; N] {
    let first: f64 = (0..N).map(|k| w[k] * m[k]).sum();
    let second: f64 = (0..N).map(|k| w[k] * w[k] * m[k]).sum();
    let r = 1.0 / (1.0 + second / first);
    w.map(|wk| r * wk)
}

/// Why a subdivision was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SubdivisionError {
    /// The reserved pool is used up.
    #[error("the subdivision pool is full")]
    PoolFull,
    /// A new edge would be shorter than the minimum edge length.
    #[error("a new edge would be shorter than the minimum")]
    TooFine,
    /// The point is not inside the element (a weight is negative or not finite).
    #[error("the point is outside the element")]
    Outside,
    /// The edge does not have exactly two triangles.
    #[error("the edge is not shared by two triangles")]
    NotAnEdge,
}

/// An edge spring's data: ends, rest length, stiffness, damping.
type EdgeRecord = (u32, u32, f64, f64, f64);

/// Edges one insertion may change in place (an edge split: the split edge and the four around it).
const MAX_REPLACED_EDGES: usize = 5;

/// What an insertion changed, to undo it. Fixed size, so logging allocates nothing.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Insertion {
    node: u32,
    corner_count: usize,
    /// Corners, their masses, link stiffness and damping before, and the mass each gave.
    corners: [(u32, f64, f64, f64, f64); 3],
    /// Triangles overwritten in place: index and previous value.
    replaced_triangles: [(u32, [u32; 3]); 2],
    replaced_triangle_count: usize,
    /// Triangles appended.
    added_triangles: usize,
    /// Edges overwritten in place: index and previous (a, b, rest, k, c).
    replaced_edges: [(u32, EdgeRecord); MAX_REPLACED_EDGES],
    replaced_edge_count: usize,
    /// Edges appended.
    added_edges: usize,
}

impl Insertion {
    fn new(node: u32) -> Self {
        Self {
            node,
            corner_count: 0,
            corners: [(0, 0.0, 0.0, 0.0, 0.0); 3],
            replaced_triangles: [(0, [0; 3]); 2],
            replaced_triangle_count: 0,
            added_triangles: 0,
            replaced_edges: [(0, (0, 0, 0.0, 0.0, 0.0)); MAX_REPLACED_EDGES],
            replaced_edge_count: 0,
            added_edges: 0,
        }
    }

    fn replace_triangle(&mut self, index: usize, old: [u32; 3]) {
        self.replaced_triangles[self.replaced_triangle_count] = (index as u32, old);
        self.replaced_triangle_count += 1;
    }

    /// Records edge `k` before it is changed (once).
    fn replace_edge(&mut self, body: &Body, k: usize) {
        if self.replaced_edges[..self.replaced_edge_count]
            .iter()
            .any(|&(e, _)| e as usize == k)
        {
            return;
        }
        let e = &body.edges;
        self.replaced_edges[self.replaced_edge_count] = (
            k as u32,
            (
                e.a[k],
                e.b[k],
                e.rest_length[k],
                e.stiffness[k],
                e.damping[k],
            ),
        );
        self.replaced_edge_count += 1;
    }
}

/// The log of a body's insertions, newest last.
#[derive(Clone, Debug)]
pub struct InsertionLog {
    entries: Vec<Insertion>,
}

impl Default for InsertionLog {
    fn default() -> Self {
        Self {
            entries: Vec::with_capacity(POOL_NODES),
        }
    }
}

impl InsertionLog {
    /// Insertions not yet coarsened away.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// True when the mesh is the original one.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Forgets every insertion: the refined mesh becomes the one coarsening returns to (a cut
    /// renumbers nodes after the insertions, so they can no longer be undone one by one).
    pub fn clear(&mut self) {
        self.entries.clear();
    }

    /// The node the newest insertion added.
    pub fn newest(&self) -> Option<u32> {
        self.entries.last().map(|e| e.node)
    }
}

/// Reserves room in every per-node, per-edge and per-triangle array of `body` for [`POOL_NODES`]
/// insertions, so that subdividing afterwards allocates nothing.
pub fn reserve_for_subdivision(body: &mut Body) {
    body.reserve_room_of(body.room_nodes().max(POOL_NODES));
}

/// The edge between `a` and `b`, if any.
pub(crate) fn find_edge(body: &Body, a: u32, b: u32) -> Option<usize> {
    let e = &body.edges;
    (0..e.len()).find(|&k| (e.a[k] == a && e.b[k] == b) || (e.a[k] == b && e.b[k] == a))
}

/// The triangle with the directed edge a→b, if any.
fn triangle_with(body: &Body, a: u32, b: u32) -> Option<usize> {
    let has = |t: &[u32; 3]| (0..3).any(|k| t[k] == a && t[(k + 1) % 3] == b);
    body.surface.triangles.iter().position(has)
}

/// Rest area of a triangle (m², from the homologues).
fn rest_area(body: &Body, t: [u32; 3]) -> f64 {
    let h = &body.surface.homologue_in_body;
    let [a, b, c] = t.map(|v| h[v as usize]);
    0.5 * (b - a).cross(&(c - a)).norm()
}

fn rest_length(body: &Body, a: u32, b: u32) -> f64 {
    let h = &body.surface.homologue_in_body;
    (h[b as usize] - h[a as usize]).norm()
}

/// Lumped rest area of a node: a third of every triangle around it (m²).
fn lumped_area(body: &Body, node: u32) -> f64 {
    body.surface
        .triangles
        .iter()
        .filter(|t| t.contains(&node))
        .map(|&t| rest_area(body, t) / 3.0)
        .sum()
}

/// Rest area of the triangle on the other side of edge a→b of a triangle (the one with b→a).
fn area_across(body: &Body, a: u32, b: u32) -> f64 {
    triangle_with(body, b, a).map_or(0.0, |t| rest_area(body, body.surface.triangles[t]))
}

/// Membrane modulus a triangle's springs stand for (N/m): the mean over its edges of k L² / Σ A,
/// Σ A the rest areas of the triangles beside the edge. Read before the triangle changes.
fn triangle_modulus(body: &Body, t: [u32; 3]) -> (f64, f64) {
    let own = rest_area(body, t);
    let (mut modulus, mut ratio, mut count) = (0.0, 0.0, 0.0);
    for (i, j) in [(0, 1), (1, 2), (2, 0)] {
        let Some(k) = find_edge(body, t[i], t[j]) else {
            continue;
        };
        let e = &body.edges;
        let beside = own + area_across(body, t[i], t[j]);
        if beside > 0.0 {
            modulus += e.stiffness[k] * e.rest_length[k] * e.rest_length[k] / beside;
        }
        if e.stiffness[k] > 0.0 {
            ratio += e.damping[k] / e.stiffness[k];
        }
        count += 1.0;
    }
    if count > 0.0 {
        (modulus / count, ratio / count)
    } else {
        (0.0, 0.0)
    }
}

/// Stiffness and damping of a new edge from `corner` to the rest point `p_rest` inside `triangle`
/// under the paper's rules.
fn paper_edge_spring(
    body: &Body,
    rule: SpringRule,
    corner: u32,
    p_rest: &Vec3,
    triangle: [u32; 3],
) -> (f64, f64) {
    let s = &body.surface;
    let e = &body.edges;
    let mut tri_edges = [usize::MAX; 3];
    for (slot, (i, j)) in [(0, 1), (1, 2), (2, 0)].into_iter().enumerate() {
        tri_edges[slot] = find_edge(body, triangle[i], triangle[j]).unwrap_or(usize::MAX);
    }
    let known = || tri_edges.iter().copied().filter(|&k| k != usize::MAX);
    let count = known().count().max(1) as f64;
    let c_mean = known().map(|k| e.damping[k]).sum::<f64>() / count;
    let new_length = (p_rest - s.homologue_in_body[corner as usize])
        .norm()
        .max(f64::MIN_POSITIVE);
    let k = match rule {
        SpringRule::ConstantKl | SpringRule::Area => {
            known()
                .map(|k| e.stiffness[k] * e.rest_length[k])
                .sum::<f64>()
                / count
                / new_length
        }
        SpringRule::Angle => {
            let to_p = (p_rest - s.homologue_in_body[corner as usize]).normalize();
            let mut weight_sum = 0.0;
            let mut k_sum = 0.0;
            for k in known() {
                if e.a[k] != corner && e.b[k] != corner {
                    continue;
                }
                let other = if e.a[k] == corner { e.b[k] } else { e.a[k] };
                let dir = (s.homologue_in_body[other as usize]
                    - s.homologue_in_body[corner as usize])
                    .normalize();
                let closeness = (1.0 + to_p.dot(&dir)).max(1e-12);
                weight_sum += closeness;
                k_sum += closeness * e.stiffness[k];
            }
            if weight_sum > 0.0 {
                k_sum / weight_sum
            } else {
                known().map(|k| e.stiffness[k]).sum::<f64>() / count
            }
        }
    };
    (k, c_mean)
}

/// Appends node data for a new node built from `corners` with weights `w` and mass fractions `a`;
/// links follow the rule (the barycentric mean, or for `area` the share `link_share[k]` of each
/// corner's link). Records the corners in `entry`.
fn append_node(
    body: &mut Body,
    entry: &mut Insertion,
    corners: &[u32],
    w: &[f64],
    a: &[f64],
    link_share: Option<&[f64]>,
) -> u32 {
    let s = &mut body.surface;
    let nu = body.params.air_viscosity;
    let mut mass = 0.0;
    let mut momentum = Vec3::zeros();
    let mut moment = Vec3::zeros();
    let mut moment_next = Vec3::zeros();
    let mut homologue = Vec3::zeros();
    let mut homologue_world = Vec3::zeros();
    let mut plastic_offset = Vec3::zeros();
    let (mut k_link, mut c_link) = (0.0, 0.0);
    entry.corner_count = corners.len();
    for (idx, &c) in corners.iter().enumerate() {
        let c = c as usize;
        let taken = a[idx] * s.mass[c];
        entry.corners[idx] = (
            c as u32,
            s.mass[c],
            s.link_stiffness[c],
            s.link_damping[c],
            taken,
        );
        mass += taken;
        momentum += s.velocity_in_world[c] * taken;
        moment += s.position_in_world[c] * taken;
        moment_next += s.next_position_in_world[c] * taken;
        homologue += s.homologue_in_body[c] * w[idx];
        homologue_world += s.homologue_in_world[c] * w[idx];
        plastic_offset += s.plastic_offset_in_body[c] * w[idx];
        match link_share {
            None => {
                k_link += s.link_stiffness[c] * w[idx];
                c_link += s.link_damping[c] * w[idx];
            }
            Some(share) => {
                k_link += s.link_stiffness[c] * share[idx];
                c_link += s.link_damping[c] * share[idx];
            }
        }
    }
    for (idx, &c) in corners.iter().enumerate() {
        let c = c as usize;
        s.mass[c] -= entry.corners[idx].4;
        s.inverse_mass[c] = 1.0 / s.mass[c];
        s.air_damping[c] = nu * s.mass[c];
        if let Some(share) = link_share {
            s.link_stiffness[c] *= 1.0 - share[idx];
            s.link_damping[c] *= 1.0 - share[idx];
        }
    }
    s.push_node(
        NewNode {
            position_in_world: moment / mass,
            next_position_in_world: moment_next / mass,
            velocity_in_world: momentum / mass,
            mass,
            homologue_in_body: homologue,
            homologue_in_world: homologue_world,
            plastic_offset_in_body: plastic_offset,
            link_stiffness: k_link,
            link_damping: c_link,
        },
        nu,
    );
    (s.mass.len() - 1) as u32
}

fn push_edge(body: &mut Body, entry: &mut Insertion, a: u32, b: u32, k: f64, c: f64) {
    let rest = rest_length(body, a, b);
    body.edges.push(a, b, rest, k, c);
    entry.added_edges += 1;
}

/// Area rule: scales the kept edge `from`→`to` (directed as in the split triangle and its child) to
/// the area now beside it: the child's `after` instead of the split triangle's `before`, plus the
/// unchanged triangle across.
fn rescale_kept_edge(
    body: &mut Body,
    entry: &mut Insertion,
    from: u32,
    to: u32,
    before: f64,
    after: f64,
) {
    let Some(k) = find_edge(body, from, to) else {
        return;
    };
    let across = area_across(body, from, to);
    let total_before = before + across;
    if total_before <= 0.0 {
        return;
    }
    let factor = (after + across) / total_before;
    entry.replace_edge(body, k);
    body.edges.stiffness[k] *= factor;
    body.edges.damping[k] *= factor;
}

/// Inserts a node inside triangle `triangle` at barycentric weights `w` (of its corners in order);
/// returns the new node. `min_edge` refuses insertions that would make a rest edge shorter than it.
pub fn subdivide_face(
    body: &mut Body,
    log: &mut InsertionLog,
    triangle: usize,
    w: [f64; 3],
    rule: SpringRule,
    min_edge: f64,
) -> Result<u32, SubdivisionError> {
    if log.entries.len() >= POOL_NODES || !body.has_room(1, 2, 3) {
        return Err(SubdivisionError::PoolFull);
    }
    if w.iter().any(|x| !x.is_finite() || *x <= 0.0) {
        return Err(SubdivisionError::Outside);
    }
    let sum: f64 = w.iter().sum();
    let w = w.map(|x| x / sum);
    let t = body.surface.triangles[triangle];
    let s = &body.surface;
    let rest_p = s.homologue_in_body[t[0] as usize] * w[0]
        + s.homologue_in_body[t[1] as usize] * w[1]
        + s.homologue_in_body[t[2] as usize] * w[2];
    if t.iter()
        .any(|&c| (rest_p - s.homologue_in_body[c as usize]).norm() < min_edge)
    {
        return Err(SubdivisionError::TooFine);
    }
    // Everything the rules read, before the mesh changes.
    let springs = t.map(|c| paper_edge_spring(body, rule, c, &rest_p, t));
    let (modulus, damping_ratio) = triangle_modulus(body, t);
    let area = rest_area(body, t);
    let link_share = t.map(|c| {
        let lumped = lumped_area(body, c);
        // Corner k hands the new node a third of the split triangle's area times its weight.
        if lumped > 0.0 {
            (w[t.iter().position(|&x| x == c).unwrap_or(0)] * area / 3.0 / lumped).min(1.0)
        } else {
            0.0
        }
    });
    let masses = t.map(|c| body.surface.mass[c as usize]);
    let a = mass_fractions(w, masses);
    let mut entry = Insertion::new(body.node_count() as u32);
    let p = append_node(
        body,
        &mut entry,
        &t,
        &w,
        &a,
        (rule == SpringRule::Area).then_some(&link_share[..]),
    );
    let [ta, tb, tc] = t;
    entry.replace_triangle(triangle, t);
    let triangles = &mut body.surface.triangles;
    triangles[triangle] = [ta, tb, p];
    triangles.push([tb, tc, p]);
    triangles.push([tc, ta, p]);
    entry.added_triangles = 2;
    if rule == SpringRule::Area {
        // Children: (a,b,p) with area w_c A, (b,c,p) w_a A, (c,a,p) w_b A.
        rescale_kept_edge(body, &mut entry, ta, tb, area, w[2] * area);
        rescale_kept_edge(body, &mut entry, tb, tc, area, w[0] * area);
        rescale_kept_edge(body, &mut entry, tc, ta, area, w[1] * area);
        for (idx, &c) in t.iter().enumerate() {
            // Edge c–p lies between the two children that contain c: (1 − w_c) A.
            let beside = (1.0 - w[idx]) * area;
            let length = rest_length(body, c, p);
            let k = modulus * beside / (length * length);
            push_edge(body, &mut entry, c, p, k, k * damping_ratio);
        }
    } else {
        for (idx, &c) in t.iter().enumerate() {
            push_edge(body, &mut entry, c, p, springs[idx].0, springs[idx].1);
        }
    }
    log.entries.push(entry);
    body.topology_version += 1;
    body.refresh_diagonals();
    Ok(p)
}

/// Inserts a node on the edge between nodes `a` and `b` at fraction `t` from `a`; returns it.
pub fn subdivide_edge(
    body: &mut Body,
    log: &mut InsertionLog,
    a: u32,
    b: u32,
    t: f64,
    rule: SpringRule,
    min_edge: f64,
) -> Result<u32, SubdivisionError> {
    if log.entries.len() >= POOL_NODES || !body.has_room(1, 2, 3) {
        return Err(SubdivisionError::PoolFull);
    }
    if !(t.is_finite() && t > 0.0 && t < 1.0) {
        return Err(SubdivisionError::Outside);
    }
    let Some(edge) = find_edge(body, a, b) else {
        return Err(SubdivisionError::NotAnEdge);
    };
    // The two triangles: one has a→b, the other b→a.
    let (Some(t1), Some(t2)) = (triangle_with(body, a, b), triangle_with(body, b, a)) else {
        return Err(SubdivisionError::NotAnEdge);
    };
    let tris = &body.surface.triangles;
    let third = |tri: &[u32; 3]| tri.iter().copied().find(|&v| v != a && v != b);
    let (Some(c), Some(d)) = (third(&tris[t1]), third(&tris[t2])) else {
        return Err(SubdivisionError::NotAnEdge);
    };
    let w = [1.0 - t, t];
    let s = &body.surface;
    let rest_p = s.homologue_in_body[a as usize] * w[0] + s.homologue_in_body[b as usize] * w[1];
    if [a, b, c, d]
        .iter()
        .any(|&v| (rest_p - s.homologue_in_body[v as usize]).norm() < min_edge)
    {
        return Err(SubdivisionError::TooFine);
    }
    let old_t1 = body.surface.triangles[t1];
    let old_t2 = body.surface.triangles[t2];
    // Everything the rules read, before the mesh changes.
    let (ka, ca) = paper_edge_spring(body, rule, a, &rest_p, old_t1);
    let (kb, cb) = paper_edge_spring(body, rule, b, &rest_p, old_t1);
    let (kc, cc) = paper_edge_spring(body, rule, c, &rest_p, old_t1);
    let (kd, cd) = paper_edge_spring(body, rule, d, &rest_p, old_t2);
    let (e1, r1) = triangle_modulus(body, old_t1);
    let (e2, r2) = triangle_modulus(body, old_t2);
    let (area1, area2) = (rest_area(body, old_t1), rest_area(body, old_t2));
    let link_share = [a, b].map(|v| {
        let lumped = lumped_area(body, v);
        let weight = if v == a { w[0] } else { w[1] };
        if lumped > 0.0 {
            (weight * (area1 + area2) / 3.0 / lumped).min(1.0)
        } else {
            0.0
        }
    });
    let masses = [body.surface.mass[a as usize], body.surface.mass[b as usize]];
    let fractions = mass_fractions(w, masses);
    let mut entry = Insertion::new(body.node_count() as u32);
    let p = append_node(
        body,
        &mut entry,
        &[a, b],
        &w,
        &fractions,
        (rule == SpringRule::Area).then_some(&link_share[..]),
    );
    // a→b→c becomes a→p→c and p→b→c; b→a→d becomes b→p→d and p→a→d.
    entry.replace_triangle(t1, old_t1);
    entry.replace_triangle(t2, old_t2);
    let triangles = &mut body.surface.triangles;
    triangles[t1] = [a, p, c];
    triangles.push([p, b, c]);
    triangles[t2] = [b, p, d];
    triangles.push([p, a, d]);
    entry.added_triangles = 2;
    // The old edge becomes a–p (same spring line), then p–b, p–c, p–d are added.
    entry.replace_edge(body, edge);
    let rest_ap = rest_length(body, a, p);
    let (k_ap, c_ap, k_pb, c_pb, k_pc, c_pc, k_pd, c_pd) = if rule == SpringRule::Area {
        // Children: (a,p,c) has t A1, (p,b,c) (1 − t) A1; likewise (p,a,d) t A2, (b,p,d) (1 − t) A2.
        let (a1a, a1b) = (t * area1, (1.0 - t) * area1);
        let (a2a, a2b) = (t * area2, (1.0 - t) * area2);
        let l_pb = rest_length(body, p, b);
        let l_pc = rest_length(body, p, c);
        let l_pd = rest_length(body, p, d);
        let k_ap = (e1 * a1a + e2 * a2a) / (rest_ap * rest_ap);
        let k_pb = (e1 * a1b + e2 * a2b) / (l_pb * l_pb);
        let k_pc = e1 * area1 / (l_pc * l_pc);
        let k_pd = e2 * area2 / (l_pd * l_pd);
        let ratio = 0.5 * (r1 + r2);
        (
            k_ap,
            k_ap * ratio,
            k_pb,
            k_pb * ratio,
            k_pc,
            k_pc * r1,
            k_pd,
            k_pd * r2,
        )
    } else {
        (ka, ca, kb, cb, kc, cc, kd, cd)
    };
    {
        let e = &mut body.edges;
        e.a[edge] = a;
        e.b[edge] = p;
        e.rest_length[edge] = rest_ap;
        e.stiffness[edge] = k_ap;
        e.damping[edge] = c_ap;
    }
    push_edge(body, &mut entry, p, b, k_pb, c_pb);
    push_edge(body, &mut entry, p, c, k_pc, c_pc);
    push_edge(body, &mut entry, p, d, k_pd, c_pd);
    if rule == SpringRule::Area {
        // The four edges around keep their other triangle and lose part of this one.
        rescale_kept_edge(body, &mut entry, c, a, area1, t * area1);
        rescale_kept_edge(body, &mut entry, b, c, area1, (1.0 - t) * area1);
        rescale_kept_edge(body, &mut entry, a, d, area2, t * area2);
        rescale_kept_edge(body, &mut entry, d, b, area2, (1.0 - t) * area2);
    }
    log.entries.push(entry);
    body.topology_version += 1;
    body.refresh_diagonals();
    Ok(p)
}

/// Removes the newest inserted node and restores exactly what its insertion changed (its mass,
/// links and momentum go back to its corners); returns it, or `None` when the mesh is the original.
pub fn coarsen_last(body: &mut Body, log: &mut InsertionLog) -> Option<u32> {
    let entry = log.entries.pop()?;
    body.topology_version += 1;
    let s = &mut body.surface;
    let nu = body.params.air_viscosity;
    let p = entry.node as usize;
    debug_assert_eq!(p, s.mass.len() - 1);
    let v_p = s.velocity_in_world[p];
    for &(c, m, k_link, c_link, taken) in &entry.corners[..entry.corner_count] {
        let c = c as usize;
        // The corner takes its share back with the removed node's velocity: momentum is kept.
        s.velocity_in_world[c] = (s.velocity_in_world[c] * s.mass[c] + v_p * taken) / m;
        s.mass[c] = m;
        s.inverse_mass[c] = 1.0 / m;
        s.air_damping[c] = nu * m;
        s.link_stiffness[c] = k_link;
        s.link_damping[c] = c_link;
    }
    for _ in 0..entry.added_triangles {
        s.triangles.pop();
    }
    for &(t, old) in entry.replaced_triangles[..entry.replaced_triangle_count]
        .iter()
        .rev()
    {
        s.triangles[t as usize] = old;
    }
    s.pop_node();
    let e = &mut body.edges;
    for _ in 0..entry.added_edges {
        e.pop();
    }
    for &(k, (a, b, rest, stiffness, damping)) in entry.replaced_edges[..entry.replaced_edge_count]
        .iter()
        .rev()
    {
        let k = k as usize;
        e.a[k] = a;
        e.b[k] = b;
        e.rest_length[k] = rest;
        e.stiffness[k] = stiffness;
        e.damping[k] = damping;
    }
    body.refresh_diagonals();
    Some(entry.node)
}
