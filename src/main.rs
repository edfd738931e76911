//! The `palpa` command line: `run` steps a scene headless and writes a CSV trace, `check` validates a
//! scene and explains its stability under the paper's scheme. Without a scene path both use the
//! embedded default scene.

use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use palpa::daemon::values;
use palpa::scene::{BUILT_IN_SCENES, Scene, built_in_scene, default_scene, load_scene};
use palpa::trace::{
    write_feedback_header, write_feedback_rows, write_trace_header, write_trace_rows,
};
use palpa::world::World;

#[derive(Parser)]
#[command(
    name = "palpa",
    version,
    about = "Haptic-loop server for surgical training rigs"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Step a scene headless, as fast as possible, and optionally write a CSV trace.
    Run {
        /// Scene file (TOML), or a built-in scene by name (`organ`, `laparoscopy`); the embedded default
        /// scene when omitted.
        scene: Option<PathBuf>,
        /// Simulated duration (s).
        #[arg(long, default_value_t = 2.0, allow_hyphen_values = true, value_parser = values::non_negative)]
        duration: f64,
        /// Write a CSV trace here, one row per traced tick per body.
        #[arg(long)]
        trace: Option<PathBuf>,
        /// Trace every N-th tick (tick 0 is always traced).
        #[arg(long, default_value_t = 1, allow_hyphen_values = true, value_parser = values::count)]
        trace_every: u64,
        /// Write the tools' feedback here, one row per tick per tool.
        #[arg(long)]
        feedback: Option<PathBuf>,
        /// Record the session to this MCAP file.
        #[cfg(feature = "record")]
        #[arg(long)]
        record: Option<PathBuf>,
    },
    /// Validate a scene and print a summary: bodies, systems switched on, stability margin.
    Check {
        /// Scene file (TOML), or a built-in scene by name (`organ`, `laparoscopy`); the embedded default
        /// scene when omitted.
        scene: Option<PathBuf>,
    },
    /// Run the 1 kHz simulation daemon: tool poses in, feedback and mesh deltas out, over iceoryx2.
    #[cfg(feature = "ipc")]
    Serve(ServeArgs),
    /// Start the daemon and simulated devices together (two processes) and palpate the default organ,
    /// or drive every IPC tool of another scene (`--scene laparoscopy`: a probe and a grasper).
    #[cfg(feature = "ipc")]
    Demo {
        /// Seconds of palpation.
        #[arg(long, default_value_t = 6.0, allow_hyphen_values = true, value_parser = values::positive)]
        duration: f64,
        /// Scene file (TOML), or a built-in scene by name (`organ`, `laparoscopy`).
        #[arg(long, default_value = "organ")]
        scene: String,
        /// Run the daemon with `--rt` (SCHED_FIFO, locked memory, a pinned core).
        #[arg(long)]
        rt: bool,
        /// Have the daemon write its tick-time histograms to FILE.csv when it stops (see `palpa
        /// serve --timings`).
        #[arg(long, value_name = "FILE.csv")]
        timings: Option<PathBuf>,
        /// Have the daemon record the session to FILE.mcap (see `palpa serve --record`; check it
        /// with `palpa-replay FILE.mcap --verify`).
        #[cfg(feature = "record")]
        #[arg(long, value_name = "FILE.mcap")]
        record: Option<PathBuf>,
        /// Show the session live to Foxglove on [HOST:]PORT (see `palpa serve --live`).
        #[cfg(feature = "live")]
        #[arg(long, value_name = "[HOST:]PORT", value_parser = palpa::record::live::address_argument)]
        live: Option<String>,
    },
}

/// Options of `palpa serve`.
#[cfg(feature = "ipc")]
#[derive(clap::Args)]
struct ServeArgs {
    /// Scene file (TOML), or a built-in scene by name (`organ`, `laparoscopy`); the embedded default
    /// scene when omitted.
    scene: Option<PathBuf>,
    /// Prefix of every service name, so rigs and tests never collide.
    #[arg(long, default_value = "palpa")]
    prefix: String,
    /// Stop after this many simulated seconds.
    #[arg(long, allow_hyphen_values = true, value_parser = values::non_negative)]
    duration: Option<f64>,
    /// Step once per received pose instead of by the clock (tests, replay, pure-compute benchmarks).
    #[arg(long)]
    lockstep: bool,
    /// Ask for SCHED_FIFO, locked memory and a pinned core (falls back with a warning).
    #[arg(long)]
    rt: bool,
    /// Mesh messages per second.
    #[arg(long, default_value_t = 60.0, allow_hyphen_values = true, value_parser = values::positive)]
    display_rate: f64,
    /// Seconds between periodic mesh keyframes.
    #[arg(long, default_value_t = 2.0, allow_hyphen_values = true, value_parser = values::positive)]
    keyframe_every: f64,
    /// Fastest believable tool motion (m/s); faster jumps are rejected.
    #[arg(long, default_value_t = 10.0, allow_hyphen_values = true, value_parser = values::positive)]
    max_speed: f64,
    /// Milliseconds without a good pose before a tool is marked disconnected.
    #[arg(long, default_value_t = 100, allow_hyphen_values = true, value_parser = values::count)]
    stale_after_ms: u64,
    /// (tests) Make every feedback send of loop ticks FROM..FROM+COUNT fail, as if iceoryx2 had
    /// refused it ("FROM:COUNT", COUNT may be "all").
    #[arg(long, hide = true, value_parser = parse_faults)]
    inject_ipc_faults: Option<palpa::daemon::serve::InjectedFaults>,
    /// When stopped, write the whole run's tick timing histograms here (CSV: bin_us, compute_ticks,
    /// lateness_ticks; 1 µs bins, the last bin holding the longer ones; empty bins left out).
    #[arg(long)]
    timings: Option<PathBuf>,
    /// Record the session to this MCAP file.
    #[cfg(feature = "record")]
    #[arg(long)]
    record: Option<PathBuf>,
    /// Show the session live to Foxglove: a WebSocket server on [HOST:]PORT (host 127.0.0.1 when
    /// omitted; 0.0.0.0 for other machines; port 0 picks a free one). Open ws://HOST:PORT in
    /// Foxglove ("Open connection", Foxglove WebSocket).
    #[cfg(feature = "live")]
    #[arg(long, value_name = "[HOST:]PORT", value_parser = palpa::record::live::address_argument)]
    live: Option<String>,
}

/// `FROM:COUNT` (COUNT a number or `all`) of `--inject-ipc-faults`.
#[cfg(feature = "ipc")]
fn parse_faults(text: &str) -> Result<palpa::daemon::serve::InjectedFaults, String> {
    let (from, ticks) = text
        .split_once(':')
        .ok_or_else(|| format!("expected FROM:COUNT, found {text}"))?;
    let from_tick = from
        .parse()
        .map_err(|_| format!("expected FROM:COUNT, found {text}"))?;
    let ticks = match ticks {
        "all" => u64::MAX,
        n => values::count(n)?,
    };
    Ok(palpa::daemon::serve::InjectedFaults { from_tick, ticks })
}

/// Exit status of `palpa run` when the divergence guard had to restore a body during the run (the
/// run itself completed, its outputs are written).
const EXIT_GUARD_ACTED: i32 = 3;

fn main() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Run {
            scene,
            duration,
            trace,
            trace_every,
            feedback,
            #[cfg(feature = "record")]
            record,
        } => run(
            scene.as_deref(),
            duration,
            trace.as_deref(),
            trace_every,
            feedback.as_deref(),
            #[cfg(feature = "record")]
            record.as_deref(),
            #[cfg(not(feature = "record"))]
            None,
        ),
        Command::Check { scene } => {
            // `palpa check … | head`: a reader that closes the pipe ends the listing quietly, as
            // for other listing tools, not with a panic in `println!`. (Only here: the commands
            // that write files and recordings keep Rust's default and finish them.)
            #[cfg(feature = "ipc")]
            // SAFETY: sets the process's disposition of SIGPIPE back to the default, before any
            // thread of this command is started; no handler is involved.
            unsafe {
                libc::signal(libc::SIGPIPE, libc::SIG_DFL);
            }
            check(scene.as_deref())
        }
        #[cfg(feature = "ipc")]
        Command::Serve(args) => serve(args),
        #[cfg(feature = "ipc")]
        Command::Demo {
            duration,
            scene,
            rt,
            timings,
            #[cfg(feature = "record")]
            record,
            #[cfg(feature = "live")]
            live,
        } => demo(
            duration,
            &scene,
            DemoDaemon {
                rt,
                timings: timings.as_deref(),
                #[cfg(feature = "record")]
                record: record.as_deref(),
                #[cfg(not(feature = "record"))]
                record: None,
                #[cfg(feature = "live")]
                live: live.as_deref(),
                #[cfg(not(feature = "live"))]
                live: None,
            },
        ),
    }
}

/// The scene of a command: a file, else a built-in scene named in its place (`organ`,
/// `laparoscopy`), else the default scene when none is given.
fn scene_from(path: Option<&Path>) -> Result<Scene> {
    match path {
        Some(p) if !p.exists() => match p.to_str().and_then(built_in_scene) {
            Some(scene) => Ok(scene?),
            None => {
                let names: Vec<&str> = BUILT_IN_SCENES.iter().map(|(n, _)| *n).collect();
                Err(anyhow::anyhow!(
                    "{}: no such scene file, nor a built-in scene (built in: {})",
                    p.display(),
                    names.join(", ")
                ))
            }
        },
        Some(p) => Ok(load_scene(p)?),
        None => Ok(default_scene()),
    }
}

/// Recording of a headless run: the poses every active tool used, its feedback, and the mesh stream
/// at 60 Hz with a keyframe every 2 s (what a daemon session records, so replay treats both alike).
struct Recording {
    #[cfg(feature = "record")]
    sink: palpa::daemon::sink::RecordSink,
    #[cfg(feature = "record")]
    meshes: std::cell::RefCell<palpa::display::MeshSchedule>,
    /// Bodies announced so far (transections add some).
    #[cfg(feature = "record")]
    known_bodies: std::cell::Cell<usize>,
}

impl Recording {
    #[cfg(feature = "record")]
    fn start(path: Option<&Path>, scene: &Scene, world: &World) -> Result<Self> {
        use palpa::daemon::sink::RecordSink;
        use palpa::record::recorder::{Recorder, RecorderSettings, SessionInfo};
        let Some(path) = path else {
            return Ok(Self {
                sink: RecordSink::none(),
                meshes: std::cell::RefCell::new(palpa::display::MeshSchedule::new(
                    world, 60.0, 2.0,
                )),
                known_bodies: std::cell::Cell::new(world.bodies.len()),
            });
        };
        let session = SessionInfo {
            mode: "run".into(),
            display_rate_hz: 60.0,
            keyframe_every_s: 2.0,
        };
        // An offline run waits for the writer rather than drop a record.
        let recorder = Recorder::start(path, scene, world, &session, RecorderSettings::default())?
            .waiting_when_full();
        let this = Self {
            sink: RecordSink::to(recorder),
            meshes: std::cell::RefCell::new(palpa::display::MeshSchedule::new(world, 60.0, 2.0)),
            known_bodies: std::cell::Cell::new(world.bodies.len()),
        };
        this.mesh(world);
        Ok(this)
    }

    #[cfg(not(feature = "record"))]
    fn start(path: Option<&Path>, _scene: &Scene, _world: &World) -> Result<Self> {
        if path.is_some() {
            bail!("this build has no recording (feature `record`)");
        }
        Ok(Self {})
    }

    #[cfg(feature = "record")]
    fn mesh(&self, world: &World) {
        let _ = self
            .meshes
            .borrow_mut()
            .produce(world, |header, bytes| -> Result<(), ()> {
                self.sink.mesh(header, bytes);
                Ok(())
            });
    }

    fn after_step(&self, world: &World) {
        #[cfg(feature = "record")]
        {
            use palpa::ipc::payload::ToolPoseV1;
            let before = world.tick - 1;
            for (i, tool) in world.tools.iter().enumerate() {
                if tool.active {
                    let q = tool.pose.world_from_tool.quaternion();
                    let pose = ToolPoseV1 {
                        seq: world.tick,
                        device_time_ns: 0,
                        position: tool.pose.position_in_world.into(),
                        orientation: [q.w, q.i, q.j, q.k],
                        jaw: tool.jaw,
                        buttons: 0,
                        reserved: 0,
                    };
                    self.sink.input(before, i, &pose, 0);
                }
                let feedback = palpa::daemon::feedback_of(world, i, tool.active, false, (0, 0));
                self.sink.feedback(i, &feedback);
            }
            if palpa::daemon::guard_acted(world) {
                for (b, guard) in world.guards.iter().enumerate() {
                    if let (true, Some(cause)) = (guard.acted, guard.last_cause) {
                        self.sink.guard(world.tick, b, cause);
                    }
                }
            }
            let mut known = self.known_bodies.get();
            self.sink.bodies_added(world, &mut known);
            self.known_bodies.set(known);
            self.mesh(world);
        }
        #[cfg(not(feature = "record"))]
        let _ = world;
    }

    /// Closes the recording of a session that ended at `world`'s tick.
    fn finish(self, world: &World) -> Result<()> {
        #[cfg(feature = "record")]
        self.sink.session_end(world.tick);
        #[cfg(not(feature = "record"))]
        let _ = world;
        #[cfg(feature = "record")]
        if let Some(summary) = self.sink.finish()? {
            let total: u64 = summary.messages.values().sum();
            println!("recorded {total} messages ({} dropped)", summary.dropped);
        }
        Ok(())
    }
}

fn create(path: &Path) -> Result<BufWriter<std::fs::File>> {
    let file =
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    Ok(BufWriter::new(file))
}

fn run(
    path: Option<&Path>,
    duration: f64,
    trace: Option<&Path>,
    trace_every: u64,
    feedback: Option<&Path>,
    record: Option<&Path>,
) -> Result<()> {
    let scene = scene_from(path)?;
    let mut world = World::from_scene(&scene);
    warn_of_crossings(&world, "warning: ");
    let ticks = (duration / world.params.dt).round() as u64;
    if ticks == 0 && duration > 0.0 {
        eprintln!(
            "warning: --duration {duration} s is less than half a tick (dt {} s): no tick is run",
            world.params.dt
        );
    }
    let mut out = match trace {
        Some(p) => {
            let mut w = create(p)?;
            write_trace_header(&mut w)?;
            write_trace_rows(&mut w, &world)?;
            Some(w)
        }
        None => None,
    };
    let mut feedback_out = match feedback {
        Some(p) => {
            let mut w = create(p)?;
            write_feedback_header(&mut w)?;
            Some(w)
        }
        None => None,
    };
    let recording = Recording::start(record, &scene, &world)?;
    // Ctrl-C or SIGTERM ends the run after the current tick, with the recording and traces finished.
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    #[cfg(feature = "ipc")]
    {
        let handler_stop = stop.clone();
        ctrlc::set_handler(move || handler_stop.store(true, std::sync::atomic::Ordering::Relaxed))
            .context("cannot install the Ctrl-C/SIGTERM handler")?;
    }
    let mut guard_ticks = 0u64;
    let started = Instant::now();
    for _ in 0..ticks {
        if stop.load(std::sync::atomic::Ordering::Relaxed) {
            break;
        }
        world.step();
        guard_ticks += palpa::daemon::guard_acted(&world) as u64;
        recording.after_step(&world);
        if let Some(w) = out.as_mut()
            && world.tick % trace_every == 0
        {
            write_trace_rows(w, &world)?;
        }
        if let Some(w) = feedback_out.as_mut() {
            write_feedback_rows(w, &world)?;
        }
    }
    let wall = started.elapsed().as_secs_f64();
    recording.finish(&world)?;
    for w in [out, feedback_out].into_iter().flatten() {
        w.into_inner()
            .map_err(|e| anyhow::anyhow!("cannot write a trace: {}", e.error()))?
            .sync_all()?;
    }
    let ticks = world.tick;
    println!(
        "{}: {} ticks ({} s simulated) in {:.3} s wall ({:.1}x real time, {:.1} µs/tick)",
        scene.name,
        ticks,
        world.time(),
        wall,
        if wall > 0.0 {
            world.time() / wall
        } else {
            f64::INFINITY
        },
        if ticks > 0 {
            wall * 1e6 / ticks as f64
        } else {
            0.0
        }
    );
    for (b, body) in world.bodies.iter().enumerate() {
        let com = body.surface_centre_of_mass();
        let gap = world
            .min_obstacle_gap(body)
            .map_or("none".to_string(), |g| format!("{g:.6} m"));
        println!(
            "  {}: com [{:.4}, {:.4}, {:.4}] m, kinetic energy {:.3e} J, min obstacle gap {}",
            body.name,
            com.x,
            com.y,
            com.z,
            body.kinetic_energy(),
            gap,
        );
        let guard = &world.guards[b];
        if guard.events > 0 {
            let cause = guard.last_cause.expect("an event has a cause");
            println!(
                "  {}: divergence guard acted {} times (last cause: {cause:?}: {}) — {}",
                body.name,
                guard.events,
                guard_cause_text(cause),
                if past_explicit_limit(&world, b) {
                    format!(
                        "the {} integrator is unstable here; `palpa check` explains why",
                        world.integrator_of(b).name()
                    )
                } else {
                    "not the integrator's stability (`palpa check` finds the body stable at dt): \
                     a load beyond the model's range, such as links too soft for the rigid \
                     component's weight, a tool with no force limit crushing the body, or bodies \
                     squeezed together"
                        .to_string()
                }
            );
        }
    }
    if world.bodies.iter().any(|b| !b.is_finite()) {
        bail!("the simulation diverged; run `palpa check` on the scene for its stability margin");
    }
    if stop.load(std::sync::atomic::Ordering::Relaxed) {
        bail!("stopped by a signal after {ticks} ticks (the outputs are complete up to there)");
    }
    if guard_ticks > 0 {
        let events: u64 = world.guards.iter().map(|g| g.events).sum();
        eprintln!(
            "warning: the divergence guard acted on {guard_ticks} of {ticks} ticks ({events} body \
             restorations): the run did not follow the model there; exit status {EXIT_GUARD_ACTED}"
        );
        std::process::exit(EXIT_GUARD_ACTED);
    }
    Ok(())
}

#[cfg(feature = "ipc")]
fn serve(args: ServeArgs) -> Result<()> {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, Ordering};

    let scene = scene_from(args.scene.as_deref())?;
    // The timings file is created before the run, so that a path that cannot be written is
    // refused at once rather than after the session (it is written when the daemon stops).
    let timings = match &args.timings {
        Some(path) => Some((
            path,
            std::fs::File::create(path)
                .with_context(|| format!("cannot create the timings file {}", path.display()))?,
        )),
        None => None,
    };
    let options = serve_options(&args, &scene);
    let stop = Arc::new(AtomicBool::new(false));
    let handler_stop = stop.clone();
    ctrlc::set_handler(move || handler_stop.store(true, Ordering::Relaxed))
        .context("cannot install the Ctrl-C/SIGTERM handler")?;
    announce_serve(&scene, &args);
    #[cfg(feature = "record")]
    let record = args.record.clone();
    #[cfg(not(feature = "record"))]
    let record: Option<PathBuf> = None;
    #[cfg(feature = "live")]
    let live = start_live_view(args.live.as_deref(), &scene)?;
    let handle = std::thread::Builder::new()
        .name("palpa-sim".into())
        .spawn(move || -> Result<_, String> {
            let sink = record_sink(record.as_deref(), &scene, &options)?;
            #[cfg(feature = "live")]
            let sink = match live {
                Some(live) => sink.with_live(live),
                None => sink,
            };
            let served = palpa::daemon::serve::serve(&scene, &options, stop, &sink)
                .map_err(|e| e.to_string());
            // The recording is finished whichever way the loop ended (and, should this thread
            // panic, by the recorder's Drop while unwinding).
            finish_sink(sink, served)
        })
        .context("cannot start the simulation thread")?;
    let summary = handle
        .join()
        .map_err(|_| anyhow::anyhow!("the simulation thread panicked"))?
        .map_err(|e| anyhow::anyhow!("palpa serve: {e}"))?;
    println!(
        "palpa serve: stopped after {} ticks{}: {} synchronicity misses, {} rejected inputs, {} disconnects, {} guard events, {} IPC errors, tick compute mean {:.1} µs, p99 {:.0} µs, max {:.1} µs",
        summary.ticks,
        if summary.paused_ticks > 0 {
            format!(" ({} of them paused)", summary.paused_ticks)
        } else {
            String::new()
        },
        summary.synchronicity_misses,
        summary.rejected_inputs,
        summary.disconnects,
        summary.guard_events,
        summary.ipc_errors,
        summary.compute_mean_us,
        summary.compute_p99_us,
        summary.compute_max_us
    );
    if let Some((path, mut file)) = timings {
        use std::io::Write;
        file.write_all(summary.timings_csv().as_bytes())
            .and_then(|()| file.flush())
            .with_context(|| format!("cannot write the timings to {}", path.display()))?;
    }
    if let Some(first) = &summary.first_ipc_error {
        eprintln!(
            "palpa serve: {} IPC operations failed (counted, outlived); the first: {first}",
            summary.ipc_errors
        );
    }
    if let Some(fatal) = &summary.fatal {
        bail!("palpa serve: stopped: {fatal}");
    }
    Ok(())
}

/// The daemon's options from `palpa serve`'s arguments (the staleness limit in ticks of `scene`).
#[cfg(feature = "ipc")]
fn serve_options(args: &ServeArgs, scene: &Scene) -> palpa::daemon::serve::ServeOptions {
    use palpa::daemon::input::InputLimits;
    palpa::daemon::serve::ServeOptions {
        prefix: args.prefix.clone(),
        duration: args.duration,
        lockstep: args.lockstep,
        realtime: args.rt,
        display_rate_hz: args.display_rate,
        keyframe_every_s: args.keyframe_every,
        limits: InputLimits {
            max_speed: args.max_speed,
            stale_after_ticks: ((args.stale_after_ms as f64 * 1e-3 / scene.world.dt).round()
                as u64)
                .max(1),
            ..InputLimits::default()
        },
        inject_ipc_faults: args.inject_ipc_faults,
    }
}

/// What `palpa serve` is about to run: the scene, the prefix, the mode, the tools over IPC and
/// the systems switched on (and a warning for bodies that start with their surfaces crossing).
#[cfg(feature = "ipc")]
fn announce_serve(scene: &Scene, args: &ServeArgs) {
    let world = World::from_scene(scene);
    warn_of_crossings(&world, "warning: ");
    let tools: Vec<&str> = world
        .tools
        .iter()
        .filter(|t| matches!(t.input, palpa::tool::ToolInput::Ipc))
        .map(|t| t.name.as_str())
        .collect();
    println!(
        "palpa serve: {} — prefix \"{}\", {} mode, tools over IPC: [{}]",
        scene.name,
        args.prefix,
        if args.lockstep {
            "lockstep"
        } else {
            "real-time 1 kHz"
        },
        tools.join(", ")
    );
    println!("  systems: {}", world.systems().names().join(", "));
}

/// The live view, listening before the loop starts so that its address can be printed (and a
/// wrong one refused) at once.
#[cfg(feature = "live")]
fn start_live_view(
    address: Option<&str>,
    scene: &Scene,
) -> Result<Option<palpa::record::live::LiveView>> {
    use palpa::record::live::{LiveSettings, LiveView, parse_address};
    let Some(text) = address else {
        return Ok(None);
    };
    let address = parse_address(text).map_err(|e| anyhow::anyhow!(e))?;
    let live = LiveView::start(address, &World::from_scene(scene), LiveSettings::default())?;
    println!(
        "palpa serve: live view on {} (open it in Foxglove: Open connection, Foxglove WebSocket)",
        live.url()
    );
    Ok(Some(live))
}

/// Where the daemon's records go: a recording of the session to `path`, or nowhere.
#[cfg(feature = "ipc")]
fn record_sink(
    path: Option<&Path>,
    scene: &Scene,
    options: &palpa::daemon::serve::ServeOptions,
) -> Result<palpa::daemon::sink::RecordSink, String> {
    #[cfg(feature = "record")]
    if let Some(path) = path {
        use palpa::record::recorder::{Recorder, RecorderSettings, SessionInfo};
        let session = SessionInfo {
            mode: "serve".into(),
            display_rate_hz: options.display_rate_hz,
            keyframe_every_s: options.keyframe_every_s,
        };
        let world = World::from_scene(scene);
        let recorder = Recorder::start(path, scene, &world, &session, RecorderSettings::default())
            .map_err(|e| e.to_string())?;
        return Ok(palpa::daemon::sink::RecordSink::to(recorder));
    }
    let _ = (path, scene, options);
    Ok(palpa::daemon::sink::RecordSink::none())
}

/// Finishes the recording and the live view after the loop, printing what each wrote; the loop's
/// summary, or its error (or the recording's, when the loop ended well but its file could not be
/// finished).
#[cfg(feature = "ipc")]
fn finish_sink(
    sink: palpa::daemon::sink::RecordSink,
    served: Result<palpa::daemon::serve::ServeSummary, String>,
) -> Result<palpa::daemon::serve::ServeSummary, String> {
    #[cfg(feature = "record")]
    {
        let (recorded, live) = sink.finish_all();
        if let Some(live) = live {
            let total: u64 = live.messages.values().sum();
            let scenes = live
                .messages
                .get(palpa::record::visual::TOPIC_SCENE_UPDATE)
                .copied()
                .unwrap_or(0);
            println!(
                "palpa serve: live view published {total} messages ({scenes} scene updates) to {} viewers ({} records dropped)",
                live.viewers, live.dropped
            );
        }
        match recorded {
            Ok(Some(recording)) => {
                let total: u64 = recording.messages.values().sum();
                println!(
                    "palpa serve: recorded {total} messages ({} dropped)",
                    recording.dropped
                );
            }
            Ok(None) => {}
            Err(e) if served.is_ok() => return Err(e.to_string()),
            Err(e) => eprintln!("palpa serve: {e}"),
        }
    }
    #[cfg(not(feature = "record"))]
    drop(sink);
    served
}

/// What `palpa demo` passes on to its daemon (`palpa serve`'s options of the same names).
#[cfg(feature = "ipc")]
struct DemoDaemon<'a> {
    rt: bool,
    timings: Option<&'a Path>,
    record: Option<&'a Path>,
    live: Option<&'a str>,
}

#[cfg(feature = "ipc")]
impl DemoDaemon<'_> {
    /// Refuses, before anything starts, a timings or recording path the daemon could not write.
    fn check_paths(&self) -> Result<()> {
        if let Some(path) = self.timings {
            std::fs::File::create(path)
                .with_context(|| format!("cannot create the timings file {}", path.display()))?;
        }
        if let Some(path) = self.record {
            std::fs::File::create(path)
                .with_context(|| format!("cannot create the recording {}", path.display()))?;
        }
        Ok(())
    }

    /// `palpa serve`'s arguments for `scene_name` under `prefix`.
    fn serve_args(&self, prefix: &str, scene_name: &str) -> Vec<std::ffi::OsString> {
        let mut args: Vec<std::ffi::OsString> = ["serve", "--prefix", prefix, scene_name]
            .into_iter()
            .map(Into::into)
            .collect();
        if self.rt {
            args.push("--rt".into());
        }
        for (flag, path) in [("--timings", self.timings), ("--record", self.record)] {
            if let Some(path) = path {
                args.extend([flag.into(), path.into()]);
            }
        }
        if let Some(address) = self.live {
            args.extend(["--live".into(), address.into()]);
        }
        args
    }

    /// Where to open the live view, when there is one.
    fn announce_live(&self) -> Result<()> {
        #[cfg(feature = "live")]
        if let Some(address) = self.live {
            use palpa::record::live::{parse_address, viewer_url};
            let parsed = parse_address(address).map_err(|e| anyhow::anyhow!(e))?;
            println!(
                "palpa demo: live view: open {} in Foxglove (Open connection, Foxglove WebSocket)",
                viewer_url(parsed)
            );
        }
        Ok(())
    }
}

/// The demo's daemon process: stopped with SIGTERM and waited for when dropped, so that a demo
/// ending early on an error leaves no daemon behind.
#[cfg(feature = "ipc")]
struct DaemonProcess(Option<std::process::Child>);

#[cfg(feature = "ipc")]
impl DaemonProcess {
    /// Starts `palpa serve` with `args`, its standard output piped.
    fn start(args: &[std::ffi::OsString]) -> Result<Self> {
        let exe = std::env::current_exe().context("cannot find the palpa executable")?;
        let child = std::process::Command::new(&exe)
            .args(args)
            .stdout(std::process::Stdio::piped())
            .spawn()
            .context("cannot start palpa serve")?;
        Ok(Self(Some(child)))
    }

    /// Stops the daemon (SIGTERM: it finishes its recording and prints its summary) and returns
    /// the last line it printed.
    fn stop(mut self) -> Result<Option<String>> {
        let Some(child) = self.0.take() else {
            return Ok(None);
        };
        terminate(&child);
        let output = child.wait_with_output().context("waiting for the daemon")?;
        Ok(String::from_utf8_lossy(&output.stdout)
            .lines()
            .last()
            .map(str::to_string))
    }
}

#[cfg(feature = "ipc")]
impl Drop for DaemonProcess {
    fn drop(&mut self) {
        if let Some(mut child) = self.0.take() {
            terminate(&child);
            let _ = child.wait();
        }
    }
}

/// Asks a child process to stop (SIGTERM: the daemon finishes its recording and prints its
/// summary).
#[cfg(feature = "ipc")]
fn terminate(child: &std::process::Child) {
    // SAFETY: kill(2) on our own child.
    unsafe {
        libc::kill(child.id() as i32, libc::SIGTERM);
    }
}

#[cfg(feature = "ipc")]
fn demo(duration: f64, scene_name: &str, daemon_options: DemoDaemon) -> Result<()> {
    use palpa::device::run::{DeviceOptions, devices_for_scene};

    if !(duration.is_finite() && duration > 0.0) {
        bail!("--duration must be > 0");
    }
    let prefix = format!("palpa_demo_{}", std::process::id());
    let scene = scene_from(Some(Path::new(scene_name)))?;
    daemon_options.check_paths()?;
    // The default organ keeps its hand-placed palpation; another scene gets a device per IPC tool.
    let devices = if scene.source == palpa::scene::DEFAULT_SCENE {
        vec![DeviceOptions::palpating_default_organ(&prefix, duration)]
    } else {
        devices_for_scene(&scene, &prefix, duration)
    };
    if devices.is_empty() {
        bail!(
            "{}: no tool takes its pose over IPC (`input = \"ipc\"`), so there is nothing for a device to drive",
            scene.name
        );
    }
    let serve_args = daemon_options.serve_args(&prefix, scene_name);
    let tools: Vec<&str> = devices.iter().map(|d| d.tool.as_str()).collect();
    println!(
        "palpa demo: starting the daemon (`palpa {}`) and {} simulated Geomagic Touch ({})",
        serve_args
            .iter()
            .map(|a| a.to_string_lossy())
            .collect::<Vec<_>>()
            .join(" "),
        devices.len(),
        tools.join(", ")
    );
    daemon_options.announce_live()?;
    let daemon = DaemonProcess::start(&serve_args)?;
    let reports = run_demo_devices(&devices, &prefix)?;
    let daemon_summary = daemon.stop()?;
    for (options, report) in devices.iter().zip(reports) {
        let report = report.map_err(|e| anyhow::anyhow!("device {}: {e}", options.tool))?;
        println!(
            "palpa demo: {}: {} poses sent, {} answered ({} lost); round trip median {:.0} µs, p99 {:.0} µs, p99.9 {:.0} µs; max force {:.3} N; touching tissue in {} answers ({:.0} %)",
            options.tool,
            report.poses_sent,
            report.latencies_us.len(),
            report.lost(),
            report.latency_percentile(0.5),
            report.latency_percentile(0.99),
            report.latency_percentile(0.999),
            report.max_force,
            report.answers_in_contact,
            100.0 * report.answers_in_contact as f64 / report.latencies_us.len().max(1) as f64
        );
    }
    if let Some(last) = daemon_summary {
        println!("{last}");
    }
    Ok(())
}

/// Runs the demo's devices until their paths end: the first on this thread, printing once a second
/// its status, the daemon's synchronicity misses (from its statistics service under `prefix`) and
/// the other devices' last force and contacts; every other device on a thread of its own. Each
/// device's report, in order.
#[cfg(feature = "ipc")]
fn run_demo_devices(
    devices: &[palpa::device::run::DeviceOptions],
    prefix: &str,
) -> Result<Vec<Result<palpa::device::run::DeviceReport, String>>> {
    use iceoryx2::prelude::PortFactory;
    use palpa::device::run::{DeviceStatus, run_device};
    use palpa::ipc::services::{IpcError, create_node, stats_service};
    use std::io::{IsTerminal, Write};
    use std::sync::atomic::AtomicBool;
    use std::sync::{Arc, Mutex};

    let node = create_node()?;
    let stats = stats_service(&node, prefix)?;
    let stats = stats
        .subscriber_builder()
        .create()
        .map_err(|e| IpcError::port(stats.name(), "subscriber", e))?;
    let stop = Arc::new(AtomicBool::new(false));
    let latest = Arc::new(Mutex::new(vec![None::<DeviceStatus>; devices.len()]));
    let others: Vec<_> = devices[1..]
        .iter()
        .cloned()
        .enumerate()
        .map(|(k, options)| {
            let (stop, latest) = (stop.clone(), latest.clone());
            std::thread::Builder::new()
                .name(format!("palpa-device-{}", k + 1))
                .spawn(move || {
                    run_device(&options, stop, |status| {
                        if let Ok(mut latest) = latest.lock() {
                            latest[k + 1] = Some(*status);
                        }
                    })
                    .map_err(|e| e.to_string())
                })
        })
        .collect();
    let terminal = std::io::stdout().is_terminal();
    let mut misses = 0u64;
    let first = run_device(&devices[0], stop, |status| {
        while let Ok(Some(sample)) = stats.receive() {
            misses = sample.payload().synchronicity_misses;
        }
        let mut line = format!(
            "t {:4.1} s | {} force {:6.3} N | contacts {:2} | round trip p99 {:7.1} µs | synchronicity misses {}",
            status.t,
            devices[0].tool,
            status.force.norm(),
            status.contacts,
            status.latency_p99_us,
            misses
        );
        // The other tools' last force and contacts (a grasper's contacts are the nodes it holds).
        if let Ok(latest) = latest.lock() {
            for (device, other) in devices.iter().zip(latest.iter()).skip(1) {
                if let Some(other) = other {
                    line += &format!(
                        " | {} force {:6.3} N, contacts {:2}",
                        device.tool,
                        other.force.norm(),
                        other.contacts
                    );
                }
            }
        }
        if terminal {
            print!("\r{line}");
            let _ = std::io::stdout().flush();
        } else {
            println!("{line}");
        }
    });
    if terminal {
        println!();
    }
    let mut reports = vec![first.map_err(|e| e.to_string())];
    for handle in others {
        reports.push(match handle {
            Ok(handle) => handle
                .join()
                .unwrap_or_else(|_| Err("the device thread panicked".into())),
            Err(e) => Err(format!("cannot start the device's thread: {e}")),
        });
    }
    Ok(reports)
}

/// One line per pair of bodies whose surfaces cross where they start (see
/// [`World::crossing_surfaces`]).
fn crossing_lines(world: &World) -> Vec<String> {
    world
        .crossing_surfaces()
        .iter()
        .map(|c| {
            let p = c.at_in_world;
            format!(
                "bodies `{}` and `{}` start with their surfaces crossing ({} triangle pairs, one at \
                 [{:.4}, {:.4}, {:.4}] m): contact between bodies keeps surfaces from passing \
                 through each other, so it cannot part them — place them apart",
                world.bodies[c.bodies.0].name,
                world.bodies[c.bodies.1].name,
                c.triangle_pairs,
                p.x,
                p.y,
                p.z
            )
        })
        .collect()
}

/// A warning for each free body that gravity alone moves by more than a tenth of its thinnest
/// extent in one step, in a scene with contact (obstacles, or other bodies): contact answers each
/// node's trajectory over the step, and where every node's would end inside what it rests on, it
/// stops them all where they started (a box resting on a table at a 0.1 s step never sags; a ball
/// dropped onto it hangs in the air above it).
fn coarse_step_lines(world: &World) -> Vec<String> {
    let dt = world.params.dt;
    let fall = world.params.gravity.norm() * dt * dt;
    let contact = world.systems().obstacle_contact || world.bodies.len() >= 2;
    if !contact || fall == 0.0 {
        return Vec::new();
    }
    world
        .bodies
        .iter()
        .filter(|b| !b.rigid.fixed)
        .filter_map(|b| {
            let positions = &b.surface.position_in_world;
            positions.first()?;
            let mut bounds = palpa::collision::tool::Aabb::empty();
            positions.iter().for_each(|p| bounds.include(p));
            let thinnest = (bounds.max - bounds.min).min();
            (fall > 0.1 * thinnest).then(|| {
                format!(
                    "body `{}`: gravity alone moves it {:.4} m in one step of {dt} s, more than a tenth \
                     of its thinnest extent ({:.4} m): contact stops a node whose trajectory over the \
                     step ends inside what it meets, and at this step it may stop the whole body where \
                     it started (resting bodies that never sag, a body hanging above what it falls \
                     onto) — lower dt",
                    b.name, fall, thinnest
                )
            })
        })
        .collect()
}

/// An obstacle in the scene's words: where it is and which way is out.
fn describe_obstacle(shape: &palpa::collision::obstacle::ObstacleShape) -> String {
    use palpa::collision::obstacle::ObstacleShape;
    let v = |v: &palpa::Vec3| format!("[{}, {}, {}]", v.x, v.y, v.z);
    match shape {
        ObstacleShape::Plane {
            point_in_world,
            normal_in_world,
        } => format!(
            "plane through {} m, outward normal {}",
            v(point_in_world),
            v(normal_in_world)
        ),
        ObstacleShape::Box {
            center_in_world,
            half_extents,
            world_from_box,
        } => {
            let q = world_from_box.quaternion();
            format!(
                "box centred at {} m, size {} m, orientation [{}, {}, {}, {}]",
                v(center_in_world),
                v(&(half_extents * 2.0)),
                q.w,
                q.i,
                q.j,
                q.k
            )
        }
    }
}

/// Prints [`crossing_lines`] on the standard error, each after `prefix`.
fn warn_of_crossings(world: &World, prefix: &str) {
    for line in crossing_lines(world)
        .into_iter()
        .chain(coarse_step_lines(world))
    {
        eprintln!("{prefix}{line}");
    }
}

/// What the divergence guard found wrong, in words.
fn guard_cause_text(cause: palpa::dynamics::guard::GuardCause) -> String {
    use palpa::dynamics::guard::{GuardCause as C, MAX_SPEED, MAX_STRETCH};
    match cause {
        C::NonFinite => "a value became NaN or infinite".to_string(),
        C::Speed => format!("a node moved faster than {MAX_SPEED} m/s"),
        C::Stretch => {
            format!("a node went further than {MAX_STRETCH} body sizes from its rigid component")
        }
        C::Energy => "the energy grew past what gravity and the tools explain".to_string(),
    }
}

/// Whether body `b` is stepped explicitly past the stability limit of its step (what `palpa
/// check` calls UNSTABLE or warns of): a node or rigid component under the paper's scheme past
/// its limit at dt, or under the multi-rate integrator past it even at its finest sub-step.
fn past_explicit_limit(world: &World, b: usize) -> bool {
    use palpa::dynamics::Integrator as I;
    let body = &world.bodies[b];
    let m = palpa::dynamics::stability::symplectic_margin(body, world.params.dt);
    match world.integrator_of(b) {
        I::Symplectic => m.margin < 0.0 || (!body.rigid.fixed && m.rigid_margin < 0.0),
        I::Multirate => substeps_fall_short(world, b).is_some(),
        I::Implicit => false,
    }
}

/// For a body the multi-rate integrator sub-steps as finely as it can
/// ([`palpa::dynamics::multirate::MAX_LEVEL`] halvings) with its worst node still past the limit
/// at that sub-step: that node's margin there.
fn substeps_fall_short(
    world: &World,
    b: usize,
) -> Option<palpa::dynamics::stability::StabilityMargin> {
    let (substeps, fast) = world.substeps_of(b);
    if world.integrator_of(b) != palpa::dynamics::Integrator::Multirate
        || fast == 0
        || substeps < 1 << palpa::dynamics::multirate::MAX_LEVEL
    {
        return None;
    }
    let m = palpa::dynamics::stability::symplectic_margin(
        &world.bodies[b],
        world.params.dt / f64::from(substeps),
    );
    (m.margin < 0.0).then_some(m)
}

/// `palpa check`'s verdict on a node or rigid component stepped explicitly past its limit.
const EXPLICIT_PAST_LIMIT: &str =
    "UNSTABLE: stepped explicitly past its limit (a bound with room to spare: the guard may act)";

fn check(path: Option<&Path>) -> Result<()> {
    let scene = scene_from(path)?;
    let world = World::from_scene(&scene);
    let w = &scene.world;
    println!("scene {}: valid", scene.name);
    println!(
        "  world: gravity [{}, {}, {}] m/s², dt {} s, air viscosity {} 1/s",
        w.gravity.x, w.gravity.y, w.gravity.z, w.dt, w.air_viscosity
    );
    for (spec, body) in scene.bodies.iter().zip(&world.bodies) {
        println!(
            "  body {}: {} — {} nodes, {} edges, {} triangles, mass {} kg surface + {} kg rigid{}",
            body.name,
            spec.mesh_source,
            body.node_count(),
            body.edges.len(),
            body.surface.triangles.len(),
            spec.params.surface_mass,
            spec.params.rigid_mass,
            if spec.params.fixed {
                ", rigid component fixed"
            } else {
                ""
            }
        );
        if let Some(sub) = &spec.params.subdivision {
            println!(
                "    subdivision at tool contact: rule {}, max depth {}, min edge {} m, tolerance {} m, \
                 coarsen after {} s, room for {} insertions",
                sub.rule.name(),
                sub.max_depth,
                sub.min_edge,
                sub.tolerance,
                sub.coarsen_after_s,
                palpa::topology::POOL_NODES
            );
        }
    }
    for o in &scene.obstacles {
        println!(
            "  obstacle {}: {}, friction {} (static {})",
            o.name,
            describe_obstacle(&o.shape),
            o.friction,
            o.static_friction
        );
    }
    for a in &scene.attachments {
        let stiffness: f64 = a.ties.iter().map(|t| t.stiffness).sum();
        let damping: f64 = a.ties.iter().map(|t| t.damping).sum();
        println!(
            "  attachment {}: {} nodes of {} tied to {}, {stiffness:.6} N/m, {damping:.6} N·s/m",
            a.name,
            a.ties.len(),
            scene.bodies[a.body].name,
            a.to.map_or("the world", |o| scene.bodies[o].name.as_str()),
        );
    }
    for line in crossing_lines(&world)
        .into_iter()
        .chain(coarse_step_lines(&world))
    {
        println!("  warning: {line}");
    }
    for spec in &scene.bodies {
        let shells = spec.mesh.shells();
        if shells.len() > 1 {
            println!(
                "  warning: body `{}`'s mesh is {} separate surfaces ({} nodes): they move as one body, \
                 every node tied to the one rigid component — give each its own `[[body]]` for \
                 separate organs",
                spec.name,
                shells.len(),
                shells
                    .iter()
                    .map(usize::to_string)
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
    }
    println!("  systems: {}", world.systems().names().join(", "));
    println!("  stability under the paper's scheme (semi-implicit Euler), per body:");
    let mut unstable = false;
    for (b, (body, m)) in world
        .bodies
        .iter()
        .zip(world.stability_margins())
        .enumerate()
    {
        let ok = m.margin >= 0.0;
        let integrator = world.integrator_of(b);
        unstable |= !ok && integrator == palpa::dynamics::Integrator::Symplectic;
        let (substeps, fast) = world.substeps_of(b);
        println!(
            "    {}: integrator {}{}",
            body.name,
            integrator.name(),
            match integrator {
                palpa::dynamics::Integrator::Multirate if fast > 0 =>
                    format!(" — {fast} nodes sub-stepped ×{substeps}, the rest at dt"),
                palpa::dynamics::Integrator::Multirate =>
                    " — every node stable at dt, no sub-stepping".into(),
                palpa::dynamics::Integrator::Implicit =>
                    " — unconditionally stable (with numerical damping)".into(),
                palpa::dynamics::Integrator::Symplectic => String::new(),
            }
        );
        // Past the explicit limit is a defect only where the body's integrator steps the node
        // explicitly at dt.
        let short = substeps_fall_short(&world, b);
        unstable |= short.is_some();
        let node_verdict = match integrator {
            _ if ok => "stable".to_string(),
            palpa::dynamics::Integrator::Multirate if let Some(s) = short => format!(
                "UNSTABLE: past the explicit limit at dt, and still past it sub-stepped ×{substeps}, \
                 the most the multirate integrator takes (ω·Δt = {:.3} there, limit {:.3}: the guard \
                 may act)",
                s.omega_dt, s.limit
            ),
            palpa::dynamics::Integrator::Multirate if fast > 0 => format!(
                "past the explicit limit at dt: sub-stepped (×{substeps}) by the multirate integrator"
            ),
            palpa::dynamics::Integrator::Implicit => {
                "past the explicit limit: stable under the implicit step".to_string()
            }
            _ => EXPLICIT_PAST_LIMIT.to_string(),
        };
        println!(
            "    {}: worst node {} ω·Δt = {:.3} (limit {:.3} with its damping, margin {:.3}) — {node_verdict}",
            body.name, m.worst_node, m.omega_dt, m.limit, m.margin,
        );
        let rigid_ok = m.rigid_margin >= 0.0;
        unstable |= !rigid_ok && integrator == palpa::dynamics::Integrator::Symplectic;
        use palpa::dynamics::Integrator as I;
        let handled = match (
            body.rigid.fixed,
            rigid_ok,
            integrator,
            world.rigid_substeps_of(b),
        ) {
            (true, ..) => "fixed, never integrated".to_string(),
            (_, _, I::Multirate, Some(n)) => format!(
                "{}: sub-stepped ×{n} with every node by the multirate integrator",
                if rigid_ok {
                    "within the explicit limit, but its exchange with sub-stepped nodes is not"
                } else {
                    "past the explicit limit"
                }
            ),
            (_, false, I::Multirate, None) if world.rigid_stepped_implicitly(b) => {
                "past the explicit limit: stepped implicitly against the nodes by the multirate integrator"
                    .to_string()
            }
            (_, true, ..) => "stable at dt".to_string(),
            (_, false, I::Implicit, _) => {
                "past the explicit limit: solved with the nodes by the implicit step".to_string()
            }
            (_, false, _, _) => {
                EXPLICIT_PAST_LIMIT.to_string()
            }
        };
        println!(
            "    {}: rigid component on its links ω·Δt = {:.3} (limit {:.3}, margin {:.3}) — {handled}",
            body.name, m.rigid_omega_dt, m.rigid_limit, m.rigid_margin
        );
    }
    if unstable {
        println!(
            "warning: a node or a rigid component is past the stability limit of the explicit scheme and this\n\
             \x20 body uses it: the divergence guard may keep restoring it (the bound is a safe one: a body a\n\
             \x20 little past it may still run). Use integrator = \"implicit\", or \"multirate\" (the default)\n\
             \x20 where its sub-steps reach the limit.\n\
             \x20 ω² ≤ (k_link + 2 Σ k_edges) / m: more nodes for the same surface_mass means lighter nodes and\n\
             \x20 higher frequencies (the paper's trap). Lower dt, raise surface_mass, or lower surface_stiffness,\n\
             \x20 link_stiffness or the damping (which also tightens the limit: ω·Δt ≤ √(4 − 2 Δt c/m))."
        );
    }
    Ok(())
}
