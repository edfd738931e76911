//! Contact responses: nodes against fixed obstacles and against tools (with Coulomb friction), and
//! surfaces of different bodies against each other.

pub mod bodies;
pub mod obstacle;
pub mod overlap;
mod self_pairs;
pub mod tool;
pub mod tool_faces;
