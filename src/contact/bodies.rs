//! Contact between deformable bodies (paper §5: collisions are found on trajectories).
//!
//! After every other stage has decided where the nodes end the tick, the trajectories of different
//! bodies are checked against each other: the broad phase ([`TriangleBvh`], swept boxes) lists the
//! triangle pairs that may meet, and the narrow phase tests each pair's vertices against the other's
//! face (both ways) and each edge against the other's edges, with the earliest time of impact.
//!
//! The response is inelastic and conservative: the free nodes of a colliding pair stop short of the
//! impact, at 90 % of the (lower-bound) time of impact along their own trajectory, and take the
//! velocity that brings them there. This repeats a few rounds, as stopping some nodes can expose other
//! pairs; what still collides after that is frozen at its start-of-tick position, where the previous
//! tick left everything apart. Primitives that touch at the start of the tick and separate over it are
//! left alone, so bodies can part. Nodes held by a tool are moved by the tool only.

use crate::Vec3;
use crate::body::Body;
use crate::collision::bvh::TriangleBvh;
use crate::collision::ccd::{CcdSettings, edge_edge_time_of_impact, vertex_face_time_of_impact};
use crate::collision::tool::{closest_point_on_triangle, segment_segment_distance};
use crate::contact::tool::NO_TOOL;

/// Rounds of stop-short before the remaining collisions are frozen.
const ROUNDS: usize = 4;
/// Fraction of the time of impact a colliding node is allowed to travel.
const STOP_SHORT: f64 = 0.9;
/// Capacity of the candidate triangle-pair list.
const PAIR_CAPACITY: usize = 1 << 16;

/// What the body–body stage did in one step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BodyContactCounters {
    /// Triangle pairs the broad phase passed to the narrow phase.
    pub candidate_pairs: u32,
    /// Vertex–face and edge–edge collisions answered.
    pub collisions: u32,
    /// Collisions still found after the rounds ran out, answered by freezing their nodes at their
    /// start-of-tick positions.
    pub frozen: u32,
    /// Broad-phase queries that filled the pair list: the pairs it holds are answered by freezing,
    /// pairs beyond its capacity are not tested (counted so it is never silent).
    pub overflows: u32,
}

/// Scratch memory of the stage, sized when the world is assembled.
#[derive(Clone, Debug)]
pub struct BodyContactScratch {
    bvhs: Vec<TriangleBvh>,
    pairs: Vec<(u32, u32)>,
    settings: CcdSettings,
}

impl BodyContactScratch {
    /// Builds the hierarchies of every body, with room for each body's triangle capacity, and empty
    /// hierarchies with room for `spare_triangles` triangles for `spare` bodies yet to come (pieces of
    /// a transection).
    pub fn new(bodies: &[Body], spare: usize, spare_triangles: usize) -> Self {
        let mut bvhs: Vec<TriangleBvh> = bodies
            .iter()
            .map(|b| {
                let mut bvh = TriangleBvh::with_capacity(b.mesh_capacity().1);
                bvh.rebuild(&b.surface.triangles, &b.surface.position_in_world);
                bvh.set_built_version(b.topology_version);
                bvh
            })
            .collect();
        bvhs.extend((0..spare).map(|_| {
            let mut bvh = TriangleBvh::with_capacity(spare_triangles);
            bvh.set_built_version(u64::MAX);
            bvh
        }));
        Self {
            bvhs,
            pairs: Vec::with_capacity(PAIR_CAPACITY),
            settings: CcdSettings::default(),
        }
    }
}

/// A node of some body.
#[derive(Clone, Copy)]
struct NodeRef {
    body: usize,
    node: usize,
}

fn start_of(bodies: &[Body], r: NodeRef) -> Vec3 {
    bodies[r.body].surface.position_in_world[r.node]
}

fn end_of(bodies: &[Body], r: NodeRef) -> Vec3 {
    bodies[r.body].surface.next_position_in_world[r.node]
}

/// Stops a node at `fraction` of its trajectory (tool-held nodes are left to the tool).
fn stop_at(bodies: &mut [Body], r: NodeRef, fraction: f64, dt: f64) {
    let s = &mut bodies[r.body].surface;
    if s.tool_contact[r.node].tool != NO_TOOL {
        return;
    }
    let start = s.position_in_world[r.node];
    let end = start + (s.next_position_in_world[r.node] - start) * fraction;
    s.next_position_in_world[r.node] = end;
    s.velocity_in_world[r.node] = (end - start) / dt;
}

/// Distance between the two primitives and a signed measure of which side of each other they are on
/// (vertex against the face's plane; edges by the orientation of their tetrahedron).
fn distance_and_side(p: &[Vec3; 4], vertex_face: bool) -> (f64, f64) {
    if vertex_face {
        let normal = (p[2] - p[1]).cross(&(p[3] - p[1]));
        (
            (closest_point_on_triangle(&p[0], &p[1], &p[2], &p[3]) - p[0]).norm(),
            (p[0] - p[1]).dot(&normal),
        )
    } else {
        (
            segment_segment_distance(&p[0], &p[1], &p[2], &p[3]),
            (p[1] - p[0]).cross(&(p[3] - p[2])).dot(&(p[2] - p[0])),
        )
    }
}

/// For primitives touching at the start of the tick: true when they part over it — their distance
/// grows and they do not cross. `nodes` is the vertex then the face when `vertex_face`, otherwise
/// edge (0, 1) then edge (2, 3).
fn parting(bodies: &[Body], nodes: &[NodeRef; 4], vertex_face: bool) -> bool {
    let (before, side_before) = distance_and_side(&nodes.map(|r| start_of(bodies, r)), vertex_face);
    let (after, side_after) = distance_and_side(&nodes.map(|r| end_of(bodies, r)), vertex_face);
    let crossed = side_before * side_after < 0.0;
    after > before && !crossed
}

/// Tests one vertex–face or edge–edge pair; answers a collision by stopping its nodes short (or,
/// when `freeze`, at their start). Returns true when it answered a collision.
fn test_primitive(
    bodies: &mut [Body],
    nodes: [NodeRef; 4],
    vertex_face: bool,
    settings: &CcdSettings,
    freeze: bool,
    dt: f64,
) -> bool {
    let s = nodes.map(|r| start_of(bodies, r));
    let e = nodes.map(|r| end_of(bodies, r));
    let hit = if vertex_face {
        vertex_face_time_of_impact(
            &s[0], &s[1], &s[2], &s[3], &e[0], &e[1], &e[2], &e[3], settings,
        )
    } else {
        edge_edge_time_of_impact(
            &s[0], &s[1], &s[2], &s[3], &e[0], &e[1], &e[2], &e[3], settings,
        )
    };
    let Some(hit) = hit else { return false };
    if hit.time_of_impact == 0.0 && parting(bodies, &nodes, vertex_face) {
        // Touching at the start and parting: left alone, so bodies can separate.
        return false;
    }
    let fraction = if freeze {
        0.0
    } else {
        STOP_SHORT * hit.time_of_impact
    };
    for r in nodes {
        stop_at(bodies, r, fraction, dt);
    }
    true
}

/// Finds and answers collisions between the trajectories of different bodies. Bodies with the same
/// `group` (the pieces of one transected body, whose caps start where they were cut apart) are not
/// tested against each other.
pub fn resolve_body_collisions(
    bodies: &mut [Body],
    group: &[usize],
    scratch: &mut BodyContactScratch,
    dt: f64,
) -> BodyContactCounters {
    let mut counters = BodyContactCounters::default();
    for round in 0..=ROUNDS {
        let freeze = round == ROUNDS;
        for (b, bvh) in bodies.iter().zip(scratch.bvhs.iter_mut()) {
            let s = &b.surface;
            // A topology change (subdivision, cut, transection) renumbers triangles: the hierarchy is
            // built again, in place.
            if round == 0 && !bvh.is_built_for(b.topology_version, s.triangles.len()) {
                bvh.rebuild(&s.triangles, &s.position_in_world);
                bvh.set_built_version(b.topology_version);
            }
            bvh.refit(
                &s.triangles,
                &s.position_in_world,
                &s.next_position_in_world,
                0.0,
            );
        }
        let mut answered = 0;
        for i in 0..bodies.len() {
            for j in i + 1..bodies.len() {
                if group.get(i).is_some_and(|g| group.get(j) == Some(g)) {
                    continue;
                }
                scratch.pairs.clear();
                let (left, right) = scratch.bvhs.split_at_mut(j);
                let complete = left[i].overlapping_pairs(&right[0], &mut scratch.pairs);
                if !complete {
                    counters.overflows += 1;
                }
                counters.candidate_pairs += scratch.pairs.len() as u32;
                for k in 0..scratch.pairs.len() {
                    let (ta, tb) = scratch.pairs[k];
                    let fa = bodies[i].surface.triangles[ta as usize].map(|v| NodeRef {
                        body: i,
                        node: v as usize,
                    });
                    let fb = bodies[j].surface.triangles[tb as usize].map(|v| NodeRef {
                        body: j,
                        node: v as usize,
                    });
                    let overflow_freeze = freeze || !complete;
                    for (vertices, face) in [(fa, fb), (fb, fa)] {
                        for v in vertices {
                            let nodes = [v, face[0], face[1], face[2]];
                            answered += test_primitive(
                                bodies,
                                nodes,
                                true,
                                &scratch.settings,
                                overflow_freeze,
                                dt,
                            ) as u32;
                        }
                    }
                    for ea in 0..3 {
                        for eb in 0..3 {
                            let nodes = [fa[ea], fa[(ea + 1) % 3], fb[eb], fb[(eb + 1) % 3]];
                            answered += test_primitive(
                                bodies,
                                nodes,
                                false,
                                &scratch.settings,
                                overflow_freeze,
                                dt,
                            ) as u32;
                        }
                    }
                }
            }
        }
        counters.collisions += answered;
        if freeze {
            counters.frozen += answered;
        }
        if answered == 0 {
            break;
        }
    }
    counters
}
