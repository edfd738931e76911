//! Golden digests: the result bits of a few reference scenes, committed in `tests/golden/digests.txt`.
//! Any change of the physics' output — one bit of one node's position on one tick — changes a digest
//! and fails this test, so a change of results is always deliberate: rerun with `PALPA_BLESS=1` to
//! rewrite the file and commit it with the change that explains it.
//!
//! Each digest is FNV-1a over the little-endian bits of every body's node positions and velocities,
//! its rigid component's position, orientation, velocity and angular momentum, and every tool's
//! feedback force and torque, after every tick. The physics uses no platform `libm` (`src/math.rs`),
//! so the digests hold on any x86_64 or aarch64 machine with IEEE doubles.

mod common;

use palpa::Vec3;
use palpa::dynamics::Integrator;
use palpa::scene::{default_scene, load_scene};
use palpa::world::World;

/// (name in the file, scene path or `None` for the embedded default, integrator override, ticks)
const CASES: [(&str, Option<&str>, Option<Integrator>, u64); 13] = [
    ("default_organ", None, None, 1000),
    ("probe_press", Some("scenes/probe_press.toml"), None, 1000),
    ("probe_refine", Some("scenes/probe_refine.toml"), None, 1000),
    (
        "inclined_plane",
        Some("scenes/inclined_plane.toml"),
        None,
        1000,
    ),
    ("two_organs", Some("scenes/two_organs.toml"), None, 500),
    (
        "stiff_links_implicit",
        Some("scenes/stress/stiff_links.toml"),
        Some(Integrator::Implicit),
        500,
    ),
    (
        "stiff_links_multirate",
        Some("scenes/stress/stiff_links.toml"),
        Some(Integrator::Multirate),
        300,
    ),
    (
        "stiff_links_symplectic",
        Some("scenes/stress/stiff_links.toml"),
        Some(Integrator::Symplectic),
        300,
    ),
    ("incision", Some("scenes/incision.toml"), None, 2500),
    ("transection", Some("scenes/transection.toml"), None, 1500),
    ("plastic", Some("scenes/plastic.toml"), None, 4000),
    ("laparoscopy", Some("scenes/laparoscopy.toml"), None, 1000),
    ("self_fold", Some("scenes/self_fold.toml"), None, 600),
];

struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn f64(&mut self, x: f64) {
        for byte in x.to_bits().to_le_bytes() {
            self.0 ^= byte as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    fn vec(&mut self, v: &Vec3) {
        self.f64(v.x);
        self.f64(v.y);
        self.f64(v.z);
    }
}

fn world_for(path: Option<&str>, integrator: Option<Integrator>) -> World {
    let scene = match path {
        None => default_scene(),
        Some(path) => match integrator {
            Some(integrator) => common::scene_file_with_integrator(path, integrator.name()),
            None => load_scene(&common::repo_root().join(path)).unwrap_or_else(|e| panic!("{e}")),
        },
    };
    World::from_scene(&scene)
}

fn digest(path: Option<&str>, integrator: Option<Integrator>, ticks: u64) -> u64 {
    let mut world = world_for(path, integrator);
    let mut hash = Fnv::new();
    for _ in 0..ticks {
        world.step();
        for body in &world.bodies {
            let s = &body.surface;
            for (x, v) in s.position_in_world.iter().zip(&s.velocity_in_world) {
                hash.vec(x);
                hash.vec(v);
            }
            let r = &body.rigid;
            hash.vec(&r.position_in_world);
            for c in r.world_from_body.coords.iter() {
                hash.f64(*c);
            }
            hash.vec(&r.velocity_in_world);
            hash.vec(&r.angular_momentum_in_world);
        }
        for tool in &world.tools {
            hash.vec(&tool.feedback.force_in_world);
            hash.vec(&tool.feedback.torque_in_world);
        }
    }
    hash.0
}

fn computed() -> Vec<(String, u64, u64)> {
    CASES
        .iter()
        .map(|&(name, path, integrator, ticks)| {
            (name.to_string(), ticks, digest(path, integrator, ticks))
        })
        .collect()
}

fn file_text(rows: &[(String, u64, u64)]) -> String {
    let mut text = String::from(
        "# Golden digests of tests/golden_digests.rs: name, ticks, FNV-1a of every state bit.\n\
         # Rewrite with PALPA_BLESS=1 cargo test --release --test golden_digests, only on purpose.\n",
    );
    for (name, ticks, digest) in rows {
        text += &format!("{name} {ticks} {digest:016x}\n");
    }
    text
}

#[test]
fn result_bits_match_the_committed_digests() {
    let path = common::repo_root().join("tests/golden/digests.txt");
    let rows = computed();
    if std::env::var("PALPA_BLESS").is_ok_and(|v| v == "1") {
        std::fs::write(&path, file_text(&rows)).unwrap();
        eprintln!("wrote {}", path.display());
        return;
    }
    let committed = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (create it with PALPA_BLESS=1)", path.display()));
    let expected = file_text(&rows);
    let mut differences = Vec::new();
    for (line_ours, line_theirs) in expected.lines().zip(committed.lines()) {
        if line_ours != line_theirs {
            differences.push(format!("committed {line_theirs:?}, computed {line_ours:?}"));
        }
    }
    if expected.lines().count() != committed.lines().count() {
        differences.push("the number of cases differs".into());
    }
    assert!(
        differences.is_empty(),
        "the result bits changed:\n{}\nIf the change is deliberate, rerun with PALPA_BLESS=1 and commit \
         tests/golden/digests.txt with it.",
        differences.join("\n")
    );
}

#[test]
fn digests_are_the_same_in_one_process_twice() {
    let (_, path, integrator, ticks) = CASES[1];
    assert_eq!(
        digest(path, integrator, ticks),
        digest(path, integrator, ticks)
    );
}
