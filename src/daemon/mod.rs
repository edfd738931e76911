//! The daemon: input hygiene and loop statistics (independent of the transport), and with the `ipc`
//! feature the 1 kHz loop over iceoryx2 ([`serve`](serve::serve)).

pub mod input;
#[cfg(feature = "ipc")]
pub mod serve;
pub mod sink;
pub mod stats;
pub mod values;

use crate::ipc::payload::{
    FEEDBACK_CLAMPED, FEEDBACK_DIVERGED, FEEDBACK_REJECTED, FEEDBACK_STALE, ToolFeedbackV1,
};
use crate::tool::Tool;
use crate::world::World;

/// Whether the divergence guard restored any body during the world's last step.
pub fn guard_acted(world: &World) -> bool {
    world.counters.guard_events > 0
}

/// [`feedback_payload`] of tool `tool` after the world's last step, with
/// [`FEEDBACK_DIVERGED`] set when the divergence guard acted on any body in that step (every tool's
/// feedback of that tick carries it). What the daemon and `palpa run` publish and record, and what
/// replay must recompute to compare.
pub fn feedback_of(
    world: &World,
    tool: usize,
    connected: bool,
    rejected: bool,
    echo: (u64, u64),
) -> ToolFeedbackV1 {
    let mut payload = feedback_payload(&world.tools[tool], world.tick, connected, rejected, echo);
    if guard_acted(world) {
        payload.flags |= FEEDBACK_DIVERGED;
    }
    payload
}

/// The feedback payload of a tool after a step: zero with the stale flag when its bridge is not
/// connected, never a non-finite number (flagged instead). It does not see the guard: use
/// [`feedback_of`], which adds the divergence flag of the tick. `echo` is the `seq` and `device_time_ns`
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
