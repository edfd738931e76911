//! Linearised backward Euler (Baraff & Witkin 1998) on the surface and its links, for stiff bodies:
//!
//! (M + h C + h² K) Δv = h (F − h K v),   v ← v + Δv,   x ← x + h v
//!
//! with K = −∂F/∂x and C = −∂F/∂v of the edge springs (each spring's stiffness block
//! k [(1 − L/l)⁺ (I − u uᵀ) + u uᵀ], its damping block c u uᵀ), of the links (k I, c I, the homologue
//! taken as moving with the rigid component) and of air viscosity (γ I). The matrix is symmetric
//! positive definite and never assembled: a conjugate gradient with a Jacobi preconditioner applies
//! it edge by edge, warm-started from the previous step's Δv, stopped at a relative residual of 1e-8
//! or a fixed iteration cap. Nodes held by a tool are fixed (their Δv is what the tool imposes).
//! All buffers are sized once; the step allocates nothing.

use crate::Vec3;
use crate::body::Body;
use crate::contact::tool::NO_TOOL;

/// Iteration cap of the conjugate gradient.
pub const MAX_ITERATIONS: u32 = 80;
/// Relative residual at which it stops.
pub const TOLERANCE: f64 = 1e-8;

/// Scratch of one body.
#[derive(Clone, Debug)]
pub struct Implicit {
    u: Vec<Vec3>,
    tangent: Vec<f64>,
    axial: Vec<f64>,
    diagonal: Vec<f64>,
    preconditioner: Vec<Vec3>,
    rhs: Vec<Vec3>,
    dv: Vec<Vec3>,
    r: Vec<Vec3>,
    z: Vec<Vec3>,
    p: Vec<Vec3>,
    ap: Vec<Vec3>,
    /// Iterations of the last solve.
    pub last_iterations: u32,
    /// Relative residual of the last solve.
    pub last_residual: f64,
}

impl Implicit {
    /// Scratch for `body`.
    pub fn new(body: &Body) -> Self {
        Self::with_room(body, 0)
    }

    /// Scratch for `body` with room for `extra_nodes` more nodes (three edges each), so that
    /// [`Implicit::resize`] after a subdivision allocates nothing.
    pub fn with_room(body: &Body, extra_nodes: usize) -> Self {
        let n = body.node_count() + extra_nodes;
        let m = body.edges.len() + 3 * extra_nodes;
        let mut implicit = Self {
            u: Vec::with_capacity(m),
            tangent: Vec::with_capacity(m),
            axial: Vec::with_capacity(m),
            diagonal: Vec::with_capacity(n),
            preconditioner: Vec::with_capacity(n),
            rhs: Vec::with_capacity(n),
            dv: Vec::with_capacity(n),
            r: Vec::with_capacity(n),
            z: Vec::with_capacity(n),
            p: Vec::with_capacity(n),
            ap: Vec::with_capacity(n),
            last_iterations: 0,
            last_residual: 0.0,
        };
        implicit.resize(body);
        implicit
    }

    /// Sizes the scratch to the body's nodes and edges (after a subdivision or a coarsening). The
    /// warm start of the solver restarts from zero.
    pub fn resize(&mut self, body: &Body) {
        let n = body.node_count();
        let m = body.edges.len();
        self.u.clear();
        self.u.resize(m, Vec3::zeros());
        for buffer in [&mut self.tangent, &mut self.axial] {
            buffer.clear();
            buffer.resize(m, 0.0);
        }
        self.diagonal.clear();
        self.diagonal.resize(n, 0.0);
        for buffer in [
            &mut self.preconditioner,
            &mut self.rhs,
            &mut self.dv,
            &mut self.r,
            &mut self.z,
            &mut self.p,
            &mut self.ap,
        ] {
            buffer.clear();
            buffer.resize(n, Vec3::zeros());
        }
    }

    /// y = (h C + h² K) x over the edges, added to y; `scale_k`, `scale_c` choose which parts.
    fn apply_edges(&self, body: &Body, x: &[Vec3], y: &mut [Vec3], scale_k: f64, scale_c: f64) {
        let e = &body.edges;
        for k in 0..e.len() {
            let (a, b) = (e.a[k] as usize, e.b[k] as usize);
            let d = x[a] - x[b];
            let u = self.u[k];
            let along = u.dot(&d);
            // K_e d = tangent d + (axial − tangent) (u·d) u ; C_e d = c (u·d) u
            let kd = d * self.tangent[k] + u * ((self.axial[k] - self.tangent[k]) * along);
            let cd = u * (e.damping[k] * along);
            let block = kd * scale_k + cd * scale_c;
            y[a] += block;
            y[b] -= block;
        }
    }

    /// Integrates the free nodes of `body` over `h` (forces already accumulated).
    pub fn integrate(&mut self, body: &mut Body, h: f64) {
        let n = body.node_count();
        let held = |body: &Body, i: usize| body.surface.tool_contact[i].tool != NO_TOOL;
        // Edge blocks at the current state.
        {
            let s = &body.surface;
            let e = &body.edges;
            for k in 0..e.len() {
                let d = s.position_in_world[e.b[k] as usize] - s.position_in_world[e.a[k] as usize];
                let length = d.norm();
                if length <= f64::MIN_POSITIVE {
                    self.u[k] = Vec3::zeros();
                    self.tangent[k] = 0.0;
                    self.axial[k] = 0.0;
                    continue;
                }
                self.u[k] = d / length;
                self.axial[k] = e.stiffness[k];
                self.tangent[k] = e.stiffness[k] * (1.0 - e.rest_length[k] / length).max(0.0);
            }
            for i in 0..n {
                self.diagonal[i] = s.mass[i]
                    + h * (s.link_damping[i] + s.air_damping[i])
                    + h * h * s.link_stiffness[i];
                self.preconditioner[i] = Vec3::repeat(self.diagonal[i]);
            }
            for k in 0..e.len() {
                let u = self.u[k];
                let c = e.damping[k];
                let block = Vec3::new(u.x * u.x, u.y * u.y, u.z * u.z);
                let entry = Vec3::repeat(h * h * self.tangent[k])
                    + block * (h * h * (self.axial[k] - self.tangent[k]) + h * c);
                self.preconditioner[e.a[k] as usize] += entry;
                self.preconditioner[e.b[k] as usize] += entry;
            }
        }
        // rhs = h (F − h K v)
        for i in 0..n {
            self.ap[i] = body.surface.velocity_in_world[i] * body.surface.link_stiffness[i];
        }
        let mut kv = std::mem::take(&mut self.ap);
        self.apply_edges(body, &body.surface.velocity_in_world, &mut kv, 1.0, 0.0);
        for (i, (rhs, kv_i)) in self.rhs.iter_mut().zip(&kv).enumerate() {
            *rhs = if held(body, i) {
                Vec3::zeros()
            } else {
                (body.surface.force_in_world[i] - kv_i * h) * h
            };
        }
        self.ap = kv;
        // Conjugate gradient on A Δv = rhs, held nodes fixed at Δv = 0 in the solve.
        for i in 0..n {
            if held(body, i) {
                self.dv[i] = Vec3::zeros();
            }
        }
        self.multiply(body, h, true);
        let mut rhs_norm = 0.0;
        for i in 0..n {
            self.r[i] = if held(body, i) {
                Vec3::zeros()
            } else {
                self.rhs[i] - self.ap[i]
            };
            rhs_norm += self.rhs[i].norm_squared();
        }
        let rhs_norm = rhs_norm.sqrt().max(f64::MIN_POSITIVE);
        let mut rz = 0.0;
        for i in 0..n {
            self.z[i] = self.r[i].component_div(&self.preconditioner[i]);
            self.p[i] = self.z[i];
            rz += self.r[i].dot(&self.z[i]);
        }
        let mut iterations = 0;
        let mut residual = self.r.iter().map(|r| r.norm_squared()).sum::<f64>().sqrt() / rhs_norm;
        while iterations < MAX_ITERATIONS && residual > TOLERANCE {
            self.multiply(body, h, false);
            let mut pap = 0.0;
            for i in 0..n {
                if held(body, i) {
                    self.ap[i] = Vec3::zeros();
                }
                pap += self.p[i].dot(&self.ap[i]);
            }
            if pap <= 0.0 || !pap.is_finite() {
                break;
            }
            let alpha = rz / pap;
            let mut rz_next = 0.0;
            let mut r_norm = 0.0;
            for i in 0..n {
                self.dv[i] += self.p[i] * alpha;
                self.r[i] -= self.ap[i] * alpha;
                self.z[i] = self.r[i].component_div(&self.preconditioner[i]);
                rz_next += self.r[i].dot(&self.z[i]);
                r_norm += self.r[i].norm_squared();
            }
            let beta = rz_next / rz;
            rz = rz_next;
            for i in 0..n {
                self.p[i] = self.z[i] + self.p[i] * beta;
            }
            iterations += 1;
            residual = r_norm.sqrt() / rhs_norm;
        }
        self.last_iterations = iterations;
        self.last_residual = residual;
        let s = &mut body.surface;
        for i in 0..n {
            if s.tool_contact[i].tool != NO_TOOL {
                continue;
            }
            let velocity = s.velocity_in_world[i] + self.dv[i];
            s.velocity_in_world[i] = velocity;
            s.next_position_in_world[i] = s.position_in_world[i] + velocity * h;
        }
    }

    /// ap = A p (or A Δv when `of_solution`), A = M + h C + h² K.
    fn multiply(&mut self, body: &Body, h: f64, of_solution: bool) {
        let n = body.node_count();
        let source = if of_solution {
            std::mem::take(&mut self.dv)
        } else {
            std::mem::take(&mut self.p)
        };
        let mut out = std::mem::take(&mut self.ap);
        for i in 0..n {
            out[i] = source[i] * self.diagonal[i];
        }
        self.apply_edges(body, &source, &mut out, h * h, h);
        self.ap = out;
        if of_solution {
            self.dv = source;
        } else {
            self.p = source;
        }
    }
}
