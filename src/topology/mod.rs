//! Topology changes of a body's surface (paper §5, MODEL.md §6): adaptive subdivision at a contact
//! point, and coarsening back to the original mesh.
//!
//! A node is inserted inside a triangle (split in three) or on an edge (its two triangles split in
//! two). Its mass is taken from the corners with the paper's rule, so the total is conserved and every
//! mass stays positive: with barycentric weights wₖ and corner masses mₖ, each corner gives
//! aₖ mₖ with aₖ = r wₖ, r = 1 / (1 + Σ wₖ² mₖ / Σ wₖ mₖ) ∈ (0, 1]. The air viscosity follows the mass (it
//! is ν m per node). The new node's homologue is the same barycentric point of the corners' homologues,
//! its link stiffness and damping the barycentric means; its new edges take their rest length from the
//! homologues and their stiffness from the chosen [`SpringRule`].
//!
//! Where the node goes: at the mass-weighted barycentre Σ aₖ mₖ xₖ / m_P of the corners (its velocity
//! likewise), which keeps the body's centre of mass and linear momentum exactly where they were — it
//! is the contact point itself when the corner masses are equal, and lies inside the triangle always.
//!
//! Every insertion is logged; [`coarsen_last`] undoes the newest one exactly (masses, triangles,
//! edges restored bit for bit), so coarsening in reverse order of insertion restores the original
//! mesh where nothing else changed. At most [`POOL_NODES`] insertions are held at once.
//!
//! State of this module: the operations and their invariants are done and tested; they are not yet
//! called from the world step (contact-driven refinement, the scene key, delayed coarsening, and
//! reserving the pools so that an insertion on the tick allocates nothing are the next steps).

use crate::Vec3;
use crate::body::Body;

/// Insertions a body can hold at once (its reserved pool).
pub const POOL_NODES: usize = 256;

/// How the stiffness of a new edge is chosen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SpringRule {
    /// The paper's first rule: the mean of the two triangle edges meeting at the corner, weighted by
    /// how close each one's direction is to the new edge's.
    #[default]
    Angle,
    /// The paper's second rule: keep k·L0 of the triangle's edges (mean), so shorter edges are stiffer.
    ConstantKl,
    /// Ours, meant to keep the triangle's membrane stiffness (a spring network's in-plane modulus
    /// scales as Σ k L² / area). Not validated: as written it makes very short new edges far too stiff.
    Area,
}

impl SpringRule {
    /// The scene name.
    pub fn name(self) -> &'static str {
        match self {
            SpringRule::Angle => "angle",
            SpringRule::ConstantKl => "constant_kl",
            SpringRule::Area => "area",
        }
    }

    /// Parses a scene name.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "angle" => Some(SpringRule::Angle),
            "constant_kl" => Some(SpringRule::ConstantKl),
            "area" => Some(SpringRule::Area),
            _ => None,
        }
    }
}

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

/// What an insertion changed, to undo it.
#[derive(Clone, Debug, PartialEq)]
struct Insertion {
    node: u32,
    /// Corners and their masses before.
    corners: Vec<(u32, f64)>,
    /// Triangles overwritten in place: index and previous value.
    replaced_triangles: Vec<(usize, [u32; 3])>,
    /// Triangles appended.
    added_triangles: usize,
    /// Edges overwritten in place: index and previous (a, b, rest, k, c).
    replaced_edges: Vec<(usize, EdgeRecord)>,
    /// Edges appended.
    added_edges: usize,
}

/// The log of a body's insertions, newest last.
#[derive(Clone, Debug, Default)]
pub struct InsertionLog {
    entries: Vec<Insertion>,
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
}

fn new_edge_stiffness(
    body: &Body,
    rule: SpringRule,
    corner: u32,
    p_rest: &Vec3,
    triangle: [u32; 3],
) -> (f64, f64) {
    let s = &body.surface;
    let e = &body.edges;
    let find = |a: u32, b: u32| {
        (0..e.len()).find(|&k| (e.a[k] == a && e.b[k] == b) || (e.a[k] == b && e.b[k] == a))
    };
    let tri_edges: Vec<usize> = [(0, 1), (1, 2), (2, 0)]
        .iter()
        .filter_map(|&(i, j)| find(triangle[i], triangle[j]))
        .collect();
    let mean = |f: &dyn Fn(usize) -> f64| {
        tri_edges.iter().map(|&k| f(k)).sum::<f64>() / tri_edges.len().max(1) as f64
    };
    let c_mean = mean(&|k| e.damping[k]);
    let new_length = (p_rest - s.homologue_in_body[corner as usize])
        .norm()
        .max(f64::MIN_POSITIVE);
    let k = match rule {
        SpringRule::ConstantKl => mean(&|k| e.stiffness[k] * e.rest_length[k]) / new_length,
        SpringRule::Area => {
            let mean_l2 = mean(&|k| e.stiffness[k] * e.rest_length[k] * e.rest_length[k]);
            // Three new edges share the triangle's area with its three old ones: the same Σ k L² per area.
            mean_l2 / (new_length * new_length)
        }
        SpringRule::Angle => {
            let to_p = (p_rest - s.homologue_in_body[corner as usize]).normalize();
            let mut weight_sum = 0.0;
            let mut k_sum = 0.0;
            for &k in &tri_edges {
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
                mean(&|k| e.stiffness[k])
            }
        }
    };
    (k, c_mean)
}

/// Appends node data for a new node built from `corners` with weights `w` and fractions `a`.
fn append_node(body: &mut Body, corners: &[u32], w: &[f64], a: &[f64]) -> u32 {
    let s = &mut body.surface;
    let nu = body.params.air_viscosity;
    let mut mass = 0.0;
    let mut momentum = Vec3::zeros();
    let mut moment = Vec3::zeros();
    let mut moment_next = Vec3::zeros();
    let mut homologue = Vec3::zeros();
    let mut homologue_world = Vec3::zeros();
    let (mut k_link, mut c_link) = (0.0, 0.0);
    for (idx, &c) in corners.iter().enumerate() {
        let c = c as usize;
        let taken = a[idx] * s.mass[c];
        mass += taken;
        momentum += s.velocity_in_world[c] * taken;
        moment += s.position_in_world[c] * taken;
        moment_next += s.next_position_in_world[c] * taken;
        homologue += s.homologue_in_body[c] * w[idx];
        homologue_world += s.homologue_in_world[c] * w[idx];
        k_link += s.link_stiffness[c] * w[idx];
        c_link += s.link_damping[c] * w[idx];
    }
    for (idx, &c) in corners.iter().enumerate() {
        let c = c as usize;
        s.mass[c] -= a[idx] * s.mass[c];
        s.inverse_mass[c] = 1.0 / s.mass[c];
        s.air_damping[c] = nu * s.mass[c];
    }
    s.position_in_world.push(moment / mass);
    s.next_position_in_world.push(moment_next / mass);
    s.velocity_in_world.push(momentum / mass);
    s.force_in_world.push(Vec3::zeros());
    s.mass.push(mass);
    s.inverse_mass.push(1.0 / mass);
    s.air_damping.push(nu * mass);
    s.homologue_in_body.push(homologue);
    s.homologue_in_world.push(homologue_world);
    s.link_stiffness.push(k_link);
    s.link_damping.push(c_link);
    s.tool_contact
        .push(crate::contact::tool::ToolContact::default());
    (s.mass.len() - 1) as u32
}

fn push_edge(body: &mut Body, a: u32, b: u32, k: f64, c: f64) {
    let rest = (body.surface.homologue_in_body[b as usize]
        - body.surface.homologue_in_body[a as usize])
        .norm();
    let e = &mut body.edges;
    e.a.push(a);
    e.b.push(b);
    e.rest_length.push(rest);
    e.stiffness.push(k);
    e.damping.push(c);
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
    if log.entries.len() >= POOL_NODES {
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
    let springs = t.map(|c| new_edge_stiffness(body, rule, c, &rest_p, t));
    let masses = t.map(|c| body.surface.mass[c as usize]);
    let a = mass_fractions(w, masses);
    let corners = t
        .iter()
        .map(|&c| (c, body.surface.mass[c as usize]))
        .collect();
    let p = append_node(body, &t, &w, &a);
    let [ta, tb, tc] = t;
    let triangles = &mut body.surface.triangles;
    triangles[triangle] = [ta, tb, p];
    triangles.push([tb, tc, p]);
    triangles.push([tc, ta, p]);
    for (idx, &c) in t.iter().enumerate() {
        push_edge(body, c, p, springs[idx].0, springs[idx].1);
    }
    log.entries.push(Insertion {
        node: p,
        corners,
        replaced_triangles: vec![(triangle, t)],
        added_triangles: 2,
        replaced_edges: Vec::new(),
        added_edges: 3,
    });
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
    if log.entries.len() >= POOL_NODES {
        return Err(SubdivisionError::PoolFull);
    }
    if !(t.is_finite() && t > 0.0 && t < 1.0) {
        return Err(SubdivisionError::Outside);
    }
    let e = &body.edges;
    let Some(edge) =
        (0..e.len()).find(|&k| (e.a[k] == a && e.b[k] == b) || (e.a[k] == b && e.b[k] == a))
    else {
        return Err(SubdivisionError::NotAnEdge);
    };
    // The two triangles: one has a→b, the other b→a.
    let tris = &body.surface.triangles;
    let has = |tri: &[u32; 3], x: u32, y: u32| (0..3).any(|k| tri[k] == x && tri[(k + 1) % 3] == y);
    let (Some(t1), Some(t2)) = (
        (0..tris.len()).find(|&k| has(&tris[k], a, b)),
        (0..tris.len()).find(|&k| has(&tris[k], b, a)),
    ) else {
        return Err(SubdivisionError::NotAnEdge);
    };
    let third = |tri: &[u32; 3]| {
        *tri.iter()
            .find(|&&v| v != a && v != b)
            .expect("a triangle has a third corner")
    };
    let (c, d) = (third(&tris[t1]), third(&tris[t2]));
    let w = [1.0 - t, t];
    let s = &body.surface;
    let rest_p = s.homologue_in_body[a as usize] * w[0] + s.homologue_in_body[b as usize] * w[1];
    if [a, b, c, d]
        .iter()
        .any(|&v| (rest_p - s.homologue_in_body[v as usize]).norm() < min_edge)
    {
        return Err(SubdivisionError::TooFine);
    }
    let (ka, ca) = new_edge_stiffness(body, rule, a, &rest_p, body.surface.triangles[t1]);
    let (kb, cb) = new_edge_stiffness(body, rule, b, &rest_p, body.surface.triangles[t1]);
    let (kc, cc) = new_edge_stiffness(body, rule, c, &rest_p, body.surface.triangles[t1]);
    let (kd, cd) = new_edge_stiffness(body, rule, d, &rest_p, body.surface.triangles[t2]);
    let masses = [body.surface.mass[a as usize], body.surface.mass[b as usize]];
    let fractions = mass_fractions(w, masses);
    let corners = vec![(a, masses[0]), (b, masses[1])];
    let old_t1 = body.surface.triangles[t1];
    let old_t2 = body.surface.triangles[t2];
    let p = append_node(body, &[a, b], &w, &fractions);
    let triangles = &mut body.surface.triangles;
    // a→b→c becomes a→p→c and p→b→c; b→a→d becomes b→p→d and p→a→d.
    triangles[t1] = [a, p, c];
    triangles.push([p, b, c]);
    triangles[t2] = [b, p, d];
    triangles.push([p, a, d]);
    let old_edge = {
        let e = &body.edges;
        (
            e.a[edge],
            e.b[edge],
            e.rest_length[edge],
            e.stiffness[edge],
            e.damping[edge],
        )
    };
    // The old edge becomes a–p (same spring line), then p–b, p–c, p–d are added.
    let rest_ap = (rest_p - body.surface.homologue_in_body[a as usize]).norm();
    {
        let e = &mut body.edges;
        e.a[edge] = a;
        e.b[edge] = p;
        e.rest_length[edge] = rest_ap;
        e.stiffness[edge] = ka;
        e.damping[edge] = ca;
    }
    push_edge(body, p, b, kb, cb);
    push_edge(body, p, c, kc, cc);
    push_edge(body, p, d, kd, cd);
    log.entries.push(Insertion {
        node: p,
        corners,
        replaced_triangles: vec![(t1, old_t1), (t2, old_t2)],
        added_triangles: 2,
        replaced_edges: vec![(edge, old_edge)],
        added_edges: 3,
    });
    Ok(p)
}

/// Removes the newest inserted node and restores exactly what its insertion changed; returns it, or
/// `None` when the mesh is the original.
pub fn coarsen_last(body: &mut Body, log: &mut InsertionLog) -> Option<u32> {
    let entry = log.entries.pop()?;
    let s = &mut body.surface;
    let nu = body.params.air_viscosity;
    for &(c, m) in &entry.corners {
        let c = c as usize;
        s.mass[c] = m;
        s.inverse_mass[c] = 1.0 / m;
        s.air_damping[c] = nu * m;
    }
    for _ in 0..entry.added_triangles {
        s.triangles.pop();
    }
    for &(t, old) in &entry.replaced_triangles {
        s.triangles[t] = old;
    }
    debug_assert_eq!(entry.node as usize, s.mass.len() - 1);
    s.position_in_world.pop();
    s.next_position_in_world.pop();
    s.velocity_in_world.pop();
    s.force_in_world.pop();
    s.mass.pop();
    s.inverse_mass.pop();
    s.air_damping.pop();
    s.homologue_in_body.pop();
    s.homologue_in_world.pop();
    s.link_stiffness.pop();
    s.link_damping.pop();
    s.tool_contact.pop();
    let e = &mut body.edges;
    for _ in 0..entry.added_edges {
        e.a.pop();
        e.b.pop();
        e.rest_length.pop();
        e.stiffness.pop();
        e.damping.pop();
    }
    for &(k, (a, b, rest, stiffness, damping)) in &entry.replaced_edges {
        e.a[k] = a;
        e.b[k] = b;
        e.rest_length[k] = rest;
        e.stiffness[k] = stiffness;
        e.damping[k] = damping;
    }
    Some(entry.node)
}
