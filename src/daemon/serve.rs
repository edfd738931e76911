//! `palpa serve`: the 1 kHz simulation loop over shared memory.
//!
//! One named thread owns everything (iceoryx2 ports are not `Send`): it creates the services, then
//! ticks on absolute deadlines — sleep to shortly before the deadline, spin the rest — or, in lockstep,
//! once per received pose. Each tick: control requests; the newest pose of every externally driven
//! tool, checked ([`ToolInputState`]); the world step; feedback per tool; at display rate, a mesh
//! keyframe or delta per body; once per simulated second, the statistics. The tick allocates
//! nothing, takes no lock, writes no file and logs nothing; its compute time and wake-up lateness are
//! measured, and a tick whose compute exceeds the period is a synchronicity miss, counted and
//! published.
//!
//! Failure paths: an iceoryx2 operation that fails inside the loop (a receive, a send, a loan, a
//! connection update) is counted (`ipc_errors` in the statistics and the summary, the first one kept
//! for the log) and the loop goes on: a lost feedback is replaced by the next tick's, a lost mesh
//! message by the next keyframe. Only IPC failing on every tick for a second (or on every poll of a
//! lockstep wait for a second) stops the loop, which then returns its summary with
//! [`ServeSummary::fatal`] set, so the caller still finishes the recording. A tick on which the
//! divergence guard restored a body sets flag 4 on every tool's feedback, records one
//! `DIVERGENCE_GUARD` event per restored body (its name and the cause) and counts in `guard_events`.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::server::Server;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::{Node, PortFactory, ipc};

use crate::daemon::feedback_payload;
use crate::daemon::input::{InputLimits, ToolInputState};
use crate::daemon::sink::{RecordSink, event};
use crate::daemon::stats::LoopStats;
use crate::display::MeshSchedule;
use crate::ipc::payload::*;
use crate::ipc::services::*;
use crate::scene::Scene;
use crate::tool::ToolInput;
use crate::world::World;

/// How the daemon runs.
#[derive(Clone, Debug)]
pub struct ServeOptions {
    /// Service name prefix.
    pub prefix: String,
    /// Stop after this many simulated seconds (`None`: until stopped).
    pub duration: Option<f64>,
    /// Step once per received pose instead of by the clock.
    pub lockstep: bool,
    /// Ask for SCHED_FIFO, locked memory and a pinned core.
    pub realtime: bool,
    /// Mesh messages per second.
    pub display_rate_hz: f64,
    /// Seconds between periodic keyframes.
    pub keyframe_every_s: f64,
    /// Input checks.
    pub limits: InputLimits,
    /// Test hook: make the loop's IPC operations fail on purpose (see [`InjectedFaults`]).
    pub inject_ipc_faults: Option<InjectedFaults>,
}

/// IPC faults injected on purpose, to test that the daemon outlives transient errors and stops
/// cleanly (its recording finished) on persistent ones: every feedback send of the loop ticks
/// `from_tick .. from_tick + ticks` fails as if iceoryx2 had refused it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InjectedFaults {
    /// First loop tick (counted from 0, paused ticks included) that fails.
    pub from_tick: u64,
    /// Ticks that fail (`u64::MAX`: all from then on).
    pub ticks: u64,
}

impl Default for ServeOptions {
    fn default() -> Self {
        Self {
            prefix: "palpa".into(),
            duration: None,
            lockstep: false,
            realtime: false,
            display_rate_hz: 60.0,
            keyframe_every_s: 2.0,
            limits: InputLimits::default(),
            inject_ipc_faults: None,
        }
    }
}

/// What a run did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ServeSummary {
    /// Ticks of the loop, paused ones included.
    pub ticks: u64,
    /// Of them, ticks spent paused (the world not stepped).
    pub paused_ticks: u64,
    /// Ticks whose compute exceeded the period.
    pub synchronicity_misses: u64,
    /// Poses rejected.
    pub rejected_inputs: u64,
    /// Tools that went stale.
    pub disconnects: u64,
    /// Largest tick compute time (µs).
    pub compute_max_us: f64,
    /// Mean tick compute time (µs): the daemon's share of a round trip, pose read to feedback sent.
    pub compute_mean_us: f64,
    /// 99th percentile of the tick compute time over the whole run (µs, 1 µs resolution).
    pub compute_p99_us: f64,
    /// Ticks per 1 µs bin of compute time over the whole run (the last bin holds the longer ones).
    pub compute_histogram: Vec<u32>,
    /// Ticks per 1 µs bin of wake-up lateness over the whole run.
    pub lateness_histogram: Vec<u32>,
    /// Times the divergence guard restored a body (resets included).
    pub guard_events: u64,
    /// Ticks on which the divergence guard acted.
    pub guard_ticks: u64,
    /// IPC operations of the loop that failed (counted; the loop went on).
    pub ipc_errors: u64,
    /// The first IPC error of the run, if any.
    pub first_ipc_error: Option<String>,
    /// Why the loop stopped on its own when it could not go on (IPC failing on every tick for a
    /// second); `None` when it was stopped or reached its duration.
    pub fatal: Option<String>,
}

impl ServeSummary {
    /// The whole run's timing histograms as CSV: `bin_us,compute_ticks,lateness_ticks`, 1 µs bins
    /// (the last one holding the longer ticks), empty bins left out.
    pub fn timings_csv(&self) -> String {
        let mut csv = String::from("bin_us,compute_ticks,lateness_ticks\n");
        for (bin, (c, l)) in self
            .compute_histogram
            .iter()
            .zip(&self.lateness_histogram)
            .enumerate()
        {
            if *c > 0 || *l > 0 {
                csv.push_str(&format!("{bin},{c},{l}\n"));
            }
        }
        csv
    }
}

/// Applies the real-time requests one by one; returns a warning for each that was not granted.
fn setup_realtime() -> Vec<String> {
    let mut warnings = Vec::new();
    // SAFETY: plain system calls on the calling thread with valid arguments.
    unsafe {
        let param = libc::sched_param { sched_priority: 80 };
        if libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) != 0 {
            warnings.push(format!(
                "SCHED_FIFO not granted ({}); running with the normal scheduler",
                std::io::Error::last_os_error()
            ));
        }
        if libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) != 0 {
            warnings.push(format!(
                "memory not locked ({})",
                std::io::Error::last_os_error()
            ));
        }
        let cores = libc::sysconf(libc::_SC_NPROCESSORS_ONLN).max(1) as usize;
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(cores - 1, &mut set);
        if libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) != 0 {
            warnings.push(format!(
                "not pinned to core {} ({})",
                cores - 1,
                std::io::Error::last_os_error()
            ));
        }
    }
    warnings
}

/// The loop's IPC failures: counted, the first one kept (formatted once, into a buffer reserved at
/// start), and the streak of consecutive ticks with a failure, which decides when the daemon cannot
/// go on.
struct IpcErrors {
    total: u64,
    first: String,
    failed_this_tick: bool,
    streak: u64,
}

impl IpcErrors {
    fn new() -> Self {
        Self {
            total: 0,
            first: String::with_capacity(512),
            failed_this_tick: false,
            streak: 0,
        }
    }

    /// Counts `error` from `site`.
    fn note(&mut self, site: &str, error: &dyn core::fmt::Debug) {
        use std::fmt::Write;
        if self.total == 0 {
            let _ = write!(self.first, "{site}: {error:?}");
        }
        self.total += 1;
        self.failed_this_tick = true;
    }

    /// The value of `result`, or `None` with the error counted.
    fn ok<T, E: core::fmt::Debug>(&mut self, site: &str, result: Result<T, E>) -> Option<T> {
        match result {
            Ok(v) => Some(v),
            Err(e) => {
                self.note(site, &e);
                None
            }
        }
    }

    /// Closes a tick; returns the number of consecutive ticks that had a failure.
    fn end_tick(&mut self) -> u64 {
        self.streak = if self.failed_this_tick {
            self.streak + 1
        } else {
            0
        };
        self.failed_this_tick = false;
        self.streak
    }
}

fn active_system_bits(world: &World) -> u32 {
    let s = world.systems();
    let mut bits = 0;
    for (on, bit) in [
        (s.gravity, SYSTEM_GRAVITY),
        (s.air_viscosity, SYSTEM_AIR_VISCOSITY),
        (s.obstacle_contact, SYSTEM_OBSTACLE_CONTACT),
        (s.obstacle_friction, SYSTEM_OBSTACLE_FRICTION),
        (s.rigid_motion, SYSTEM_RIGID_COMPONENTS),
        (s.tool_contact, SYSTEM_TOOL_CONTACT),
        (s.body_contact, SYSTEM_BODY_CONTACT),
    ] {
        if on {
            bits |= bit;
        }
    }
    bits
}

/// Runs the daemon on the calling thread until `stop` is set or the duration is reached.
pub fn serve(
    scene: &Scene,
    options: &ServeOptions,
    stop: Arc<AtomicBool>,
    sink: &RecordSink,
) -> Result<ServeSummary, IpcError> {
    if options.realtime {
        for warning in setup_realtime() {
            eprintln!("palpa serve: warning: {warning}");
        }
    }
    let node = create_node()?;
    let mut daemon = Daemon::new(&node, scene, options, sink)?;
    let dt = daemon.dt;
    let max_ticks = options.duration.map(|d| (d / dt).round() as u64);
    let period = Duration::from_secs_f64(dt);
    let mut deadline = Instant::now() + period;
    loop {
        if stop.load(Ordering::Relaxed) || max_ticks.is_some_and(|m| daemon.world.tick >= m) {
            break;
        }
        // Wait for this tick's turn.
        let lateness_us = if options.lockstep && !daemon.ports.ipc_tools.is_empty() {
            daemon.wait_for_a_pose(&stop);
            if stop.load(Ordering::Relaxed) || daemon.summary.fatal.is_some() {
                break;
            }
            0.0
        } else {
            wait_until(deadline)
        };
        let started = Instant::now();
        daemon.answer_control();
        daemon.take_poses();
        let (stepped, diverged) = daemon.step();
        daemon.send_feedback(stepped, diverged);
        if stepped {
            daemon.send_meshes();
        }
        daemon.close_tick(started.elapsed().as_secs_f64() * 1e6, lateness_us);
        if daemon.summary.fatal.is_some() {
            break;
        }
        deadline += period;
        let now = Instant::now();
        if now > deadline + period * 10 {
            // Far behind (a stall): start again from now rather than racing through missed deadlines.
            deadline = now + period;
        }
    }
    daemon.sink.session_end(daemon.world.tick);
    Ok(daemon.finish())
}

/// Sleeps to shortly before `deadline`, spins the rest; returns how late it woke (µs).
fn wait_until(deadline: Instant) -> f64 {
    let spin = Duration::from_micros(200);
    let now = Instant::now();
    if deadline > now + spin {
        std::thread::sleep(deadline - now - spin);
    }
    while Instant::now() < deadline {
        std::hint::spin_loop();
    }
    Instant::now()
        .saturating_duration_since(deadline)
        .as_secs_f64()
        * 1e6
}

/// The daemon's iceoryx2 ports for one run.
struct Ports {
    /// Indices of the externally driven tools; their pose subscribers and feedback publishers, in
    /// the same order.
    ipc_tools: Vec<usize>,
    poses: Vec<Subscriber<ipc::Service, ToolPoseV1, ()>>,
    feedback: Vec<Publisher<ipc::Service, ToolFeedbackV1, ()>>,
    stats: Publisher<ipc::Service, StatsV1, ()>,
    meshes: Publisher<ipc::Service, [u8], MeshHeaderV1>,
    control: Server<ipc::Service, ControlRequestV1, (), ControlResponseV1, ()>,
}

impl Ports {
    /// Creates the services and ports of `world`'s run; each tool's feedback starts stale.
    fn open(
        node: &Node<ipc::Service>,
        world: &World,
        prefix: &str,
        max_mesh_bytes: usize,
    ) -> Result<Self, IpcError> {
        let mut poses = Vec::new();
        let mut feedback = Vec::new();
        let mut ipc_tools = Vec::new();
        for (index, tool) in world.tools.iter().enumerate() {
            if matches!(tool.input, ToolInput::Ipc) {
                let pose = pose_service(node, prefix, &tool.name)?;
                let feedback_of = feedback_service(node, prefix, &tool.name)?;
                poses.push(
                    pose.subscriber_builder()
                        .create()
                        .map_err(|e| IpcError::port(pose.name(), "subscriber", e))?,
                );
                let publisher = feedback_of
                    .publisher_builder()
                    .create()
                    .map_err(|e| IpcError::port(feedback_of.name(), "publisher", e))?;
                publisher
                    .send_copy(ToolFeedbackV1 {
                        flags: FEEDBACK_STALE,
                        ..ToolFeedbackV1::default()
                    })
                    .map_err(|e| IpcError::transfer(feedback_of.name(), "send", e))?;
                feedback.push(publisher);
                ipc_tools.push(index);
            }
        }
        let stats = stats_service(node, prefix)?;
        let meshes = mesh_service(node, prefix)?;
        let control = control_service(node, prefix)?;
        Ok(Self {
            ipc_tools,
            poses,
            feedback,
            stats: stats
                .publisher_builder()
                .create()
                .map_err(|e| IpcError::port(stats.name(), "publisher", e))?,
            meshes: meshes
                .publisher_builder()
                .initial_max_slice_len(max_mesh_bytes)
                .create()
                .map_err(|e| IpcError::port(meshes.name(), "publisher", e))?,
            control: control
                .server_builder()
                .create()
                .map_err(|e| IpcError::port(control.name(), "server", e))?,
        })
    }
}

/// The loop's state from tick to tick: the world, the tools' inputs, the display schedule, the
/// statistics and the summary.
struct Daemon<'a> {
    scene: &'a Scene,
    options: &'a ServeOptions,
    sink: &'a RecordSink,
    ports: Ports,
    world: World,
    /// Bodies the recording knows of (a transection adds some).
    known_bodies: usize,
    inputs: Vec<ToolInputState>,
    /// Per external tool, the sequence number and device time of the pose last taken.
    echo: Vec<(u64, u64)>,
    meshes: MeshSchedule,
    /// The explicit scheme's stability bound, which depends on masses and stiffnesses only:
    /// computed once (again after a reset).
    stability_margin: f64,
    /// This window's statistics, and the whole run's.
    stats: LoopStats,
    whole_run: LoopStats,
    stats_out: StatsV1,
    summary: ServeSummary,
    errors: IpcErrors,
    paused: bool,
    /// The daemon's receive clock: loop ticks since start, paused ones included (in lockstep, one
    /// per pose). Input checks measure time on it, never on the bridges' time stamps.
    clock: u64,
    dt: f64,
    /// IPC failing on every tick for a second (or every poll of a lockstep wait for a second of
    /// wall time) is what the daemon cannot go on from; anything shorter is counted and outlived.
    fatal_streak: u64,
}

impl<'a> Daemon<'a> {
    fn new(
        node: &Node<ipc::Service>,
        scene: &'a Scene,
        options: &'a ServeOptions,
        sink: &'a RecordSink,
    ) -> Result<Self, IpcError> {
        let world = World::from_scene(scene);
        let meshes = MeshSchedule::new(&world, options.display_rate_hz, options.keyframe_every_s);
        let ports = Ports::open(node, &world, &options.prefix, meshes.max_message_bytes())?;
        let externals = ports.ipc_tools.len();
        let dt = world.params.dt;
        Ok(Self {
            scene,
            options,
            sink,
            ports,
            known_bodies: world.bodies.len(),
            inputs: vec![ToolInputState::default(); externals],
            echo: vec![(0u64, 0u64); externals],
            meshes,
            stability_margin: least_stability_margin(&world),
            world,
            stats: LoopStats::default(),
            whole_run: LoopStats::default(),
            stats_out: StatsV1::default(),
            summary: ServeSummary::default(),
            errors: IpcErrors::new(),
            paused: false,
            clock: 0,
            dt,
            fatal_streak: ((1.0 / dt).round() as u64).max(1),
        })
    }

    /// In lockstep: waits until a pose is there, or `stop` is set, or polling has failed for a
    /// second (then `summary.fatal` is set).
    fn wait_for_a_pose(&mut self, stop: &AtomicBool) {
        let fatal_wait = Duration::from_secs(1);
        let mut polls = 0u32;
        let mut failing_since: Option<Instant> = None;
        loop {
            if stop.load(Ordering::Relaxed) {
                return;
            }
            let mut any = false;
            let mut failed = false;
            for s in &self.ports.poses {
                match s.has_samples() {
                    Ok(has) => any |= has,
                    Err(e) => {
                        self.errors.note("pose subscriber (has_samples)", &e);
                        failed = true;
                    }
                }
            }
            if any {
                return;
            }
            if failed {
                let since = *failing_since.get_or_insert_with(Instant::now);
                if since.elapsed() > fatal_wait {
                    self.summary.fatal = Some(format!(
                        "iceoryx2 failed on every poll for pose samples for {} s",
                        fatal_wait.as_secs()
                    ));
                    return;
                }
            } else {
                failing_since = None;
            }
            // While idle, let late subscribers (a bridge that starts after us) receive the last
            // feedback, so they can tell the daemon is up.
            polls += 1;
            if polls % 500 == 0 {
                for publisher in &self.ports.feedback {
                    self.errors.ok(
                        "feedback publisher (connections)",
                        publisher.update_connections(),
                    );
                }
            }
            std::thread::sleep(Duration::from_micros(20));
        }
    }

    /// Answers the control requests (reset, pause, resume, keyframe).
    fn answer_control(&mut self) {
        while let Some(request) = self
            .errors
            .ok("control server (receive)", self.ports.control.receive())
            .flatten()
        {
            let command = request.payload().command;
            let status = match command {
                CONTROL_RESET => {
                    self.sink.event(self.world.tick, event::RESET, None);
                    self.world = World::from_scene(self.scene);
                    self.known_bodies = self.world.bodies.len();
                    self.meshes.reset(&self.world);
                    self.stability_margin = least_stability_margin(&self.world);
                    // Each tool's history is forgotten (it reappears with its next good pose, as
                    // a bridge that connects), its totals kept: the statistics count the session.
                    for input in &mut self.inputs {
                        let (rejected, disconnects) = (input.rejected, input.disconnects);
                        *input = ToolInputState::default();
                        input.rejected = rejected;
                        input.disconnects = disconnects;
                    }
                    0
                }
                CONTROL_PAUSE => {
                    self.sink.event(self.world.tick, event::PAUSE, None);
                    self.paused = true;
                    0
                }
                CONTROL_RESUME => {
                    self.sink.event(self.world.tick, event::RESUME, None);
                    self.paused = false;
                    0
                }
                CONTROL_KEYFRAME => {
                    self.meshes.request_keyframe();
                    0
                }
                _ => -1,
            };
            self.errors.ok(
                "control server (respond)",
                request.send_copy(ControlResponseV1 {
                    command,
                    status,
                    tick: self.world.tick,
                }),
            );
        }
    }

    /// Takes the newest pose of every external tool, checked; marks the tools gone stale.
    fn take_poses(&mut self) {
        for (k, &tool_index) in self.ports.ipc_tools.iter().enumerate() {
            let mut newest = None;
            while let Some(sample) = self
                .errors
                .ok("pose subscriber (receive)", self.ports.poses[k].receive())
                .flatten()
            {
                newest = Some(*sample.payload());
            }
            if let Some(pose) = newest {
                match self.inputs[k].offer(&pose, self.clock, self.dt, &self.options.limits) {
                    Ok((tool_pose, jaw)) => {
                        self.world.tools[tool_index].set_target(tool_pose, jaw);
                        self.echo[k] = (pose.seq, pose.device_time_ns);
                        self.sink
                            .input(self.world.tick, tool_index, &pose, monotonic_ns());
                    }
                    Err(_) => {
                        self.sink
                            .event(self.world.tick, event::INPUT_REJECTED, Some(tool_index))
                    }
                }
            }
            if self.inputs[k].update_staleness(self.clock, &self.options.limits) {
                self.world.tools[tool_index].deactivate();
                self.sink
                    .event(self.world.tick, event::DISCONNECT, Some(tool_index));
            }
        }
    }

    /// Steps the world unless paused; records added bodies and what the divergence guard did.
    /// Returns (stepped, the guard acted).
    fn step(&mut self) -> (bool, bool) {
        let stepped = !self.paused;
        if stepped {
            self.world.step();
        } else {
            self.summary.paused_ticks += 1;
        }
        // The divergence guard restored a body in this step: flag every tool's feedback, record
        // which body and why, count it.
        self.sink.bodies_added(&self.world, &mut self.known_bodies);
        let diverged = stepped && crate::daemon::guard_acted(&self.world);
        if diverged {
            self.summary.guard_ticks += 1;
            for (b, guard) in self.world.guards.iter().enumerate() {
                if guard.acted {
                    self.summary.guard_events += 1;
                    if let Some(cause) = guard.last_cause {
                        self.sink.guard(self.world.tick, b, cause);
                    }
                }
            }
        }

        (stepped, diverged)
    }

    /// Sends each external tool its feedback (flagged when the guard acted), and records it.
    fn send_feedback(&mut self, stepped: bool, diverged: bool) {
        let faulty = self
            .options
            .inject_ipc_faults
            .is_some_and(|f| self.clock >= f.from_tick && self.clock - f.from_tick < f.ticks);
        for (k, &tool_index) in self.ports.ipc_tools.iter().enumerate() {
            let mut payload = feedback_payload(
                &self.world.tools[tool_index],
                self.world.tick,
                self.inputs[k].connected,
                self.inputs[k].rejected_this_tick,
                self.echo[k],
            );
            if diverged {
                payload.flags |= FEEDBACK_DIVERGED;
            }
            if faulty {
                self.errors
                    .note("feedback publisher (send)", &"injected fault");
            } else {
                self.errors.ok(
                    "feedback publisher (send)",
                    self.ports.feedback[k].send_copy(payload),
                );
            }
            if stepped {
                self.sink.feedback(tool_index, &payload);
                self.inputs[k].rejected_this_tick = false;
            }
        }
    }

    /// At display rate, a mesh keyframe or delta per body. A message iceoryx2 refuses is lost to
    /// the displays (they resynchronise on the next keyframe, or ask for one); it is still
    /// recorded, as the daemon produced it.
    fn send_meshes(&mut self) {
        let produced = self.meshes.produce(&self.world, |header, bytes| {
            if let Some(mut sample) = self.errors.ok(
                "mesh publisher (loan)",
                self.ports.meshes.loan_slice_uninit(bytes.len()),
            ) {
                *sample.user_header_mut() = *header;
                self.errors.ok(
                    "mesh publisher (send)",
                    sample.write_from_slice(bytes).send(),
                );
            }
            self.sink.mesh(header, bytes);
            Ok::<(), std::convert::Infallible>(())
        });
        let Ok(()) = produced;
    }

    /// The tick's compute time and wake-up lateness into the statistics (published once per
    /// window); the tick counted; `summary.fatal` set when IPC failed on too many ticks in a row.
    fn close_tick(&mut self, compute_us: f64, lateness_us: f64) {
        let period_us = self.dt * 1e6;
        self.stats.record(compute_us, lateness_us, period_us);
        self.whole_run.record(compute_us, lateness_us, period_us);
        if compute_us > period_us {
            self.sink
                .event(self.world.tick, event::SYNCHRONICITY_MISS, None);
        }
        self.summary.compute_max_us = self.summary.compute_max_us.max(compute_us);
        self.summary.compute_mean_us += compute_us;
        if self.stats.window_ticks() >= 1000 {
            self.stats.close_window(&mut self.stats_out);
            self.stats_out.tick = self.world.tick;
            self.stats_out.rejected_inputs = self.inputs.iter().map(|i| i.rejected).sum();
            self.stats_out.disconnects = self.inputs.iter().map(|i| i.disconnects).sum();
            self.stats_out.active_systems = active_system_bits(&self.world);
            self.stats_out.tools_connected = self
                .ports
                .ipc_tools
                .iter()
                .zip(&self.inputs)
                .filter(|(_, i)| i.connected)
                .fold(0u32, |bits, (&t, _)| bits | (1u32 << t.min(31)));
            self.stats_out.paused = self.paused as u32;
            self.stats_out.dropped_records = self.sink.dropped().min(u32::MAX as u64) as u32;
            self.stats_out.stability_margin = self.stability_margin;
            self.stats_out.guard_events = self.summary.guard_events;
            self.stats_out.ipc_errors = self.errors.total;
            self.errors.ok(
                "stats publisher (send)",
                self.ports.stats.send_copy(self.stats_out),
            );
            self.sink.stats(&self.stats_out);
        }
        self.summary.ticks += 1;
        self.clock += 1;
        if self.errors.end_tick() >= self.fatal_streak {
            self.summary.fatal = Some(format!(
                "iceoryx2 failed on each of the last {} ticks",
                self.fatal_streak
            ));
        }
    }

    /// The run's summary.
    fn finish(mut self) -> ServeSummary {
        self.summary.compute_mean_us /= self.summary.ticks.max(1) as f64;
        self.summary.compute_histogram = self.whole_run.compute_histogram().to_vec();
        self.summary.lateness_histogram = self.whole_run.lateness_histogram().to_vec();
        let mut overall = StatsV1::default();
        self.whole_run.close_window(&mut overall);
        self.summary.compute_p99_us = overall.compute_p99_us;
        self.summary.synchronicity_misses = self.stats.synchronicity_misses;
        self.summary.rejected_inputs = self.inputs.iter().map(|i| i.rejected).sum();
        self.summary.disconnects = self.inputs.iter().map(|i| i.disconnects).sum();
        self.summary.ipc_errors = self.errors.total;
        if self.errors.total > 0 {
            self.summary.first_ipc_error = Some(self.errors.first.clone());
        }
        self.summary
    }
}

/// The least stability margin of `world`'s bodies.
fn least_stability_margin(world: &World) -> f64 {
    world
        .stability_margins()
        .iter()
        .map(|m| m.margin)
        .fold(f64::INFINITY, f64::min)
}
