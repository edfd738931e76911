//! Session recording to MCAP and its replay (feature `record`).

/// The protobuf types of `proto/palpa.proto`.
#[allow(missing_docs, clippy::all)]
pub mod proto {
    include!(concat!(env!("OUT_DIR"), "/palpa.rs"));
}

/// The FileDescriptorSet of `proto/palpa.proto`, embedded as each channel's schema.
pub const DESCRIPTOR_SET: &[u8] =
    include_bytes!(concat!(env!("OUT_DIR"), "/palpa_descriptor_set.bin"));

#[cfg(feature = "live")]
pub mod live;
pub mod reader;
pub mod recorder;
pub mod replay;
pub mod visual;
