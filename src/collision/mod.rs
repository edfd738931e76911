//! Collision geometry: fixed obstacles and continuous detection against tools.

pub mod obstacle;
pub mod tool;
