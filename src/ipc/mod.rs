//! Shared-memory IPC: the payload types of `proto/palpa_ipc.h` (always available, plain data) and,
//! with the `ipc` feature, the iceoryx2 services of the daemon.

pub mod payload;
#[cfg(feature = "ipc")]
pub mod services;
