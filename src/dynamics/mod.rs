//! Forces, integration and stability analysis of the bodies (MODEL.md §2–3).

pub mod assess;
pub mod attachment;
pub mod forces;
pub mod guard;
pub mod implicit;
pub mod integrate;
pub mod kernel;
pub mod multirate;
pub mod plasticity;
pub mod stability;

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
