//! Recording and replay: a scripted press-and-stroke session recorded to MCAP replays bit for bit,
//! an altered input is caught at its tick, replay is deterministic, an independent Python reader
//! decodes every message, and a daemon killed while recording leaves a readable file.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use palpa::record::proto;
use palpa::record::replay::{read_recording_file, summarise, verify, write_recording};
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
    let path = temp(name);
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/probe_press.toml");
    let out = palpa(&[
        "run",
        scene,
        "--duration",
        "5",
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
    assert!((decoded["max_force"].as_f64().unwrap() - ours.max_force).abs() < 1e-12);
    assert!(
        decoded["messages"]["/palpa/mesh/keyframe"]
            .as_u64()
            .unwrap()
            >= 3
    );
    std::fs::remove_file(path).ok();
}

#[test]
fn a_daemon_killed_while_recording_leaves_a_readable_file() {
    let path = temp("killed.mcap");
    let prefix = format!("rk{}", std::process::id());
    let mut daemon = Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args([
            "serve",
            "--prefix",
            &prefix,
            "--record",
            path.to_str().unwrap(),
        ])
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let mut device = Command::new(env!("CARGO_BIN_EXE_palpa-device"))
        .args([
            "--prefix",
            &prefix,
            "--duration",
            "10",
            "--motion",
            "palpate",
        ])
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    // Let it run a little over 2.5 simulated seconds, then SIGKILL the daemon.
    let started = Instant::now();
    while started.elapsed() < Duration::from_millis(2700) {
        std::thread::sleep(Duration::from_millis(50));
    }
    daemon.kill().unwrap();
    daemon.wait().unwrap();
    let _ = device.kill();
    let _ = device.wait();
    let out = replay(&[path.to_str().unwrap(), "--summary", "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(summary["complete"], false);
    // At most the last second is lost: more than a second of the ~2.7 s is in complete chunks.
    let ticks = summary["ticks"].as_u64().unwrap();
    assert!(ticks >= 1000, "only {ticks} ticks readable");
    assert!(
        summary["messages"]["/palpa/tool/probe/feedback"]
            .as_u64()
            .unwrap()
            >= 1000
    );
    std::fs::remove_file(Path::new(&path)).ok();
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
