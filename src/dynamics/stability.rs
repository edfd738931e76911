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
    /// ω Δt of the rigid component's translation on all its links, √(Σ k_i / M) Δt.
    pub rigid_omega_dt: f64,
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
                rigid_omega_dt: 0.0,
            };
        }
    }
    let total_link: f64 = s.link_stiffness.iter().sum();
    worst.rigid_omega_dt = (total_link / body.rigid.mass).sqrt() * dt;
    worst
}
