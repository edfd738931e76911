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

/// The little-endian wire form of a v1 payload: the bytes of its C layout (no padding in any of
/// them), written and read field by field so that it is the same on every machine. What
/// `palpa-zenoh` carries over Zenoh.
pub trait WireV1: Sized {
    /// Size of the C layout (bytes).
    const BYTES: usize;
    /// Appends the wire form to `out`.
    fn write_le(&self, out: &mut Vec<u8>);
    /// The payload in `bytes`, which must be exactly [`WireV1::BYTES`] long (`None` otherwise).
    fn read_le(bytes: &[u8]) -> Option<Self>;
    /// The wire form.
    fn to_le_vec(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(Self::BYTES);
        self.write_le(&mut out);
        out
    }
}

/// Reads little-endian fields in order.
struct LeReader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl LeReader<'_> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut field = [0u8; N];
        field.copy_from_slice(&self.bytes[self.at..self.at + N]);
        self.at += N;
        field
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.take())
    }
    fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.take())
    }
    fn f64s<const N: usize>(&mut self) -> [f64; N] {
        std::array::from_fn(|_| self.f64())
    }
}

fn put_f64s(out: &mut Vec<u8>, values: &[f64]) {
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

impl WireV1 for ToolPoseV1 {
    const BYTES: usize = 88;
    fn write_le(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.seq.to_le_bytes());
        out.extend_from_slice(&self.device_time_ns.to_le_bytes());
        put_f64s(out, &self.position);
        put_f64s(out, &self.orientation);
        put_f64s(out, &[self.jaw]);
        out.extend_from_slice(&self.buttons.to_le_bytes());
        out.extend_from_slice(&self.reserved.to_le_bytes());
    }
    fn read_le(bytes: &[u8]) -> Option<Self> {
        if bytes.len() != Self::BYTES {
            return None;
        }
        let mut r = LeReader { bytes, at: 0 };
        Some(Self {
            seq: r.u64(),
            device_time_ns: r.u64(),
            position: r.f64s(),
            orientation: r.f64s(),
            jaw: r.f64(),
            buttons: r.u32(),
            reserved: r.u32(),
        })
    }
}

impl WireV1 for ToolFeedbackV1 {
    const BYTES: usize = 80;
    fn write_le(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.seq.to_le_bytes());
        out.extend_from_slice(&self.device_time_ns.to_le_bytes());
        out.extend_from_slice(&self.tick.to_le_bytes());
        put_f64s(out, &self.force);
        put_f64s(out, &self.torque);
        out.extend_from_slice(&self.contacts.to_le_bytes());
        out.extend_from_slice(&self.flags.to_le_bytes());
    }
    fn read_le(bytes: &[u8]) -> Option<Self> {
        if bytes.len() != Self::BYTES {
            return None;
        }
        let mut r = LeReader { bytes, at: 0 };
        Some(Self {
            seq: r.u64(),
            device_time_ns: r.u64(),
            tick: r.u64(),
            force: r.f64s(),
            torque: r.f64s(),
            contacts: r.u32(),
            flags: r.u32(),
        })
    }
}

impl WireV1 for StatsV1 {
    const BYTES: usize = 128;
    fn write_le(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.tick.to_le_bytes());
        out.extend_from_slice(&self.window_ticks.to_le_bytes());
        put_f64s(
            out,
            &[
                self.compute_min_us,
                self.compute_mean_us,
                self.compute_max_us,
                self.compute_p99_us,
                self.lateness_mean_us,
                self.lateness_max_us,
            ],
        );
        for v in [
            self.synchronicity_misses,
            self.rejected_inputs,
            self.disconnects,
        ] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for v in [
            self.active_systems,
            self.tools_connected,
            self.paused,
            self.dropped_records,
        ] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        put_f64s(out, &[self.stability_margin]);
        out.extend_from_slice(&self.guard_events.to_le_bytes());
        out.extend_from_slice(&self.ipc_errors.to_le_bytes());
    }
    fn read_le(bytes: &[u8]) -> Option<Self> {
        if bytes.len() != Self::BYTES {
            return None;
        }
        let mut r = LeReader { bytes, at: 0 };
        Some(Self {
            tick: r.u64(),
            window_ticks: r.u64(),
            compute_min_us: r.f64(),
            compute_mean_us: r.f64(),
            compute_max_us: r.f64(),
            compute_p99_us: r.f64(),
            lateness_mean_us: r.f64(),
            lateness_max_us: r.f64(),
            synchronicity_misses: r.u64(),
            rejected_inputs: r.u64(),
            disconnects: r.u64(),
            active_systems: r.u32(),
            tools_connected: r.u32(),
            paused: r.u32(),
            dropped_records: r.u32(),
            stability_margin: r.f64(),
            guard_events: r.u64(),
            ipc_errors: r.u64(),
        })
    }
}

impl WireV1 for MeshHeaderV1 {
    const BYTES: usize = 40;
    fn write_le(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.kind.to_le_bytes());
        out.extend_from_slice(&self.body.to_le_bytes());
        out.extend_from_slice(&self.tick.to_le_bytes());
        out.extend_from_slice(&self.base_tick.to_le_bytes());
        for v in [
            self.vertex_count,
            self.triangle_count,
            self.changed_count,
            self.payload_bytes,
        ] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    fn read_le(bytes: &[u8]) -> Option<Self> {
        if bytes.len() != Self::BYTES {
            return None;
        }
        let mut r = LeReader { bytes, at: 0 };
        Some(Self {
            kind: r.u32(),
            body: r.u32(),
            tick: r.u64(),
            base_tick: r.u64(),
            vertex_count: r.u32(),
            triangle_count: r.u32(),
            changed_count: r.u32(),
            payload_bytes: r.u32(),
        })
    }
}

#[cfg(test)]
mod wire_tests {
    use super::*;

    /// The in-memory bytes of a `#[repr(C)]` payload without padding.
    fn memory<T: Copy>(value: &T) -> Vec<u8> {
        // SAFETY: T is a plain-data payload of this module (no padding, no pointers): every byte is
        // initialised and may be read as u8.
        unsafe {
            std::slice::from_raw_parts((value as *const T).cast::<u8>(), size_of::<T>()).to_vec()
        }
    }

    fn check<T: WireV1 + Copy + PartialEq + std::fmt::Debug>(value: T) {
        let wire = value.to_le_vec();
        assert_eq!(wire.len(), T::BYTES);
        assert_eq!(size_of::<T>(), T::BYTES);
        if cfg!(target_endian = "little") {
            assert_eq!(
                wire,
                memory(&value),
                "the wire form is the C layout's bytes"
            );
        }
        assert_eq!(T::read_le(&wire), Some(value));
        assert_eq!(T::read_le(&wire[1..]), None);
        let mut longer = wire.clone();
        longer.push(0);
        assert_eq!(T::read_le(&longer), None);
    }

    #[test]
    fn every_payload_round_trips_through_its_little_endian_wire_form() {
        check(ToolPoseV1 {
            seq: 7,
            device_time_ns: 1 << 40,
            position: [0.1, -0.2, 0.3],
            orientation: [0.5, 0.5, -0.5, 0.5],
            jaw: 0.25,
            buttons: 5,
            reserved: 0,
        });
        check(ToolFeedbackV1 {
            seq: 3,
            device_time_ns: 9,
            tick: 11,
            force: [1.0, -2.5, 3.25],
            torque: [0.0, 1e-3, -4.0],
            contacts: 12,
            flags: FEEDBACK_CLAMPED | FEEDBACK_STALE,
        });
        let mut stats = StatsV1 {
            tick: 1000,
            window_ticks: 1000,
            compute_min_us: 1.5,
            compute_mean_us: 2.5,
            compute_max_us: 30.0,
            compute_p99_us: 7.0,
            lateness_mean_us: 0.5,
            lateness_max_us: 4.0,
            synchronicity_misses: 2,
            rejected_inputs: 3,
            disconnects: 4,
            active_systems: 0x7f,
            tools_connected: 1,
            paused: 0,
            dropped_records: 6,
            stability_margin: -0.25,
            guard_events: 8,
            ipc_errors: 9,
        };
        check(stats);
        stats.paused = 1;
        check(stats);
        check(MeshHeaderV1 {
            kind: MESH_DELTA,
            body: 2,
            tick: 500,
            base_tick: 484,
            vertex_count: 642,
            triangle_count: 0,
            changed_count: 17,
            payload_bytes: 272,
        });
    }
}
