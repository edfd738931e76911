//! `palpa-zenoh`: a bridge between a daemon's iceoryx2 services and Zenoh, so devices, displays and
//! instructor stations on other hosts can work with the daemon.
//!
//! Key expressions, under `palpa/<prefix>/` (`<prefix>` is the daemon's service prefix):
//!
//! * `tool/<tool>/pose` (remote → daemon): a `palpa_tool_pose_v1`, published on the tool's pose
//!   service; the daemon's input checks apply to it as to a local bridge's pose.
//! * `tool/<tool>/feedback` (daemon → remote): each `palpa_tool_feedback_v1` the daemon publishes.
//! * `stats` (daemon → remote): each `palpa_stats_v1`.
//! * `display/mesh` (daemon → remote): each mesh message, its `palpa_mesh_header_v1` followed by its
//!   payload.
//!
//! Payloads are exactly the v1 structures of `proto/palpa_ipc.h`, little-endian. A pose of another
//! size is refused (counted). The tools are found among the daemon's services (`<prefix>/tool/*/pose`),
//! i.e. those of the scene it serves. Multicast scouting is off unless `--scout`: peers meet through
//! the endpoints given.

use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail};
use clap::Parser;
use iceoryx2::prelude::PortFactory;
use iceoryx2::prelude::*;
use palpa::ipc::payload::{MeshHeaderV1, StatsV1, ToolFeedbackV1, ToolPoseV1, WireV1};
use palpa::ipc::services::{
    IpcError, create_node, feedback_service, mesh_service, pose_service, stats_service,
};
use zenoh::Wait;
use zenoh::handlers::RingChannel;

/// How long after the last message the bridge keeps polling without sleeping.
const ACTIVE_WINDOW: Duration = Duration::from_millis(20);
/// The pause between polls while nothing flows.
const IDLE_POLL: Duration = Duration::from_micros(200);

#[derive(Parser)]
#[command(
    name = "palpa-zenoh",
    version,
    about = "Bridge a palpa daemon's iceoryx2 services to Zenoh (poses in, feedback, stats and meshes out)"
)]
struct Args {
    /// The daemon's service prefix (`palpa serve --prefix`); keys are under `palpa/<prefix>/`.
    #[arg(long, default_value = "palpa")]
    prefix: String,
    /// Zenoh endpoint to listen on (e.g. tcp/0.0.0.0:7447); repeatable.
    #[arg(long, value_name = "ENDPOINT")]
    listen: Vec<String>,
    /// Zenoh endpoint to connect to (e.g. tcp/192.168.1.20:7447); repeatable.
    #[arg(long, value_name = "ENDPOINT")]
    connect: Vec<String>,
    /// Stop after this many seconds (wall clock); until Ctrl-C or SIGTERM when omitted.
    #[arg(long, allow_hyphen_values = true, value_parser = palpa::daemon::values::positive)]
    duration: Option<f64>,
    /// Turn Zenoh's multicast scouting on (off by default: peers meet through the endpoints).
    #[arg(long)]
    scout: bool,
    /// Seconds to wait for the daemon's services to appear.
    #[arg(long, default_value_t = 10.0, allow_hyphen_values = true, value_parser = palpa::daemon::values::non_negative)]
    wait: f64,
}

/// The tools whose pose service the daemon under `prefix` created (sorted, each once).
fn discover_tools(prefix: &str) -> Result<Vec<String>> {
    let head = format!("{prefix}/tool/");
    let mut tools = Vec::new();
    ipc::Service::list(iceoryx2::config::Config::global_config(), |service| {
        let name = service.static_details.name().as_str();
        if let Some(tool) = name
            .strip_prefix(&head)
            .and_then(|rest| rest.strip_suffix("/pose"))
            && !tool.is_empty()
        {
            tools.push(tool.to_string());
        }
        CallbackProgression::Continue
    })
    .map_err(|e| anyhow!("cannot list the iceoryx2 services: {e:?}"))?;
    tools.sort();
    tools.dedup();
    Ok(tools)
}

fn zenoh_config(args: &Args) -> Result<zenoh::Config> {
    let mut config = zenoh::Config::default();
    let list = |endpoints: &[String]| serde_json::to_string(endpoints).expect("strings");
    let set = |config: &mut zenoh::Config, key: &str, value: &str| {
        config
            .insert_json5(key, value)
            .map_err(|e| anyhow!("zenoh configuration {key} = {value}: {e}"))
    };
    set(&mut config, "mode", "\"peer\"")?;
    set(&mut config, "listen/endpoints", &list(&args.listen))?;
    set(&mut config, "connect/endpoints", &list(&args.connect))?;
    set(
        &mut config,
        "scouting/multicast/enabled",
        if args.scout { "true" } else { "false" },
    )?;
    Ok(config)
}

/// What the bridge carried.
#[derive(Default)]
struct Counts {
    poses: u64,
    refused_poses: u64,
    feedback: u64,
    stats: u64,
    meshes: u64,
    errors: u64,
}

fn main() -> ExitCode {
    match run(Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("palpa-zenoh: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(args: Args) -> Result<()> {
    if args.listen.is_empty() && args.connect.is_empty() && !args.scout {
        bail!("give at least one --listen or --connect endpoint (or --scout)");
    }
    let stop = Arc::new(AtomicBool::new(false));
    let handler_stop = stop.clone();
    ctrlc::set_handler(move || handler_stop.store(true, Ordering::Relaxed))
        .context("cannot install the Ctrl-C/SIGTERM handler")?;

    // The node first: it sets iceoryx2's logging, which the service listing below also uses.
    let node = create_node().map_err(|e| anyhow!("{e}"))?;
    // The daemon's tools, from its services.
    let waited = Instant::now();
    let tools = loop {
        let tools = discover_tools(&args.prefix)?;
        if !tools.is_empty() {
            break tools;
        }
        if waited.elapsed().as_secs_f64() > args.wait || stop.load(Ordering::Relaxed) {
            bail!(
                "no daemon tool under prefix {:?} (no service {}/tool/*/pose) after {} s",
                args.prefix,
                args.prefix,
                args.wait
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    };

    let session = zenoh::open(zenoh_config(&args)?)
        .wait()
        .map_err(|e| anyhow!("cannot open the Zenoh session: {e}"))?;
    let key = |rest: &str| format!("palpa/{}/{rest}", args.prefix);
    let zerr = |what: &str, e: zenoh::Error| anyhow!("{what}: {e}");

    struct ToolPorts {
        pose_in:
            zenoh::pubsub::Subscriber<zenoh::handlers::RingChannelHandler<zenoh::sample::Sample>>,
        pose_out: iceoryx2::port::publisher::Publisher<ipc::Service, ToolPoseV1, ()>,
        feedback_in: iceoryx2::port::subscriber::Subscriber<ipc::Service, ToolFeedbackV1, ()>,
        feedback_out: zenoh::pubsub::Publisher<'static>,
    }
    let mut ports = Vec::new();
    for tool in &tools {
        let pose_in = session
            .declare_subscriber(key(&format!("tool/{tool}/pose")))
            .with(RingChannel::new(1))
            .wait()
            .map_err(|e| zerr("pose subscriber", e))?;
        let feedback_out = session
            .declare_publisher(key(&format!("tool/{tool}/feedback")))
            .express(true)
            .wait()
            .map_err(|e| zerr("feedback publisher", e))?;
        let pose_out = pose_service(&node, &args.prefix, tool)
            .and_then(|s| {
                s.publisher_builder()
                    .create()
                    .map_err(|e| IpcError::port(s.name(), "publisher", e))
            })
            .map_err(|e| anyhow!("pose service of {tool}: {e}"))?;
        let feedback_in = feedback_service(&node, &args.prefix, tool)
            .and_then(|s| {
                s.subscriber_builder()
                    .create()
                    .map_err(|e| IpcError::port(s.name(), "subscriber", e))
            })
            .map_err(|e| anyhow!("feedback service of {tool}: {e}"))?;
        ports.push(ToolPorts {
            pose_in,
            pose_out,
            feedback_in,
            feedback_out,
        });
    }
    let stats_in = stats_service(&node, &args.prefix)
        .and_then(|s| {
            s.subscriber_builder()
                .create()
                .map_err(|e| IpcError::port(s.name(), "subscriber", e))
        })
        .map_err(|e| anyhow!("stats service: {e}"))?;
    let stats_out = session
        .declare_publisher(key("stats"))
        .wait()
        .map_err(|e| zerr("stats publisher", e))?;
    let mesh_in = mesh_service(&node, &args.prefix)
        .and_then(|s| {
            s.subscriber_builder()
                .create()
                .map_err(|e| IpcError::port(s.name(), "subscriber", e))
        })
        .map_err(|e| anyhow!("mesh service: {e}"))?;
    let mesh_out = session
        .declare_publisher(key("display/mesh"))
        .wait()
        .map_err(|e| zerr("mesh publisher", e))?;
    println!(
        "palpa-zenoh: prefix {:?}, tools [{}]; listening on [{}], connecting to [{}]; keys palpa/{}/...",
        args.prefix,
        tools.join(", "),
        args.listen.join(", "),
        args.connect.join(", "),
        args.prefix
    );

    let started = Instant::now();
    let mut counts = Counts::default();
    let mut first_error: Option<String> = None;
    let mut note = |counts: &mut Counts, e: String| {
        counts.errors += 1;
        first_error.get_or_insert(e);
    };
    let mut bytes = Vec::with_capacity(256);
    let mut last_activity = Instant::now();
    while !stop.load(Ordering::Relaxed)
        && args
            .duration
            .is_none_or(|d| started.elapsed().as_secs_f64() < d)
    {
        let mut busy = false;
        for p in &ports {
            // Remote → daemon: the newest pose (the ring keeps one, as the daemon's service does).
            match p.pose_in.try_recv() {
                Ok(Some(sample)) => {
                    busy = true;
                    match ToolPoseV1::read_le(&sample.payload().to_bytes()) {
                        Some(pose) => match p.pose_out.send_copy(pose) {
                            Ok(_) => counts.poses += 1,
                            Err(e) => note(&mut counts, format!("pose send: {e:?}")),
                        },
                        None => counts.refused_poses += 1,
                    }
                }
                Ok(None) => {}
                Err(e) => note(&mut counts, format!("pose receive: {e}")),
            }
            // Daemon → remote.
            loop {
                match p.feedback_in.receive() {
                    Ok(Some(sample)) => {
                        busy = true;
                        bytes.clear();
                        sample.payload().write_le(&mut bytes);
                        match p.feedback_out.put(bytes.clone()).wait() {
                            Ok(()) => counts.feedback += 1,
                            Err(e) => note(&mut counts, format!("feedback put: {e}")),
                        }
                    }
                    Ok(None) => break,
                    Err(e) => {
                        note(&mut counts, format!("feedback receive: {e:?}"));
                        break;
                    }
                }
            }
        }
        while let Ok(Some(sample)) = stats_in.receive() {
            busy = true;
            let stats: &StatsV1 = sample.payload();
            match stats_out.put(stats.to_le_vec()).wait() {
                Ok(()) => counts.stats += 1,
                Err(e) => note(&mut counts, format!("stats put: {e}")),
            }
        }
        while let Ok(Some(sample)) = mesh_in.receive() {
            busy = true;
            let header: &MeshHeaderV1 = sample.user_header();
            let payload = sample.payload();
            let used = (header.payload_bytes as usize).min(payload.len());
            let mut message = Vec::with_capacity(MeshHeaderV1::BYTES + used);
            header.write_le(&mut message);
            message.extend_from_slice(&payload[..used]);
            match mesh_out.put(message).wait() {
                Ok(()) => counts.meshes += 1,
                Err(e) => note(&mut counts, format!("mesh put: {e}")),
            }
        }
        // While messages flow (one passed within ACTIVE_WINDOW), poll again at once, yielding the
        // core to whatever else is ready: a sleep, however short, costs a round trip about 150 µs
        // of wake-up on this kind of machine (`palpa-bench remote`). Idle, sleep between polls.
        if busy {
            last_activity = Instant::now();
        } else if last_activity.elapsed() < ACTIVE_WINDOW {
            std::thread::yield_now();
        } else {
            std::thread::sleep(IDLE_POLL);
        }
    }
    println!(
        "palpa-zenoh: stopped after {:.1} s: {} poses in ({} refused: not {} bytes), {} feedback, {} stats, {} mesh messages out, {} errors",
        started.elapsed().as_secs_f64(),
        counts.poses,
        counts.refused_poses,
        ToolPoseV1::BYTES,
        counts.feedback,
        counts.stats,
        counts.meshes,
        counts.errors
    );
    if let Some(first) = first_error {
        eprintln!("palpa-zenoh: first error: {first}");
    }
    drop(ports);
    let _ = session.close().wait();
    Ok(())
}
