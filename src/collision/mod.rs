//! Collision detection: fixed obstacles, continuous detection against tools, the broad phase between
//! deformable surfaces and the continuous narrow phase (vertex–face, edge–edge).

pub mod blocks;
pub mod bvh;
pub mod ccd;
pub mod obstacle;
pub mod tool;
