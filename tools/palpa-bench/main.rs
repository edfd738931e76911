//! `palpa-bench`: latency and synchronicity of the haptic loop between real processes, and step
//! time against node count. Each writes JSON, a markdown summary and SVG plots into `--out DIR`.
//!
//! * `latency`: starts `palpa serve --rt` and drives it with the simulated device (Geomagic Touch
//!   preset palpating the default organ) over iceoryx2 for `--duration` seconds; reports round-trip
//!   latency (median, p99, p99.9, max), the daemon's share, wake-up lateness, the tick compute time
//!   distribution and synchronicity misses. In the same run it measures the floor: a raw iceoryx2
//!   ping-pong of the same payloads (a pose out, a feedback back) between this process and an echo
//!   process, and prints the ratio.
//! * `scaling`: one step of an icosphere on a table from 162 to 40 962 nodes, with and without a probe
//!   pressed into it, per stage, with the fitted log-log slope.
//! * `cut`: a 10 cm incision drawn in 1 s across a 2 562-node organ: tick distribution during the cut
//!   against the same scene with the blade passing above the organ, the cost of one incision step,
//!   and the cost of a transection (the tube of `scenes/transection.toml` cut through).
//! * `bodies`: the body–body contact stage and the whole tick for organs apart, touching,
//!   stacked in twos and (4 organs) in a tower that topples into a heap (2 and 4 organs of 162 and
//!   642 nodes), the laparoscopy scene's tick distribution with the demo's two tools, per stage,
//!   a ball's landing on an organ (`scenes/two_organs.toml`) with the collision net's answers, and
//!   a light organ crushed against the table by a heavy one.
//! * `reference`: palpa's whole tick on a 10 242-node organ (no contact) against the plain reference
//!   step ([`reference`]: array of structs, scalar `f64`) of the same system, in the same run, best
//!   of three, after checking that both step the same system.

use palpa::report as plot;
mod reference;
mod remote;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use iceoryx2::prelude::PortFactory;
use palpa::ipc::payload::{ToolFeedbackV1, ToolPoseV1};
use palpa::ipc::services::{IpcError, create_node, feedback_service, pose_service};
use palpa::world::{Stage, StepProfile, World};
use plot::{Progress, Series, histogram, loglog, loglog_slope, machine, percentile};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

#[derive(Parser)]
#[command(
    name = "palpa-bench",
    about = "Latency/synchronicity and scaling benchmarks of palpa"
)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Round-trip latency and synchronicity of daemon + simulated device, against the iceoryx2 floor.
    Latency(LatencyArgs),
    /// Step time against node count, per stage, with and without a probe in contact.
    Scaling(ScalingArgs),
    /// Tick time while a blade cuts a 2 562-node organ, against no cut; incision step and
    /// transection costs.
    Cut(CutArgs),
    /// Tick time while a grasper lifts a 2 562-node organ and while a grasper tears an organ,
    /// against the same scenes without the grasp or the tearing.
    Grasp(GraspArgs),
    /// Body–body contact stage and whole tick against the number of bodies and nodes (apart,
    /// touching, stacked), per stage; the laparoscopy scene's tick distribution with both tools; a
    /// ball's landing on an organ; a light organ crushed by a heavy one.
    Bodies(GraspArgs),
    /// palpa's tick against the plain reference step of the same model (array of structs, scalar
    /// f64), same organ, same run.
    Reference(ReferenceArgs),
    /// Round trip through `palpa-zenoh` against the local iceoryx2 path (p50, p99), and the daemon's
    /// tick with and without the live view and a viewer.
    Remote(GraspArgs),
    /// (internal) The daemon on the embedded default scene, real-time mode, when no `palpa`
    /// executable sits next to this one: the same serve loop as `palpa serve --rt --timings`.
    #[command(hide = true)]
    Daemon {
        #[arg(long)]
        prefix: String,
        #[arg(long)]
        timings: PathBuf,
    },
    /// (internal) The far side of the ping-pong floor: answers every pose with a feedback.
    #[command(hide = true)]
    Echo {
        #[arg(long)]
        prefix: String,
        #[arg(long, default_value_t = 60.0, value_parser = palpa::daemon::values::positive)]
        timeout: f64,
    },
}

#[derive(Args)]
struct LatencyArgs {
    /// Output directory.
    #[arg(long, default_value = "bench-out")]
    out: PathBuf,
    /// A few seconds and fewer pings: a smoke test for CI.
    #[arg(long)]
    quick: bool,
    /// Seconds of daemon + device (default 30; 3 with --quick).
    #[arg(long, allow_hyphen_values = true, value_parser = palpa::daemon::values::positive)]
    duration: Option<f64>,
    /// Ping-pong round trips for the floor (default 10 000; 1 000 with --quick).
    #[arg(long, allow_hyphen_values = true, value_parser = palpa::daemon::values::count)]
    pings: Option<u64>,
}

#[derive(Args)]
struct ScalingArgs {
    /// Output directory.
    #[arg(long, default_value = "bench-out")]
    out: PathBuf,
    /// 162 to 2 562 nodes and fewer steps: a smoke test for CI.
    #[arg(long)]
    quick: bool,
    /// Every force pass on the step's thread (by default a body of 4 096 nodes or more offers half
    /// of its force passes to the world's helper thread).
    #[arg(long)]
    one_thread: bool,
}

#[derive(Args)]
struct GraspArgs {
    /// Output directory.
    #[arg(long, default_value = "bench-out")]
    out: PathBuf,
    /// One repetition instead of three: a smoke test.
    #[arg(long)]
    quick: bool,
}

#[derive(Args)]
struct ReferenceArgs {
    /// Output directory.
    #[arg(long, default_value = "bench-out")]
    out: PathBuf,
    /// Icosphere subdivisions of the organ (5: 10 242 nodes).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(0..=7))]
    subdivisions: u32,
    /// palpa's integrator (`symplectic`, `multirate`, `implicit`).
    #[arg(long, default_value = "symplectic")]
    integrator: String,
    /// Steps per timed run (default 2 000; 200 with --quick).
    #[arg(long, value_parser = palpa::daemon::values::count)]
    steps: Option<u64>,
    /// Fewer steps: a smoke test.
    #[arg(long)]
    quick: bool,
}

#[derive(Args)]
struct CutArgs {
    /// Output directory.
    #[arg(long, default_value = "bench-out")]
    out: PathBuf,
    /// One repetition instead of five: a smoke test for CI.
    #[arg(long)]
    quick: bool,
    /// The organ's integrator (`symplectic`, `multirate`, `implicit`).
    #[arg(long, default_value = "multirate")]
    integrator: String,
    /// The organ's surface mass (kg).
    #[arg(long, default_value_t = 1.2, value_parser = palpa::daemon::values::positive)]
    surface_mass: f64,
}

fn main() -> Result<()> {
    match Cli::parse().command {
        Cmd::Latency(args) => latency(args),
        Cmd::Scaling(args) => scaling(args),
        Cmd::Cut(args) => cut(args),
        Cmd::Grasp(args) => grasp(args),
        Cmd::Bodies(args) => bodies(args),
        Cmd::Reference(args) => reference_comparison(args),
        Cmd::Remote(args) => remote::remote(&args.out, args.quick),
        Cmd::Echo { prefix, timeout } => echo(&prefix, timeout),
        Cmd::Daemon { prefix, timings } => daemon(&prefix, &timings),
    }
}

/// The daemon process to start: `palpa serve --rt` when the `palpa` executable sits next to this
/// one (a `cargo build`), else this executable's own `daemon` mode, which runs the same serve loop.
fn daemon_command(prefix: &str, timings: &Path) -> Result<Command> {
    let exe = std::env::current_exe().context("cannot find this executable")?;
    let palpa = exe.with_file_name("palpa");
    let mut command;
    if palpa.is_file() {
        command = Command::new(palpa);
        command.args(["serve", "--rt", "--prefix", prefix, "--timings"]);
    } else {
        command = Command::new(exe);
        command.args(["daemon", "--prefix", prefix, "--timings"]);
    }
    command.arg(timings);
    Ok(command)
}

fn daemon(prefix: &str, timings: &Path) -> Result<()> {
    use palpa::daemon::serve::{ServeOptions, serve};
    use palpa::daemon::sink::RecordSink;
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, Ordering};
    let stop = Arc::new(AtomicBool::new(false));
    let handler = stop.clone();
    ctrlc::set_handler(move || handler.store(true, Ordering::Relaxed))
        .context("cannot install the SIGTERM handler")?;
    let options = ServeOptions {
        prefix: prefix.to_string(),
        realtime: true,
        ..ServeOptions::default()
    };
    let summary = serve(
        &palpa::scene::default_scene(),
        &options,
        stop,
        &RecordSink::none(),
    )
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    std::fs::write(timings, summary.timings_csv())
        .with_context(|| format!("cannot write {}", timings.display()))?;
    match summary.fatal {
        Some(fatal) => Err(anyhow::anyhow!("the daemon stopped: {fatal}")),
        None => Ok(()),
    }
}

/// Summary of a latency sample set (µs).
fn spread(mut values: Vec<f64>) -> serde_json::Value {
    values.sort_by(f64::total_cmp);
    json!({
        "count": values.len(),
        "median": percentile(&values, 0.5),
        "p99": percentile(&values, 0.99),
        "p99_9": percentile(&values, 0.999),
        "max": values.last().copied().unwrap_or(f64::NAN),
        "mean": values.iter().sum::<f64>() / values.len().max(1) as f64,
    })
}

/// The compute and lateness histograms of `palpa serve --timings FILE` (non-empty 1 µs bins).
#[allow(clippy::type_complexity)]
fn read_timings(path: &Path) -> Result<(Vec<(usize, u64)>, Vec<(usize, u64)>)> {
    let csv =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut compute: Vec<(usize, u64)> = Vec::new();
    let mut lateness: Vec<(usize, u64)> = Vec::new();
    for line in csv.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 3 {
            bail!("bad timings line {line:?}");
        }
        let bin: usize = f[0].parse()?;
        let (c, l): (u64, u64) = (f[1].parse()?, f[2].parse()?);
        if c > 0 {
            compute.push((bin, c));
        }
        if l > 0 {
            lateness.push((bin, l));
        }
    }
    Ok((compute, lateness))
}

/// Percentile from a 1 µs histogram (upper bin edge).
fn histogram_percentile(bins: &[(usize, u64)], q: f64) -> f64 {
    let total: u64 = bins.iter().map(|b| b.1).sum();
    let rank = ((q * total as f64).ceil() as u64).max(1);
    let mut seen = 0;
    for &(bin, count) in bins {
        seen += count;
        if seen >= rank {
            return (bin + 1) as f64;
        }
    }
    f64::NAN
}

fn latency(args: LatencyArgs) -> Result<()> {
    use palpa::device::run::{DeviceOptions, run_device};
    use std::sync::Arc;
    use std::sync::atomic::AtomicBool;

    let duration = args.duration.unwrap_or(if args.quick { 3.0 } else { 30.0 });
    let pings = args.pings.unwrap_or(if args.quick { 1000 } else { 10_000 });
    if !(duration.is_finite() && duration > 0.0) {
        bail!("--duration must be > 0");
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let timings = args.out.join("latency_timings.csv");
    let prefix = format!("palpa_bench_{}", std::process::id());
    let mut progress = Progress::new("latency", 3);

    // 1. Daemon (real-time mode) + simulated device.
    let mut command = daemon_command(&prefix, &timings)?;
    let daemon_process = format!(
        "{} {}",
        command.get_program().to_string_lossy(),
        command
            .get_args()
            .map(|a| a.to_string_lossy().into_owned())
            .collect::<Vec<_>>()
            .join(" ")
    );
    let daemon = command
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .context("cannot start palpa serve")?;
    let options = DeviceOptions::palpating_default_organ(&prefix, duration);
    let device = run_device(&options, Arc::new(AtomicBool::new(false)), |_| {});
    // SAFETY: kill(2) on our own child.
    unsafe {
        libc::kill(daemon.id() as i32, libc::SIGTERM);
    }
    let output = daemon
        .wait_with_output()
        .context("waiting for the daemon")?;
    let report = device.map_err(|e| anyhow::anyhow!("device: {e}"))?;
    if !output.status.success() {
        bail!(
            "palpa serve failed: {}",
            String::from_utf8_lossy(&output.stderr)
        );
    }
    let daemon_warnings: Vec<String> = String::from_utf8_lossy(&output.stderr)
        .lines()
        .map(str::to_string)
        .collect();
    progress.step("daemon + device");
    let (compute, lateness) = read_timings(&timings)?;
    let ticks: u64 = compute.iter().map(|b| b.1).sum();
    let misses: u64 = compute.iter().filter(|b| b.0 >= 1000).map(|b| b.1).sum();
    let compute_mean = compute
        .iter()
        .map(|&(b, c)| (b as f64 + 0.5) * c as f64)
        .sum::<f64>()
        / ticks.max(1) as f64;
    let lateness_mean = lateness
        .iter()
        .map(|&(b, c)| (b as f64 + 0.5) * c as f64)
        .sum::<f64>()
        / ticks.max(1) as f64;

    // 2. The floor: raw ping-pong of the same payloads between two processes.
    let floor_prefix = format!("palpa_bench_floor_{}", std::process::id());
    let mut echo = Command::new(std::env::current_exe()?)
        .args(["echo", "--prefix", &floor_prefix, "--timeout", "120"])
        .stdout(Stdio::null())
        .spawn()
        .context("cannot start the echo process")?;
    let floor = ping_pong(&floor_prefix, pings);
    let _ = echo.kill();
    let _ = echo.wait();
    let floor = floor?;
    progress.step("iceoryx2 ping-pong floor");

    // 3. Report.
    let round_trip = spread(report.latencies_us.clone());
    let floor_summary = spread(floor.clone());
    let median = round_trip["median"].as_f64().unwrap_or(f64::NAN);
    let floor_median = floor_summary["median"].as_f64().unwrap_or(f64::NAN);
    let result = json!({
        "command": format!("palpa-bench latency{} --out {}", if args.quick { " --quick" } else { "" }, args.out.display()),
        "date": plot::utc_now(),
        "machine": machine(),
        "duration_s": duration,
        "scene": "embedded default (scenes/organ.toml), tool `probe`",
        "daemon_process": daemon_process,
        "device": "simulated Geomagic Touch, palpate motion, 1 kHz",
        "poses_sent": report.poses_sent,
        "poses_answered": report.latencies_us.len(),
        "poses_lost": report.lost(),
        "round_trip_us": round_trip,
        "daemon": {
            "ticks": ticks,
            "synchronicity_misses": misses,
            "compute_mean_us": compute_mean,
            "compute_median_us": histogram_percentile(&compute, 0.5),
            "compute_p99_us": histogram_percentile(&compute, 0.99),
            "compute_p99_9_us": histogram_percentile(&compute, 0.999),
            "compute_max_us": compute.last().map_or(f64::NAN, |b| (b.0 + 1) as f64),
            "lateness_mean_us": lateness_mean,
            "lateness_p99_us": histogram_percentile(&lateness, 0.99),
            "lateness_max_us": lateness.last().map_or(f64::NAN, |b| (b.0 + 1) as f64),
            "share_of_median_round_trip": compute_mean / median,
            "warnings": daemon_warnings,
        },
        "floor_ping_pong_us": floor_summary,
        "ratio_median_round_trip_to_floor": median / floor_median,
    });
    let path = args.out.join("latency.json");
    std::fs::write(&path, serde_json::to_string_pretty(&result)?)?;
    let mut bars: Vec<(f64, f64, u64)> = Vec::new();
    let mut sorted = report.latencies_us.clone();
    sorted.sort_by(f64::total_cmp);
    if let (Some(&lo), Some(&hi)) = (sorted.first(), sorted.last()) {
        let width = ((hi - lo) / 60.0).max(1.0);
        let mut counts = vec![0u64; 61];
        for v in &sorted {
            counts[(((v - lo) / width) as usize).min(60)] += 1;
        }
        for (k, c) in counts.into_iter().enumerate() {
            let a = lo + k as f64 * width;
            bars.push((a, a + width, c));
        }
    }
    histogram(
        &args.out.join("latency_round_trip.svg"),
        "Round trip, device pose to feedback (µs)",
        "µs",
        &bars,
    )?;
    let compute_bars: Vec<(f64, f64, u64)> = compute
        .iter()
        .map(|&(b, c)| (b as f64, b as f64 + 1.0, c))
        .collect();
    histogram(
        &args.out.join("latency_tick_compute.svg"),
        "Daemon tick compute time (µs, 1 µs bins)",
        "µs",
        &compute_bars,
    )?;
    let d = &result["daemon"];
    let rt = &result["round_trip_us"];
    let fl = &result["floor_ping_pong_us"];
    let md = format!(
        "# palpa-bench latency\n\n`{}` — {} — {}\n\n\
         Daemon `palpa serve --rt` and the simulated device (Touch preset, palpating) as two processes \
         over iceoryx2 for {duration} s.\n\n\
         | round trip (µs) | median | p99 | p99.9 | max | answered / sent |\n| --- | --- | --- | --- | --- | --- |\n\
         | daemon + device | {:.0} | {:.0} | {:.0} | {:.0} | {} / {} |\n\
         | iceoryx2 ping-pong floor | {:.1} | {:.1} | {:.1} | {:.1} | {} |\n\n\
         Ratio of the medians: {:.0}× (the daemon answers on its next 1 ms tick, by design).\n\n\
         | daemon tick | value |\n| --- | --- |\n\
         | ticks | {} |\n| synchronicity misses (compute > 1 ms) | {} |\n\
         | compute mean / median / p99 / p99.9 / max (µs) | {:.1} / {:.0} / {:.0} / {:.0} / {:.0} |\n\
         | share of the median round trip | {:.1} % |\n\
         | wake-up lateness mean / p99 / max (µs) | {:.1} / {:.0} / {:.0} |\n\n\
         ![round trip](latency_round_trip.svg)\n![tick compute](latency_tick_compute.svg)\n",
        result["command"].as_str().unwrap_or(""),
        result["date"].as_str().unwrap_or(""),
        result["machine"].as_str().unwrap_or(""),
        rt["median"].as_f64().unwrap_or(f64::NAN),
        rt["p99"].as_f64().unwrap_or(f64::NAN),
        rt["p99_9"].as_f64().unwrap_or(f64::NAN),
        rt["max"].as_f64().unwrap_or(f64::NAN),
        report.latencies_us.len(),
        report.poses_sent,
        fl["median"].as_f64().unwrap_or(f64::NAN),
        fl["p99"].as_f64().unwrap_or(f64::NAN),
        fl["p99_9"].as_f64().unwrap_or(f64::NAN),
        fl["max"].as_f64().unwrap_or(f64::NAN),
        fl["count"],
        median / floor_median,
        ticks,
        misses,
        compute_mean,
        d["compute_median_us"].as_f64().unwrap_or(f64::NAN),
        d["compute_p99_us"].as_f64().unwrap_or(f64::NAN),
        d["compute_p99_9_us"].as_f64().unwrap_or(f64::NAN),
        d["compute_max_us"].as_f64().unwrap_or(f64::NAN),
        100.0 * compute_mean / median,
        lateness_mean,
        d["lateness_p99_us"].as_f64().unwrap_or(f64::NAN),
        d["lateness_max_us"].as_f64().unwrap_or(f64::NAN),
    );
    std::fs::write(args.out.join("latency.md"), &md)?;
    progress.step("report");
    println!("{md}");
    Ok(())
}

/// Sends `count` poses at 1 kHz and waits (spinning) for each answer; returns the round trips (µs).
fn ping_pong(prefix: &str, count: u64) -> Result<Vec<f64>> {
    let node = create_node().map_err(|e| anyhow::anyhow!("{e}"))?;
    let publisher = pose_service(&node, prefix, "probe")
        .and_then(|s| {
            s.publisher_builder()
                .create()
                .map_err(|e| IpcError::port(s.name(), "publisher", e))
        })
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let subscriber = feedback_service(&node, prefix, "probe")
        .and_then(|s| {
            s.subscriber_builder()
                .create()
                .map_err(|e| IpcError::port(s.name(), "subscriber", e))
        })
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let send = |seq: u64| -> Result<()> {
        publisher
            .send_copy(ToolPoseV1 {
                seq,
                orientation: [1.0, 0.0, 0.0, 0.0],
                ..ToolPoseV1::default()
            })
            .map(|_| ())
            .map_err(|e| anyhow::anyhow!("{e:?}"))
    };
    // Wait for the echo to answer at all.
    let ready_by = Instant::now() + Duration::from_secs(20);
    'ready: loop {
        send(0)?;
        let until = Instant::now() + Duration::from_millis(5);
        while Instant::now() < until {
            if let Some(sample) = subscriber.receive().map_err(|e| anyhow::anyhow!("{e:?}"))?
                && sample.payload().seq == 0
            {
                break 'ready;
            }
        }
        if Instant::now() > ready_by {
            bail!("the echo process never answered");
        }
    }
    let mut round_trips = Vec::with_capacity(count as usize);
    let start = Instant::now();
    for seq in 1..=count {
        let slot = start + Duration::from_micros(1000 * seq);
        while Instant::now() < slot {
            std::thread::sleep(slot.saturating_duration_since(Instant::now()));
        }
        let sent = Instant::now();
        send(seq)?;
        let give_up = sent + Duration::from_millis(100);
        loop {
            if let Some(sample) = subscriber.receive().map_err(|e| anyhow::anyhow!("{e:?}"))?
                && sample.payload().seq == seq
            {
                round_trips.push(sent.elapsed().as_secs_f64() * 1e6);
                break;
            }
            if Instant::now() > give_up {
                break;
            }
            std::hint::spin_loop();
        }
    }
    Ok(round_trips)
}

fn echo(prefix: &str, timeout: f64) -> Result<()> {
    let node = create_node().map_err(|e| anyhow::anyhow!("{e}"))?;
    let subscriber = pose_service(&node, prefix, "probe")
        .and_then(|s| {
            s.subscriber_builder()
                .create()
                .map_err(|e| IpcError::port(s.name(), "subscriber", e))
        })
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let publisher = feedback_service(&node, prefix, "probe")
        .and_then(|s| {
            s.publisher_builder()
                .create()
                .map_err(|e| IpcError::port(s.name(), "publisher", e))
        })
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let until = Instant::now() + Duration::from_secs_f64(timeout);
    while Instant::now() < until {
        match subscriber.receive().map_err(|e| anyhow::anyhow!("{e:?}"))? {
            Some(sample) => {
                let pose = *sample.payload();
                publisher
                    .send_copy(ToolFeedbackV1 {
                        seq: pose.seq,
                        device_time_ns: pose.device_time_ns,
                        ..ToolFeedbackV1::default()
                    })
                    .map_err(|e| anyhow::anyhow!("{e:?}"))?;
            }
            None => std::hint::spin_loop(),
        }
    }
    Ok(())
}

/// An icosphere of the given level, its rigid component held just above a table it rests on
/// (surface mass growing with the node count so the explicit scheme stays stable at 1 ms), optionally with an 8 mm probe pressed 5 mm into its
/// top and held.
fn scaling_world(level: u32, probe: bool) -> World {
    let nodes = 10 * 4u64.pow(level) + 2;
    let surface_mass = 0.2 * nodes as f64 / 642.0;
    let tool = if probe {
        r#"
        [[tool]]
        name = "probe"
        shape = { sphere = { radius = 0.008 } }
        input = "script"
        script = [
          { t = 0.0, position = [0.003, 0.002, 0.112] },
          { t = 0.3, position = [0.003, 0.002, 0.103] },
        ]
        "#
    } else {
        ""
    };
    let text = format!(
        r#"
        [world]
        integrator = "multirate"
        [[body]]
        name = "organ"
        mesh = {{ icosphere = {{ radius = 0.05, subdivisions = {level} }} }}
        position = [0.0, 0.0, 0.05]
        fixed = true
        surface_mass = {surface_mass}
        rigid_mass = 1.0
        [[obstacle]]
        name = "table"
        plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }}
        friction = 0.4
        {tool}
        "#
    );
    let scene = palpa::scene::parse_scene(&text, "scaling.toml", Path::new("."))
        .expect("the scaling scene is valid");
    World::from_scene(&scene)
}

fn scaling(args: ScalingArgs) -> Result<()> {
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let levels: Vec<u32> = if args.quick {
        vec![2, 3, 4]
    } else {
        vec![2, 3, 4, 5, 6]
    };
    let mut progress = Progress::new("scaling", levels.len() * 2);
    let mut rows = Vec::new();
    let mut series = [Vec::new(), Vec::new()];
    for &level in &levels {
        for (k, probe) in [false, true].into_iter().enumerate() {
            let mut world = scaling_world(level, probe);
            world.set_helper_thread(!args.one_thread);
            let nodes = world.bodies[0].node_count();
            for _ in 0..400 {
                world.step();
            }
            // At least 1 000 steps in a full run, so that the p99.9 is one of them.
            let steps = if args.quick {
                100
            } else {
                (2_000_000 / nodes).clamp(1000, 2000)
            };
            let mut profile = StepProfile::default();
            let mut times = Vec::with_capacity(steps);
            for _ in 0..steps {
                let start = Instant::now();
                world.step_profiled(&mut profile);
                times.push(start.elapsed().as_secs_f64() * 1e6);
            }
            times.sort_by(f64::total_cmp);
            let median = percentile(&times, 0.5);
            series[k].push((nodes as f64, median));
            let stages: serde_json::Map<String, serde_json::Value> = Stage::ALL
                .iter()
                .map(|&s| (s.name().to_string(), json!(profile.mean(s) * 1e6)))
                .collect();
            rows.push(json!({
                "nodes": nodes,
                "probe": probe,
                "contacts": world.tools.first().map_or(0, |t| t.feedback.contacts),
                "steps": steps,
                "median_us": median,
                "p99_us": percentile(&times, 0.99),
                "p999_us": percentile(&times, 0.999),
                "max_us": times.last().copied().unwrap_or(f64::NAN),
                "stages_mean_us": stages,
            }));
            progress.step(&format!(
                "{nodes} nodes{}",
                if probe { " + probe" } else { "" }
            ));
        }
    }
    let slope_free = loglog_slope(&series[0]);
    let slope_probe = loglog_slope(&series[1]);
    let result = json!({
        "command": format!(
            "palpa-bench scaling{}{} --out {}",
            if args.quick { " --quick" } else { "" },
            if args.one_thread { " --one-thread" } else { "" },
            args.out.display()
        ),
        "date": plot::utc_now(),
        "machine": machine(),
        "integrator": "multirate",
        "helper_thread": !args.one_thread,
        "rows": rows,
        "slope_without_probe": slope_free,
        "slope_with_probe": slope_probe,
    });
    std::fs::write(
        args.out.join("scaling.json"),
        serde_json::to_string_pretty(&result)?,
    )?;
    loglog(
        &args.out.join("scaling.svg"),
        "Step time against node count (icosphere on a table)",
        "nodes",
        "median step time (µs)",
        &[
            Series {
                name: format!("without probe (slope {slope_free:.2})"),
                points: series[0].clone(),
                points_only: false,
            },
            Series {
                name: format!("probe pressed in (slope {slope_probe:.2})"),
                points: series[1].clone(),
                points_only: false,
            },
        ],
    )?;
    let mut md = format!(
        "# palpa-bench scaling\n\n`{}` — {} — {}\n\nOne step (multi-rate integrator; {}) of an \
         icosphere (rigid component held) resting on a table, without and with an 8 mm probe pressed 5 mm into it. Fitted \
         log-log slope: {slope_free:.2} without the probe, {slope_probe:.2} with it.\n\n\
         | nodes | probe | steps | median (µs) | p99 (µs) | p99.9 (µs) | max (µs) |",
        result["command"].as_str().unwrap_or(""),
        result["date"].as_str().unwrap_or(""),
        result["machine"].as_str().unwrap_or(""),
        if args.one_thread {
            "every force pass on the step's thread"
        } else {
            "from 4 096 nodes, half of the force passes offered to the helper thread"
        }
    );
    for s in Stage::ALL {
        md += &format!(" {} |", s.name());
    }
    md += "\n| --- | --- | --- | --- | --- | --- | --- |";
    for _ in Stage::ALL {
        md += " --- |";
    }
    md += "\n";
    for row in &rows {
        md += &format!(
            "| {} | {} | {} | {:.1} | {:.1} | {:.1} | {:.1} |",
            row["nodes"],
            if row["probe"].as_bool() == Some(true) {
                "yes"
            } else {
                "no"
            },
            row["steps"],
            row["median_us"].as_f64().unwrap_or(f64::NAN),
            row["p99_us"].as_f64().unwrap_or(f64::NAN),
            row["p999_us"].as_f64().unwrap_or(f64::NAN),
            row["max_us"].as_f64().unwrap_or(f64::NAN)
        );
        for s in Stage::ALL {
            md += &format!(
                " {:.1} |",
                row["stages_mean_us"][s.name()].as_f64().unwrap_or(f64::NAN)
            );
        }
        md += "\n";
    }
    md += "\nStages (mean µs per step): forces = springs, links, gravity, air; contact = held nodes, \
           obstacle contact and the tool guard; tool_ccd = swept-box broad phase and continuous \
           detection against the tool (nodes and faces); body_contact = body–body BVH broad phase and \
           CCD (none here, one body); commit = positions and rigid component; guard = divergence guard.\n\n\
           ![scaling](scaling.svg)\n";
    std::fs::write(args.out.join("scaling.md"), &md)?;
    println!("{md}");
    Ok(())
}

/// The incision bench's scene: the incision scene's organ at 2 562 nodes on a table, and a scalpel
/// that dips 2.5 cm into its top during the first half second, is drawn 10 cm along x in the next
/// second and lifts off. With `cut` false the blade follows the same path 6 cm higher, above the
/// organ: the same scene and systems, no cut.
fn incision_world(args: &CutArgs, cut: bool) -> World {
    let lift = if cut { 0.0 } else { 0.06 };
    let (high, low, off) = (0.10 + lift, 0.055 + lift, 0.12 + lift);
    let (integrator, surface_mass) = (&args.integrator, args.surface_mass);
    let text = format!(
        r#"
        [world]
        gravity = [0.0, 0.0, -9.81]
        integrator = "{integrator}"
        [[body]]
        name = "organ"
        mesh = {{ ellipsoid = {{ radii = [0.08, 0.05, 0.04], subdivisions = 4 }} }}
        position = [0.0, 0.0, 0.04]
        surface_mass = {surface_mass}
        rigid_mass = 1.0
        surface_stiffness = 40.0
        surface_damping = 0.02
        link_stiffness = 30.0
        link_damping = 0.08
        friction = 0.3
        cutting = {{ prestress = 0.1 }}
        [[obstacle]]
        name = "table"
        plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }}
        friction = 0.5
        static_friction = 0.7
        [[tool]]
        name = "scalpel"
        shape = {{ blade = {{ length = 0.03, thickness = 0.0005 }} }}
        input = "script"
        script = [
          {{ t = 0.0, position = [-0.05, 0.001, {high}] }},
          {{ t = 0.5, position = [-0.05, 0.001, {low}] }},
          {{ t = 1.5, position = [0.05, 0.001, {low}] }},
          {{ t = 2.0, position = [0.05, 0.001, {off}] }},
        ]
        "#
    );
    let scene = palpa::scene::parse_scene(&text, "incision_bench.toml", Path::new("."))
        .expect("the incision bench scene is valid");
    World::from_scene(&scene)
}

/// Ticks the bench runs: through the descent, the 1 s draw and the lift-off.
const CUT_TICKS: usize = 2000;
/// The draw: ticks 500 to 1 500 (t = 0.5 s to 1.5 s).
const DRAW: std::ops::Range<usize> = 500..1500;

/// Tick times (µs) of one run, and per tick the time in the cut stage (µs) and whether it cut.
struct CutRun {
    ticks: Vec<f64>,
    cut_stage: Vec<f64>,
    cut: Vec<bool>,
    boundary_edges: u32,
    profile: StepProfile,
}

fn run_incision(args: &CutArgs, cut: bool) -> CutRun {
    let mut world = incision_world(args, cut);
    let mut profile = StepProfile::default();
    let mut run = CutRun {
        ticks: Vec::with_capacity(CUT_TICKS),
        cut_stage: Vec::with_capacity(CUT_TICKS),
        cut: Vec::with_capacity(CUT_TICKS),
        boundary_edges: 0,
        profile: StepProfile::default(),
    };
    for _ in 0..CUT_TICKS {
        let before = profile.seconds[Stage::Cut as usize];
        let start = Instant::now();
        world.step_profiled(&mut profile);
        run.ticks.push(start.elapsed().as_secs_f64() * 1e6);
        run.cut_stage
            .push((profile.seconds[Stage::Cut as usize] - before) * 1e6);
        run.cut.push(world.counters.cuts > 0);
    }
    run.boundary_edges =
        palpa::topology::cut::count_boundary_edges(&world.bodies[0].surface.triangles);
    run.profile = profile;
    run
}

/// Time of the transection stage (µs) and of the whole tick on the tick `scenes/transection.toml`'s
/// tube is cut through, with that tick's number and the bodies after it.
fn run_transection() -> Result<(f64, f64, u64, usize)> {
    let text = include_str!("../../scenes/transection.toml");
    let scene = palpa::scene::parse_scene(text, "transection.toml", Path::new("."))
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut world = World::from_scene(&scene);
    let mut profile = StepProfile::default();
    for _ in 0..2000 {
        let before = profile.seconds[Stage::Transection as usize];
        let start = Instant::now();
        world.step_profiled(&mut profile);
        let tick = start.elapsed().as_secs_f64() * 1e6;
        if world.counters.transections > 0 {
            let stage = (profile.seconds[Stage::Transection as usize] - before) * 1e6;
            return Ok((stage, tick, world.tick, world.bodies.len()));
        }
    }
    bail!("the transection scene's tube was not cut through in 2 s")
}

/// One markdown table row of a [`spread_of`] summary.
fn spread_row(name: &str, v: &serde_json::Value) -> String {
    format!(
        "| {name} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} |\n",
        v["samples"],
        v["mean_us"].as_f64().unwrap_or(f64::NAN),
        v["p50_us"].as_f64().unwrap_or(f64::NAN),
        v["p99_us"].as_f64().unwrap_or(f64::NAN),
        v["p999_us"].as_f64().unwrap_or(f64::NAN),
        v["max_us"].as_f64().unwrap_or(f64::NAN),
    )
}

fn spread_of(mut values: Vec<f64>) -> serde_json::Value {
    values.sort_by(f64::total_cmp);
    let mean = values.iter().sum::<f64>() / values.len().max(1) as f64;
    json!({
        "samples": values.len(),
        "mean_us": mean,
        "p50_us": percentile(&values, 0.5),
        "p99_us": percentile(&values, 0.99),
        "p999_us": percentile(&values, 0.999),
        "max_us": values.last().copied().unwrap_or(f64::NAN),
    })
}

/// Tick times (µs) of `text` (a scene) over the ticks `window`.
fn scene_ticks(text: &str, name: &str, window: std::ops::Range<u64>) -> Result<Vec<f64>> {
    let scene = palpa::scene::parse_scene(text, name, Path::new("."))
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut world = World::from_scene(&scene);
    let mut ticks = Vec::with_capacity(window.end as usize);
    for tick in 1..window.end {
        let start = Instant::now();
        world.step();
        let elapsed = start.elapsed().as_secs_f64() * 1e6;
        if window.contains(&tick) {
            ticks.push(elapsed);
        }
    }
    Ok(ticks)
}

/// `count` organs (ellipsoids 8 × 6 × 3 cm of `subdivisions`) on the table: `apart` in a row 4 cm
/// from each other, `touching` side by side in a row (0.5 mm apart, within the contact skin),
/// `stacked` in stacks of two (each organ on the table or resting on the one below; the stacks in
/// a row, 4 cm apart), or `tower`, all one on another (three or more of these soft, rounded organs
/// topple: the upper ones fall off and slide, and the case measures a heap settling). Of the
/// `parameters`: `bench`, the bench's organs (stiffer springs and links, lighter nodes: every node
/// and the rigid component sub-stepped by the multi-rate integrator, four substeps a tick);
/// `uterus`, those of `scenes/laparoscopy.toml`'s uterus (no node sub-stepped; an organ that keeps
/// its shape); `default`, the scene format's defaults (no node sub-stepped at 162 nodes; a heavy
/// rigid component on soft links: an organ alone sags to half its height, and one under another
/// is pressed flat onto the table).
fn bodies_scene(count: usize, subdivisions: u32, layout: &str, parameters: &str) -> String {
    let mut text = String::from(
        "[world]\nair_viscosity = 1.0\n\n[[obstacle]]\nname = \"table\"\nplane = { point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }\nfriction = 0.5\nstatic_friction = 0.7\n",
    );
    for k in 0..count {
        let (x, z) = match layout {
            "apart" => (k as f64 * 0.12, 0.0155),
            "touching" => (k as f64 * 0.0805, 0.0155),
            "stacked" => ((k / 2) as f64 * 0.12, 0.0155 + (k % 2) as f64 * 0.0305),
            _ => (0.0, 0.0155 + k as f64 * 0.0305),
        };
        text += &format!(
            "\n[[body]]\nname = \"organ{k}\"\nmesh = {{ ellipsoid = {{ radii = [0.04, 0.03, 0.015], subdivisions = {subdivisions} }} }}\nposition = [{x}, 0.0, {z}]\n"
        );
        // (Masses raised with the node count, so that each node weighs the same.)
        let scale = 4f64.powi(subdivisions as i32 - 2);
        match parameters {
            "bench" => {
                text += &format!(
                    "surface_mass = {}\nrigid_mass = 0.2\nsurface_stiffness = 100.0\nsurface_damping = 0.05\nlink_stiffness = 200.0\nlink_damping = 0.3\nfriction = 0.4\n",
                    0.1 * scale
                )
            }
            "uterus" => {
                text += &format!(
                    "surface_mass = {}\nrigid_mass = 0.03\nsurface_stiffness = 12.0\nsurface_damping = 0.02\nlink_stiffness = 50.0\nlink_damping = 0.05\nfriction = 0.3\n",
                    0.06 * scale
                )
            }
            _ => {}
        }
    }
    text
}

/// A 5 kg organ laid on a 0.06 kg one of a tenth of the default stiffnesses (ellipsoids of
/// `subdivisions`), which it crushes flat against the table (the pair of
/// `tests/body_contact.rs`' `HEAVY_ON_FLIMSY`).
fn crushed_scene(subdivisions: u32) -> String {
    format!(
        "[[obstacle]]\nname = \"table\"\nplane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }}\n\n\
         [[body]]\nname = \"light\"\nmesh = {{ ellipsoid = {{ radii = [0.08, 0.06, 0.03], subdivisions = {subdivisions} }} }}\n\
         position = [0.0, 0.0, 0.0301]\nsurface_mass = 0.02\nrigid_mass = 0.04\nsurface_stiffness = 20.0\nlink_stiffness = 10.0\n\n\
         [[body]]\nname = \"heavy\"\nmesh = {{ ellipsoid = {{ radii = [0.06, 0.05, 0.04], subdivisions = {subdivisions} }} }}\n\
         position = [0.0, 0.0, 0.11]\nsurface_mass = 1.0\nrigid_mass = 4.0\nsurface_stiffness = 80.0\nlink_stiffness = 60.0\n"
    )
}

/// `reps` runs of `scene` stepped to the end of `window`: the ticks' times in `window` (µs), and
/// the collisions the net answered over them.
fn ticks_and_net_collisions(
    scene: &palpa::Scene,
    window: std::ops::Range<u64>,
    reps: usize,
    (progress, what): (&mut Progress, &str),
) -> (Vec<f64>, u64) {
    let (mut ticks, mut net) = (Vec::new(), 0u64);
    for _ in 0..reps {
        let mut world = World::from_scene(scene);
        for tick in 0..window.end {
            let start = Instant::now();
            world.step();
            if window.contains(&tick) {
                ticks.push(start.elapsed().as_secs_f64() * 1e6);
                net += u64::from(world.counters.bodies.collisions);
            }
        }
        progress.step(what);
    }
    (ticks, net)
}

/// The shipped two-organ scene (a soft ball dropped on an organ), for the landing's cost.
const TWO_ORGANS: &str = include_str!("../../scenes/two_organs.toml");

fn bodies(args: GraspArgs) -> Result<()> {
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let reps = if args.quick { 1 } else { 3 };
    let levels: &[u32] = if args.quick { &[2] } else { &[2, 3] };
    let counts: &[usize] = if args.quick { &[2] } else { &[2, 4] };
    let layouts = ["apart", "touching", "stacked", "tower"];
    let mut cases = Vec::new();
    for &level in levels {
        for &count in counts {
            // Two organs in a tower are a stack of two.
            for layout in layouts.into_iter().filter(|&l| l != "tower" || count > 2) {
                cases.push((level, count, layout, "bench"));
            }
        }
        // Two organs whose own tick is cheap (no node sub-stepped), apart and stacked: the
        // uterus's parameters, and the defaults (the upper one pressing the lower one flat).
        for parameters in ["uterus", "default"] {
            for layout in ["apart", "stacked"] {
                cases.push((level, 2, layout, parameters));
            }
        }
    }
    let mut progress = Progress::new("bodies", cases.len() * reps + (2 + levels.len()) * reps);
    let command = format!(
        "palpa-bench bodies{} --out {}",
        if args.quick { " --quick" } else { "" },
        args.out.display()
    );
    let mut md = format!(
        "# palpa-bench bodies\n\n`{command}` — {} — {}\n\n\
         Organs (ellipsoids 8 × 6 × 3 cm) on a table, `apart` (4 cm gaps), `touching` (side by side, \
         0.5 mm apart: within the contact skin), `stacked` (stacks of two, 4 cm apart: each organ resting \
         on the table or on the one below) or `tower` (all one on another: they topple, and the upper \
         ones fall and slide, so this measures a heap settling, bodies in moving contact); 1.5 s to \
         settle, then 1 s measured with `World::step_profiled`, {reps} run(s) each (the cases in turn \
         in each round of runs), the best kept (the least mean tick). *body contact*: the body–body stage (response and collision net) per \
         tick; *tick*: the whole tick. *Parameters*: `bench`, stiffer springs and links on light nodes \
         (every node and the rigid component sub-stepped, four substeps a tick: a costly tick of the \
         organs' own); `uterus`, those of the laparoscopy scene's uterus (no node sub-stepped: a cheap \
         tick of their own; an organ that keeps its shape); `default`, the scene format's defaults (a \
         cheap tick too; a heavy rigid component on soft links, so that the lower organ is pressed \
         flat onto the table by the upper one, and their contact spans the organs).\n\n\
         | nodes per organ | organs | parameters | layout | body contact (µs) | tick (µs) | contacts per tick | ratio to apart |\n\
         | --- | --- | --- | --- | --- | --- | --- | --- |\n",
        plot::utc_now(),
        machine()
    );
    let mut rows = Vec::new();
    let mut apart_tick = 0.0;
    let scenes = cases
        .iter()
        .map(|&(level, count, layout, parameters)| {
            palpa::scene::parse_scene(
                &bodies_scene(count, level, layout, parameters),
                layout,
                Path::new("."),
            )
            .map_err(|e| anyhow::anyhow!("{e}"))
        })
        .collect::<Result<Vec<_>>>()?;
    // The best of the runs of each case (the least mean tick, with its stage and contacts), the
    // cases taken in turn in each round of runs: a slow spell of the shared machine falls on one
    // run of several cases, not on every run of one.
    let mut best = vec![(0usize, f64::INFINITY, 0.0, 0.0); cases.len()];
    for _ in 0..reps {
        for ((&(_, _, layout, _), scene), best) in cases.iter().zip(&scenes).zip(best.iter_mut()) {
            let mut world = World::from_scene(scene);
            let nodes = world.bodies[0].node_count();
            for _ in 0..1500 {
                world.step();
            }
            let mut profile = StepProfile::default();
            let mut seen = 0u64;
            let started = Instant::now();
            for _ in 0..1000 {
                world.step_profiled(&mut profile);
                seen += u64::from(world.counters.bodies.contacts);
            }
            let tick = started.elapsed().as_secs_f64() * 1e6 / 1000.0;
            if tick < best.1 {
                let stage = profile.mean(Stage::BodyContact) * 1e6;
                *best = (nodes, tick, stage, seen as f64 / 1000.0);
            }
            progress.step(layout);
        }
    }
    for (&(_, count, layout, parameters), &(nodes, tick, stage, contacts)) in
        cases.iter().zip(&best)
    {
        if layout == "apart" {
            apart_tick = tick;
        }
        md += &format!(
            "| {nodes} | {count} | {parameters} | {layout} | {stage:.1} | {tick:.1} | {contacts:.0} | {:.2} |\n",
            tick / apart_tick
        );
        rows.push(json!({
            "nodes_per_body": nodes, "bodies": count, "parameters": parameters, "layout": layout,
            "body_contact_us": stage, "tick_us": tick, "contacts_per_tick": contacts,
            "ratio_to_apart": tick / apart_tick,
        }));
    }
    // The laparoscopy scene with the demo's two devices as scripts: the tick distribution over 6 s.
    let mut scene = palpa::scene::built_in_scene("laparoscopy")
        .expect("built in")
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let seconds = 6.0;
    let devices = palpa::device::run::devices_for_scene(&scene, "bench", seconds);
    for (tool, device) in scene.tools.iter_mut().zip(&devices) {
        tool.input = palpa::tool::ToolInput::Script(match &device.path {
            palpa::device::run::HandPath::Script(keys) => keys.clone(),
            palpa::device::run::HandPath::BuiltIn { motion, at, seed } => (0..=600)
                .map(|i| {
                    let t = i as f64 * 0.01;
                    palpa::tool::Keyframe {
                        t,
                        pose: palpa::tool::ToolPose {
                            position_in_world: palpa::device::run::built_in_target(
                                *motion, at, t, *seed,
                            ),
                            ..Default::default()
                        },
                        jaw: 0.0,
                    }
                })
                .collect(),
        });
    }
    let mut ticks = Vec::new();
    let mut profile = StepProfile::default();
    for _ in 0..reps {
        let mut world = World::from_scene(&scene);
        for tick in 0..(seconds * 1000.0) as u64 {
            let start = Instant::now();
            world.step_profiled(&mut profile);
            if tick >= 500 {
                ticks.push(start.elapsed().as_secs_f64() * 1e6);
            }
        }
        progress.step("laparoscopy");
    }
    let spread = spread_of(ticks);
    md += &format!(
        "\n`scenes/laparoscopy.toml` ({} bodies, the demo's probe palpating and grasper lifting, as scripts), \
         ticks 500–6 000, {reps} run(s) pooled:\n\n\
         | scene | samples | mean (µs) | p50 | p99 | p99.9 | max |\n\
         | --- | --- | --- | --- | --- | --- | --- |\n",
        scene.bodies.len()
    );
    md += &spread_row("laparoscopy", &spread);
    md += "\nMean per stage (µs):\n\n| stage | µs |\n| --- | --- |\n";
    let mut stages = serde_json::Map::new();
    for stage in Stage::ALL {
        let us = profile.mean(stage) * 1e6;
        md += &format!("| {} | {us:.1} |\n", stage.name());
        stages.insert(stage.name().into(), json!(us));
    }
    // A ball's landing (`scenes/two_organs.toml`, ticks 100–300: the impact), with what the
    // collision net answered over it.
    let landing = palpa::scene::parse_scene(TWO_ORGANS, "scenes/two_organs.toml", Path::new("."))
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let (landing_ticks, net_collisions) =
        ticks_and_net_collisions(&landing, 100..300, reps, (&mut progress, "landing"));
    let landing_spread = spread_of(landing_ticks);
    let net_per_run = net_collisions / reps as u64;
    md += &format!(
        "\n`scenes/two_organs.toml` (a soft ball landing on an organ), ticks 100–300, {reps} run(s) \
         pooled; the collision net answered {net_per_run} collisions a run:\n\n\
         | scene | samples | mean (µs) | p50 | p99 | p99.9 | max |\n\
         | --- | --- | --- | --- | --- | --- | --- |\n"
    );
    md += &spread_row("two_organs landing", &landing_spread);
    // A light organ crushed flat against the table by a heavy one (5 kg on 0.06 kg), ticks
    // 500–1 000: where the response's contacts hold least and the net answers most.
    md += &format!(
        "\nA 5 kg organ crushing a 0.06 kg one against the table, ticks 500–1 000, {reps} run(s) \
         pooled:\n\n\
         | nodes per organ | samples | mean (µs) | p50 | p99 | p99.9 | max | net collisions a tick |\n\
         | --- | --- | --- | --- | --- | --- | --- | --- |\n"
    );
    let mut crushed = Vec::new();
    for &level in levels {
        let scene = palpa::scene::parse_scene(&crushed_scene(level), "crushed", Path::new("."))
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        let nodes = World::from_scene(&scene).bodies[0].node_count();
        let (ticks, net) =
            ticks_and_net_collisions(&scene, 500..1000, reps, (&mut progress, "crushed"));
        let per_tick = net as f64 / ticks.len().max(1) as f64;
        let spread = spread_of(ticks);
        // (The spread's row, with the net's collisions a tick as a last column.)
        let row = spread_row(&nodes.to_string(), &spread);
        md += &format!("{} {per_tick:.1} |\n", row.trim_end());
        crushed.push(json!({
            "nodes_per_body": nodes, "ticks": spread, "net_collisions_per_tick": per_tick,
        }));
    }
    let result = json!({
        "command": command, "date": plot::utc_now(), "machine": machine(), "repetitions": reps,
        "layouts": rows, "laparoscopy": spread, "laparoscopy_stages_us": stages,
        "landing": landing_spread, "landing_net_collisions_per_run": net_per_run,
        "crushed": crushed,
    });
    std::fs::write(
        args.out.join("bodies.json"),
        serde_json::to_string_pretty(&result)?,
    )?;
    std::fs::write(args.out.join("bodies.md"), &md)?;
    print!("{md}");
    Ok(())
}

fn grasp(args: GraspArgs) -> Result<()> {
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let reps = if args.quick { 1 } else { 3 };
    // Grasp and lift: scenes/grasp_lift.toml with a 2 562-node organ, from the jaws closing to the
    // end of the hold; without: the same jaws coming down and going up open.
    // (Its surface mass raised with the node count, as in `palpa-bench cut`, so that each node
    // stays as heavy as the 162-node scene's within a factor of 2.)
    let lift = include_str!("../../scenes/grasp_lift.toml")
        .replace("subdivisions = 2", "subdivisions = 4")
        .replace("surface_mass = 0.03", "surface_mass = 0.25");
    let lift_open = lift.replace("jaw = 0.0 }", "jaw = 1.2 }");
    let tear = include_str!("../../scenes/tear.toml").to_string();
    // The same scene with the body's `tearing` line switched off (whatever its keys).
    let tear_off: String = tear
        .lines()
        .map(|line| {
            if line.starts_with("tearing = ") {
                "tearing = { enabled = false }"
            } else {
                line
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    anyhow::ensure!(
        tear_off.contains("tearing = { enabled = false }"),
        "scenes/tear.toml has no `tearing = ` line to switch off"
    );
    let cases = [
        ("grasp_lift", &lift, 2000..8800),
        ("open_jaws", &lift_open, 2000..8800),
        ("tear", &tear, 1000..4200),
        ("no_tearing", &tear_off, 1000..4200),
    ];
    let mut progress = Progress::new("grasp", cases.len() * reps);
    let mut pooled: Vec<Vec<f64>> = vec![Vec::new(); cases.len()];
    for _ in 0..reps {
        for (k, (name, text, window)) in cases.iter().enumerate() {
            pooled[k].extend(scene_ticks(text, name, window.clone())?);
            progress.step(name);
        }
    }
    let command = format!(
        "palpa-bench grasp{} --out {}",
        if args.quick { " --quick" } else { "" },
        args.out.display()
    );
    let mut result = serde_json::Map::new();
    result.insert("command".into(), json!(command));
    result.insert("date".into(), json!(plot::utc_now()));
    result.insert("machine".into(), json!(machine()));
    result.insert("repetitions".into(), json!(reps));
    let mut md = format!(
        "# palpa-bench grasp\n\n`{command}` — {} — {}\n\n\
         *grasp_lift*: `scenes/grasp_lift.toml` with a 2 562-node organ (surface mass 0.25 kg), ticks 2 000–8 800 (jaws \
         closing, lift, 5 s hold); *open_jaws*: the same with the jaws kept open. *tear*: \
         `scenes/tear.toml` (642 nodes), ticks 1 000–4 200 (grasp and pull); *no_tearing*: the same \
         with tearing off. {reps} run(s) each, pooled.\n\n\
         | scene | samples | mean (µs) | p50 | p99 | p99.9 | max |\n\
         | --- | --- | --- | --- | --- | --- | --- |\n",
        plot::utc_now(),
        machine()
    );
    for ((name, _, _), ticks) in cases.iter().zip(pooled) {
        let v = spread_of(ticks);
        md += &spread_row(name, &v);
        result.insert(name.to_string(), v);
    }
    std::fs::write(
        args.out.join("grasp.json"),
        serde_json::to_string_pretty(&serde_json::Value::Object(result))?,
    )?;
    std::fs::write(args.out.join("grasp.md"), &md)?;
    print!("{md}");
    Ok(())
}

fn cut(args: CutArgs) -> Result<()> {
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let reps = if args.quick { 1 } else { 5 };
    let mut progress = Progress::new("cut", 3 * reps);
    let (mut with_cut, mut without) = (Vec::new(), Vec::new());
    let (mut step_costs, mut whole_run_max) = (Vec::new(), [0.0f64; 2]);
    let mut boundary_edges = 0;
    let mut cut_ticks = 0;
    let mut transections = Vec::new();
    let mut transection_ticks = Vec::new();
    let mut transection_at = (0, 0);
    let mut stages = [StepProfile::default(), StepProfile::default()];
    for rep in 0..reps {
        // Alternate the order, so neither variant always runs on a warmer machine.
        for cut in if rep % 2 == 0 {
            [true, false]
        } else {
            [false, true]
        } {
            let run = run_incision(&args, cut);
            let slot = &mut stages[usize::from(!cut)];
            for (sum, s) in slot.seconds.iter_mut().zip(run.profile.seconds) {
                *sum += s;
            }
            slot.steps += run.profile.steps;
            let max = run.ticks.iter().copied().fold(0.0, f64::max);
            if cut {
                with_cut.extend_from_slice(&run.ticks[DRAW]);
                whole_run_max[0] = whole_run_max[0].max(max);
                step_costs.extend(
                    run.cut_stage
                        .iter()
                        .zip(&run.cut)
                        .filter(|(_, c)| **c)
                        .map(|(t, _)| *t),
                );
                cut_ticks = run.cut.iter().filter(|c| **c).count();
                boundary_edges = run.boundary_edges;
            } else {
                if run.cut.iter().any(|c| *c) {
                    bail!("the blade above the organ cut it");
                }
                without.extend_from_slice(&run.ticks[DRAW]);
                whole_run_max[1] = whole_run_max[1].max(max);
            }
            progress.step(if cut { "incision" } else { "no cut" });
        }
        let (stage, tick, at, bodies) = run_transection()?;
        transections.push(stage);
        transection_ticks.push(tick);
        transection_at = (at, bodies);
        progress.step("transection");
    }
    if boundary_edges == 0 {
        bail!("the incision opened nothing");
    }
    let command = format!(
        "palpa-bench cut{} --integrator {} --surface-mass {} --out {}",
        if args.quick { " --quick" } else { "" },
        args.integrator,
        args.surface_mass,
        args.out.display()
    );
    let cut_spread = spread_of(with_cut.clone());
    let plain_spread = spread_of(without.clone());
    let result = json!({
        "command": command,
        "date": plot::utc_now(),
        "machine": machine(),
        "integrator": args.integrator,
        "surface_mass": args.surface_mass,
        "nodes": incision_world(&args, true).bodies[0].node_count(),
        "repetitions": reps,
        "draw_ticks": DRAW.len(),
        "with_cut": cut_spread,
        "without_cut": plain_spread,
        "max_whole_run_us": { "with_cut": whole_run_max[0], "without_cut": whole_run_max[1] },
        "cut_ticks_per_run": cut_ticks,
        "boundary_edges": boundary_edges,
        "incision_step": spread_of(step_costs),
        "transection": {
            "tick": transection_at.0,
            "bodies_after": transection_at.1,
            "stage": spread_of(transections),
            "whole_tick": spread_of(transection_ticks),
        },
        "goal_p999_us": 500.0,
        "stages_mean_us": stages.iter().zip(["with_cut", "without_cut"]).map(|(p, name)| {
            (name.to_string(), json!(Stage::ALL
                .iter()
                .map(|&s| (s.name().to_string(), json!(p.mean(s) * 1e6)))
                .collect::<serde_json::Map<String, serde_json::Value>>()))
        }).collect::<serde_json::Map<String, serde_json::Value>>(),
    });
    std::fs::write(
        args.out.join("cut.json"),
        serde_json::to_string_pretty(&result)?,
    )?;
    // Both tick distributions over the draw, on one pair of histograms.
    let hi = with_cut
        .iter()
        .chain(&without)
        .copied()
        .fold(0.0f64, f64::max)
        .max(1.0);
    let bins = 60;
    let width = hi / bins as f64;
    for (name, values) in [("cut_ticks.svg", &with_cut), ("no_cut_ticks.svg", &without)] {
        let mut counts = vec![0u64; bins];
        for v in values {
            counts[((v / width) as usize).min(bins - 1)] += 1;
        }
        let bars: Vec<(f64, f64, u64)> = counts
            .iter()
            .enumerate()
            .map(|(k, &n)| (k as f64 * width, (k + 1) as f64 * width, n))
            .collect();
        histogram(
            &args.out.join(name),
            if name.starts_with("cut") {
                "Tick time while the blade draws a 10 cm cut (2 562 nodes)"
            } else {
                "Tick time, same scene, blade above the organ"
            },
            "tick time (µs)",
            &bars,
        )?;
    }
    let row = spread_row;
    let mut md = format!(
        "# palpa-bench cut\n\n`{command}` — {} — {}\n\n\
         A scalpel draws a 10 cm incision in 1 s across the top of a {}-node organ ({} \
         integrator, prestress 0.1, one thread); {reps} run(s) of each variant, ticks of the draw \
         (t = 0.5 s to 1.5 s) pooled. *No cut*: the same scene with the blade 6 cm higher. \
         The cut opened {boundary_edges} boundary edges on {cut_ticks} cutting ticks per run. \
         Goal: p99.9 ≤ 500 µs during the cut.\n\n\
         | ticks | samples | mean (µs) | p50 | p99 | p99.9 | max |\n\
         | --- | --- | --- | --- | --- | --- | --- |\n",
        result["date"].as_str().unwrap_or(""),
        result["machine"].as_str().unwrap_or(""),
        result["nodes"],
        result["integrator"].as_str().unwrap_or("?"),
    );
    md += &row("with the cut", &result["with_cut"]);
    md += &row("no cut", &result["without_cut"]);
    md += &row("incision step (cut stage)", &result["incision_step"]);
    md += &row(
        "transection stage (434-node tube)",
        &result["transection"]["stage"],
    );
    md += &row(
        "transection tick (whole)",
        &result["transection"]["whole_tick"],
    );
    md += &format!(
        "\nLargest tick over the whole run (descent, draw, lift-off): {:.1} µs with the cut, \
         {:.1} µs without. The transection happens at tick {} of `scenes/transection.toml`.\n\n\
         Mean µs per tick and stage over the whole runs:\n\n| stage | with the cut | no cut |\n| --- | --- | --- |\n",
        whole_run_max[0], whole_run_max[1], transection_at.0
    );
    for s in Stage::ALL {
        md += &format!(
            "| {} | {:.1} | {:.1} |\n",
            s.name(),
            stages[0].mean(s) * 1e6,
            stages[1].mean(s) * 1e6
        );
    }
    md += "\n![with the cut](cut_ticks.svg)\n![no cut](no_cut_ticks.svg)\n";
    std::fs::write(args.out.join("cut.md"), &md)?;
    println!("{md}");
    Ok(())
}

/// The organ of `palpa-bench reference`: an icosphere of radius 5 cm, its rigid component held, under
/// gravity, with nothing to touch (surface mass growing with the node count, as in `scaling`, so that
/// the explicit step stays stable at 1 ms).
fn reference_world(subdivisions: u32, integrator: &str) -> Result<World> {
    let nodes = 10 * 4u64.pow(subdivisions) + 2;
    let surface_mass = 0.2 * nodes as f64 / 642.0;
    let text = format!(
        "[world]\nintegrator = \"{integrator}\"\n[[body]]\nname = \"organ\"\n\
         mesh = {{ icosphere = {{ radius = 0.05, subdivisions = {subdivisions} }} }}\n\
         position = [0.0, 0.0, 0.1]\nfixed = true\nsurface_mass = {surface_mass}\nrigid_mass = 1.0\n\
         air_viscosity = 0.5\n"
    );
    let scene = palpa::scene::parse_scene(&text, "reference.toml", Path::new("."))
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(World::from_scene(&scene))
}

fn reference_comparison(args: ReferenceArgs) -> Result<()> {
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let steps = args.steps.unwrap_or(if args.quick { 200 } else { 2000 });
    // Both step the same system: after 200 steps from rest the nodes agree to round-off.
    let mut world = reference_world(args.subdivisions, &args.integrator)?;
    let gravity = world.params.gravity;
    let dt = world.params.dt;
    let mut plain = reference::Reference::from_body(&world.bodies[0], &gravity, dt);
    for _ in 0..200 {
        world.step();
        plain.step();
    }
    let body = &world.bodies[0];
    let nodes = body.node_count();
    let (mut gap, mut sag) = (0.0f64, 0.0f64);
    for i in 0..nodes {
        gap = gap.max((body.surface.position_in_world[i] - plain.position(i)).norm());
        sag = sag
            .max((body.surface.position_in_world[i] - body.surface.homologue_in_world[i]).norm());
    }
    if gap.is_nan() || gap > 1e-9 * sag.max(1e-6) {
        bail!(
            "palpa and the reference disagree: nodes {gap:.3e} m apart after 200 steps (deflection {sag:.3e} m)"
        );
    }
    println!(
        "same system: {nodes} nodes, {} edges; after 200 steps the largest gap is {gap:.2e} m (deflection {sag:.2e} m)",
        body.edges.len()
    );
    // palpa as it runs (a body this large offers half of its force passes to the world's helper
    // thread), palpa on the step's thread alone, and the plain reference.
    let mut best = [f64::INFINITY; 3];
    let mut all = [Vec::new(), Vec::new(), Vec::new()];
    let mut helped = (0u64, 0u64);
    for _run in 0..3 {
        let mut times = [0.0; 3];
        for (k, helper) in [true, false].into_iter().enumerate() {
            let mut world = reference_world(args.subdivisions, &args.integrator)?;
            world.set_helper_thread(helper);
            for _ in 0..100 {
                world.step();
            }
            let before = world.helper_counts();
            let start = Instant::now();
            for _ in 0..steps {
                world.step();
            }
            times[k] = start.elapsed().as_secs_f64() * 1e6 / steps as f64;
            if helper {
                let after = world.helper_counts();
                helped.0 += after.0 - before.0;
                helped.1 += after.1 - before.1;
            }
        }
        let mut plain = reference::Reference::from_body(&world.bodies[0], &gravity, dt);
        for _ in 0..100 {
            plain.step();
        }
        let start = Instant::now();
        for _ in 0..steps {
            plain.step();
        }
        times[2] = start.elapsed().as_secs_f64() * 1e6 / steps as f64;
        std::hint::black_box(&plain.reaction);
        for (k, us) in times.into_iter().enumerate() {
            best[k] = best[k].min(us);
            all[k].push(us);
        }
    }
    let plain_best = best[2];
    let one_thread_ratio = best[1] / plain_best;
    let helper_share = if helped.0 > 0 {
        helped.1 as f64 / helped.0 as f64
    } else {
        0.0
    };
    let ratio = best[0] / plain_best;
    // The cost of rebuilding the edge batches (what a topology change of this body costs the force
    // stage): least of 20.
    let rebuild_us = {
        let body = &world.bodies[0];
        let mut kernel = palpa::dynamics::kernel::ForceKernel::new(body);
        let mut least = f64::INFINITY;
        for _ in 0..20 {
            kernel.invalidate();
            let start = Instant::now();
            kernel.refresh(body);
            least = least.min(start.elapsed().as_secs_f64() * 1e6);
        }
        least
    };
    // Following a cut-sized change instead (what the world does): 16 springs cut in two where
    // their ends were (the kept half's rest length and stiffness change, the other half is a new
    // spring to a new node), on a body cut once already (the first cut of a body also ends its
    // uniform stiffness): the patch of the batches, least of 20.
    let patch_us = {
        let body = &world.bodies[0];
        let edges = body.edges.len();
        let split = |body: &palpa::body::Body, phase: usize| {
            let mut changed = body.clone();
            for i in 0..16 {
                let k = (i * edges + phase) / 16;
                let node = changed.node_count() as u32;
                changed.surface.position_in_world.push(palpa::Vec3::zeros());
                let e = &mut changed.edges;
                let (far, rest, stiffness, damping) =
                    (e.b[k], e.rest_length[k], e.stiffness[k], e.damping[k]);
                e.b[k] = node;
                e.rest_length[k] = 0.5 * rest;
                e.stiffness[k] = 2.0 * stiffness;
                e.push(node, far, 0.5 * rest, 2.0 * stiffness, damping);
            }
            changed
        };
        let first = split(body, 0);
        let second = split(&first, edges / 32);
        let mut least = f64::INFINITY;
        // One scratch, as a body keeps it (its pages touched by the first round).
        let mut batches = palpa::dynamics::kernel::EdgeBatches::with_capacity(
            second.node_count(),
            second.edges.len(),
        );
        for _ in 0..20 {
            batches.rebuild(&body.edges, body.node_count());
            let followed = batches.patch(&first.edges, first.node_count());
            let start = Instant::now();
            let followed = followed && batches.patch(&second.edges, second.node_count());
            least = least.min(start.elapsed().as_secs_f64() * 1e6);
            assert!(followed, "the patch did not follow a cut-sized change");
        }
        least
    };
    let result = json!({
        "command": format!(
            "palpa-bench reference --subdivisions {} --integrator {}{} --out {}",
            args.subdivisions,
            args.integrator,
            if args.quick { " --quick" } else { "" },
            args.out.display()
        ),
        "date": plot::utc_now(),
        "machine": machine(),
        "nodes": nodes,
        "edges": world.bodies[0].edges.len(),
        "steps_per_run": steps,
        "palpa_tick_us": all[0],
        "palpa_one_thread_tick_us": all[1],
        "reference_step_us": all[2],
        "palpa_best_us": best[0],
        "palpa_one_thread_best_us": best[1],
        "reference_best_us": plain_best,
        "ratio": ratio,
        "one_thread_ratio": one_thread_ratio,
        "helper_parts_posted": helped.0,
        "helper_parts_taken": helped.1,
        "palpa_ns_per_node": best[0] * 1e3 / nodes as f64,
        "largest_gap_m": gap,
        "batch_rebuild_us": rebuild_us,
        "batch_patch_us": patch_us,
    });
    let md = format!(
        "# palpa-bench reference\n\n`{}` — {} — {}\n\n{nodes} nodes, {} edges, no contact, {steps} steps a run, best of 3:\n\n\
         | | µs per step | ns per node |\n| --- | --- | --- |\n\
         | palpa ({}) | {:.1} | {:.1} |\n| palpa, the step's thread alone | {:.1} | {:.1} |\n| plain reference | {:.1} | {:.1} |\n\n\
         Ratio palpa / reference: **{ratio:.3}** (goal ≤ 0.25); on the step's thread alone {one_thread_ratio:.3}. \
         The helper thread joined {:.0} % of the force passes offered to it. Largest node gap after 200 steps: {gap:.2e} m. \
         Colouring the edge batches again: {rebuild_us:.1} µs; following a cut-sized change (16 springs cut in two) with a patch instead: {patch_us:.1} µs.\n",
        result["command"].as_str().unwrap_or(""),
        result["date"].as_str().unwrap_or(""),
        result["machine"].as_str().unwrap_or(""),
        world.bodies[0].edges.len(),
        args.integrator,
        best[0],
        best[0] * 1e3 / nodes as f64,
        best[1],
        best[1] * 1e3 / nodes as f64,
        plain_best,
        plain_best * 1e3 / nodes as f64,
        100.0 * helper_share,
    );
    let scenes = shipped_scene_ticks(if args.quick { 200 } else { 2000 })?;
    let mut md = md;
    md += "\nEvery shipped scene (`scenes/*.toml`, tools as the scene drives them, IPC tools idle), mean tick over the run after 100 ticks:\n\n| scene | nodes | mean tick (µs) | ns per node |\n| --- | --- | --- | --- |\n";
    for (name, nodes, mean) in &scenes {
        md += &format!(
            "| {name} | {nodes} | {mean:.1} | {:.1} |\n",
            mean * 1e3 / *nodes as f64
        );
    }
    let mut result = result;
    result["scenes"] = json!(
        scenes
            .iter()
            .map(|(name, nodes, mean)| json!({"scene": name, "nodes": nodes, "mean_tick_us": mean, "ns_per_node": mean * 1e3 / *nodes as f64}))
            .collect::<Vec<_>>()
    );
    std::fs::write(
        args.out.join("reference.json"),
        serde_json::to_string_pretty(&result)?,
    )?;
    std::fs::write(args.out.join("reference.md"), &md)?;
    println!("{md}");
    Ok(())
}

/// Mean tick (µs) of every scene in `scenes/` (sorted by name; the stress scenes left out), over
/// `ticks` ticks after 100, with the node count at the end: (file name, nodes, µs).
fn shipped_scene_ticks(ticks: u64) -> Result<Vec<(String, usize, f64)>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&dir)
        .with_context(|| format!("cannot list {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    paths.sort();
    let mut rows = Vec::new();
    for path in paths {
        let scene = palpa::scene::load_scene(&path).map_err(|e| anyhow::anyhow!("{e}"))?;
        let mut world = World::from_scene(&scene);
        for _ in 0..100 {
            world.step();
        }
        let start = Instant::now();
        for _ in 0..ticks {
            world.step();
        }
        let mean = start.elapsed().as_secs_f64() * 1e6 / ticks as f64;
        let nodes = world.bodies.iter().map(|b| b.node_count()).sum::<usize>();
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        rows.push((name, nodes, mean));
    }
    Ok(rows)
}
