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

/// A ball of the default parameters (radius 2 cm, 642 nodes) 0.5 m above the table, with
/// `self_contact` as given: it lands at 3.1 m/s and flattens until its top meets its bottom.
pub fn dropped_ball(self_contact: bool) -> Scene {
    scene(&scene_text_of_dropped_ball(self_contact))
}

/// The text of [`dropped_ball`]'s scene.
pub fn scene_text_of_dropped_ball(self_contact: bool) -> String {
    format!(
        r#"
        [world]
        gravity = [0.0, 0.0, -9.81]
        [[body]]
        name = "ball"
        mesh = {{ ellipsoid = {{ radii = [0.02, 0.02, 0.02], subdivisions = 3 }} }}
        position = [0.0, 0.0, 0.5]
        self_contact = {self_contact}
        [[obstacle]]
        name = "table"
        plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }}
        "#
    )
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

/// splitmix64: a seeded, reproducible stream of random words for the tests that mangle inputs.
pub struct Rng(pub u64);

impl Rng {
    /// The next word.
    pub fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// A number in `0..n` (0 when n is 0).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }

    /// A number in `0..n` (n > 0), as a word.
    pub fn below_u64(&mut self, n: u64) -> u64 {
        self.next() % n
    }

    /// A number in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A direction uniform on the sphere (rejection from the cube, away from the centre).
    pub fn unit_vector(&mut self) -> palpa::Vec3 {
        loop {
            let v = palpa::Vec3::new(
                2.0 * self.unit() - 1.0,
                2.0 * self.unit() - 1.0,
                2.0 * self.unit() - 1.0,
            );
            if v.norm() > 0.2 && v.norm() <= 1.0 {
                return v.normalize();
            }
        }
    }

    /// Any 64 bits as a double (NaN, infinities and denormals included).
    pub fn bits(&mut self) -> f64 {
        f64::from_bits(self.next())
    }
}

unsafe extern "C" {
    #[link_name = "kill"]
    fn libc_kill(pid: i32, signal: i32) -> i32;
}

/// Sends SIGTERM to a child process.
pub fn sigterm(child: &std::process::Child) {
    // SAFETY: kill(2) on our own child's pid.
    unsafe {
        libc_kill(child.id() as i32, 15);
    }
}

/// Waits for a child process to end (a watchdog of `seconds`, failing the test with `what` past it);
/// returns its status and its standard output followed by its standard error, where they are piped.
pub fn wait_for_exit(
    child: &mut std::process::Child,
    seconds: u64,
    what: &str,
) -> (std::process::ExitStatus, String) {
    use std::io::Read;
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(seconds);
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        assert!(std::time::Instant::now() < deadline, "{what}");
        std::thread::sleep(std::time::Duration::from_millis(10));
    };
    let mut text = String::new();
    if let Some(mut out) = child.stdout.take() {
        out.read_to_string(&mut text).unwrap();
    }
    if let Some(mut err) = child.stderr.take() {
        err.read_to_string(&mut text).unwrap();
    }
    (status, text)
}

/// Runs `palpa run SCENE --duration D --trace … --record …` twice in `dir`; asserts that both runs
/// succeed with identical trace bytes and that `palpa-replay --verify` finds the first recording
/// replays bit for bit. Returns the trace text.
pub fn session_replays(scene: &Path, duration: &str, dir: &Path) -> String {
    let mut traces = Vec::new();
    for run in 0..2 {
        let trace = dir.join(format!("trace{run}.csv"));
        let file = dir.join(format!("session{run}.mcap"));
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_palpa"))
            .args([
                "run",
                scene.to_str().unwrap(),
                "--duration",
                duration,
                "--trace",
            ])
            .arg(&trace)
            .arg("--record")
            .arg(&file)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        traces.push(std::fs::read(&trace).unwrap());
        if run == 0 {
            let verify = std::process::Command::new(env!("CARGO_BIN_EXE_palpa-replay"))
                .arg(&file)
                .arg("--verify")
                .output()
                .unwrap();
            let text = String::from_utf8_lossy(&verify.stdout);
            assert!(
                verify.status.success() && text.contains("verify: OK"),
                "{text}{}",
                String::from_utf8_lossy(&verify.stderr)
            );
        }
    }
    assert!(
        traces[0] == traces[1],
        "two runs of {} differ",
        scene.display()
    );
    String::from_utf8_lossy(&traces[0]).into_owned()
}

/// The numbers of the column `name` of a trace (CSV with a header), in row order.
pub fn trace_column(text: &str, name: &str) -> Vec<f64> {
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let column = header
        .iter()
        .position(|c| *c == name)
        .unwrap_or_else(|| panic!("no column {name}"));
    text.lines()
        .skip(1)
        .map(|l| l.split(',').nth(column).unwrap().parse::<f64>().unwrap())
        .collect()
}

/// Asserts that a body with `key` (a line of a `[[body]]` table) is refused at line 3 of the scene
/// with a message containing `expected`.
pub fn assert_body_key_refused(key: &str, expected: &str) {
    let text = format!("[[body]]\nmesh = {{ icosphere = {{ radius = 0.02 }} }}\n{key}\n");
    let error = palpa::scene::parse_scene(&text, "bad.toml", &repo_root())
        .err()
        .unwrap_or_else(|| panic!("{key} accepted"))
        .to_string();
    assert!(
        error.contains("bad.toml:3") && error.contains(expected),
        "{key}: {error}"
    );
}

/// The number in environment variable `name`, or `default` when it is unset or not a number (lets a
/// property test run more cases or another seed by hand).
pub fn env_or<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// The whole energy of `bodies` (kinetic, links, springs, gravity on nodes and rigid components; J).
pub fn total_energy<'a>(
    bodies: impl IntoIterator<Item = &'a palpa::body::Body>,
    gravity: &palpa::Vec3,
) -> f64 {
    bodies
        .into_iter()
        .map(|b| palpa::dynamics::guard::body_energy(b, gravity))
        .sum()
}

/// The momentum of a body's surface nodes (N s; the rigid component's not included).
pub fn surface_momentum(body: &palpa::body::Body) -> palpa::Vec3 {
    let s = &body.surface;
    s.velocity_in_world
        .iter()
        .zip(&s.mass)
        .fold(palpa::Vec3::zeros(), |acc, (v, m)| acc + v * *m)
}

/// Least-squares acceleration of s(t) = s0 + v0 t + a t²/2.
pub fn fitted_acceleration(times: &[f64], s: &[f64]) -> f64 {
    // Normal equations for [1, t, t²/2].
    let mut ata = nalgebra::Matrix3::<f64>::zeros();
    let mut atb = nalgebra::Vector3::<f64>::zeros();
    for (&t, &y) in times.iter().zip(s) {
        let row = nalgebra::Vector3::new(1.0, t, t * t / 2.0);
        ata += row * row.transpose();
        atb += row * y;
    }
    (ata.try_inverse().unwrap() * atb)[2]
}

/// Generalised winding number of `p` with respect to a closed mesh: 1 inside, 0 outside.
pub fn winding_number(p: &palpa::Vec3, positions: &[palpa::Vec3], triangles: &[[u32; 3]]) -> f64 {
    let mut total = 0.0;
    for t in triangles {
        let [a, b, c] = t.map(|v| positions[v as usize] - p);
        let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
        let numerator = a.dot(&b.cross(&c));
        let denominator = la * lb * lc + a.dot(&b) * lc + b.dot(&c) * la + c.dot(&a) * lb;
        total += 2.0 * numerator.atan2(denominator);
    }
    total / (4.0 * std::f64::consts::PI)
}

/// Whether segment (p, q) crosses triangle (a, b, c) (Möller–Trumbore, touching excluded).
pub fn segment_crosses_triangle(
    p: &palpa::Vec3,
    q: &palpa::Vec3,
    a: &palpa::Vec3,
    b: &palpa::Vec3,
    c: &palpa::Vec3,
) -> bool {
    let d = q - p;
    let (e1, e2) = (b - a, c - a);
    let h = d.cross(&e2);
    let det = e1.dot(&h);
    if det.abs() < 1e-18 {
        return false;
    }
    let f = 1.0 / det;
    let s = p - a;
    let u = f * s.dot(&h);
    let qv = s.cross(&e1);
    let v = f * d.dot(&qv);
    let t = f * e2.dot(&qv);
    u > 0.0 && v > 0.0 && u + v < 1.0 && t > 0.0 && t < 1.0
}

/// Edges of each body that cross a triangle of another body.
pub fn surfaces_crossing(world: &palpa::world::World) -> usize {
    let mut count = 0;
    for (i, a) in world.bodies.iter().enumerate() {
        let x = &a.surface.position_in_world;
        for (j, b) in world.bodies.iter().enumerate() {
            if i == j {
                continue;
            }
            let y = &b.surface.position_in_world;
            for k in 0..a.edges.len() {
                let (p, q) = (x[a.edges.a[k] as usize], x[a.edges.b[k] as usize]);
                count += b
                    .surface
                    .triangles
                    .iter()
                    .filter(|t| {
                        segment_crosses_triangle(
                            &p,
                            &q,
                            &y[t[0] as usize],
                            &y[t[1] as usize],
                            &y[t[2] as usize],
                        )
                    })
                    .count();
            }
        }
    }
    count
}

/// Nodes of each body inside another body.
pub fn nodes_inside_others(world: &palpa::world::World) -> usize {
    let mut count = 0;
    for (i, a) in world.bodies.iter().enumerate() {
        for (j, b) in world.bodies.iter().enumerate() {
            if i == j {
                continue;
            }
            count += a
                .surface
                .position_in_world
                .iter()
                .filter(|p| {
                    winding_number(p, &b.surface.position_in_world, &b.surface.triangles) > 0.5
                })
                .count();
        }
    }
    count
}

/// The built-in laparoscopy scene with its two IPC tools driven by the paths of the devices
/// `palpa demo --scene laparoscopy` runs (as scripts, `seconds` long).
pub fn laparoscopy_with_demo_tools(seconds: f64) -> Scene {
    use palpa::device::run::{HandPath, built_in_target, devices_for_scene};
    use palpa::tool::{Keyframe, ToolInput, ToolPose};
    let mut scene = palpa::scene::built_in_scene("laparoscopy")
        .unwrap()
        .unwrap();
    let devices = devices_for_scene(&scene, "test", seconds);
    assert_eq!(devices.len(), 2);
    for (tool, device) in scene.tools.iter_mut().zip(&devices) {
        assert_eq!(tool.name, device.tool);
        tool.input = ToolInput::Script(match &device.path {
            HandPath::Script(keys) => keys.clone(),
            HandPath::BuiltIn { motion, at, seed } => (0..=(seconds * 100.0) as usize)
                .map(|i| {
                    let t = i as f64 * 0.01;
                    Keyframe {
                        t,
                        pose: ToolPose {
                            position_in_world: built_in_target(*motion, at, t, *seed),
                            ..ToolPose::default()
                        },
                        jaw: 0.0,
                    }
                })
                .collect(),
        });
    }
    scene
}

/// Pairs (edge, triangle) of one body where the edge crosses the triangle and has no node in it:
/// the body's surface passes through itself (two triangles that cross have such a pair, also
/// when they share a node: the side facing that node crosses the other).
pub fn self_crossings(body: &palpa::body::Body) -> usize {
    let x = &body.surface.position_in_world;
    let triangles = &body.surface.triangles;
    let boxes: Vec<(palpa::Vec3, palpa::Vec3)> = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| x[v as usize]);
            (a.inf(&b).inf(&c), a.sup(&b).sup(&c))
        })
        .collect();
    let mut count = 0;
    for k in 0..body.edges.len() {
        let (ea, eb) = (body.edges.a[k], body.edges.b[k]);
        let (p, q) = (x[ea as usize], x[eb as usize]);
        let (lo, hi) = (p.inf(&q), p.sup(&q));
        for (t, (tlo, thi)) in triangles.iter().zip(&boxes) {
            if t.contains(&ea)
                || t.contains(&eb)
                || (0..3).any(|d| lo[d] > thi[d] || tlo[d] > hi[d])
            {
                continue;
            }
            let [a, b, c] = t.map(|v| x[v as usize]);
            count += usize::from(segment_crosses_triangle(&p, &q, &a, &b, &c));
        }
    }
    count
}

/// The least distance from the first tool's capsules to body `body`'s surface, less their radius
/// (m): negative when a triangle cuts into the tool.
pub fn tool_clearance(world: &palpa::world::World, body: usize) -> f64 {
    let tool = &world.tools[0];
    let s = &world.bodies[body].surface;
    let mut least = f64::INFINITY;
    for part in &tool.parts_end[..tool.part_count] {
        for tri in &s.triangles {
            let [a, b, c] = tri.map(|v| s.position_in_world[v as usize]);
            let d = palpa::collision::tool::segment_triangle_distance(&part.a, &part.b, &a, &b, &c);
            least = least.min(d - part.radius);
        }
    }
    least
}
