//! `palpa serve --live`: a headless WebSocket viewer (`tools/python/live_view_client.py`) decodes
//! the `foxglove.SceneUpdate` messages with the schema the server advertises while the daemon runs,
//! offering the current subprotocol or its legacy name; a viewer that subscribes and then stops
//! reading costs the daemon nothing: every tick is stepped, nothing is dropped on the way from the
//! tick, and another viewer keeps receiving. `palpa-replay --play --live` shows a recording the same
//! way.
#![cfg(feature = "live")]

mod common;

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::Duration;

#[test]
fn a_headless_viewer_decodes_the_live_scene_and_a_stalled_one_changes_nothing() {
    let Some(python) = common::python_with("websockets, google.protobuf") else {
        return;
    };
    let prefix = format!("lv{}", std::process::id());
    let mut daemon = Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args([
            "serve",
            "--prefix",
            &prefix,
            "--duration",
            "8",
            "--live",
            "127.0.0.1:0",
        ])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    // The daemon prints where it listens; the rest of its output is kept for the end.
    let (lines_tx, lines) = std::sync::mpsc::channel::<String>();
    let stdout = daemon.stdout.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            let _ = lines_tx.send(line);
        }
    });
    let mut printed = Vec::new();
    let url = loop {
        let line = lines
            .recv_timeout(Duration::from_secs(60))
            .expect("the daemon prints its live address");
        printed.push(line.clone());
        if let Some(at) = line.find("ws://") {
            break line[at..].split_whitespace().next().unwrap().to_string();
        }
    };
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tools/python/live_view_client.py"
    );
    let viewer = |args: &[&str]| {
        Command::new(&python)
            .arg(script)
            .arg(&url)
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    // A viewer that subscribes to everything and then reads nothing for 4 s, while another reads.
    let stalled = viewer(&["--stall", "4"]);
    let reading = viewer(&["--seconds", "2.5"]);
    let legacy = viewer(&["--seconds", "1", "--protocol", "foxglove.websocket.v1"]);
    let finish = |child: std::process::Child| -> serde_json::Value {
        let out = child.wait_with_output().unwrap();
        let text = String::from_utf8_lossy(&out.stdout).to_string();
        assert!(
            out.status.success(),
            "{text}\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_str(text.lines().last().unwrap_or("null")).unwrap_or_default()
    };
    let summary = finish(reading);
    let legacy = finish(legacy);
    let _ = finish(stalled);
    let (status, _) = common::wait_for_exit(&mut daemon, 120, "the daemon ends after 8 s");
    assert!(status.success());
    while let Ok(line) = lines.recv_timeout(Duration::from_secs(5)) {
        printed.push(line);
    }
    let printed = printed.join("\n");

    // Decoded with the advertised schemas, on the advertised channels.
    assert_eq!(summary["protocol"], "foxglove.sdk.v1", "{summary}");
    assert_eq!(summary["decode_errors"], 0, "{summary}");
    let channels = &summary["channels"];
    assert_eq!(channels["/foxglove/scene"], "foxglove.SceneUpdate");
    assert_eq!(channels["/palpa/tool/probe/feedback"], "palpa.Feedback");
    assert_eq!(channels["/palpa/stats"], "palpa.Stats");
    assert_eq!(channels["/palpa/events"], "palpa.Event");
    let scenes = summary["scene_updates"].as_u64().unwrap();
    // 150 are published in 2.5 s at the display rate of 60 Hz; a third of that is a loose floor
    // for a shared machine, far above what a stalled pipeline delivers.
    assert!(scenes >= 50, "{summary}");
    // One organ in every update, with every triangle.
    assert_eq!(summary["body_entities"], scenes, "{summary}");
    assert_eq!(summary["triangles"], 1280, "{summary}");
    assert!(
        summary["messages"]["/palpa/tool/probe/feedback"]
            .as_u64()
            .unwrap()
            > scenes
    );
    assert!(summary["messages"]["/palpa/stats"].as_u64().unwrap() >= 1);
    // The legacy name of the protocol is served too.
    assert_eq!(legacy["protocol"], "foxglove.websocket.v1", "{legacy}");
    assert_eq!(legacy["decode_errors"], 0, "{legacy}");
    assert!(legacy["scene_updates"].as_u64().unwrap() >= 1, "{legacy}");

    // The daemon: every tick stepped, every scene update published (one per display tick: every
    // round(1000 / 60) = 17 ticks, and the keyframe ticks 1, 2001, 4001, … of a keyframe every
    // 2 s), nothing dropped between the tick and the live view, three viewers seen.
    let display_ticks = (1..=8000u64)
        .filter(|t| t % 17 == 0 || (t - 1) % 2000 == 0)
        .count();
    assert!(printed.contains("stopped after 8000 ticks"), "{printed}");
    let live = printed
        .lines()
        .find(|l| l.contains("live view published"))
        .unwrap_or_else(|| panic!("{printed}"));
    assert!(
        live.contains(&format!(
            "({display_ticks} scene updates) to 3 viewers (0 records dropped)"
        )),
        "{live}"
    );
}

#[test]
fn a_recording_played_back_is_shown_live() {
    let Some(python) = common::python_with("websockets, google.protobuf") else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("palpa_live_play_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let recording = dir.join("session.mcap");
    let run = Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args(["run", "--duration", "3", "--record"])
        .arg(&recording)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let mut play = Command::new(env!("CARGO_BIN_EXE_palpa-replay"))
        .arg(&recording)
        .args(["--play", "--speed", "0.5", "--live", "127.0.0.1:0"])
        .args(["--prefix", &format!("lp{}", std::process::id())])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let stdout = play.stdout.take().unwrap();
    let mut lines = BufReader::new(stdout).lines().map_while(Result::ok);
    let url = lines
        .by_ref()
        .find_map(|l| {
            l.find("ws://")
                .map(|at| l[at..].split_whitespace().next().unwrap().to_string())
        })
        .expect("palpa-replay prints its live address");
    let out = Command::new(&python)
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tools/python/live_view_client.py"
        ))
        .args([&url, "--seconds", "2"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value = serde_json::from_str(text.lines().last().unwrap()).unwrap();
    let rest: Vec<String> = lines.collect();
    let (status, _) = common::wait_for_exit(&mut play, 60, "the playback ends");
    assert!(status.success(), "{rest:?}");
    let _ = std::fs::remove_dir_all(&dir);
    // The recorded SceneUpdates, decoded with the advertised schema: the organ, every triangle.
    assert_eq!(summary["decode_errors"], 0, "{summary}");
    assert!(
        summary["scene_updates"].as_u64().unwrap() >= 10,
        "{summary}"
    );
    assert_eq!(
        summary["body_entities"], summary["scene_updates"],
        "{summary}"
    );
    assert_eq!(summary["triangles"], 1280, "{summary}");
    assert!(
        rest.iter().any(|l| l.contains("to 1 viewers")),
        "one viewer counted: {rest:?}"
    );
}

/// A live view asked for an address in use says which address and why, as a `LiveError::Listen`,
/// and starts on a free one.
#[test]
fn a_live_view_on_an_address_in_use_names_it() {
    use palpa::record::live::{LiveError, LiveServer};
    let taken = std::net::TcpListener::bind("127.0.0.1:0").expect("a free port");
    let address = taken.local_addr().expect("its address");
    match LiveServer::start(address, 16) {
        Err(LiveError::Listen {
            address: asked,
            reason,
        }) => {
            assert_eq!(asked, address);
            assert_eq!(reason.kind(), std::io::ErrorKind::AddrInUse, "{reason}");
            let message = LiveError::Listen { address, reason }.to_string();
            assert!(
                message.starts_with(&format!("live view: cannot listen on {address}: ")),
                "{message}"
            );
        }
        Err(other) => panic!("expected the address in use, got {other}"),
        Ok(_) => panic!("listened on {address}, which is in use"),
    }
    let free = LiveServer::start("127.0.0.1:0".parse().unwrap(), 16).expect("a free port");
    assert_ne!(free.address().port(), 0);
}
