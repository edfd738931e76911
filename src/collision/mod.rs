//! Collision geometry: fixed obstacles (continuous detection between moving surfaces comes with tools).

pub mod obstacle;
