//! `palpa-replay FILE.mcap`: check, watch and summarise a recorded session.
//!
//! * `--verify` rebuilds the scene from the recording, feeds the recorded inputs tick by tick and
//!   compares every feedback and mesh message bit for bit; the first difference is printed (tick,
//!   channel, field) and the exit code is 1.
//! * `--play [--speed X] [--prefix P]` publishes the recorded feedback and mesh messages on the
//!   daemon's iceoryx2 services at the recorded pace (scaled), for testing a display without a device.
//! * `--summary [--json]` prints duration, ticks, tools, contacts, max force, misses, rejects and the
//!   message count of every channel.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Result, anyhow, bail};
use clap::Parser;
use palpa::record::replay::{VerifyError, read_recording_file, summarise, verify};

#[derive(Parser)]
#[command(
    name = "palpa-replay",
    version,
    about = "Verify, play and summarise palpa recordings"
)]
struct Args {
    /// The recording.
    file: PathBuf,
    /// Replay the session and compare every feedback and mesh message bit for bit.
    #[arg(long)]
    verify: bool,
    /// Publish the recorded feedback and mesh messages over iceoryx2 in real time.
    #[arg(long)]
    play: bool,
    /// Playback speed factor.
    #[arg(long, default_value_t = 1.0)]
    speed: f64,
    /// Service prefix for --play.
    #[arg(long, default_value = "palpa")]
    prefix: String,
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
                s.duration_s,
                s.ticks,
                if s.complete {
                    ""
                } else {
                    ", file cut short (read up to its last complete chunk)"
                }
            );
            println!("  tools: {}", s.tools.join(", "));
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
        let result = verify(&recording, &work, |tick, last| {
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
        match result {
            Ok(report) => println!(
                "verify: OK — {} ticks replayed, {} feedback and {} mesh messages identical (digest {:016x})",
                report.ticks, report.feedback, report.meshes, report.digest
            ),
            Err(VerifyError::Differs(d)) => {
                println!("verify: FAILED at {d}");
                std::process::exit(1);
            }
            Err(e) => bail!("{e}"),
        }
    }
    if args.play {
        play(&recording, &args)?;
    }
    Ok(())
}

fn play(recording: &palpa::record::replay::Recording, args: &Args) -> Result<()> {
    use palpa::ipc::payload::{MESH_DELTA, MESH_KEYFRAME, MeshHeaderV1, ToolFeedbackV1};
    use palpa::ipc::services::{create_node, feedback_service, mesh_service};
    use palpa::record::proto;
    use prost::Message;

    if !(args.speed.is_finite() && args.speed > 0.0) {
        bail!("--speed must be > 0");
    }
    let node = create_node().map_err(|e| anyhow!("{e}"))?;
    let mut feedback = std::collections::BTreeMap::new();
    for tool in &recording.scene.tools {
        let publisher = feedback_service(&node, &args.prefix, tool)
            .and_then(|f| Ok(f.publisher_builder().create()?))
            .map_err(|e| anyhow!("{e}"))?;
        feedback.insert(format!("/palpa/tool/{tool}/feedback"), publisher);
    }
    let largest = recording
        .scene
        .body_nodes
        .iter()
        .zip(&recording.scene.body_triangles)
        .map(|(&n, &t)| palpa::display::max_message_bytes(n as usize, t as usize))
        .max()
        .unwrap_or(1);
    let mesh = mesh_service(&node, &args.prefix)
        .and_then(|f| {
            Ok(f.publisher_builder()
                .initial_max_slice_len(largest)
                .create()?)
        })
        .map_err(|e| anyhow!("{e}"))?;
    let started = Instant::now();
    let mut bytes = Vec::with_capacity(largest);
    let mut published = 0u64;
    for m in &recording.messages {
        let at = Duration::from_secs_f64(m.log_time as f64 * 1e-9 / args.speed);
        if let Some(wait) = at.checked_sub(started.elapsed()) {
            std::thread::sleep(wait);
        }
        if let Some(publisher) = feedback.get(&m.topic) {
            let f = proto::Feedback::decode(&m.data[..])?;
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
            bytes.clear();
            let header = if m.topic.ends_with("keyframe") {
                let k = proto::MeshKeyframe::decode(&m.data[..])?;
                k.positions
                    .iter()
                    .for_each(|x| bytes.extend_from_slice(&x.to_le_bytes()));
                k.triangles
                    .iter()
                    .for_each(|x| bytes.extend_from_slice(&x.to_le_bytes()));
                MeshHeaderV1 {
                    kind: MESH_KEYFRAME,
                    body: k.body,
                    tick: k.tick,
                    base_tick: k.tick,
                    vertex_count: (k.positions.len() / 3) as u32,
                    triangle_count: (k.triangles.len() / 3) as u32,
                    changed_count: 0,
                    payload_bytes: 0,
                }
            } else {
                let d = proto::MeshDelta::decode(&m.data[..])?;
                for (e, &v) in d.vertices.iter().enumerate() {
                    bytes.extend_from_slice(&v.to_le_bytes());
                    for k in 0..3 {
                        bytes.extend_from_slice(&d.positions[3 * e + k].to_le_bytes());
                    }
                }
                MeshHeaderV1 {
                    kind: MESH_DELTA,
                    body: d.body,
                    tick: d.tick,
                    base_tick: d.base_tick,
                    vertex_count: d.vertex_count,
                    triangle_count: 0,
                    changed_count: d.vertices.len() as u32,
                    payload_bytes: 0,
                }
            };
            let header = MeshHeaderV1 {
                payload_bytes: bytes.len() as u32,
                ..header
            };
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
    Ok(())
}
