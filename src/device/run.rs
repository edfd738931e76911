//! The simulated device's loop over iceoryx2 (used by `palpa-device` and `palpa demo`): publish the
//! handle's pose every millisecond on `<prefix>/tool/<tool>/pose`, render the force received on
//! `<prefix>/tool/<tool>/feedback`, and time every round trip.
//!
//! Real-time mode sends on its own 1 ms clock; lockstep mode sends the next pose only when the
//! previous one was answered (10 s at most — a watchdog against a daemon that is gone — then it
//! counts as lost).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::{Node, PortFactory, ipc};
use iceoryx2::service::port_factory::publish_subscribe;

use super::model::{Device, DeviceSpec, Hand};
use crate::Vec3;
use crate::ipc::payload::{ToolFeedbackV1, ToolPoseV1};
use crate::ipc::services::{IpcError, create_node, feedback_service, monotonic_ns, pose_service};
use crate::tool::{Keyframe, ToolInput};

/// A built-in motion of the hand.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motion {
    /// Down 6 mm into the surface, hold, and up.
    Press,
    /// Down 3 mm and back and forth 2 cm along x, then up.
    Stroke,
    /// Four presses of 4 mm, one a second.
    Palpate,
    /// Presses of 4 mm, one a second, for as long as the device runs (a tool kept at work).
    PalpateThroughout,
    /// A smooth random walk over and into the surface (seeded).
    Random,
}

/// Where the hand goes.
#[derive(Clone, Debug, PartialEq)]
pub enum HandPath {
    /// A built-in motion around a surface point.
    BuiltIn {
        /// The motion.
        motion: Motion,
        /// The surface point (m, world).
        at: Vec3,
        /// Seed of the random motion.
        seed: u64,
    },
    /// Waypoints as in a scene tool script.
    Script(Vec<Keyframe>),
}

/// How the device runs.
#[derive(Clone, Debug)]
pub struct DeviceOptions {
    /// Service prefix.
    pub prefix: String,
    /// Tool name.
    pub tool: String,
    /// The device model.
    pub spec: DeviceSpec,
    /// The hand's path.
    pub path: HandPath,
    /// Seconds to run.
    pub duration: f64,
    /// Wait for each answer before the next pose.
    pub lockstep: bool,
    /// Keep one row per pose for a trace.
    pub keep_trace: bool,
}

impl DeviceOptions {
    /// The demo's device: a Geomagic Touch palpating the top of the embedded default organ through
    /// its tool `probe`, for `duration` seconds (`palpa demo`, `palpa-bench latency`).
    pub fn palpating_default_organ(prefix: &str, duration: f64) -> Self {
        Self {
            prefix: prefix.to_string(),
            tool: "probe".into(),
            spec: crate::device::model::PRESETS[0],
            path: HandPath::BuiltIn {
                motion: Motion::Palpate,
                at: Vec3::new(0.0, 0.0, 0.0645),
                seed: 1,
            },
            duration,
            lockstep: false,
            keep_trace: false,
        }
    }
}

/// One simulated device per tool of `scene` whose pose comes over IPC (`palpa demo --scene`), each
/// a Geomagic Touch. A grasper works on the thinnest body (whose narrower horizontal side is the
/// smallest: the easiest to take between its jaws), any other tool on the k-th body for the k-th
/// IPC tool (in scene order, wrapping round), at the top of the body as placed. A grasper comes
/// down over it with its jaws open across the body's narrower side, closes and, holding it, lifts
/// it 2 cm and puts it down every 5 s, letting go at the end of the run; any other tool palpates it
/// (presses of 4 mm once a second, from 3 cm above, for as long as the devices run).
pub fn devices_for_scene(
    scene: &crate::scene::Scene,
    prefix: &str,
    duration: f64,
) -> Vec<DeviceOptions> {
    use crate::tool::{ToolInput, ToolShape};
    let mut devices = Vec::new();
    if scene.bodies.is_empty() {
        return devices;
    }
    // Each body's box as placed (m, world).
    let boxes: Vec<(Vec3, Vec3, Vec<Vec3>)> = scene
        .bodies
        .iter()
        .map(|body| {
            let placement = &body.placement;
            let world: Vec<Vec3> = body
                .mesh
                .positions_in_body
                .iter()
                .map(|p| placement.position_in_world + placement.world_from_body * p)
                .collect();
            let (mut low, mut high) = (world[0], world[0]);
            for x in &world {
                low = low.inf(x);
                high = high.sup(x);
            }
            (low, high, world)
        })
        .collect();
    // The thinnest body (its narrower horizontal side the smallest): the one a grasper takes.
    let thinnest = (0..boxes.len())
        .min_by(|&a, &b| {
            let narrow = |i: usize| {
                let size = boxes[i].1 - boxes[i].0;
                size.x.min(size.y)
            };
            narrow(a).total_cmp(&narrow(b))
        })
        .unwrap_or(0);
    let ipc_tools = scene
        .tools
        .iter()
        .filter(|t| matches!(t.input, ToolInput::Ipc));
    for (k, tool) in ipc_tools.enumerate() {
        let grasper = matches!(tool.shape, ToolShape::Grasper { .. });
        let (low, high, world) = &boxes[if grasper { thinnest } else { k % boxes.len() }];
        let (low, high) = (*low, *high);
        // The top of the body above its centre: the highest node near the vertical through it (a
        // node, so that a thin jaw meets tissue rather than a gap between nodes).
        let centre = (low + high) * 0.5;
        let reach = 0.25 * (high - low).xy().norm();
        let at = world
            .iter()
            .filter(|x| (x.xy() - centre.xy()).norm() <= reach)
            .fold(None::<Vec3>, |best, x| match best {
                Some(b) if b.z >= x.z => Some(b),
                _ => Some(*x),
            })
            .unwrap_or(Vec3::new(centre.x, centre.y, high.z));
        let path = match tool.shape {
            ToolShape::Grasper { jaw_length, .. } => {
                // Pointing down, the jaws opening across the narrower horizontal side.
                let size = high - low;
                let down = if size.x > size.y {
                    nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                        0.0,
                        std::f64::consts::FRAC_1_SQRT_2,
                        std::f64::consts::FRAC_1_SQRT_2,
                        0.0,
                    ))
                } else {
                    nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                        0.0, 1.0, 0.0, 0.0,
                    ))
                };
                HandPath::Script(grasp_cycle(&at, centre.z, jaw_length, &down, duration))
            }
            _ => HandPath::BuiltIn {
                motion: Motion::PalpateThroughout,
                at,
                seed: k as u64 + 1,
            },
        };
        devices.push(DeviceOptions {
            prefix: prefix.to_string(),
            tool: tool.name.clone(),
            spec: crate::device::model::PRESETS[0],
            path,
            duration,
            lockstep: false,
            keep_trace: false,
        });
    }
    devices
}

/// Keyframes of a grasper taking a body whose top is at `top` and centre at height `middle`:
/// hover 3 cm over the top with the jaws open (1.2 rad), come down until their tips, closed, are at
/// the middle's height, and close (at 1.5 s); then, holding it, lift it 2 cm over a second, hold
/// it up a second, put it down over a second and rest two, every 5 s (a retraction, repeated);
/// at the end of the run (after the last whole lift that leaves a second to spare) open and go
/// back up. Held throughout, the body cannot slip out of the jaws' path between grasps (a tissue
/// let go settles elsewhere on its ligaments, and jaws that come down where it was would miss it).
fn grasp_cycle(
    top: &Vec3,
    middle: f64,
    jaw_length: f64,
    orientation: &nalgebra::UnitQuaternion<f64>,
    duration: f64,
) -> Vec<Keyframe> {
    let open: f64 = 1.2;
    let hinge = middle + jaw_length;
    let above = top.z + jaw_length + 0.03;
    let mut steps: Vec<(f64, f64, f64)> = vec![(0.0, above, open), (1.0, hinge, open)];
    let mut lift = 1.5;
    loop {
        steps.extend([
            (lift, hinge, 0.0),
            (lift + 1.0, hinge + 0.02, 0.0),
            (lift + 2.0, hinge + 0.02, 0.0),
            (lift + 3.0, hinge, 0.0),
        ]);
        // Another whole lift, then the release a second after it, within the run?
        if lift + 5.0 + 4.0 > duration {
            break;
        }
        lift += 5.0;
    }
    let release = lift + 3.5;
    steps.extend([
        (release, hinge, 0.0),
        (release + 0.3, hinge, open),
        (release + 1.0, above, open),
    ]);
    steps
        .into_iter()
        .map(|(t, z, jaw)| Keyframe {
            t,
            pose: crate::tool::ToolPose {
                position_in_world: Vec3::new(top.x, top.y, z),
                world_from_tool: *orientation,
            },
            jaw,
        })
        .collect()
}

/// One row of the device trace.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceRow {
    /// Sequence number of the pose.
    pub seq: u64,
    /// Device time (s).
    pub t: f64,
    /// Measured handle position (m).
    pub position: Vec3,
    /// Last force received (N).
    pub force: Vec3,
    /// Its contact count.
    pub contacts: u32,
    /// Its flags.
    pub flags: u32,
}

/// What the device measured.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DeviceReport {
    /// Poses published.
    pub poses_sent: u64,
    /// Feedback samples received.
    pub feedback_received: u64,
    /// Round-trip latencies of the answered poses (µs), sorted.
    pub latencies_us: Vec<f64>,
    /// Largest force received (N).
    pub max_force: f64,
    /// Answered poses whose answer had the tool touching tissue (contact or a grasp: `contacts`
    /// above 0).
    pub answers_in_contact: u64,
    /// Wall time (s).
    pub seconds: f64,
    /// One row per pose, when asked.
    pub trace: Vec<TraceRow>,
}

impl DeviceReport {
    /// Poses never answered.
    pub fn lost(&self) -> u64 {
        self.poses_sent - self.latencies_us.len() as u64
    }

    /// Latency percentile (µs) of the answered poses, `q` in [0, 1].
    pub fn latency_percentile(&self, q: f64) -> f64 {
        percentile(&self.latencies_us, q)
    }
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let rank = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1]
}

/// A live view of the device, handed to the status callback about once a second.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DeviceStatus {
    /// Device time (s).
    pub t: f64,
    /// Last force received (N).
    pub force: Vec3,
    /// Its contact count.
    pub contacts: u32,
    /// 99th percentile round-trip latency over the last second (µs).
    pub latency_p99_us: f64,
}

/// The hand's intended position at time `t` for a built-in motion around the surface point `at`.
pub fn built_in_target(motion: Motion, at: &Vec3, t: f64, seed: u64) -> Vec3 {
    let smooth = |x: f64| {
        let x = x.clamp(0.0, 1.0);
        x * x * (3.0 - 2.0 * x)
    };
    // Hover high enough to clear the default organ before it settles (its top starts 1.6 cm higher).
    let above = 0.03;
    match motion {
        Motion::Press => {
            let depth = -0.006;
            let z = if t < 0.5 {
                above
            } else if t < 1.5 {
                above + (depth - above) * smooth(t - 0.5)
            } else if t < 2.0 {
                depth
            } else {
                depth + (above - depth) * smooth((t - 2.0) / 0.8)
            };
            at + Vec3::new(0.0, 0.0, z)
        }
        Motion::Stroke => {
            let depth = -0.003;
            let z = above + (depth - above) * smooth(t - 0.3);
            let x = if t < 1.3 {
                0.0
            } else {
                0.02 * (std::f64::consts::PI * (t - 1.3) / 2.0).sin()
            };
            let lift = smooth((t - 5.3) / 0.7);
            at + Vec3::new(x, 0.0, z + (above - z) * lift)
        }
        Motion::Palpate | Motion::PalpateThroughout => {
            let depth = -0.004;
            let phase = (t - 0.5).rem_euclid(1.0);
            let pressing = t >= 0.5 && (t < 4.5 || motion == Motion::PalpateThroughout);
            let dip = if pressing {
                (std::f64::consts::PI * phase).sin().powi(2)
            } else {
                0.0
            };
            at + Vec3::new(0.0, 0.0, above + (depth - above) * dip)
        }
        Motion::Random => {
            // A sum of slow sines with seeded phases: smooth, bounded, repeatable.
            let phase = |k: u64| {
                let mixed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(k.wrapping_mul(1442695040888963407));
                (mixed >> 11) as f64 / (1u64 << 53) as f64 * std::f64::consts::TAU
            };
            let wave = |k: u64, f: f64| (f * t + phase(k)).sin();
            let x = 0.01 * wave(1, 1.1) + 0.004 * wave(2, 2.3);
            let y = 0.01 * wave(3, 0.7) + 0.004 * wave(4, 1.9);
            let z = 0.5 * (above - 0.004) + 0.5 * (above + 0.004) * wave(5, 1.3);
            at + Vec3::new(x, y, z)
        }
    }
}

/// What the device measured about the answers.
struct Tally {
    sent_at: Vec<Instant>,
    latencies: Vec<f64>,
    window: Vec<f64>,
    answered_up_to: u64,
    received: u64,
    max_force: f64,
    in_contact: u64,
    force: Vec3,
    contacts: u32,
    flags: u32,
}

impl Tally {
    fn mark_sent(&mut self, seq: u64) {
        let slot = (seq as usize) & (self.sent_at.len() - 1);
        self.sent_at[slot] = Instant::now();
    }

    /// A feedback sample arrived at `now`: its force is rendered from now on; the first answer to a
    /// pose gives that pose's round-trip latency.
    fn take(&mut self, feedback: &ToolFeedbackV1, now: Instant) {
        self.received += 1;
        self.contacts = feedback.contacts;
        self.flags = feedback.flags;
        let f = Vec3::from(feedback.force);
        if f.iter().all(|x| x.is_finite()) {
            self.force = f;
            self.max_force = self.max_force.max(f.norm());
        }
        if feedback.seq > self.answered_up_to {
            self.answered_up_to = feedback.seq;
            let slot = (feedback.seq as usize) & (self.sent_at.len() - 1);
            let latency = (now - self.sent_at[slot]).as_secs_f64() * 1e6;
            self.latencies.push(latency);
            self.window.push(latency);
            if feedback.contacts > 0 {
                self.in_contact += 1;
            }
        }
    }
}

/// Where the device's hand goes: a script of keyframes, or a built-in motion.
struct HandSampler<'a> {
    path: &'a HandPath,
    script: Option<ToolInput>,
}

impl<'a> HandSampler<'a> {
    fn new(path: &'a HandPath) -> Self {
        let script = match path {
            HandPath::Script(keys) => Some(ToolInput::Script(keys.clone())),
            HandPath::BuiltIn { .. } => None,
        };
        Self { path, script }
    }

    /// The hand's position and jaw opening at `t`, and the handle's orientation (the device
    /// renders forces only, so the hand's orientation is sent as it is meant).
    fn pose_at(&self, t: f64) -> ((Vec3, f64), [f64; 4]) {
        match (self.path, &self.script) {
            (_, Some(input)) => {
                let (pose, jaw) = input.sample(t).unwrap_or_default();
                let q = pose.world_from_tool.quaternion();
                ((pose.position_in_world, jaw), [q.w, q.i, q.j, q.k])
            }
            (HandPath::BuiltIn { motion, at, seed }, None) => (
                (built_in_target(*motion, at, t, *seed), 0.0),
                [1.0, 0.0, 0.0, 0.0],
            ),
            (HandPath::Script(_), None) => unreachable!("a script path always has its input"),
        }
    }

    /// The hand's position at `t`.
    fn position_at(&self, t: f64) -> Vec3 {
        self.pose_at(t).0.0
    }
}

/// The device's ports on its tool's services: poses out, feedback in (the ports first, so that
/// they are dropped before their services and node).
struct DevicePorts {
    publisher: Publisher<ipc::Service, ToolPoseV1, ()>,
    subscriber: Subscriber<ipc::Service, ToolFeedbackV1, ()>,
    poses: publish_subscribe::PortFactory<ipc::Service, ToolPoseV1, ()>,
    feedback: publish_subscribe::PortFactory<ipc::Service, ToolFeedbackV1, ()>,
    _node: Node<ipc::Service>,
}

impl DevicePorts {
    /// Opens (or creates) the pose and feedback services of `tool` under `prefix`, and the ports.
    fn open(prefix: &str, tool: &str) -> Result<Self, IpcError> {
        let node = create_node()?;
        let poses = pose_service(&node, prefix, tool)?;
        let publisher = poses
            .publisher_builder()
            .create()
            .map_err(|e| IpcError::port(poses.name(), "publisher", e))?;
        let feedback = feedback_service(&node, prefix, tool)?;
        let subscriber = feedback
            .subscriber_builder()
            .create()
            .map_err(|e| IpcError::port(feedback.name(), "subscriber", e))?;
        Ok(Self {
            publisher,
            subscriber,
            poses,
            feedback,
            _node: node,
        })
    }

    fn connected(&self) -> Result<(), IpcError> {
        self.publisher
            .update_connections()
            .map_err(|e| IpcError::transfer(self.poses.name(), "update connections", e))
    }

    /// Waits for the daemon: its feedback publisher hands over the last feedback (history 1) once
    /// both ends are connected; then makes sure the first pose reaches its subscriber. False when
    /// `stop` was set first; an error when no daemon answered within 30 s.
    fn wait_for_daemon(&self, stop: &AtomicBool, prefix: &str) -> Result<bool, IpcError> {
        let waiting = Instant::now();
        loop {
            if self.receive()?.is_some() {
                break;
            }
            if stop.load(Ordering::Relaxed) {
                return Ok(false);
            }
            if waiting.elapsed() > Duration::from_secs(30) {
                return Err(IpcError::NoDaemon {
                    prefix: prefix.to_string(),
                });
            }
            self.connected()?;
            std::thread::sleep(Duration::from_millis(1));
        }
        self.connected()?;
        Ok(true)
    }

    fn receive(
        &self,
    ) -> Result<Option<iceoryx2::sample::Sample<ipc::Service, ToolFeedbackV1, ()>>, IpcError> {
        self.subscriber
            .receive()
            .map_err(|e| IpcError::transfer(self.feedback.name(), "receive", e))
    }

    fn send(&self, pose: ToolPoseV1) -> Result<(), IpcError> {
        self.publisher
            .send_copy(pose)
            .map(|_| ())
            .map_err(|e| IpcError::transfer(self.poses.name(), "send", e))
    }

    /// Every answer waiting, into `tally`.
    fn take_answers(&self, tally: &mut Tally) -> Result<(), IpcError> {
        while let Some(sample) = self.receive()? {
            tally.take(sample.payload(), Instant::now());
        }
        Ok(())
    }

    /// Lockstep: waits until pose `seq` is answered (at most 10 s, or until `stop`).
    fn await_answer(&self, tally: &mut Tally, seq: u64, stop: &AtomicBool) -> Result<(), IpcError> {
        let give_up = Instant::now() + Duration::from_secs(10);
        while tally.answered_up_to < seq
            && Instant::now() < give_up
            && !stop.load(Ordering::Relaxed)
        {
            self.take_answers(tally)?;
            if tally.answered_up_to < seq {
                std::thread::sleep(Duration::from_micros(10));
            }
        }
        Ok(())
    }

    /// The answers that arrive within 50 ms after the last pose.
    fn collect_last(&self, tally: &mut Tally) -> Result<(), IpcError> {
        let settle = Instant::now() + Duration::from_millis(50);
        while Instant::now() < settle {
            self.take_answers(tally)?;
            std::thread::sleep(Duration::from_millis(1));
        }
        Ok(())
    }
}

/// Runs the device until the duration is over or `stop` is set; `status` is called about once a
/// second of device time.
pub fn run_device(
    options: &DeviceOptions,
    stop: Arc<AtomicBool>,
    mut status: impl FnMut(&DeviceStatus),
) -> Result<DeviceReport, IpcError> {
    let hand = HandSampler::new(&options.path);
    let ports = DevicePorts::open(&options.prefix, &options.tool)?;
    if !ports.wait_for_daemon(&stop, &options.prefix)? {
        return Ok(DeviceReport::default());
    }
    let dt = 0.001;
    let ticks = (options.duration / dt).round() as u64;
    let mut handle = Device::new(options.spec, Hand::default(), hand.position_at(0.0));
    let mut tally = Tally {
        sent_at: vec![Instant::now(); 1 << 14],
        latencies: Vec::with_capacity(ticks as usize),
        window: Vec::with_capacity(2000),
        answered_up_to: 0,
        received: 0,
        max_force: 0.0,
        in_contact: 0,
        force: Vec3::zeros(),
        contacts: 0,
        flags: 0,
    };
    let mut trace = Vec::with_capacity(if options.keep_trace {
        ticks as usize
    } else {
        0
    });
    let mut sent = 0u64;
    let started = Instant::now();
    let mut deadline = started;

    for tick in 1..=ticks {
        if stop.load(Ordering::Relaxed) {
            break;
        }
        let t = tick as f64 * dt;
        let ((target, jaw), orientation) = hand.pose_at(t);
        let previous = hand.position_at(t - dt);
        handle.step(&target, &((target - previous) / dt), &tally.force, dt);
        let position = handle.measured_position();
        if !options.lockstep {
            deadline += Duration::from_millis(1);
            let now = Instant::now();
            if deadline > now {
                std::thread::sleep(deadline - now);
            }
        }
        let seq = tick;
        tally.mark_sent(seq);
        ports.send(ToolPoseV1 {
            seq,
            device_time_ns: monotonic_ns(),
            position: position.into(),
            orientation,
            jaw,
            buttons: 0,
            reserved: 0,
        })?;
        sent += 1;
        if options.lockstep {
            ports.await_answer(&mut tally, seq, &stop)?;
        } else {
            ports.take_answers(&mut tally)?;
        }
        if options.keep_trace {
            trace.push(TraceRow {
                seq,
                t,
                position,
                force: tally.force,
                contacts: tally.contacts,
                flags: tally.flags,
            });
        }
        if tick % 1000 == 0 {
            tally.window.sort_by(f64::total_cmp);
            status(&DeviceStatus {
                t,
                force: tally.force,
                contacts: tally.contacts,
                latency_p99_us: percentile(&tally.window, 0.99),
            });
            tally.window.clear();
        }
    }
    ports.collect_last(&mut tally)?;
    let mut latencies = tally.latencies;
    latencies.sort_by(f64::total_cmp);
    Ok(DeviceReport {
        poses_sent: sent,
        feedback_received: tally.received,
        latencies_us: latencies,
        max_force: tally.max_force,
        answers_in_contact: tally.in_contact,
        seconds: started.elapsed().as_secs_f64(),
        trace,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn palpation_throughout_keeps_pressing_where_four_presses_stop() {
        let at = Vec3::new(0.01, -0.02, 0.05);
        // The bottom of each press (half a second into each second from 0.5 s on) is 4 mm below
        // the surface point; between presses the hand hovers 3 cm above it.
        for t in [1.0, 2.0, 4.0] {
            for motion in [Motion::Palpate, Motion::PalpateThroughout] {
                let z = built_in_target(motion, &at, t, 1).z - at.z;
                assert!((z + 0.004).abs() < 1e-12, "{motion:?} at {t} s: {z}");
            }
        }
        for t in [5.0, 17.0, 59.0] {
            let four = built_in_target(Motion::Palpate, &at, t, 1) - at;
            let throughout = built_in_target(Motion::PalpateThroughout, &at, t, 1) - at;
            assert!(
                (four.z - 0.03).abs() < 1e-12,
                "four presses at {t} s: {four:?}"
            );
            assert!(
                (throughout.z + 0.004).abs() < 1e-12,
                "throughout at {t} s: {throughout:?}"
            );
            assert_eq!((throughout.x, throughout.y), (0.0, 0.0));
        }
        // A scene's non-grasping tools palpate throughout.
        let scene = crate::scene::built_in_scene("laparoscopy")
            .unwrap()
            .unwrap();
        let devices = devices_for_scene(&scene, "t", 60.0);
        let probe = devices.iter().find(|d| d.tool == "probe").unwrap();
        assert!(matches!(
            probe.path,
            HandPath::BuiltIn {
                motion: Motion::PalpateThroughout,
                ..
            }
        ));
        // The grasper holds what it took from 1.5 s until a last put-down with a second to spare,
        // lifting it 2 cm every 5 s, then lets go and goes up within the run.
        let grasper = devices.iter().find(|d| d.tool == "grasper").unwrap();
        let HandPath::Script(keys) = &grasper.path else {
            panic!("the grasper follows keyframes");
        };
        let release = keys.iter().find(|k| k.t > 1.5 && k.jaw > 0.0).unwrap().t;
        assert!(release > 50.0 && release <= 59.0, "{release}");
        assert!(
            keys.iter()
                .all(|k| (1.5..release - 0.3).contains(&k.t) <= (k.jaw == 0.0))
        );
        let low = keys[2].pose.position_in_world.z;
        let lifts = keys
            .iter()
            .filter(|k| (k.pose.position_in_world.z - low - 0.02).abs() < 1e-12 && k.jaw == 0.0)
            .count();
        assert_eq!(
            lifts,
            2 * 11,
            "two keyframes up per lift, one lift every 5 s"
        );
        let last = keys.last().unwrap();
        assert!(last.t <= 60.0 && last.jaw > 0.0 && last.pose.position_in_world.z > low);
    }
}
