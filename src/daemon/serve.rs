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

use iceoryx2::port::update_connections::UpdateConnections;

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
    /// Ticks stepped.
    pub ticks: u64,
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
    let mut world = World::from_scene(scene);
    let mut known_bodies = world.bodies.len();
    let dt = world.params.dt;

    // Ports of the externally driven tools, by tool index.
    let mut pose_subscribers = Vec::new();
    let mut feedback_publishers = Vec::new();
    let mut ipc_tools = Vec::new();
    for (index, tool) in world.tools.iter().enumerate() {
        if matches!(tool.input, ToolInput::Ipc) {
            let pose = pose_service(&node, &options.prefix, &tool.name)?;
            let feedback = feedback_service(&node, &options.prefix, &tool.name)?;
            pose_subscribers.push(pose.subscriber_builder().create()?);
            let publisher = feedback.publisher_builder().create()?;
            publisher.send_copy(ToolFeedbackV1 {
                flags: FEEDBACK_STALE,
                ..ToolFeedbackV1::default()
            })?;
            feedback_publishers.push(publisher);
            ipc_tools.push(index);
        }
    }
    let mut inputs = vec![ToolInputState::default(); ipc_tools.len()];
    let mut echo = vec![(0u64, 0u64); ipc_tools.len()];

    let stats_publisher = stats_service(&node, &options.prefix)?
        .publisher_builder()
        .create()?;
    let mut meshes = MeshSchedule::new(&world, options.display_rate_hz, options.keyframe_every_s);
    let mesh_publisher = mesh_service(&node, &options.prefix)?
        .publisher_builder()
        .initial_max_slice_len(meshes.max_message_bytes())
        .create()?;
    let control_server = control_service(&node, &options.prefix)?
        .server_builder()
        .create()?;

    let max_ticks = options.duration.map(|d| (d / dt).round() as u64);
    let period = Duration::from_secs_f64(dt);
    let period_us = dt * 1e6;
    // IPC failing on every tick for a second (or every poll of a lockstep wait for a second of wall
    // time) is what the daemon cannot go on from; anything shorter is counted and outlived.
    let fatal_streak = ((1.0 / dt).round() as u64).max(1);
    let fatal_wait = Duration::from_secs(1);
    // The bound depends on masses and stiffnesses only: computed once (again after a reset).
    let mut stability_margin = world
        .stability_margins()
        .iter()
        .map(|m| m.margin)
        .fold(f64::INFINITY, f64::min);
    let mut stats = LoopStats::default();
    let mut whole_run = LoopStats::default();
    let mut stats_out = StatsV1::default();
    let mut summary = ServeSummary::default();
    let mut errors = IpcErrors::new();
    let mut paused = false;
    // The daemon's receive clock: loop ticks since start, paused ones included (in lockstep, one
    // per pose). Input checks measure time on it, never on the bridges' time stamps.
    let mut clock: u64 = 0;
    let mut deadline = Instant::now() + period;
    let spin = Duration::from_micros(200);

    loop {
        if stop.load(Ordering::Relaxed) || max_ticks.is_some_and(|m| world.tick >= m) {
            break;
        }
        // Wait for this tick's turn.
        let lateness_us = if options.lockstep && !ipc_tools.is_empty() {
            let mut polls = 0u32;
            let mut failing_since: Option<Instant> = None;
            'wait: loop {
                if stop.load(Ordering::Relaxed) {
                    break 'wait;
                }
                let mut any = false;
                let mut failed = false;
                for s in &pose_subscribers {
                    match s.has_samples() {
                        Ok(has) => any |= has,
                        Err(e) => {
                            errors.note("pose subscriber (has_samples)", &e);
                            failed = true;
                        }
                    }
                }
                if any {
                    break 'wait;
                }
                if failed {
                    let since = *failing_since.get_or_insert_with(Instant::now);
                    if since.elapsed() > fatal_wait {
                        summary.fatal = Some(format!(
                            "iceoryx2 failed on every poll for pose samples for {} s",
                            fatal_wait.as_secs()
                        ));
                        break 'wait;
                    }
                } else {
                    failing_since = None;
                }
                // While idle, let late subscribers (a bridge that starts after us) receive the last
                // feedback, so they can tell the daemon is up.
                polls += 1;
                if polls % 500 == 0 {
                    for publisher in &feedback_publishers {
                        errors.ok(
                            "feedback publisher (connections)",
                            publisher.update_connections(),
                        );
                    }
                }
                std::thread::sleep(Duration::from_micros(20));
            }
            if stop.load(Ordering::Relaxed) || summary.fatal.is_some() {
                break;
            }
            0.0
        } else {
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
        };
        let started = Instant::now();
        let faulty = options
            .inject_ipc_faults
            .is_some_and(|f| clock >= f.from_tick && clock - f.from_tick < f.ticks);

        // Control.
        while let Some(request) = errors
            .ok("control server (receive)", control_server.receive())
            .flatten()
        {
            let command = request.payload().command;
            let status = match command {
                CONTROL_RESET => {
                    sink.event(world.tick, event::RESET, None);
                    world = World::from_scene(scene);
                    known_bodies = world.bodies.len();
                    meshes.reset(&world);
                    stability_margin = world
                        .stability_margins()
                        .iter()
                        .map(|m| m.margin)
                        .fold(f64::INFINITY, f64::min);
                    for input in &mut inputs {
                        *input = ToolInputState::default();
                    }
                    0
                }
                CONTROL_PAUSE => {
                    sink.event(world.tick, event::PAUSE, None);
                    paused = true;
                    0
                }
                CONTROL_RESUME => {
                    sink.event(world.tick, event::RESUME, None);
                    paused = false;
                    0
                }
                CONTROL_KEYFRAME => {
                    meshes.request_keyframe();
                    0
                }
                _ => -1,
            };
            errors.ok(
                "control server (respond)",
                request.send_copy(ControlResponseV1 {
                    command,
                    status,
                    tick: world.tick,
                }),
            );
        }

        // Newest pose of every external tool.
        for (k, &tool_index) in ipc_tools.iter().enumerate() {
            let mut newest = None;
            while let Some(sample) = errors
                .ok("pose subscriber (receive)", pose_subscribers[k].receive())
                .flatten()
            {
                newest = Some(*sample.payload());
            }
            inputs[k].rejected_this_tick = false;
            if let Some(pose) = newest {
                match inputs[k].offer(&pose, clock, dt, &options.limits) {
                    Ok((tool_pose, jaw)) => {
                        world.tools[tool_index].set_target(tool_pose, jaw);
                        echo[k] = (pose.seq, pose.device_time_ns);
                        sink.input(world.tick, tool_index, &pose, monotonic_ns());
                    }
                    Err(_) => sink.event(world.tick, event::INPUT_REJECTED, Some(tool_index)),
                }
            }
            if inputs[k].update_staleness(clock, &options.limits) {
                world.tools[tool_index].deactivate();
                sink.event(world.tick, event::DISCONNECT, Some(tool_index));
            }
        }

        let stepped = !paused;
        if stepped {
            world.step();
        }
        // The divergence guard restored a body in this step: flag every tool's feedback, record
        // which body and why, count it.
        sink.bodies_added(&world, &mut known_bodies);
        let diverged = stepped && crate::daemon::guard_acted(&world);
        if diverged {
            summary.guard_ticks += 1;
            for (b, guard) in world.guards.iter().enumerate() {
                if guard.acted {
                    summary.guard_events += 1;
                    if let Some(cause) = guard.last_cause {
                        sink.guard(world.tick, b, cause);
                    }
                }
            }
        }

        // Feedback.
        for (k, &tool_index) in ipc_tools.iter().enumerate() {
            let mut payload = feedback_payload(
                &world.tools[tool_index],
                world.tick,
                inputs[k].connected,
                inputs[k].rejected_this_tick,
                echo[k],
            );
            if diverged {
                payload.flags |= FEEDBACK_DIVERGED;
            }
            if faulty {
                errors.note("feedback publisher (send)", &"injected fault");
            } else {
                errors.ok(
                    "feedback publisher (send)",
                    feedback_publishers[k].send_copy(payload),
                );
            }
            if stepped {
                sink.feedback(tool_index, &payload);
            }
        }

        // Display. A message iceoryx2 refuses is lost to the displays (they resynchronise on the
        // next keyframe, or ask for one); it is still recorded, as the daemon produced it.
        if stepped {
            let _ = meshes.produce(&world, |header, bytes| -> Result<(), ()> {
                if let Some(mut sample) = errors.ok(
                    "mesh publisher (loan)",
                    mesh_publisher.loan_slice_uninit(bytes.len()),
                ) {
                    *sample.user_header_mut() = *header;
                    errors.ok(
                        "mesh publisher (send)",
                        sample.write_from_slice(bytes).send(),
                    );
                }
                sink.mesh(header, bytes);
                Ok(())
            });
        }

        // Statistics.
        let compute_us = started.elapsed().as_secs_f64() * 1e6;
        stats.record(compute_us, lateness_us, period_us);
        whole_run.record(compute_us, lateness_us, period_us);
        if compute_us > period_us {
            sink.event(world.tick, event::SYNCHRONICITY_MISS, None);
        }
        summary.compute_max_us = summary.compute_max_us.max(compute_us);
        summary.compute_mean_us += compute_us;
        if stats.window_ticks() >= 1000 {
            stats.close_window(&mut stats_out);
            stats_out.tick = world.tick;
            stats_out.rejected_inputs = inputs.iter().map(|i| i.rejected).sum();
            stats_out.disconnects = inputs.iter().map(|i| i.disconnects).sum();
            stats_out.active_systems = active_system_bits(&world);
            stats_out.tools_connected = ipc_tools
                .iter()
                .zip(&inputs)
                .filter(|(_, i)| i.connected)
                .fold(0u32, |bits, (&t, _)| bits | (1u32 << t.min(31)));
            stats_out.paused = paused as u32;
            stats_out.dropped_records = sink.dropped().min(u32::MAX as u64) as u32;
            stats_out.stability_margin = stability_margin;
            stats_out.guard_events = summary.guard_events;
            stats_out.ipc_errors = errors.total;
            errors.ok(
                "stats publisher (send)",
                stats_publisher.send_copy(stats_out),
            );
            sink.stats(&stats_out);
        }
        summary.ticks += 1;
        clock += 1;
        if errors.end_tick() >= fatal_streak {
            summary.fatal = Some(format!(
                "iceoryx2 failed on each of the last {fatal_streak} ticks"
            ));
            break;
        }
        deadline += period;
        let now = Instant::now();
        if now > deadline + period * 10 {
            // Far behind (a stall): start again from now rather than racing through missed deadlines.
            deadline = now + period;
        }
    }
    summary.compute_mean_us /= summary.ticks.max(1) as f64;
    summary.compute_histogram = whole_run.compute_histogram().to_vec();
    summary.lateness_histogram = whole_run.lateness_histogram().to_vec();
    let mut overall = StatsV1::default();
    whole_run.close_window(&mut overall);
    summary.compute_p99_us = overall.compute_p99_us;
    summary.synchronicity_misses = stats.synchronicity_misses;
    summary.rejected_inputs = inputs.iter().map(|i| i.rejected).sum();
    summary.disconnects = inputs.iter().map(|i| i.disconnects).sum();
    summary.ipc_errors = errors.total;
    if errors.total > 0 {
        summary.first_ipc_error = Some(errors.first.clone());
    }
    Ok(summary)
}
