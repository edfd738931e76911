//! Stability of the paper's explicit scheme (MODEL.md §3, §7).
//!
//! Each node's highest frequency is bounded (Gershgorin) by ω² ≤ (k_link + 2 Σ k_edges) / m, and its
//! damping rate by (c_link + 2 Σ c_edges + γ) / m. For semi-implicit Euler on a damped oscillator
//! x'' = −ω² x − (c/m) x' the update matrix has determinant 1 − b and trace 2 − a − b with a = (ω Δt)²
//! and b = Δt c/m; the Jury conditions give stability iff b ≤ 2 and a ≤ 4 − 2b, i.e.
//! ω Δt ≤ √(4 − 2 b). Without damping that is the sampling limit ω Δt < 2.

use crate::body::Body;

/// The worst node of a body under the symplectic scheme.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StabilityMargin {
    /// Index of the node with the smallest margin.
    pub worst_node: usize,
    /// Its ω Δt (bound).
    pub omega_dt: f64,
    /// The largest stable ω Δt given its damping, √(max(0, 4 − 2 b)).
    pub limit: f64,
    /// `limit − omega_dt`: negative means the scheme diverges on that node.
    pub margin: f64,
    /// ω Δt of the rigid component on all its links, the worse of translation and rotation (see
    /// [`rigid_bounds`]).
    pub rigid_omega_dt: f64,
    /// The largest stable ω Δt of the rigid component given its damping.
    pub rigid_limit: f64,
    /// `rigid_limit − rigid_omega_dt`: negative means the explicit scheme diverges on the rigid
    /// component's coupling (a fixed rigid component is never integrated: +∞).
    pub rigid_margin: f64,
}

/// ω Δt limit of semi-implicit Euler for a damping rate `b = Δt c / m`.
pub fn symplectic_limit(b: f64) -> f64 {
    if b > 2.0 {
        0.0
    } else {
        (4.0 - 2.0 * b).max(0.0).sqrt()
    }
}

/// Gershgorin sums of every node: (k_link + 2 Σ k_edges, c_link + 2 Σ c_edges + γ).
pub fn node_bounds(body: &Body) -> (Vec<f64>, Vec<f64>) {
    let (mut stiffness, mut damping) = (Vec::new(), Vec::new());
    node_bounds_into(body, &mut stiffness, &mut damping);
    (stiffness, damping)
}

/// [`node_bounds`] into buffers the caller keeps (no allocation within their capacity).
pub fn node_bounds_into(body: &Body, stiffness: &mut Vec<f64>, damping: &mut Vec<f64>) {
    let s = &body.surface;
    stiffness.clear();
    stiffness.extend_from_slice(&s.link_stiffness);
    damping.clear();
    damping.extend(
        s.link_damping
            .iter()
            .zip(&s.air_damping)
            .map(|(c, g)| c + g),
    );
    let e = &body.edges;
    for k in 0..e.len() {
        for node in [e.a[k] as usize, e.b[k] as usize] {
            stiffness[node] += 2.0 * e.stiffness[k];
            damping[node] += 2.0 * e.damping[k];
        }
    }
}

/// The rigid component's modes on its links, as `(stiffness, damping, inverse mass)` for its
/// translation and for its rotation about its least inertial axis: the two-body modes of the rigid
/// component against the whole surface (the surface moving as one), with the reduced mass
/// μ = M m_s / (M + m_s) and the reduced inertia likewise:
///
/// * translation: (Σ kᵢ, Σ cᵢ + ν μ, 1/μ), so ω² = Σ kᵢ (1/M + 1/m_s);
/// * rotation: (Σ kᵢ |rᵢ|², Σ cᵢ |rᵢ|² + ν μ_I, 1/μ_I), with rᵢ the homologues' arms and
///   1/μ_I = 1/I_min + 1/I_s,min (I_s the surface nodes' inertia about the rigid component's centre).
///
/// With M = m_s this is the Gershgorin bound 2 Σ k / M of the rigid component's row.
pub fn rigid_bounds(body: &Body) -> [(f64, f64, f64); 2] {
    let mut sums = [0.0; RIGID_TERMS];
    for i in 0..body.surface.mass.len() {
        let terms = rigid_terms(body, i);
        for (sum, term) in sums.iter_mut().zip(terms) {
            *sum += term;
        }
    }
    rigid_bounds_from(body, &sums)
}

/// Number of per-node terms of [`rigid_bounds`].
pub const RIGID_TERMS: usize = 11;

/// Node `i`'s terms of [`rigid_bounds`]' sums: link stiffness and damping, the same times the
/// squared arm, mass, and the six entries (xx, yy, zz, xy, xz, yz) of its inertia about the
/// rigid component's centre.
pub fn rigid_terms(body: &Body, i: usize) -> [f64; RIGID_TERMS] {
    let s = &body.surface;
    let arm = s.homologue_in_body[i];
    let arm2 = arm.norm_squared();
    let (k, c, m) = (s.link_stiffness[i], s.link_damping[i], s.mass[i]);
    [
        k,
        c,
        k * arm2,
        c * arm2,
        m,
        (arm2 - arm.x * arm.x) * m,
        (arm2 - arm.y * arm.y) * m,
        (arm2 - arm.z * arm.z) * m,
        (0.0 - arm.x * arm.y) * m,
        (0.0 - arm.x * arm.z) * m,
        (0.0 - arm.y * arm.z) * m,
    ]
}

/// [`rigid_bounds`] from the sums of the nodes' [`rigid_terms`] (in any order the caller fixes).
pub fn rigid_bounds_from(body: &Body, sums: &[f64; RIGID_TERMS]) -> [(f64, f64, f64); 2] {
    let r = &body.rigid;
    let [k, c, k_turn, c_turn, surface_mass, xx, yy, zz, xy, xz, yz] = *sums;
    let surface_inertia = nalgebra::Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz);
    let smallest =
        |m: nalgebra::Matrix3<f64>| m.symmetric_eigenvalues().min().max(f64::MIN_POSITIVE);
    let inverse_reduced = 1.0 / r.mass + 1.0 / surface_mass.max(f64::MIN_POSITIVE);
    let inverse_reduced_turn = 1.0 / smallest(r.inertia_in_body) + 1.0 / smallest(surface_inertia);
    [
        (k, c + r.air_viscosity / inverse_reduced, inverse_reduced),
        (
            k_turn,
            c_turn + r.air_viscosity / inverse_reduced_turn,
            inverse_reduced_turn,
        ),
    ]
}

/// The rigid component's ω Δt on its links (the larger of translation and rotation, from
/// [`rigid_bounds`]) and its limit under semi-implicit Euler, `(omega_dt, limit)`.
pub fn rigid_omega_dt(body: &Body, dt: f64) -> (f64, f64) {
    rigid_bounds(body)
        .iter()
        .map(|&(k, c, inverse_mass)| {
            (
                (k * inverse_mass).sqrt() * dt,
                symplectic_limit(dt * c * inverse_mass),
            )
        })
        .fold((0.0, f64::INFINITY), |(w, l), (w2, l2)| {
            if w2 - l2 > w - l { (w2, l2) } else { (w, l) }
        })
}

/// Whether a node with these Gershgorin sums and inverse mass is stable under semi-implicit Euler
/// at step `h`, with a safety factor on the limit.
pub fn stable_at(stiffness: f64, damping: f64, inverse_mass: f64, h: f64, safety: f64) -> bool {
    let omega_h = (stiffness * inverse_mass).sqrt() * h;
    omega_h <= safety * symplectic_limit(h * damping * inverse_mass)
}

/// Per-node bounds for the paper's scheme at step `dt`.
pub fn symplectic_margin(body: &Body, dt: f64) -> StabilityMargin {
    let s = &body.surface;
    let n = s.mass.len();
    let (stiffness, damping) = node_bounds(body);
    let mut worst = StabilityMargin {
        worst_node: 0,
        omega_dt: 0.0,
        limit: 2.0,
        margin: f64::INFINITY,
        rigid_omega_dt: 0.0,
        rigid_limit: 2.0,
        rigid_margin: f64::INFINITY,
    };
    for i in 0..n {
        let omega_dt = (stiffness[i] * s.inverse_mass[i]).sqrt() * dt;
        let limit = symplectic_limit(dt * damping[i] * s.inverse_mass[i]);
        if limit - omega_dt < worst.margin {
            worst = StabilityMargin {
                worst_node: i,
                omega_dt,
                limit,
                margin: limit - omega_dt,
                ..worst
            };
        }
    }
    let (rigid_omega_dt, rigid_limit) = rigid_omega_dt(body, dt);
    worst.rigid_omega_dt = rigid_omega_dt;
    worst.rigid_limit = rigid_limit;
    if !body.rigid.fixed {
        worst.rigid_margin = rigid_limit - rigid_omega_dt;
    }
    worst
}
