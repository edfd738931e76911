//! Attachments: ligaments and mesentery. A region of a body (its nodes within a radius of a point of
//! its rest frame) is tied, node by node, to the world or to the nearest node of another body by
//! damped springs, so organs hang where anatomy puts them.
//!
//! Each tie is a spring of rest length the distance it spans when the scene starts (0 for a tie to
//! the world: its anchor is where the node starts) and a damper on the relative velocity of its two
//! ends. The attachment's `stiffness` and `damping` are totals, shared by the region's nodes in
//! proportion to their mass, so the region's own frequency √(k/M) does not depend on the mesh.
//!
//! The ties' forces are computed once per tick from the start-of-tick state (all bodies alike) and
//! added to the nodes' forces before each body's integrator, as any force from outside the body: the
//! implicit solve takes them in its right-hand side (so a body at rest balances them exactly), the
//! multi-rate substeps add them to the forces they recompute. The two ends of a tie between bodies
//! take equal and opposite forces. A node a tool holds passes its tie's pull to the tool.

use crate::Vec3;
use crate::body::Body;

/// No other body: the tie's anchor is fixed in the world.
pub const WORLD: u32 = u32::MAX;

/// One node's tie, as the scene resolves it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tie {
    /// The node of the attached body.
    pub node: u32,
    /// The node of the other body it is tied to ([`WORLD`] for the world).
    pub other_node: u32,
    /// Spring stiffness (N/m).
    pub stiffness: f64,
    /// Damping of the relative velocity (N·s/m).
    pub damping: f64,
}

/// An attachment as the scene describes it, its ties resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct AttachmentSpec {
    /// Unique name.
    pub name: String,
    /// Index of the attached body.
    pub body: usize,
    /// Index of the body it is tied to (`None`: the world).
    pub to: Option<usize>,
    /// One tie per node of the region.
    pub ties: Vec<Tie>,
}

/// A tie with its ends in the world's bodies.
#[derive(Clone, Copy, Debug, PartialEq)]
struct LiveTie {
    body: u32,
    node: u32,
    other_body: u32,
    other_node: u32,
    /// Anchor of a tie to the world (m, world).
    anchor_in_world: Vec3,
    rest_length: f64,
    stiffness: f64,
    damping: f64,
}

/// The attachments of a world: ties, and each tie's force of the tick.
#[derive(Clone, Debug, Default)]
pub struct Attachments {
    names: Vec<String>,
    /// Ties of attachment `a`: `ties[start[a]..start[a + 1]]`.
    start: Vec<usize>,
    ties: Vec<LiveTie>,
    /// Force of each tie on its node of the attached body this tick (N, world); the other end takes
    /// the opposite.
    force: Vec<Vec3>,
    /// Work the ties did on each body this tick, in absolute value (J), for the divergence guard.
    work: Vec<f64>,
}

impl Attachments {
    /// Builds the ties of `specs` on `bodies` as they are placed now: rest lengths are the distances
    /// the ties span, anchors in the world where the nodes are.
    pub fn new(specs: &[AttachmentSpec], bodies: &[Body]) -> Self {
        let mut a = Self {
            start: vec![0],
            work: vec![0.0; bodies.len()],
            ..Self::default()
        };
        for spec in specs {
            let body = &bodies[spec.body];
            for tie in &spec.ties {
                let x = body.surface.position_in_world[tie.node as usize];
                let (other_body, anchor, rest_length) = match spec.to {
                    None => (WORLD, x, 0.0),
                    Some(o) => {
                        let y = bodies[o].surface.position_in_world[tie.other_node as usize];
                        (o as u32, y, (y - x).norm())
                    }
                };
                a.ties.push(LiveTie {
                    body: spec.body as u32,
                    node: tie.node,
                    other_body,
                    other_node: tie.other_node,
                    anchor_in_world: anchor,
                    rest_length,
                    stiffness: tie.stiffness,
                    damping: tie.damping,
                });
            }
            a.names.push(spec.name.clone());
            a.start.push(a.ties.len());
        }
        a.force = vec![Vec3::zeros(); a.ties.len()];
        a
    }

    /// True when there is no tie.
    pub fn is_empty(&self) -> bool {
        self.ties.is_empty()
    }

    /// Number of attachments.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Name of attachment `a`.
    pub fn name(&self, a: usize) -> &str {
        &self.names[a]
    }

    /// Total force attachment `a` puts on its body this tick (N, world); its other end (the world
    /// or the other body) takes the opposite.
    pub fn force_on_body(&self, a: usize) -> Vec3 {
        self.force[self.start[a]..self.start[a + 1]]
            .iter()
            .fold(Vec3::zeros(), |sum, f| sum + f)
    }

    /// Total force every attachment puts on body `b` this tick (N, world), both ends counted.
    pub fn force_on(&self, b: usize) -> Vec3 {
        let mut sum = Vec3::zeros();
        for (tie, f) in self.ties.iter().zip(&self.force) {
            if tie.body as usize == b {
                sum += f;
            }
            if tie.other_body as usize == b {
                sum -= f;
            }
        }
        sum
    }

    /// The body ends of attachment `a`'s ties, as `(body, node)` (they follow their nodes through
    /// transections).
    pub fn tied_nodes(&self, a: usize) -> impl Iterator<Item = (usize, u32)> + '_ {
        self.ties[self.start[a]..self.start[a + 1]]
            .iter()
            .map(|t| (t.body as usize, t.node))
    }

    /// Makes room for the work of `count` bodies (the scene's and the spares a transection may
    /// fill), so that a tie that follows a node into a new body is counted there. Setup only.
    pub fn reserve_bodies(&mut self, count: usize) {
        if self.work.len() < count {
            self.work.resize(count, 0.0);
        }
    }

    /// Follows a renumbering of body `body`'s nodes (a transection): every tie end on it moves to
    /// where `place` puts its node — `(body, node)`, the same body or a new one. A tie whose node
    /// has no place (cannot happen: ties hold nodes of the mesh the transection split) is left
    /// as it was. Allocation-free.
    pub fn renumber(&mut self, body: usize, place: impl Fn(u32) -> Option<(usize, u32)>) {
        for t in &mut self.ties {
            if t.body as usize == body
                && let Some((b, n)) = place(t.node)
            {
                t.body = b as u32;
                t.node = n;
            }
            if t.other_body as usize == body
                && let Some((b, n)) = place(t.other_node)
            {
                t.other_body = b as u32;
                t.other_node = n;
            }
        }
    }

    /// Work the ties did on body `b` this tick, in absolute value (J).
    pub fn work_on(&self, b: usize) -> f64 {
        self.work.get(b).copied().unwrap_or(0.0)
    }

    /// Elastic energy stored in the ties (J).
    pub fn energy(&self, bodies: &[Body]) -> f64 {
        self.ties
            .iter()
            .map(|t| {
                let (x, _) = end(bodies, t.body, t.node, &t.anchor_in_world);
                let (y, _) = end(bodies, t.other_body, t.other_node, &t.anchor_in_world);
                let stretch = (y - x).norm() - t.rest_length;
                0.5 * t.stiffness * stretch * stretch
            })
            .sum()
    }

    /// Computes every tie's force from the bodies' start-of-tick state. Allocation-free.
    pub fn compute(&mut self, bodies: &[Body], dt: f64) {
        for w in &mut self.work {
            *w = 0.0;
        }
        for (t, force) in self.ties.iter().zip(&mut self.force) {
            let (x, v) = end(bodies, t.body, t.node, &t.anchor_in_world);
            let (y, w) = end(bodies, t.other_body, t.other_node, &t.anchor_in_world);
            let d = y - x;
            let spring = if t.rest_length == 0.0 {
                d * t.stiffness
            } else {
                let length = d.norm();
                if length > f64::MIN_POSITIVE {
                    d * (t.stiffness * (length - t.rest_length) / length)
                } else {
                    Vec3::zeros()
                }
            };
            let f = spring + (w - v) * t.damping;
            *force = if f.iter().all(|c| c.is_finite()) {
                f
            } else {
                Vec3::zeros()
            };
            if let Some(work) = self.work.get_mut(t.body as usize) {
                *work += (force.dot(&v) * dt).abs();
            }
            if let Some(work) = self.work.get_mut(t.other_body as usize) {
                *work += (force.dot(&w) * dt).abs();
            }
        }
    }

    /// The tick's tie forces on body `b`'s nodes, as `(node, force)` (N, world). Allocation-free.
    pub fn forces_on(&self, b: usize) -> impl Iterator<Item = (usize, Vec3)> + '_ {
        self.ties.iter().zip(&self.force).filter_map(move |(t, f)| {
            if t.body as usize == b {
                Some((t.node as usize, *f))
            } else if t.other_body as usize == b {
                Some((t.other_node as usize, -f))
            } else {
                None
            }
        })
    }
}

/// Position and velocity of a tie's end: a body's node, or the anchor in the world.
fn end(bodies: &[Body], body: u32, node: u32, anchor: &Vec3) -> (Vec3, Vec3) {
    if body == WORLD {
        return (*anchor, Vec3::zeros());
    }
    let s = &bodies[body as usize].surface;
    (
        s.position_in_world[node as usize],
        s.velocity_in_world[node as usize],
    )
}
