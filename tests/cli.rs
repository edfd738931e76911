//! The `palpa` command line: the embedded default scene runs with no argument, `check` lists the
//! systems a scene switches on and explains the stability of the paper's scheme, errors are clear.

use std::process::{Command, Output};

fn palpa(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap()
}

fn text(out: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

#[test]
fn run_without_a_scene_uses_the_embedded_default() {
    let out = palpa(&["run", "--duration", "0.5"]);
    let t = text(&out);
    assert!(out.status.success(), "{t}");
    assert!(
        t.starts_with("<default scene>: 500 ticks (0.5 s simulated)"),
        "{t}"
    );
    assert!(t.contains("organ: com"), "{t}");
}

#[test]
fn check_lists_systems_and_the_stability_margin() {
    let out = palpa(&["check", "scenes/organ.toml"]);
    let t = text(&out);
    assert!(out.status.success(), "{t}");
    assert!(
        t.contains("systems: surface_springs, links, rigid_components, gravity, obstacle_contact, obstacle_friction"),
        "{t}"
    );
    assert!(t.contains("organ: worst node"), "{t}");
    assert!(t.contains("— stable"), "{t}");
    // Tool–face contact is listed where a tool may meet the faces of a body that does not refine.
    let t = text(&palpa(&["check", "scenes/probe_press.toml"]));
    assert!(t.contains("feedback, tool_faces"), "{t}");
    let t = text(&palpa(&["check", "scenes/probe_refine.toml"]));
    assert!(t.contains("feedback") && !t.contains("tool_faces"), "{t}");
    assert!(!t.contains("warning"), "{t}");
    // Obstacles in the scene's words (they were Rust debug structures), and a body that tears is
    // `tearing`, not `cutting` (one stage does both; it was named for cuts).
    let t = text(&palpa(&["check", "scenes/tear.toml"]));
    assert!(
        t.contains(
            "obstacle tray: plane through [0, 0, -0.031] m, outward normal [0, 0, 1], friction 0.5"
        ),
        "{t}"
    );
    assert!(t.contains(", feedback, tool_faces, tearing\n"), "{t}");
    let t = text(&palpa(&["check", "scenes/transection.toml"]));
    assert!(
        t.contains("obstacle block: box centred at [0, 0, 0.01] m, size [0.03, 0.06, 0.02] m, orientation [1, 0, 0, 0]"),
        "{t}"
    );
    assert!(t.contains(", feedback, tool_faces, cutting\n"), "{t}");
    // Self-contact is named where a body has it on (it was not, found by a reader).
    let t = text(&palpa(&["check", "scenes/self_fold.toml"]));
    assert!(
        t.contains(", body_broad_phase, body_ccd, self_contact"),
        "{t}"
    );
    let t = text(&palpa(&["check", "scenes/two_organs.toml"]));
    assert!(t.contains("body_ccd") && !t.contains("self_contact"), "{t}");
}

#[test]
fn a_run_shorter_than_half_a_tick_says_that_it_runs_none() {
    let out = palpa(&["run", "--duration", "0.0004"]);
    let t = text(&out);
    assert!(out.status.success(), "{t}");
    let warning = String::from_utf8_lossy(&out.stderr);
    assert!(
        warning.starts_with(
            "warning: --duration 0.0004 s is less than half a tick (dt 0.001 s): no tick is run\n"
        ),
        "{t}"
    );
    assert!(t.starts_with("<default scene>: 0 ticks"), "{t}");
    let t = text(&palpa(&["run", "--duration", "0.0006"]));
    assert!(!t.contains("warning"), "{t}");
    assert!(t.contains("<default scene>: 1 ticks"), "{t}");
}

#[test]
fn check_and_run_warn_of_bodies_placed_with_their_surfaces_crossing() {
    let dir = std::env::temp_dir().join(format!("palpa-cli-crossing-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let organ = |name: &str, z: f64| {
        format!(
            "[[body]]\nname = \"{name}\"\nmesh = {{ ellipsoid = {{ radii = [0.04, 0.03, 0.015], subdivisions = 2 }} }}\nposition = [0.0, 0.0, {z:?}]\n"
        )
    };
    let crossing = dir.join("crossing.toml");
    std::fs::write(
        &crossing,
        format!(
            "{}{}{}",
            organ("lower", 0.0155),
            organ("upper", 0.04),
            organ("aside", 0.0).replace("[0.0, 0.0, 0.0]", "[0.2, 0.0, 0.0155]")
        ),
    )
    .unwrap();
    let path = crossing.to_str().unwrap();
    let out = palpa(&["check", path]);
    let t = text(&out);
    assert!(out.status.success(), "{t}");
    assert!(
        t.contains("warning: bodies `lower` and `upper` start with their surfaces crossing"),
        "{t}"
    );
    assert!(!t.contains("`aside`"), "{t}");
    let out = palpa(&["run", path, "--duration", "0.01"]);
    let t = text(&out);
    assert!(
        t.contains("warning: bodies `lower` and `upper` start with their surfaces crossing"),
        "{t}"
    );
    // Apart: no warning.
    let apart = dir.join("apart.toml");
    std::fs::write(
        &apart,
        format!("{}{}", organ("lower", 0.0155), organ("upper", 0.05)),
    )
    .unwrap();
    let t = text(&palpa(&["check", apart.to_str().unwrap()]));
    assert!(!t.contains("surfaces crossing"), "{t}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn check_warns_of_a_mesh_of_separate_surfaces() {
    // Two cubes in one OBJ file are one body: every node tied to one rigid component.
    let dir = std::env::temp_dir().join(format!("palpa-cli-shells-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cube = |offset: f64, first: usize| {
        let mut t = String::new();
        for z in [0.0, 1.0] {
            for (x, y) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
                t += &format!("v {} {y} {z}\n", x + offset);
            }
        }
        for f in [
            [1, 3, 2],
            [1, 4, 3],
            [5, 6, 7],
            [5, 7, 8],
            [1, 2, 6],
            [1, 6, 5],
            [2, 3, 7],
            [2, 7, 6],
            [3, 4, 8],
            [3, 8, 7],
            [4, 1, 5],
            [4, 5, 8],
        ] {
            t += &format!("f {} {} {}\n", f[0] + first, f[1] + first, f[2] + first);
        }
        t
    };
    std::fs::write(dir.join("one.obj"), cube(0.0, 0)).unwrap();
    std::fs::write(dir.join("two.obj"), cube(0.0, 0) + &cube(3.0, 8)).unwrap();
    for (name, warned) in [("one", false), ("two", true)] {
        let scene = dir.join(format!("{name}.toml"));
        std::fs::write(
            &scene,
            format!("[[body]]\nname = \"b\"\nmesh = {{ obj = \"{name}.obj\", scale = 0.02 }}\n"),
        )
        .unwrap();
        let out = palpa(&["check", scene.to_str().unwrap()]);
        let t = text(&out);
        assert!(out.status.success(), "{t}");
        assert_eq!(
            t.contains(
                "warning: body `b`'s mesh is 2 separate surfaces (8, 8 nodes): they move as one body"
            ),
            warned,
            "{t}"
        );
        assert_eq!(t.contains("separate surfaces"), warned, "{t}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn check_warns_before_a_scene_diverges() {
    // Light nodes and stiff springs: the paper's trap. The warning comes before any run; the run
    // then really diverges and says so with a non-zero exit.
    let dir = std::env::temp_dir().join(format!("palpa-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("stiff.toml");
    std::fs::write(
        &scene,
        "[world]\ngravity = [0.0, 0.0, 0.0]\nintegrator = \"symplectic\"\n[[body]]\nname = \"stiff\"\n\
         mesh = { icosphere = { radius = 0.05, subdivisions = 4 } }\nsurface_mass = 0.05\n\
         surface_stiffness = 400.0\nangular_velocity = [0.0, 0.0, 3.0]\n",
    )
    .unwrap();
    let path = scene.to_str().unwrap();
    let out = palpa(&["check", path]);
    let t = text(&out);
    assert!(out.status.success(), "{t}");
    assert!(t.contains("UNSTABLE"), "{t}");
    assert!(
        t.contains("warning: a node") && t.contains("past the stability limit"),
        "{t}"
    );
    // A scene without obstacles runs no contact system.
    assert!(
        t.contains("systems: surface_springs, links, rigid_components\n"),
        "{t}"
    );
    // The run goes on to its end: the divergence guard catches the explicit scheme, and the run
    // says so with a warning and exit status 3 (the guard acted: the run did not follow the model).
    let out = palpa(&["run", path, "--duration", "1"]);
    assert_eq!(out.status.code(), Some(3), "{}", text(&out));
    assert!(
        text(&out).contains("1000 ticks (1 s simulated)"),
        "{}",
        text(&out)
    );
    assert!(
        text(&out).contains("divergence guard acted"),
        "{}",
        text(&out)
    );
    // Blamed on the explicit scheme, which `check` found past its limit.
    assert!(
        text(&out).contains("the symplectic integrator is unstable here"),
        "{}",
        text(&out)
    );
    assert!(
        text(&out).contains("warning: the divergence guard acted on "),
        "{}",
        text(&out)
    );
    assert!(!text(&out).contains("NaN"), "{}", text(&out));
    // The same body with the multi-rate integrator is stable.
    std::fs::write(
        &scene,
        std::fs::read_to_string(&scene)
            .unwrap()
            .replace("symplectic", "multirate"),
    )
    .unwrap();
    let out = palpa(&["check", path]);
    assert!(text(&out).contains("nodes sub-stepped"), "{}", text(&out));
    // Its worst node is past the explicit limit at dt, and said to be sub-stepped, not unstable.
    assert!(
        text(&out).contains("past the explicit limit at dt: sub-stepped (×"),
        "{}",
        text(&out)
    );
    assert!(!text(&out).contains("UNSTABLE"), "{}", text(&out));
    let out = palpa(&["run", path, "--duration", "1"]);
    assert!(out.status.success(), "{}", text(&out));
    assert!(!text(&out).contains("divergence guard"), "{}", text(&out));
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn a_bad_scene_fails_with_its_place() {
    let dir = std::env::temp_dir().join(format!("palpa-cli-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("bad.toml");
    std::fs::write(&scene, "[world]\ndt = -1.0\n").unwrap();
    let out = palpa(&["check", scene.to_str().unwrap()]);
    assert!(!out.status.success());
    let t = text(&out);
    assert!(
        t.contains("bad.toml:2:6: `dt` must be a finite number > 0, found -1"),
        "{t}"
    );
    assert!(!t.contains("panicked"), "{t}");
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn numeric_options_refuse_zero_negative_and_non_finite_values() {
    // (command, option, values refused); each refusal names the option and says what it expects.
    let positive = ["0", "-1", "NaN", "inf", "-inf", "x"];
    let non_negative = ["-1", "-0.5", "NaN", "inf", "x"];
    let counts = ["0", "-1", "1.5", "NaN", "x"];
    let cases: &[(&[&str], &str, &[&str])] = &[
        (&["serve"], "--keyframe-every", &positive),
        (&["serve"], "--max-speed", &positive),
        (&["serve"], "--display-rate", &positive),
        (&["serve"], "--stale-after-ms", &counts),
        (&["serve"], "--duration", &non_negative),
        (&["run"], "--duration", &non_negative),
        (&["run"], "--trace-every", &counts),
        (&["demo"], "--duration", &positive),
    ];
    for (command, option, values) in cases {
        for value in *values {
            let mut args: Vec<&str> = command.to_vec();
            args.extend([*option, *value]);
            let out = palpa(&args);
            let t = text(&out);
            assert_eq!(out.status.code(), Some(2), "{args:?}: {t}");
            assert!(
                t.contains(&format!("invalid value '{value}' for '{option}"))
                    && t.contains("must be a "),
                "{args:?}: {t}"
            );
        }
    }
    for (option, value) in [
        ("--duration", "0"),
        ("--duration", "-2"),
        ("--duration", "NaN"),
        ("--at", "0,0,inf"),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_palpa-device"))
            .args([option, value])
            .output()
            .unwrap();
        let t = text(&out);
        assert_eq!(out.status.code(), Some(2), "{option} {value}: {t}");
        assert!(t.contains(&format!("invalid value '{value}'")), "{t}");
    }
    for (args, option) in [
        (&["serve", "--live", "abc:def"][..], "--live"),
        (&["serve", "--live", "70000"], "--live"),
        (&["demo", "--live", "host.invalid"], "--live"),
    ] {
        let out = palpa(args);
        let t = text(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {t}");
        assert!(t.contains(&format!("for '{option}")), "{t}");
        assert!(t.contains("expected [HOST:]PORT"), "{t}");
    }
    // A timings file that cannot be created is refused before the daemon runs (not after the
    // session, when the histograms are written).
    for command in ["serve", "demo"] {
        let out = palpa(&[command, "--timings", "/nonexistent-palpa-dir/t.csv"]);
        let t = text(&out);
        assert_eq!(out.status.code(), Some(1), "{command}: {t}");
        assert!(
            t.contains("cannot create the timings file /nonexistent-palpa-dir/t.csv"),
            "{command}: {t}"
        );
    }
    // palpa-replay's playback speed (it said `Error: --speed must be > 0`, status 1; `-1` was
    // taken for an option).
    for value in positive {
        let out = Command::new(env!("CARGO_BIN_EXE_palpa-replay"))
            .args(["no-such.mcap", "--play", "--speed", value])
            .output()
            .unwrap();
        let t = text(&out);
        assert_eq!(out.status.code(), Some(2), "--speed {value}: {t}");
        assert!(
            t.contains(&format!("invalid value '{value}' for '--speed"))
                && t.contains("must be a "),
            "{t}"
        );
    }
    for (option, value) in [("--duration", "0"), ("--duration", "NaN"), ("--wait", "-1")] {
        let out = Command::new(env!("CARGO_BIN_EXE_palpa-zenoh"))
            .args(["--listen", "tcp/127.0.0.1:0", option, value])
            .output()
            .unwrap();
        let t = text(&out);
        assert_eq!(out.status.code(), Some(2), "{option} {value}: {t}");
        assert!(t.contains("must be a "), "{t}");
    }
    for args in [
        ["latency", "--duration", "0"],
        ["latency", "--duration", "NaN"],
        ["latency", "--pings", "0"],
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_palpa-bench"))
            .args(args)
            .output()
            .unwrap();
        let t = text(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {t}");
        assert!(t.contains("must be a "), "{t}");
    }
}

#[test]
fn the_guard_is_blamed_on_the_integrator_only_where_check_finds_it_past_its_limit() {
    // Found by a reader: every guard event was put down to the integrator's stability, also
    // where `check` finds the body stable, and `check` called a body sub-stepped as far as the
    // multi-rate integrator goes, and still past its limit there, merely sub-stepped.
    let dir = std::env::temp_dir().join(format!("palpa-cli-guard-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // A rigid component of a tonne on the default links: it sinks through its nodes, which rest
    // on the table (stable at dt; the guard finds the links stretched).
    let heavy = dir.join("heavy.toml");
    std::fs::write(
        &heavy,
        "[[body]]\nname = \"a\"\nmesh = { icosphere = { radius = 0.03, subdivisions = 1 } }\n\
         position = [0.0, 0.0, 0.05]\nrigid_mass = 1e3\n[[obstacle]]\nplane = { normal = [0.0, 0.0, 1.0] }\n",
    )
    .unwrap();
    let t = text(&palpa(&["check", heavy.to_str().unwrap()]));
    assert!(!t.contains("UNSTABLE"), "{t}");
    let out = palpa(&["run", heavy.to_str().unwrap(), "--duration", "1"]);
    let t = text(&out);
    assert_eq!(out.status.code(), Some(3), "{t}");
    assert!(
        t.contains(
            "(last cause: Stretch: a node went further than 5 body sizes from its rigid \
             component) — not the integrator's stability"
        ),
        "{t}"
    );
    // Nodes of 1e-7 kg under the default damping, falling: past the limit at 1/4096 of the step
    // too.
    let light = dir.join("light.toml");
    std::fs::write(
        &light,
        "[[body]]\nname = \"ico\"\n\
         mesh = { icosphere = { radius = 0.0005, subdivisions = 0 } }\nsurface_mass = 1e-7\n\
         rigid_mass = 1e-7\nsurface_stiffness = 0.1\nlink_stiffness = 0.1\n",
    )
    .unwrap();
    let t = text(&palpa(&["check", light.to_str().unwrap()]));
    assert!(
        t.contains("UNSTABLE: past the explicit limit at dt, and still past it sub-stepped ×4096"),
        "{t}"
    );
    assert!(t.contains("warning: a node"), "{t}");
    let out = palpa(&["run", light.to_str().unwrap(), "--duration", "0.05"]);
    let t = text(&out);
    assert_eq!(out.status.code(), Some(3), "{t}");
    assert!(
        t.contains("the multirate integrator is unstable here"),
        "{t}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_step_that_drops_a_body_further_than_its_thickness_is_warned_of() {
    // Found by a reader: at a 0.1 s step a box resting on a table never sagged, and a ball dropped
    // onto it hung in the air (every node's trajectory ended inside what it rests on, and contact
    // stopped them all where they started), with no word from `check` or `run`.
    let dir = std::env::temp_dir().join(format!("palpa-cli-coarse-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("box.toml");
    let scene_text = |dt: f64| {
        format!(
            "[world]\ndt = {dt}\n[[body]]\nname = \"lower\"\n\
             mesh = {{ box = {{ size = [0.1, 0.1, 0.04], subdivisions = 2 }} }}\n\
             position = [0.0, 0.0, 0.02]\n[[obstacle]]\nplane = {{ normal = [0.0, 0.0, 1.0] }}\n"
        )
    };
    std::fs::write(&scene, scene_text(0.1)).unwrap();
    let path = scene.to_str().unwrap();
    let t = text(&palpa(&["check", path]));
    assert!(
        t.contains(
            "warning: body `lower`: gravity alone moves it 0.0981 m in one step of 0.1 s, more \
             than a tenth of its thinnest extent (0.0400 m)"
        ),
        "{t}"
    );
    let t = text(&palpa(&["run", path, "--duration", "0.2"]));
    assert!(t.contains("warning: body `lower`: gravity alone"), "{t}");
    // At 10 ms it falls 1 mm a step: no warning.
    std::fs::write(&scene, scene_text(0.01)).unwrap();
    let t = text(&palpa(&["check", path]));
    assert!(!t.contains("gravity alone"), "{t}");
    std::fs::remove_dir_all(&dir).ok();
}
