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
