//! Forces, integration and stability analysis of the bodies (MODEL.md §2–3).

pub mod assess;
pub mod attachment;
pub mod forces;
pub mod guard;
pub mod helper;
pub mod implicit;
pub mod integrate;
pub mod kernel;
pub mod multirate;
pub mod plasticity;
pub mod stability;

pub use crate::body::settings::Integrator;
