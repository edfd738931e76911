//! Linearised backward Euler (Baraff & Witkin 1998) on the surface, its links **and the rigid
//! component**, for stiff bodies:
//!
//! (M + h C + h² K) Δu = h (F − h K u),   u ← u + Δu,   x ← x + h u
//!
//! The unknowns `u` are every node's velocity, the rigid component's linear velocity V and its angular
//! velocity ω: the links couple them, so a stiff link set cannot make the rigid component run away
//! while the nodes are solved implicitly (issue 12: with the rigid component stepped explicitly, a
//! stiff coupling diverged with every integrator). M is the nodes' masses, M_r and the world-frame
//! inertia I_w; K = −∂F/∂x and C = −∂F/∂v of
//!
//! * the edge springs (each spring's stiffness block k [(1 − L/l)⁺ (I − u uᵀ) + u uᵀ], damping c u uᵀ),
//! * the links, linearised in the rigid motion: a link's stretch d = h − x changes by
//!   δd = −δx + δX + δθ × a (a = h − X, the homologue's arm), so its blocks are k Jᵀ J and c Jᵀ J with
//!   J = [−I, I, −[a]×] on (node, rigid translation, rigid rotation) — symmetric positive
//!   semi-definite (the term of the arm's second derivative is left out),
//! * air viscosity (γ I on a node, ν M_r and ν I_w on the rigid component).
//!
//! The matrix is symmetric positive definite and never assembled. A conjugate gradient applies it
//! edge by edge and link by link, preconditioned by two levels: block Jacobi (a node's diagonal, the
//! rigid component's 3×3 blocks) plus an exact correction on the six rigid modes of the whole body
//! (every node and the rigid component translating or turning together), the modes a stiff coupling
//! leaves nearly free and Jacobi alone resolves slowly. Warm-started from the previous step's Δu,
//! stopped at a relative residual of 1e-8 or a fixed iteration cap. Nodes held by a tool are fixed
//! (their motion is the tool's), as is a fixed rigid component; after the obstacle contact stage the
//! nodes it resolved are pinned at their new velocity and the rest solved again ([`Implicit::pin_contacts`]). The result for the rigid component is
//! handed to its own integration as the force and torque that give the solved ΔV and I_w Δω over the
//! step. All buffers are sized once; the step allocates nothing.

use crate::Vec3;
use crate::body::Body;
use crate::contact::tool::NO_TOOL;
use nalgebra::{Matrix3, Matrix6, Vector6};

/// Iteration cap of the conjugate gradient.
pub const MAX_ITERATIONS: u32 = 80;
/// Relative residual at which it stops.
pub const TOLERANCE: f64 = 1e-8;

/// Scratch of one body. Vectors have one entry per node, then the rigid component's translation
/// (index `n`) and rotation (index `n + 1`).
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
    /// Velocities at the start of the step (nodes, then V and ω).
    start_velocity: Vec<Vec3>,
    /// Node velocities as the last solve left them (to see which nodes the contact stage changed).
    solved_velocity: Vec<Vec3>,
    /// Nodes whose velocity change is imposed: held by a tool, or resolved against an obstacle.
    pinned: Vec<bool>,
    /// M_r (1 + h ν).
    rigid_mass: f64,
    /// I_w (1 + h ν).
    rigid_inertia: Matrix3<f64>,
    /// Inverse of the translation block of the preconditioner.
    translation_block_inverse: f64,
    /// Inverse of the rotation block of the preconditioner.
    rotation_block_inverse: Matrix3<f64>,
    /// Inverse of the matrix restricted to the rigid modes, when it is invertible.
    coarse_inverse: Option<Matrix6<f64>>,
    /// The body's topology version the scratch is sized for.
    synced_version: u64,
    /// Whether the scratch holds this step's solve (prepared and solved since the last resize):
    /// what [`Implicit::pin_contacts`] solves again from. A subdivision after the integration
    /// resizes it, and the step's contacts are then answered without a second solve.
    solved: bool,
    /// Topology changes followed keeping the warm start (nodes appended by a cut or a tear).
    pub follows: u64,
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
        let n = body.node_count() + extra_nodes + 2;
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
            start_velocity: Vec::with_capacity(n),
            solved_velocity: Vec::with_capacity(n),
            pinned: Vec::with_capacity(n),
            rigid_mass: 0.0,
            rigid_inertia: Matrix3::zeros(),
            translation_block_inverse: 0.0,
            rotation_block_inverse: Matrix3::zeros(),
            coarse_inverse: None,
            synced_version: 0,
            solved: false,
            follows: 0,
            last_iterations: 0,
            last_residual: 0.0,
        };
        implicit.resize(body);
        implicit
    }

    /// Sizes the scratch to the body's nodes and edges (after a subdivision or a coarsening). The
    /// warm start of the solver restarts from zero.
    pub fn resize(&mut self, body: &Body) {
        self.synced_version = body.topology_version;
        self.solved = false;
        let n = body.node_count() + 2;
        let m = body.edges.len();
        self.u.clear();
        self.u.resize(m, Vec3::zeros());
        for buffer in [&mut self.tangent, &mut self.axial] {
            buffer.clear();
            buffer.resize(m, 0.0);
        }
        self.diagonal.clear();
        self.diagonal.resize(n, 0.0);
        for buffer in self.node_buffers() {
            buffer.clear();
            buffer.resize(n, Vec3::zeros());
        }
        self.pinned.clear();
        self.pinned.resize(n - 2, false);
    }

    /// The buffers with one vector per node, then the rigid component's two.
    fn node_buffers(&mut self) -> [&mut Vec<Vec3>; 9] {
        [
            &mut self.preconditioner,
            &mut self.rhs,
            &mut self.dv,
            &mut self.r,
            &mut self.z,
            &mut self.p,
            &mut self.ap,
            &mut self.start_velocity,
            &mut self.solved_velocity,
        ]
    }

    /// The body's topology version the scratch is sized for.
    pub fn synced_version(&self) -> u64 {
        self.synced_version
    }

    /// Sizes the scratch to the body after a change that only appended nodes and springs (a cut or
    /// a tear: every node keeps its index), keeping the warm start: the last Δu of the nodes that
    /// were there and of the rigid component (moved to its new rows), zero for the new nodes. Every
    /// other buffer is written in full before it is read in a step, so it is only resized (no pass
    /// over it). A body with fewer nodes than before is sized afresh by [`Implicit::resize`].
    pub fn follow(&mut self, body: &Body) {
        let before = self.pinned.len();
        let n = body.node_count();
        if n < before || self.dv.len() != before + 2 {
            self.resize(body);
            return;
        }
        self.synced_version = body.topology_version;
        self.solved = false;
        self.follows += 1;
        let m = body.edges.len();
        self.u.resize(m, Vec3::zeros());
        self.tangent.resize(m, 0.0);
        self.axial.resize(m, 0.0);
        self.diagonal.resize(n + 2, 0.0);
        for buffer in self.node_buffers() {
            buffer.resize(n + 2, Vec3::zeros());
        }
        self.pinned.resize(n, false);
        let rigid = [self.dv[before], self.dv[before + 1]];
        for dv in &mut self.dv[before..n] {
            *dv = Vec3::zeros();
        }
        self.dv[n] = rigid[0];
        self.dv[n + 1] = rigid[1];
    }

    /// The warm start: the last Δu of every node, then of the rigid component's translation and
    /// rotation.
    pub fn warm_start(&self) -> &[Vec3] {
        &self.dv
    }

    /// y += (scale_k K + scale_c C) x over the edges.
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

    /// y += (scale_k K + scale_c C) x over the links: Jᵀ w J x per node, J = [−I, I, −[a]×].
    fn apply_links(body: &Body, x: &[Vec3], y: &mut [Vec3], scale_k: f64, scale_c: f64) {
        let s = &body.surface;
        let n = s.mass.len();
        let centre = body.rigid.position_in_world;
        let (translation, rotation) = (x[n], x[n + 1]);
        let (mut on_translation, mut on_rotation) = (Vec3::zeros(), Vec3::zeros());
        for i in 0..n {
            let arm = s.homologue_in_world[i] - centre;
            let d = translation - x[i] + rotation.cross(&arm);
            let w = scale_k * s.link_stiffness[i] + scale_c * s.link_damping[i];
            let wd = d * w;
            y[i] -= wd;
            on_translation += wd;
            on_rotation += arm.cross(&wd);
        }
        y[n] += on_translation;
        y[n + 1] += on_rotation;
    }

    /// Integrates the free nodes of `body` over `h` (forces already accumulated) and sets the rigid
    /// component's force and torque to what its own integration needs to follow the solve.
    pub fn integrate(&mut self, body: &mut Body, h: f64) {
        let n = body.node_count();
        // A solve that failed (its residual, and answer, not a number, which the divergence guard
        // undid) leaves no warm start: each later solve would start from it and fail again.
        if !self.last_residual.is_finite() {
            self.dv.iter_mut().for_each(|d| *d = Vec3::zeros());
        }
        self.prepare(body, h);
        for (pinned, contact) in self.pinned.iter_mut().zip(&body.surface.tool_contact) {
            *pinned = contact.tool != NO_TOOL;
        }

        // rhs = h (F − h K u), u = (v, V, ω).
        self.start_velocity[..n].copy_from_slice(&body.surface.velocity_in_world);
        self.start_velocity[n] = body.rigid.velocity_in_world;
        self.start_velocity[n + 1] = body.rigid.angular_velocity_in_world();
        let mut kv = std::mem::take(&mut self.ap);
        for x in &mut kv {
            *x = Vec3::zeros();
        }
        self.apply_edges(body, &self.start_velocity, &mut kv, 1.0, 0.0);
        Self::apply_links(body, &self.start_velocity, &mut kv, 1.0, 0.0);
        for ((rhs, force), kv) in self
            .rhs
            .iter_mut()
            .zip(&body.surface.force_in_world)
            .zip(&kv)
        {
            *rhs = (force - kv * h) * h;
        }
        self.rhs[n] = (body.rigid.force_in_world - kv[n] * h) * h;
        self.rhs[n + 1] = (body.rigid.torque_in_world - kv[n + 1] * h) * h;
        self.ap = kv;
        self.mask(body, Buffer::Rhs);
        self.mask(body, Buffer::Dv);
        self.solve(body, h);
        self.apply(body, h);
        self.solved = true;
    }

    /// After the obstacle contact stage: the nodes it stopped or slid (their velocity is no longer
    /// the solve's) are pinned at their new velocity and the rest — free nodes and rigid component —
    /// solved again around them, so the body answers a contact within the step it happens instead of
    /// storing the contact's displacement in its stiff links. Returns whether any node was newly
    /// pinned (then the caller runs the contact stage again on the new trajectories). Nothing is
    /// solved again where the scratch was sized afresh since the integration (a subdivision at a
    /// tool in between): its buffers no longer hold this step's solve.
    pub fn pin_contacts(&mut self, body: &mut Body, h: f64) -> bool {
        let n = body.node_count();
        if !self.solved {
            return false;
        }
        let mut any = false;
        for i in 0..n {
            if !self.pinned[i] && body.surface.velocity_in_world[i] != self.solved_velocity[i] {
                self.pinned[i] = true;
                self.dv[i] = body.surface.velocity_in_world[i] - self.start_velocity[i];
                any = true;
            }
        }
        if any {
            self.solve(body, h);
            self.apply(body, h);
        }
        any
    }

    /// Preconditioned conjugate gradient on A Δu = rhs, the pinned rows held at their Δu (zero for a
    /// fixed rigid component), warm-started from `dv`.
    fn solve(&mut self, body: &Body, h: f64) {
        let n = body.node_count();
        self.build_coarse(body, h);
        self.multiply(body, h, Operand::Solution);
        let mut rhs_norm = 0.0;
        for i in 0..n + 2 {
            self.r[i] = self.rhs[i] - self.ap[i];
            rhs_norm += self.rhs[i].norm_squared();
        }
        self.mask(body, Buffer::R);
        let rhs_norm = rhs_norm.sqrt().max(f64::MIN_POSITIVE);
        let mut rz = self.precondition(body);
        self.p.copy_from_slice(&self.z);
        let mut iterations = 0;
        let mut residual = self.r.iter().map(|r| r.norm_squared()).sum::<f64>().sqrt() / rhs_norm;
        while iterations < MAX_ITERATIONS && residual > TOLERANCE {
            self.multiply(body, h, Operand::Direction);
            let pap: f64 = self.p.iter().zip(&self.ap).map(|(p, ap)| p.dot(ap)).sum();
            if pap <= 0.0 || !pap.is_finite() {
                break;
            }
            let alpha = rz / pap;
            let mut r_norm = 0.0;
            for i in 0..n + 2 {
                self.dv[i] += self.p[i] * alpha;
                self.r[i] -= self.ap[i] * alpha;
                r_norm += self.r[i].norm_squared();
            }
            let rz_next = self.precondition(body);
            let beta = rz_next / rz;
            rz = rz_next;
            for i in 0..n + 2 {
                self.p[i] = self.z[i] + self.p[i] * beta;
            }
            iterations += 1;
            residual = r_norm.sqrt() / rhs_norm;
        }
        self.last_iterations = iterations;
        self.last_residual = residual;
    }

    /// The free nodes' new velocities and end positions, the rigid component's force and torque.
    fn apply(&mut self, body: &mut Body, h: f64) {
        let n = body.node_count();
        let s = &mut body.surface;
        for i in 0..n {
            if !self.pinned[i] {
                let velocity = self.start_velocity[i] + self.dv[i];
                s.velocity_in_world[i] = velocity;
                s.next_position_in_world[i] = s.position_in_world[i] + velocity * h;
            }
            self.solved_velocity[i] = s.velocity_in_world[i];
        }
        if !body.rigid.fixed {
            // The rigid component's semi-implicit update, V += F h / M and L += T h, then gives
            // V + ΔV and L + I_w Δω = I_w (ω + Δω).
            let inertia = body.rigid.inertia_in_world();
            body.rigid.force_in_world = self.dv[n] * (body.rigid.mass / h);
            body.rigid.torque_in_world = inertia * self.dv[n + 1] / h;
        }
    }

    /// Edge blocks, diagonals and the block-Jacobi preconditioner at the current state.
    fn prepare(&mut self, body: &Body, h: f64) {
        let s = &body.surface;
        let e = &body.edges;
        let n = s.mass.len();
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
        let centre = body.rigid.position_in_world;
        let mut translation_block = 0.0;
        let mut rotation_block = Matrix3::zeros();
        for i in 0..n {
            self.diagonal[i] = s.mass[i] + h * s.air_damping[i];
            let w = h * h * s.link_stiffness[i] + h * s.link_damping[i];
            self.preconditioner[i] = Vec3::repeat(self.diagonal[i] + w);
            let arm = s.homologue_in_world[i] - centre;
            translation_block += w;
            rotation_block +=
                (Matrix3::identity() * arm.norm_squared() - arm * arm.transpose()) * w;
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
        let r = &body.rigid;
        let air = 1.0 + h * r.air_viscosity;
        self.rigid_mass = r.mass * air;
        self.rigid_inertia = r.inertia_in_world() * air;
        self.translation_block_inverse = 1.0 / (self.rigid_mass + translation_block);
        let rotation = self.rigid_inertia + rotation_block;
        self.rotation_block_inverse = rotation.try_inverse().unwrap_or_else(|| {
            Matrix3::from_diagonal(&rotation.diagonal().map(|x| 1.0 / x.max(f64::MIN_POSITIVE)))
        });
    }

    /// Zeroes the rows the solve keeps fixed: pinned nodes, a fixed rigid component.
    fn mask(&mut self, body: &Body, which: Buffer) {
        let n = body.node_count();
        let buffer = match which {
            Buffer::Rhs => &mut self.rhs,
            Buffer::Dv => &mut self.dv,
            Buffer::R => &mut self.r,
            Buffer::Ap => &mut self.ap,
        };
        for (x, &pinned) in buffer.iter_mut().zip(&self.pinned) {
            if pinned {
                *x = Vec3::zeros();
            }
        }
        if body.rigid.fixed {
            buffer[n] = Vec3::zeros();
            buffer[n + 1] = Vec3::zeros();
        }
    }

    /// Zᵀ x: the sum over the free rows of the six rigid modes (translations, then rotations about
    /// the rigid component's centre).
    fn restrict(&self, body: &Body, x: &[Vec3]) -> Vector6<f64> {
        let s = &body.surface;
        let n = s.mass.len();
        let centre = body.rigid.position_in_world;
        let (mut force, mut torque) = (Vec3::zeros(), Vec3::zeros());
        for ((x, position), &pinned) in x.iter().zip(&s.position_in_world).zip(&self.pinned) {
            if !pinned {
                force += x;
                torque += (position - centre).cross(x);
            }
        }
        if !body.rigid.fixed {
            force += x[n];
            torque += x[n + 1];
        }
        Vector6::new(force.x, force.y, force.z, torque.x, torque.y, torque.z)
    }

    /// y += Z c: every free node moves by t + θ × (x − X), the rigid component by (t, θ).
    fn prolong(pinned: &[bool], body: &Body, c: &Vector6<f64>, y: &mut [Vec3]) {
        let s = &body.surface;
        let n = s.mass.len();
        let centre = body.rigid.position_in_world;
        let t = Vec3::new(c[0], c[1], c[2]);
        let theta = Vec3::new(c[3], c[4], c[5]);
        for i in 0..n {
            if pinned[i] {
                continue;
            }
            y[i] += t + theta.cross(&(s.position_in_world[i] - centre));
        }
        if !body.rigid.fixed {
            y[n] += t;
            y[n + 1] += theta;
        }
    }

    /// E = Zᵀ A Z by six products with A, inverted (`None` when it is not positive definite, e.g. a
    /// fixed rigid component with every node held).
    fn build_coarse(&mut self, body: &Body, h: f64) {
        let mut e = Matrix6::zeros();
        for column in 0..6 {
            for x in &mut self.p {
                *x = Vec3::zeros();
            }
            let mut unit = Vector6::zeros();
            unit[column] = 1.0;
            Self::prolong(&self.pinned, body, &unit, &mut self.p);
            self.multiply(body, h, Operand::Direction);
            e.set_column(column, &self.restrict(body, &self.ap));
        }
        let symmetric = (e + e.transpose()) * 0.5;
        self.coarse_inverse = symmetric.cholesky().map(|c| c.inverse());
    }

    /// z = P⁻¹ r (block Jacobi plus the rigid-mode correction); returns r·z.
    fn precondition(&mut self, body: &Body) -> f64 {
        let n = body.node_count();
        for i in 0..n {
            self.z[i] = self.r[i].component_div(&self.preconditioner[i]);
        }
        self.z[n] = self.r[n] * self.translation_block_inverse;
        self.z[n + 1] = self.rotation_block_inverse * self.r[n + 1];
        if let Some(coarse) = &self.coarse_inverse {
            let c = coarse * self.restrict(body, &self.r);
            Self::prolong(&self.pinned, body, &c, &mut self.z);
        }
        let z = std::mem::take(&mut self.z);
        let rz = self.r.iter().zip(&z).map(|(r, z)| r.dot(z)).sum();
        self.z = z;
        self.mask_z(body);
        rz
    }

    fn mask_z(&mut self, body: &Body) {
        let n = body.node_count();
        for (x, &pinned) in self.z.iter_mut().zip(&self.pinned) {
            if pinned {
                *x = Vec3::zeros();
            }
        }
        if body.rigid.fixed {
            self.z[n] = Vec3::zeros();
            self.z[n + 1] = Vec3::zeros();
        }
    }

    /// ap = A p (or A Δu), A = M + h C + h² K, fixed rows zeroed.
    fn multiply(&mut self, body: &Body, h: f64, operand: Operand) {
        let n = body.node_count();
        let source = match operand {
            Operand::Solution => std::mem::take(&mut self.dv),
            Operand::Direction => std::mem::take(&mut self.p),
        };
        let mut out = std::mem::take(&mut self.ap);
        for i in 0..n {
            out[i] = source[i] * self.diagonal[i];
        }
        out[n] = source[n] * self.rigid_mass;
        out[n + 1] = self.rigid_inertia * source[n + 1];
        self.apply_edges(body, &source, &mut out, h * h, h);
        Self::apply_links(body, &source, &mut out, h * h, h);
        self.ap = out;
        match operand {
            Operand::Solution => self.dv = source,
            Operand::Direction => self.p = source,
        }
        self.mask(body, Buffer::Ap);
    }
}

#[derive(Clone, Copy)]
enum Operand {
    Solution,
    Direction,
}

#[derive(Clone, Copy)]
enum Buffer {
    Rhs,
    Dv,
    R,
    Ap,
}
