//! The Python example bridge (`tools/python/bridge.py`, PyPI `iceoryx2`) drives `palpa serve`: every
//! pose answered, the force rises during the press and is zero at the end.
//!
//! The interpreter is `$PALPA_PYTHON`, else `.venv/bin/python` in the repository (what `.ci/run`
//! creates). Without one that can import `iceoryx2` the test prints SKIPPED, unless
//! `PALPA_REQUIRE_PYTHON=1` (set by `.ci/run`), where that is a failure.

mod common;

use std::process::{Command, Stdio};

#[test]
fn python_bridge_presses_through_the_daemon() {
    let Some(python) = common::python_with("iceoryx2") else {
        return;
    };
    let prefix = format!("py{}", std::process::id());
    let mut daemon = Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args(["serve", "--lockstep", "--prefix", &prefix])
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let bridge = Command::new(python)
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tools/python/bridge.py"
        ))
        .args(["--prefix", &prefix, "--seconds", "3"])
        .output();
    let _ = daemon.kill();
    let _ = daemon.wait();
    let bridge = bridge.unwrap();
    let out = String::from_utf8_lossy(&bridge.stdout).to_string();
    assert!(
        bridge.status.success(),
        "{out}\n{}",
        String::from_utf8_lossy(&bridge.stderr)
    );
    let summary: serde_json::Value = serde_json::from_str(out.lines().last().unwrap()).unwrap();
    assert_eq!(summary["sent"], 3000);
    assert_eq!(summary["answered"], 3000, "{summary}");
    assert!(summary["max_force"].as_f64().unwrap() > 0.1, "{summary}");
    assert_eq!(summary["final_force"], serde_json::json!([0.0, 0.0, 0.0]));
    assert_eq!(summary["final_contacts"], 0);
}
