//! The plain reference of `palpa-bench reference`: the simplest correct code for the model of
//! MODEL.md §2–3 on one body whose rigid component is held — array of structs, scalar `f64`, one pass
//! over the nodes (gravity, air, link and its reaction), one over the edges (damped springs), one
//! over the nodes (semi-implicit Euler). No contact, no guard, no profiling, no topology: what an
//! afternoon's code for the same physics costs on this machine, to compare palpa's whole tick with.
//!
//! It is built from a palpa [`Body`] (same mesh, masses, springs, links) so that both step the same
//! system; `palpa-bench reference` checks that they stay within round-off of each other.

use palpa::Vec3;
use palpa::body::Body;

/// One node, everything it needs side by side.
#[derive(Clone, Copy)]
struct Node {
    x: [f64; 3],
    v: [f64; 3],
    f: [f64; 3],
    mass: f64,
    air: f64,
    homologue_in_body: [f64; 3],
    link_stiffness: f64,
    link_damping: f64,
}

/// One edge spring.
#[derive(Clone, Copy)]
struct Edge {
    a: usize,
    b: usize,
    rest: f64,
    stiffness: f64,
    damping: f64,
}

/// The reference system: nodes, edges and the held rigid component's pose.
pub struct Reference {
    nodes: Vec<Node>,
    edges: Vec<Edge>,
    centre: [f64; 3],
    rotation: [[f64; 3]; 3],
    gravity: [f64; 3],
    dt: f64,
    /// Reaction of the links on the rigid component, last step (N and N·m, world frame); a held
    /// component does not move, but the code computes what it would feel, as palpa's does.
    pub reaction: ([f64; 3], [f64; 3]),
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

impl Reference {
    /// The reference copy of `body` (its rigid component must be held) under `gravity`, step `dt`.
    pub fn from_body(body: &Body, gravity: &Vec3, dt: f64) -> Self {
        assert!(body.params.fixed, "the reference holds the rigid component");
        let s = &body.surface;
        let nodes = (0..body.node_count())
            .map(|i| Node {
                x: s.position_in_world[i].into(),
                v: s.velocity_in_world[i].into(),
                f: [0.0; 3],
                mass: s.mass[i],
                air: s.air_damping[i],
                homologue_in_body: s.homologue_in_body[i].into(),
                link_stiffness: s.link_stiffness[i],
                link_damping: s.link_damping[i],
            })
            .collect();
        let e = &body.edges;
        let edges = (0..e.len())
            .map(|k| Edge {
                a: e.a[k] as usize,
                b: e.b[k] as usize,
                rest: e.rest_length[k],
                stiffness: e.stiffness[k],
                damping: e.damping[k],
            })
            .collect();
        let r = body.rigid.world_from_body.to_rotation_matrix();
        let m = r.matrix();
        Self {
            nodes,
            edges,
            centre: body.rigid.position_in_world.into(),
            rotation: [
                [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
                [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
                [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
            ],
            gravity: (*gravity).into(),
            dt,
            reaction: ([0.0; 3], [0.0; 3]),
        }
    }

    /// One step of the model.
    pub fn step(&mut self) {
        let (g, dt, r, c) = (self.gravity, self.dt, self.rotation, self.centre);
        let mut reaction_force = [0.0; 3];
        let mut reaction_torque = [0.0; 3];
        for n in &mut self.nodes {
            let h = n.homologue_in_body;
            let arm = [dot(r[0], h), dot(r[1], h), dot(r[2], h)];
            // The held component: the homologue does not move.
            let link_vector = sub([c[0] + arm[0], c[1] + arm[1], c[2] + arm[2]], n.x);
            let mut link = [0.0; 3];
            for k in 0..3 {
                link[k] = link_vector[k] * n.link_stiffness - n.v[k] * n.link_damping;
                n.f[k] = g[k] * n.mass - n.v[k] * n.air + link[k];
                reaction_force[k] -= link[k];
            }
            let torque = cross(arm, link);
            for k in 0..3 {
                reaction_torque[k] -= torque[k];
            }
        }
        self.reaction = (reaction_force, reaction_torque);
        for e in &self.edges {
            let (na, nb) = (self.nodes[e.a], self.nodes[e.b]);
            let d = sub(nb.x, na.x);
            let length = dot(d, d).sqrt();
            if length <= f64::MIN_POSITIVE {
                continue;
            }
            let magnitude =
                e.stiffness * (length - e.rest) + e.damping * dot(sub(nb.v, na.v), d) / length;
            for (k, dk) in d.into_iter().enumerate() {
                let force = dk * magnitude / length;
                self.nodes[e.a].f[k] += force;
                self.nodes[e.b].f[k] -= force;
            }
        }
        for n in &mut self.nodes {
            for k in 0..3 {
                n.v[k] += dt * n.f[k] / n.mass;
                n.x[k] += dt * n.v[k];
            }
        }
    }

    /// Position of node `i` (m, world frame).
    pub fn position(&self, i: usize) -> Vec3 {
        Vec3::from(self.nodes[i].x)
    }
}
