//! `palpa-bench remote`: what the Zenoh path adds to a round trip over the local iceoryx2 path, and
//! what the live view costs the tick.
//!
//! 1. A lockstep daemon (`palpa serve --lockstep`: one tick per pose) answers pings of the same
//!    payloads, one per millisecond, first over its local iceoryx2 services, then through
//!    `palpa-zenoh` from a Zenoh client in this process (loopback TCP): p50, p99 of each and of the
//!    difference.
//! 2. The real-time daemon with the simulated device palpating the default organ, without and with
//!    `--live` and a viewer subscribed to every channel and reading: the tick's compute distribution
//!    (p50, p99, p99.9, max, misses) of each.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use palpa::ipc::payload::{ToolFeedbackV1, ToolPoseV1, WireV1};
use serde_json::json;
use zenoh::Wait;

/// A child process killed when dropped.
struct Running(Child);

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn free_port() -> Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port())
}

/// Round trips through `palpa-zenoh` at `endpoint`: a pose put on `palpa/<prefix>/tool/probe/pose`
/// every millisecond, timed until the feedback answering it arrives.
pub fn zenoh_ping(endpoint: &str, prefix: &str, count: u64) -> Result<Vec<f64>> {
    let mut config = zenoh::Config::default();
    let set = |config: &mut zenoh::Config, key: &str, value: &str| {
        config
            .insert_json5(key, value)
            .map_err(|e| anyhow::anyhow!("{key}: {e}"))
    };
    set(&mut config, "mode", "\"client\"")?;
    set(
        &mut config,
        "connect/endpoints",
        &format!("[\"{endpoint}\"]"),
    )?;
    set(&mut config, "scouting/multicast/enabled", "false")?;
    let ready_by = Instant::now() + Duration::from_secs(20);
    let session = loop {
        match zenoh::open(config.clone()).wait() {
            Ok(s) => break s,
            Err(e) if Instant::now() > ready_by => bail!("cannot reach the bridge: {e}"),
            Err(_) => std::thread::sleep(Duration::from_millis(100)),
        }
    };
    let base = format!("palpa/{prefix}/tool/probe");
    let feedback = session
        .declare_subscriber(format!("{base}/feedback"))
        .wait()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let poses = session
        .declare_publisher(format!("{base}/pose"))
        .express(true)
        .wait()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let send = |seq: u64| -> Result<()> {
        let pose = ToolPoseV1 {
            seq,
            orientation: [1.0, 0.0, 0.0, 0.0],
            ..ToolPoseV1::default()
        };
        poses
            .put(pose.to_le_vec())
            .wait()
            .map_err(|e| anyhow::anyhow!("{e}"))
    };
    let answered = |seq: u64| -> Result<bool> {
        while let Some(sample) = feedback.try_recv().map_err(|e| anyhow::anyhow!("{e}"))? {
            if ToolFeedbackV1::read_le(&sample.payload().to_bytes()).is_some_and(|f| f.seq == seq) {
                return Ok(true);
            }
        }
        Ok(false)
    };
    // Wait for the bridge and the daemon to answer at all (sequence numbers above the timed ones).
    let mut warm = count + 1;
    'ready: loop {
        warm += 1;
        send(warm)?;
        let until = Instant::now() + Duration::from_millis(50);
        while Instant::now() < until {
            if answered(warm)? {
                break 'ready;
            }
            std::thread::sleep(Duration::from_micros(20));
        }
        if Instant::now() > ready_by {
            bail!("no answer through the bridge");
        }
    }
    // The daemon checks that sequence numbers increase: keep counting up from the warm-up.
    let mut round_trips = Vec::with_capacity(count as usize);
    let start = Instant::now();
    for k in 1..=count {
        let seq = warm + k;
        let slot = start + Duration::from_micros(1000 * k);
        std::thread::sleep(slot.saturating_duration_since(Instant::now()));
        let sent = Instant::now();
        send(seq)?;
        // Blocking on the subscriber's queue, as a remote client would (spinning would take one of
        // this machine's two cores from the bridge and the daemon).
        let give_up = sent + Duration::from_millis(100);
        while let Some(sample) = feedback
            .recv_deadline(give_up)
            .map_err(|e| anyhow::anyhow!("{e}"))?
        {
            if ToolFeedbackV1::read_le(&sample.payload().to_bytes()).is_some_and(|f| f.seq == seq) {
                round_trips.push(sent.elapsed().as_secs_f64() * 1e6);
                break;
            }
        }
    }
    drop(poses);
    drop(feedback);
    let _ = session.close().wait();
    Ok(round_trips)
}

/// A viewer of the live view at `address` on a thread: subscribes to every channel and reads until
/// `stop`; counts the bytes it read.
fn viewer(address: String, stop: Arc<AtomicBool>, read: Arc<AtomicU64>) {
    use tungstenite::client::IntoClientRequest;
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut socket = loop {
        let mut request = format!("ws://{address}")
            .into_client_request()
            .expect("a ws:// address");
        request.headers_mut().insert(
            "Sec-WebSocket-Protocol",
            "foxglove.sdk.v1".parse().expect("a header value"),
        );
        match tungstenite::connect(request) {
            Ok((socket, _)) => break socket,
            Err(_) if Instant::now() < deadline && !stop.load(Ordering::Relaxed) => {
                std::thread::sleep(Duration::from_millis(50))
            }
            Err(_) => return,
        }
    };
    let mut next_id = 1u64;
    while !stop.load(Ordering::Relaxed) {
        let Ok(message) = socket.read() else { return };
        read.fetch_add(message.len() as u64, Ordering::Relaxed);
        if let tungstenite::Message::Text(text) = message
            && let Ok(value) = serde_json::from_str::<serde_json::Value>(&text)
            && value["op"] == "advertise"
        {
            let subscriptions: Vec<_> = value["channels"]
                .as_array()
                .into_iter()
                .flatten()
                .map(|c| {
                    next_id += 1;
                    json!({"id": next_id, "channelId": c["id"]})
                })
                .collect();
            let subscribe = json!({"op": "subscribe", "subscriptions": subscriptions});
            if socket
                .send(tungstenite::Message::Text(subscribe.to_string().into()))
                .is_err()
            {
                return;
            }
        }
    }
    let _ = socket.close(None);
}

/// Tick compute distribution of the real-time daemon on the default organ palpated by the simulated
/// device for `duration` s, with the live view and a reading viewer when `live`.
fn tick_distribution(
    palpa: &Path,
    live: bool,
    duration: f64,
    out: &Path,
) -> Result<serde_json::Value> {
    use palpa::device::run::{DeviceOptions, run_device};
    let prefix = format!("palpa_bench_live_{}_{}", std::process::id(), live as u8);
    let timings = out.join(format!("remote_timings_live_{}.csv", live as u8));
    let mut command = Command::new(palpa);
    command.args(["serve", "--rt", "--prefix", &prefix, "--timings"]);
    command.arg(&timings);
    let port = free_port()?;
    if live {
        command.args(["--live", &format!("127.0.0.1:{port}")]);
    }
    let daemon = Running(
        command
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .context("cannot start palpa serve")?,
    );
    let stop = Arc::new(AtomicBool::new(false));
    let read = Arc::new(AtomicU64::new(0));
    let viewer_thread = live.then(|| {
        let (stop, read) = (stop.clone(), read.clone());
        std::thread::Builder::new()
            .name("palpa-bench-viewer".into())
            .spawn(move || viewer(format!("127.0.0.1:{port}"), stop, read))
    });
    let viewer_thread = viewer_thread
        .transpose()
        .context("cannot start the viewer's thread")?;
    let options = DeviceOptions::palpating_default_organ(&prefix, duration);
    let report = run_device(&options, Arc::new(AtomicBool::new(false)), |_| {})
        .map_err(|e| anyhow::anyhow!("device: {e}"))?;
    stop.store(true, Ordering::Relaxed);
    // SAFETY: kill(2) on our own child.
    unsafe {
        libc::kill(daemon.0.id() as i32, libc::SIGTERM);
    }
    let mut daemon = daemon;
    let deadline = Instant::now() + Duration::from_secs(30);
    while daemon.0.try_wait()?.is_none() {
        if Instant::now() > deadline {
            bail!("the daemon did not stop");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    if let Some(t) = viewer_thread {
        t.join()
            .map_err(|_| anyhow::anyhow!("the viewer's thread panicked"))?;
    }
    let (compute, _) = super::read_timings(&timings)?;
    let ticks: u64 = compute.iter().map(|b| b.1).sum();
    Ok(json!({
        "live": live,
        "ticks": ticks,
        "synchronicity_misses": compute.iter().filter(|b| b.0 >= 1000).map(|b| b.1).sum::<u64>(),
        "compute_median_us": super::histogram_percentile(&compute, 0.5),
        "compute_p99_us": super::histogram_percentile(&compute, 0.99),
        "compute_p99_9_us": super::histogram_percentile(&compute, 0.999),
        "compute_max_us": compute.last().map_or(f64::NAN, |b| (b.0 + 1) as f64),
        "viewer_bytes_read": read.load(Ordering::Relaxed),
        "device_poses_answered": report.latencies_us.len(),
    }))
}

/// The `remote` benchmark (see the module's documentation); writes `remote.json` and `remote.md`.
pub fn remote(out: &Path, quick: bool) -> Result<()> {
    let pings = if quick { 1000 } else { 10_000 };
    let duration = if quick { 3.0 } else { 20.0 };
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let exe = std::env::current_exe()?;
    let palpa = exe.with_file_name("palpa");
    let bridge = exe.with_file_name("palpa-zenoh");
    if !palpa.is_file() || !bridge.is_file() {
        bail!(
            "needs the palpa and palpa-zenoh executables beside this one (cargo build --release)"
        );
    }
    let mut progress = super::Progress::new("remote", 4);

    // 1. Round trips: local iceoryx2, then through the bridge, to the same lockstep daemon.
    let prefix = format!("palpa_bench_remote_{}", std::process::id());
    let _daemon = Running(
        Command::new(&palpa)
            .args(["serve", "--lockstep", "--prefix", &prefix])
            .stdout(Stdio::null())
            .spawn()
            .context("cannot start palpa serve")?,
    );
    let local = super::ping_pong(&prefix, pings)?;
    progress.step("iceoryx2 round trips");
    let endpoint = format!("tcp/127.0.0.1:{}", free_port()?);
    let _bridge = Running(
        Command::new(&bridge)
            .args(["--prefix", &prefix, "--listen", &endpoint])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .context("cannot start palpa-zenoh")?,
    );
    let remote = zenoh_ping(&endpoint, &prefix, pings)?;
    drop(_bridge);
    drop(_daemon);
    progress.step("Zenoh round trips");

    // 2. The live view's cost on the tick.
    let without = tick_distribution(&palpa, false, duration, out)?;
    progress.step("tick without the live view");
    let with = tick_distribution(&palpa, true, duration, out)?;
    progress.step("tick with the live view and a viewer");

    let local_spread = super::spread(local);
    let remote_spread = super::spread(remote);
    let added = |q: &str| {
        remote_spread[q].as_f64().unwrap_or(f64::NAN) - local_spread[q].as_f64().unwrap_or(f64::NAN)
    };
    let result = json!({
        "command": format!("palpa-bench remote{} --out {}", if quick { " --quick" } else { "" }, out.display()),
        "date": super::plot::utc_now(),
        "machine": super::machine(),
        "round_trip": {
            "daemon": "palpa serve --lockstep (one tick per pose), embedded default scene, tool probe",
            "iceoryx2_us": local_spread,
            "zenoh_us": remote_spread,
            "zenoh_path": "Zenoh client (this process) -> tcp loopback -> palpa-zenoh -> iceoryx2 -> daemon, and back",
            "added_median_us": added("median"),
            "added_p99_us": added("p99"),
        },
        "live_view_tick_cost": {
            "scene": "embedded default, simulated device palpating, palpa serve --rt",
            "duration_s": duration,
            "without": without,
            "with_live_and_a_viewer": with,
        },
    });
    std::fs::write(
        out.join("remote.json"),
        serde_json::to_string_pretty(&result)?,
    )?;
    let md = format!(
        "# palpa-bench remote\n\n`{}` — {}\n\n| path | p50 µs | p99 µs |\n| --- | --- | --- |\n| iceoryx2 (local) | {:.1} | {:.1} |\n| Zenoh through palpa-zenoh (loopback) | {:.1} | {:.1} |\n| added by Zenoh | {:.1} | {:.1} |\n\n| daemon tick (µs) | p50 | p99 | p99.9 | max | misses |\n| --- | --- | --- | --- | --- | --- |\n| without the live view | {} | {} | {} | {} | {} |\n| with `--live` and a viewer | {} | {} | {} | {} | {} |\n",
        result["command"].as_str().unwrap_or(""),
        result["date"].as_str().unwrap_or(""),
        local_spread["median"].as_f64().unwrap_or(f64::NAN),
        local_spread["p99"].as_f64().unwrap_or(f64::NAN),
        remote_spread["median"].as_f64().unwrap_or(f64::NAN),
        remote_spread["p99"].as_f64().unwrap_or(f64::NAN),
        added("median"),
        added("p99"),
        without["compute_median_us"],
        without["compute_p99_us"],
        without["compute_p99_9_us"],
        without["compute_max_us"],
        without["synchronicity_misses"],
        with["compute_median_us"],
        with["compute_p99_us"],
        with["compute_p99_9_us"],
        with["compute_max_us"],
        with["synchronicity_misses"],
    );
    std::fs::write(out.join("remote.md"), &md)?;
    print!("{md}");
    Ok(())
}
