//! Contact responses: nodes against fixed obstacles, with Coulomb friction.

pub mod obstacle;
