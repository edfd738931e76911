//! Adaptive subdivision driven by contact (MODEL.md §6): precision of a coarse body refined at the
//! contact against a finely meshed one, the three spring rules compared, stability at the deepest
//! refinement with multi-rate integration, a long stroke that leaves the mesh as it found it, and
//! determinism.

mod common;

use palpa::Vec3;
use palpa::tool::{Tool, ToolInput, ToolPose, ToolShape};
use palpa::topology::refine::{MIN_ANGLE_DEG, min_angle_deg};
use palpa::world::World;

const RADIUS: f64 = 0.05;

/// A fixed ball (icosphere of the given level) whose mechanics do not depend on its mesh: surface
/// mass spread by area, the same spring constant on every edge (a triangle lattice's membrane modulus
/// does not depend on its edge length), no friction, and links of stiffness `kappa` (N/m³) and
/// damping κ/250 per unit area. A sphere probe of radius `probe_radius` driven by poses.
fn ball(level: u32, subdivision: &str, kappa: f64, probe_radius: f64) -> World {
    // A variant of nodes only (the paper's contact) says so in a comment.
    let faces = !subdivision.contains(NODES_ONLY);
    let scene = common::scene(&format!(
        r#"
        [world]
        gravity = [0.0, 0.0, 0.0]
        integrator = "multirate"
        face_contact = {faces}
        [[body]]
        name = "ball"
        mesh = {{ icosphere = {{ radius = {RADIUS}, subdivisions = {level} }} }}
        fixed = true
        surface_mass = 2.0
        surface_stiffness = 40.0
        surface_damping = 0.02
        friction = 0.0
        {subdivision}
        "#
    ));
    let mut world = World::from_scene(&scene);
    assert_eq!(world.params.face_contact, faces);
    world.bodies[0].set_links_per_area(kappa, kappa / 250.0);
    let probe = Tool::new(
        "probe",
        ToolShape::Sphere {
            radius: probe_radius,
        },
        ToolInput::Ipc,
        None,
    );
    world.add_tool(probe);
    world
}

/// Brings the probe down along −z onto the ball above (x, y), presses `depth` in over 0.5 s, holds
/// 0.5 s, and returns the mean upward feedback over the last 100 ms.
fn press_at(world: &mut World, probe_radius: f64, depth: f64, x: f64, y: f64) -> f64 {
    let top = (RADIUS * RADIUS - x * x - y * y).sqrt();
    let mut sum = 0.0;
    for k in 0..=1000 {
        let pressed = depth * (k as f64 / 500.0).min(1.0);
        world.tools[0].set_target(
            ToolPose {
                position_in_world: Vec3::new(x, y, top + probe_radius - pressed),
                ..ToolPose::default()
            },
            0.0,
        );
        world.step();
        if k > 900 {
            sum += world.tools[0].feedback.force_in_world.z;
        }
    }
    sum / 100.0
}

/// Presses at four points between the coarse nodes; returns the fine forces and, per variant, the
/// relative errors against them.
fn compare(
    kappa: f64,
    r: f64,
    depth: f64,
    variants: &[(&str, u32, &str)],
) -> (Vec<f64>, Vec<Vec<f64>>) {
    let points = [
        (0.006, 0.004),
        (0.003, 0.009),
        (-0.005, 0.007),
        (0.011, -0.002),
    ];
    let mut fine = Vec::new();
    let mut errors = vec![Vec::new(); variants.len()];
    for &(x, y) in &points {
        let reference = press_at(&mut ball(5, "", kappa, r), r, depth, x, y);
        fine.push(reference);
        for (k, (_, level, key)) in variants.iter().enumerate() {
            let force = press_at(&mut ball(*level, key, kappa, r), r, depth, x, y);
            errors[k].push((force - reference) / reference);
        }
    }
    (fine, errors)
}

/// The body line of a variant whose tools meet its nodes only (`face_contact = false`).
const NODES_ONLY: &str = "# nodes only";

const RULES: [(&str, u32, &str); 6] = [
    ("coarse 162, nodes only", 2, NODES_ONLY),
    ("coarse 162, faces", 2, ""),
    (
        "coarse 162 + angle",
        2,
        "subdivision = { rule = \"angle\", max_depth = 6, min_edge = 0.0015, coarsen_after = 5.0 }",
    ),
    (
        "coarse 162 + constant_kl",
        2,
        "subdivision = { rule = \"constant_kl\", max_depth = 6, min_edge = 0.0015, coarsen_after = 5.0 }",
    ),
    (
        "coarse 162 + area",
        2,
        "subdivision = { rule = \"area\", max_depth = 6, min_edge = 0.0015, coarsen_after = 5.0 }",
    ),
    ("uniform 2 562", 4, ""),
];

fn report(title: &str, fine: &[f64], errors: &[Vec<f64>]) {
    eprintln!("{title}: fine (10 242 nodes) {:.5?} N", fine);
    for ((name, _, _), e) in RULES.iter().zip(errors) {
        let shown: Vec<String> = e.iter().map(|x| format!("{:+.1} %", 100.0 * x)).collect();
        eprintln!("  {name:<28} {}", shown.join("  "));
    }
}

#[test]
fn a_coarse_body_refined_at_the_contact_matches_a_fine_one_within_10_percent() {
    // A 5 mm probe pressed 4 mm, between the nodes of the coarse ball (edges ≈ 13 mm).
    let (fine, errors) = compare(5e4, 0.005, 0.004, &RULES);
    report("kappa 5e4 N/m³, 5 mm probe, 4 mm press", &fine, &errors);
    let spread = fine.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
        / fine.iter().cloned().fold(f64::INFINITY, f64::min)
        - 1.0;
    assert!(
        spread < 0.03,
        "the fine reference does not depend on where it is pressed: {spread}"
    );
    // With nodes only, and no subdivision, the probe slips between the coarse nodes. The faces
    // keep the 5 mm probe out (it fits between the corners of the coarse triangles, whose circles
    // are about 8 mm), as stiff as the coarse mesh is: far stiffer than the fine body. (While the
    // faces met only tools finer than half of a triangle's circle, the probe slipped through here
    // too: −100 %.)
    assert!(errors[0].iter().all(|e| *e < -0.95), "{:?}", errors[0]);
    assert!(errors[1].iter().all(|e| *e > 0.5), "{:?}", errors[1]);
    // The area rule is within 10 % at every point; the paper's rules are far stiffer.
    assert!(errors[4].iter().all(|e| e.abs() < 0.10), "{:?}", errors[4]);
    let mean_abs = |e: &[f64]| e.iter().map(|x| x.abs()).sum::<f64>() / e.len() as f64;
    assert!(mean_abs(&errors[2]) > 5.0 * mean_abs(&errors[4]));
    assert!(mean_abs(&errors[3]) > 5.0 * mean_abs(&errors[4]));
}

#[test]
fn a_stiffer_foundation_and_a_finer_probe_are_harder() {
    // The same comparison where the deflection is more local: the area rule is still far better than
    // the paper's, and about as good as a uniform 2 562-node mesh, but not within 10 % everywhere
    // (figures in the README).
    let (fine, errors) = compare(1.5e5, 0.004, 0.003, &RULES);
    report("kappa 1.5e5 N/m³, 4 mm probe, 3 mm press", &fine, &errors);
    let mean_abs = |e: &[f64]| e.iter().map(|x| x.abs()).sum::<f64>() / e.len() as f64;
    assert!(errors[0].iter().all(|e| *e < -0.95));
    // The 4 mm probe is fine enough for the faces of the coarse ball: they keep it out, but a
    // pressed triangle carries its three corners' whole links (each a coarse node's share of the
    // foundation), so the response is several times the fine ball's (+484 to +662 % measured).
    assert!(errors[1].iter().all(|e| *e > 1.0), "{:?}", errors[1]);
    assert!(mean_abs(&errors[4]) < 0.25, "{:?}", errors[4]);
    assert!(mean_abs(&errors[2]) > 3.0 * mean_abs(&errors[4]));
}

/// Checks the body's mesh is a closed, consistently oriented manifold with one spring per edge, and
/// returns the smallest rest angle of its triangles (degrees).
fn check_manifold(world: &World) -> f64 {
    let body = &world.bodies[0];
    let s = &body.surface;
    let mut directed: Vec<(u32, u32)> = s
        .triangles
        .iter()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .collect();
    directed.sort_unstable();
    let before = directed.len();
    directed.dedup();
    assert_eq!(directed.len(), before, "a directed edge appears twice");
    for &(a, b) in &directed {
        assert!(
            directed.binary_search(&(b, a)).is_ok(),
            "edge {a}-{b} has one triangle"
        );
    }
    assert_eq!(body.edges.len() * 2, directed.len(), "one spring per edge");
    for t in &s.triangles {
        assert!(t.iter().all(|&v| (v as usize) < s.mass.len()));
    }
    s.triangles
        .iter()
        .map(|t| min_angle_deg(&t.map(|v| s.homologue_in_body[v as usize])))
        .fold(180.0, f64::min)
}

fn probe_scene(key: &str, script: &str, friction: f64) -> World {
    World::from_scene(&common::scene(&format!(
        r#"
        [world]
        gravity = [0.0, 0.0, -9.81]
        integrator = "multirate"
        [[body]]
        name = "organ"
        mesh = {{ icosphere = {{ radius = {RADIUS}, subdivisions = 2 }} }}
        fixed = true
        surface_mass = 0.3
        surface_stiffness = 40.0
        surface_damping = 0.02
        link_stiffness = 30.0
        link_damping = 0.08
        friction = {friction}
        {key}
        [[tool]]
        name = "probe"
        shape = {{ sphere = {{ radius = 0.004 }} }}
        input = "script"
        script = [{script}]
        "#
    )))
}

#[test]
fn a_30_s_stroke_leaves_the_mesh_as_it_found_it() {
    // Down onto the top, then back and forth across it for 30 s (±2.5 cm at 1 cm/s, pressed 3 mm),
    // then up and away.
    let z = RADIUS + 0.004 - 0.003;
    let mut script = vec![
        "{ t = 0.0, position = [0.0, 0.0, 0.07] }".to_string(),
        format!("{{ t = 1.0, position = [0.0, 0.0, {z}] }}"),
    ];
    let mut t = 1.0;
    for k in 0..6 {
        let x: f64 = if k % 2 == 0 { 0.025 } else { -0.025 };
        t += if k == 0 { 2.5 } else { 5.0 };
        let y = 0.004 * (k as f64 - 2.5);
        script.push(format!(
            "{{ t = {t}, position = [{x}, {y}, {}] }}",
            z - 0.0003 * (x / 0.025).abs()
        ));
    }
    t += 0.5;
    script.push(format!("{{ t = {t}, position = [-0.025, 0.0, 0.08] }}"));
    let key = "subdivision = { max_depth = 4, min_edge = 0.002, coarsen_after = 0.5 }";
    let mut world = probe_scene(key, &script.join(", "), 0.3);
    let initial_nodes = world.bodies[0].node_count();
    let initial_mass = world.bodies[0].surface_mass();
    let original_min_angle = check_manifold(&world);
    let mut max_nodes = initial_nodes;
    let mut min_angle = original_min_angle;
    let mut worst_mass = 0.0f64;
    let ticks = ((t + 1.5) / world.params.dt) as u64;
    for tick in 0..ticks {
        world.step();
        let body = &world.bodies[0];
        max_nodes = max_nodes.max(body.node_count());
        worst_mass = worst_mass.max(((body.surface_mass() - initial_mass) / initial_mass).abs());
        assert!(body.surface.mass.iter().all(|&m| m > 0.0));
        if tick % 50 == 0 {
            min_angle = min_angle.min(check_manifold(&world));
        }
        assert_eq!(world.guards[0].events, 0, "guard acted at tick {tick}");
    }
    let r = world.refinements[0].as_ref().unwrap();
    let final_nodes = world.bodies[0].node_count();
    eprintln!(
        "30 s stroke: {initial_nodes} → at most {max_nodes} → {final_nodes} nodes; {:?}; smallest \
         angle {min_angle:.2}° (original mesh {original_min_angle:.2}°, floor {MIN_ANGLE_DEG}°); mass \
         drift {worst_mass:.1e}",
        r.counters
    );
    assert!(
        r.counters.face_splits + r.counters.edge_splits >= 20,
        "the stroke refines"
    );
    assert!(max_nodes > initial_nodes + 10);
    assert!((final_nodes as f64 - initial_nodes as f64).abs() <= 0.05 * initial_nodes as f64);
    assert_eq!(
        final_nodes, initial_nodes,
        "every refinement undone after lift-off"
    );
    assert!(min_angle >= original_min_angle.min(MIN_ANGLE_DEG) - 1e-9);
    assert!(worst_mass < 1e-12);
}

#[test]
fn lifting_off_restores_the_original_mesh_bit_for_bit() {
    let script = "{ t = 0.0, position = [0.006, 0.004, 0.06] }, { t = 1.0, position = [0.006, 0.004, 0.0505] }, \
                  { t = 1.5, position = [0.006, 0.004, 0.0505] }, { t = 2.0, position = [0.006, 0.004, 0.07] }";
    let key = "subdivision = { coarsen_after = 0.3 }";
    let mut world = probe_scene(key, script, 0.3);
    let body = &world.bodies[0];
    let (masses, triangles, links) = (
        body.surface.mass.clone(),
        body.surface.triangles.clone(),
        body.surface.link_stiffness.clone(),
    );
    let edges = (
        body.edges.a.clone(),
        body.edges.stiffness.clone(),
        body.edges.rest_length.clone(),
    );
    let mut grown = 0;
    for _ in 0..3000 {
        world.step();
        grown = grown.max(world.bodies[0].node_count());
    }
    let body = &world.bodies[0];
    assert!(grown > masses.len(), "the press refined the mesh");
    assert_eq!(body.surface.mass, masses);
    assert_eq!(body.surface.triangles, triangles);
    assert_eq!(body.surface.link_stiffness, links);
    assert_eq!(
        (
            body.edges.a.clone(),
            body.edges.stiffness.clone(),
            body.edges.rest_length.clone()
        ),
        edges
    );
}

#[test]
fn refined_to_the_maximum_depth_multirate_stays_stable_at_1_ms() {
    // A probe pressing 4 mm and circling over the top for 4 s: refinement goes to the depth limit and
    // the light new nodes are sub-stepped. Stable means: nothing diverges or trips the guard while
    // it circles, and once the probe has left, the refined body (still refined) comes back to rest
    // on its links.
    let mut script = vec!["{ t = 0.0, position = [0.004, 0.003, 0.06] }".to_string()];
    for k in 0..=40 {
        let angle = k as f64 * 0.6;
        let (x, y) = (0.004 * angle.cos(), 0.004 * angle.sin());
        script.push(format!(
            "{{ t = {}, position = [{x}, {y}, 0.05] }}",
            1.0 + 0.1 * k as f64
        ));
    }
    script.push("{ t = 5.5, position = [0.004, 0.0, 0.07] }".to_string());
    let key =
        "subdivision = { max_depth = 3, min_edge = 0.0005, tolerance = 2e-5, coarsen_after = 2.0 }";
    let mut world = probe_scene(key, &script.join(", "), 0.3);
    let mut deepest = 0;
    let mut max_speed: f64 = 0.0;
    let mut max_substeps = 1;
    let mut max_force: f64 = 0.0;
    for _ in 0..6800 {
        world.step();
        let body = &world.bodies[0];
        let r = world.refinements[0].as_ref().unwrap();
        for i in 0..body.node_count() {
            deepest = deepest.max(r.depth_of(i));
            max_speed = max_speed.max(body.surface.velocity_in_world[i].norm());
        }
        max_substeps = max_substeps.max(world.substeps_of(0).0);
        max_force = max_force.max(world.tools[0].feedback.force_in_world.norm());
        assert!(body.is_finite());
    }
    let body = &world.bodies[0];
    let s = &body.surface;
    let away_of = |nodes: std::ops::Range<usize>| {
        nodes
            .map(|i| (s.position_in_world[i] - s.homologue_in_world[i]).norm())
            .fold(0.0, f64::max)
    };
    let (away, away_refined) = (away_of(0..162), away_of(162..body.node_count()));
    let kinetic = body.kinetic_energy();
    let refined_nodes = body.node_count();
    let r = world.refinements[0].as_ref().unwrap();
    eprintln!(
        "circling press: depth reached {deepest} (max 3), {:?}, up to {max_substeps} substeps, fastest \
         node {max_speed:.3} m/s, largest feedback {max_force:.3} N, guard events {}; 1.3 s after \
         lift-off: {refined_nodes} nodes, kinetic energy {kinetic:.2e} J, farthest original node {:.3} mm \
         from its homologue, farthest inserted node {:.3} mm",
        r.counters,
        world.guards[0].events,
        away * 1e3,
        away_refined * 1e3
    );
    assert_eq!(deepest, 3, "refinement reaches the depth limit");
    assert_eq!(world.guards[0].events, 0);
    assert!(max_substeps < 1 << palpa::dynamics::multirate::MAX_LEVEL);
    assert!(max_force < 2.0, "{max_force} N");
    assert!(refined_nodes > 162, "still refined while it settles");
    assert!(kinetic < 1e-7, "back at rest: {kinetic} J");
    // The same body never touched, after as long: its sag under gravity.
    let mut untouched = probe_scene("", "{ t = 0.0, position = [0.0, 0.0, 0.2] }", 0.3);
    for _ in 0..3000 {
        untouched.step();
    }
    let u = &untouched.bodies[0].surface;
    let sag = (0..162)
        .map(|i| (u.position_in_world[i] - u.homologue_in_world[i]).norm())
        .fold(0.0, f64::max);
    eprintln!(
        "untouched body: farthest node {:.3} mm from its homologue",
        sag * 1e3
    );
    assert!(away < sag + 2e-3, "back on its links: {away} m");
    // Inserted nodes have weak links (their share of the area) and no bending stiffness holds them:
    // a small fold may stay until they are removed.
    assert!(away_refined < 5e-3, "{away_refined} m");
    for _ in 0..1200 {
        world.step();
    }
    assert_eq!(
        world.bodies[0].node_count(),
        162,
        "all undone 2 s after the probe left"
    );
}

#[test]
fn subdivision_and_coarsening_are_deterministic() {
    let path = common::repo_root().join("scenes/probe_refine.toml");
    let scene = palpa::scene::load_scene(&path).unwrap();
    let run = || {
        let mut world = World::from_scene(&scene);
        let mut trace = Vec::new();
        let mut feedback = Vec::new();
        palpa::trace::write_trace_header(&mut trace).unwrap();
        palpa::trace::write_feedback_header(&mut feedback).unwrap();
        let mut most = 0;
        for _ in 0..8000 {
            world.step();
            palpa::trace::write_trace_rows(&mut trace, &world).unwrap();
            palpa::trace::write_feedback_rows(&mut feedback, &world).unwrap();
            most = most.max(world.bodies[0].node_count());
        }
        (trace, feedback, most, world.bodies[0].node_count())
    };
    let (a, fa, most, last) = run();
    let (b, fb, _, _) = run();
    assert!(
        most > 162 && last == 162,
        "the scene refines and coarsens: {most}, {last}"
    );
    assert!(a == b, "traces differ");
    assert!(fa == fb, "feedback traces differ");
}

#[test]
fn a_display_follows_the_refined_mesh_through_keyframes() {
    use palpa::display::{DisplayMesh, MeshSchedule};
    let path = common::repo_root().join("scenes/probe_refine.toml");
    let scene = palpa::scene::load_scene(&path).unwrap();
    let mut world = World::from_scene(&scene);
    let mut schedule = MeshSchedule::new(&world, 60.0, 2.0);
    let mut display = DisplayMesh::default();
    let mut checked_refined = 0;
    for _ in 0..8000 {
        world.step();
        let mut sent = false;
        schedule
            .produce(&world, |header, bytes| -> Result<(), ()> {
                display.apply(header, bytes).expect("every message applies");
                sent = true;
                Ok(())
            })
            .unwrap();
        if sent {
            let s = &world.bodies[0].surface;
            assert_eq!(display.triangles, s.triangles);
            assert_eq!(display.positions.len(), s.position_in_world.len());
            for (shown, exact) in display.positions.iter().zip(&s.position_in_world) {
                assert_eq!(*shown, [exact.x as f32, exact.y as f32, exact.z as f32]);
            }
            checked_refined += (s.mass.len() > 162) as u32;
        }
    }
    assert!(
        checked_refined > 20,
        "the display saw the refined mesh {checked_refined} times"
    );
}

#[test]
fn a_refining_session_records_and_replays_bit_for_bit() {
    let dir = std::env::temp_dir().join(format!("palpa_refine_record_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("refine.mcap");
    let scene = common::repo_root().join("scenes/probe_refine.toml");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args([
            "run",
            scene.to_str().unwrap(),
            "--duration",
            "8",
            "--record",
        ])
        .arg(&file)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let verify = std::process::Command::new(env!("CARGO_BIN_EXE_palpa-replay"))
        .arg(&file)
        .arg("--verify")
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&verify.stdout);
    assert!(
        verify.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&verify.stderr)
    );
    assert!(text.contains("verify: OK"), "{text}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_tool_leaving_the_tissue_from_inside_drags_nothing_out() {
    // A probe that starts inside the organ (it got there without subdivision) and is pulled out
    // through the top: the surface meets it from within, which must not insert nodes held on the
    // wrong side of the tool.
    let script =
        "{ t = 0.0, position = [0.003, 0.002, 0.0] }, { t = 1.0, position = [0.003, 0.002, 0.09] }";
    let mut world = probe_scene("subdivision = {}", script, 0.3);
    let mut most_held = 0;
    for _ in 0..1500 {
        world.step();
        most_held = most_held.max(world.tools[0].feedback.contacts);
    }
    let body = &world.bodies[0];
    let held = body
        .surface
        .tool_contact
        .iter()
        .filter(|c| c.tool != palpa::contact::tool::NO_TOOL)
        .count();
    let force = world.tools[0].feedback.force_in_world.norm();
    let highest = body
        .surface
        .position_in_world
        .iter()
        .map(|x| x.z)
        .fold(f64::NEG_INFINITY, f64::max);
    eprintln!(
        "probe pulled out from inside: at most {most_held} contacts, {held} held at the end, force {force} N, highest node z {highest:.4} m"
    );
    assert_eq!(held, 0);
    assert_eq!(force, 0.0);
    assert!(highest < RADIUS + 0.005, "no node dragged up: {highest}");
}

/// The implicit integrator refined under a probe that presses an organ onto the table: a node
/// inserted at the tool after the integration must not leave the step's second solve (the one
/// around the nodes the table stopped) working from the scratch the insertion sized afresh. Before
/// the mend (2026-12-06, a scene written from the README alone) that solve divided by the fresh
/// scratch's zero preconditioner: the state went non-finite at the insertion, and the solve's
/// warm start stayed so, the divergence guard acting at every tick from then on (481 times in
/// 1.8 s) with the organ frozen.
#[test]
fn the_implicit_integrator_refined_under_a_probe_on_a_table_stays_finite() {
    for rule in ["area", "angle"] {
        let scene = common::scene(&format!(
            r#"
            [[body]]
            name = "organ"
            mesh = {{ ellipsoid = {{ radii = [0.04, 0.03, 0.015], subdivisions = 3 }} }}
            position = [0.0, 0.0, 0.015]
            surface_mass = 0.06
            rigid_mass = 0.03
            surface_stiffness = 12.0
            link_stiffness = 50.0
            subdivision = {{ rule = "{rule}" }}
            integrator = "implicit"
            [[obstacle]]
            name = "table"
            plane = {{ normal = [0, 0, 1] }}
            [[tool]]
            name = "probe"
            shape = {{ sphere = {{ radius = 0.005 }} }}
            max_force = 1.5
            script = [
              {{ t = 0.0, position = [0.0, 0.0, 0.05] }},
              {{ t = 0.4, position = [0.0, 0.0, 0.05] }},
              {{ t = 0.7, position = [0.0, 0.0, 0.022] }},
              {{ t = 1.2, position = [0.02, 0.0, 0.022] }},
              {{ t = 1.5, position = [0.02, 0.0, 0.05] }},
            ]
            "#
        ));
        let mut world = World::from_scene(&scene);
        let (mut refinements, mut guard_events, mut contacts) = (0, 0, 0);
        for _ in 0..1800 {
            world.step();
            refinements += world.counters.refinements;
            guard_events += world.counters.guard_events;
            contacts += world.counters.obstacle_contacts;
            let body = &world.bodies[0];
            assert!(
                body.surface
                    .position_in_world
                    .iter()
                    .all(|p| p.iter().all(|x| x.is_finite()))
            );
        }
        println!(
            "rule {rule}: {refinements} insertions, {contacts} table contacts, {guard_events} guard events, \
             {} nodes at the end",
            world.bodies[0].node_count()
        );
        assert!(refinements > 0, "the probe refined nothing ({rule})");
        assert!(contacts > 0, "the table stopped nothing ({rule})");
        assert_eq!(guard_events, 0, "the divergence guard acted ({rule})");
    }
}
