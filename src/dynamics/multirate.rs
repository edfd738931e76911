//! Multi-rate integration (paper §5, "pas de temps à différents grains"; MODEL.md §7): the rigid
//! component and every node whose stability bound allows it keep the big step; the nodes that violate
//! it (light nodes, stiff springs) are sub-stepped with the smallest power-of-two division that
//! satisfies it.
//!
//! Fixed, deterministic exchange schedule: the slow nodes are integrated first over the whole step
//! with the forces of its start; then the fast nodes are integrated together in substeps, each
//! substep recomputing their forces from their own current states and from the slow neighbours'
//! positions interpolated linearly between the start and the end of the step. The slow nodes feel the
//! fast ones through the forces at the start of the step. With no fast node this is exactly the
//! symplectic scheme.

use crate::Vec3;
use crate::body::Body;
use crate::contact::tool::NO_TOOL;
use crate::dynamics::stability::{node_bounds_into, stable_at};

/// Largest number of halvings of the step.
pub const MAX_LEVEL: u32 = 12;
/// Fraction of the stability limit a node may use.
pub const SAFETY: f64 = 0.9;

/// Scratch and classification of one body.
#[derive(Clone, Debug)]
pub struct Multirate {
    /// Fast nodes, in index order.
    pub fast: Vec<u32>,
    /// Substeps per step of the fast nodes (2^level of the fastest).
    pub substeps: u32,
    local: Vec<u32>,
    start: Vec<u32>,
    neighbour: Vec<u32>,
    edge: Vec<u32>,
    x: Vec<Vec3>,
    v: Vec<Vec3>,
    f: Vec<Vec3>,
    homologue_end: Vec<Vec3>,
    bound_stiffness: Vec<f64>,
    bound_damping: Vec<f64>,
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
            local: Vec::with_capacity(n),
            start: Vec::with_capacity(n + 1),
            neighbour: Vec::with_capacity(2 * m),
            edge: Vec::with_capacity(2 * m),
            x: Vec::with_capacity(n),
            v: Vec::with_capacity(n),
            f: Vec::with_capacity(n),
            homologue_end: Vec::with_capacity(n),
            bound_stiffness: Vec::with_capacity(n),
            bound_damping: Vec::with_capacity(n),
        };
        multirate.rebuild(body, dt);
        multirate
    }

    /// Classifies the nodes again after the body's topology changed, reusing the scratch (allocates
    /// nothing while the body stays within the room reserved).
    pub fn rebuild(&mut self, body: &Body, dt: f64) {
        let s = &body.surface;
        let n = s.mass.len();
        node_bounds_into(body, &mut self.bound_stiffness, &mut self.bound_damping);
        self.fast.clear();
        let mut level_max = 0;
        for i in 0..n {
            let mut level = 0;
            while level < MAX_LEVEL
                && !stable_at(
                    self.bound_stiffness[i],
                    self.bound_damping[i],
                    s.inverse_mass[i],
                    dt / (1u32 << level) as f64,
                    SAFETY,
                )
            {
                level += 1;
            }
            if level > 0 {
                self.fast.push(i as u32);
                level_max = level_max.max(level);
            }
        }
        self.substeps = 1 << level_max;
        self.local.clear();
        self.local.resize(n, u32::MAX);
        for (k, &i) in self.fast.iter().enumerate() {
            self.local[i as usize] = k as u32;
        }
        // Incident edges of every node (CSR), in edge order.
        let e = &body.edges;
        self.start.clear();
        self.start.resize(n + 1, 0);
        for k in 0..e.len() {
            self.start[e.a[k] as usize + 1] += 1;
            self.start[e.b[k] as usize + 1] += 1;
        }
        for i in 0..n {
            self.start[i + 1] += self.start[i];
        }
        self.neighbour.clear();
        self.neighbour.resize(2 * e.len(), 0);
        self.edge.clear();
        self.edge.resize(2 * e.len(), 0);
        // Fill each node's slots from the back, `start[i + 1]` (the end of node i's slots) serving as
        // the cursor: it counts down to the first slot of node i.
        for k in (0..e.len()).rev() {
            for (me, other) in [(e.b[k], e.a[k]), (e.a[k], e.b[k])] {
                let me = me as usize;
                self.start[me + 1] -= 1;
                let at = self.start[me + 1] as usize;
                self.neighbour[at] = other;
                self.edge[at] = k as u32;
            }
        }
        // Now `start[i + 1]` is where node i's slots begin: shift down by one.
        for i in 0..n {
            self.start[i] = self.start[i + 1];
        }
        self.start[n] = 2 * e.len() as u32;
        let m = self.fast.len();
        for buffer in [
            &mut self.x,
            &mut self.v,
            &mut self.f,
            &mut self.homologue_end,
        ] {
            buffer.clear();
            buffer.resize(m, Vec3::zeros());
        }
    }

    /// Integrates the free nodes of `body` over `dt` (forces already accumulated): slow nodes in one
    /// step, fast nodes in substeps. Allocates nothing.
    pub fn integrate(&mut self, body: &mut Body, dt: f64, gravity: &Vec3) {
        let s = &mut body.surface;
        let n = s.mass.len();
        for i in 0..n {
            if self.local[i] != u32::MAX || s.tool_contact[i].tool != NO_TOOL {
                continue;
            }
            let velocity = s.velocity_in_world[i] + s.force_in_world[i] * (dt * s.inverse_mass[i]);
            s.velocity_in_world[i] = velocity;
            s.next_position_in_world[i] = s.position_in_world[i] + velocity * dt;
        }
        if self.fast.is_empty() {
            return;
        }
        // Where the rigid component will be at the end of the step (its forces are already known), so
        // the fast nodes' homologues move with it through the substeps instead of waiting a step.
        let mut rigid_end = body.rigid.clone();
        rigid_end.integrate(dt);
        let end_rotation = rigid_end.world_from_body.to_rotation_matrix();
        for (k, &i) in self.fast.iter().enumerate() {
            self.x[k] = s.position_in_world[i as usize];
            self.v[k] = s.velocity_in_world[i as usize];
            self.homologue_end[k] =
                rigid_end.position_in_world + end_rotation * s.homologue_in_body[i as usize];
        }
        let h = dt / self.substeps as f64;
        let e = &body.edges;
        for step in 0..self.substeps {
            let fraction = step as f64 / self.substeps as f64;
            for (k, &i) in self.fast.iter().enumerate() {
                let i = i as usize;
                if s.tool_contact[i].tool != NO_TOOL {
                    continue;
                }
                let (x, v) = (self.x[k], self.v[k]);
                let (start, end) = (s.homologue_in_world[i], self.homologue_end[k]);
                let homologue = start + (end - start) * fraction;
                let homologue_velocity = (end - start) / dt;
                let mut force = gravity * s.mass[i] - v * s.air_damping[i]
                    + (homologue - x) * s.link_stiffness[i]
                    + (homologue_velocity - v) * s.link_damping[i];
                for at in self.start[i] as usize..self.start[i + 1] as usize {
                    let j = self.neighbour[at] as usize;
                    let edge = self.edge[at] as usize;
                    let (xj, vj) = match self.local[j] {
                        u32::MAX => {
                            let (a, b) = (s.position_in_world[j], s.next_position_in_world[j]);
                            (a + (b - a) * fraction, (b - a) / dt)
                        }
                        l => (self.x[l as usize], self.v[l as usize]),
                    };
                    let d = xj - x;
                    let length = d.norm();
                    if length <= f64::MIN_POSITIVE {
                        continue;
                    }
                    let inverse_length = 1.0 / length;
                    let magnitude = e.stiffness[edge] * (length - e.rest_length[edge])
                        + e.damping[edge] * (vj - v).dot(&d) * inverse_length;
                    force += d * (magnitude * inverse_length);
                }
                self.f[k] = force;
            }
            for (k, &i) in self.fast.iter().enumerate() {
                let i = i as usize;
                if s.tool_contact[i].tool != NO_TOOL {
                    continue;
                }
                self.v[k] += self.f[k] * (h * s.inverse_mass[i]);
                self.x[k] += self.v[k] * h;
            }
        }
        for (k, &i) in self.fast.iter().enumerate() {
            let i = i as usize;
            if s.tool_contact[i].tool != NO_TOOL {
                continue;
            }
            s.velocity_in_world[i] = self.v[k];
            s.next_position_in_world[i] = self.x[k];
        }
    }
}
