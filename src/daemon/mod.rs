//! The daemon: input hygiene and loop statistics (independent of the transport), and with the `ipc`
//! feature the 1 kHz loop over iceoryx2 ([`serve`](serve::serve)).

pub mod input;
#[cfg(feature = "ipc")]
pub mod serve;
pub mod stats;
