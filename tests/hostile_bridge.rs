//! A hostile bridge: for 3 000 ticks of `palpa serve --lockstep` (3 simulated seconds, one tick per
//! pose) a bridge publishes on the pose service random bytes, NaN, ±inf, denormals, huge numbers,
//! zero and non-unit quaternions, sequence numbers going backwards and device time stamps jumping
//! by hours, mixed with plausible poses; then good poses. The daemon ticks through all of it, never
//! sends a non-finite number, answers the good poses once the tool is picked up again, and a time
//! stamp jump does not widen the speed limit. Every wait has a watchdog; nothing is timed.

mod common;

use common::Rng;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use iceoryx2::port::update_connections::UpdateConnections;
use palpa::ipc::payload::*;
use palpa::ipc::services::*;

/// Kills its process when dropped.
struct Guard(Child);

impl Drop for Guard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

const IDENTITY: [f64; 4] = [1.0, 0.0, 0.0, 0.0];

fn pose(seq: u64, device_time_ns: u64, position: [f64; 3]) -> ToolPoseV1 {
    ToolPoseV1 {
        seq,
        device_time_ns,
        position,
        orientation: IDENTITY,
        ..ToolPoseV1::default()
    }
}

/// One hostile pose; `seq` is the bridge's running sequence number.
fn hostile(rng: &mut Rng, seq: u64) -> ToolPoseV1 {
    let t = seq * 1_000_000;
    // A plausible spot over or in the default organ (its top is at z = 0.0645).
    let near = |rng: &mut Rng| {
        [
            0.02 * (rng.unit() - 0.5),
            0.02 * (rng.unit() - 0.5),
            0.05 + 0.04 * rng.unit(),
        ]
    };
    let specials = [
        f64::NAN,
        -f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::MIN_POSITIVE / 3.0,
        f64::from_bits(1),
        -f64::from_bits(1),
        f64::MAX,
        -f64::MAX,
        1e300,
        0.0,
        -0.0,
    ];
    match rng.below(11) {
        // Random bytes, all of them.
        0 => ToolPoseV1 {
            seq: rng.next(),
            device_time_ns: rng.next(),
            position: [rng.bits(), rng.bits(), rng.bits()],
            orientation: [rng.bits(), rng.bits(), rng.bits(), rng.bits()],
            jaw: rng.bits(),
            buttons: rng.next() as u32,
            reserved: rng.next() as u32,
        },
        // A special value in one of the eight numbers.
        1 => {
            let mut p = pose(seq, t, near(rng));
            let v = specials[rng.below(specials.len())];
            match rng.below(8) {
                k @ 0..3 => p.position[k] = v,
                k @ 3..7 => p.orientation[k - 3] = v,
                _ => p.jaw = v,
            }
            p
        }
        // Denormal positions and jaw, a valid quaternion: finite, so possibly accepted.
        2 => {
            let mut p = pose(seq, t, [f64::from_bits(rng.below_u64(1 << 52)); 3]);
            p.jaw = f64::from_bits(rng.below_u64(1 << 52));
            p
        }
        // Zero, tiny and non-unit quaternions.
        3 => {
            let mut p = pose(seq, t, near(rng));
            p.orientation = match rng.below(3) {
                0 => [0.0; 4],
                1 => [f64::from_bits(1), 0.0, 0.0, 0.0],
                _ => [2.0, 0.0, 0.0, 0.0],
            };
            p
        }
        // The sequence number goes backwards.
        4 => pose(seq.saturating_sub(1 + rng.below_u64(50)), t, near(rng)),
        // The device clock jumps by up to an hour, forwards or back to 0, with the pose far away.
        5 => {
            let jump = if rng.below(2) == 0 {
                t + rng.below_u64(3_600_000_000_000)
            } else {
                0
            };
            pose(seq, jump, [rng.unit() - 0.5, rng.unit() - 0.5, rng.unit()])
        }
        // Huge but finite coordinates, a valid quaternion.
        6 => pose(seq, t, [1e300 * (rng.unit() - 0.5), 1e200, -1e250]),
        // A huge negative jaw (clamped) and buttons set.
        7 => {
            let mut p = pose(seq, t, near(rng));
            p.jaw = -1e308;
            p.buttons = u32::MAX;
            p.reserved = u32::MAX;
            p
        }
        // Plausible poses.
        _ => pose(seq, t, near(rng)),
    }
}

fn finite(f: &ToolFeedbackV1) -> bool {
    f.force.iter().chain(&f.torque).all(|x| x.is_finite())
}

#[test]
fn a_hostile_bridge_cannot_make_the_daemon_send_a_non_finite_number() {
    let p = format!("hostile{}", std::process::id());
    let mut daemon = Guard(
        Command::new(env!("CARGO_BIN_EXE_palpa"))
            .args(["serve", "--lockstep", "--prefix", &p])
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start palpa serve"),
    );
    let node = create_node().unwrap();
    let poses = pose_service(&node, &p, "probe")
        .unwrap()
        .publisher_builder()
        .create()
        .unwrap();
    let feedback = feedback_service(&node, &p, "probe")
        .unwrap()
        .subscriber_builder()
        .create()
        .unwrap();
    let mut received = 0u64;
    let mut non_finite = 0u64;
    // Every feedback that arrives is checked; returns the newest.
    let mut drain = || {
        let mut last = None;
        while let Some(sample) = feedback.receive().unwrap() {
            let f = *sample.payload();
            received += 1;
            non_finite += !finite(&f) as u64;
            last = Some(f);
        }
        last
    };
    // Wait for the daemon (its first feedback), then connect the pose publisher to it.
    let watchdog = Instant::now() + Duration::from_secs(20);
    let mut tick = loop {
        poses.update_connections().unwrap();
        if let Some(f) = drain() {
            break f.tick;
        }
        assert!(Instant::now() < watchdog, "the daemon does not come up");
        std::thread::sleep(Duration::from_millis(1));
    };
    poses.update_connections().unwrap();
    // Sends one pose and waits for the tick it causes (lockstep: one tick per pose).
    let mut exchange = |pose: ToolPoseV1, drain: &mut dyn FnMut() -> Option<ToolFeedbackV1>| {
        poses.send_copy(pose).unwrap();
        let watchdog = Instant::now() + Duration::from_secs(10);
        loop {
            if let Some(f) = drain().filter(|f| f.tick > tick) {
                tick = f.tick;
                return f;
            }
            assert!(
                Instant::now() < watchdog,
                "no answer after tick {tick}: the daemon stopped ticking"
            );
            std::thread::sleep(Duration::from_micros(50));
        }
    };

    let mut rng = Rng(0x5eed);
    let mut seq = 1u64;
    let mut rejected_flags = 0u64;
    let hostile_ticks = 3000;
    for _ in 0..hostile_ticks {
        let f = exchange(hostile(&mut rng, seq), &mut drain);
        rejected_flags += (f.flags & FEEDBACK_REJECTED != 0) as u64;
        seq += 1;
    }
    assert!(
        rejected_flags > hostile_ticks / 2,
        "most hostile poses are rejected ({rejected_flags} of {hostile_ticks})"
    );

    // Good poses: a press from 2 cm over the organ's top to 4.5 mm into it. The tool may be
    // anywhere after the hostile phase (a huge coordinate that was accepted as a first pose): it
    // is picked up at once or, at the latest, once it went stale (100 ticks) and was forgotten.
    let good = |k: u64| {
        let z = 0.085 - 0.025 * (k as f64 / 800.0).min(1.0);
        pose(0, 0, [0.0, 0.0, z])
    };
    let seq_base = seq + 1_000_000;
    let mut answered_from = None;
    let mut max_force = 0.0f64;
    for k in 0..1000u64 {
        let mut g = good(k);
        g.seq = seq_base + k;
        g.device_time_ns = g.seq * 1_000_000;
        let f = exchange(g, &mut drain);
        if f.seq == g.seq && f.flags & (FEEDBACK_REJECTED | FEEDBACK_STALE) == 0 {
            answered_from.get_or_insert(k);
        } else if let Some(from) = answered_from {
            panic!("good pose {k} not answered (answered from {from} on): {f:?}");
        }
        if answered_from.is_some() {
            max_force = max_force.max(f.force.iter().map(|x| x * x).sum::<f64>().sqrt());
        }
    }
    let from = answered_from.expect("the good poses are answered");
    assert!(from <= 110, "picked up after {from} good poses");
    assert!(max_force > 0.05, "the press is felt: {max_force} N");

    // A device time stamp jumping an hour ahead does not widen the speed limit: 0.5 m in one tick
    // is rejected, and the last good pose is kept.
    let last = seq_base + 999;
    let mut jump = pose(
        last + 1,
        last * 1_000_000 + 3_600_000_000_000,
        [0.5, 0.0, 0.06],
    );
    jump.orientation = IDENTITY;
    let f = exchange(jump, &mut drain);
    assert_ne!(f.flags & FEEDBACK_REJECTED, 0, "{f:?}");
    assert_eq!(f.seq, last, "the jump is not used");
    let f = exchange(pose(last + 2, 0, [0.0, 0.0, 0.06]), &mut drain);
    assert_eq!(f.seq, last + 2, "the next good pose is used: {f:?}");

    assert_eq!(
        non_finite, 0,
        "non-finite numbers in {non_finite} of {received} feedbacks"
    );
    assert!(received >= 4000);

    // The daemon is alive and stops cleanly; it counted the rejections.
    common::sigterm(&daemon.0);
    let (status, out) = common::wait_for_exit(&mut daemon.0, 10, "palpa serve does not stop");
    assert!(status.success(), "{status}: {out}");
    let line = out
        .lines()
        .find(|l| l.contains("stopped after"))
        .unwrap_or_else(|| panic!("{out}"));
    let rejected: u64 = line
        .split(", ")
        .find_map(|part| part.strip_suffix(" rejected inputs"))
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{line}"));
    assert!(rejected > rejected_flags, "{line}");
    eprintln!(
        "hostile phase: {rejected_flags} of {hostile_ticks} answers flagged rejected; good poses answered from the {from}-th on; max force {max_force:.3} N; {line}"
    );
}
