//! Determinism: the same scene run twice gives byte-identical traces, through the library and through
//! the `palpa run` command.

mod common;

use std::process::Command;

use palpa::scene::load_scene;
use palpa::trace::{write_trace_header, write_trace_rows};
use palpa::world::World;

fn trace_of(scene: &str, ticks: u64) -> Vec<u8> {
    let scene = load_scene(&common::repo_root().join(scene)).unwrap();
    let mut world = World::from_scene(&scene);
    let mut out = Vec::new();
    write_trace_header(&mut out).unwrap();
    for _ in 0..ticks {
        world.step();
        write_trace_rows(&mut out, &world).unwrap();
    }
    out
}

#[test]
fn two_library_runs_give_byte_identical_traces() {
    for scene in [
        "scenes/organ.toml",
        "scenes/inclined_plane.toml",
        "scenes/table_rest.toml",
        "scenes/probe_press.toml",
    ] {
        let a = trace_of(scene, 1500);
        let b = trace_of(scene, 1500);
        assert!(a.len() > 1500 * 100, "{scene}: a real trace");
        assert!(a == b, "{scene}: traces differ");
    }
}

#[test]
fn two_cli_runs_give_byte_identical_trace_files() {
    let dir = std::env::temp_dir().join(format!("palpa-determinism-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut traces = Vec::new();
    for k in 0..2 {
        let path = dir.join(format!("trace{k}.csv"));
        let status = Command::new(env!("CARGO_BIN_EXE_palpa"))
            .args(["run", "--duration", "1.5", "--trace"])
            .arg(&path)
            .status()
            .unwrap();
        assert!(status.success());
        traces.push(std::fs::read(&path).unwrap());
    }
    std::fs::remove_dir_all(&dir).unwrap();
    let text = String::from_utf8(traces[0].clone()).unwrap();
    assert_eq!(text.lines().count(), 1 + 1501, "header plus ticks 0..=1500");
    assert!(text.starts_with(palpa::trace::TRACE_HEADER));
    assert!(traces[0] == traces[1], "the two runs' traces differ");
}

#[test]
fn every_integrator_is_deterministic() {
    let path = common::repo_root().join("scenes/stress/light_nodes.toml");
    for integrator in ["symplectic", "multirate", "implicit"] {
        let text = std::fs::read_to_string(&path).unwrap().replacen(
            "[world]",
            &format!("[world]\nintegrator = \"{integrator}\""),
            1,
        );
        let run = || {
            let scene =
                palpa::scene::parse_scene(&text, "light_nodes.toml", path.parent().unwrap())
                    .unwrap();
            let mut world = World::from_scene(&scene);
            let mut out = Vec::new();
            for _ in 0..500 {
                world.step();
                write_trace_rows(&mut out, &world).unwrap();
            }
            out
        };
        assert!(run() == run(), "{integrator}: traces differ");
    }
}

/// A world cloned mid-run steps on to the same bits as the original, in scenes whose topology
/// changes (a cut, a transection, a tear, subdivision) and with bodies in contact: the clone keeps
/// the room reserved in every list whose room is its limit (a bare copy of those lists stopped a
/// cut's search early, and dropped every contact between bodies). Every node's position is compared
/// after every tick, with the trace rows.
#[test]
fn a_world_cloned_mid_run_steps_on_to_the_same_bits() {
    for (scene, at, ticks) in [
        ("scenes/incision.toml", 300, 1500),
        ("scenes/transection.toml", 300, 1500),
        ("scenes/tear.toml", 300, 1500),
        ("scenes/probe_refine.toml", 300, 800),
        ("scenes/two_organs.toml", 100, 600),
    ] {
        let loaded = load_scene(&common::repo_root().join(scene)).unwrap();
        let mut world = World::from_scene(&loaded);
        for _ in 0..at {
            world.step();
        }
        let mut copy = world.clone();
        let (mut rows, mut copy_rows) = (Vec::new(), Vec::new());
        for tick in 0..ticks {
            world.step();
            copy.step();
            assert_eq!(
                world.bodies.len(),
                copy.bodies.len(),
                "{scene}, tick {tick}"
            );
            for (a, b) in world.bodies.iter().zip(&copy.bodies) {
                let (pa, pb) = (&a.surface.position_in_world, &b.surface.position_in_world);
                assert_eq!(pa.len(), pb.len(), "{scene}, tick {tick}");
                for (p, q) in pa.iter().zip(pb) {
                    for d in 0..3 {
                        assert_eq!(p[d].to_bits(), q[d].to_bits(), "{scene}, tick {tick}");
                    }
                }
            }
            write_trace_rows(&mut rows, &world).unwrap();
            write_trace_rows(&mut copy_rows, &copy).unwrap();
        }
        assert!(rows == copy_rows, "{scene}: the traces differ");
    }
}
