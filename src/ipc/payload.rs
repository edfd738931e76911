//! The shared-memory payloads of `proto/palpa_ipc.h`, as `#[repr(C)]` Rust types: plain data, no
//! pointers, the same size, alignment and field offsets as the C header (tests/ipc_layout.rs checks
//! all three against a C compiler). The iceoryx2 type names are the C type names.

#[cfg(feature = "ipc")]
use iceoryx2::prelude::ZeroCopySend;

/// iceoryx2 type name of [`ToolPoseV1`].
pub const TOOL_POSE_TYPE_NAME: &str = "palpa_tool_pose_v1";
/// iceoryx2 type name of [`ToolFeedbackV1`].
pub const TOOL_FEEDBACK_TYPE_NAME: &str = "palpa_tool_feedback_v1";
/// iceoryx2 type name of [`StatsV1`].
pub const STATS_TYPE_NAME: &str = "palpa_stats_v1";
/// iceoryx2 type name of [`ControlRequestV1`].
pub const CONTROL_REQUEST_TYPE_NAME: &str = "palpa_control_request_v1";
/// iceoryx2 type name of [`ControlResponseV1`].
pub const CONTROL_RESPONSE_TYPE_NAME: &str = "palpa_control_response_v1";
/// iceoryx2 type name of [`MeshHeaderV1`].
pub const MESH_HEADER_TYPE_NAME: &str = "palpa_mesh_header_v1";

/// A tool pose sent by a device bridge (`palpa_tool_pose_v1`, 88 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend), type_name("palpa_tool_pose_v1"))]
pub struct ToolPoseV1 {
    /// Strictly increasing per bridge run.
    pub seq: u64,
    /// The bridge's CLOCK_MONOTONIC at sampling (ns).
    pub device_time_ns: u64,
    /// The tool's tip (m, world frame).
    pub position: [f64; 3],
    /// Unit quaternion w, x, y, z (world_from_tool).
    pub orientation: [f64; 4],
    /// Grasper opening (rad); 0 for tools without jaws.
    pub jaw: f64,
    /// Button bit mask.
    pub buttons: u32,
    /// 0.
    pub reserved: u32,
}

/// Feedback flag: no fresh pose within the timeout; the force is zero.
pub const FEEDBACK_STALE: u32 = 1;
/// Feedback flag: the force was scaled down to the tool's `max_force`.
pub const FEEDBACK_CLAMPED: u32 = 2;
/// Feedback flag: the divergence guard acted on this tick — it restored at least one body (any body,
/// not only one this tool touches) — or the tool's force or torque was not finite and was sent as
/// zero. Set on that tick's feedback of every tool.
pub const FEEDBACK_DIVERGED: u32 = 4;
/// Feedback flag: the newest pose was rejected; the last good one was used.
pub const FEEDBACK_REJECTED: u32 = 8;

/// The daemon's answer to a pose (`palpa_tool_feedback_v1`, 80 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(
    feature = "ipc",
    derive(ZeroCopySend),
    type_name("palpa_tool_feedback_v1")
)]
pub struct ToolFeedbackV1 {
    /// `seq` of the pose this answers (0 before any pose).
    pub seq: u64,
    /// Echoed from that pose (ns).
    pub device_time_ns: u64,
    /// Simulation tick that computed it.
    pub tick: u64,
    /// Force to render on the device (N, world frame).
    pub force: [f64; 3],
    /// Torque about the tool's tip (N·m, world frame).
    pub torque: [f64; 3],
    /// Nodes in contact.
    pub contacts: u32,
    /// `FEEDBACK_*` bits.
    pub flags: u32,
}

/// Active-system bit: gravity.
pub const SYSTEM_GRAVITY: u32 = 1 << 0;
/// Active-system bit: air viscosity.
pub const SYSTEM_AIR_VISCOSITY: u32 = 1 << 1;
/// Active-system bit: node–obstacle contact.
pub const SYSTEM_OBSTACLE_CONTACT: u32 = 1 << 2;
/// Active-system bit: obstacle friction.
pub const SYSTEM_OBSTACLE_FRICTION: u32 = 1 << 3;
/// Active-system bit: moving rigid components.
pub const SYSTEM_RIGID_COMPONENTS: u32 = 1 << 4;
/// Active-system bit: tool contact, friction and feedback.
pub const SYSTEM_TOOL_CONTACT: u32 = 1 << 5;
/// Active-system bit: body–body contact.
pub const SYSTEM_BODY_CONTACT: u32 = 1 << 6;

/// Loop statistics over a one-second window (`palpa_stats_v1`, 128 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend), type_name("palpa_stats_v1"))]
pub struct StatsV1 {
    /// Last tick of the window.
    pub tick: u64,
    /// Ticks in the window.
    pub window_ticks: u64,
    /// Tick compute time (step and publish), µs.
    pub compute_min_us: f64,
    /// Mean compute time, µs.
    pub compute_mean_us: f64,
    /// Largest compute time, µs.
    pub compute_max_us: f64,
    /// 99th percentile of the compute time, µs.
    pub compute_p99_us: f64,
    /// Mean wake-up lateness past the deadline, µs.
    pub lateness_mean_us: f64,
    /// Largest wake-up lateness, µs.
    pub lateness_max_us: f64,
    /// Total ticks whose compute exceeded the period.
    pub synchronicity_misses: u64,
    /// Total poses rejected by the input checks.
    pub rejected_inputs: u64,
    /// Total times a tool went stale.
    pub disconnects: u64,
    /// `SYSTEM_*` bits.
    pub active_systems: u32,
    /// Bit i: tool i (scene order) has a fresh pose.
    pub tools_connected: u32,
    /// 1 while paused.
    pub paused: u32,
    /// Total records the recorder had to drop (queue full); 0 when not recording.
    pub dropped_records: u32,
    /// Smallest stability margin of any body under the paper's scheme at dt (ω·Δt limit minus the
    /// worst node's ω·Δt; negative: that body needs its multi-rate or implicit integrator).
    pub stability_margin: f64,
    /// Total times the divergence guard restored a body (over the whole session, resets included).
    pub guard_events: u64,
    /// Total iceoryx2 operations of the loop that failed (a send, a receive, a loan, a connection
    /// update); the daemon counts them and goes on.
    pub ipc_errors: u64,
}

/// Control command: rebuild the world from the scene, back to tick 0.
pub const CONTROL_RESET: u32 = 1;
/// Control command: pause the simulation (the loop keeps answering).
pub const CONTROL_PAUSE: u32 = 2;
/// Control command: resume.
pub const CONTROL_RESUME: u32 = 3;
/// Control command: publish a mesh keyframe on the next display tick.
pub const CONTROL_KEYFRAME: u32 = 4;

/// A control request (`palpa_control_request_v1`, 16 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(
    feature = "ipc",
    derive(ZeroCopySend),
    type_name("palpa_control_request_v1")
)]
pub struct ControlRequestV1 {
    /// `CONTROL_*`.
    pub command: u32,
    /// 0.
    pub reserved: u32,
    /// 0 (reserved for commands with an argument).
    pub argument: u64,
}

/// The answer to a control request (`palpa_control_response_v1`, 16 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(
    feature = "ipc",
    derive(ZeroCopySend),
    type_name("palpa_control_response_v1")
)]
pub struct ControlResponseV1 {
    /// Echoed.
    pub command: u32,
    /// 0 done, −1 unknown command.
    pub status: i32,
    /// Tick at which it was applied.
    pub tick: u64,
}

/// Mesh message kind: a keyframe (all positions and triangles).
pub const MESH_KEYFRAME: u32 = 0;
/// Mesh message kind: a delta (changed vertices).
pub const MESH_DELTA: u32 = 1;

/// The user header of a mesh message (`palpa_mesh_header_v1`, 40 bytes); the byte slice that follows
/// is laid out as `proto/palpa_ipc.h` says.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(
    feature = "ipc",
    derive(ZeroCopySend),
    type_name("palpa_mesh_header_v1")
)]
pub struct MeshHeaderV1 {
    /// `MESH_KEYFRAME` or `MESH_DELTA`.
    pub kind: u32,
    /// Body index: scene order, then bodies a transection added, in order of creation (each starts
    /// with a keyframe).
    pub body: u32,
    /// Tick of the state this message brings the display to.
    pub tick: u64,
    /// Delta: tick of the state it applies to; keyframe: equal to `tick`.
    pub base_tick: u64,
    /// Vertices of the body at `tick`.
    pub vertex_count: u32,
    /// Keyframe: triangles that follow; delta: 0.
    pub triangle_count: u32,
    /// Delta: entries that follow; keyframe: 0.
    pub changed_count: u32,
    /// Bytes of the slice that carry data.
    pub payload_bytes: u32,
}
