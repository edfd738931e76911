//! The simulated haptic device: a model of a real device held by a hand ([`model`]) and, with the
//! `ipc` feature, its loop over the daemon's services ([`run`]), shared by `palpa-device` and
//! `palpa demo`.

pub mod model;
#[cfg(feature = "ipc")]
pub mod run;
