//! Contact responses: nodes against fixed obstacles and against tools, with Coulomb friction.

pub mod obstacle;
pub mod tool;
