//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use palpa::scene::{Scene, parse_scene};

/// Repository root (where Cargo.toml is).
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `../shared` beside the repository, or `None` (with a message) when it is absent and not required.
/// Under `PALPA_REQUIRE_SHARED=1` (set by `.ci/run`) its absence fails the test.
pub fn shared_dir() -> Option<PathBuf> {
    let dir = repo_root().join("../shared");
    if dir.join("data").is_dir() {
        return Some(dir);
    }
    if std::env::var("PALPA_REQUIRE_SHARED").is_ok_and(|v| v == "1") {
        panic!(
            "PALPA_REQUIRE_SHARED=1 but {} is missing: the shared test data must sit beside the repository",
            dir.display()
        );
    }
    eprintln!(
        "SKIPPED: {} is absent (a fresh clone without the shared test data)",
        dir.display()
    );
    None
}

/// Parses scene text as if it were a file in the repository root.
pub fn scene(text: &str) -> Scene {
    parse_scene(text, "test.toml", &repo_root()).unwrap_or_else(|e| panic!("{e}"))
}

/// Parses scene text from a directory.
pub fn scene_in(text: &str, dir: &Path) -> Scene {
    parse_scene(text, "test.toml", dir).unwrap_or_else(|e| panic!("{e}"))
}

/// A Python interpreter that can import `modules` (`$PALPA_PYTHON`, else `.venv/bin/python` in the
/// repository, as `.ci/run` creates it), or `None` with a SKIPPED message — unless
/// `PALPA_REQUIRE_PYTHON=1`, where its absence fails the test.
pub fn python_with(modules: &str) -> Option<PathBuf> {
    use std::process::{Command, Stdio};
    let candidate = std::env::var_os("PALPA_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo_root().join(".venv/bin/python"));
    let works = Command::new(&candidate)
        .args(["-c", &format!("import {modules}")])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if works {
        return Some(candidate);
    }
    if std::env::var("PALPA_REQUIRE_PYTHON").is_ok_and(|v| v == "1") {
        panic!(
            "PALPA_REQUIRE_PYTHON=1 but {} cannot import {modules}",
            candidate.display()
        );
    }
    eprintln!(
        "SKIPPED: no Python that can import {modules} ({})",
        candidate.display()
    );
    None
}

/// A scene file of the repository (path relative to its root) with the world's integrator set to
/// `integrator` (a scene name: "symplectic", "multirate", "implicit").
pub fn scene_file_with_integrator(path: &str, integrator: &str) -> Scene {
    let path = repo_root().join(path);
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .replacen(
            "[world]",
            &format!("[world]\nintegrator = \"{integrator}\""),
            1,
        );
    let name = path.file_name().unwrap().to_string_lossy().into_owned();
    parse_scene(&text, &name, path.parent().unwrap()).unwrap_or_else(|e| panic!("{e}"))
}
