//! Recording and replay: a scripted press-and-stroke session recorded to MCAP replays bit for bit,
//! an altered input is caught at its tick, replay is deterministic, an independent Python reader
//! decodes every message, a daemon killed while recording leaves a readable file, and one stopped by
//! SIGTERM or by an error leaves a complete one (summary and footer).

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use palpa::record::proto;
use palpa::record::replay::{
    RecordedMessage, read_recording_file, summarise, verify, verify_timed, write_recording,
};
use prost::Message;

fn temp(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("palpa-recording-{}-{name}", std::process::id()))
}

fn palpa(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args(args)
        .output()
        .unwrap()
}

fn replay(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_palpa-replay"))
        .args(args)
        .output()
        .unwrap()
}

/// Records 5 s of the probe press-and-stroke scene.
fn record_session(name: &str) -> PathBuf {
    record_run(name, "probe_press.toml", "5")
}

/// Records `palpa run` of a shipped scene for `seconds` into the temporary file `name`.
fn record_run(name: &str, scene: &str, seconds: &str) -> PathBuf {
    let path = temp(name);
    let scene = format!("{}/scenes/{scene}", env!("CARGO_MANIFEST_DIR"));
    let out = palpa(&[
        "run",
        &scene,
        "--duration",
        seconds,
        "--record",
        path.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    path
}

#[test]
fn a_recorded_session_verifies_and_an_altered_input_fails_at_its_tick() {
    let path = record_session("roundtrip.mcap");
    let out = replay(&[path.to_str().unwrap(), "--verify"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(
        text.contains("verify: OK — 5000 ticks replayed, 5000 feedback and"),
        "{text}"
    );

    // Change one byte of one recorded input (a bit in the sixth byte of the probe's height: 18 µm) while
    // it presses.
    let mut recording = read_recording_file(&path).unwrap();
    let contact_tick = recording
        .messages
        .iter()
        .filter(|m| m.topic.ends_with("/feedback"))
        .map(|m| proto::Feedback::decode(&m.data[..]).unwrap())
        .find(|f| f.contacts >= 2 && f.tick > 3000)
        .expect("contact in the stroke")
        .tick;
    let input_tick = contact_tick - 1;
    let message = recording
        .messages
        .iter_mut()
        .find(|m| {
            m.topic.ends_with("/input")
                && proto::ToolInput::decode(&m.data[..]).unwrap().tick == input_tick
        })
        .unwrap();
    let mut input = proto::ToolInput::decode(&message.data[..]).unwrap();
    let position = input.position.as_mut().unwrap();
    position.z = f64::from_bits(position.z.to_bits() ^ (0x01 << 40));
    message.data = input.encode_to_vec();
    let altered = temp("altered.mcap");
    write_recording(&recording, &altered).unwrap();
    let out = replay(&[altered.to_str().unwrap(), "--verify"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(
        text.contains(&format!(
            "verify: FAILED at tick {contact_tick}: /palpa/tool/probe/feedback field"
        )),
        "{text}"
    );
    std::fs::remove_file(path).ok();
    std::fs::remove_file(altered).ok();
}

#[test]
fn the_ticks_a_daemon_missed_are_timed_when_replayed() {
    // The daemon records a miss with the tick its step led to: ticks 1, 2 500 and 5 000 (the last)
    // are the steps from 0, 2 499 and 4 999. Read as the tick a step starts from, the last one
    // would never be found.
    let path = record_session("misses.mcap");
    let mut recording = read_recording_file(&path).unwrap();
    let dt_ns = (recording.scene.dt * 1e9).round() as u64;
    for tick in [1u64, 2500, 5000] {
        recording.messages.push(RecordedMessage {
            topic: "/palpa/events".into(),
            log_time: tick * dt_ns,
            data: proto::Event {
                tick,
                kind: proto::event::Kind::SynchronicityMiss as i32,
                ..Default::default()
            }
            .encode_to_vec(),
        });
    }
    let marked = temp("misses-marked.mcap");
    write_recording(&recording, &marked).unwrap();
    let recording = read_recording_file(&marked).unwrap();
    let work = temp("work-misses");
    let (report, times) = verify_timed(&recording, &work, |_, _| {}).unwrap();
    assert_eq!(report.ticks, 5000);
    assert_eq!(times.ticks(), 5000);
    assert_eq!(times.at_misses_us.len(), 3, "{:?}", times.at_misses_us);
    assert_eq!(times.period_us, recording.scene.dt * 1e6);
    let (median, p99, longest) = (
        times.quantile_us(0.5),
        times.quantile_us(0.99),
        times.max_us,
    );
    assert!(
        0.0 < median && median <= p99 && p99 <= longest && longest.is_finite(),
        "{median} {p99} {longest}"
    );
    assert!(
        times
            .at_misses_us
            .iter()
            .all(|&us| us > 0.0 && us <= longest)
    );
    // The same bits as without the marks: the events are not inputs.
    let plain = verify(&read_recording_file(&path).unwrap(), &work, |_, _| {}).unwrap();
    assert_eq!(plain, report);

    let out = replay(&[marked.to_str().unwrap(), "--verify", "--step-times"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(
        text.contains("step times: 5000 steps replayed here, mean "),
        "{text}"
    );
    assert!(
        text.contains("step times: the 3 ticks recorded as synchronicity misses replay in median "),
        "{text}"
    );
    assert!(text.contains("verify: OK — 5000 ticks replayed"), "{text}");
    // Without the flag the output is the same every run (no times); the flag needs --verify.
    let out = replay(&[marked.to_str().unwrap(), "--verify"]);
    assert!(!String::from_utf8_lossy(&out.stdout).contains("step times"));
    let out = replay(&[marked.to_str().unwrap(), "--step-times"]);
    assert_eq!(out.status.code(), Some(2));
    let _ = std::fs::remove_dir_all(work);
    std::fs::remove_file(path).ok();
    std::fs::remove_file(marked).ok();
}

#[test]
fn replaying_twice_gives_identical_output() {
    let path = record_session("twice.mcap");
    let recording = read_recording_file(&path).unwrap();
    let a = verify(&recording, &temp("work-a"), |_, _| {}).unwrap();
    let b = verify(&recording, &temp("work-b"), |_, _| {}).unwrap();
    assert_eq!(a, b);
    assert_eq!(a.ticks, 5000);
    let first = replay(&[path.to_str().unwrap(), "--verify", "--summary", "--json"]);
    let second = replay(&[path.to_str().unwrap(), "--verify", "--summary", "--json"]);
    assert!(first.status.success());
    assert_eq!(first.stdout, second.stdout);
    let _ = std::fs::remove_dir_all(temp("work-a"));
    let _ = std::fs::remove_dir_all(temp("work-b"));
    std::fs::remove_file(path).ok();
}

#[test]
fn an_independent_python_reader_decodes_every_message() {
    let Some(python) = common::python_with("mcap, mcap_protobuf") else {
        return;
    };
    let path = record_session("python.mcap");
    let out = Command::new(python)
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tools/python/read_recording.py"
        ))
        .arg(&path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let decoded: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let ours = summarise(&read_recording_file(&path).unwrap());
    assert_eq!(
        decoded["messages"],
        serde_json::to_value(&ours.messages).unwrap()
    );
    assert_eq!(decoded["last_feedback_tick"], 5000);
    assert_eq!(decoded["session_end_tick"], 5000);
    assert_eq!(ours.ticks, 5000);
    assert!((decoded["max_force"].as_f64().unwrap() - ours.max_force).abs() < 1e-12);
    assert!(
        decoded["messages"]["/palpa/mesh/keyframe"]
            .as_u64()
            .unwrap()
            >= 3
    );
    std::fs::remove_file(path).ok();
}

/// `palpa-replay FILE --summary --json`.
fn summary_of(path: &Path) -> serde_json::Value {
    let out = replay(&[path.to_str().unwrap(), "--summary", "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Ticks readable in a file being written (0 while it cannot be read yet).
fn ticks_on_disk(path: &Path) -> u64 {
    let out = replay(&[path.to_str().unwrap(), "--summary", "--json"]);
    serde_json::from_slice::<serde_json::Value>(&out.stdout)
        .ok()
        .and_then(|s| s["ticks"].as_u64())
        .unwrap_or(0)
}

/// Kills its process when dropped.
struct Child(std::process::Child);

impl Drop for Child {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn serve_recording(prefix: &str, path: &Path, extra: &[&str]) -> Child {
    Child(
        Command::new(env!("CARGO_BIN_EXE_palpa"))
            .args([
                "serve",
                "--prefix",
                prefix,
                "--record",
                path.to_str().unwrap(),
            ])
            .args(extra)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap(),
    )
}

/// Waits for the process to end (watchdog 30 s); its status, standard output and error.
fn ended(mut child: Child) -> (std::process::ExitStatus, String) {
    common::wait_for_exit(&mut child.0, 30, "palpa serve does not stop")
}

/// Drives a lockstep daemon's probe with `count` poses (a press), each answered before the next.
fn drive(prefix: &str, count: u64) {
    use iceoryx2::port::update_connections::UpdateConnections;
    use palpa::ipc::payload::ToolPoseV1;
    use palpa::ipc::services::{create_node, feedback_service, pose_service};
    let node = create_node().unwrap();
    let poses = pose_service(&node, prefix, "probe")
        .unwrap()
        .publisher_builder()
        .create()
        .unwrap();
    let feedback = feedback_service(&node, prefix, "probe")
        .unwrap()
        .subscriber_builder()
        .create()
        .unwrap();
    let newest = || {
        let mut last = None;
        while let Some(s) = feedback.receive().unwrap() {
            last = Some(*s.payload());
        }
        last
    };
    let wait = |what: &str, f: &mut dyn FnMut() -> bool| {
        let deadline = Instant::now() + Duration::from_secs(20);
        while !f() {
            assert!(Instant::now() < deadline, "{what}");
            std::thread::sleep(Duration::from_micros(100));
        }
    };
    let mut tick = 0;
    wait("the daemon is up", &mut || {
        poses.update_connections().unwrap();
        newest().map(|f| tick = f.tick).is_some()
    });
    poses.update_connections().unwrap();
    for seq in 1..=count {
        let z = 0.08 - 0.02 * (seq as f64 / count as f64);
        poses
            .send_copy(ToolPoseV1 {
                seq,
                device_time_ns: seq,
                position: [0.0, 0.0, z],
                orientation: [1.0, 0.0, 0.0, 0.0],
                ..ToolPoseV1::default()
            })
            .unwrap();
        wait("answered", &mut || {
            newest()
                .filter(|f| f.tick > tick)
                .map(|f| tick = f.tick)
                .is_some()
        });
    }
}

#[test]
fn a_daemon_killed_while_recording_leaves_a_readable_file() {
    let path = temp("killed.mcap");
    let prefix = format!("rk{}", std::process::id());
    let mut daemon = serve_recording(&prefix, &path, &["--lockstep"]);
    // 2 500 ticks, then wait (watchdog, no timing) until the recorder has closed the chunks of the
    // first two seconds; the lockstep daemon waits meanwhile. Then SIGKILL.
    drive(&prefix, 2500);
    let deadline = Instant::now() + Duration::from_secs(30);
    while ticks_on_disk(&path) < 2000 {
        assert!(
            Instant::now() < deadline,
            "chunks are not closed every 1000 ticks"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    daemon.0.kill().unwrap();
    daemon.0.wait().unwrap();
    let summary = summary_of(&path);
    assert_eq!(summary["complete"], false);
    // At most the last second is lost.
    let ticks = summary["ticks"].as_u64().unwrap();
    assert!((2000..=2500).contains(&ticks), "{ticks} ticks readable");
    assert!(
        summary["messages"]["/palpa/tool/probe/feedback"]
            .as_u64()
            .unwrap()
            >= 2000
    );
    std::fs::remove_file(&path).ok();
}

#[test]
fn serve_stopped_by_sigterm_leaves_a_complete_recording() {
    let path = temp("sigterm.mcap");
    let prefix = format!("rt{}", std::process::id());
    let daemon = serve_recording(&prefix, &path, &["--lockstep"]);
    drive(&prefix, 1500);
    // SAFETY: kill(2) on our own child.
    common::sigterm(&daemon.0);
    let (status, text) = ended(daemon);
    assert!(status.success(), "{status}: {text}");
    let summary = summary_of(&path);
    assert_eq!(summary["complete"], true, "{summary}");
    assert_eq!(summary["ticks"], 1500, "{summary}");
    assert_eq!(summary["messages"]["/palpa/tool/probe/feedback"], 1500);
    assert_eq!(summary["messages"]["/palpa/tool/probe/input"], 1500);
    let out = replay(&[path.to_str().unwrap(), "--verify"]);
    let verified = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{verified}");
    assert!(
        verified.contains("verify: OK — 1500 ticks replayed"),
        "{verified}"
    );
    std::fs::remove_file(&path).ok();
}

#[test]
fn serve_stopped_by_an_error_leaves_a_complete_recording() {
    // In the loop: IPC failing on every tick from tick 200 on; after a second of it the daemon
    // stops with an error.
    let path = temp("error.mcap");
    let prefix = format!("re{}", std::process::id());
    let daemon = serve_recording(&prefix, &path, &["--inject-ipc-faults", "200:all"]);
    let (status, text) = ended(daemon);
    assert!(!status.success(), "{text}");
    assert!(text.contains("stopped after 1200 ticks"), "{text}");
    assert!(
        text.contains("iceoryx2 failed on each of the last 1000 ticks"),
        "{text}"
    );
    let summary = summary_of(&path);
    assert_eq!(summary["complete"], true, "{summary}");
    assert_eq!(summary["ticks"], 1200, "{summary}");
    assert_eq!(summary["messages"]["/palpa/tool/probe/feedback"], 1200);
    std::fs::remove_file(&path).ok();

    // At start: the daemon's statistics service already exists with another payload type, so the
    // daemon cannot open it and stops before the first tick.
    use palpa::ipc::services::{create_node, stats_service_name};
    let prefix = format!("rs{}", std::process::id());
    let node = create_node().unwrap();
    let _squatter = node
        .service_builder(
            &iceoryx2::prelude::ServiceName::new(&stats_service_name(&prefix)).unwrap(),
        )
        .publish_subscribe::<u64>()
        .open_or_create()
        .unwrap();
    let daemon = serve_recording(&prefix, &path, &[]);
    let (status, text) = ended(daemon);
    assert!(!status.success(), "{text}");
    assert!(text.contains("Error: palpa serve:"), "{text}");
    let summary = summary_of(&path);
    assert_eq!(summary["complete"], true, "{summary}");
    assert_eq!(summary["messages"]["/palpa/scene"], 1, "{summary}");
    std::fs::remove_file(&path).ok();
}

#[test]
fn palpa_run_stopped_by_sigterm_finishes_its_recording() {
    let path = temp("run-sigterm.mcap");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/probe_press.toml");
    let run = Child(
        Command::new(env!("CARGO_BIN_EXE_palpa"))
            .args(["run", scene, "--duration", "100000", "--record"])
            .arg(&path)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap(),
    );
    // Once a chunk is on disk (the run is under way), SIGTERM.
    let deadline = Instant::now() + Duration::from_secs(60);
    while ticks_on_disk(&path) < 1000 {
        assert!(Instant::now() < deadline, "the run records nothing");
        std::thread::sleep(Duration::from_millis(50));
    }
    // SAFETY: kill(2) on our own child.
    common::sigterm(&run.0);
    let (status, text) = ended(run);
    assert_eq!(status.code(), Some(1), "{text}");
    assert!(text.contains("stopped by a signal after "), "{text}");
    let summary = summary_of(&path);
    assert_eq!(summary["complete"], true, "{summary}");
    let ticks = summary["ticks"].as_u64().unwrap();
    assert!((1000..100_000_000).contains(&ticks), "{summary}");
    std::fs::remove_file(&path).ok();
}

#[test]
fn play_publishes_the_recording_for_a_display() {
    use palpa::display::DisplayMesh;
    use palpa::ipc::services::{create_node, feedback_service, mesh_service};
    let path = record_session("play.mcap");
    let prefix = format!("play{}", std::process::id());
    let node = create_node().unwrap();
    let mesh = mesh_service(&node, &prefix)
        .unwrap()
        .subscriber_builder()
        .create()
        .unwrap();
    let feedback = feedback_service(&node, &prefix, "probe")
        .unwrap()
        .subscriber_builder()
        .create()
        .unwrap();
    let mut player = Command::new(env!("CARGO_BIN_EXE_palpa-replay"))
        .args([
            path.to_str().unwrap(),
            "--play",
            "--speed",
            "10",
            "--prefix",
            &prefix,
        ])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut display = DisplayMesh::default();
    let mut last_feedback_tick = 0;
    let started = Instant::now();
    loop {
        while let Some(sample) = mesh.receive().unwrap() {
            let _ = display.apply(sample.user_header(), sample.payload());
        }
        while let Some(sample) = feedback.receive().unwrap() {
            last_feedback_tick = last_feedback_tick.max(sample.payload().tick);
        }
        if let Some(status) = player.try_wait().unwrap() {
            assert!(status.success());
            break;
        }
        assert!(
            started.elapsed() < Duration::from_secs(20),
            "playback hangs"
        );
        std::thread::sleep(Duration::from_micros(200));
    }
    while let Some(sample) = mesh.receive().unwrap() {
        let _ = display.apply(sample.user_header(), sample.payload());
    }
    // The display followed the recorded stream to its end; the last feedback came through.
    let recording = read_recording_file(&path).unwrap();
    let last_mesh_tick = recording
        .messages
        .iter()
        .filter(|m| m.topic.starts_with("/palpa/mesh/"))
        .map(|m| m.log_time / 1_000_000)
        .max()
        .unwrap();
    assert!(display.ready);
    assert_eq!(display.tick, last_mesh_tick);
    assert!(last_feedback_tick >= 4990, "{last_feedback_tick}");
    std::fs::remove_file(path).ok();
}

/// The events of a recording, in file order.
fn events_of(path: &Path) -> Vec<proto::Event> {
    read_recording_file(path)
        .unwrap()
        .messages
        .iter()
        .filter(|m| m.topic == "/palpa/events")
        .map(|m| proto::Event::decode(&m.data[..]).unwrap())
        .collect()
}

#[test]
fn a_session_without_tools_is_recorded_and_replayed_to_its_last_tick() {
    // No tool: the outputs are the mesh messages alone, at display rate (every 16 or 17 ticks), so
    // the last 14 ticks of a 1 s session sent nothing. The session's end event says where it ended
    // (before it, summary and replay stopped at the last mesh message: 986 ticks).
    let path = record_run("toolless.mcap", "table_rest.toml", "1");
    let events = events_of(&path);
    let end = events.last().expect("events");
    assert_eq!(end.kind, proto::event::Kind::SessionEnd as i32);
    assert_eq!(end.tick, 1000);
    assert_eq!(
        events
            .iter()
            .filter(|e| e.kind == proto::event::Kind::SessionEnd as i32)
            .count(),
        1
    );
    let summary = summary_of(&path);
    assert_eq!(summary["ticks"], 1000, "{summary}");
    assert_verifies(&path, 1000, 0);
    std::fs::remove_file(&path).ok();
}

/// Drives a lockstep daemon's probe through `plan`: a pose (its sequence number and position) is
/// sent and answered before the next; a control command is sent before the next pose (a lockstep
/// daemon answers control requests when a pose comes) and its response checked. Returns the tick
/// each pose's feedback carried.
fn drive_plan(prefix: &str, plan: &[Plan]) -> Vec<u64> {
    use iceoryx2::port::update_connections::UpdateConnections;
    use palpa::ipc::payload::{ControlRequestV1, ToolPoseV1};
    use palpa::ipc::services::{control_service, create_node, feedback_service, pose_service};
    let node = create_node().unwrap();
    let poses = pose_service(&node, prefix, "probe")
        .unwrap()
        .publisher_builder()
        .create()
        .unwrap();
    let feedback = feedback_service(&node, prefix, "probe")
        .unwrap()
        .subscriber_builder()
        .create()
        .unwrap();
    let control = control_service(&node, prefix)
        .unwrap()
        .client_builder()
        .create()
        .unwrap();
    let wait = |what: &str, f: &mut dyn FnMut() -> bool| {
        let deadline = Instant::now() + Duration::from_secs(20);
        while !f() {
            assert!(Instant::now() < deadline, "{what}");
            std::thread::sleep(Duration::from_micros(100));
        }
    };
    let newest = || {
        let mut last = None;
        while let Some(s) = feedback.receive().unwrap() {
            last = Some(*s.payload());
        }
        last
    };
    wait("the daemon is up", &mut || {
        poses.update_connections().unwrap();
        newest().is_some()
    });
    poses.update_connections().unwrap();
    let mut answered = Vec::new();
    let mut pending = Vec::new();
    for step in plan {
        match *step {
            Plan::Pose(seq, position) => {
                poses
                    .send_copy(ToolPoseV1 {
                        seq,
                        device_time_ns: seq,
                        position,
                        orientation: [1.0, 0.0, 0.0, 0.0],
                        ..ToolPoseV1::default()
                    })
                    .unwrap();
                let mut tick = 0;
                // A pose that is not a number is answered with the rejection's flag (the echo
                // keeps the last good pose's sequence number).
                let rejected = position.iter().any(|x| !x.is_finite());
                wait("answered", &mut || {
                    newest()
                        .filter(|f| {
                            f.seq == seq
                                || (rejected
                                    && f.flags & palpa::ipc::payload::FEEDBACK_REJECTED != 0)
                        })
                        .map(|f| tick = f.tick)
                        .is_some()
                });
                answered.push(tick);
            }
            Plan::Control(command) => pending.push(
                control
                    .send_copy(ControlRequestV1 {
                        command,
                        ..ControlRequestV1::default()
                    })
                    .unwrap(),
            ),
        }
    }
    for p in pending {
        let mut response = None;
        wait("the control request answered", &mut || {
            response = p.receive().unwrap().map(|r| *r.payload());
            response.is_some()
        });
        assert_eq!(response.unwrap().status, 0);
    }
    answered
}

/// A step of [`drive_plan`].
enum Plan {
    Pose(u64, [f64; 3]),
    Control(u32),
}

/// `count` poses pressing the probe 3 cm down from 8 cm above the table (sequence numbers from 1).
fn press(count: u64) -> Vec<Plan> {
    (1..=count)
        .map(|seq| Plan::Pose(seq, [0.0, 0.0, 0.08 - 0.03 * seq as f64 / count as f64]))
        .collect()
}

/// The session's summary says `ticks` ticks and `feedback` feedback messages, and it verifies.
fn assert_summary_and_verify(path: &Path, ticks: u64, feedback: u64) {
    let summary = summary_of(path);
    assert_eq!(summary["ticks"], ticks, "{summary}");
    assert_eq!(
        summary["messages"]["/palpa/tool/probe/feedback"], feedback,
        "{summary}"
    );
    assert_verifies(path, ticks, feedback);
}

/// The kinds and ticks of a recording's events but synchronicity misses (a tick whose compute took
/// longer than the period is one, in lockstep too: the first, warming up, may be one on this shared
/// machine).
fn events_but_misses(path: &Path) -> Vec<(i32, u64)> {
    events_of(path)
        .iter()
        .filter(|e| e.kind != proto::event::Kind::SynchronicityMiss as i32)
        .map(|e| (e.kind, e.tick))
        .collect()
}

/// Runs `plan` against a recording lockstep daemon, stops it; the recording's path and each pose's
/// feedback tick.
/// `name` names the file (`plan-NAME.mcap`) and the daemon's prefix, apart from the other tests'.
fn record_plan(name: &str, plan: &[Plan]) -> (PathBuf, Vec<u64>) {
    let (path, answered, _) = record_plan_printing(name, plan);
    (path, answered)
}

/// [`record_plan`], with what the daemon printed.
fn record_plan_printing(name: &str, plan: &[Plan]) -> (PathBuf, Vec<u64>, String) {
    let path = temp(&format!("plan-{name}.mcap"));
    let prefix = format!("plan{name}{}", std::process::id());
    let daemon = serve_recording(&prefix, &path, &["--lockstep"]);
    let answered = drive_plan(&prefix, plan);
    common::sigterm(&daemon.0);
    let (status, text) = ended(daemon);
    assert!(status.success(), "{status}: {text}");
    (path, answered, text)
}

/// `palpa-replay --verify` passes on `path` with `ticks` ticks and `feedback` feedback messages.
fn assert_verifies(path: &Path, ticks: u64, feedback: u64) {
    let out = replay(&[path.to_str().unwrap(), "--verify"]);
    let verified = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{verified}");
    assert!(
        verified.contains(&format!(
            "verify: OK — {ticks} ticks replayed, {feedback} feedback and"
        )),
        "{verified}"
    );
}

#[test]
fn a_session_reset_midway_replays_bit_for_bit_across_the_reset() {
    // 700 lockstep poses pressing down, a reset, then 500 more pressing elsewhere: the world's tick
    // starts again from 0 at the reset, so ticks 1..500 happen twice with different poses. Replay
    // tells them apart by the reset between them (before 2026-12-06 it applied the inputs of both
    // at the first and failed at tick 1: `contacts` recorded 1, replayed 0).
    use palpa::ipc::payload::CONTROL_RESET;
    let mut plan = press(700);
    plan.push(Plan::Control(CONTROL_RESET));
    plan.extend((701..=1200u64).map(|seq| {
        let k = (seq - 700) as f64 / 500.0;
        Plan::Pose(seq, [0.01 * k, 0.0, 0.07 - 0.025 * k])
    }));
    let (path, answered) = record_plan("reset", &plan);
    assert_eq!(answered[699], 700);
    assert_eq!(
        answered[700], 1,
        "the first pose after the reset is stepped at tick 1"
    );
    assert_eq!(answered[1199], 500);
    assert_eq!(
        events_but_misses(&path),
        [
            (proto::event::Kind::Reset as i32, 700),
            (proto::event::Kind::SessionEnd as i32, 500)
        ]
    );
    assert_summary_and_verify(&path, 1200, 1200);
    // The duration in short (1 200 ticks of 1 ms is 1.2000000000000002 s as a float).
    let out = replay(&[path.to_str().unwrap(), "--summary"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains(": 1.2 s simulated (1200 ticks)"), "{text}");
    std::fs::remove_file(&path).ok();
}

#[test]
fn a_session_paused_and_resumed_replays_bit_for_bit() {
    // 400 poses pressing, a pause, 100 poses moving the probe elsewhere while nothing steps (each is
    // answered, none recorded as stepped), a resume, 400 more: the poses taken while paused set the
    // target the first step after the resume starts from.
    use palpa::ipc::payload::{CONTROL_PAUSE, CONTROL_RESUME};
    let mut plan = press(400);
    plan.push(Plan::Control(CONTROL_PAUSE));
    plan.extend((401..=500u64).map(|seq| Plan::Pose(seq, [0.005, 0.0, 0.05])));
    plan.push(Plan::Control(CONTROL_RESUME));
    plan.extend((501..=900u64).map(|seq| {
        let k = (seq - 500) as f64 / 400.0;
        Plan::Pose(seq, [0.005 + 0.005 * k, 0.0, 0.05 - 0.01 * k])
    }));
    let (path, answered, printed) = record_plan_printing("pause", &plan);
    // The closing line tells the paused ticks from the stepped ones (it counted them all as
    // ticks, without a word).
    assert!(
        printed.contains("stopped after 900 ticks (100 of them paused): "),
        "{printed}"
    );
    // The pause is answered with the pose after it: that pose is taken, not stepped.
    assert_eq!(answered[399], 400);
    assert!(answered[400..500].iter().all(|&t| t == 400), "{answered:?}");
    assert_eq!(answered[500], 401);
    assert_eq!(answered[899], 800);
    assert_eq!(
        events_but_misses(&path),
        [
            (proto::event::Kind::Pause as i32, 400),
            (proto::event::Kind::Resume as i32, 400),
            (proto::event::Kind::SessionEnd as i32, 800)
        ]
    );
    assert_eq!(
        summary_of(&path)["messages"]["/palpa/tool/probe/input"],
        900
    );
    assert_summary_and_verify(&path, 800, 800);
    std::fs::remove_file(&path).ok();
}

#[test]
fn a_pose_rejected_while_paused_replays_bit_for_bit() {
    // A pose that is not a number among those taken while paused (found by an integrator's client,
    // 2026-12-07): the daemon flagged its rejection (8) on that paused answer only, and the first
    // step after the resume carried no flag, where the replay applies the rejection recorded at
    // that tick to that step — `--verify` failed there on `flags`. The rejection now flags the
    // feedback of every answer up to and including the first step after it.
    use palpa::ipc::payload::{CONTROL_PAUSE, CONTROL_RESUME};
    let mut plan = press(300);
    plan.push(Plan::Control(CONTROL_PAUSE));
    plan.extend((301..=340u64).map(|seq| {
        let x = if seq == 320 { f64::NAN } else { 0.004 };
        Plan::Pose(seq, [x, 0.0, 0.055])
    }));
    plan.push(Plan::Control(CONTROL_RESUME));
    plan.extend((341..=600u64).map(|seq| Plan::Pose(seq, [0.004, 0.0, 0.055])));
    let (path, answered) = record_plan("pause-reject", &plan);
    assert!(answered[300..340].iter().all(|&t| t == 300), "{answered:?}");
    assert_eq!(answered[340], 301);
    assert_eq!(
        events_but_misses(&path),
        [
            (proto::event::Kind::Pause as i32, 300),
            (proto::event::Kind::InputRejected as i32, 300),
            (proto::event::Kind::Resume as i32, 300),
            (proto::event::Kind::SessionEnd as i32, 560)
        ]
    );
    assert_summary_and_verify(&path, 560, 560);
    std::fs::remove_file(&path).ok();
}

#[test]
fn resets_answered_together_replay_as_one_after_the_other() {
    // Two reset requests before one pose: the daemon answers both in the same tick, the second at
    // the fresh world's tick 0 — two epochs, the first of no tick.
    use palpa::ipc::payload::CONTROL_RESET;
    let mut plan = press(300);
    plan.push(Plan::Control(CONTROL_RESET));
    plan.push(Plan::Control(CONTROL_RESET));
    plan.extend((301..=600u64).map(|seq| Plan::Pose(seq, [0.004, 0.0, 0.06])));
    let (path, answered) = record_plan("resettwice", &plan);
    assert_eq!((answered[299], answered[300], answered[599]), (300, 1, 300));
    assert_eq!(
        events_but_misses(&path),
        [
            (proto::event::Kind::Reset as i32, 300),
            (proto::event::Kind::Reset as i32, 0),
            (proto::event::Kind::SessionEnd as i32, 300)
        ]
    );
    assert_summary_and_verify(&path, 600, 600);
    std::fs::remove_file(&path).ok();
}
