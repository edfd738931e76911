//! Tools against tissue: no tunnelling at surgical speeds, the feedback of a press matches the static
//! balance of the held nodes and of the whole body, Coulomb friction bounds the stroke, lifting off
//! returns the force to exactly zero, and all of it is deterministic.

mod common;

use palpa::Vec3;
use palpa::contact::tool::SURFACE_ROUNDING;
use palpa::tool::{Tool, ToolInput, ToolPose, ToolShape};
use palpa::world::World;

const ORGAN_ON_TABLE: &str = r#"
    [world]
    gravity = [0.0, 0.0, -9.81]
    air_viscosity = 2.0
    [[body]]
    name = "organ"
    mesh = { ellipsoid = { radii = [0.06, 0.05, 0.04], subdivisions = 3 } }
    position = [0.0, 0.0, 0.04]
    surface_mass = 0.3
    rigid_mass = 1.0
    surface_stiffness = 40.0
    surface_damping = 0.02
    link_stiffness = 30.0
    link_damping = 0.1
    friction = 0.3
    [[obstacle]]
    name = "table"
    plane = { point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }
    friction = 0.6
    static_friction = 0.8
"#;

/// The organ settled on the table (2 s), with a probe of `radius` driven from outside, parked above.
fn settled_organ_with_probe(radius: f64) -> World {
    let scene = common::scene(ORGAN_ON_TABLE);
    let mut world = World::from_scene(&scene);
    assert!(world.stability_margins()[0].margin > 0.0);
    for _ in 0..2000 {
        world.step();
    }
    let mut probe = Tool::new("probe", ToolShape::Sphere { radius }, ToolInput::Ipc, None);
    let parked = ToolPose {
        position_in_world: Vec3::new(0.0, 0.0, 0.3),
        ..ToolPose::default()
    };
    probe.set_target(parked, 0.0);
    world.add_tool(probe);
    world.step();
    world
}

/// Height of the top of the organ on its vertical axis (m).
fn top_of(world: &World) -> f64 {
    world.bodies[0]
        .surface
        .position_in_world
        .iter()
        .filter(|p| p.x.abs() < 0.01 && p.y.abs() < 0.01)
        .map(|p| p.z)
        .fold(f64::MIN, f64::max)
}

fn move_probe(world: &mut World, position: Vec3) {
    let pose = ToolPose {
        position_in_world: position,
        ..ToolPose::default()
    };
    world.tools[0].set_target(pose, 0.0);
    world.step();
}

/// Deepest node inside any tool after the last tick (m; ≤ 0 means none inside).
fn deepest_node_in_tools(world: &World) -> f64 {
    let mut deepest = f64::NEG_INFINITY;
    for body in &world.bodies {
        for x in &body.surface.position_in_world {
            for tool in &world.tools {
                deepest = deepest.max(-tool.signed_distance(x).0);
            }
        }
    }
    deepest
}

#[test]
fn a_probe_striking_at_2_m_per_s_never_leaves_a_node_inside() {
    for direction in [Vec3::new(0.0, 0.0, -1.0), Vec3::new(-1.0, 0.0, 0.0)] {
        let mut world = settled_organ_with_probe(0.008);
        let top = top_of(&world);
        // From 5 cm outside the body, through its surface, 2 cm deep, at 2 mm per tick.
        let target = if direction.z < 0.0 {
            Vec3::new(0.0, 0.0, top - 0.015)
        } else {
            Vec3::new(0.045, 0.0, 0.03)
        };
        let start = target - direction * 0.07;
        move_probe(&mut world, start);
        let mut deepest: f64 = f64::NEG_INFINITY;
        let mut most_contacts = 0;
        for k in 1..=35 {
            move_probe(&mut world, start + direction * (0.002 * k as f64));
            deepest = deepest.max(deepest_node_in_tools(&world));
            most_contacts = most_contacts.max(world.tools[0].feedback.contacts);
        }
        for _ in 0..200 {
            move_probe(&mut world, target);
            deepest = deepest.max(deepest_node_in_tools(&world));
        }
        eprintln!(
            "strike along {:?}: deepest node {deepest:e} m, {most_contacts} contacts",
            direction.as_slice()
        );
        assert!(most_contacts >= 3, "the probe really hit the body");
        assert!(
            deepest <= SURFACE_ROUNDING,
            "a node ended a tick {deepest} m inside the probe"
        );
        assert!(world.bodies[0].is_finite());
    }
}

#[test]
fn a_thin_plate_hit_edge_on_at_2_m_per_s_is_pushed_not_pierced() {
    // A 3 mm plate held in place, 1 cm mesh; a 6 mm probe strikes its rim along +x.
    let scene = common::scene(
        r#"
        [world]
        gravity = [0.0, 0.0, 0.0]
        [[body]]
        name = "plate"
        mesh = { box = { size = [0.1, 0.1, 0.003], subdivisions = [9, 9, 0] } }
        fixed = true
        surface_mass = 0.3
        surface_stiffness = 10.0
        surface_damping = 0.005
        link_stiffness = 20.0
        link_damping = 0.02
        "#,
    );
    let mut world = World::from_scene(&scene);
    assert!(world.stability_margins()[0].margin > 0.0);
    let mut probe = Tool::new(
        "probe",
        ToolShape::Sphere { radius: 0.006 },
        ToolInput::Ipc,
        None,
    );
    probe.set_target(
        ToolPose {
            position_in_world: Vec3::new(-0.09, 0.003, 0.0),
            ..ToolPose::default()
        },
        0.0,
    );
    world.add_tool(probe);
    world.step();
    let mut deepest: f64 = f64::NEG_INFINITY;
    let mut most_contacts = 0;
    // 2 mm per tick for 25 ticks: the probe's front goes 4.4 cm past the rim.
    for k in 1..=25 {
        move_probe(&mut world, Vec3::new(-0.09 + 0.002 * k as f64, 0.003, 0.0));
        deepest = deepest.max(deepest_node_in_tools(&world));
        most_contacts = most_contacts.max(world.tools[0].feedback.contacts);
    }
    eprintln!("edge-on: deepest node {deepest:e} m, {most_contacts} contacts");
    assert!(most_contacts >= 2, "the probe hit the rim");
    assert!(
        deepest <= SURFACE_ROUNDING,
        "a node ended a tick {deepest} m inside the probe"
    );
    // The rim nodes the probe met went ahead of it: none is left behind the probe's centre.
    let probe_x = world.tools[0].pose.position_in_world.x;
    let dented = world.bodies[0]
        .surface
        .position_in_world
        .iter()
        .filter(|p| (p.y - 0.003).abs() < 0.004 && p.z.abs() < 0.002)
        .map(|p| p.x)
        .fold(f64::MAX, f64::min);
    assert!(
        dented > probe_x,
        "rim pierced: a node at x = {dented} behind the probe at {probe_x}"
    );
}

/// Force of the springs, links and gravity on node `i` at rest (recomputed here from positions).
fn static_force_on(world: &World, i: usize) -> Vec3 {
    let body = &world.bodies[0];
    let s = &body.surface;
    let r = &body.rigid;
    let homologue = r.position_in_world + r.world_from_body * s.homologue_in_body[i];
    let mut f = (homologue - s.position_in_world[i]) * s.link_stiffness[i]
        + world.params.gravity * s.mass[i];
    for e in 0..body.edges.len() {
        let (a, b) = (body.edges.a[e] as usize, body.edges.b[e] as usize);
        if a != i && b != i {
            continue;
        }
        let other = if a == i { b } else { a };
        let d = s.position_in_world[other] - s.position_in_world[i];
        let length = d.norm();
        f += d / length * (body.edges.stiffness[e] * (length - body.edges.rest_length[e]));
    }
    f
}

#[test]
fn pressing_5_mm_gives_an_outward_growing_force_in_static_balance() {
    let mut world = settled_organ_with_probe(0.01);
    let top = top_of(&world);
    let above = top + 0.01 + 0.002;
    move_probe(&mut world, Vec3::new(0.0, 0.0, above));
    // Down to contact and then 1 mm at a time, each step held 0.6 s to settle (a quasi-static press).
    let mut forces = Vec::new();
    for depth_mm in 0..=5 {
        let target = top + 0.01 - depth_mm as f64 * 0.001;
        let from = world.tools[0].pose.position_in_world.z;
        for k in 1..=200 {
            move_probe(
                &mut world,
                Vec3::new(0.0, 0.0, from + (target - from) * k as f64 / 200.0),
            );
        }
        for _ in 0..600 {
            move_probe(&mut world, Vec3::new(0.0, 0.0, target));
        }
        forces.push(world.tools[0].feedback.force_in_world);
    }
    // Hold at 5 mm until the body is at rest.
    let hold = Vec3::new(0.0, 0.0, top + 0.01 - 0.005);
    let mut reaction = Vec3::zeros();
    for k in 0..3000 {
        move_probe(&mut world, hold);
        if k >= 2900 {
            reaction += world.obstacle_reactions[0] / 100.0;
        }
    }
    let feedback = world.tools[0].feedback;
    eprintln!(
        "forces at 0..5 mm: {:?}",
        forces.iter().map(|f| f.z).collect::<Vec<_>>()
    );
    for w in forces.windows(2).skip(1) {
        assert!(
            w[1].z > w[0].z,
            "force must grow with depth: {} then {}",
            w[0].z,
            w[1].z
        );
    }
    for f in &forces[1..] {
        // Out of the surface: up, with a negligible sideways part (the press is on the axis).
        assert!(f.z > 0.0 && f.xy().norm() < 1e-6 * f.z, "{f:?}");
    }
    // The feedback is the static balance of the held nodes' springs, links and weight.
    let s = &world.bodies[0].surface;
    let mut balance = Vec3::zeros();
    let mut held = 0;
    for i in 0..s.position_in_world.len() {
        if s.tool_contact[i].tool == 0 {
            balance += static_force_on(&world, i);
            held += 1;
        }
    }
    let mismatch = (feedback.force_in_world - balance).norm() / feedback.force_in_world.norm();
    eprintln!(
        "5 mm: feedback {:?} N from {held} nodes, static balance {:?}, mismatch {:.2e}",
        feedback.force_in_world.as_slice(),
        balance.as_slice(),
        mismatch
    );
    assert!(held >= 3 && held as u32 == feedback.contacts);
    assert!(
        mismatch < 0.01,
        "feedback and static balance differ by {mismatch}"
    );
    // The table carries the weight plus the probe's push.
    let body = &world.bodies[0];
    let weight = body.total_mass() * 9.81;
    let expected = weight + feedback.force_in_world.z;
    let table_error = (reaction.z - expected).abs() / expected;
    eprintln!(
        "table normal force {} N, weight {weight} N + push {} N: error {table_error:.2e}",
        reaction.z, feedback.force_in_world.z
    );
    assert!(
        table_error < 0.01,
        "table {} N against {expected} N",
        reaction.z
    );
}

#[test]
fn a_stroke_with_friction_stays_in_the_coulomb_cone_and_lifting_off_returns_exactly_zero() {
    let mu = 0.3;
    let mut world = settled_organ_with_probe(0.01);
    let top = top_of(&world);
    let press = top + 0.01 - 0.004;
    let from = top + 0.012;
    for k in 0..=400 {
        move_probe(
            &mut world,
            Vec3::new(0.0, 0.0, from + (press - from) * k as f64 / 400.0),
        );
    }
    for _ in 0..500 {
        move_probe(&mut world, Vec3::new(0.0, 0.0, press));
    }
    // Stroke 1.5 cm along +x at 3 cm/s.
    let mut sliding_ticks = 0;
    let mut drag = 0.0;
    for k in 1..=500 {
        move_probe(&mut world, Vec3::new(0.015 * k as f64 / 500.0, 0.0, press));
        let f = world.tools[0].feedback;
        assert!(
            f.friction_force <= mu * f.normal_force * (1.0 + 1e-12) + 1e-15,
            "outside the cone: {f:?}"
        );
        if f.contacts > 0 && f.sliding == f.contacts {
            sliding_ticks += 1;
            let relative = (f.friction_force - mu * f.normal_force).abs() / f.normal_force;
            assert!(
                relative < 1e-9,
                "sliding friction {} ≠ μ N {}",
                f.friction_force,
                mu * f.normal_force
            );
        }
        drag += f.force_in_world.x;
    }
    eprintln!(
        "sliding on {sliding_ticks} of 500 ticks, mean drag {} N",
        drag / 500.0
    );
    assert!(sliding_ticks > 50, "the probe should slide on the surface");
    assert!(
        drag < 0.0,
        "the tissue resists the stroke (feedback along −x)"
    );
    // Lift off at 1 cm/s.
    let x = 0.015;
    let mut released_at = None;
    let mut previous_contacts = world.tools[0].feedback.contacts;
    for k in 1..=2000 {
        move_probe(&mut world, Vec3::new(x, 0.0, press + 0.00001 * k as f64));
        let f = world.tools[0].feedback;
        if f.contacts == 0 {
            assert_eq!(f.force_in_world, Vec3::zeros());
            assert_eq!(f.torque_in_world, Vec3::zeros());
            if released_at.is_none() {
                assert!(previous_contacts > 0);
                released_at = Some(k);
            }
        } else {
            assert!(
                released_at.is_none(),
                "contact again after release at tick {k}"
            );
        }
        previous_contacts = f.contacts;
    }
    let released_at = released_at.expect("the probe left the surface");
    eprintln!("last node released {} ms into the lift", released_at);
}

#[test]
fn max_force_clamps_and_flags() {
    let mut world = settled_organ_with_probe(0.01);
    world.tools[0].max_force = Some(0.05);
    let top = top_of(&world);
    for k in 0..=500 {
        move_probe(
            &mut world,
            Vec3::new(0.0, 0.0, top + 0.012 - 0.008 * k as f64 / 500.0),
        );
    }
    let f = world.tools[0].feedback;
    assert!(f.clamped);
    assert!((f.force_in_world.norm() - 0.05).abs() < 1e-12);
    assert!(f.normal_force > 0.05, "the unclamped force was larger");
}

#[test]
fn scripted_probe_session_is_deterministic() {
    use palpa::scene::load_scene;
    use palpa::trace::{write_feedback_rows, write_trace_rows};
    let run = || {
        let scene = load_scene(&common::repo_root().join("scenes/probe_press.toml")).unwrap();
        let mut world = World::from_scene(&scene);
        let mut out = Vec::new();
        for _ in 0..6000 {
            world.step();
            write_trace_rows(&mut out, &world).unwrap();
            write_feedback_rows(&mut out, &world).unwrap();
        }
        let touched = out.windows(2).count();
        (out, touched)
    };
    let (a, _) = run();
    let (b, _) = run();
    let text = String::from_utf8(a.clone()).unwrap();
    assert!(
        text.lines()
            .any(|l| l.contains(",probe,") && l.split(',').nth(9).is_some_and(|c| c != "0")),
        "contact happened"
    );
    assert!(a == b, "traces with contact differ");
}

/// The tool broad phase skips the nodes of a block whose box (made by the force stage's node
/// pass, grown by the nodes the contact stage moved after it) misses the tool's sweep. Over the
/// shipped scenes (presses, lift-offs, grasps, cuts, tears, organs on a table, organs on organs),
/// each free node's trajectory lies in its block's box whenever the boxes are used, so none could
/// be skipped wrongly, and the guard's maxima taken from the blocks are those of a pass over every
/// node, bit for bit (also for the bodies the body–body stage left alone).
#[test]
fn the_node_boxes_hold_every_free_trajectory_the_broad_phase_skips_by() {
    use palpa::scene::load_scene;
    use palpa::world::NodeBoxCheck;
    let mut total = NodeBoxCheck::default();
    for name in [
        "probe_press",
        "probe_refine",
        "grasp_lift",
        "incision",
        "plastic",
        "tear",
        "transection",
        "table_rest",
        "inclined_plane",
        "liver",
        "organ",
        "two_organs",
        "laparoscopy",
    ] {
        let scene = load_scene(&common::repo_root().join(format!("scenes/{name}.toml"))).unwrap();
        let mut world = World::from_scene(&scene);
        world.node_box_check = Some(NodeBoxCheck::default());
        let mut captures = 0;
        for _ in 0..4000 {
            world.step();
            captures += world.counters.tool_captures;
        }
        let check = world.node_box_check.unwrap();
        assert_eq!(check.misses, 0, "{name}: {check:?}");
        assert_eq!(check.maxima_misses, 0, "{name}: {check:?}");
        println!("{name}: {check:?}, {captures} captures");
        total.uses += check.uses;
        total.nodes += check.nodes;
        total.misses += check.misses;
        total.maxima += check.maxima;
    }
    // Two organs thrown at each other at 4 m/s each, no gravity: the collision net stops nodes
    // the response did not reach, and the guard's maxima stay those of every node.
    let text = r#"
        [world]
        gravity = [0.0, 0.0, 0.0]
        [[body]]
        name = "left"
        mesh = { icosphere = { radius = 0.03, subdivisions = 2 } }
        position = [-0.05, 0.0, 0.0]
        velocity = [4.0, 0.0, 0.0]
        [[body]]
        name = "right"
        mesh = { ellipsoid = { radii = [0.03, 0.04, 0.02], subdivisions = 2 } }
        position = [0.05, 0.004, 0.003]
        velocity = [-4.0, 0.0, 0.0]
    "#;
    let scene = common::scene(text);
    let mut world = World::from_scene(&scene);
    world.node_box_check = Some(NodeBoxCheck::default());
    let mut collisions = 0;
    for _ in 0..400 {
        world.step();
        collisions += world.counters.bodies.collisions;
    }
    let check = world.node_box_check.unwrap();
    println!("thrown: {check:?}, {collisions} net collisions");
    assert_eq!(check.maxima_misses, 0, "thrown: {check:?}");
    assert!(
        collisions > 0 && check.maxima >= 4,
        "{collisions} {check:?}"
    );
    total.maxima += check.maxima;
    // The boxes were used, over many nodes (most scenes integrate every node in the node pass).
    assert!(total.uses > 5_000 && total.nodes > 2_000_000, "{total:?}");
    // The guard read the blocks at most of those ticks.
    assert!(total.maxima > 5_000, "{total:?}");
}

/// A probe that jumps 40 cm through an organ in one tick (an external pose accepted after the
/// speed check held it back, or a script's jump) and stays beside it, 12 cm off: the nodes it
/// swept up were carried off with it, the divergence guard restored the organ, and — the tool
/// still holding them — did so again at every tick for as long as the probe stayed (1 500 times
/// in 1.5 s, the probe feeling nothing with 8 contacts; found by an integrator's bridge,
/// 2026-12-07). The guard's restore now makes the tools let go of the nodes: one event, then the
/// organ rests and the probe, away from it, touches nothing.
#[test]
fn a_probe_jumping_through_an_organ_does_not_hold_it_restored_for_ever() {
    let scene = common::scene(
        r#"
        [[body]]
        name = "organ"
        mesh = { ellipsoid = { radii = [0.05, 0.035, 0.02], subdivisions = 3 } }
        position = [0.0, 0.0, 0.02]
        [[obstacle]]
        name = "table"
        plane = { normal = [0.0, 0.0, 1.0] }
        friction = 0.5
        [[tool]]
        name = "probe"
        shape = { sphere = { radius = 0.005 } }
        script = [
          { t = 0.0, position = [-0.2, 0.0, 0.02] },
          { t = 0.5, position = [-0.2, 0.0, 0.02] },
          { t = 0.501, position = [0.2, 0.0, 0.02] },
          { t = 2.0, position = [0.2, 0.0, 0.02] },
        ]
        "#,
    );
    let mut world = World::from_scene(&scene);
    let mut swept = 0;
    for tick in 0..2000 {
        world.step();
        if tick == 500 {
            swept = world.tools[0].feedback.contacts;
        }
        if tick > 510 {
            assert_eq!(
                world.tools[0].feedback.contacts, 0,
                "tick {tick}: the probe holds nodes"
            );
        }
    }
    assert!(swept > 0, "the jump swept up no node: the case is not made");
    let events = world.guards[0].events;
    assert!(events <= 2, "the guard acted {events} times");
    assert!(
        world.bodies[0].kinetic_energy() < 1e-6,
        "{}",
        world.bodies[0].kinetic_energy()
    );
}
