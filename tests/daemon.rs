//! The daemon between real processes over iceoryx2: `palpa serve` with `palpa-device`, a misbehaving
//! bridge, a device killed and replaced, and a display that joins late. Every test uses its own
//! service prefix; the tests run one at a time (the machine has two cores) and every child process is
//! killed when its test ends, passing or not.

mod common;

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use iceoryx2::port::update_connections::UpdateConnections;
use palpa::Vec3;
use palpa::display::DisplayMesh;
use palpa::ipc::payload::*;
use palpa::ipc::services::*;
use palpa::scene::default_scene;
use palpa::tool::ToolPose;
use palpa::world::World;

static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// Kills its process when dropped.
struct Guard(Child);

impl Drop for Guard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn prefix(test: &str) -> String {
    format!("t{}_{test}", std::process::id())
}

fn temp(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("palpa-daemon-{}-{name}", std::process::id()))
}

fn serve(args: &[&str]) -> Guard {
    Guard(
        Command::new(env!("CARGO_BIN_EXE_palpa"))
            .arg("serve")
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start palpa serve"),
    )
}

fn device(args: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_palpa-device"));
    c.args(args).stdout(Stdio::null()).stderr(Stdio::inherit());
    c
}

/// Sends SIGTERM and returns what the daemon printed; it must stop cleanly.
fn stop(mut guard: Guard) -> String {
    common::sigterm(&guard.0);
    let (status, out) =
        common::wait_for_exit(&mut guard.0, 10, "palpa serve did not stop on SIGTERM");
    assert!(status.success(), "palpa serve exited with {status}");
    out
}

type Ipc = iceoryx2::prelude::ipc::Service;
type Topic<T> = iceoryx2::service::port_factory::publish_subscribe::PortFactory<Ipc, T, ()>;

fn publisher_of<T: std::fmt::Debug + iceoryx2::prelude::ZeroCopySend>(
    factory: Result<Topic<T>, IpcError>,
) -> iceoryx2::port::publisher::Publisher<Ipc, T, ()> {
    factory.unwrap().publisher_builder().create().unwrap()
}

fn subscriber_of<T: std::fmt::Debug + iceoryx2::prelude::ZeroCopySend>(
    factory: Result<Topic<T>, IpcError>,
) -> iceoryx2::port::subscriber::Subscriber<Ipc, T, ()> {
    factory.unwrap().subscriber_builder().create().unwrap()
}

type Control = iceoryx2::service::port_factory::request_response::PortFactory<
    Ipc,
    ControlRequestV1,
    (),
    ControlResponseV1,
    (),
>;

fn client_of(
    factory: Result<Control, IpcError>,
) -> iceoryx2::port::client::Client<Ipc, ControlRequestV1, (), ControlResponseV1, ()> {
    factory.unwrap().client_builder().create().unwrap()
}

/// Polls `f` every 0.2 ms until it returns Some, for at most `seconds`.
fn wait_for<T>(seconds: f64, mut f: impl FnMut() -> Option<T>) -> Option<T> {
    let deadline = Instant::now() + Duration::from_secs_f64(seconds);
    while Instant::now() < deadline {
        if let Some(v) = f() {
            return Some(v);
        }
        std::thread::sleep(Duration::from_micros(200));
    }
    None
}

#[test]
fn serve_and_device_press_for_3_s_in_lockstep() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let p = prefix("press");
    let daemon = serve(&["--prefix", &p, "--lockstep"]);
    let node = create_node().unwrap();
    let stats = subscriber_of(stats_service(&node, &p));
    let (report, trace) = (temp("press.json"), temp("press.csv"));
    let status = device(&[
        "--prefix",
        &p,
        "--lockstep",
        "--duration",
        "3",
        "--motion",
        "press",
        "--report",
    ])
    .arg(&report)
    .arg("--trace")
    .arg(&trace)
    .status()
    .unwrap();
    assert!(status.success());
    let mut last_stats = None;
    while let Some(s) = stats.receive().unwrap() {
        last_stats = Some(*s.payload());
    }
    let out = stop(daemon);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(report["poses_sent"], 3000);
    assert_eq!(report["lost"], 0, "{report}");
    // Force rises while pressing and is zero once the probe is back up.
    let rows: Vec<Vec<f64>> = std::fs::read_to_string(&trace)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    // One row per pose, in sequence.
    assert_eq!(rows.len(), 3000);
    assert!(rows.iter().enumerate().all(|(k, r)| r[0] == (k + 1) as f64));
    let force_at = |t: f64| rows.iter().find(|r| r[1] >= t).map(|r| r[7]).unwrap();
    assert!(force_at(1.6) > 0.1, "pressing: {}", force_at(1.6));
    assert!(force_at(1.2) < force_at(1.6), "the force rises with depth");
    assert!(
        rows.iter()
            .filter(|r| r[1] > 2.9)
            .all(|r| r[5] == 0.0 && r[6] == 0.0 && r[7] == 0.0 && r[8] == 0.0)
    );
    // The daemon published its statistics (counts only: timing figures belong in palpa-bench)
    // and stepped once per pose.
    let stats = last_stats.expect("the stats service publishes");
    assert!(stats.tick >= 1000 && stats.tick % 1000 == 0 && stats.window_ticks == 1000);
    assert_eq!((stats.rejected_inputs, stats.disconnects), (0, 0));
    assert_eq!((stats.guard_events, stats.ipc_errors), (0, 0));
    assert_ne!(stats.active_systems & SYSTEM_TOOL_CONTACT, 0);
    assert!(out.contains("stopped after 3000 ticks: "), "{out}");
    assert!(
        out.contains("0 rejected inputs, 0 disconnects, 0 guard events, 0 IPC errors"),
        "{out}"
    );
    std::fs::remove_file(temp("press.json")).ok();
    std::fs::remove_file(temp("press.csv")).ok();
}

fn good_pose(seq: u64, z: f64) -> ToolPoseV1 {
    ToolPoseV1 {
        seq,
        device_time_ns: seq * 1_000_000,
        position: [0.0, 0.0, z],
        orientation: [1.0, 0.0, 0.0, 0.0],
        ..ToolPoseV1::default()
    }
}

#[test]
fn bad_input_is_rejected_counted_and_the_next_good_pose_used() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let p = prefix("bad");
    // Lockstep: one tick per pose, so the speed check sees exactly one tick between poses whatever
    // the machine's load.
    let daemon = serve(&["--prefix", &p, "--lockstep"]);
    let node = create_node().unwrap();
    let poses = publisher_of(pose_service(&node, &p, "probe"));
    let feedback = subscriber_of(feedback_service(&node, &p, "probe"));
    let stats = subscriber_of(stats_service(&node, &p));
    let newest = || {
        let mut last = None;
        while let Some(s) = feedback.receive().unwrap() {
            last = Some(*s.payload());
        }
        last
    };
    // Waits until the daemon has stepped past `tick` (the pose just sent) and returns that feedback.
    let after = |tick: u64| {
        wait_for(10.0, || newest().filter(|f| f.tick > tick)).expect("the daemon ticks")
    };
    let mut tick = wait_for(10.0, || {
        poses.update_connections().unwrap();
        newest()
    })
    .expect("the daemon is up")
    .tick;
    poses.update_connections().unwrap();
    poses.send_copy(good_pose(1, 0.2)).unwrap();
    let f = after(tick);
    assert_eq!(f.seq, 1);
    tick = f.tick;
    let mut nan = good_pose(2, 0.2);
    nan.position[0] = f64::NAN;
    let jump = good_pose(3, 1.2);
    let mut zero = good_pose(4, 0.2);
    zero.orientation = [0.0; 4];
    for bad in [nan, jump, zero] {
        poses.send_copy(bad).unwrap();
        let f = after(tick);
        assert_eq!(f.seq, 1, "a rejected pose is not answered as used");
        assert!(f.force.iter().all(|x| x.is_finite()));
        tick = f.tick;
    }
    poses.send_copy(good_pose(5, 0.2005)).unwrap();
    let f = after(tick);
    assert_eq!(f.seq, 5, "the next good pose is used");
    tick = f.tick;
    poses.send_copy(good_pose(3, 0.2)).unwrap();
    let f = after(tick);
    assert_eq!(f.seq, 5, "a backwards sequence number is rejected");
    tick = f.tick;
    poses.send_copy(good_pose(6, 0.201)).unwrap();
    let f = after(tick);
    assert_eq!(f.seq, 6);
    tick = f.tick;
    // Counted in the statistics (published every simulated second: step on to tick 1000).
    let mut seq = 7;
    while tick < 1000 {
        poses.send_copy(good_pose(seq, 0.201)).unwrap();
        let f = after(tick);
        assert_eq!(f.seq, seq);
        (tick, seq) = (f.tick, seq + 1);
    }
    let counted = wait_for(10.0, || {
        let mut last = None;
        while let Some(s) = stats.receive().unwrap() {
            last = Some(*s.payload());
        }
        last.filter(|s| s.tick >= 1000)
    })
    .expect("stats after the bad poses");
    assert_eq!(counted.rejected_inputs, 4);
    let out = stop(daemon);
    assert!(out.contains("4 rejected inputs"), "{out}");
}

#[test]
fn a_killed_device_goes_stale_and_a_new_one_is_picked_up() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let p = prefix("kill");
    let daemon = serve(&["--prefix", &p, "--stale-after-ms", "100"]);
    let node = create_node().unwrap();
    let feedback = subscriber_of(feedback_service(&node, &p, "probe"));
    let newest = || {
        let mut last = None;
        while let Some(s) = feedback.receive().unwrap() {
            last = Some(*s.payload());
        }
        last
    };
    let first = Guard(
        device(&["--prefix", &p, "--duration", "20", "--motion", "press"])
            .spawn()
            .unwrap(),
    );
    // Connected and pressing.
    let pressing = wait_for(10.0, || {
        newest().filter(|f| f.seq > 1200 && f.flags & FEEDBACK_STALE == 0 && f.contacts > 0)
    });
    assert!(pressing.is_some(), "the device connects and presses");
    let mut first = first;
    first.0.kill().unwrap(); // SIGKILL
    first.0.wait().unwrap();
    // Marked stale after 100 ticks without a pose (the waits below are watchdogs, not timings).
    let stale = wait_for(20.0, || newest().filter(|f| f.flags & FEEDBACK_STALE != 0))
        .expect("marked stale");
    assert!(stale.tick > pressing.unwrap().tick);
    assert_eq!(stale.force, [0.0; 3]);
    assert_eq!(stale.torque, [0.0; 3]);
    // The daemon keeps ticking.
    let later =
        wait_for(20.0, || newest().filter(|f| f.tick > stale.tick + 200)).expect("still ticking");
    assert_ne!(later.flags & FEEDBACK_STALE, 0);
    // A new device process is picked up (its sequence starts again from 1).
    let second = device(&["--prefix", &p, "--duration", "1", "--motion", "press"])
        .spawn()
        .unwrap();
    let second = Guard(second);
    let picked = wait_for(20.0, || {
        newest().filter(|f| f.flags & FEEDBACK_STALE == 0 && f.seq < 1000 && f.seq > 0)
    });
    assert!(picked.is_some(), "the new device is picked up");
    drop(second);
    let out = stop(daemon);
    assert!(out.contains("disconnects"), "{out}");
}

#[test]
fn a_display_joining_late_rebuilds_the_exact_mesh() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let p = prefix("display");
    let daemon = serve(&["--prefix", &p, "--lockstep", "--keyframe-every", "1000"]);
    let node = create_node().unwrap();
    let poses = publisher_of(pose_service(&node, &p, "probe"));
    let feedback = subscriber_of(feedback_service(&node, &p, "probe"));
    let control = client_of(control_service(&node, &p));
    // The probe goes down into the organ and comes back: the mesh moves.
    let pose_at = |k: u64| {
        let t = k as f64 * 0.001;
        let z = 0.12 - 0.06 * (t / 0.8).min(1.0) + 0.06 * ((t - 1.0) / 0.5).clamp(0.0, 1.0);
        good_pose(k, z)
    };
    // Wait until the daemon is up (its initial feedback reaches us), then connect our poses.
    wait_for(10.0, || {
        poses.update_connections().unwrap();
        feedback.receive().unwrap().map(|_| ())
    })
    .expect("the daemon is up");
    poses.update_connections().unwrap();
    let mut display = DisplayMesh::default();
    let mut mesh = None;
    let total = 1500u64;
    for k in 1..=total {
        poses.send_copy(pose_at(k)).unwrap();
        wait_for(5.0, || {
            let mut answered = false;
            while let Some(s) = feedback.receive().unwrap() {
                answered |= s.payload().seq == k;
            }
            answered.then_some(())
        })
        .expect("answered");
        if k == 700 {
            // The display joins now and asks for a keyframe.
            let subscriber = mesh_service(&node, &p)
                .unwrap()
                .subscriber_builder()
                .create()
                .unwrap();
            let pending = control
                .send_copy(ControlRequestV1 {
                    command: CONTROL_KEYFRAME,
                    ..ControlRequestV1::default()
                })
                .unwrap();
            mesh = Some((subscriber, pending));
        }
        if let Some((subscriber, _)) = &mesh {
            while let Some(sample) = subscriber.receive().unwrap() {
                // Deltas before the keyframe are refused; everything after applies.
                let _ = display.apply(sample.user_header(), sample.payload());
            }
        }
    }
    let out = stop(daemon);
    assert!(display.ready, "a keyframe arrived");
    assert!(
        display.tick > 700 && display.tick <= total,
        "display at tick {}",
        display.tick
    );
    // The same scene and the same poses, in this process: the display must hold its exact f32 bits.
    let mut world = World::from_scene(&default_scene());
    let probe = world.tools.iter().position(|t| t.name == "probe").unwrap();
    for k in 1..=display.tick {
        let pose = pose_at(k);
        world.tools[probe].set_target(
            ToolPose {
                position_in_world: Vec3::from(pose.position),
                ..ToolPose::default()
            },
            0.0,
        );
        world.step();
    }
    let exact = &world.bodies[0].surface.position_in_world;
    assert_eq!(display.positions.len(), exact.len());
    for (shown, x) in display.positions.iter().zip(exact) {
        let bits = [x.x as f32, x.y as f32, x.z as f32].map(f32::to_bits);
        assert_eq!(shown.map(f32::to_bits), bits);
    }
    assert_eq!(display.triangles, world.bodies[0].surface.triangles);
    assert!(out.contains("stopped"), "{out}");
}

#[test]
fn demo_runs_daemon_and_device_together() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let out = Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args(["demo", "--duration", "1.5"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(text.contains("1500 poses sent"), "{text}");
    assert!(text.contains("round trip median"), "{text}");
    assert!(text.contains("palpa serve: stopped after"), "{text}");
}

/// The whole number that follows the first `marker` in `text`.
fn number_after(text: &str, marker: &str) -> u64 {
    text.split(marker)
        .nth(1)
        .and_then(|a| a.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no number after {marker:?}: {text}"))
}

#[test]
fn demo_drives_both_tools_of_the_laparoscopy_scene() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let timings = temp("demo-timings.csv");
    let recording = temp("demo-recording.mcap");
    let out = Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args([
            "demo",
            "--scene",
            "laparoscopy",
            "--duration",
            "2",
            "--timings",
        ])
        .arg(&timings)
        .arg("--record")
        .arg(&recording)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    // One simulated device per IPC tool, each answered by the daemon serving the built-in scene.
    assert!(
        text.contains("2 simulated Geomagic Touch (probe, grasper)"),
        "{text}"
    );
    for tool in ["probe", "grasper"] {
        let line = text
            .lines()
            .find(|l| l.starts_with(&format!("palpa demo: {tool}: 2000 poses sent")))
            .unwrap_or_else(|| panic!("no report for {tool}: {text}"));
        let answered = number_after(line, "poses sent, ");
        assert!(answered > 1000, "{line}");
        // Each tool reaches tissue within the 2 s: the probe's first press bottoms out at 1 s,
        // the grasper's jaws close on the tube at 1.5 s.
        let touching = number_after(line, "touching tissue in ");
        assert!(touching > 50, "{line}");
    }
    assert!(text.contains("palpa serve: stopped after"), "{text}");
    // `--timings` went on to the daemon: its histogram holds every tick it ran.
    let ticks = number_after(&text, "stopped after ");
    let csv = std::fs::read_to_string(&timings).unwrap();
    let counted: u64 = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).unwrap().parse::<u64>().unwrap())
        .sum();
    assert_eq!(counted, ticks, "{csv}");
    let _ = std::fs::remove_file(&timings);
    // `--record` went on to the daemon too: the session replays bit for bit, every tick of it.
    let out = Command::new(env!("CARGO_BIN_EXE_palpa-replay"))
        .arg(&recording)
        .args(["--verify", "--step-times"])
        .output()
        .unwrap();
    let replayed = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{replayed}");
    assert!(
        replayed.contains(&format!("verify: OK — {ticks} ticks replayed")),
        "{replayed}"
    );
    assert!(
        replayed.contains(&format!("step times: {ticks} steps replayed here")),
        "{replayed}"
    );
    let _ = std::fs::remove_file(&recording);
    // A scene name that is neither a file nor built in is refused, naming the built-in ones.
    let out = Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args(["demo", "--scene", "no_such_scene"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(text.contains("built in: organ, laparoscopy"), "{text}");
}

#[test]
fn control_pauses_resumes_and_resets() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let p = prefix("control");
    let daemon = serve(&["--prefix", &p]);
    let node = create_node().unwrap();
    let control = client_of(control_service(&node, &p));
    let stats = subscriber_of(stats_service(&node, &p));
    let ask = |command: u32| -> ControlResponseV1 {
        let pending = wait_for(10.0, || {
            let pending = control
                .send_copy(ControlRequestV1 {
                    command,
                    ..ControlRequestV1::default()
                })
                .unwrap();
            // A request sent before the daemon's server exists is lost: ask again.
            (pending.number_of_server_connections() > 0).then_some(pending)
        })
        .expect("the daemon's control server");
        wait_for(5.0, || pending.receive().unwrap().map(|r| *r.payload())).expect("a response")
    };
    let newest_stats = || {
        let mut last = None;
        while let Some(s) = stats.receive().unwrap() {
            last = Some(*s.payload());
        }
        last
    };
    let unknown = ask(99);
    assert_eq!(unknown.status, -1);
    let paused = ask(CONTROL_PAUSE);
    assert_eq!((paused.command, paused.status), (CONTROL_PAUSE, 0));
    let stats_paused =
        wait_for(3.0, || newest_stats().filter(|s| s.paused == 1)).expect("paused in stats");
    let resumed = ask(CONTROL_RESUME);
    assert_eq!(resumed.status, 0);
    assert!(resumed.tick >= paused.tick);
    // A pose that is not a number, rejected and counted; the count is the session's: a reset
    // keeps it (it went back to 0 with the tools' histories before 2026-12-06).
    let poses = publisher_of(pose_service(&node, &p, "probe"));
    let rejected = wait_for(10.0, || {
        poses.update_connections().unwrap();
        poses
            .send_copy(ToolPoseV1 {
                seq: 1,
                position: [f64::NAN; 3],
                orientation: [1.0, 0.0, 0.0, 0.0],
                ..ToolPoseV1::default()
            })
            .unwrap();
        newest_stats().filter(|s| s.rejected_inputs > 0)
    })
    .expect("the rejected pose counted in the statistics")
    .rejected_inputs;
    let reset = ask(CONTROL_RESET);
    assert_eq!(reset.status, 0);
    assert!(reset.tick < 5, "reset goes back to tick 0: {}", reset.tick);
    let after_reset = wait_for(5.0, || newest_stats().filter(|s| s.tick > reset.tick))
        .expect("statistics after the reset");
    assert!(
        after_reset.rejected_inputs >= rejected,
        "{} rejected inputs after the reset, {rejected} before",
        after_reset.rejected_inputs
    );
    assert_eq!(stats_paused.paused, 1);
    stop(daemon);
}

#[test]
fn a_hostile_control_client_gets_an_answer_to_every_request_and_the_daemon_goes_on() {
    // Requests with arbitrary bits: commands from 0..6 half of the time (resets, pauses, resumes,
    // keyframes among them), any u32 otherwise; reserved and argument fields filled with noise.
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let p = prefix("hostile_control");
    let daemon = serve(&["--prefix", &p]);
    let node = create_node().unwrap();
    let control = client_of(control_service(&node, &p));
    let stats = subscriber_of(stats_service(&node, &p));
    let mut rng = common::Rng(0x5eed_0003);
    let mut next = move || rng.next();
    let known = [
        CONTROL_RESET,
        CONTROL_PAUSE,
        CONTROL_RESUME,
        CONTROL_KEYFRAME,
    ];
    let (mut applied, mut refused) = (0, 0);
    for k in 0..300 {
        let bits = next();
        let command = if bits & 1 == 0 {
            (bits >> 8) as u32 % 6
        } else {
            (bits >> 32) as u32
        };
        let request = ControlRequestV1 {
            command,
            reserved: next() as u32,
            argument: next(),
        };
        let pending = wait_for(10.0, || {
            let pending = control.send_copy(request).unwrap();
            (pending.number_of_server_connections() > 0).then_some(pending)
        })
        .expect("the daemon's control server");
        let response = wait_for(5.0, || pending.receive().unwrap().map(|r| *r.payload()))
            .unwrap_or_else(|| panic!("request {k} ({command}) unanswered"));
        assert_eq!(response.command, command, "request {k} echoed");
        if known.contains(&command) {
            assert_eq!(response.status, 0, "request {k}: {command} is a command");
            applied += 1;
        } else {
            assert_eq!(
                response.status, -1,
                "request {k}: {command} is not a command"
            );
            refused += 1;
        }
    }
    assert!(
        applied > 50 && refused > 100,
        "{applied} applied, {refused} refused"
    );
    // Resume (the last pause may have held it) and watch the loop tick on.
    let pending = control
        .send_copy(ControlRequestV1 {
            command: CONTROL_RESUME,
            ..ControlRequestV1::default()
        })
        .unwrap();
    wait_for(5.0, || pending.receive().unwrap().map(|r| *r.payload())).expect("resumed");
    let first = wait_for(3.0, || newest_of(&stats)).expect("statistics");
    let later = wait_for(5.0, || newest_of(&stats).filter(|s| s.tick > first.tick))
        .expect("the daemon still ticks");
    assert_eq!(later.paused, 0);
    assert_eq!(later.guard_events, 0);
    stop(daemon);
}

/// Reads the newest sample of a latest-value subscriber.
fn newest_of<T: std::fmt::Debug + Copy + iceoryx2::prelude::ZeroCopySend>(
    subscriber: &iceoryx2::port::subscriber::Subscriber<Ipc, T, ()>,
) -> Option<T> {
    let mut last = None;
    while let Some(s) = subscriber.receive().unwrap() {
        last = Some(*s.payload());
    }
    last
}

/// Waits (watchdog 20 s) for a process to end on its own and returns its status and output.
fn wait_end(mut guard: Guard) -> (std::process::ExitStatus, String) {
    common::wait_for_exit(&mut guard.0, 20, "palpa serve did not stop")
}

#[test]
fn transient_ipc_errors_are_counted_and_outlived() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let p = prefix("transient");
    // Feedback sends of loop ticks 100..150 fail as if iceoryx2 had refused them.
    let daemon = serve(&["--prefix", &p, "--inject-ipc-faults", "100:50"]);
    let node = create_node().unwrap();
    let stats = subscriber_of(stats_service(&node, &p));
    let feedback = subscriber_of(feedback_service(&node, &p, "probe"));
    let counted = wait_for(30.0, || newest_of(&stats).filter(|s| s.tick >= 2000))
        .expect("the daemon goes on ticking");
    assert_eq!(counted.ipc_errors, 50);
    let f = wait_for(10.0, || {
        newest_of(&feedback).filter(|f| f.tick > counted.tick)
    })
    .expect("feedback flows again");
    assert!(f.flags & FEEDBACK_STALE != 0, "no device: {f:?}");
    let out = stop(daemon);
    assert!(out.contains("0 guard events, 50 IPC errors"), "{out}");
}

#[test]
fn persistent_ipc_errors_stop_the_daemon_with_an_error() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let p = prefix("persistent");
    let daemon = serve(&["--prefix", &p, "--inject-ipc-faults", "100:all"]);
    let (status, out) = wait_end(daemon);
    assert!(!status.success(), "{out}");
    // 100 good ticks, then a second (1000 ticks) of failures on every tick.
    assert!(out.contains("stopped after 1100 ticks"), "{out}");
    assert!(out.contains("1000 IPC errors"), "{out}");
}

/// The stiff body of the `palpa check` warning test, stepped with the explicit scheme (the guard
/// acts), with a tool over IPC far from it.
const GUARDED_SCENE: &str = "[world]\ngravity = [0.0, 0.0, 0.0]\nintegrator = \"symplectic\"\n\
    [[body]]\nname = \"stiff\"\nmesh = { icosphere = { radius = 0.05, subdivisions = 4 } }\n\
    surface_mass = 0.05\nsurface_stiffness = 400.0\nangular_velocity = [0.0, 0.0, 3.0]\n\
    [[tool]]\nname = \"probe\"\nshape = { sphere = { radius = 0.006 } }\ninput = \"ipc\"\n";

#[test]
fn the_divergence_guard_flags_feedback_records_events_and_counts() {
    use palpa::record::proto;
    use palpa::record::replay::read_recording_file;
    use prost::Message;
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let p = prefix("guard");
    let scene = temp("guard.toml");
    let recording = temp("guard.mcap");
    std::fs::write(&scene, GUARDED_SCENE).unwrap();
    let daemon = serve(&[
        "--prefix",
        &p,
        "--lockstep",
        scene.to_str().unwrap(),
        "--record",
        recording.to_str().unwrap(),
    ]);
    let node = create_node().unwrap();
    let poses = publisher_of(pose_service(&node, &p, "probe"));
    let feedback = subscriber_of(feedback_service(&node, &p, "probe"));
    let stats = subscriber_of(stats_service(&node, &p));
    let mut tick = wait_for(10.0, || {
        poses.update_connections().unwrap();
        newest_of(&feedback)
    })
    .expect("the daemon is up")
    .tick;
    poses.update_connections().unwrap();
    let mut flagged = Vec::new();
    for seq in 1..=1000 {
        poses.send_copy(good_pose(seq, 0.5)).unwrap();
        let f =
            wait_for(10.0, || newest_of(&feedback).filter(|f| f.tick > tick)).expect("answered");
        assert_eq!(f.seq, seq);
        assert!(f.force.iter().chain(&f.torque).all(|x| x.is_finite()));
        if f.flags & FEEDBACK_DIVERGED != 0 {
            flagged.push(f.tick);
        }
        tick = f.tick;
    }
    let s = wait_for(10.0, || newest_of(&stats)).expect("stats at tick 1000");
    let out = stop(daemon);
    assert!(!flagged.is_empty(), "the guard acts on this scene");
    assert_eq!(
        s.guard_events,
        flagged.len() as u64,
        "one body: one event a flagged tick"
    );
    assert!(
        out.contains(&format!("{} guard events", flagged.len())),
        "{out}"
    );
    // The recording has one DIVERGENCE_GUARD event per flagged tick, naming the body and the cause,
    // and the recorded feedback carries the flag on exactly those ticks.
    let r = read_recording_file(&recording).unwrap();
    let events: Vec<proto::Event> = r
        .messages
        .iter()
        .filter(|m| m.topic == "/palpa/events")
        .map(|m| proto::Event::decode(&m.data[..]).unwrap())
        .filter(|e| e.kind == proto::event::Kind::DivergenceGuard as i32)
        .collect();
    assert_eq!(
        events.iter().map(|e| e.tick).collect::<Vec<_>>(),
        flagged,
        "events at the flagged ticks"
    );
    assert!(
        events.iter().all(|e| e.detail.starts_with("body stiff: ")),
        "{:?}",
        events[0]
    );
    let recorded_flagged: Vec<u64> = r
        .messages
        .iter()
        .filter(|m| m.topic == "/palpa/tool/probe/feedback")
        .map(|m| proto::Feedback::decode(&m.data[..]).unwrap())
        .filter(|f| f.flags & FEEDBACK_DIVERGED != 0)
        .map(|f| f.tick)
        .collect();
    assert_eq!(recorded_flagged, flagged);
    // A guarded session replays bit for bit, flags included.
    let verify = std::process::Command::new(env!("CARGO_BIN_EXE_palpa-replay"))
        .arg(&recording)
        .arg("--verify")
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&verify.stdout).to_string()
        + &String::from_utf8_lossy(&verify.stderr);
    assert!(verify.status.success(), "{said}");
    assert!(said.contains("verify: OK"), "{said}");
    std::fs::remove_file(scene).ok();
    std::fs::remove_file(recording).ok();
}
