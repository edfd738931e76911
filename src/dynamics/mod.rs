//! Forces, integration and stability analysis of the bodies (MODEL.md §2–3).

pub mod forces;
pub mod integrate;
pub mod stability;
