//! The daemon's parts that do not depend on the transport: input hygiene and loop statistics.

pub mod input;
pub mod stats;
