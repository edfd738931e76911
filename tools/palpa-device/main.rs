//! `palpa-device`: a simulated haptic device process. It publishes the pose of its handle at 1 kHz on
//! `<prefix>/tool/<tool>/pose`, renders the force it receives on `<prefix>/tool/<tool>/feedback` on a
//! model of a real device held by a hand that follows a motion, and measures for every pose the time
//! until the feedback answering it arrives. See `palpa::device`.

use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::{Context, Result, anyhow, bail};
use clap::{Parser, ValueEnum};
use palpa::Vec3;
use palpa::device::model::PRESETS;
use palpa::device::run::{DeviceOptions, HandPath, Motion, run_device};

#[derive(Clone, Copy, Debug, ValueEnum)]
enum Preset {
    /// Geomagic Touch: 3.3 N.
    Touch,
    /// Novint Falcon: 8 N.
    Falcon,
    /// Force Dimension omega.x: 12 N.
    Omega,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum MotionArg {
    /// Down 6 mm into the surface, hold, and up.
    Press,
    /// Down 3 mm and back and forth 2 cm along x, then up.
    Stroke,
    /// Four presses of 4 mm, one a second.
    Palpate,
    /// Presses of 4 mm, one a second, for as long as the device runs.
    PalpateThroughout,
    /// A smooth random walk over and into the surface (seeded).
    Random,
}

#[derive(Parser)]
#[command(
    name = "palpa-device",
    version,
    about = "Simulated haptic device for palpa"
)]
struct Args {
    /// Service name prefix of the daemon.
    #[arg(long, default_value = "palpa")]
    prefix: String,
    /// Tool (scene `[[tool]]` name with `input = "ipc"`).
    #[arg(long, default_value = "probe")]
    tool: String,
    /// Device model.
    #[arg(long, value_enum, default_value = "touch")]
    preset: Preset,
    /// Built-in motion of the hand.
    #[arg(long, value_enum, default_value = "press")]
    motion: MotionArg,
    /// Follow this motion script instead (TOML: `script = [{ t, position, orientation, jaw }, ...]`).
    #[arg(long)]
    script: Option<PathBuf>,
    /// Surface point the built-in motions work at, "x,y,z" in metres (the default scene's organ top).
    #[arg(long, default_value = "0.0,0.0,0.0645", allow_hyphen_values = true, value_parser = parse_point)]
    at: Vec3,
    /// Seconds to run.
    #[arg(long, default_value_t = 5.0, allow_hyphen_values = true, value_parser = palpa::daemon::values::positive)]
    duration: f64,
    /// Send the next pose only when the last one is answered (with `palpa serve --lockstep`).
    #[arg(long)]
    lockstep: bool,
    /// Seed of the random motion.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Write the JSON summary here too.
    #[arg(long)]
    report: Option<PathBuf>,
    /// Write one CSV row per pose sent: `seq,t,x,y,z,fx,fy,fz,contacts,flags` (the last feedback seen).
    #[arg(long)]
    trace: Option<PathBuf>,
}

fn parse_point(text: &str) -> Result<Vec3, String> {
    let parts: Vec<f64> = text
        .split(',')
        .map(|p| p.trim().parse::<f64>().map_err(|e| format!("{p:?}: {e}")))
        .collect::<Result<_, _>>()?;
    match parts.as_slice() {
        [x, y, z] if parts.iter().all(|v| v.is_finite()) => Ok(Vec3::new(*x, *y, *z)),
        _ => Err(format!(
            "expected three finite numbers \"x,y,z\", found {text:?}"
        )),
    }
}

fn main() -> Result<()> {
    let args = Args::parse();
    if !(args.duration.is_finite() && args.duration > 0.0) {
        bail!("--duration must be > 0");
    }
    let path = match &args.script {
        Some(file) => {
            let text = std::fs::read_to_string(file)
                .with_context(|| format!("cannot read {}", file.display()))?;
            HandPath::Script(palpa::scene::parse_script(
                &text,
                &file.display().to_string(),
            )?)
        }
        None => HandPath::BuiltIn {
            motion: match args.motion {
                MotionArg::Press => Motion::Press,
                MotionArg::Stroke => Motion::Stroke,
                MotionArg::Palpate => Motion::Palpate,
                MotionArg::PalpateThroughout => Motion::PalpateThroughout,
                MotionArg::Random => Motion::Random,
            },
            at: args.at,
            seed: args.seed,
        },
    };
    let options = DeviceOptions {
        prefix: args.prefix.clone(),
        tool: args.tool.clone(),
        spec: PRESETS[args.preset as usize],
        path,
        duration: args.duration,
        lockstep: args.lockstep,
        keep_trace: args.trace.is_some(),
    };
    let stop = Arc::new(AtomicBool::new(false));
    let handler_stop = stop.clone();
    ctrlc::set_handler(move || handler_stop.store(true, Ordering::Relaxed))
        .context("signal handler")?;
    let report = run_device(&options, stop, |_| {}).map_err(|e| anyhow!("palpa-device: {e}"))?;
    let summary = serde_json::json!({
        "device": options.spec.name,
        "poses_sent": report.poses_sent,
        "feedback_received": report.feedback_received,
        "answered": report.latencies_us.len(),
        "lost": report.lost(),
        "latency_us": {
            "min": report.latency_percentile(0.0),
            "median": report.latency_percentile(0.5),
            "p99": report.latency_percentile(0.99),
            "p999": report.latency_percentile(0.999),
            "max": report.latencies_us.last().copied().unwrap_or(0.0),
        },
        "max_force": report.max_force,
        "answers_in_contact": report.answers_in_contact,
        "seconds": report.seconds,
    });
    println!("{summary}");
    if let Some(path) = &args.report {
        std::fs::write(path, format!("{summary:#}\n"))
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    if let Some(path) = &args.trace {
        let mut out = std::io::BufWriter::new(
            std::fs::File::create(path)
                .with_context(|| format!("cannot create {}", path.display()))?,
        );
        writeln!(out, "seq,t,x,y,z,fx,fy,fz,contacts,flags")?;
        for r in &report.trace {
            let (p, f) = (r.position, r.force);
            writeln!(
                out,
                "{},{},{},{},{},{},{},{},{},{}",
                r.seq, r.t, p.x, p.y, p.z, f.x, f.y, f.z, r.contacts, r.flags
            )?;
        }
        out.flush()?;
    }
    Ok(())
}
