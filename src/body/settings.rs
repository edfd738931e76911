//! The configuration of a body that its consumers read (integrator, subdivision, cutting, tearing,
//! plasticity): plain data, here so that `body` needs no type of the stages that use them.

/// The time integration of a body's surface nodes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Integrator {
    /// The paper's semi-implicit Euler, every node at the world's step (the reference).
    Symplectic,
    /// Semi-implicit Euler with the nodes that violate the stability bound sub-stepped.
    #[default]
    Multirate,
    /// Linearised backward Euler solved by preconditioned conjugate gradients.
    Implicit,
}

impl Integrator {
    /// The scene name of the integrator.
    pub fn name(self) -> &'static str {
        match self {
            Integrator::Symplectic => "symplectic",
            Integrator::Multirate => "multirate",
            Integrator::Implicit => "implicit",
        }
    }

    /// Parses a scene name.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "symplectic" => Some(Integrator::Symplectic),
            "multirate" => Some(Integrator::Multirate),
            "implicit" => Some(Integrator::Implicit),
            _ => None,
        }
    }
}

/// Insertions a body can hold at once (its reserved pool).
pub const POOL_NODES: usize = 256;

/// How the stiffness of new edges and links is chosen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SpringRule {
    /// The paper's first rule: the mean of the two triangle edges meeting at the corner, weighted by
    /// how close each one's direction is to the new edge's; links the barycentric mean.
    Angle,
    /// The paper's second rule: keep k·L0 of the triangle's edges (mean), so shorter edges are
    /// stiffer; links the barycentric mean.
    ConstantKl,
    /// Ours: the refined patch keeps the coarse patch's membrane modulus (k = E Σ A / L² on every edge
    /// the split touches) and elastic foundation per unit area (links split by area handed over).
    #[default]
    Area,
}

impl SpringRule {
    /// The scene name.
    pub fn name(self) -> &'static str {
        match self {
            SpringRule::Angle => "angle",
            SpringRule::ConstantKl => "constant_kl",
            SpringRule::Area => "area",
        }
    }

    /// Parses a scene name.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "angle" => Some(SpringRule::Angle),
            "constant_kl" => Some(SpringRule::ConstantKl),
            "area" => Some(SpringRule::Area),
            _ => None,
        }
    }
}

/// How a body refines at contact (scene key `subdivision`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SubdivisionSettings {
    /// How new edges and links get their stiffness.
    pub rule: SpringRule,
    /// Deepest refinement: a new node's depth is one more than the deepest of its corners.
    pub max_depth: u8,
    /// Shortest rest edge a refinement may create (m).
    pub min_edge: f64,
    /// Seconds without contact after which a refinement is undone.
    pub coarsen_after_s: f64,
    /// How far the surface between held nodes may cut into a tool before a node is inserted (m).
    pub tolerance: f64,
    /// Longest rest edge of a triangle at a held node (m); `None`: 1.6 times the radius of the tool
    /// part holding it.
    pub zone_edge: Option<f64>,
}

impl Default for SubdivisionSettings {
    fn default() -> Self {
        Self {
            rule: SpringRule::default(),
            max_depth: 4,
            min_edge: 0.001,
            coarsen_after_s: 0.5,
            tolerance: 1e-4,
            zone_edge: None,
        }
    }
}

/// How a body is cut (scene key `cutting`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CuttingSettings {
    /// Force the blade must press the tissue with before it cuts through (N); 0: the blade cuts every
    /// edge it crosses and never presses.
    pub resistance: f64,
    /// Smallest angle a triangle the cut creates may have (degrees), bounded by half the original
    /// mesh's smallest angle.
    pub min_angle_deg: f64,
    /// Pre-strain of the surface springs (0 ≤ prestress < 0.5): their rest lengths are the mesh's
    /// times (1 − prestress), so the intact surface is under tension and the lips of a cut draw apart.
    pub prestress: f64,
    /// Nodes the cuts on this body may add in all (splits and copies); the pool reserved up front.
    pub max_nodes: usize,
    /// Least distance within which a node counts as on the blade's path (m); the tolerance is the
    /// larger of this and a quarter of the local edge length.
    pub tolerance: f64,
    /// New bodies the transections of this body (and of its pieces) may create in all: the spare
    /// bodies a world reserves up front. A cut that would need more leaves the parts in one body.
    pub max_pieces: usize,
}

impl Default for CuttingSettings {
    fn default() -> Self {
        Self {
            resistance: 0.0,
            min_angle_deg: 15.0,
            prestress: 0.0,
            max_nodes: 2048,
            tolerance: 5e-4,
            max_pieces: 4,
        }
    }
}

/// How a body tears (scene key `tearing`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TearingSettings {
    /// Relative stretch past which a surface spring breaks: (length − rest) / rest.
    pub strain: f64,
    /// Ticks in a row a spring must stay past `strain` before it breaks (1: the first tick).
    pub ticks: u32,
    /// Most springs that break in one tick (each may take one more with it, see the module).
    pub max_per_tick: usize,
    /// Nodes the tears may add in all (node copies); the pool reserved up front (shared with
    /// cutting's when both are on: the larger).
    pub max_nodes: usize,
    /// New bodies the tears may separate in all (spare bodies reserved up front).
    pub max_pieces: usize,
}

impl Default for TearingSettings {
    fn default() -> Self {
        Self {
            strain: 0.5,
            ticks: 1,
            max_per_tick: 4,
            max_nodes: 2048,
            max_pieces: 8,
        }
    }
}

/// A body's plasticity (scene key `plasticity = { yield, creep, max }`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlasticitySettings {
    /// Link stretch below which nothing flows (m).
    pub yield_stretch: f64,
    /// Rate of flow per metre of excess stretch (1/s).
    pub creep: f64,
    /// Farthest a homologue may flow from its original place (m).
    pub max: f64,
}

impl Default for PlasticitySettings {
    fn default() -> Self {
        Self {
            yield_stretch: 2e-3,
            creep: 1.0,
            max: 1e-2,
        }
    }
}

impl PlasticitySettings {
    /// Fraction of the excess a tick of `dt` seconds removes: 1 − exp(−creep Δt), the same bits on
    /// every machine.
    pub fn tick_fraction(&self, dt: f64) -> f64 {
        -libm::expm1(-self.creep * dt)
    }
}
