//! Tool–tissue contact as the paper states it (MODEL.md §4, paper §3.2): nodes in the contact zone
//! take their position from the tool; the force on each is what the rest of the model exerts on it
//! (springs, link, gravity, air), and the sum of those forces, with its moment about the tool's tip,
//! is the feedback the device must render.
//!
//! Each tick, per body, after the forces are known:
//! 1. [`hold_contact_nodes`]: a contact node whose force pulls it away from the tool is released (it is
//!    then integrated as a free node). Otherwise Coulomb friction decides: it sticks (it stays at its
//!    point of the tool, and feeds back its whole force: at rest, exactly the force of the springs,
//!    link and gravity on it) when the friction needed to keep it there is inside the cone μ N, and
//!    otherwise slides along the tool surface, feeding back its normal force plus the kinetic
//!    friction μ N along its slip. Either way the tangential feedback of a node is at most μ N.
//! 2. The free nodes are integrated.
//! 3. [`capture_new_contacts`]: continuous detection of each free node's trajectory against each tool
//!    capsule's motion over the tick; a node that meets the tool joins the contact zone at the point
//!    where it touched and ends the tick there.
//!    [`detect_face_contacts`] finds the triangles the tool touches between their corners.
//! 4. [`push_out_of_tools`]: a last guard so that no node ends a tick inside a tool (only ever acts
//!    when two parts of a tool squeeze a node).

use crate::Vec3;
use crate::body::Surface;
use crate::body::changes::TopologyChanges;
pub use crate::body::{JawHold, NO_TOOL, ToolContact};
use crate::collision::blocks::{BLOCK, NodeBlock, NodeBlocks};
use crate::collision::tool::{
    Aabb, lerp_capsule, time_of_impact_capsule_triangle, time_of_impact_point_capsule, tool_reach,
};
use crate::tool::{Tool, ToolPose};

/// How far inside a tool a node placed on its surface may sit through rounding alone (m).
pub const SURFACE_ROUNDING: f64 = 1e-12;

/// Distance within which continuous detection reports contact (m).
pub const CONTACT_TOLERANCE: f64 = 1e-9;

/// Whether `point_in_tool` (tool frame), touching jaw `part` (0 or 1) of a grasper whose half
/// opening is `half` (rad), lies between the jaws: along that jaw between its hinge and its tip,
/// within the jaws' width of their plane (|y| below 0.7 radius), and on the inner side of both jaws'
/// outer faces (less than half a jaw radius past either jaw's axis outwards). Tissue there is what
/// closing jaws pinch; a node on a jaw's outer face (a radius past its axis outwards), on its flank
/// or beyond its tip is not.
pub fn between_jaws(tool: &Tool, part: usize, point_in_tool: &Vec3, half: f64) -> bool {
    let jaw = &tool.parts_in_tool[0];
    let (length, radius) = ((jaw.b - jaw.a).norm(), jaw.radius);
    let half = half.max(0.0);
    let (s, c) = (crate::math::sin(half), crate::math::cos(half));
    let p = point_in_tool;
    let mut inside = p.y.abs() < 0.7 * radius;
    for (k, sign) in [1.0, -1.0].into_iter().enumerate() {
        // Jaw k's axis: through `sign · radius · (c, 0, −sign · s)` along `(sign · s, 0, c)`;
        // `inward` points from it towards the other jaw.
        let along = Vec3::new(sign * s, 0.0, c);
        let inward = Vec3::new(-sign * c, 0.0, s);
        let t = p.dot(&along);
        if k == part && (t <= 0.0 || t > length) {
            return false;
        }
        inside &= p.dot(&inward) + radius > -0.5 * radius;
    }
    inside
}

impl Default for ToolContact {
    fn default() -> Self {
        Self {
            tool: NO_TOOL,
            part: 0,
            point_in_tool: Vec3::zeros(),
            grasp: None,
        }
    }
}

/// Accumulates one node's contribution to a tool's feedback.
fn add_feedback(
    tool: &mut Tool,
    at: &Vec3,
    force: &Vec3,
    normal: f64,
    friction: f64,
    sliding: bool,
) {
    let fb = &mut tool.feedback;
    fb.force_in_world += force;
    fb.torque_in_world += (at - tool.pose.position_in_world).cross(force);
    fb.contacts += 1;
    fb.normal_force += normal;
    fb.friction_force += friction;
    fb.sliding += sliding as u32;
}

/// Step 1: releases, sticks or slides every node already in contact; writes the end position and
/// velocity of the nodes still held, and their feedback. `friction` is the body's Coulomb coefficient.
pub fn hold_contact_nodes(
    surface: &mut Surface,
    tools: &mut [Tool],
    friction: f64,
    dt: f64,
    integrate_released: bool,
    held: &mut HeldNodes,
) {
    held.refresh_if_stale(surface);
    for k in 0..held.nodes.len() {
        let i = held.nodes[k] as usize;
        let contact = surface.tool_contact[i];
        if contact.tool == NO_TOOL {
            continue;
        }
        let tool = &mut tools[contact.tool as usize];
        let part = contact.part as usize;
        if part >= tool.part_count {
            surface.tool_contact[i] = ToolContact::default();
            if integrate_released {
                integrate_node(surface, i, dt);
            }
            continue;
        }
        let start = surface.position_in_world[i];
        if let Some(hold) = contact.grasp {
            // Grasped: the node moves with its jaw; the tool supplies whatever force that takes,
            // and the tissue pulls the tool with the rest (the node's force less its inertia).
            let point = hold.point_now(&contact.point_in_tool, 0.5 * tool.jaw.max(0.0));
            let end = tool.pose.to_world(&point);
            let velocity = (end - start) / dt;
            let feedback = surface.force_in_world[i]
                - (velocity - surface.velocity_in_world[i]) * (surface.mass[i] / dt);
            surface.next_position_in_world[i] = end;
            surface.velocity_in_world[i] = velocity;
            add_feedback(tool, &end, &feedback, feedback.norm(), 0.0, false);
            tool.feedback.grasped += 1;
            continue;
        }
        // Outward normal of the tool at the node, from where the node sits at the start of the tick.
        let fallback = tool.previous_pose.world_from_tool
            * (contact.point_in_tool
                - tool.parts_in_tool[part].closest_on_segment(&contact.point_in_tool));
        let fallback = fallback.try_normalize(1e-15).unwrap_or(Vec3::z());
        let (_, normal) = tool.parts_start[part].project_to_surface(&start, &fallback);
        let force = surface.force_in_world[i];
        let normal_component = force.dot(&normal);
        if normal_component > 0.0 {
            // The model pulls the node away from the tool: released, integrated as a free node.
            surface.tool_contact[i] = ToolContact::default();
            if integrate_released {
                integrate_node(surface, i, dt);
            }
            continue;
        }
        let normal_force = -normal_component;
        let tangential_force = force - normal * normal_component;
        let mass = surface.mass[i];
        // The point of the tool it sits on, carried by the tool's motion — and, on a grasper's jaw,
        // by the jaw's turn about the hinge over the tick.
        let point_in_tool = if tool.grasp.is_some() && part < 2 {
            JawHold::on_part(part, 0.5 * tool.previous_jaw.max(0.0))
                .point_now(&contact.point_in_tool, 0.5 * tool.jaw.max(0.0))
        } else {
            contact.point_in_tool
        };
        let held_at = tool.pose.to_world(&point_in_tool);
        let tool_point_velocity = (held_at - start) / dt;
        // Relative tangential velocity the node would have without friction this tick.
        let relative = surface.velocity_in_world[i] - tool_point_velocity;
        let relative_tangential =
            relative - normal * relative.dot(&normal) + tangential_force * (dt / mass);
        let slip_speed = relative_tangential.norm();
        let friction_dv = friction * normal_force * dt / mass;
        let (end, feedback, friction_magnitude, sliding) = if slip_speed <= friction_dv {
            // Sticks: the tool holds it where it is on the tool. The friction the tool supplies is
            // what stops the relative slip this tick — the node's tangential force at rest, plus its
            // inertia when the tool accelerates — and is inside the cone by the test above.
            let stick_friction = relative_tangential * (mass / dt);
            let feedback = normal * normal_component + stick_friction;
            (held_at, feedback, stick_friction.norm(), false)
        } else {
            let slip = relative_tangential / slip_speed;
            let remaining = relative_tangential - slip * friction_dv;
            // The slide itself is taken implicitly in the node's own stiffness (linearised
            // backward Euler on its diagonal): a light node held between stiff springs slides
            // towards its balance instead of overshooting it, whatever the step.
            let effective_mass =
                mass + dt * surface.damping_diagonal[i] + dt * dt * surface.stiffness_diagonal[i];
            let moved = held_at + remaining * (dt * mass / effective_mass);
            let (on_surface, _) = tool.parts_end[part].project_to_surface(&moved, &normal);
            let kinetic = slip * (friction * normal_force);
            (
                on_surface,
                normal * normal_component + kinetic,
                kinetic.norm(),
                true,
            )
        };
        surface.tool_contact[i].point_in_tool = tool.pose.to_tool(&end);
        surface.next_position_in_world[i] = end;
        surface.velocity_in_world[i] = (end - start) / dt;
        add_feedback(
            tool,
            &end,
            &feedback,
            normal_force,
            friction_magnitude,
            sliding,
        );
    }
    held.nodes
        .retain(|&i| surface.tool_contact[i as usize].tool != NO_TOOL);
}

/// The nodes a tool holds on one body, in index order: the contact stage goes through them instead
/// of every node. Kept up to date by the stages that change contacts ([`HeldNodes::add_captured`],
/// the hold's releases); swept again from the nodes' contact state after anything else may have
/// changed it (a topology change, a grasp, a release) — [`HeldNodes::invalidate`].
#[derive(Clone, Debug, Default)]
pub struct HeldNodes {
    nodes: Vec<u32>,
    saved: Vec<Vec3>,
    valid: bool,
    version: u64,
    count: usize,
    /// Sweeps of every node's contact state.
    pub sweeps: u64,
    /// Topology changes followed from their record (no sweep).
    pub follows: u64,
}

impl HeldNodes {
    /// Room for `nodes` held nodes (a body's node capacity: no allocation on the tick).
    pub fn with_capacity(nodes: usize) -> Self {
        Self {
            nodes: Vec::with_capacity(nodes),
            saved: Vec::with_capacity(nodes),
            ..Self::default()
        }
    }

    /// The held nodes, in index order (as of the last refresh).
    pub fn nodes(&self) -> &[u32] {
        &self.nodes
    }

    /// Forgets the list: the next refresh sweeps the nodes.
    pub fn invalidate(&mut self) {
        self.valid = false;
    }

    /// Sweeps the nodes again if the list may be stale: invalidated, or the surface changed
    /// (topology version or node count, as `stamp` gives them).
    pub fn refresh(&mut self, surface: &Surface, version: u64) {
        let count = surface.tool_contact.len();
        if self.valid && self.version == version && self.count == count {
            return;
        }
        self.sweeps += 1;
        self.nodes.clear();
        for (i, contact) in surface.tool_contact.iter().enumerate() {
            if contact.tool != NO_TOOL {
                self.nodes.push(i as u32);
            }
        }
        self.valid = true;
        self.version = version;
        self.count = count;
    }

    /// Follows a topology change from its record instead of sweeping: when the list was up to date
    /// at a version the record covers, only the nodes the record lists may have changed their
    /// contact or come new (a cut or a tear moves no node to another index); each is put in or
    /// taken out of the list. Otherwise the next refresh sweeps.
    pub fn follow(&mut self, surface: &Surface, version: u64, changes: &TopologyChanges) {
        let count = surface.tool_contact.len();
        if !self.valid || !changes.covers(self.version, version) || count < self.count {
            return;
        }
        // Nodes new since the list was made, should the record not list one.
        let fresh = (self.count..count).map(|i| i as u32);
        for i in changes.nodes().iter().copied().chain(fresh) {
            let held = surface
                .tool_contact
                .get(i as usize)
                .is_some_and(|c| c.tool != NO_TOOL);
            match (self.nodes.binary_search(&i), held) {
                (Err(at), true) => self.nodes.insert(at, i),
                (Ok(at), false) => {
                    self.nodes.remove(at);
                }
                _ => {}
            }
        }
        self.version = version;
        self.count = count;
        self.follows += 1;
    }

    /// Sweeps again if the node count changed since the last refresh (a caller without the body's
    /// version: the hold keeps to what its caller refreshed).
    fn refresh_if_stale(&mut self, surface: &Surface) {
        if !self.valid || self.count != surface.tool_contact.len() {
            let version = self.version;
            self.valid = false;
            self.refresh(surface, version);
        }
    }

    /// Adds the `candidates` of a capture that a tool now holds.
    pub fn add_captured(&mut self, surface: &Surface, candidates: &[u32]) {
        let before = self.nodes.len();
        for &i in candidates {
            if surface.tool_contact[i as usize].tool != NO_TOOL {
                self.nodes.push(i);
            }
        }
        if self.nodes.len() > before {
            self.nodes.sort_unstable();
            self.nodes.dedup();
        }
    }

    /// Keeps the velocities of the held nodes (before a pass that integrates every node).
    pub fn save_velocities(&mut self, surface: &Surface) {
        self.saved.clear();
        self.saved.extend(
            self.nodes
                .iter()
                .map(|&i| surface.velocity_in_world[i as usize]),
        );
    }

    /// Puts back the velocities [`HeldNodes::save_velocities`] kept: the held nodes start the
    /// contact stage as they started the tick.
    pub fn restore_velocities(&self, surface: &mut Surface) {
        for (&i, v) in self.nodes.iter().zip(&self.saved) {
            surface.velocity_in_world[i as usize] = *v;
        }
    }
}

/// Semi-implicit Euler for node `i` (the operations of the force stage's node pass).
fn integrate_node(surface: &mut Surface, i: usize, dt: f64) {
    let velocity =
        surface.velocity_in_world[i] + surface.force_in_world[i] * (dt * surface.inverse_mass[i]);
    surface.velocity_in_world[i] = velocity;
    surface.next_position_in_world[i] = surface.position_in_world[i] + velocity * dt;
}

/// The pose a fraction `s` of the way through the tick.
fn pose_between(a: &ToolPose, b: &ToolPose, s: f64) -> ToolPose {
    ToolPose {
        position_in_world: a.position_in_world.lerp(&b.position_in_world, s),
        world_from_tool: crate::math::try_slerp(&a.world_from_tool, &b.world_from_tool, s, 1e-12)
            .unwrap_or(b.world_from_tool),
    }
}

/// The box swept by a tool's capsules over the tick.
pub fn swept_box(tool: &Tool) -> Aabb {
    let mut aabb = Aabb::empty();
    let mut margin: f64 = 0.0;
    for k in 0..tool.part_count {
        for part in [&tool.parts_start[k], &tool.parts_end[k]] {
            aabb.include(&part.a);
            aabb.include(&part.b);
            margin = margin.max(part.radius);
        }
    }
    aabb.inflate(margin + CONTACT_TOLERANCE);
    aabb
}

/// Step 3: continuous detection of every free node's trajectory against every tool; returns how many
/// nodes joined a contact zone. Contact nodes of step 1 are not touched. (The world step runs the
/// same in two phases, [`capture_broad_phase`] then [`capture_among`], to time them apart.)
pub fn capture_new_contacts(surface: &mut Surface, tools: &mut [Tool], dt: f64) -> u32 {
    let mut captured = 0;
    for (tool_index, tool) in tools.iter_mut().enumerate() {
        let sweep = swept_box(tool);
        for i in 0..surface.position_in_world.len() {
            if surface.tool_contact[i].tool == NO_TOOL
                && sweep.overlaps_segment(
                    &surface.position_in_world[i],
                    &surface.next_position_in_world[i],
                )
            {
                captured += try_capture(surface, tool_index, tool, i, dt) as u32;
            }
        }
    }
    captured
}

/// Broad phase of the capture against one tool: the free nodes whose trajectory over the tick
/// overlaps the tool's swept box, in index order, into `out` (allocation-free within its capacity).
/// With `blocks` (the node pass's blocks, whose boxes hold every trajectory), only the blocks
/// whose box meets the tool's are looked at: the same nodes, found without reading the others.
pub fn capture_broad_phase(
    surface: &Surface,
    tool: &Tool,
    blocks: Option<&[NodeBlock]>,
    out: &mut Vec<u32>,
) {
    let sweep = swept_box(tool);
    out.clear();
    let (x0, x1) = (&surface.position_in_world, &surface.next_position_in_world);
    let n = x0.len().min(x1.len());
    let mut among = |nodes: std::ops::Range<usize>| {
        for i in nodes {
            // The box first: the contact state is read only for the nodes near the tool.
            if sweep.overlaps_segment(&x0[i], &x1[i]) && surface.tool_contact[i].tool == NO_TOOL {
                out.push(i as u32);
            }
        }
    };
    match blocks {
        // A node whose sweep's box meets the tool's lies in a block box that does too (each
        // coordinate of its sweep's box is one of its block's; one that is not a number fails
        // the node's test as well): skipping the blocks whose box misses skips no candidate.
        Some(blocks) if blocks.len() == n.div_ceil(BLOCK) => {
            for (k, b) in blocks.iter().enumerate() {
                if b.bounds.overlaps(&sweep) {
                    among(k * BLOCK..((k + 1) * BLOCK).min(n));
                }
            }
        }
        _ => among(0..n),
    }
}

/// Narrow phase of the capture against tool `tool_index`: continuous detection of the candidates'
/// trajectories; returns how many joined the contact zone.
pub fn capture_among(
    surface: &mut Surface,
    tool_index: usize,
    tool: &mut Tool,
    candidates: &[u32],
    dt: f64,
) -> u32 {
    candidates
        .iter()
        .map(|&i| try_capture(surface, tool_index, tool, i as usize, dt) as u32)
        .sum()
}

/// Continuous detection of node `i`'s trajectory against the tool; on a touch the node joins the
/// contact zone where it touched, carried to the end of the tick.
fn try_capture(
    surface: &mut Surface,
    tool_index: usize,
    tool: &mut Tool,
    i: usize,
    dt: f64,
) -> bool {
    let start = surface.position_in_world[i];
    let predicted = surface.next_position_in_world[i];
    // A node that starts the tick touching the tool (one just released, or resting against it)
    // joins the contact zone only if the tool ends up pushing into it; otherwise it is separating
    // and stays free. Every other node joins at its first touch.
    let touching_at_start = (0..tool.part_count)
        .any(|k| tool.parts_start[k].signed_distance(&start) <= CONTACT_TOLERANCE);
    if touching_at_start
        && (0..tool.part_count).all(|k| tool.parts_end[k].signed_distance(&predicted) >= 0.0)
    {
        return false;
    }
    // Earliest touch over the tool's parts.
    let mut first: Option<(f64, usize)> = None;
    for k in 0..tool.part_count {
        if let Some(t) = time_of_impact_point_capsule(
            &start,
            &predicted,
            &tool.parts_start[k],
            &tool.parts_end[k],
            CONTACT_TOLERANCE,
        ) && first.is_none_or(|(best, _)| t < best)
        {
            first = Some((t, k));
        }
    }
    let Some((t, part)) = first else {
        return false;
    };
    // Where on the tool it touched, carried to the end of the tick with the tool.
    let at_touch = start.lerp(&predicted, t);
    let capsule = lerp_capsule(&tool.parts_start[part], &tool.parts_end[part], t);
    let toward = (predicted - start)
        .try_normalize(1e-15)
        .map_or(Vec3::z(), |d| -d);
    let (touch_point, _) = capsule.project_to_surface(&at_touch, &toward);
    let pose = pose_between(&tool.previous_pose, &tool.pose, t);
    let carried = tool.pose.to_world(&pose.to_tool(&touch_point));
    let (end, _) = tool.parts_end[part].project_to_surface(&carried, &toward);
    surface.tool_contact[i] = ToolContact {
        tool: tool_index as u32,
        part: part as u32,
        point_in_tool: tool.pose.to_tool(&end),
        // A node that meets the jaws of a grasper that holds, between them, is held with them (one
        // that meets a jaw's outer face is an ordinary contact).
        grasp: (tool.grasping
            && part < 2
            && between_jaws(tool, part, &tool.pose.to_tool(&end), 0.5 * tool.jaw))
        .then(|| JawHold::on_part(part, 0.5 * tool.jaw.max(0.0))),
    };
    surface.next_position_in_world[i] = end;
    surface.velocity_in_world[i] = (end - start) / dt;
    // It touched during the tick and is held from its end on: it counts as a contact now, and its
    // force reaches the device from the next tick, when the tool holds it.
    add_feedback(tool, &end, &Vec3::zeros(), 0.0, 0.0, false);
    true
}

/// Step 3b: detection of the tool touching a face or an edge *between* nodes — a probe finer than the
/// mesh, a blade edge across an edge — for every triangle none of whose corners the tool holds: the
/// tool's capsules against the triangle's motion over the tick (both ways: a tool end through the
/// face, the tool's axis across the triangle's edges). Returns how many triangles the tool touches
/// this way. The paper's response, a node inserted at the touch point with its mass taken from the
/// corners, is adaptive subdivision (`crate::topology::refine`); without it these contacts are
/// counted, and the nodes around them still meet the tool through [`capture_new_contacts`].
///
/// `outcodes` is scratch memory (one byte per node; give it the capacity of the node count and the
/// call allocates nothing): the broad phase codes each node's trajectory against the tool's swept box
/// once, and a triangle is looked at only if its three corners' codes share no side. (The world step
/// runs the same in two phases, [`face_broad_phase`] then [`face_contacts_among`].)
pub fn detect_face_contacts(surface: &Surface, tools: &[Tool], outcodes: &mut Vec<u8>) -> u32 {
    let mut touched = 0;
    for tool in tools {
        code_trajectories(surface, tool, outcodes);
        for tri in &surface.triangles {
            if face_candidate(surface, outcodes, tri) {
                touched += face_touched(surface, tool, tri) as u32;
            }
        }
    }
    touched
}

/// Broad phase of the face detection against one tool: the triangles, none of whose corners is held,
/// whose swept box may meet the tool's, in index order, into `out` (`outcodes` is scratch; both
/// allocation-free within their capacity).
pub fn face_broad_phase(
    surface: &Surface,
    tool: &Tool,
    outcodes: &mut Vec<u8>,
    out: &mut Vec<u32>,
) {
    code_trajectories(surface, tool, outcodes);
    out.clear();
    for (t, tri) in surface.triangles.iter().enumerate() {
        if face_candidate(surface, outcodes, tri) {
            out.push(t as u32);
        }
    }
}

/// Narrow phase of the face detection: how many of the candidate triangles the tool touches.
pub fn face_contacts_among(surface: &Surface, tool: &Tool, candidates: &[u32]) -> u32 {
    candidates
        .iter()
        .map(|&t| face_touched(surface, tool, &surface.triangles[t as usize]) as u32)
        .sum()
}

fn code_trajectories(surface: &Surface, tool: &Tool, outcodes: &mut Vec<u8>) {
    let sweep = swept_box(tool);
    let (x0, x1) = (&surface.position_in_world, &surface.next_position_in_world);
    outcodes.clear();
    outcodes.extend(x0.iter().zip(x1).map(|(p, q)| sweep.outcode(p, q)));
}

fn face_candidate(surface: &Surface, outcodes: &[u8], &[a, b, c]: &[u32; 3]) -> bool {
    let (a, b, c) = (a as usize, b as usize, c as usize);
    outcodes[a] & outcodes[b] & outcodes[c] == 0
        && [a, b, c]
            .iter()
            .all(|&v| surface.tool_contact[v].tool == NO_TOOL)
}

fn face_touched(surface: &Surface, tool: &Tool, &[a, b, c]: &[u32; 3]) -> bool {
    let (x0, x1) = (&surface.position_in_world, &surface.next_position_in_world);
    let (a, b, c) = (a as usize, b as usize, c as usize);
    let start = [x0[a], x0[b], x0[c]];
    let end = [x1[a], x1[b], x1[c]];
    (0..tool.part_count).any(|k| {
        time_of_impact_capsule_triangle(
            &tool.parts_start[k],
            &tool.parts_end[k],
            &start,
            &end,
            CONTACT_TOLERANCE,
        )
        .is_some()
    })
}

/// Step 4: moves any node left inside a tool capsule at the end of the tick onto its surface; returns
/// how many were moved.
/// Tools whose bit is set in `skip` (bit k for tool k) are left out: blades cutting this body.
///
/// With `blocks` (the node pass's, whose boxes hold every trajectory), the blocks whose box misses
/// a tool's reach are skipped (a node ending in the reach lies in its block's box), and the nodes
/// moved join their blocks.
pub fn push_out_of_tools(
    surface: &mut Surface,
    tools: &[Tool],
    skip: u64,
    dt: f64,
    mut blocks: Option<&mut NodeBlocks>,
) -> u32 {
    let mut moved = 0;
    let n = surface.next_position_in_world.len();
    for (index, tool) in tools.iter().enumerate() {
        if index < 64 && skip & (1 << index) != 0 {
            continue;
        }
        let reach = tool_reach(tool, 0.0);
        for k in 0..n.div_ceil(BLOCK) {
            if let Some(b) = blocks.as_ref().and_then(|b| b.bounds(n))
                && !b[k].bounds.overlaps(&reach)
            {
                continue;
            }
            for i in k * BLOCK..((k + 1) * BLOCK).min(n) {
                let p = surface.next_position_in_world[i];
                // The box first: it reads the positions the loop streams through, the contact
                // state (a wide record per node) only for the few nodes near the tool.
                if !reach.overlaps_segment(&p, &p) || surface.tool_contact[i].grasp.is_some() {
                    continue;
                }
                let (distance, part) = tool.signed_distance(&p);
                // Nodes placed on the surface sit there to rounding; deeper than that is a squeeze.
                if distance < -SURFACE_ROUNDING {
                    let (on_surface, _) = tool.parts_end[part].project_to_surface(&p, &Vec3::z());
                    surface.next_position_in_world[i] = on_surface;
                    surface.velocity_in_world[i] += (on_surface - p) / dt;
                    moved += 1;
                    if let Some(blocks) = blocks.as_mut() {
                        blocks.include(surface, i);
                    }
                }
            }
        }
    }
    moved
}

/// Whether both jaws of grasper `tool` (index `index`) touch the surface (contacts of the last tick).
pub fn jaws_touch(surface: &Surface, index: usize, tool: &Tool, touching: &mut [bool; 2]) {
    let half = 0.5 * tool.previous_jaw;
    for c in &surface.tool_contact {
        if c.tool == index as u32
            && c.grasp.is_none()
            && (c.part as usize) < 2
            && between_jaws(tool, c.part as usize, &c.point_in_tool, half)
        {
            touching[c.part as usize] = true;
        }
    }
}

/// Grasps with grasper `tool` (index `index`) at the start of its tick: the nodes in contact with its
/// jaws, and the free nodes within `reach` of a jaw's surface, are held in that jaw's frame. Returns
/// how many nodes were grasped.
pub fn grasp_nodes(surface: &mut Surface, index: usize, tool: &Tool, reach: f64) -> u32 {
    let half = 0.5 * tool.previous_jaw.max(0.0);
    let mut grasped = 0;
    for i in 0..surface.tool_contact.len() {
        let contact = &mut surface.tool_contact[i];
        if contact.tool == index as u32 {
            if (contact.part as usize) < 2
                && contact.grasp.is_none()
                && between_jaws(tool, contact.part as usize, &contact.point_in_tool, half)
            {
                contact.grasp = Some(JawHold::on_part(contact.part as usize, half));
                grasped += 1;
            }
            continue;
        }
        if contact.tool != NO_TOOL || reach <= 0.0 {
            continue;
        }
        let p = surface.position_in_world[i];
        let distance = |part: &crate::tool::CapsulePart| {
            (p - part.closest_on_segment(&p)).norm() - part.radius
        };
        let (d0, d1) = (
            distance(&tool.parts_start[0]),
            distance(&tool.parts_start[1]),
        );
        let part = if d1 < d0 { 1 } else { 0 };
        if d0.min(d1) <= reach && between_jaws(tool, part, &tool.previous_pose.to_tool(&p), half) {
            *contact = ToolContact {
                tool: index as u32,
                part: part as u32,
                point_in_tool: tool.previous_pose.to_tool(&p),
                grasp: Some(JawHold::on_part(part, half)),
            };
            grasped += 1;
        }
    }
    grasped
}

/// Lets go of every node grasper `index` holds: each becomes an ordinary contact at the point of the
/// tool where it is (released at once if the tissue pulls it away). Returns how many.
pub fn release_nodes(surface: &mut Surface, index: usize, tool: &Tool) -> u32 {
    let mut released = 0;
    for i in 0..surface.tool_contact.len() {
        let contact = &mut surface.tool_contact[i];
        if contact.tool == index as u32 && contact.grasp.is_some() {
            contact.grasp = None;
            contact.point_in_tool = tool.previous_pose.to_tool(&surface.position_in_world[i]);
            released += 1;
        }
    }
    released
}
