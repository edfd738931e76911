//! The laparoscopy scene (`scenes/laparoscopy.toml`, built in as `laparoscopy`): its organs settle
//! on their ligaments without entering each other, and the two tools the demo drives work in it —
//! the probe presses the uterus (through the bowel in the way), the grasper takes a Fallopian tube,
//! lifts it, puts it down and lets go.

mod common;

use palpa::Vec3;
use palpa::tool::ToolInput;
use palpa::world::World;

#[test]
fn the_built_in_scene_is_the_shipped_file() {
    let built_in = palpa::scene::built_in_scene("laparoscopy")
        .expect("a built-in laparoscopy scene")
        .unwrap();
    let file =
        std::fs::read_to_string(common::repo_root().join("scenes/laparoscopy.toml")).unwrap();
    assert_eq!(built_in.source, file);
    let names: Vec<&str> = built_in.bodies.iter().map(|b| b.name.as_str()).collect();
    for organ in [
        "uterus",
        "ovary_left",
        "ovary_right",
        "tube_left",
        "tube_right",
        "bowel_1",
    ] {
        assert!(names.contains(&organ), "{names:?}");
    }
    assert!(built_in.attachments.len() >= 8);
    let tools: Vec<(&str, bool)> = built_in
        .tools
        .iter()
        .map(|t| (t.name.as_str(), matches!(t.input, ToolInput::Ipc)))
        .collect();
    assert_eq!(tools, [("probe", true), ("grasper", true)]);
}

/// The scene as built in, its IPC tools idle (no device connected: they touch nothing): the organs
/// come to rest on their ligaments and on one another.
#[test]
fn the_laparoscopy_organs_settle_on_their_ligaments() {
    let scene = palpa::scene::built_in_scene("laparoscopy")
        .unwrap()
        .unwrap();
    let mut world = World::from_scene(&scene);
    let mut energies = Vec::new();
    for _ in 0..1000 {
        world.step();
        energies.push(world.bodies.iter().map(|b| b.kinetic_energy()).sum::<f64>());
    }
    let after = |from: usize| energies[from..].iter().copied().fold(0.0, f64::max);
    println!(
        "kinetic energy, largest from 0.5 s {:.2e} J, from 0.7 s {:.2e} J, from 0.8 s {:.2e} J, \
         at 1 s {:.2e} J",
        after(499),
        after(699),
        after(799),
        energies[999]
    );
    assert!(
        after(799) < 1e-5,
        "not settled 0.8 s in: {:e} J",
        after(799)
    );
    assert!(
        energies[999] < 1e-6,
        "not settled at 1 s: {:e} J",
        energies[999]
    );
}

#[test]
fn organs_settle_and_the_demo_tools_press_and_grasp_in_the_laparoscopy_scene() {
    // The devices `palpa demo --scene laparoscopy` runs, as scripts (their hands' paths).
    let seconds = 6.0;
    let scene = common::laparoscopy_with_demo_tools(seconds);
    let tube = scene
        .bodies
        .iter()
        .position(|b| b.name == "tube_left")
        .unwrap();
    let mut world = World::from_scene(&scene);
    let tube_start = world.bodies[tube].surface_centre_of_mass();
    let (mut probe_force, mut grasped, mut lift): (f64, u32, f64) = (0.0, 0, 0.0);
    let mut settled_kinetic = f64::NAN;
    let mut worst_sum: f64 = 0.0;
    for tick in 1..=(seconds * 1000.0) as u64 {
        world.step();
        let forces = world.body_contact_forces();
        let sum = forces.iter().fold(Vec3::zeros(), |s, f| s + f);
        worst_sum = worst_sum.max(sum.norm());
        probe_force = probe_force.max(world.tools[0].feedback.force_in_world.norm());
        let held = world.tools[1].feedback.grasped;
        grasped = grasped.max(held);
        if held > 0 {
            lift = lift.max(world.bodies[tube].surface_centre_of_mass().z - tube_start.z);
        }
        if tick == 700 {
            // The grasper coming down to the tube brushes the bowel loops from the first ticks
            // (its shaft on their faces, with friction): reported, not asserted (the organs'
            // own settling is `the_laparoscopy_organs_settle_on_their_ligaments`).
            settled_kinetic = world.bodies.iter().map(|b| b.kinetic_energy()).sum();
        }
        if tick % 500 == 0 {
            assert_eq!(common::nodes_inside_others(&world), 0, "tick {tick}");
            assert_eq!(common::surfaces_crossing(&world), 0, "tick {tick}");
        }
    }
    let guard_events: u64 = world.guards.iter().map(|g| g.events).sum();
    println!(
        "kinetic energy at 0.7 s (the grasper coming down) {settled_kinetic:.2e} J; probe force up to {probe_force:.3} N; grasper held {grasped} nodes and lifted the tube {:.1} mm; contact forces sum to {worst_sum:.1e} N at worst; guard events {guard_events}",
        lift * 1e3
    );
    assert!(settled_kinetic.is_finite());
    assert!(probe_force > 0.05, "{probe_force}");
    assert!(grasped >= 2, "{grasped}");
    assert!(lift > 0.01, "{lift}");
    assert!(worst_sum < 1e-9, "{worst_sum}");
    assert_eq!(guard_events, 0);
    // Put down and let go: the tube lies where it started (within its own radius).
    let tube_end = world.bodies[tube].surface_centre_of_mass();
    assert!(
        (tube_end - tube_start).norm() < 0.004,
        "{tube_start:?} -> {tube_end:?}"
    );
    assert_eq!(world.tools[1].feedback.grasped, 0);
}
