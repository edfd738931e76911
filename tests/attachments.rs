//! Attachments (`[[attachment]]`): an organ hung from the world and an organ hung from another by
//! ligaments come to rest where their ties carry their weight, with every integrator; the ties
//! never add energy; bad tables are refused with their position.

mod common;

use palpa::Vec3;
use palpa::world::World;

/// An organ of 0.4 kg hung by the top of its surface from the world.
fn hanging_scene(integrator: &str) -> String {
    format!(
        r#"
[world]
integrator = "{integrator}"

[[body]]
name = "organ"
mesh = {{ icosphere = {{ radius = 0.03, subdivisions = 2 }} }}
position = [0.0, 0.0, 0.2]
surface_mass = 0.2
rigid_mass = 0.2
link_stiffness = 40.0
link_damping = 0.2

[[attachment]]
name = "ligament"
body = "organ"
at = [0.0, 0.0, 0.03]
radius = 0.012
to = "world"
stiffness = 300.0
damping = 4.0
"#
    )
}

/// Steps `world` for `seconds`; returns the largest rise of the bodies' energy plus the ties' in one
/// tick and the largest excess over the start (J).
fn step_without_energy_gain(world: &mut World, seconds: f64) -> (f64, f64) {
    let gravity = world.params.gravity;
    let energy =
        |w: &World| common::total_energy(&w.bodies, &gravity) + w.attachments().energy(&w.bodies);
    let start = energy(world);
    let mut worst: f64 = f64::NEG_INFINITY;
    let mut previous = start;
    let mut excess: f64 = f64::NEG_INFINITY;
    for _ in 0..(seconds / world.params.dt).round() as u64 {
        world.step();
        let e = energy(world);
        worst = worst.max(e - previous);
        excess = excess.max(e - start);
        previous = e;
        assert!(e.is_finite());
    }
    (worst, excess)
}

#[test]
fn an_organ_hung_from_the_world_rests_where_the_ligament_carries_its_weight() {
    for integrator in ["symplectic", "multirate", "implicit"] {
        let scene = common::scene(&hanging_scene(integrator));
        let ties = scene.attachments[0].ties.len();
        let mut world = World::from_scene(&scene);
        let start = world.bodies[0].rigid.position_in_world;
        let (rise, excess) = step_without_energy_gain(&mut world, 8.0);
        let body = &world.bodies[0];
        let weight = body.total_mass() * world.params.gravity;
        let pull = world.attachments().force_on_body(0);
        let kinetic = body.kinetic_energy();
        let drop = start.z - body.rigid.position_in_world.z;
        println!(
            "{integrator}: {ties} ties, hangs {:.2} mm lower, kinetic {kinetic:.2e} J, pull {:.6} N against weight {:.6} N (|sum| {:.2e} N), largest energy rise in a tick {rise:.2e} J, above the start {excess:.2e} J, guard events {}",
            drop * 1e3,
            pull.z,
            -weight.z,
            (pull + weight).norm(),
            world.guards[0].events
        );
        assert!(ties >= 3, "{integrator}: the region has {ties} nodes");
        // Hangs below where it was placed, by about its weight over the ligament's stiffness (the
        // links and springs stretch too), and is at rest.
        assert!(
            drop > 0.8 * -weight.z / 300.0 && drop < 0.05,
            "{integrator}: dropped {drop} m"
        );
        assert!(kinetic < 1e-8, "{integrator}: kinetic energy {kinetic} J");
        // At rest the ligament carries the whole weight.
        assert!(
            (pull + weight).norm() < 1e-6 * weight.norm(),
            "{integrator}: pull {pull:?} against weight {weight:?}"
        );
        assert!(rise < 1e-9, "{integrator}: energy rose {rise} J in a tick");
        assert_eq!(world.guards[0].events, 0, "{integrator}");
    }
}

#[test]
fn an_organ_hung_from_another_by_a_ligament_pulls_it_with_the_opposite_force() {
    let text = r#"
[[body]]
name = "uterus"
mesh = { ellipsoid = { radii = [0.035, 0.025, 0.025], subdivisions = 2 } }
position = [0.0, 0.0, 0.2]
fixed = true

[[body]]
name = "ovary"
mesh = { ellipsoid = { radii = [0.015, 0.01, 0.008], subdivisions = 2 } }
position = [0.08, 0.0, 0.2]
surface_mass = 0.01
rigid_mass = 0.02
air_viscosity = 5.0

[[attachment]]
name = "ovarian_ligament"
body = "ovary"
at = [-0.015, 0.0, 0.0]
radius = 0.006
to = "uterus"
stiffness = 20.0
damping = 0.2
"#;
    let scene = common::scene(text);
    let mut world = World::from_scene(&scene);
    let start = world.bodies[1].rigid.position_in_world;
    let (rise, excess) = step_without_energy_gain(&mut world, 8.0);
    let ovary = &world.bodies[1];
    let weight = ovary.total_mass() * world.params.gravity;
    let on_ovary = world.attachments().force_on(1);
    let on_uterus = world.attachments().force_on(0);
    let moved = ovary.rigid.position_in_world - start;
    println!(
        "ovary hangs {:.2} mm lower, {:.2} mm towards the uterus; pull on it {:.6} N against its weight {:.6} N; on the uterus {:?} N; kinetic {:.2e} J; largest energy rise {rise:.2e} J, above the start {excess:.2e} J",
        -moved.z * 1e3,
        -moved.x * 1e3,
        on_ovary.z,
        -weight.z,
        on_uterus,
        ovary.kinetic_energy()
    );
    // Equal and opposite on the two bodies.
    assert!((on_ovary + on_uterus).norm() < 1e-12);
    // The ovary hangs from the uterus, at rest, its weight carried: straight below the uterus's
    // side (x = 0.035 m) where the ligament starts, by about the ligament (3 cm at rest, stretched
    // by its load, 0.29 N over 20 N/m) and half the ovary (1.5 cm) below it: 6 cm.
    let centre = ovary.rigid.position_in_world;
    assert!((centre.x - 0.035).abs() < 0.005, "centre {centre:?}");
    assert!(moved.z < -0.05 && moved.z > -0.075, "moved {moved:?}");
    assert!(ovary.kinetic_energy() < 1e-8);
    assert!((on_ovary + weight).norm() < 1e-6 * weight.norm());
    // The uterus (fixed) holds the ovary's weight through its tissue: its nodes near the ligament
    // are pulled down.
    assert!(on_uterus.z < 0.0);
    assert!(rise < 1e-9, "energy rose {rise} J in a tick");
    assert_eq!(world.guards.iter().map(|g| g.events).sum::<u64>(), 0);
}

#[test]
fn the_tie_forces_change_the_motion_exactly_by_their_impulse() {
    // A free organ in zero gravity with one end of a stretched ligament: its momentum changes by
    // the ties' impulse every tick (nothing else acts on it).
    let text = r#"
[world]
gravity = [0.0, 0.0, 0.0]

[[body]]
name = "organ"
mesh = { icosphere = { radius = 0.03, subdivisions = 2 } }
position = [0.0, 0.0, 0.0]
velocity = [0.05, 0.0, 0.02]

[[attachment]]
body = "organ"
at = [0.03, 0.0, 0.0]
radius = 0.01
stiffness = 50.0
damping = 0.5
"#;
    let mut world = World::from_scene(&common::scene(text));
    let momentum = |w: &World| {
        let b = &w.bodies[0];
        let nodes = b
            .surface
            .velocity_in_world
            .iter()
            .zip(&b.surface.mass)
            .fold(Vec3::zeros(), |sum, (v, m)| sum + v * *m);
        nodes + b.rigid.velocity_in_world * b.rigid.mass
    };
    let mut worst: f64 = 0.0;
    let mut largest: f64 = 0.0;
    for _ in 0..500 {
        let before = momentum(&world);
        world.step();
        let impulse = world.attachments().force_on(0) * world.params.dt;
        worst = worst.max((momentum(&world) - before - impulse).norm());
        largest = largest.max(impulse.norm());
    }
    println!("largest impulse {largest:.3e} N·s, largest momentum error {worst:.2e} N·s");
    assert!(largest > 1e-4, "the ligament never pulled");
    assert!(worst < 1e-12 * largest.max(1.0) + 1e-15, "{worst}");
}

fn refused(extra: &str, expected: &str) {
    let text = format!(
        r#"
[[body]]
name = "a"
mesh = {{ icosphere = {{ radius = 0.03, subdivisions = 1 }} }}

[[body]]
name = "b"
mesh = {{ icosphere = {{ radius = 0.03, subdivisions = 1 }} }}
position = [0.1, 0.0, 0.0]
cutting = {{}}

{extra}
"#
    );
    let error = palpa::scene::parse_scene(&text, "x.toml", std::path::Path::new("."))
        .err()
        .unwrap_or_else(|| panic!("accepted: {extra}"))
        .to_string();
    println!("{error}");
    assert!(error.starts_with("x.toml:"), "{error}");
    assert!(error.contains(expected), "{error} lacks {expected}");
}

#[test]
fn bad_attachments_are_refused_with_their_position() {
    refused(
        "[[attachment]]\nbody = \"c\"\nat = [0.0, 0.0, 0.03]",
        "names no body",
    );
    refused(
        "[[attachment]]\nbody = \"a\"\nat = [0.0, 0.0, 0.03]\nto = \"a\"",
        "to itself",
    );
    refused(
        "[[attachment]]\nbody = \"a\"\nat = [0.0, 0.0, 0.2]\nradius = 0.01",
        "no node of body `a` within",
    );
    refused(
        "[[attachment]]\nbody = \"a\"\nat = [0.0, 0.0, 0.03]\nstiffness = 1e6",
        "too stiff for",
    );
    refused(
        "[[attachment]]\nbody = \"a\"\nat = [0.0, 0.0, 0.03]\ndamping = 1e3",
        "too damped for",
    );
    refused(
        "[[attachment]]\nbody = \"a\"\nat = [0.0, 0.0, 0.03]\nstiffness = 1e6\ndamping = 1e3",
        "too stiff and too damped",
    );
    refused("[[attachment]]\nbody = \"a\"", "needs `at`");
    refused(
        "[[attachment]]\nbody = \"a\"\nat = [0.0, 0.0, 0.03]\nstiff = 1.0",
        "unknown field `stiff`",
    );
    refused(
        "[[attachment]]\nname = \"l\"\nbody = \"a\"\nat = [0.0, 0.0, 0.03]\n[[attachment]]\nname = \"l\"\nbody = \"a\"\nat = [0.0, 0.0, -0.03]",
        "duplicate attachment name `l`",
    );
}

#[test]
fn a_ligament_between_two_free_organs_conserves_their_momentum() {
    // Zero gravity, two organs tied and thrown apart: the ties are internal, the total momentum
    // stays, each organ's changes by the ties' impulse on it until they touch. (The multi-rate
    // scheme is left out: its edges between sub-stepped and single-stepped nodes do not give
    // exactly opposite impulses within a tick, with or without ties.)
    for integrator in ["symplectic", "implicit"] {
        let text = format!(
            r#"
[world]
gravity = [0.0, 0.0, 0.0]
integrator = "{integrator}"

[[body]]
name = "a"
mesh = {{ icosphere = {{ radius = 0.03, subdivisions = 2 }} }}
velocity = [-0.1, 0.02, 0.0]

[[body]]
name = "b"
mesh = {{ ellipsoid = {{ radii = [0.02, 0.015, 0.015], subdivisions = 2 }} }}
position = [0.06, 0.0, 0.0]
velocity = [0.1, 0.0, 0.03]
angular_velocity = [0.0, 2.0, 0.0]
surface_mass = 0.05
rigid_mass = 0.1
link_stiffness = 5.0

[[attachment]]
body = "b"
at = [-0.02, 0.0, 0.0]
radius = 0.008
to = "a"
stiffness = 30.0
damping = 0.3
"#
        );
        let mut world = World::from_scene(&common::scene(&text));
        let momentum = |w: &World, b: usize| {
            let body = &w.bodies[b];
            let s = &body.surface;
            s.velocity_in_world.iter().zip(&s.mass).fold(
                body.rigid.velocity_in_world * body.rigid.mass,
                |sum, (v, m)| sum + v * *m,
            )
        };
        let total = |w: &World| momentum(w, 0) + momentum(w, 1);
        let start = total(&world);
        let (mut worst_total, mut worst_each, mut largest): (f64, f64, f64) = (0.0, 0.0, 0.0);
        let mut touched_at = None;
        for _ in 0..1000 {
            let before = momentum(&world, 1);
            world.step();
            let impulse = world.attachments().force_on(1) * world.params.dt;
            if world.counters.bodies.contacts > 0 {
                touched_at.get_or_insert(world.tick);
            }
            if touched_at.is_none() {
                worst_each = worst_each.max((momentum(&world, 1) - before - impulse).norm());
            }
            worst_total = worst_total.max((total(&world) - start).norm());
            largest = largest.max(impulse.norm());
        }
        let apart =
            world.bodies[1].rigid.position_in_world - world.bodies[0].rigid.position_in_world;
        println!(
            "{integrator}: largest impulse {largest:.3e} N·s; total momentum drift {worst_total:.2e} N·s (of {:.3e}); one organ's momentum against its ties' impulse {worst_each:.2e} N·s (before they touch at tick {touched_at:?}); {:.1} mm apart at the end",
            start.norm(),
            apart.norm() * 1e3
        );
        assert!(largest > 1e-4, "{integrator}: the ligament never pulled");
        // The implicit solve conserves momentum to its conjugate-gradient tolerance (relative 1e-9
        // here), the explicit scheme to rounding.
        let bound = if integrator == "implicit" {
            1e-9 * start.norm()
        } else {
            1e-15
        };
        assert!(worst_total < bound, "{integrator}: {worst_total}");
        assert!(worst_each < bound, "{integrator}: {worst_each}");
        // Held together: they started 6 cm apart flying apart at 0.2 m/s (20 cm in the second).
        assert!(apart.norm() < 0.1, "{integrator}: {apart:?}");
    }
}

/// An organ hung by a ligament on one side and cut through by a blade: each tie follows its node
/// through the transection (the nodes renumbered), the piece with the ligament stays hung and the
/// piece cut away falls to the table; mass is kept.
#[test]
fn a_hung_organ_cut_through_keeps_its_ligament_on_the_piece_that_holds_it() {
    let text = r#"
[world]
integrator = "implicit"

[[body]]
name = "organ"
mesh = { icosphere = { radius = 0.03, subdivisions = 2 } }
position = [0.0, 0.0, 0.2]
surface_mass = 0.2
rigid_mass = 0.2
link_stiffness = 40.0
link_damping = 0.2
cutting = {}

[[obstacle]]
name = "table"
plane = { point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }

[[attachment]]
name = "ligament"
body = "organ"
at = [0.02, 0.0, 0.022]
radius = 0.01
to = "world"
stiffness = 300.0
damping = 2.0

[[tool]]
name = "scalpel"
shape = { blade = { length = 0.14, thickness = 0.0005 } }
input = "script"
script = [
  { t = 0.0, position = [0.005, -0.08, 0.1] },
  { t = 2.0, position = [0.005, -0.08, 0.1] },
  { t = 2.6, position = [0.005, 0.08, 0.1] },
  { t = 3.2, position = [0.005, -0.08, 0.1] },
]
"#;
    let mut world = World::from_scene(&common::scene(text));
    let mass0: f64 = world.bodies.iter().map(|b| b.total_mass()).sum();
    let mut cut_at = None;
    let tied_places = |world: &World| -> Vec<Vec<Vec3>> {
        (0..world.attachments().len())
            .map(|a| {
                world
                    .attachments()
                    .tied_nodes(a)
                    .map(|(b, n)| world.bodies[b].surface.position_in_world[n as usize])
                    .collect()
            })
            .collect()
    };
    let mut before = tied_places(&world);
    for tick in 0..5000 {
        if world.bodies.len() == 1 {
            before = tied_places(&world);
        }
        world.step();
        if cut_at.is_none() && world.bodies.len() > 1 {
            cut_at = Some(tick);
            // A transection moves no node: every tie end is where its node was.
            let after = tied_places(&world);
            for (a, (b, c)) in before.iter().zip(&after).enumerate() {
                for (p, q) in b.iter().zip(c) {
                    assert!(
                        (p - q).norm() < 0.01,
                        "tie end of attachment {a} moved from {p:?} to {q:?}"
                    );
                }
            }
        }
        for b in &world.bodies {
            assert!(b.is_finite(), "tick {tick}: {} is not finite", b.name);
        }
    }
    let cut_at = cut_at.expect("the blade did not cut the organ through");
    assert_eq!(
        world.bodies.len(),
        2,
        "two pieces: {:?}",
        world
            .bodies
            .iter()
            .map(|b| (b.name.clone(), b.total_mass()))
            .collect::<Vec<_>>()
    );
    let mass: f64 = world.bodies.iter().map(|b| b.total_mass()).sum();
    assert!(
        (mass - mass0).abs() <= 1e-12 * mass0,
        "mass {mass0} → {mass}"
    );
    let centre = |b: usize| world.bodies[b].surface_centre_of_mass();
    let pull = |b: usize| world.attachments().force_on(b).norm();
    let attachments = world.attachments();
    let body_of = |a: usize| {
        let bodies: Vec<usize> = attachments.tied_nodes(a).map(|(b, _)| b).collect();
        assert!(
            bodies.iter().all(|&b| b == bodies[0]),
            "attachment {a} split across bodies: {bodies:?}"
        );
        bodies[0]
    };
    let hung = body_of(0);
    let cut_away = 1 - hung;
    let weight = world.bodies[hung].total_mass() * 9.81;
    println!(
        "separated at tick {cut_at}: `{}` {:.4} kg hung (centre z {:.4} m, ligament {:.4} N against \
         its weight {:.4} N); `{}` {:.4} kg cut away (centre z {:.4} m)",
        world.bodies[hung].name,
        world.bodies[hung].total_mass(),
        centre(hung).z,
        pull(hung),
        weight,
        world.bodies[cut_away].name,
        world.bodies[cut_away].total_mass(),
        centre(cut_away).z,
    );
    assert_eq!(
        pull(cut_away),
        0.0,
        "the ligament pulls on the piece cut away"
    );
    // The hung piece stays up, carried by the ligament (at rest by the end: pull ≈ its weight).
    assert!(
        centre(hung).z > 0.15,
        "the hung piece fell: {:?}",
        centre(hung)
    );
    assert!(
        (pull(hung) - weight).abs() <= 0.05 * weight,
        "ligament {} N against a weight of {weight} N",
        pull(hung)
    );
    // The piece cut away fell onto the table.
    assert!(
        centre(cut_away).z < 0.03,
        "the piece cut away did not fall: {:?}",
        centre(cut_away)
    );
}

/// A tube tied to the world at both ends and cut across in the middle: each end's ties follow their
/// nodes into their own piece — one stays in `tube`, the other moves into the new body `tube.1` —
/// each tie end where its node was, and each piece held by its own ligament.
#[test]
fn a_tube_tied_at_both_ends_and_cut_across_keeps_each_tie_on_its_own_piece() {
    let scene = std::fs::read_to_string(common::repo_root().join("scenes/transection.toml"))
        .expect("scenes/transection.toml");
    let text = format!(
        "{scene}
[[attachment]]
name = \"left\"
body = \"tube\"
at = [-0.07, 0.0, 0.0]
radius = 0.012
to = \"world\"
stiffness = 20.0
damping = 0.01

[[attachment]]
name = \"right\"
body = \"tube\"
at = [0.07, 0.0, 0.0]
radius = 0.012
to = \"world\"
stiffness = 20.0
damping = 0.01
"
    );
    let mut world = World::from_scene(&common::scene(&text));
    let places = |world: &World, a: usize| -> Vec<(usize, Vec3)> {
        world
            .attachments()
            .tied_nodes(a)
            .map(|(b, n)| (b, world.bodies[b].surface.position_in_world[n as usize]))
            .collect()
    };
    let mut before = [places(&world, 0), places(&world, 1)];
    let mut separated = false;
    for _ in 0..1500 {
        if world.bodies.len() == 1 {
            before = [places(&world, 0), places(&world, 1)];
        }
        world.step();
        if world.bodies.len() > 1 {
            separated = true;
            break;
        }
    }
    assert!(separated, "the tube was not cut through");
    let after = [places(&world, 0), places(&world, 1)];
    let mut body_of = [0; 2];
    for a in 0..2 {
        assert_eq!(before[a].len(), after[a].len());
        body_of[a] = after[a][0].0;
        for ((_, p), (b, q)) in before[a].iter().zip(&after[a]) {
            assert_eq!(*b, body_of[a], "attachment {a} split across bodies");
            assert!(
                (p - q).norm() < 1e-3,
                "attachment {a}: a tie end moved from {p:?} to {q:?} in the transection"
            );
        }
    }
    println!(
        "left ties on `{}`, right ties on `{}`; pulls {:.4} / {:.4} N",
        world.bodies[body_of[0]].name,
        world.bodies[body_of[1]].name,
        world.attachments().force_on_body(0).norm(),
        world.attachments().force_on_body(1).norm()
    );
    assert_ne!(body_of[0], body_of[1], "both ends' ties on one piece");
    // A few more ticks: each piece is held by its own ligament, and nothing breaks.
    for _ in 0..200 {
        world.step();
    }
    for (a, &b) in body_of.iter().enumerate() {
        assert!(world.bodies[b].is_finite());
        let pull = world.attachments().force_on(b);
        assert!(
            (pull - world.attachments().force_on_body(a)).norm() <= 1e-12,
            "piece `{}` feels another attachment's ties",
            world.bodies[b].name
        );
    }
}
