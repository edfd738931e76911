//! The daemon: input hygiene and loop statistics (independent of the transport), and with the `ipc`
//! feature the 1 kHz loop over iceoryx2 ([`serve`](serve::serve)).

pub mod input;
#[cfg(feature = "ipc")]
pub mod serve;
pub mod sink;
pub mod stats;

use crate::ipc::payload::{
    FEEDBACK_CLAMPED, FEEDBACK_DIVERGED, FEEDBACK_REJECTED, FEEDBACK_STALE, ToolFeedbackV1,
};
use crate::tool::Tool;

/// The feedback payload of a tool after a step: zero with the stale flag when its bridge is not
/// connected, never a non-finite number (flagged instead). `echo` is the `seq` and `device_time_ns`
/// of the pose it answers. Shared by the daemon and replay, so both produce the same bytes.
pub fn feedback_payload(
    tool: &Tool,
    tick: u64,
    connected: bool,
    rejected: bool,
    echo: (u64, u64),
) -> ToolFeedbackV1 {
    let feedback = &tool.feedback;
    let mut flags = 0;
    if !connected {
        flags |= FEEDBACK_STALE;
    }
    if feedback.clamped {
        flags |= FEEDBACK_CLAMPED;
    }
    if rejected {
        flags |= FEEDBACK_REJECTED;
    }
    let (force, torque) = if connected {
        (feedback.force_in_world, feedback.torque_in_world)
    } else {
        (crate::Vec3::zeros(), crate::Vec3::zeros())
    };
    let finite = force.iter().chain(torque.iter()).all(|x| x.is_finite());
    ToolFeedbackV1 {
        seq: echo.0,
        device_time_ns: echo.1,
        tick,
        force: if finite { force.into() } else { [0.0; 3] },
        torque: if finite { torque.into() } else { [0.0; 3] },
        contacts: feedback.contacts,
        flags: if finite {
            flags
        } else {
            flags | FEEDBACK_DIVERGED
        },
    }
}
