//! `palpa-device`: a simulated haptic device process. It publishes the pose of its handle at 1 kHz on
//! `<prefix>/tool/<tool>/pose`, renders the force it receives on `<prefix>/tool/<tool>/feedback` on a
//! model of a real device held by a hand that follows a motion, and measures for every pose the time
//! until the feedback answering it arrives.
//!
//! Real-time mode sends on its own 1 ms clock; `--lockstep` sends the next pose only when the previous
//! one was answered (or after a timeout), for tests against `palpa serve --lockstep`.

mod device;

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail};
use clap::{Parser, ValueEnum};
use iceoryx2::port::update_connections::UpdateConnections;
use palpa::Vec3;
use palpa::ipc::payload::{ToolFeedbackV1, ToolPoseV1};
use palpa::ipc::services::{create_node, feedback_service, pose_service};
use palpa::tool::{Keyframe, ToolInput};

use device::{Device, Hand, PRESETS};

#[derive(Clone, Copy, Debug, ValueEnum)]
enum Preset {
    /// Geomagic Touch: 3.3 N.
    Touch,
    /// Novint Falcon: 8 N.
    Falcon,
    /// Force Dimension omega.x: 12 N.
    Omega,
}

#[derive(Clone, Copy, Debug, ValueEnum, PartialEq)]
enum Motion {
    /// Down 6 mm into the surface, hold, and up.
    Press,
    /// Down 3 mm and back and forth 2 cm along x.
    Stroke,
    /// Four presses of 4 mm, one a second.
    Palpate,
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
    motion: Motion,
    /// Follow this motion script instead (TOML: `script = [{ t, position, orientation, jaw }, ...]`).
    #[arg(long)]
    script: Option<PathBuf>,
    /// Surface point the built-in motions work at, "x,y,z" in metres (the default scene's organ top).
    #[arg(long, default_value = "0.0,0.0,0.0645", value_parser = parse_point)]
    at: Vec3,
    /// Seconds to run.
    #[arg(long, default_value_t = 5.0)]
    duration: f64,
    /// Send the next pose only when the last one is answered (with `palpa serve --lockstep`).
    #[arg(long)]
    lockstep: bool,
    /// Seed of the random motion.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Write a JSON summary here.
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

/// The hand's intended position at time `t` for a built-in motion around the surface point `at`.
fn built_in_target(motion: Motion, at: &Vec3, t: f64, seed: u64) -> Vec3 {
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
        Motion::Palpate => {
            let depth = -0.004;
            let phase = (t - 0.5).rem_euclid(1.0);
            let pressing = (0.5..4.5).contains(&t);
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
                ((seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(k * 1442695040888963407))
                    >> 11) as f64
                    / (1u64 << 53) as f64
                    * std::f64::consts::TAU
            };
            let wave = |k: u64, f: f64| (f * t + phase(k)).sin();
            let x = 0.01 * wave(1, 1.1) + 0.004 * wave(2, 2.3);
            let y = 0.01 * wave(3, 0.7) + 0.004 * wave(4, 1.9);
            let z = 0.5 * (above - 0.004) + 0.5 * (above + 0.004) * wave(5, 1.3);
            at + Vec3::new(x, y, z)
        }
    }
}

/// Latency figures (µs) of the answered poses.
fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let rank = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1]
}

fn monotonic_ns() -> u64 {
    let mut ts = libc_timespec();
    // SAFETY: clock_gettime writes into the valid timespec we pass.
    unsafe {
        libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts);
    }
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

fn libc_timespec() -> libc::timespec {
    libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    }
}

/// What the device measured about the answers.
struct Tally {
    sent_at: Vec<Instant>,
    latencies: Vec<f64>,
    answered_up_to: u64,
    received: u64,
    max_force: f64,
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
            self.latencies
                .push((now - self.sent_at[slot]).as_secs_f64() * 1e6);
        }
    }
}

fn main() -> Result<()> {
    let args = Args::parse();
    if !(args.duration.is_finite() && args.duration > 0.0) {
        bail!("--duration must be > 0");
    }
    let spec = PRESETS[args.preset as usize];
    let script: Option<Vec<Keyframe>> = match &args.script {
        None => None,
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read {}", path.display()))?;
            Some(palpa::scene::parse_script(
                &text,
                &path.display().to_string(),
            )?)
        }
    };
    let script_input = script.map(ToolInput::Script);
    let target_at = |t: f64| -> (Vec3, f64) {
        match &script_input {
            Some(input) => {
                let (pose, jaw) = input.sample(t).expect("a script");
                (pose.position_in_world, jaw)
            }
            None => (built_in_target(args.motion, &args.at, t, args.seed), 0.0),
        }
    };

    let stop = Arc::new(AtomicBool::new(false));
    let handler_stop = stop.clone();
    ctrlc::set_handler(move || handler_stop.store(true, Ordering::Relaxed))
        .context("signal handler")?;

    let node = create_node().map_err(|e| anyhow!("iceoryx2 node: {e}"))?;
    let publisher = pose_service(&node, &args.prefix, &args.tool)
        .map_err(|e| anyhow!("pose service: {e}"))?
        .publisher_builder()
        .create()
        .map_err(|e| anyhow!("pose publisher: {e}"))?;
    let subscriber = feedback_service(&node, &args.prefix, &args.tool)
        .map_err(|e| anyhow!("feedback service: {e}"))?
        .subscriber_builder()
        .create()
        .map_err(|e| anyhow!("feedback subscriber: {e}"))?;

    // Wait for the daemon: its feedback publisher answers with the last feedback (history 1) once
    // both ends are connected. Then make sure our first pose reaches its subscriber.
    let waiting = Instant::now();
    loop {
        if subscriber
            .receive()
            .map_err(|e| anyhow!("receive: {e}"))?
            .is_some()
        {
            break;
        }
        if stop.load(Ordering::Relaxed) {
            return Ok(());
        }
        if waiting.elapsed() > Duration::from_secs(30) {
            bail!(
                "no daemon answers on prefix {:?} (is `palpa serve --prefix {}` running?)",
                args.prefix,
                args.prefix
            );
        }
        publisher
            .update_connections()
            .map_err(|e| anyhow!("connections: {e}"))?;
        std::thread::sleep(Duration::from_millis(1));
    }
    publisher
        .update_connections()
        .map_err(|e| anyhow!("connections: {e}"))?;

    let dt = 0.001;
    let ticks = (args.duration / dt).round() as u64;
    let (start_position, _) = target_at(0.0);
    let mut handle = Device::new(spec, Hand::default(), start_position);
    let mut tally = Tally {
        sent_at: vec![Instant::now(); 1 << 14],
        latencies: Vec::with_capacity(ticks as usize),
        answered_up_to: 0,
        received: 0,
        max_force: 0.0,
        force: Vec3::zeros(),
        contacts: 0,
        flags: 0,
    };
    let mut trace = Vec::with_capacity(if args.trace.is_some() {
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
        let (target, jaw) = target_at(t);
        let (previous, _) = target_at(t - dt);
        handle.step(&target, &((target - previous) / dt), &tally.force, dt);
        let position = handle.measured_position();
        if !args.lockstep {
            deadline += Duration::from_millis(1);
            let now = Instant::now();
            if deadline > now {
                std::thread::sleep(deadline - now);
            }
        }
        let seq = tick;
        tally.mark_sent(seq);
        publisher
            .send_copy(ToolPoseV1 {
                seq,
                device_time_ns: monotonic_ns(),
                position: position.into(),
                orientation: [1.0, 0.0, 0.0, 0.0],
                jaw,
                buttons: 0,
                reserved: 0,
            })
            .map_err(|e| anyhow!("send pose: {e}"))?;
        sent += 1;
        if args.lockstep {
            // Wait for the answer to this pose (1 s at most: then it counts as lost).
            let give_up = Instant::now() + Duration::from_secs(1);
            while tally.answered_up_to < seq
                && Instant::now() < give_up
                && !stop.load(Ordering::Relaxed)
            {
                while let Some(sample) =
                    subscriber.receive().map_err(|e| anyhow!("receive: {e}"))?
                {
                    tally.take(sample.payload(), Instant::now());
                }
                if tally.answered_up_to < seq {
                    std::thread::sleep(Duration::from_micros(10));
                }
            }
        } else {
            while let Some(sample) = subscriber.receive().map_err(|e| anyhow!("receive: {e}"))? {
                tally.take(sample.payload(), Instant::now());
            }
        }
        if args.trace.is_some() {
            trace.push((seq, t, position, tally.force, tally.contacts, tally.flags));
        }
    }
    // Collect the last answers.
    let settle = Instant::now() + Duration::from_millis(50);
    while Instant::now() < settle {
        while let Some(sample) = subscriber.receive().map_err(|e| anyhow!("receive: {e}"))? {
            tally.take(sample.payload(), Instant::now());
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    let Tally {
        mut latencies,
        received,
        max_force,
        ..
    } = tally;
    let answered = latencies.len() as u64;
    latencies.sort_by(f64::total_cmp);
    let summary = serde_json::json!({
        "device": spec.name,
        "poses_sent": sent,
        "feedback_received": received,
        "answered": answered,
        "lost": sent - answered,
        "latency_us": {
            "min": percentile(&latencies, 0.0),
            "median": percentile(&latencies, 0.5),
            "p99": percentile(&latencies, 0.99),
            "p999": percentile(&latencies, 0.999),
            "max": latencies.last().copied().unwrap_or(0.0),
        },
        "max_force": max_force,
        "seconds": started.elapsed().as_secs_f64(),
    });
    println!("{summary}");
    if let Some(path) = &args.trace {
        use std::io::Write;
        let mut out = std::io::BufWriter::new(
            std::fs::File::create(path)
                .with_context(|| format!("cannot create {}", path.display()))?,
        );
        writeln!(out, "seq,t,x,y,z,fx,fy,fz,contacts,flags")?;
        for (seq, t, p, f, contacts, flags) in &trace {
            writeln!(
                out,
                "{seq},{t},{},{},{},{},{},{},{contacts},{flags}",
                p.x, p.y, p.z, f.x, f.y, f.z
            )?;
        }
        out.flush()?;
    }
    if let Some(path) = &args.report {
        std::fs::write(path, format!("{summary:#}\n"))
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(())
}
