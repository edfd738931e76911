//! `palpa-zenoh` between a daemon and a Zenoh client in another process: the client (this test
//! process, in client mode, connected to the bridge's listen endpoint) presses the organ with poses
//! published on `palpa/<prefix>/tool/probe/pose`; every pose is answered on `.../feedback`, with force
//! while pressed and none after lift-off; the daemon's statistics arrive on `palpa/<prefix>/stats`;
//! the daemon's input checks apply to remote poses; a payload of the wrong size is refused by the
//! bridge. With the Python client (`tools/python/zenoh_client.py`,
//! PyPI `eclipse-zenoh`), the same press and a remote display of the mesh stream.
#![cfg(feature = "zenoh")]

mod common;

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use palpa::ipc::payload::{FEEDBACK_REJECTED, StatsV1, ToolFeedbackV1, ToolPoseV1, WireV1};
use zenoh::Wait;

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// The tip height of the press (the Python bridge's): hover 3 cm above the organ's top, down 6 mm
/// into it, hold, back up.
fn press_height(t: f64) -> f64 {
    let top = 0.0645;
    let smooth = |x: f64| {
        let x = x.clamp(0.0, 1.0);
        x * x * (3.0 - 2.0 * x)
    };
    let (above, depth) = (top + 0.03, top - 0.006);
    if t < 0.3 {
        above
    } else if t < 1.3 {
        above + (depth - above) * smooth(t - 0.3)
    } else if t < 1.8 {
        depth
    } else {
        depth + (above - depth) * smooth((t - 1.8) / 0.8)
    }
}

struct Processes(Vec<Child>);

impl Drop for Processes {
    fn drop(&mut self) {
        for child in &mut self.0 {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// A daemon (`serve_args`) and a bridge listening on a free port; returns them and the endpoint.
fn daemon_and_bridge(prefix: &str, serve_args: &[&str]) -> (Processes, String) {
    let daemon = Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args(["serve", "--prefix", prefix])
        .args(serve_args)
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let bridge = Command::new(env!("CARGO_BIN_EXE_palpa-zenoh"))
        .args([
            "--prefix",
            prefix,
            "--listen",
            &endpoint,
            "--duration",
            "120",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    (Processes(vec![daemon, bridge]), endpoint)
}

fn pose(seq: u64, z: f64) -> ToolPoseV1 {
    ToolPoseV1 {
        seq,
        device_time_ns: seq,
        position: [0.0, 0.0, z],
        orientation: [1.0, 0.0, 0.0, 0.0],
        ..ToolPoseV1::default()
    }
}

#[test]
fn a_remote_client_presses_the_organ_through_the_bridge() {
    let prefix = format!("zb{}", std::process::id());
    let (mut processes, endpoint) = daemon_and_bridge(&prefix, &["--lockstep"]);

    let mut config = zenoh::Config::default();
    config.insert_json5("mode", "\"client\"").unwrap();
    config
        .insert_json5("connect/endpoints", &format!("[\"{endpoint}\"]"))
        .unwrap();
    config
        .insert_json5("scouting/multicast/enabled", "false")
        .unwrap();
    // The bridge may still be starting: retry the connection for a while.
    let deadline = Instant::now() + Duration::from_secs(30);
    let session = loop {
        match zenoh::open(config.clone()).wait() {
            Ok(s) => break s,
            Err(e) => {
                assert!(Instant::now() < deadline, "cannot reach the bridge: {e}");
                std::thread::sleep(Duration::from_millis(100));
            }
        }
    };
    let base = format!("palpa/{prefix}/tool/probe");
    let feedback = session
        .declare_subscriber(format!("{base}/feedback"))
        .wait()
        .unwrap();
    let poses = session
        .declare_publisher(format!("{base}/pose"))
        .wait()
        .unwrap();
    let stats = session
        .declare_subscriber(format!("palpa/{prefix}/stats"))
        .wait()
        .unwrap();
    // Waits for the feedback `accept` takes (a watchdog, not a timing assertion: a lockstep daemon
    // answers every pose it gets).
    let wait_for = |accept: &dyn Fn(&ToolFeedbackV1) -> bool, resend: &dyn Fn()| {
        let deadline = Instant::now() + Duration::from_secs(30);
        let mut last_send = Instant::now();
        loop {
            while let Ok(Some(sample)) = feedback.try_recv() {
                let f = ToolFeedbackV1::read_le(&sample.payload().to_bytes())
                    .expect("feedback of 80 bytes");
                if accept(&f) {
                    return f;
                }
            }
            assert!(Instant::now() < deadline, "no answer");
            if last_send.elapsed() > Duration::from_millis(200) {
                resend();
                last_send = Instant::now();
            }
            std::thread::sleep(Duration::from_micros(50));
        }
    };
    let send = |p: &ToolPoseV1| poses.put(p.to_le_vec()).wait().unwrap();

    // The first pose, re-sent until the bridge and the daemon are up and answer it.
    send(&pose(1, press_height(0.0)));
    wait_for(&|f| f.seq == 1, &|| send(&pose(1, press_height(0.0))));
    let steps = 2600u64;
    let mut answered = 1;
    let mut max_pressed_force = 0.0f64;
    let mut last = ToolFeedbackV1::default();
    for seq in 2..=steps {
        let t = seq as f64 * 1e-3;
        send(&pose(seq, press_height(t)));
        let f = wait_for(&|f| f.seq >= seq, &|| {});
        assert_eq!(f.seq, seq, "each pose is answered, in order");
        answered += 1;
        let force = (f.force[0].powi(2) + f.force[1].powi(2) + f.force[2].powi(2)).sqrt();
        if (1.3..1.8).contains(&t) {
            assert!(
                force > 0.05 && f.contacts > 0,
                "pressed 6 mm into the organ at t {t}: {f:?}"
            );
            max_pressed_force = max_pressed_force.max(force);
        }
        last = f;
    }
    assert_eq!(answered, steps);
    assert!(max_pressed_force > 0.3, "{max_pressed_force} N");
    assert_eq!(last.force, [0.0; 3], "lifted off: {last:?}");
    assert_eq!(last.contacts, 0);

    // The daemon's input checks apply to remote poses: a non-finite position is rejected, the
    // last good pose used, and the answer says so.
    let mut bad = pose(steps + 1, press_height(3.0));
    bad.position[0] = f64::NAN;
    send(&bad);
    let f = wait_for(&|f| f.flags & FEEDBACK_REJECTED != 0, &|| {});
    assert_eq!(f.seq, steps, "the answer echoes the last good pose: {f:?}");
    assert!(f.force.iter().all(|x| x.is_finite()));
    // The daemon's statistics, once a simulated second: 2 600 ticks stepped, two windows.
    let mut windows = Vec::new();
    while let Ok(Some(sample)) = stats.try_recv() {
        windows.push(StatsV1::read_le(&sample.payload().to_bytes()).expect("stats of 128 bytes"));
    }
    let ticks: Vec<u64> = windows.iter().map(|s| s.tick).collect();
    assert_eq!(ticks, [1000, 2000], "{windows:?}");
    assert!(
        windows
            .iter()
            .all(|s| s.window_ticks == 1000 && s.tools_connected == 1)
    );
    // A payload that is not a palpa_tool_pose_v1 (87 bytes) never reaches the daemon.
    poses.put(vec![0u8; 87]).wait().unwrap();
    std::thread::sleep(Duration::from_millis(300));
    drop(poses);
    drop(feedback);
    drop(stats);
    session.close().wait().unwrap();

    let bridge = &mut processes.0[1];
    common::sigterm(bridge);
    let (status, out) = common::wait_for_exit(bridge, 30, "the bridge stops on SIGTERM");
    assert!(status.success(), "{out}");
    assert!(
        out.contains("(1 refused: not 88 bytes)"),
        "the 87-byte pose is refused: {out}"
    );
}

#[test]
fn the_python_zenoh_client_presses_and_displays_through_the_bridge() {
    let Some(python) = common::python_with("zenoh") else {
        return;
    };
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tools/python/zenoh_client.py");
    let run = |args: &[&str]| -> serde_json::Value {
        let out = Command::new(&python)
            .arg(script)
            .args(args)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout).to_string();
        assert!(
            out.status.success(),
            "{text}\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_str(text.lines().last().unwrap()).unwrap()
    };

    // A device on another host, against a lockstep daemon.
    let prefix = format!("zp{}", std::process::id());
    let (processes, endpoint) = daemon_and_bridge(&prefix, &["--lockstep"]);
    let press = run(&[
        "press",
        "--connect",
        &endpoint,
        "--prefix",
        &prefix,
        "--seconds",
        "3",
    ]);
    drop(processes);
    assert_eq!(press["sent"], 3000);
    assert_eq!(press["answered"], 3000, "{press}");
    assert!(press["max_force"].as_f64().unwrap() > 0.3, "{press}");
    assert_eq!(press["final_force"], serde_json::json!([0.0, 0.0, 0.0]));
    assert_eq!(press["final_contacts"], 0);

    // A display on another host, against a real-time daemon (keyframes every second).
    let prefix = format!("zd{}", std::process::id());
    let (processes, endpoint) =
        daemon_and_bridge(&prefix, &["--duration", "30", "--keyframe-every", "1"]);
    let display = run(&[
        "display",
        "--connect",
        &endpoint,
        "--prefix",
        &prefix,
        "--seconds",
        "3",
    ]);
    drop(processes);
    assert_eq!(display["bad"], 0, "{display}");
    assert!(display["keyframes"].as_u64().unwrap() >= 1, "{display}");
    assert!(display["deltas"].as_u64().unwrap() >= 1, "{display}");
    let organ = &display["bodies"]["0"];
    assert_eq!(organ["vertices"], 642, "{display}");
    assert_eq!(organ["triangles"], 1280, "{display}");
}
