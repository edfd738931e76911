//! `palpa-replay FILE.mcap`: check, watch and summarise a recorded session.
//!
//! * `--verify` rebuilds the scene from the recording, feeds the recorded inputs tick by tick and
//!   compares every feedback and mesh message bit for bit; the first difference is printed (tick,
//!   channel, field) and the exit code is 1. A damaged or cut-short file is verified as far as it
//!   can be read, reported as damaged (where and what, and how many ticks were verified), and never
//!   passes: exit code 3 (the codes are listed by `--help`).
//! * `--play [--speed X] [--prefix P]` publishes the recorded feedback and mesh messages on the
//!   daemon's iceoryx2 services at the recorded pace (scaled), for testing a display without a device.
//! * `--summary [--json]` prints duration, ticks, tools, contacts, max force, misses, rejects and the
//!   message count of every channel.
//! * `--verify --step-times` also times each replayed step on this machine and the ticks the daemon
//!   recorded as synchronicity misses: a miss whose tick replays well within the period was the
//!   machine's (the daemon's thread held off its core), not the scene's work.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Result, anyhow, bail};
use clap::Parser;
use palpa::record::replay::{
    StepTimes, VerifyError, mesh_payload, read_recording_file, summarise, verify_timed,
};

/// Exit statuses, as `--help` lists them.
const EXIT_CODES: &str = "Exit status:
  0  success; with --verify: the recording is complete and undamaged and replays bit for bit
  1  --verify found a difference (printed: tick, channel, field), or any error (the file cannot
     be read at all, the recording cannot be replayed, --play failed, nothing to do)
  2  bad command line (unknown option, missing FILE)
  3  --verify: the file is damaged or cut short; everything readable before the damage replays
     bit for bit (printed: where the damage is, what it is, how many ticks were verified)";

/// `--verify`: the file is damaged or cut short, and what could be read replays bit for bit. (1 is
/// a difference or any other error, 2 clap's usage errors.)
const EXIT_DAMAGED: i32 = 3;

#[derive(Parser)]
#[command(
    name = "palpa-replay",
    version,
    about = "Verify, play and summarise palpa recordings",
    after_help = EXIT_CODES
)]
struct Args {
    /// The recording.
    file: PathBuf,
    /// Replay the session and compare every feedback and mesh message bit for bit (exit 0: OK;
    /// 1: a difference; 3: the file is damaged or cut short, its readable part replays).
    #[arg(long)]
    verify: bool,
    /// With --verify: time each replayed step on this machine and print the distribution, and the
    /// replayed time of every tick the daemon recorded as a synchronicity miss (wall clock; not
    /// part of what is compared).
    #[arg(long, requires = "verify")]
    step_times: bool,
    /// Publish the recorded feedback and mesh messages over iceoryx2 in real time.
    #[arg(long)]
    play: bool,
    /// Playback speed factor (> 0).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true, value_parser = palpa::daemon::values::positive)]
    speed: f64,
    /// Service prefix for --play.
    #[arg(long, default_value = "palpa")]
    prefix: String,
    /// With --play: also show the session to Foxglove on [HOST:]PORT (a WebSocket server, as
    /// `palpa serve --live`: its scene, feedback, statistics and events as recorded).
    #[arg(
        long,
        requires = "play",
        value_name = "[HOST:]PORT",
        value_parser = palpa::record::live::address_argument
    )]
    live: Option<String>,
    /// Print a summary of the session.
    #[arg(long)]
    summary: bool,
    /// With --summary: as JSON.
    #[arg(long)]
    json: bool,
}

fn main() -> Result<()> {
    let args = Args::parse();
    if !(args.verify || args.play || args.summary) {
        bail!("say what to do: --verify, --play or --summary");
    }
    let recording = read_recording_file(&args.file).map_err(|e| anyhow!(e))?;
    if args.summary {
        let s = summarise(&recording);
        if args.json {
            let value = serde_json::json!({
                "file": args.file.display().to_string(),
                "complete": s.complete,
                "damage": s.damage.as_ref().map(|d| d.to_string()),
                "duration_s": s.duration_s,
                "ticks": s.ticks,
                "tools": s.tools,
                "max_contacts": s.max_contacts,
                "max_force": s.max_force,
                "misses": s.misses,
                "rejects": s.rejects,
                "messages": s.messages,
            });
            println!("{value}");
        } else {
            println!(
                "{}: {} s simulated ({} ticks){}",
                args.file.display(),
                // (Ticks times dt, to the nanosecond: 1.636, not 1.6360000000000001.)
                format!("{:.9}", s.duration_s)
                    .trim_end_matches('0')
                    .trim_end_matches('.'),
                s.ticks,
                match (&s.damage, s.complete) {
                    (_, true) => String::new(),
                    (None, false) => ", file cut short (read up to its last complete chunk)".into(),
                    (Some(d), false) => format!(", read up to damaged bytes {d}"),
                }
            );
            if s.tools.is_empty() {
                println!("  tools: none");
            } else {
                println!("  tools: {}", s.tools.join(", "));
            }
            println!(
                "  max contacts {}, max force {:.4} N",
                s.max_contacts, s.max_force
            );
            println!(
                "  synchronicity misses {}, rejected inputs {}",
                s.misses, s.rejects
            );
            for (topic, count) in &s.messages {
                println!("  {topic}: {count} messages");
            }
        }
    }
    if args.verify {
        let work = std::env::temp_dir().join(format!("palpa-replay-{}", std::process::id()));
        let terminal = std::io::stderr().is_terminal();
        let result = verify_timed(&recording, &work, |tick, last| {
            if terminal {
                let done = (tick as f64 / last.max(1) as f64 * 40.0) as usize;
                eprint!(
                    "\r[{}{}] tick {tick}/{last}",
                    "#".repeat(done.min(40)),
                    " ".repeat(40 - done.min(40))
                );
            }
        });
        if terminal {
            eprintln!();
        }
        let _ = std::fs::remove_dir_all(&work);
        let damage = damage_of(&recording, &args.file);
        if let (Ok((_, times)), true) = (&result, args.step_times) {
            print_step_times(times);
        }
        let result = result.map(|(report, _)| report);
        match (result, damage) {
            (Ok(report), None) => println!(
                "verify: OK — {} ticks replayed, {} feedback and {} mesh messages identical (digest {:016x})",
                report.ticks, report.feedback, report.meshes, report.digest
            ),
            (Ok(report), Some(damage)) => {
                println!(
                    "verify: DAMAGED — {} is damaged: {damage}",
                    args.file.display()
                );
                if report.feedback + report.meshes == 0 {
                    println!(
                        "verify: no feedback or mesh message could be read before the damage: \
                         nothing was verified"
                    );
                } else {
                    println!(
                        "verify: the {} ticks read before the damage replay bit for bit ({} feedback \
                         and {} mesh messages identical, digest {:016x}); anything recorded beyond \
                         the damage could not be read and is not verified",
                        report.ticks, report.feedback, report.meshes, report.digest
                    );
                }
                std::process::exit(EXIT_DAMAGED);
            }
            (Err(VerifyError::Differs(d)), damage) => {
                println!("verify: FAILED at {d}");
                if let Some(damage) = damage {
                    println!("verify: the file is also damaged — {damage}");
                }
                std::process::exit(1);
            }
            (Err(e), None) => bail!("{e}"),
            (Err(e), Some(damage)) => bail!("{e} (the file is damaged — {damage})"),
        }
    }
    if args.play {
        play(&recording, &args)?;
    }
    Ok(())
}

/// Where and why a recording is not whole, or `None` for a complete, undamaged one (footer read, no
/// damage before it).
fn damage_of(
    recording: &palpa::record::replay::Recording,
    file: &std::path::Path,
) -> Option<String> {
    match (&recording.damage, recording.complete) {
        (Some(d), _) => Some(format!("reading stopped {d}")),
        (None, true) => None,
        (None, false) => {
            let end = std::fs::metadata(file).map_or_else(
                |_| "the end of the file".to_string(),
                |m| format!("byte {}", m.len()),
            );
            Some(format!(
                "the file ends at {end} without its footer: cut short (a crash, or a copy cut off) \
                 after its last complete record"
            ))
        }
    }
}

/// Largest step between the log times of consecutive messages --play accepts (1 min).
const MAX_LOG_TIME_JUMP_NS: u64 = 60_000_000_000;

fn play(recording: &palpa::record::replay::Recording, args: &Args) -> Result<()> {
    use iceoryx2::prelude::PortFactory;
    use palpa::daemon::sink::event;
    use palpa::ipc::payload::ToolFeedbackV1;
    use palpa::ipc::services::{IpcError, create_node, feedback_service, mesh_service};
    use palpa::record::proto;
    use palpa::record::recorder::MessageOut;
    use prost::Message;

    let node = create_node().map_err(|e| anyhow!("{e}"))?;
    let mut feedback = std::collections::BTreeMap::new();
    for tool in &recording.scene.tools {
        let publisher = feedback_service(&node, &args.prefix, tool)
            .and_then(|f| {
                f.publisher_builder()
                    .create()
                    .map_err(|e| IpcError::port(f.name(), "publisher", e))
            })
            .map_err(|e| anyhow!("{e}"))?;
        feedback.insert(format!("/palpa/tool/{tool}/feedback"), publisher);
    }
    // Every mesh message is checked (and its size found) before anything is published; the
    // largest sizes the shared-memory slice, so a damaged count cannot size it.
    let mut bytes = Vec::new();
    let mut largest = 1;
    for m in recording
        .messages
        .iter()
        .filter(|m| m.topic.starts_with("/palpa/mesh/"))
    {
        mesh_payload(m, &mut bytes)?;
        largest = largest.max(bytes.len());
    }
    let mesh = mesh_service(&node, &args.prefix)
        .and_then(|f| {
            f.publisher_builder()
                .initial_max_slice_len(largest)
                .create()
                .map_err(|e| IpcError::port(f.name(), "publisher", e))
        })
        .map_err(|e| anyhow!("{e}"))?;
    let live = match &args.live {
        Some(text) => {
            use palpa::record::live::{LiveServer, LiveSettings, parse_address};
            let address = parse_address(text).map_err(|e| anyhow!(e))?;
            let server = LiveServer::start(address, LiveSettings::default().viewer_backlog)?;
            let channels = server.channels(recording.scene.tools.iter().map(String::as_str))?;
            println!(
                "play: live view on {} (open it in Foxglove: Open connection, Foxglove WebSocket)",
                server.url()
            );
            Some((server, channels))
        }
        None => None,
    };
    let mut live = live;
    let started = Instant::now();
    let mut published = 0u64;
    let mut previous_log_time = 0u64;
    // A reset starts the world's clock (and the log times) again from 0: the session's time at a
    // message is the log time plus the log times of the resets before it.
    let mut epoch_start_ns = 0u64;
    for m in &recording.messages {
        // Simulated time passes evenly in a session; a jump of more than a minute is a damaged log
        // time, which would otherwise be waited for.
        if m.log_time.saturating_sub(previous_log_time) > MAX_LOG_TIME_JUMP_NS {
            bail!(
                "{} message at log time {} ns follows {} ns: a damaged log time",
                m.topic,
                m.log_time,
                previous_log_time
            );
        }
        previous_log_time = previous_log_time.max(m.log_time);
        let session_ns = epoch_start_ns.saturating_add(m.log_time);
        if m.topic == "/palpa/events"
            && proto::Event::decode(&m.data[..]).is_ok_and(|e| e.kind == event::RESET)
        {
            epoch_start_ns = session_ns;
            previous_log_time = 0;
        }
        let at = Duration::try_from_secs_f64(session_ns as f64 * 1e-9 / args.speed)
            .map_err(|e| anyhow!("log time {} ns at speed {}: {e}", m.log_time, args.speed))?;
        if let Some(wait) = at.checked_sub(started.elapsed()) {
            std::thread::sleep(wait);
        }
        if let Some((_, channels)) = live.as_mut()
            && channels.wants(&m.topic)
        {
            channels
                .write(&m.topic, session_ns, &m.data)
                .map_err(|e| anyhow!(e))?;
        }
        if let Some(publisher) = feedback.get(&m.topic) {
            let f = proto::Feedback::decode(&m.data[..])
                .map_err(|e| anyhow!("{} message at log time {} ns: {e}", m.topic, m.log_time))?;
            let v = |v: Option<proto::Vec3>| v.map_or([0.0; 3], |v| [v.x, v.y, v.z]);
            publisher
                .send_copy(ToolFeedbackV1 {
                    seq: f.seq,
                    device_time_ns: 0,
                    tick: f.tick,
                    force: v(f.force),
                    torque: v(f.torque),
                    contacts: f.contacts,
                    flags: f.flags,
                })
                .map_err(|e| anyhow!("{e}"))?;
            published += 1;
        } else if m.topic.starts_with("/palpa/mesh/") {
            let header = mesh_payload(m, &mut bytes)?;
            let mut sample = mesh
                .loan_slice_uninit(bytes.len())
                .map_err(|e| anyhow!("{e}"))?;
            *sample.user_header_mut() = header;
            sample
                .write_from_slice(&bytes)
                .send()
                .map_err(|e| anyhow!("{e}"))?;
            published += 1;
        }
    }
    println!(
        "play: {published} messages published on prefix {:?}",
        args.prefix
    );
    if let Some((server, channels)) = live {
        let total: u64 = channels.counts().values().sum();
        println!(
            "play: live view published {total} messages to {} viewers",
            server.viewers()
        );
    }
    Ok(())
}

/// `--step-times`: the replayed steps' distribution, and the ticks the daemon missed.
fn print_step_times(times: &StepTimes) {
    println!(
        "step times: {} steps replayed here, mean {:.1} µs, median {:.0}, p99 {:.0}, p99.9 {:.0}, max {:.1} µs (period {:.0} µs)",
        times.ticks(),
        times.mean_us(),
        times.quantile_us(0.5),
        times.quantile_us(0.99),
        times.quantile_us(0.999),
        times.max_us,
        times.period_us
    );
    let misses = &times.at_misses_us;
    if misses.is_empty() {
        println!("step times: no tick was recorded as a synchronicity miss");
        return;
    }
    let mut sorted = misses.clone();
    sorted.sort_by(f64::total_cmp);
    let longest = sorted[sorted.len() - 1];
    let within = sorted.iter().filter(|&&us| us <= times.period_us).count();
    println!(
        "step times: the {} ticks recorded as synchronicity misses replay in median {:.1} µs, at most {:.1} µs; {within} of them within the period{}",
        misses.len(),
        sorted[sorted.len() / 2],
        longest,
        if within == misses.len() {
            " (not the scene's work as replayed here: the machine or IPC slowed those ticks)"
        } else {
            ""
        }
    );
}
