//! The world: owns the bodies and obstacles, and steps them as an explicit list of stages.
//!
//! Only what the scene needs runs: [`Systems`] is decided once from the scene (no obstacle contact
//! without obstacles, no rigid integration for fixed bodies...), and the step calls only those stages.
//! One step is, for every body in scene order:
//! forces → node integration (semi-implicit Euler, end positions kept apart) → obstacle contact and
//! friction on the node trajectories → commit positions → rigid component integration.

use crate::Vec3;
use crate::body::Body;
use crate::collision::blocks::{BLOCK, NodeBlock};
use crate::collision::obstacle::Obstacle;
use crate::collision::tool::Aabb;
use crate::contact::bodies::{
    BodyContactCounters, BodyContactScratch, resolve_body_collisions, respond_to_body_contacts,
};
use crate::contact::obstacle::resolve_nodes_against_obstacles;
use crate::contact::tool::{
    HeldNodes, capture_among, capture_broad_phase, grasp_nodes, hold_contact_nodes, jaws_touch,
    push_out_of_tools, release_nodes,
};
use crate::contact::tool_faces::{ToolFaces, press_faces};
use crate::dynamics::Integrator;
use crate::dynamics::attachment::Attachments;
use crate::dynamics::guard::{Guard, body_energy, maxima as guard_maxima, maxima_by_blocks};
use crate::dynamics::helper::LazyHelper;
use crate::dynamics::implicit::Implicit;
use crate::dynamics::integrate::commit_positions;
use crate::dynamics::kernel::{ForceKernel, NodePass, SPLIT_NODES};
use crate::dynamics::multirate::Multirate;
use crate::dynamics::plasticity;
use crate::dynamics::stability::{StabilityMargin, symplectic_margin};
use crate::scene::{Scene, WorldParams};
use crate::tool::ToolShape;
use crate::tool::{Feedback, Tool};
use crate::topology::Cutter;
use crate::topology::cut::NodeExtent;
use crate::topology::explicit::finest_step;
use crate::topology::refine::Refinement;

/// Scales a tool's feedback force down to its `max_force`, flagging it.
fn clamp_feedback(tool: &mut Tool) {
    let Some(max) = tool.max_force else { return };
    let magnitude = tool.feedback.force_in_world.norm();
    if magnitude > max {
        tool.feedback.force_in_world *= max / magnitude;
        tool.feedback.clamped = true;
    }
}

/// Which systems the scene switches on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Systems {
    /// Non-zero gravity.
    pub gravity: bool,
    /// Some body has air viscosity.
    pub air_viscosity: bool,
    /// There are obstacles: node–obstacle contact runs.
    pub obstacle_contact: bool,
    /// Some obstacle has a non-zero friction coefficient.
    pub obstacle_friction: bool,
    /// Some body's rigid component is free to move.
    pub rigid_motion: bool,
    /// There are tools: continuous detection against them, contact zones, friction, feedback.
    pub tool_contact: bool,
    /// Tools may meet the triangles between the nodes (`face_contact`) of some body that does not
    /// refine (`crate::contact::tool_faces`; a tool coarser than all of a body's triangles is
    /// skipped before it costs anything).
    pub tool_faces: bool,
    /// Two bodies or more: broad phase and continuous detection between their surfaces.
    pub body_contact: bool,
    /// Some body has `self_contact` on: its surface against itself (within the body-contact stage).
    pub self_contact: bool,
    /// Some body refines at tool contact.
    pub subdivision: bool,
    /// Some body can be cut and some tool is a blade.
    pub cutting: bool,
    /// Some body can tear.
    pub tearing: bool,
}

impl Systems {
    /// The stage that cuts and tears (and turns a body cut or torn in parts into bodies) runs.
    pub fn cuts_or_tears(&self) -> bool {
        self.cutting || self.tearing
    }

    /// Names of the systems that are on, in a fixed order (always-on parts of the model first).
    pub fn names(&self) -> Vec<&'static str> {
        let mut names = vec!["surface_springs", "links"];
        for (on, name) in [
            (self.rigid_motion, "rigid_components"),
            (self.gravity, "gravity"),
            (self.air_viscosity, "air_viscosity"),
            (self.obstacle_contact, "obstacle_contact"),
            (self.obstacle_friction, "obstacle_friction"),
            (self.tool_contact, "tool_ccd"),
            (self.tool_contact, "tool_contact"),
            (self.tool_contact, "tool_friction"),
            (self.tool_contact, "feedback"),
            (self.tool_faces, "tool_faces"),
            (self.body_contact, "body_broad_phase"),
            (self.body_contact, "body_ccd"),
            (self.self_contact, "self_contact"),
            (self.subdivision, "subdivision"),
            (self.cutting, "cutting"),
            (self.tearing, "tearing"),
        ] {
            if on {
                names.push(name);
            }
        }
        names
    }
}

/// Counters of the last step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StepCounters {
    /// Node–obstacle contacts resolved.
    pub obstacle_contacts: usize,
    /// Nodes that joined a tool's contact zone this step.
    pub tool_captures: u32,
    /// Nodes moved out of a tool by the final guard (two parts squeezing a node).
    pub tool_push_outs: u32,
    /// Triangles a tool pressed between their nodes this step (`contact::tool_faces`).
    pub tool_face_contacts: u32,
    /// Triangles in contact with a tool left unanswered: the tool's list was full.
    pub tool_face_contacts_dropped: u32,
    /// Triangles the face stage's broad phase kept (their box met a tool's reach).
    pub tool_face_candidates: u32,
    /// Body–body contact stage.
    pub bodies: BodyContactCounters,
    /// Bodies the divergence guard restored this step.
    pub guard_events: u32,
    /// Nodes inserted by adaptive subdivision this step.
    pub refinements: u32,
    /// Inserted nodes removed again this step.
    pub coarsenings: u32,
    /// Bodies a blade cut this step (their mesh changed).
    pub cuts: u32,
    /// Edges opened by cuts this step.
    pub opened_edges: u32,
    /// Bodies a cut separated into several this step (each part past the first a new body).
    pub transections: u32,
    /// Transections left undone this step: no spare body left (the parts stay in one body).
    pub transections_refused: u32,
    /// Nodes graspers took into their jaws this step.
    pub grasped: u32,
    /// Nodes graspers let go this step.
    pub released: u32,
    /// Homologues that flowed plastically this step.
    pub plastic_flows: u32,
    /// Bodies whose springs tore this step (their mesh changed).
    pub tears: u32,
}

/// Everything simulated, and the step.
#[derive(Clone, Debug)]
pub struct World {
    /// Gravity, time step, defaults.
    pub params: WorldParams,
    /// Deformable bodies, in scene order.
    pub bodies: Vec<Body>,
    /// Fixed obstacles, in scene order.
    pub obstacles: Vec<Obstacle>,
    /// When set, every broad phase that skips nodes by the node pass's boxes first checks that
    /// each free node's trajectory lies in its box, and every guard pass taken from the node
    /// pass's blocks is compared with one over every node; counted here (for tests: sweeps of
    /// their own).
    pub node_box_check: Option<NodeBoxCheck>,
    /// Force each obstacle exerted on the bodies during the last step (N, world frame).
    pub obstacle_reactions: Vec<Vec3>,
    /// Each obstacle's reach this step (`ObstacleShape::reach_in_world`), for the multi-rate
    /// substeps: sized with the reactions, refreshed at every step (the obstacles are public).
    obstacle_reach: Vec<Option<[Vec3; 2]>>,
    /// Rigid tools, in scene order.
    pub tools: Vec<Tool>,
    /// Number of steps taken; simulated time is `tick × dt`.
    pub tick: u64,
    /// Counters of the last step.
    pub counters: StepCounters,
    systems: Systems,
    body_contact: Option<BodyContactScratch>,
    solvers: Vec<BodySolver>,
    /// The force stage's scratch (edge batches, accumulators) of each body.
    kernels: Vec<ForceKernel>,
    /// The divergence guard of each body.
    pub guards: Vec<Guard>,
    /// Adaptive subdivision state of each body (`None` where the scene leaves it off).
    pub refinements: Vec<Option<Refinement>>,
    /// Cutting state of each body (`None` where the scene leaves it off).
    pub cutters: Vec<Option<Cutter>>,
    /// Magnitude of each tool's feedback at the end of the previous tick (N).
    previous_force: Vec<f64>,
    /// Broad-phase scratch of the tool contact detection, per body.
    broad: Vec<BroadScratch>,
    /// The scene body each body comes from (itself, or the body a transection cut it from).
    origin: Vec<usize>,
    /// Pieces each body's transections have named so far (the k of `<name>.<k>`).
    pieces_named: Vec<u32>,
    /// Bodies reserved up front for the pieces of transections, with their solvers and scratch.
    spares: Vec<Option<Spare>>,
    /// Ligaments: ties between bodies and to the world.
    attachments: Attachments,
    /// The second thread that runs half of a large body's force passes (see
    /// [`crate::dynamics::helper`]); the bits are the same with it and without.
    helper: LazyHelper,
}

/// A body reserved for a piece of a transection: buffers sized like its origin's, its solver,
/// refinement, cutting state and broad-phase scratch, so that a transection allocates nothing.
#[derive(Clone, Debug)]
struct Spare {
    origin: usize,
    body: Body,
    solver: BodySolver,
    kernel: ForceKernel,
    refinement: Option<Refinement>,
    cutter: Option<Cutter>,
    broad: BroadScratch,
}

/// After a transection, for the part kept and for each piece: no node lighter than the finest
/// multi-rate sub-step carries (the caps took their mass from the rims and added springs there),
/// then the solver goes on multi-rate if it was waiting for a first cut, and follows the new mesh.
fn settle_after_transection(
    solver: &mut BodySolver,
    cutter: Option<&mut Cutter>,
    body: &mut Body,
    dt: f64,
) {
    if solver.sub_steps()
        && let Some(cutter) = cutter
    {
        cutter.hold_least_mass_everywhere(body, finest_step(dt));
    }
    solver.cut_made(body, dt);
    solver.topology_changed(body, dt, None);
}

/// The integrator of one body with its scratch memory.
#[derive(Clone, Debug)]
enum BodySolver {
    /// The paper's scheme; on a body that cuts or tears, with a multi-rate solver reserved for its
    /// first topology change (see [`BodySolver::cut_made`]).
    Symplectic(Option<Box<Multirate>>),
    Multirate(Box<Multirate>),
    Implicit(Box<Implicit>),
}

/// The integrator of a body with scratch sized for it (and for its subdivision pool when on).
fn solver_for(body: &Body, world_integrator: Integrator, dt: f64) -> BodySolver {
    let room = body.room_nodes();
    match body.params.integrator.unwrap_or(world_integrator) {
        Integrator::Symplectic => BodySolver::Symplectic(
            body.params
                .topology_cutter()
                .map(|_| Box::new(Multirate::with_room(body, dt, room))),
        ),
        Integrator::Multirate => {
            BodySolver::Multirate(Box::new(Multirate::with_room(body, dt, room)))
        }
        Integrator::Implicit => BodySolver::Implicit(Box::new(Implicit::with_room(body, room))),
    }
}

impl BodySolver {
    /// The solver integrates the rigid component itself (multi-rate sub-stepping it with the nodes);
    /// otherwise the commit stage does, with the force and torque the solver leaves.
    fn integrates_rigid(&self) -> bool {
        matches!(self, BodySolver::Multirate(m) if m.rigid_substepped)
    }

    /// The body is (or from its first cut on will be) stepped by the multi-rate solver: its nodes
    /// must be no lighter than the finest sub-step carries (see [`crate::topology::explicit`]).
    fn sub_steps(&self) -> bool {
        matches!(
            self,
            BodySolver::Multirate(_) | BodySolver::Symplectic(Some(_))
        )
    }

    /// A cut or a tear made light nodes and short, stiff spring pieces that the plain explicit
    /// scheme does not carry at the step (ω Δt past its limit: a copy keeps only a share of its
    /// origin's mass, a spring cut near an end is k/t stiff). From its first cut on, a symplectic
    /// body is stepped by the multi-rate solver reserved for it: every node within the limit is
    /// stepped exactly as the symplectic scheme steps it (the same bits), the others are
    /// sub-stepped (MODEL.md §7). No allocation: the solver was reserved at setup.
    fn cut_made(&mut self, body: &Body, dt: f64) {
        if let BodySolver::Symplectic(reserve) = self
            && let Some(mut multirate) = reserve.take()
        {
            multirate.rebuild(body, dt);
            *self = BodySolver::Multirate(multirate);
        }
    }

    /// Follows a change of the body's topology (allocation-free within the reserved room): where
    /// the cutter's record covers it, only at the nodes it lists (their springs from its rest-frame
    /// index).
    fn topology_changed(&mut self, body: &Body, dt: f64, cutter: Option<&mut Cutter>) {
        match self {
            BodySolver::Symplectic(_) => {}
            BodySolver::Multirate(m) => match cutter {
                Some(Cutter {
                    changes,
                    index: Some(index),
                    ..
                }) if changes.covers(m.synced_version(), body.topology_version) => {
                    m.follow(body, dt, changes.nodes(), changes.edges(), &mut |v, out| {
                        if !index.incident_edges(body, v) || index.found.len() > out.capacity() {
                            return false;
                        }
                        out.clear();
                        out.extend_from_slice(&index.found);
                        true
                    });
                }
                _ => m.rebuild(body, dt),
            },
            BodySolver::Implicit(i) => match cutter {
                // A cut or a tear appends nodes: the warm start is kept.
                Some(Cutter { changes, .. })
                    if changes.covers(i.synced_version(), body.topology_version) =>
                {
                    i.follow(body)
                }
                _ => i.resize(body),
            },
        }
    }
}

/// What [`World::node_box_check`] found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NodeBoxCheck {
    /// Broad phases that skipped nodes by the boxes.
    pub uses: u64,
    /// Free nodes (no tool holds them) whose start or end position lay outside their box.
    pub misses: u64,
    /// Free nodes checked.
    pub nodes: u64,
    /// Guard passes taken from the blocks.
    pub maxima: u64,
    /// Of these, passes whose largest squared speed or stretch or flag differed from a pass over
    /// every node.
    pub maxima_misses: u64,
}

impl NodeBoxCheck {
    fn take(&mut self, surface: &crate::body::Surface, blocks: &[NodeBlock]) {
        self.uses += 1;
        let inside = |b: &Aabb, p: &Vec3| {
            (0..3).all(|k| p[k].is_nan() || (b.min[k] <= p[k] && p[k] <= b.max[k]))
        };
        for i in 0..surface.position_in_world.len() {
            if surface.tool_contact[i].tool != crate::contact::tool::NO_TOOL {
                continue;
            }
            self.nodes += 1;
            let held = blocks.get(i / BLOCK).is_some_and(|b| {
                inside(&b.bounds, &surface.position_in_world[i])
                    && inside(&b.bounds, &surface.next_position_in_world[i])
            });
            self.misses += u64::from(!held);
        }
    }
}

/// Candidates of the tool broad phase and the nodes the tools hold, per body (reserved for its
/// node capacity).
#[derive(Clone, Debug, Default)]
struct BroadScratch {
    nodes: Vec<u32>,
    held: HeldNodes,
    faces: ToolFaces,
}

impl BroadScratch {
    fn with_capacity((nodes, triangles): (usize, usize)) -> Self {
        Self {
            nodes: Vec::with_capacity(nodes),
            held: HeldNodes::with_capacity(nodes),
            faces: ToolFaces::with_capacity((nodes, triangles)),
        }
    }

    /// The body changed in a way its topology version may not tell (a spare taken for a piece).
    fn invalidate(&mut self) {
        self.held.invalidate();
        self.faces.invalidate();
    }
}

/// The stages of a step, as [`World::step_profiled`] times them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Tools moved to their pose, feedback and reactions reset.
    Tools,
    /// Springs, links, gravity and air on every node and on the rigid component, the body's
    /// energy, and the integration of an explicit body's free nodes (one pass over the nodes).
    Forces,
    /// Contact response: held nodes stick, slide or let go; node–obstacle contact; the tool guard.
    Contact,
    /// Free nodes integrated by the solvers that do not do it in the force stage (multi-rate with
    /// sub-stepped nodes, implicit).
    Integration,
    /// Broad phase against the tools: node trajectories against each tool's swept box.
    BroadPhase,
    /// Continuous detection against the tools of what the broad phase kept: node trajectories
    /// (conservative advancement, the node joins the contact zone).
    ToolCcd,
    /// Adaptive subdivision and coarsening.
    Subdivision,
    /// Body–body broad phase (BVH) and continuous detection, with the response.
    BodyContact,
    /// Cuts along the blades' sweeps (incision steps), with the solvers' update after a cut.
    Cut,
    /// A body a cut separated made into bodies (parts found, caps, rigid components split).
    Transection,
    /// Positions committed, rigid components integrated.
    Commit,
    /// Divergence guard, feedback clamp.
    Guard,
}

impl Stage {
    /// Every stage, in step order.
    pub const ALL: [Stage; 12] = [
        Stage::Tools,
        Stage::Forces,
        Stage::Contact,
        Stage::Integration,
        Stage::BroadPhase,
        Stage::ToolCcd,
        Stage::Subdivision,
        Stage::BodyContact,
        Stage::Commit,
        Stage::Cut,
        Stage::Transection,
        Stage::Guard,
    ];

    /// The name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Tools => "tools",
            Stage::Forces => "forces",
            Stage::Contact => "contact",
            Stage::Integration => "integration",
            Stage::BroadPhase => "broad_phase",
            Stage::ToolCcd => "tool_ccd",
            Stage::Subdivision => "subdivision",
            Stage::BodyContact => "body_contact",
            Stage::Cut => "cut",
            Stage::Transection => "transection",
            Stage::Commit => "commit",
            Stage::Guard => "guard",
        }
    }
}

/// Marks where a step enters a stage.
trait StageClock {
    fn enter(&mut self, stage: Stage);
}

/// No timing: compiles away.
struct NoClock;

impl StageClock for NoClock {
    #[inline(always)]
    fn enter(&mut self, _stage: Stage) {}
}

/// Wall time spent in each stage, summed over the profiled steps (s).
#[derive(Clone, Debug, Default)]
pub struct StepProfile {
    /// Seconds per stage, indexed like [`Stage::ALL`].
    pub seconds: [f64; 12],
    /// Steps profiled.
    pub steps: u64,
    current: Option<(Stage, std::time::Instant)>,
}

impl StepProfile {
    fn close(&mut self) {
        if let Some((stage, since)) = self.current.take() {
            self.seconds[stage as usize] += since.elapsed().as_secs_f64();
        }
        self.steps += 1;
    }

    /// Mean time per step in a stage (s).
    pub fn mean(&self, stage: Stage) -> f64 {
        self.seconds[stage as usize] / self.steps.max(1) as f64
    }
}

impl StageClock for StepProfile {
    fn enter(&mut self, stage: Stage) {
        let now = std::time::Instant::now();
        if let Some((previous, since)) = self.current {
            self.seconds[previous as usize] += (now - since).as_secs_f64();
        }
        self.current = Some((stage, now));
    }
}

/// Ticks a blade that pressed through a body's resistance must stay away from it before it presses
/// again.
const BLADE_AWAY_TICKS: u32 = 100;

/// The bit of a tool in a mask of tools (tools past the 64th are never in a mask).
fn tool_bit(tool: usize) -> u64 {
    if tool < 64 { 1 << tool } else { 0 }
}

/// Which blades cut `body` this tick instead of pressing it: every blade when the body has no
/// resistance; otherwise those that pressed through it (the force they felt last tick reached the
/// resistance), which then let go of what they held.
fn cutting_blade_mask(
    cutter: &mut Cutter,
    body: &mut Body,
    held: &mut HeldNodes,
    tools: &[Tool],
    previous_force: &[f64],
) -> u64 {
    let mut mask = 0;
    for (index, tool) in tools.iter().enumerate() {
        if !matches!(tool.shape, ToolShape::Blade { .. }) {
            continue;
        }
        let resistance = cutter.settings.resistance;
        if resistance > 0.0 && !cutter.through[index] {
            if previous_force[index] < resistance {
                continue;
            }
            cutter.through[index] = true;
            cutter.away[index] = 0;
            let_go(&mut body.surface, held, |c| c.tool == index as u32);
        }
        mask |= tool_bit(index);
    }
    mask
}

/// The tools let go of the nodes whose contact `which` picks (their hold lists swept again).
fn let_go(
    surface: &mut crate::body::Surface,
    held: &mut HeldNodes,
    which: impl Fn(&crate::contact::tool::ToolContact) -> bool,
) {
    let mut released = false;
    for contact in &mut surface.tool_contact {
        if which(contact) {
            *contact = crate::contact::tool::ToolContact::default();
            released = true;
        }
    }
    if released {
        held.invalidate();
    }
}

/// Rounds of contact and implicit re-solve per step (each pins the nodes the contact stage resolved).
const CONTACT_ROUNDS: usize = 3;

/// Whether the body–body stage has work with these bodies: two or more, or one whose surface may
/// not pass through itself.
fn body_contact_needed(bodies: &[Body]) -> bool {
    bodies.len() >= 2 || bodies.iter().any(|b| b.params.self_contact_on())
}

impl World {
    /// An empty world.
    pub fn new(params: WorldParams) -> Self {
        let mut world = Self {
            params,
            bodies: Vec::new(),
            obstacles: Vec::new(),
            obstacle_reactions: Vec::new(),
            obstacle_reach: Vec::new(),
            node_box_check: None,
            tools: Vec::new(),
            tick: 0,
            counters: StepCounters::default(),
            systems: Systems::default(),
            body_contact: None,
            solvers: Vec::new(),
            kernels: Vec::new(),
            guards: Vec::new(),
            refinements: Vec::new(),
            cutters: Vec::new(),
            previous_force: Vec::new(),
            broad: Vec::new(),
            origin: Vec::new(),
            pieces_named: Vec::new(),
            spares: Vec::new(),
            attachments: Attachments::default(),
            helper: LazyHelper::default(),
        };
        world.assemble();
        world
    }

    /// Builds the world a scene describes.
    pub fn from_scene(scene: &Scene) -> Self {
        let mut world = Self::new(scene.world.clone());
        for spec in &scene.bodies {
            world.bodies.push(Body::new(
                &spec.name,
                &spec.mesh,
                &spec.params,
                &spec.placement,
            ));
        }
        world.attachments = Attachments::new(&scene.attachments, &world.bodies);
        world.obstacles = scene.obstacles.clone();
        world.tools = scene
            .tools
            .iter()
            .map(|t| {
                let mut tool = Tool::new(&t.name, t.shape.clone(), t.input.clone(), t.max_force);
                tool.grasp = t.grasp;
                tool
            })
            .collect();
        world.assemble();
        world
    }

    /// Adds a body (and re-decides which systems run).
    pub fn add_body(&mut self, body: Body) {
        self.bodies.push(body);
        self.assemble();
    }

    /// Adds an obstacle (and re-decides which systems run).
    pub fn add_obstacle(&mut self, obstacle: Obstacle) {
        self.obstacles.push(obstacle);
        self.assemble();
    }

    /// Adds a tool (and re-decides which systems run).
    pub fn add_tool(&mut self, tool: Tool) {
        self.tools.push(tool);
        self.assemble();
    }

    /// Rebuilds everything derived from the bodies — which systems run, each body's integrator
    /// scratch and multi-rate classification, its divergence guard (budget from the energy now), its
    /// refinement state — after bodies were changed in place (masses, stiffnesses, positions).
    pub fn reassemble(&mut self) {
        self.assemble();
    }

    /// Decides which systems run from what the world holds, and sizes the per-obstacle buffers.
    fn assemble(&mut self) {
        for body in &mut self.bodies {
            body.refresh_diagonals();
        }
        self.obstacle_reactions = vec![Vec3::zeros(); self.obstacles.len()];
        self.obstacle_reach = vec![None; self.obstacles.len()];
        self.systems = Systems {
            gravity: self.params.gravity != Vec3::zeros(),
            air_viscosity: self.bodies.iter().any(|b| b.params.air_viscosity > 0.0),
            obstacle_contact: !self.obstacles.is_empty() && !self.bodies.is_empty(),
            obstacle_friction: self
                .obstacles
                .iter()
                .any(|o| o.friction > 0.0 || o.static_friction > 0.0),
            rigid_motion: self.bodies.iter().any(|b| !b.rigid.fixed),
            tool_contact: !self.tools.is_empty() && !self.bodies.is_empty(),
            tool_faces: self.params.face_contact
                && !self.tools.is_empty()
                && self.bodies.iter().any(|b| b.params.subdivision.is_none()),
            body_contact: body_contact_needed(&self.bodies),
            self_contact: self.bodies.iter().any(|b| b.params.self_contact_on()),
            subdivision: !self.tools.is_empty()
                && self.bodies.iter().any(|b| b.params.subdivision.is_some()),
            cutting: self
                .tools
                .iter()
                .any(|t| matches!(t.shape, ToolShape::Blade { .. }))
                && self.bodies.iter().any(|b| b.params.cutting.is_some()),
            tearing: self.bodies.iter().any(|b| b.params.tearing.is_some()),
        };
        for body in &mut self.bodies {
            if body.room_nodes() > 0 {
                body.reserve_room();
            }
        }
        let dt = self.params.dt;
        let world_integrator = self.params.integrator;
        let tool_count = self.tools.len();
        self.build_spares(dt, world_integrator, tool_count);
        self.attachments
            .reserve_bodies(self.bodies.len() + self.spares.len());
        let spare_triangles = self
            .spares
            .iter()
            .flatten()
            .map(|s| s.body.mesh_capacity().1)
            .max()
            .unwrap_or(0);
        let self_contact = self.bodies.iter().any(|b| b.params.self_contact_on());
        self.body_contact = (self.bodies.len() + self.spares.len() >= 2 || self_contact)
            .then(|| BodyContactScratch::new(&self.bodies, self.spares.len(), spare_triangles));
        self.refinements = self
            .bodies
            .iter_mut()
            .map(|b| {
                b.params
                    .subdivision
                    .map(|settings| Refinement::new(b, settings))
            })
            .collect();
        self.cutters = self
            .bodies
            .iter()
            .map(|b| {
                b.params
                    .topology_cutter()
                    .map(|settings| Cutter::new(b, settings, tool_count))
            })
            .collect();
        self.previous_force = vec![0.0; tool_count];
        self.solvers = self
            .bodies
            .iter()
            .map(|b| solver_for(b, world_integrator, dt))
            .collect();
        self.kernels = self.bodies.iter().map(ForceKernel::new).collect();
        self.broad = self
            .bodies
            .iter()
            .map(|b| BroadScratch::with_capacity(b.mesh_capacity()))
            .collect();
        self.origin = (0..self.bodies.len()).collect();
        self.pieces_named = vec![0; self.bodies.len()];
        let room = self.spares.len();
        self.bodies.reserve(room);
        self.solvers.reserve(room);
        self.kernels.reserve(room);
        self.refinements.reserve(room);
        self.cutters.reserve(room);
        self.broad.reserve(room);
        self.origin.reserve(room);
        self.pieces_named.reserve(room);
        let gravity = self.params.gravity;
        self.guards = self
            .bodies
            .iter()
            .zip(&self.solvers)
            .map(|(b, solver)| {
                let mut guard = Guard::new(b, &gravity);
                // A body stepped explicitly past its stability limit can gain energy within a tick
                // without moving fast: the energy of the end of each step is checked. Every other
                // body's is checked every tick from the force stage's measure, one tick behind.
                if matches!(solver, BodySolver::Symplectic(_)) {
                    let margin = symplectic_margin(b, dt);
                    guard.energy_at_end = margin.margin < 0.0 || margin.rigid_margin < 0.0;
                }
                guard
            })
            .collect();
        self.guards.reserve(room);
    }

    /// Reserves the spare bodies of the cutting bodies (`max_pieces` each, shaped like their origin).
    fn build_spares(&mut self, dt: f64, world_integrator: Integrator, tool_count: usize) {
        self.spares.clear();
        if !self.systems.cuts_or_tears() {
            return;
        }
        for (origin, body) in self.bodies.iter().enumerate() {
            let Some(settings) = body.params.topology_cutter() else {
                continue;
            };
            for _ in 0..settings.max_pieces {
                let mut shell = body.clone();
                shell.name = String::with_capacity(body.name.len() + 24);
                // A piece cut off falls free, even from a body held in place.
                shell.params.fixed = false;
                shell.rigid.fixed = false;
                shell.reserve_room();
                let refinement = shell.params.subdivision.map(|s| Refinement::new(&shell, s));
                let cutter = Some(Cutter::new(&shell, settings, tool_count));
                let capacity = shell.mesh_capacity();
                self.spares.push(Some(Spare {
                    origin,
                    solver: solver_for(&shell, world_integrator, dt),
                    kernel: ForceKernel::new(&shell),
                    refinement,
                    cutter,
                    broad: BroadScratch::with_capacity(capacity),
                    body: shell,
                }));
            }
        }
    }

    /// Most bodies this world may hold: its own and the spares reserved for transections.
    pub fn body_capacity(&self) -> usize {
        self.bodies.len() + self.spares.iter().flatten().count()
    }

    /// Largest mesh (nodes, triangles) a body still to come from a transection may have.
    pub fn spare_mesh_capacity(&self) -> (usize, usize) {
        self.spares
            .iter()
            .flatten()
            .map(|s| s.body.mesh_capacity())
            .fold((0, 0), |(n, t), (a, b)| (n.max(a), t.max(b)))
    }

    /// Separates body `b` into bodies if its last cut cut it in parts (see
    /// [`crate::topology::transect`]). Allocation-free: new bodies come from the spares.
    fn transect(&mut self, b: usize, counters: &mut StepCounters) {
        use crate::topology::transect::MAX_PARTS;
        let dt = self.params.dt;
        let tick = self.tick + 1;
        let first_piece = self.bodies.len();
        let Some(cutter) = self.cutters[b].as_mut() else {
            return;
        };
        let body = &mut self.bodies[b];
        // One part before, and every opening since joined its copies to their origins again (or
        // a separation of this body was refused: no search could end in one).
        if cutter.connected || cutter.separation_refused {
            cutter.counters.parts_searches_spared += 1;
            return;
        }
        if !cutter
            .transector
            .fits(body.node_count(), body.surface.triangles.len())
        {
            return;
        }
        cutter.counters.parts_searches += 1;
        let parts = cutter.transector.find_parts(body);
        cutter.connected = parts == 1;
        cutter.counters.parts_searches_one_part += u64::from(parts == 1);
        if parts < 2 {
            return;
        }
        let origin = self.origin[b];
        let mut slots = [usize::MAX; MAX_PARTS];
        let mut found = 0;
        for (i, spare) in self.spares.iter().enumerate() {
            if found + 1 >= parts.min(MAX_PARTS) {
                break;
            }
            if spare.as_ref().is_some_and(|s| s.origin == origin) {
                slots[found] = i;
                found += 1;
            }
        }
        if parts > MAX_PARTS || found + 1 < parts {
            counters.transections_refused += 1;
            // Later openings only add parts, and spares do not come back: no later search of
            // this body could end in a transection.
            if let Some(cutter) = self.cutters[b].as_mut() {
                cutter.separation_refused = true;
            }
            return;
        }
        let mut taken: [Option<Spare>; MAX_PARTS] = Default::default();
        for (t, &slot) in taken.iter_mut().zip(&slots[..found]) {
            *t = self.spares[slot].take();
        }
        let mut refs: [Option<&mut Body>; MAX_PARTS] = Default::default();
        for (r, t) in refs.iter_mut().zip(taken.iter_mut()) {
            *r = t.as_mut().map(|s| &mut s.body);
        }
        let min_angle = cutter.quality_bound_deg;
        let result =
            cutter
                .transector
                .separate(body, &mut refs[..found], min_angle, &self.params.gravity);
        cutter.transection_counts(&result);
        // Ties on the body follow their nodes, into the pieces too (pushed below in spare order).
        let transector = &cutter.transector;
        self.attachments.renumber(b, |v| {
            transector
                .new_place(v, result.kept)
                .map(|(k, index)| (if k == 0 { b } else { first_piece + k - 1 }, index))
        });
        cutter.renumbered();
        // The part kept is one part of the spring graph (its caps only add springs within it).
        cutter.connected = true;
        settle_after_transection(&mut self.solvers[b], Some(cutter), body, dt);
        self.kernels[b].invalidate();
        self.broad[b].invalidate();
        if let Some(refinement) = self.refinements[b].as_mut() {
            refinement.renumbered(body);
        }
        self.guards[b].rebase(body);
        counters.transections += 1;
        let energy_at_end = self.guards[b].energy_at_end;
        let gravity = self.params.gravity;
        for spare in taken.iter_mut() {
            let Some(mut spare) = spare.take() else {
                continue;
            };
            self.pieces_named[b] += 1;
            {
                use std::fmt::Write;
                let parent_name = &self.bodies[b].name;
                spare.body.name.clear();
                let _ = write!(spare.body.name, "{}.{}", parent_name, self.pieces_named[b]);
            }
            if let Some(cutter) = spare.cutter.as_mut() {
                cutter.restart();
                // A piece is one part of the spring graph, as the part kept.
                cutter.connected = true;
                cutter.changed_at = tick;
            }
            settle_after_transection(
                &mut spare.solver,
                spare.cutter.as_mut(),
                &mut spare.body,
                dt,
            );
            if let Some(refinement) = spare.refinement.as_mut() {
                refinement.renumbered(&spare.body);
            }
            let mut guard = Guard::new(&spare.body, &gravity);
            guard.energy_at_end = energy_at_end;
            self.bodies.push(spare.body);
            self.solvers.push(spare.solver);
            spare.kernel.invalidate();
            self.kernels.push(spare.kernel);
            self.refinements.push(spare.refinement);
            self.cutters.push(spare.cutter);
            spare.broad.invalidate();
            self.broad.push(spare.broad);
            self.guards.push(guard);
            self.origin.push(spare.origin);
            self.pieces_named.push(0);
        }
        self.systems.body_contact =
            body_contact_needed(&self.bodies) && self.body_contact.is_some();
    }

    /// Keeps the body–body response's candidate pairs from tick to tick while the bodies stay
    /// within their slack (the default), or lists them again every tick; the result bits are the
    /// same either way (for tests and benchmarks).
    pub fn set_candidate_cache(&mut self, keep: bool) {
        if let Some(scratch) = self.body_contact.as_mut() {
            scratch.set_candidate_cache(keep);
        }
    }

    /// The most boxes one continuous query of the body–body collision net examines
    /// ([`crate::collision::ccd::CcdSettings::max_boxes`]; default
    /// [`crate::collision::ccd::DEFAULT_MAX_BOXES`]). A query past it is answered as a hit at the
    /// earliest time it had not resolved and counted in `counters.bodies.budget_spent` (for tests
    /// and benchmarks).
    pub fn set_ccd_max_boxes(&mut self, max_boxes: u32) {
        if let Some(scratch) = self.body_contact.as_mut() {
            scratch.set_ccd_max_boxes(max_boxes);
        }
    }

    /// Lets a second thread run half of the force passes of each body of
    /// [`crate::dynamics::kernel::SPLIT_NODES`] nodes or more (the default), or keeps every pass on
    /// the step's thread; the result bits are the same either way.
    pub fn set_helper_thread(&mut self, on: bool) {
        self.params.helper_thread = on;
        if !on {
            self.helper.stop();
        }
    }

    /// Force passes offered to the helper thread, and those it joined (it may find every unit
    /// taken by then; the others ran on the step's thread alone), since it started.
    pub fn helper_counts(&self) -> (u64, u64) {
        self.helper.counts()
    }

    /// Chooses the force stage's SIMD path (where the machine has one) or its scalar path for every
    /// body; the result bits are the same either way.
    pub fn set_simd(&mut self, simd: bool) {
        for kernel in &mut self.kernels {
            kernel.set_simd(simd);
        }
        for solver in &mut self.solvers {
            if let BodySolver::Multirate(m) | BodySolver::Symplectic(Some(m)) = solver {
                m.set_simd(simd);
            }
        }
        for spare in self.spares.iter_mut().flatten() {
            spare.kernel.set_simd(simd);
            if let BodySolver::Multirate(m) | BodySolver::Symplectic(Some(m)) = &mut spare.solver {
                m.set_simd(simd);
            }
        }
    }

    /// How often body `b`'s list of held nodes was swept from every node's contact state, and how
    /// often it followed a topology change from the cutter's record instead.
    pub fn held_list_counts(&self, b: usize) -> (u64, u64) {
        let held = &self.broad[b].held;
        (held.sweeps, held.follows)
    }

    /// The nodes of body `b` the contact stage will take as held next tick (its list refreshed as
    /// the next step refreshes it), and those a sweep of every node's contact state finds: the two
    /// must agree (tests check it after every step).
    pub fn held_nodes_and_sweep(&self, b: usize) -> (Vec<u32>, Vec<u32>) {
        let body = &self.bodies[b];
        let mut held = self.broad[b].held.clone();
        held.refresh(&body.surface, body.topology_version);
        let sweep = (0..body.node_count() as u32)
            .filter(|&i| {
                body.surface.tool_contact[i as usize].tool != crate::contact::tool::NO_TOOL
            })
            .collect();
        (held.nodes().to_vec(), sweep)
    }

    /// The multi-rate solver of body `b`, when it has one.
    pub fn multirate(&self, b: usize) -> Option<&Multirate> {
        match self.solvers.get(b) {
            Some(BodySolver::Multirate(m)) => Some(m),
            _ => None,
        }
    }

    /// The force stage's scratch of body `b` (its edge batches).
    pub fn force_kernel(&self, b: usize) -> Option<&ForceKernel> {
        self.kernels.get(b)
    }

    /// The attachments (ligaments) and their forces of the last tick.
    pub fn attachments(&self) -> &Attachments {
        &self.attachments
    }

    /// The systems this world runs.
    pub fn systems(&self) -> Systems {
        self.systems
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.tick as f64 * self.params.dt
    }

    /// The force the body–body contact response put on each body in the last step (N, world
    /// frame; indexed like `bodies`; empty when body contact is off). The forces of a touching pair
    /// are equal and opposite.
    pub fn body_contact_forces(&self) -> &[Vec3] {
        self.body_contact
            .as_ref()
            .map_or(&[], |s| &s.forces[..s.forces.len().min(self.bodies.len())])
    }

    /// The pairs of bodies whose surfaces cross where they are now (pieces of one cut body not
    /// compared): at the start of a session, a scene mistake that contact between bodies cannot
    /// mend — see [`crate::contact::overlap`]. Allocates; not for the tick.
    pub fn crossing_surfaces(&self) -> Vec<crate::contact::overlap::Crossing> {
        crate::contact::overlap::crossing_surfaces(&self.bodies, &self.origin)
    }

    /// Advances the world by one time step. Allocates nothing.
    ///
    /// Stages: tools move to their pose for the end of the tick; then per body forces → contact
    /// nodes held, slid or released → free nodes integrated → continuous detection against the tools
    /// → obstacle contact → tool guard; then body–body broad phase and continuous detection on all
    /// trajectories; then per body positions committed → rigid component; last, each tool's feedback
    /// is clamped to its `max_force`.
    pub fn step(&mut self) {
        self.step_with(&mut NoClock);
    }

    /// [`World::step`], timing its stages into `profile` (for the bench tools; the physics is the
    /// same bit for bit, the clock is only read).
    pub fn step_profiled(&mut self, profile: &mut StepProfile) {
        self.step_with(profile);
        profile.close();
    }

    /// Graspers grasp when both jaws touch and the opening falls to `grasp_below`, and let go when
    /// it grows past `release_above` (hysteresis), at the start of the tick, for every body at once.
    fn update_grasps(&mut self, counters: &mut StepCounters) {
        for (index, tool) in self.tools.iter_mut().enumerate() {
            let Some(settings) = tool.grasp else {
                continue;
            };
            if tool.grasping {
                // Let go when the jaws open past the release opening (or the tool left the scene).
                if tool.part_count < 2 || tool.jaw > settings.release_above {
                    for (body, broad) in self.bodies.iter_mut().zip(self.broad.iter_mut()) {
                        counters.released += release_nodes(&mut body.surface, index, tool);
                        broad.held.invalidate();
                    }
                    tool.grasping = false;
                }
            } else if tool.part_count >= 2 && tool.jaw <= settings.grasp_below {
                let mut touching = [false; 2];
                for body in &self.bodies {
                    jaws_touch(&body.surface, index, tool, &mut touching);
                }
                if touching[0] && touching[1] {
                    for (body, broad) in self.bodies.iter_mut().zip(self.broad.iter_mut()) {
                        counters.grasped +=
                            grasp_nodes(&mut body.surface, index, tool, settings.reach);
                        broad.held.invalidate();
                    }
                    tool.grasping = true;
                }
            }
        }
    }

    fn step_with<C: StageClock>(&mut self, clock: &mut C) {
        let mut counters = StepCounters::default();
        self.begin_tick(clock, &mut counters);
        let attached = !self.attachments.is_empty();
        if attached {
            clock.enter(Stage::Forces);
            self.attachments.compute(&self.bodies, self.params.dt);
        }
        for b in 0..self.bodies.len() {
            self.step_body(b, attached, clock, &mut counters);
        }
        clock.enter(Stage::BodyContact);
        self.contact_between_bodies(&mut counters);
        clock.enter(Stage::Commit);
        self.commit_bodies(&mut counters);
        self.cut_tear_and_coarsen(clock, &mut counters);
        // A cut that opened edges may have cut a body in parts: each becomes a body.
        if self.systems.cuts_or_tears() {
            clock.enter(Stage::Transection);
            for b in 0..self.bodies.len() {
                if self.cutters[b]
                    .as_mut()
                    .is_some_and(|c| std::mem::take(&mut c.check_parts))
                {
                    self.transect(b, &mut counters);
                }
            }
        }
        clock.enter(Stage::Guard);
        self.guard_bodies(&mut counters);
        for tool in &mut self.tools {
            clamp_feedback(tool);
        }
        self.counters = counters;
        self.tick += 1;
    }

    /// The tick's start: each tool's last force kept and its motion over the tick set up, its
    /// feedback and the obstacles' reactions cleared, the obstacles' reach, the graspers' grasps.
    fn begin_tick<C: StageClock>(&mut self, clock: &mut C, counters: &mut StepCounters) {
        clock.enter(Stage::Tools);
        let t_end = (self.tick + 1) as f64 * self.params.dt;
        for (tool, force) in self.tools.iter_mut().zip(self.previous_force.iter_mut()) {
            *force = tool.feedback.force_in_world.norm();
            tool.begin_tick(t_end);
            tool.feedback = Feedback::default();
        }
        for reaction in &mut self.obstacle_reactions {
            *reaction = Vec3::zeros();
        }
        for (reach, obstacle) in self.obstacle_reach.iter_mut().zip(&self.obstacles) {
            *reach = obstacle.shape.reach_in_world();
        }
        if self.systems.tool_contact {
            self.update_grasps(counters);
        }
    }

    /// Body `b`'s part of the tick before the contact between bodies: its forces (and the
    /// integration of an explicit body in the same pass), the nodes the tools hold, its solver's
    /// integration, the tools' captures and the refinement under them, the obstacles and the
    /// tools' push-out.
    fn step_body<C: StageClock>(
        &mut self,
        b: usize,
        attached: bool,
        clock: &mut C,
        counters: &mut StepCounters,
    ) {
        let cutting_blades = self.cutting_blades(b);
        let fused = self.body_forces(b, attached, clock);
        clock.enter(Stage::Contact);
        self.hold_tool_nodes(b, fused);
        clock.enter(Stage::Integration);
        self.integrate_body(b, attached, fused, counters);
        if self.systems.tool_contact {
            self.capture_and_refine(b, cutting_blades, clock, counters);
        }
        clock.enter(Stage::Contact);
        self.answer_obstacles_and_tools(b, cutting_blades, counters);
    }

    /// The tools whose blades cut body `b` this tick (bits by tool), which pass through it instead
    /// of pressing (after pressing through its resistance, when it has one); the nodes the tools
    /// hold brought up to date first.
    fn cutting_blades(&mut self, b: usize) -> u64 {
        let systems = self.systems;
        let body = &mut self.bodies[b];
        let broad = &mut self.broad[b];
        let cutter = &mut self.cutters[b];
        if systems.tool_contact {
            broad.held.refresh(&body.surface, body.topology_version);
        }
        let mut cutting_blades: u64 = 0;
        if systems.cuts_or_tears()
            && let Some(cutter) = cutter.as_mut()
            && cutter.blades
        {
            cutting_blades = cutting_blade_mask(
                cutter,
                body,
                &mut broad.held,
                &self.tools,
                &self.previous_force,
            );
        }
        cutting_blades
    }

    /// Body `b`'s forces: springs, links, gravity, air and the attachments; an explicit body with
    /// every node at the step is integrated in the same pass (true is returned), but for the nodes
    /// the tools hold, which keep their velocity.
    fn body_forces<C: StageClock>(&mut self, b: usize, attached: bool, clock: &mut C) -> bool {
        let (dt, gravity, systems) = (self.params.dt, self.params.gravity, self.systems);
        let body = &mut self.bodies[b];
        let solver = &mut self.solvers[b];
        let kernel = &mut self.kernels[b];
        let broad = &mut self.broad[b];
        let cutter = &mut self.cutters[b];
        clock.enter(Stage::Forces);
        kernel.refresh_with(body, cutter.as_ref().map(|c| &c.changes));
        let helper = if self.params.helper_thread && body.node_count() >= SPLIT_NODES {
            Some(self.helper.get())
        } else {
            None
        };
        kernel.edge_forces_with(body, helper);
        if attached {
            for (node, force) in self.attachments.forces_on(b) {
                kernel.add_external(node, &force);
                if let BodySolver::Multirate(m) = solver {
                    m.add_external_force(node, &force);
                }
            }
        }
        // An explicit body with every node at the step is integrated in the force stage's node
        // pass; the held nodes keep their start velocity for the contact stage, which moves
        // them. The others are integrated by their solver.
        let fused = match solver {
            BodySolver::Symplectic(_) => true,
            BodySolver::Multirate(m) => m.fast.is_empty() && !m.rigid_substepped,
            BodySolver::Implicit(_) => false,
        };
        let hold = systems.tool_contact && fused;
        if hold {
            broad.held.save_velocities(&body.surface);
        }
        let pass = if fused {
            NodePass::IntegrateAll
        } else {
            NodePass::Forces
        };
        kernel.node_pass_with(body, &gravity, dt, pass, helper);
        if hold {
            broad.held.restore_velocities(&mut body.surface);
            // Their velocities are not the node pass's: they join their blocks.
            kernel.blocks.include_all(&body.surface, broad.held.nodes());
        }
        fused
    }

    /// The nodes of body `b` the tools hold, moved with them (`fused`: the force pass integrated
    /// the body).
    fn hold_tool_nodes(&mut self, b: usize, fused: bool) {
        let dt = self.params.dt;
        let body = &mut self.bodies[b];
        let kernel = &mut self.kernels[b];
        let broad = &mut self.broad[b];
        if self.systems.tool_contact {
            hold_contact_nodes(
                &mut body.surface,
                &mut self.tools,
                body.params.friction,
                dt,
                fused,
                &mut broad.held,
            );
            // The held nodes moved after the node pass: their trajectories join the boxes (a
            // node released here ends where the node pass put it, the same operations, but the
            // boxes must not rest on that).
            kernel.blocks.include_all(&body.surface, broad.held.nodes());
        }
    }

    /// Body `b`'s solver integrates what the force pass did not (a multi-rate body's sub-stepped
    /// nodes, with last tick's contact forces carried into their substeps; an implicit body).
    fn integrate_body(
        &mut self,
        b: usize,
        attached: bool,
        fused: bool,
        counters: &mut StepCounters,
    ) {
        let (dt, gravity) = (self.params.dt, self.params.gravity);
        let body = &mut self.bodies[b];
        let solver = &mut self.solvers[b];
        let kernel = &mut self.kernels[b];
        match solver {
            BodySolver::Symplectic(_) => {}
            BodySolver::Multirate(m) => {
                // Last tick's contact forces on the sub-stepped nodes, felt by their substeps
                // and taken back after them (the response's impulses follow).
                let version = body.topology_version;
                let carried = || {
                    self.body_contact
                        .as_ref()
                        .into_iter()
                        .flat_map(move |scratch| scratch.carried_on(b, version))
                };
                m.carry_contact_forces(body, carried());
                counters.obstacle_contacts += m.integrate(
                    body,
                    dt,
                    &gravity,
                    (&self.obstacles, &self.obstacle_reach),
                    &mut self.obstacle_reactions,
                    fused,
                );
                m.take_back_contact_forces(body, carried(), dt);
                // Nodes moved by the solver (none when the node pass integrated them all and
                // no contact force was carried) are not in the node pass's boxes.
                if !fused || carried().next().is_some() {
                    kernel.blocks.drop_all();
                }
            }
            BodySolver::Implicit(i) => {
                i.integrate(body, dt);
                kernel.blocks.drop_all();
            }
        }
        if attached && let BodySolver::Multirate(m) = solver {
            for (node, _) in self.attachments.forces_on(b) {
                m.clear_external_force(node);
            }
        }
    }

    /// The tools capture the nodes of body `b` they reach this tick (broad phase, then the
    /// continuous test), and the refinement subdivides under them.
    fn capture_and_refine<C: StageClock>(
        &mut self,
        b: usize,
        cutting_blades: u64,
        clock: &mut C,
        counters: &mut StepCounters,
    ) {
        let dt = self.params.dt;
        let body = &mut self.bodies[b];
        let solver = &mut self.solvers[b];
        let kernel = &mut self.kernels[b];
        let refinement = &mut self.refinements[b];
        let broad = &mut self.broad[b];
        for (tool_index, tool) in self.tools.iter_mut().enumerate() {
            if cutting_blades & tool_bit(tool_index) != 0 {
                continue;
            }
            clock.enter(Stage::BroadPhase);
            let blocks = kernel.blocks.bounds(body.node_count());
            if let (Some(check), Some(blocks)) = (self.node_box_check.as_mut(), blocks) {
                check.take(&body.surface, blocks);
            }
            capture_broad_phase(&body.surface, tool, blocks, &mut broad.nodes);
            // A node whose triangles this tool pressed in the last tick is the faces'.
            broad
                .faces
                .leave_pressed(&mut broad.nodes, tool, tool_index);
            clock.enter(Stage::ToolCcd);
            counters.tool_captures +=
                capture_among(&mut body.surface, tool_index, tool, &broad.nodes, dt);
            broad.held.add_captured(&body.surface, &broad.nodes);
            // The captured nodes moved (to where they touched, carried with the tool).
            kernel.blocks.include_all(&body.surface, &broad.nodes);
        }
        clock.enter(Stage::Subdivision);
        if let Some(refinement) = refinement.as_mut() {
            let inserted =
                refinement.refine_at_tools(body, &self.tools, cutting_blades, self.tick + 1, dt);
            if inserted > 0 {
                counters.refinements += inserted;
                solver.topology_changed(body, dt, None);
                kernel.blocks.drop_all();
            }
        }
        // The tools against the triangles between the nodes, for a body that does not refine
        // (one that does answers such a cut with a node, the paper's way).
        if refinement.is_none() && self.params.face_contact {
            clock.enter(Stage::ToolCcd);
            let faces = press_faces(
                &mut body.surface,
                body.topology_version,
                body.params.plasticity.is_some(),
                body.params.friction,
                &mut self.tools,
                cutting_blades,
                dt,
                Some(&mut kernel.blocks),
                &mut broad.faces,
            );
            counters.tool_face_contacts += faces.contacts;
            counters.tool_face_contacts_dropped += faces.dropped;
            counters.tool_face_candidates += faces.candidates;
        }
    }

    /// Body `b`'s nodes against the obstacles (an implicit body solved again with the stopped
    /// nodes pinned), then pushed out of the tools.
    fn answer_obstacles_and_tools(
        &mut self,
        b: usize,
        cutting_blades: u64,
        counters: &mut StepCounters,
    ) {
        let (dt, systems) = (self.params.dt, self.systems);
        let body = &mut self.bodies[b];
        let solver = &mut self.solvers[b];
        let kernel = &mut self.kernels[b];
        if systems.obstacle_contact {
            counters.obstacle_contacts += resolve_nodes_against_obstacles(
                &mut body.surface,
                &self.obstacles,
                &mut self.obstacle_reactions,
                dt,
                Some(&mut kernel.blocks),
            );
            // The implicit body answers its contacts within the step: the nodes the contact
            // stopped are pinned and the rest solved again, a few rounds at most.
            if let BodySolver::Implicit(i) = solver {
                for _ in 0..CONTACT_ROUNDS {
                    if !i.pin_contacts(body, dt) {
                        break;
                    }
                    counters.obstacle_contacts += resolve_nodes_against_obstacles(
                        &mut body.surface,
                        &self.obstacles,
                        &mut self.obstacle_reactions,
                        dt,
                        None,
                    );
                }
            }
        }
        if systems.tool_contact {
            counters.tool_push_outs += push_out_of_tools(
                &mut body.surface,
                &self.tools,
                cutting_blades,
                dt,
                Some(&mut kernel.blocks),
            );
        }
    }

    /// The contact between bodies (the response, then the collision net), and its counters.
    fn contact_between_bodies(&mut self, counters: &mut StepCounters) {
        let dt = self.params.dt;
        if self.systems.body_contact
            && let Some(scratch) = self.body_contact.as_mut()
        {
            let solvers = &self.solvers;
            let sub_stepped = |body: usize, node: usize| match solvers.get(body) {
                Some(BodySolver::Multirate(m)) => m.carries_contact_forces_to(node),
                _ => false,
            };
            let response = respond_to_body_contacts(
                &mut self.bodies,
                &self.origin,
                (&self.obstacles, &mut self.obstacle_reactions),
                scratch,
                sub_stepped,
                dt,
            );
            counters.bodies = resolve_body_collisions(
                &mut self.bodies,
                &self.origin,
                &self.obstacles,
                scratch,
                dt,
            );
            counters.bodies.candidate_pairs += response.candidate_pairs;
            counters.bodies.overflows += response.overflows;
            counters.bodies.contacts = response.contacts;
            counters.bodies.contacts_dropped = response.contacts_dropped;
            counters.bodies.listed_pairs += response.listed_pairs;
            // A body whose nodes the stage moved: the guard makes its own pass over it.
            for (b, kernel) in self.kernels.iter_mut().enumerate() {
                if scratch.moved(b) {
                    kernel.blocks.drop_maxima();
                }
            }
        }
    }

    /// The end positions committed, the rigid components integrated (where their solver does not),
    /// plastic flow.
    fn commit_bodies(&mut self, counters: &mut StepCounters) {
        let dt = self.params.dt;
        for (body, solver) in self.bodies.iter_mut().zip(&self.solvers) {
            commit_positions(&mut body.surface);
            if !solver.integrates_rigid() {
                body.rigid.integrate(dt);
            }
            // Plastic flow of the links stretched past their yield, on the committed state.
            if let Some(plasticity) = body.params.plasticity {
                counters.plastic_flows +=
                    plasticity::flow(body, &plasticity, plasticity.tick_fraction(dt));
            }
        }
    }

    /// Cuts along the blades' sweeps and tears, then coarsening, before the guard looks at the
    /// bodies.
    fn cut_tear_and_coarsen<C: StageClock>(&mut self, clock: &mut C, counters: &mut StepCounters) {
        let (dt, systems) = (self.params.dt, self.systems);
        let blades = self
            .tools
            .iter()
            .any(|t| matches!(t.shape, ToolShape::Blade { .. }) && t.part_count > 0);
        for ((((((body, solver), refinement), cutter), guard), kernel), broad) in self
            .bodies
            .iter_mut()
            .zip(self.solvers.iter_mut())
            .zip(self.refinements.iter_mut())
            .zip(self.cutters.iter_mut())
            .zip(self.guards.iter_mut())
            .zip(self.kernels.iter_mut())
            .zip(self.broad.iter_mut())
        {
            // Cuts, tears and transections change the nodes: the guard makes its own pass.
            if cutter.is_some() {
                kernel.blocks.drop_all();
            }
            if systems.cuts_or_tears()
                && let Some(cutter) = cutter.as_mut()
            {
                // What this tick's cuts and tears change, for the force kernel and the solver.
                cutter.changes.begin(body.topology_version);
                // The guard's pass over the nodes, taken now with the box of their positions: a
                // blade whose sweep misses the box is away, at no cost (the guard reads the pass).
                clock.enter(Stage::Guard);
                let extent = if blades && cutter.blades {
                    guard.measure(body, true);
                    // Every node within the guard's largest stretch of its homologue as the force
                    // stage placed it.
                    guard.node_bounds().map(|bounds| NodeExtent {
                        bounds,
                        frame: kernel
                            .homologue_frame
                            .zip(guard.node_reach())
                            .map(|((rotation, origin), reach)| (rotation, origin, reach)),
                    })
                } else {
                    None
                };
                clock.enter(Stage::Cut);
                let mut changed =
                    cut_along_blades(cutter, body, &self.tools, extent.as_ref(), counters);
                let cut = changed;
                // Springs stretched past the tearing threshold break, a bounded number per tick.
                if let Some(mut tearer) = cutter.tearer.take() {
                    let step = tearer.step(body, cutter);
                    cutter.tearer = Some(tearer);
                    if step.changed {
                        changed = true;
                        counters.tears += 1;
                        counters.opened_edges += step.opened;
                    }
                }
                if cut {
                    counters.cuts += 1;
                }
                if changed {
                    cutter.changed_at = self.tick + 1;
                    cutter.changes.seal(body.topology_version);
                    if let Some(refinement) = refinement.as_mut() {
                        refinement.commit(body);
                    }
                    // No node lighter than the finest sub-step of the multi-rate scheme carries.
                    if solver.sub_steps() {
                        cutter.hold_least_mass(body, finest_step(dt));
                    }
                    solver.cut_made(body, dt);
                    solver.topology_changed(body, dt, Some(cutter));
                    // The tools' held nodes, from the same record.
                    broad
                        .held
                        .follow(&body.surface, body.topology_version, &cutter.changes);
                }
            }
            if let Some(refinement) = refinement.as_mut() {
                clock.enter(Stage::Subdivision);
                let removed = refinement.coarsen(body, self.tick + 1, dt);
                if removed > 0 {
                    counters.coarsenings += removed;
                    solver.topology_changed(body, dt, None);
                    kernel.blocks.drop_all();
                }
            }
        }
    }

    /// The divergence guard of every body, with the work done on it from outside this tick.
    fn guard_bodies(&mut self, counters: &mut StepCounters) {
        let gravity = self.params.gravity;
        // Work the tools did on the tissue this tick (the tissue pushes the tool with the feedback).
        let tool_work: f64 = self
            .tools
            .iter()
            .map(|t| {
                -t.feedback
                    .force_in_world
                    .dot(&(t.pose.position_in_world - t.previous_pose.position_in_world))
            })
            .filter(|w| w.is_finite())
            .map(f64::abs)
            .sum();
        let several = self.bodies.len() > 1;
        for (b, ((((body, guard), kernel), refinement), cutter)) in self
            .bodies
            .iter_mut()
            .zip(self.guards.iter_mut())
            .zip(&self.kernels)
            .zip(&self.refinements)
            .zip(&self.cutters)
            .enumerate()
        {
            // Work from outside the body: tools, ligaments and the other bodies' contact.
            let contact_work = self
                .body_contact
                .as_ref()
                .and_then(|c| c.work.get(b).copied())
                .unwrap_or(0.0);
            guard.add_work(tool_work + self.attachments.work_on(b) + contact_work);
            let refined_now = refinement
                .as_ref()
                .is_some_and(|r| r.changed_at == self.tick + 1)
                || cutter
                    .as_ref()
                    .is_some_and(|c| c.changed_at == self.tick + 1);
            guard.start(kernel.energy);
            // The energy the force stage measured at the start of this tick (free of cost, one tick
            // behind), or, when the topology changed this tick or the body needs it, the energy now.
            let energy = if refined_now || guard.energy_at_end {
                let e = body_energy(body, &gravity);
                if refined_now {
                    // An insertion and its capture by the tool add energy from outside the model,
                    // like the tool's work: the budget takes it.
                    guard.raise_budget_to(e);
                }
                e
            } else {
                kernel.energy
            };
            guard.keep_start = several && !refined_now;
            // The node pass's blocks, where nothing moved the nodes since without a record.
            if let Some(blocks) = kernel.blocks.maxima(body.node_count()) {
                let s = &body.surface;
                let (v, x, h) = (
                    &s.velocity_in_world,
                    &s.position_in_world,
                    &s.homologue_in_world,
                );
                let found = maxima_by_blocks(blocks, v, x, h);
                if let Some(check) = self.node_box_check.as_mut() {
                    let every = guard_maxima(v, x, h);
                    check.maxima += 1;
                    check.maxima_misses += u64::from(
                        found.0.to_bits() != every.0.to_bits()
                            || found.1.to_bits() != every.1.to_bits()
                            || found.2 != every.2,
                    );
                }
                guard.take_maxima(found);
            }
            if guard.check(body, Some(energy)).is_some() {
                counters.guard_events += 1;
                // The tools let go of the restored nodes they touched, and take again those they
                // still touch at the next tick: kept, a node a tool carried off (a tool that
                // jumped through the organ in one tick, 40 cm, holding eight nodes 12 cm from
                // it) was carried off again at every tick, and the body restored at every tick
                // for as long as the tool stayed (found by an integrator's bridge, 2026-12-07).
                // A grasp is let go when the restore failed again.
                let again = guard.events_in_a_row() >= 2;
                let_go(&mut body.surface, &mut self.broad[b].held, |c| {
                    c.tool != crate::body::NO_TOOL && (c.grasp.is_none() || again)
                });
                // The restored shape may cross an obstacle the deformed one was resting on.
                for x in &mut body.surface.position_in_world {
                    for o in &self.obstacles {
                        if o.shape.signed_distance(x) < 0.0
                            && let Some(plane) = o.shape.contact_plane(x, x)
                        {
                            let depth = plane.signed_distance(x);
                            if depth < 0.0 {
                                *x -= plane.normal_in_world * depth;
                            }
                        }
                    }
                }
            }
        }
    }

    /// Deepest penetration of any node of `body` into an obstacle or a tool (m), 0 when none.
    pub fn max_penetration(&self, body: &Body) -> f64 {
        let mut deepest: f64 = 0.0;
        for x in &body.surface.position_in_world {
            for o in &self.obstacles {
                deepest = deepest.max(-o.shape.signed_distance(x));
            }
            for t in &self.tools {
                deepest = deepest.max(-t.signed_distance(x).0);
            }
        }
        deepest
    }

    /// Smallest signed distance of any node of `body` to any obstacle (m); `None` without obstacles.
    pub fn min_obstacle_gap(&self, body: &Body) -> Option<f64> {
        if self.obstacles.is_empty() {
            return None;
        }
        let mut gap = f64::INFINITY;
        for x in &body.surface.position_in_world {
            for o in &self.obstacles {
                gap = gap.min(o.shape.signed_distance(x));
            }
        }
        Some(gap)
    }

    /// The integrator each body uses.
    pub fn integrator_of(&self, body: usize) -> Integrator {
        match self.solvers.get(body) {
            Some(BodySolver::Multirate(_)) => Integrator::Multirate,
            Some(BodySolver::Implicit(_)) => Integrator::Implicit,
            _ => Integrator::Symplectic,
        }
    }

    /// Substeps the multi-rate integrator takes for the fastest nodes of a body (1 otherwise), and
    /// how many nodes it sub-steps.
    pub fn substeps_of(&self, body: usize) -> (u32, usize) {
        match self.solvers.get(body) {
            Some(BodySolver::Multirate(m)) => (m.substeps, m.fast.len()),
            _ => (1, 0),
        }
    }

    /// Substeps of a body's rigid component when the multi-rate integrator sub-steps it with its
    /// nodes (its coupling passes the explicit limit); `None` otherwise.
    pub fn rigid_substeps_of(&self, body: usize) -> Option<u32> {
        match self.solvers.get(body) {
            Some(BodySolver::Multirate(m)) if m.rigid_substepped => {
                Some(m.substeps / m.base_stride)
            }
            _ => None,
        }
    }

    /// Whether the multi-rate integrator steps a body's rigid component implicitly (it alone is past
    /// the explicit limit).
    pub fn rigid_stepped_implicitly(&self, body: usize) -> bool {
        matches!(self.solvers.get(body), Some(BodySolver::Multirate(m)) if m.rigid_implicit)
    }

    /// The implicit solver of body `b`, if it has one.
    pub fn implicit(&self, b: usize) -> Option<&Implicit> {
        match self.solvers.get(b) {
            Some(BodySolver::Implicit(i)) => Some(i),
            _ => None,
        }
    }

    /// Iterations and relative residual of the last implicit solve of a body.
    pub fn implicit_solve_of(&self, body: usize) -> Option<(u32, f64)> {
        match self.solvers.get(body) {
            Some(BodySolver::Implicit(i)) => Some((i.last_iterations, i.last_residual)),
            _ => None,
        }
    }

    /// Stability margin of each body under the paper's scheme at this world's step.
    pub fn stability_margins(&self) -> Vec<StabilityMargin> {
        self.bodies
            .iter()
            .map(|b| symplectic_margin(b, self.params.dt))
            .collect()
    }
}

/// Cuts `body` along the sweep of each blade that is through it this tick (one still pressing
/// against its resistance is not; a blade away from it for long enough presses again): true when
/// the topology changed.
fn cut_along_blades(
    cutter: &mut Cutter,
    body: &mut Body,
    tools: &[Tool],
    extent: Option<&NodeExtent>,
    counters: &mut StepCounters,
) -> bool {
    let mut changed = false;
    for (tool_index, tool) in tools.iter().enumerate() {
        if !cutter.blades || !matches!(tool.shape, ToolShape::Blade { .. }) || tool.part_count == 0
        {
            continue;
        }
        let pressing = cutter.settings.resistance > 0.0 && !cutter.through[tool_index];
        if pressing {
            continue;
        }
        let (start, end) = (tool.parts_start[0], tool.parts_end[0]);
        let step = cutter.cut_within(body, tool_index, [start.a, start.b], [end.a, end.b], extent);
        if cutter.settings.resistance > 0.0 {
            if step.nodes_near == 0 {
                cutter.away[tool_index] += 1;
                if cutter.away[tool_index] > BLADE_AWAY_TICKS {
                    cutter.through[tool_index] = false;
                    cutter.away[tool_index] = 0;
                }
            } else {
                cutter.away[tool_index] = 0;
            }
        }
        if step.changed {
            changed = true;
            counters.opened_edges += step.opened;
        }
        if step.opened > 0 {
            cutter.check_parts = true;
        }
    }
    changed
}
