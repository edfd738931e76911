//! The iceoryx2 services of the daemon (`proto/palpa_ipc.h`): names under a prefix, and the one set of
//! service settings every side uses, so a bridge that opens a service asks for exactly what the daemon
//! created. Daemon and clients both call these builders (`open_or_create`); settings that must agree
//! (history 1, subscriber buffer 1, safe overflow for the latest-value streams) are fixed here.

use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::{publish_subscribe, request_response};

use crate::ipc::payload::{
    ControlRequestV1, ControlResponseV1, MeshHeaderV1, StatsV1, ToolFeedbackV1, ToolPoseV1,
};

/// What failed in setting up or using the services: each names the service (or prefix) it was
/// for, with iceoryx2's own account of the failure.
#[derive(Debug, thiserror::Error)]
pub enum IpcError {
    /// This process's iceoryx2 node could not be created.
    #[error("cannot create this process's iceoryx2 node: {0}")]
    Node(String),
    /// A service name iceoryx2 refuses (a prefix with characters it does not accept).
    #[error("{name:?} is not a service name iceoryx2 accepts: {reason}")]
    Name {
        /// The name asked for.
        name: String,
        /// iceoryx2's reason.
        reason: String,
    },
    /// A service could not be opened or created (for one, it exists with other settings).
    #[error("cannot open or create the service {service:?}: {reason}")]
    Service {
        /// The service's name.
        service: String,
        /// iceoryx2's reason.
        reason: String,
    },
    /// A port of a service could not be created.
    #[error("cannot create a {port} of the service {service:?}: {reason}")]
    Port {
        /// The service's name.
        service: String,
        /// `publisher`, `subscriber`, `server` or `client`.
        port: &'static str,
        /// iceoryx2's reason.
        reason: String,
    },
    /// Sending, receiving or reaching the other ends of a service failed.
    #[error("{what} on the service {service:?} failed: {reason}")]
    Transfer {
        /// The service's name.
        service: String,
        /// What was being done (`send`, `receive`, `update connections`).
        what: &'static str,
        /// iceoryx2's reason.
        reason: String,
    },
    /// No daemon answered a device on its prefix in the time it waits.
    #[error("no daemon answers on prefix {prefix:?} (is `palpa serve --prefix {prefix}` running?)")]
    NoDaemon {
        /// The prefix the device used.
        prefix: String,
    },
}

impl IpcError {
    /// A port of `service` that could not be created.
    pub fn port(
        service: &ServiceName,
        port: &'static str,
        reason: impl core::fmt::Display,
    ) -> Self {
        Self::Port {
            service: service.to_string(),
            port,
            reason: reason.to_string(),
        }
    }

    /// `what` on `service` failed.
    pub fn transfer(
        service: &ServiceName,
        what: &'static str,
        reason: impl core::fmt::Display,
    ) -> Self {
        Self::Transfer {
            service: service.to_string(),
            what,
            reason: reason.to_string(),
        }
    }
}

/// CLOCK_MONOTONIC in nanoseconds: the clock of `device_time_ns` and of receive times.
pub fn monotonic_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes into the valid timespec we pass.
    unsafe {
        libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts);
    }
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// Name of a tool's pose service.
pub fn pose_service_name(prefix: &str, tool: &str) -> String {
    format!("{prefix}/tool/{tool}/pose")
}

/// Name of a tool's feedback service.
pub fn feedback_service_name(prefix: &str, tool: &str) -> String {
    format!("{prefix}/tool/{tool}/feedback")
}

/// Name of the mesh stream.
pub fn mesh_service_name(prefix: &str) -> String {
    format!("{prefix}/display/mesh")
}

/// Name of the statistics stream.
pub fn stats_service_name(prefix: &str) -> String {
    format!("{prefix}/stats")
}

/// Name of the control service.
pub fn control_service_name(prefix: &str) -> String {
    format!("{prefix}/control")
}

/// A node for this process, with iceoryx2's own logging limited to errors.
pub fn create_node() -> Result<Node<ipc::Service>, IpcError> {
    set_log_level(LogLevel::Error);
    NodeBuilder::new()
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|e| IpcError::Node(e.to_string()))
}

fn service_name(name: &str) -> Result<ServiceName, IpcError> {
    ServiceName::new(name).map_err(|e| IpcError::Name {
        name: name.to_string(),
        reason: e.to_string(),
    })
}

/// The service `name` could not be opened or created.
fn service_error(name: &str, reason: impl core::fmt::Display) -> IpcError {
    IpcError::Service {
        service: name.to_string(),
        reason: reason.to_string(),
    }
}

/// A latest-value stream: history 1, subscriber buffer 1, safe overflow (the newest sample wins).
fn latest_value<T: core::fmt::Debug + ZeroCopySend>(
    node: &Node<ipc::Service>,
    name: &str,
) -> Result<publish_subscribe::PortFactory<ipc::Service, T, ()>, IpcError> {
    node.service_builder(&service_name(name)?)
        .publish_subscribe::<T>()
        .history_size(1)
        .subscriber_max_buffer_size(1)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(|e| service_error(name, e))
}

/// The pose service of a tool.
pub fn pose_service(
    node: &Node<ipc::Service>,
    prefix: &str,
    tool: &str,
) -> Result<publish_subscribe::PortFactory<ipc::Service, ToolPoseV1, ()>, IpcError> {
    latest_value(node, &pose_service_name(prefix, tool))
}

/// The feedback service of a tool.
pub fn feedback_service(
    node: &Node<ipc::Service>,
    prefix: &str,
    tool: &str,
) -> Result<publish_subscribe::PortFactory<ipc::Service, ToolFeedbackV1, ()>, IpcError> {
    latest_value(node, &feedback_service_name(prefix, tool))
}

/// The statistics stream.
pub fn stats_service(
    node: &Node<ipc::Service>,
    prefix: &str,
) -> Result<publish_subscribe::PortFactory<ipc::Service, StatsV1, ()>, IpcError> {
    latest_value(node, &stats_service_name(prefix))
}

/// Messages a display may hold unread before the oldest is overwritten.
pub const MESH_BUFFER: usize = 16;

/// The mesh stream: byte slices with a [`MeshHeaderV1`] user header; a buffer of
/// [`MESH_BUFFER`] messages with safe overflow (a slow display loses the oldest and resynchronises
/// on the next keyframe), history of one message per body is not kept: late joiners ask for a
/// keyframe or wait for the periodic one.
pub fn mesh_service(
    node: &Node<ipc::Service>,
    prefix: &str,
) -> Result<publish_subscribe::PortFactory<ipc::Service, [u8], MeshHeaderV1>, IpcError> {
    let name = mesh_service_name(prefix);
    node.service_builder(&service_name(&name)?)
        .publish_subscribe::<[u8]>()
        .user_header::<MeshHeaderV1>()
        .history_size(0)
        .subscriber_max_buffer_size(MESH_BUFFER)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(|e| service_error(&name, e))
}

/// The control service.
pub fn control_service(
    node: &Node<ipc::Service>,
    prefix: &str,
) -> Result<
    request_response::PortFactory<ipc::Service, ControlRequestV1, (), ControlResponseV1, ()>,
    IpcError,
> {
    let name = control_service_name(prefix);
    node.service_builder(&service_name(&name)?)
        .request_response::<ControlRequestV1, ControlResponseV1>()
        .open_or_create()
        .map_err(|e| service_error(&name, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_name_iceoryx2_refuses_is_reported_with_the_name() {
        let long = "x".repeat(300);
        match service_name(&long) {
            Err(IpcError::Name { name, reason }) => {
                assert_eq!(name, long);
                assert!(reason.contains("ExceedsMaximumLength"), "{reason}");
            }
            other => panic!("expected a name error, got {other:?}"),
        }
        assert!(service_name(&pose_service_name("palpa", "probe")).is_ok());
    }
}
