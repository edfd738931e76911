//! One step of the paper's model for icosphere bodies of 642, 2 562 and 10 242 nodes resting on a
//! table (forces, integration, obstacle contact and friction, rigid component), single-threaded.
//! Target: under 100 µs per step for 10 242 nodes on one core of the CI machine.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use palpa::scene::parse_scene;
use palpa::world::World;
use std::hint::black_box;
use std::path::Path;

/// A body on a table, its surface mass growing with the node count so the explicit scheme stays
/// stable at 1 ms (the bound of `palpa check`), warmed up until it rests in contact.
fn resting_world(subdivisions: u32) -> World {
    resting_world_with(subdivisions, "multirate")
}

/// The same with a given integrator.
fn resting_world_with(subdivisions: u32, integrator: &str) -> World {
    let nodes = 10 * 4u64.pow(subdivisions) + 2;
    let surface_mass = 0.2 * nodes as f64 / 642.0;
    let text = format!(
        r#"
        [world]
        integrator = "{integrator}"
        [[body]]
        name = "organ"
        mesh = {{ icosphere = {{ radius = 0.05, subdivisions = {subdivisions} }} }}
        position = [0.0, 0.0, 0.05]
        surface_mass = {surface_mass}
        rigid_mass = 1.0
        [[obstacle]]
        name = "table"
        plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }}
        friction = 0.4
        "#
    );
    let scene = parse_scene(&text, "bench.toml", Path::new(".")).expect("bench scene");
    let mut world = World::from_scene(&scene);
    assert!(world.stability_margins()[0].margin > 0.0);
    for _ in 0..200 {
        world.step();
    }
    assert!(world.bodies[0].is_finite());
    world
}

fn bench_step(c: &mut Criterion) {
    let mut group = c.benchmark_group("step");
    for subdivisions in [3, 4, 5] {
        let mut world = resting_world(subdivisions);
        let nodes = world.bodies[0].node_count();
        group.throughput(Throughput::Elements(nodes as u64));
        group.bench_function(BenchmarkId::new("icosphere_on_table", nodes), |b| {
            b.iter(|| {
                world.step();
                black_box(&world.bodies[0].surface.position_in_world[0]);
            })
        });
    }
    group.finish();
}

/// The stages of one step, separately, on the 10 242-node body: where the time goes.
fn bench_stages(c: &mut Criterion) {
    use palpa::contact::obstacle::resolve_nodes_against_obstacles;
    use palpa::dynamics::forces::accumulate_body_forces;
    use palpa::dynamics::integrate::integrate_nodes_symplectic;
    let mut group = c.benchmark_group("stage_10242");
    let mut world = resting_world(5);
    let gravity = world.params.gravity;
    let dt = world.params.dt;
    group.bench_function("forces", |b| {
        b.iter(|| accumulate_body_forces(&mut world.bodies[0], &gravity))
    });
    group.bench_function("integrate", |b| {
        b.iter(|| integrate_nodes_symplectic(&mut world.bodies[0].surface, dt))
    });
    let obstacles = world.obstacles.clone();
    let mut reactions = vec![palpa::Vec3::zeros(); obstacles.len()];
    group.bench_function("obstacle_contact", |b| {
        b.iter(|| {
            resolve_nodes_against_obstacles(
                &mut world.bodies[0].surface,
                &obstacles,
                &mut reactions,
                dt,
                None,
            )
        })
    });
    group.finish();
}

/// Continuous detection with a probe pressed into the 10 242-node body on the table: the stages that
/// find contacts on trajectories (node–probe CCD with its swept-box broad phase, triangle–probe
/// detection between nodes, node–table contact) and a whole step. Target: under 200 µs for the
/// detection stages.
fn bench_contact(c: &mut Criterion) {
    use palpa::Vec3;
    use palpa::contact::obstacle::resolve_nodes_against_obstacles;
    use palpa::contact::tool::{capture_new_contacts, detect_face_contacts};
    use palpa::tool::{Tool, ToolInput, ToolPose, ToolShape};
    let mut world = resting_world(5);
    let top = world.bodies[0]
        .surface
        .position_in_world
        .iter()
        .map(|p| p.z)
        .fold(f64::MIN, f64::max);
    let mut probe = Tool::new(
        "probe",
        ToolShape::Sphere { radius: 0.005 },
        ToolInput::Ipc,
        None,
    );
    let at = |z: f64| ToolPose {
        position_in_world: Vec3::new(0.0, 0.0, z),
        ..ToolPose::default()
    };
    probe.set_target(at(top + 0.01), 0.0);
    world.add_tool(probe);
    for k in 0..400 {
        let z = top + 0.005 - 0.004 * (k as f64 / 400.0);
        world.tools[0].set_target(at(z), 0.0);
        world.step();
    }
    assert!(
        world.tools[0].feedback.contacts > 0,
        "the probe is pressing"
    );
    let dt = world.params.dt;
    let mut group = c.benchmark_group("contact_10242");
    group.bench_function("step_with_probe", |b| b.iter(|| world.step()));
    let obstacles = world.obstacles.clone();
    let mut reactions = vec![Vec3::zeros(); obstacles.len()];
    let World { bodies, tools, .. } = &mut world;
    let mut outcodes = Vec::with_capacity(bodies[0].node_count());
    group.bench_function("detection_stages", |b| {
        b.iter(|| {
            let surface = &mut bodies[0].surface;
            let captured = capture_new_contacts(surface, tools, dt);
            let faces = detect_face_contacts(surface, tools, &mut outcodes);
            let table =
                resolve_nodes_against_obstacles(surface, &obstacles, &mut reactions, dt, None);
            black_box((captured, faces, table))
        })
    });
    group.finish();
}

/// One step per integrator for 2 562 and 10 242 nodes (the explicit schemes take the same path here:
/// every node is stable at 1 ms, so multirate sub-steps none), plus multirate on the stiff stress
/// body, where it sub-steps every node.
fn bench_integrators(c: &mut Criterion) {
    let mut group = c.benchmark_group("integrator");
    for subdivisions in [4, 5] {
        for integrator in ["symplectic", "multirate", "implicit"] {
            let mut world = resting_world_with(subdivisions, integrator);
            let nodes = world.bodies[0].node_count();
            group.bench_function(BenchmarkId::new(integrator, nodes), |b| {
                b.iter(|| world.step())
            });
        }
    }
    group.finish();
}

/// A fixed ball (icosphere level `subdivisions`) with mesh-independent mechanics (links per unit
/// area), a 5 mm probe pressed 4 mm into it between the coarse nodes and held there: the set-up of
/// the precision test in `tests/refinement.rs`.
fn pressed_ball(subdivisions: u32, subdivision: &str) -> World {
    use palpa::Vec3;
    use palpa::tool::{Tool, ToolInput, ToolPose, ToolShape};
    let text = format!(
        r#"
        [world]
        gravity = [0.0, 0.0, 0.0]
        integrator = "multirate"
        [[body]]
        name = "ball"
        mesh = {{ icosphere = {{ radius = 0.05, subdivisions = {subdivisions} }} }}
        fixed = true
        surface_mass = 2.0
        surface_stiffness = 40.0
        surface_damping = 0.02
        friction = 0.0
        {subdivision}
        "#
    );
    let scene = parse_scene(&text, "bench.toml", Path::new(".")).expect("bench scene");
    let mut world = World::from_scene(&scene);
    world.bodies[0].set_links_per_area(5e4, 200.0);
    world.add_tool(Tool::new(
        "probe",
        ToolShape::Sphere { radius: 0.005 },
        ToolInput::Ipc,
        None,
    ));
    let (x, y) = (0.006, 0.004);
    let top = (0.05f64 * 0.05 - x * x - y * y).sqrt();
    for k in 0..=1000 {
        let pressed = 0.004 * (k as f64 / 500.0).min(1.0);
        let pose = ToolPose {
            position_in_world: Vec3::new(x, y, top + 0.005 - pressed),
            ..ToolPose::default()
        };
        world.tools[0].set_target(pose, 0.0);
        world.step();
    }
    world
}

/// Adaptive subdivision: the cost of one insertion and of one coarsening on the 162-node body, and
/// the step of the coarse body refined at a contact against the fine body without refinement.
fn bench_subdivision(c: &mut Criterion) {
    use palpa::topology::{
        InsertionLog, SpringRule, coarsen_last, reserve_for_subdivision, subdivide_edge,
        subdivide_face,
    };
    use std::time::{Duration, Instant};
    let mut group = c.benchmark_group("subdivision");
    let mut body = resting_world(2).bodies.remove(0);
    reserve_for_subdivision(&mut body);
    let mut log = InsertionLog::default();
    for rule in [SpringRule::Angle, SpringRule::Area] {
        group.bench_function(BenchmarkId::new("face_split_162", rule.name()), |b| {
            b.iter_custom(|iterations| {
                let mut spent = Duration::ZERO;
                for _ in 0..iterations {
                    let start = Instant::now();
                    black_box(
                        subdivide_face(&mut body, &mut log, 17, [0.3, 0.3, 0.4], rule, 0.0)
                            .unwrap(),
                    );
                    spent += start.elapsed();
                    coarsen_last(&mut body, &mut log);
                }
                spent
            })
        });
        let (a, b_node) = (body.edges.a[5], body.edges.b[5]);
        group.bench_function(BenchmarkId::new("edge_split_162", rule.name()), |b| {
            b.iter_custom(|iterations| {
                let mut spent = Duration::ZERO;
                for _ in 0..iterations {
                    let start = Instant::now();
                    black_box(
                        subdivide_edge(&mut body, &mut log, a, b_node, 0.5, rule, 0.0).unwrap(),
                    );
                    spent += start.elapsed();
                    coarsen_last(&mut body, &mut log);
                }
                spent
            })
        });
    }
    group.bench_function("coarsen_162", |b| {
        b.iter_custom(|iterations| {
            let mut spent = Duration::ZERO;
            for _ in 0..iterations {
                subdivide_face(
                    &mut body,
                    &mut log,
                    17,
                    [0.3, 0.3, 0.4],
                    SpringRule::Area,
                    0.0,
                )
                .unwrap();
                let start = Instant::now();
                black_box(coarsen_last(&mut body, &mut log));
                spent += start.elapsed();
            }
            spent
        })
    });
    let mut refined = pressed_ball(
        2,
        "subdivision = { max_depth = 6, min_edge = 0.0015, coarsen_after = 1000.0 }",
    );
    let nodes = refined.bodies[0].node_count();
    group.bench_function(
        BenchmarkId::new("pressed_step_refined_coarse", nodes),
        |b| b.iter(|| refined.step()),
    );
    let mut fine = pressed_ball(5, "");
    let nodes = fine.bodies[0].node_count();
    group.bench_function(BenchmarkId::new("pressed_step_fine", nodes), |b| {
        b.iter(|| fine.step())
    });
    group.finish();
}

/// A fixed icosphere (radius 5 cm, no gravity) with a probe of `radius` pressed `press` m into the
/// middle of its topmost triangle (its lowest point that far below where the middle was), between
/// the nodes, and held there (800 steps).
fn probe_between_nodes(subdivisions: u32, radius: f64, press: f64, face_contact: bool) -> World {
    use palpa::Vec3;
    use palpa::tool::{Tool, ToolInput, ToolPose, ToolShape};
    let nodes = 10 * 4u64.pow(subdivisions) + 2;
    let text = format!(
        r#"
        [world]
        gravity = [0.0, 0.0, 0.0]
        integrator = "multirate"
        face_contact = {face_contact}
        [[body]]
        name = "ball"
        mesh = {{ icosphere = {{ radius = 0.05, subdivisions = {subdivisions} }} }}
        fixed = true
        surface_mass = {}
        rigid_mass = 1.0
        friction = 0.3
        "#,
        0.2 * nodes as f64 / 642.0
    );
    let scene = parse_scene(&text, "bench.toml", Path::new(".")).expect("bench scene");
    let mut world = World::from_scene(&scene);
    let s = &world.bodies[0].surface;
    let top = s
        .triangles
        .iter()
        .map(|t| {
            t.iter()
                .map(|&v| s.position_in_world[v as usize])
                .sum::<Vec3>()
                / 3.0
        })
        .max_by(|a, b| a.z.total_cmp(&b.z))
        .expect("triangles");
    world.add_tool(Tool::new(
        "probe",
        ToolShape::Sphere { radius },
        ToolInput::Ipc,
        None,
    ));
    for k in 0..=800 {
        // From 1 mm over the triangle's middle to `press` into it, in 0.4 s.
        let pressed = (0.001 + press) * (k as f64 / 400.0).min(1.0);
        let pose = ToolPose {
            position_in_world: top + Vec3::new(0.0, 0.0, radius + 0.001 - pressed),
            ..ToolPose::default()
        };
        world.tools[0].set_target(pose, 0.0);
        world.step();
    }
    world
}

/// Tool–face contact (`face_contact`): the step with a probe finer than the mesh pressed between
/// the nodes, with the faces answering it and without them (the probe then sits inside the body,
/// touching nothing): what the stage costs in contact, on 642 and 40 962 nodes.
fn bench_faces(c: &mut Criterion) {
    let mut group = c.benchmark_group("faces");
    group.sample_size(30);
    // The topmost triangle's circle: 4.2 mm (642 nodes) and 0.53 mm (40 962 nodes): probes under
    // half of it.
    for (subdivisions, radius, press) in [(3, 0.0015, 0.002), (6, 0.00012, 0.0002)] {
        for face_contact in [true, false] {
            let mut world = probe_between_nodes(subdivisions, radius, press, face_contact);
            let nodes = world.bodies[0].node_count();
            if face_contact {
                assert!(
                    world.tools[0].feedback.faces > 0,
                    "the faces hold the probe ({nodes} nodes)"
                );
            }
            let name = if face_contact {
                "pressed_step"
            } else {
                "pressed_step_no_faces"
            };
            group.bench_function(BenchmarkId::new(name, nodes), |b| b.iter(|| world.step()));
        }
    }
    group.finish();
}

criterion_group!(
    benches,
    bench_step,
    bench_stages,
    bench_contact,
    bench_integrators,
    bench_subdivision,
    bench_faces
);
criterion_main!(benches);
