//! Deformable surfaces meet on their trajectories: no node of one body ever ends a tick inside
//! another, at rest (a ball dropped on an organ) or at speed (two balls thrown at each other).

mod common;

use palpa::Vec3;
use palpa::scene::load_scene;
use palpa::world::World;

#[test]
fn a_ball_dropped_on_an_organ_never_enters_it() {
    let scene = load_scene(&common::repo_root().join("scenes/two_organs.toml")).unwrap();
    let mut world = World::from_scene(&scene);
    assert!(world.systems().body_contact);
    let (mut collisions, mut contacts) = (0, 0);
    for k in 0..3000 {
        world.step();
        collisions += world.counters.bodies.collisions;
        contacts += world.counters.bodies.contacts;
        assert_eq!(world.counters.bodies.overflows, 0);
        if k % 5 == 0 {
            assert_eq!(
                common::nodes_inside_others(&world),
                0,
                "interpenetration at tick {k}"
            );
            assert_eq!(
                common::surfaces_crossing(&world),
                0,
                "surfaces cross at tick {k}"
            );
        }
        assert!(world.bodies.iter().all(|b| b.is_finite()));
    }
    println!("{contacts} contacts solved, {collisions} collisions answered by the net");
    assert!(
        contacts + collisions > 100,
        "the bodies met: {contacts} contacts, {collisions} collisions answered"
    );
}

/// The soft ball of `scenes/two_organs.toml` landing on the organ (ticks 100 to 300): the response's
/// contacts hold it, and the collision net, the guarantee behind them, has next to nothing left to
/// stop. The net's answers were 93 % the pair it answered the tick before, which the response's
/// nearest contacts did not hold: 7 765 answers over the landing, 915 µs a tick on this machine.
/// The response now takes a contact for each pair the net answered last tick (and keeps it while it
/// presses, its impulse capped at half of last tick's): 2 answers, 389 µs a tick.
#[test]
fn a_ball_landing_on_an_organ_is_held_by_contacts_not_stopped_by_the_net() {
    let scene = load_scene(&common::repo_root().join("scenes/two_organs.toml")).unwrap();
    let mut world = World::from_scene(&scene);
    let (mut collisions, mut contacts) = (0, 0);
    for k in 0..600 {
        world.step();
        if (100..300).contains(&k) {
            collisions += world.counters.bodies.collisions;
            contacts += world.counters.bodies.contacts;
        }
        assert_eq!(world.counters.bodies.contacts_dropped, 0, "tick {k}");
        if k % 10 == 0 {
            assert_eq!(common::nodes_inside_others(&world), 0, "tick {k}");
        }
    }
    println!("landing: {contacts} contacts solved, {collisions} collisions answered by the net");
    assert!(
        contacts > 10_000,
        "the ball did not land: {contacts} contacts"
    );
    assert!(
        collisions < 100,
        "the net answered {collisions} collisions over the landing"
    );
}

#[test]
fn two_balls_thrown_at_each_other_at_1_m_per_s_do_not_pass_through() {
    let (collisions, budget_spent) = thrown_balls(None);
    assert!(collisions > 0);
    // Every continuous query of the net settled within the default box budget: exact answers.
    assert_eq!(budget_spent, 0, "queries spent the default budget");
}

/// The same balls with a budget of `max_boxes` for the net's continuous queries: a query past it
/// is a hit at the earliest time it had not resolved (earlier than the exact one, or a collision
/// where there is none), so the bound on a query's time keeps the surfaces apart. (Checked against
/// a broken variant that reported a spent budget as no hit: the balls crossed.)
#[test]
fn a_spent_box_budget_answers_conservatively_and_is_counted() {
    for max_boxes in [1, 4] {
        let (collisions, budget_spent) = thrown_balls(Some(max_boxes));
        println!("budget {max_boxes}: {collisions} collisions, {budget_spent} budgets spent");
        assert!(collisions > 0);
        assert!(budget_spent > 0, "no query spent a budget of {max_boxes}");
    }
}

/// Two soft balls thrown at each other at 1 m/s each (zero gravity), stepped 300 ticks with the
/// net's box budget `max_boxes` (the default when `None`), asserting at every tick that no node of
/// one is inside the other and no edge of one crosses a triangle of the other: the net's
/// collisions and the queries that spent the budget over the run.
fn thrown_balls(max_boxes: Option<u32>) -> (u32, u32) {
    let scene = common::scene(
        r#"
        [world]
        gravity = [0.0, 0.0, 0.0]
        [[body]]
        name = "left"
        mesh = { icosphere = { radius = 0.03, subdivisions = 2 } }
        position = [-0.05, 0.0, 0.0]
        velocity = [1.0, 0.0, 0.0]
        surface_mass = 0.1
        rigid_mass = 0.3
        surface_stiffness = 30.0
        link_stiffness = 30.0
        [[body]]
        name = "right"
        mesh = { icosphere = { radius = 0.03, subdivisions = 2 } }
        position = [0.05, 0.005, 0.0]
        velocity = [-1.0, 0.0, 0.0]
        surface_mass = 0.1
        rigid_mass = 0.3
        surface_stiffness = 30.0
        link_stiffness = 30.0
        "#,
    );
    let mut world = World::from_scene(&scene);
    if let Some(max_boxes) = max_boxes {
        world.set_ccd_max_boxes(max_boxes);
    }
    let (mut collisions, mut budget_spent) = (0, 0);
    for k in 0..300 {
        world.step();
        collisions += world.counters.bodies.collisions;
        budget_spent += world.counters.bodies.budget_spent;
        assert_eq!(
            common::nodes_inside_others(&world),
            0,
            "interpenetration at tick {k}"
        );
        // No surface passes through the other: no edge of one crosses a triangle of the other
        // (the interface of two soft balls squashed to 2.8 cm apart bulges and tilts, so the
        // nodes are not ordered along x, but the surfaces never cross).
        assert_eq!(
            common::surfaces_crossing(&world),
            0,
            "surfaces cross at tick {k}"
        );
    }
    // They stopped each other: the surface centres no longer close in.
    let gap =
        world.bodies[1].surface_centre_of_mass().x - world.bodies[0].surface_centre_of_mass().x;
    assert!(gap > 0.0, "centres crossed: {gap}");
    (collisions, budget_spent)
}

/// A block of `friction` resting on a fixed slab of the same `friction` tilted by `theta` about y:
/// body on body, the pair's coefficient √(μ μ) = μ.
fn block_on_tilted_slab(theta: f64, friction: f64) -> World {
    let normal = Vec3::new(theta.sin(), 0.0, theta.cos());
    let downhill = Vec3::new(theta.cos(), 0.0, -theta.sin());
    // The slab's top face is 2 cm above its centre; the block's centre 3 cm above its bottom, which
    // starts 0.3 mm above the slab (inside the contact skin), 20 cm uphill.
    let centre = normal * (0.02 + 0.03 + 0.0003) - downhill * 0.2;
    let (w, y) = ((theta / 2.0).cos(), (theta / 2.0).sin());
    let text = format!(
        r#"
        [world]
        gravity = [0.0, 0.0, -9.81]
        [[body]]
        name = "slab"
        mesh = {{ box = {{ size = [0.6, 0.2, 0.04], subdivisions = 11 }} }}
        orientation = [{w}, 0.0, {y}, 0.0]
        fixed = true
        surface_mass = 8.0
        rigid_mass = 5.0
        surface_stiffness = 300.0
        surface_damping = 0.2
        link_stiffness = 5000.0
        link_damping = 10.0
        friction = {friction}
        [[body]]
        name = "block"
        mesh = {{ box = {{ size = [0.1, 0.1, 0.06], subdivisions = 2 }} }}
        position = [{}, {}, {}]
        orientation = [{w}, 0.0, {y}, 0.0]
        surface_mass = 0.5
        rigid_mass = 1.0
        surface_stiffness = 300.0
        surface_damping = 0.2
        link_stiffness = 300.0
        link_damping = 0.5
        friction = {friction}
        "#,
        centre.x, centre.y, centre.z,
    );
    World::from_scene(&common::scene(&text))
}

/// The paper's inclined-plane test, body on body: a block on a tilted slab (another deformable body)
/// stays below atan(μ) and above it slides with g (sin θ − μ cos θ) within 5 %; the contact forces on
/// the two bodies are equal and opposite every tick; no node of one ends inside the other.
#[test]
fn a_block_on_a_tilted_body_sticks_or_slides_with_coulomb_friction() {
    let mu = 0.3;
    for theta_deg in [10.0f64, 30.0, 25.0] {
        let theta = theta_deg.to_radians();
        let downhill = Vec3::new(theta.cos(), 0.0, -theta.sin());
        let mut world = block_on_tilted_slab(theta, mu);
        let (mut times, mut s) = (Vec::new(), Vec::new());
        let mut worst_sum: f64 = 0.0;
        let mut largest: f64 = 0.0;
        let expected = 9.81 * (theta.sin() - mu * theta.cos());
        // A sliding block reaches the slab's lower end after about 0.6 s at 30°: its acceleration
        // is fitted over 0.2–0.55 s. A sticking one settles into its elastic sag (and the slab
        // under it) in about a second and must not creep over the next second.
        let (ticks, from) = if expected > 0.0 {
            (550, 200)
        } else {
            (2000, 1000)
        };
        for tick in 0..ticks {
            world.step();
            let forces = world.body_contact_forces();
            let sum = forces[0] + forces[1];
            worst_sum = worst_sum.max(sum.norm());
            largest = largest.max(forces[1].norm());
            if tick % 50 == 0 {
                assert_eq!(
                    common::nodes_inside_others(&world),
                    0,
                    "θ = {theta_deg}°, tick {tick}"
                );
            }
            if tick >= from {
                times.push(world.time());
                s.push(world.bodies[1].surface_centre_of_mass().dot(&downhill));
            }
        }
        let a = common::fitted_acceleration(&times, &s);
        let travel = s.last().unwrap() - s[0];
        eprintln!(
            "θ = {theta_deg}°, μ = {mu}: a = {a:.4} m/s², expected {expected:.4}; travel over the window {travel:.3e} m; contact force up to {largest:.3} N, worst sum {worst_sum:.2e} N; {:?}",
            world.counters.bodies
        );
        assert!(
            largest > 1.0,
            "θ = {theta_deg}°: the block does not rest on the slab"
        );
        assert!(
            worst_sum < 1e-9,
            "θ = {theta_deg}°: forces do not cancel: {worst_sum} N"
        );
        if expected <= 0.0 {
            assert!(
                travel.abs() < 1e-4,
                "θ = {theta_deg}° below atan μ: the block slid {travel} m"
            );
        } else {
            let relative = (a - expected).abs() / expected;
            assert!(
                relative < 0.05,
                "θ = {theta_deg}°: a = {a}, expected {expected} ({:.1} %)",
                relative * 100.0
            );
        }
    }
}

/// An organ resting on another, pressed by a probe: it stays on the lower one and comes to rest
/// (kinetic energy below 1e-5 J at tick 3 499 and at every tick from 1 s after the probe left,
/// laid at three heights; before the held contacts, single ticks in which one node
/// fell reached 1.3e-5 to 2.0e-5 J there, see the README); no node of either is ever inside the
/// other and no surface crosses the other; the contact forces on the two organs are equal and
/// opposite every tick; without the probe, the pair's energy never grows. With the multi-rate
/// (default) and the implicit integrator.
///
/// The multi-rate figure from 1 s is near the bound: what rings is the upper organ thrown up as the
/// probe lifts, bouncing on the lower one about every 0.37 s with its energy falling about 5× a
/// bounce, and a peak falls near 1 s (README, **Contact between bodies → What must be shown**,
/// item 1). From 2026-12-07 (the probe kept out by the faces, pressing 8.6 N instead of 6.0) to
/// the faces' contacts being taken again in their later sweeps it was 1.02–1.08e-5 J.
#[test]
fn an_organ_resting_on_another_and_pressed_stays_and_comes_to_rest() {
    for integrator in ["multirate", "implicit"] {
        // Laid at three heights 0.05 mm apart or less: a figure that held at one height only
        // would be chance (see the README, "Ninth session").
        for lift in [0.0, 1e-5, 5e-5] {
            organ_pressed_on_another_comes_to_rest(integrator, lift);
        }
    }
}

/// The pressing probe's radius (m).
const PROBE_RADIUS: f64 = 0.006;

/// A probe (a 6 mm sphere) on the vertical through the origin, scripted: from 0.2 m high down to
/// `approach` (m) at 1.5 s, to `deepest` at 2 s, back up to 0.2 m at 2.5 s.
fn pressing_probe(approach: f64, deepest: f64) -> String {
    format!(
        r#"
        [[tool]]
        name = "probe"
        shape = {{ sphere = {{ radius = {PROBE_RADIUS:?} }} }}
        input = "script"
        script = [
          {{ t = 0.0, position = [0.0, 0.0, 0.2] }},
          {{ t = 1.5, position = [0.0, 0.0, {approach:?}] }},
          {{ t = 2.0, position = [0.0, 0.0, {deepest:?}] }},
          {{ t = 2.5, position = [0.0, 0.0, 0.2] }},
        ]
    "#
    )
}

fn organ_pressed_on_another_comes_to_rest(integrator: &str, lift: f64) {
    let organs = organ_on_organ(integrator, 0.2, lift);
    let probe = pressing_probe(0.13, 0.066);
    let mut world = World::from_scene(&common::scene(&format!("{organs}\n{probe}")));
    let gravity = world.params.gravity;
    let mut energy_before_probe = 0.0;
    let mut growth: f64 = 0.0;
    let mut worst_sum: f64 = 0.0;
    let mut pressed: f64 = 0.0;
    let mut resting_kinetic = f64::INFINITY;
    let (mut left_at, mut most_after, mut most_later) = (0, 0.0f64, 0.0f64);
    for k in 0..4000 {
        world.step();
        let forces = world.body_contact_forces();
        worst_sum = worst_sum.max((forces[0] + forces[1]).norm());
        pressed = pressed.max(world.tools[0].feedback.force_in_world.norm());
        // Before the probe arrives (it reaches 0.13 m at 1.5 s) the upper organ settles: the
        // energy at 1.4 s must not exceed the energy at 0.5 s.
        if k == 500 {
            energy_before_probe = common::total_energy(&world.bodies, &gravity);
        }
        if k == 1400 {
            growth = common::total_energy(&world.bodies, &gravity) - energy_before_probe;
        }
        if k % 10 == 0 {
            assert_eq!(
                common::nodes_inside_others(&world),
                0,
                "interpenetration at tick {k}"
            );
            assert_eq!(
                common::surfaces_crossing(&world),
                0,
                "surfaces cross at tick {k}"
            );
        }
        if k == 3499 {
            resting_kinetic = world.bodies[1].kinetic_energy();
        }
        // The largest kinetic energy of any tick from a second, and from 1.5 s, after the probe
        // left.
        if world.tools[0].feedback.force_in_world.norm() > 0.0 {
            left_at = k;
            most_after = 0.0;
            most_later = 0.0;
        } else if left_at > 0 && k >= left_at + 1000 {
            most_after = most_after.max(world.bodies[1].kinetic_energy());
            if k >= left_at + 1500 {
                most_later = most_later.max(world.bodies[1].kinetic_energy());
            }
        }
    }
    let (lower, upper) = (&world.bodies[0], &world.bodies[1]);
    let (l, u) = (
        lower.surface_centre_of_mass(),
        upper.surface_centre_of_mass(),
    );
    println!(
        "{integrator}, laid {:.2} mm higher: probe pressed up to {pressed:.3} N; upper organ at {:.4?} on the lower at {:.4?}; kinetic energy 1 s after the probe left {resting_kinetic:.2e} J (at tick 3 499; the probe left at tick {left_at}, the largest of any tick from 1 s after it {most_after:.2e} J, from 1.5 s {most_later:.2e} J); energy change from 0.5 to 1.4 s {growth:.2e} J; worst force sum {worst_sum:.2e} N; {:?}",
        lift * 1e3,
        u.as_slice(),
        l.as_slice(),
        world.counters.bodies
    );
    assert!(
        pressed > 0.1,
        "the probe did not touch the upper organ: {pressed} N"
    );
    assert!(
        resting_kinetic < 1e-5,
        "{integrator}: still moving: {resting_kinetic} J"
    );
    assert!(
        left_at > 0 && most_after < 1e-5,
        "{integrator}: a tick from 1 s after the probe left (tick {left_at}) moved with {most_after} J"
    );
    // Still on top of the lower organ: its centre above the lower one's top at rest (3 cm above
    // the lower's centre; slid off, it would lie on the table, below the lower's centre), within
    // its footprint.
    assert!(
        u.z > l.z + 0.03,
        "the upper organ left the lower one: {u:?} vs {l:?}"
    );
    assert!(
        (u.x - l.x).abs() < 0.05 && (u.y - l.y).abs() < 0.03,
        "slid off: {u:?}"
    );
    assert!(
        worst_sum < 1e-9,
        "contact forces do not cancel: {worst_sum} N"
    );
    assert!(growth <= 0.0, "{integrator}: the energy grew by {growth} J");
}

/// A heavy organ (2.1 kg) resting on another: the state velocities of the nodes are their motion.
/// The contact stops the nodes it pushes where they end the tick; a velocity it left in them
/// (along the contact, or a sub-stepped node's into it) would not move them, the contact pushing
/// them back each tick — kinetic energy that is not motion (2e-5 J in the multi-rate organ and
/// 9e-5 J in the implicit one before the response gave such a node its displacement's velocity).
#[test]
fn a_heavy_organ_resting_on_another_keeps_no_velocity_that_does_not_move_it() {
    for integrator in ["multirate", "implicit"] {
        let text = organ_on_organ(integrator, 2.0, 0.0);
        let mut world = World::from_scene(&common::scene(&text));
        let dt = world.params.dt;
        let mut before: Vec<Vec<palpa::Vec3>> = world
            .bodies
            .iter()
            .map(|b| b.surface.position_in_world.clone())
            .collect();
        // Per tick, summed over the two organs: the mean over the last second, and the largest.
        let mut per_tick = vec![0.0; 1000];
        for k in 0..3000 {
            world.step();
            for (body, before) in world.bodies.iter().zip(before.iter_mut()) {
                let s = &body.surface;
                if k >= 2000 {
                    let not_motion: f64 = (0..s.mass.len())
                        .map(|i| {
                            let motion = (s.position_in_world[i] - before[i]) / dt;
                            0.5 * s.mass[i] * (s.velocity_in_world[i] - motion).norm_squared()
                        })
                        .sum();
                    per_tick[k - 2000] += not_motion;
                }
                before.copy_from_slice(&s.position_in_world);
            }
        }
        let mean = per_tick.iter().sum::<f64>() / per_tick.len() as f64;
        let worst = per_tick.iter().fold(0.0f64, |a, &b| a.max(b));
        let (l, u) = (
            world.bodies[0].surface_centre_of_mass(),
            world.bodies[1].surface_centre_of_mass(),
        );
        println!(
            "{integrator}: kinetic energy of the nodes' velocities less their motion over 2-3 s: mean {mean:.2e} J, largest {worst:.2e} J; upper organ at {:.4?} on the lower at {:.4?}",
            u.as_slice(),
            l.as_slice()
        );
        assert!(
            u.z > l.z + 0.03,
            "{integrator}: the upper organ left the lower one"
        );
        assert!(
            mean < 1e-6,
            "{integrator}: the nodes' velocities hold {mean} J that is not motion (mean)"
        );
    }
}

/// A heavy organ (5.1 kg) laid on a lighter one (1.3 kg) stays where it was laid, its centre within
/// 5 mm of the lower one's, and no node of one is ever inside the other, with either integrator;
/// the multi-rate pair comes to rest (kinetic energy below 1e-5 J at 4.5 s). Before the response's
/// warm start the multi-rate organ moved 11 mm off the centre in 3.5 s and was still creeping off
/// (1.3e-4 J); with the warm start but without the net's further freezing rounds, the implicit pair
/// had nodes inside each other from tick 93. The heavy organ rings on the light one's links, whose
/// damping is low (about 40 nodes of 400 N/m and 0.5 N s/m under it: ζ ≈ 0.04): its energy falls
/// by about 2.5 a second, 3.3e-4 J at 3.5 s, 4e-6 J at 4.5 s (with four times that damping it
/// rests by 2.5 s). Until the response kept the contacts that start the tick over a face
/// (`started_near`), the collision net stopped the light organ's nodes every tick (17 collisions a
/// tick) and damped that ringing numerically: 6e-6 J at 3.5 s.
#[test]
fn a_heavy_organ_on_a_light_one_stays_where_it_was_laid_and_comes_to_rest() {
    for integrator in ["multirate", "implicit"] {
        let mut world = World::from_scene(&common::scene(&organ_on_organ(integrator, 5.0, 0.0)));
        for k in 1..=4500 {
            world.step();
            if k % 50 == 0 {
                assert_eq!(
                    common::nodes_inside_others(&world),
                    0,
                    "{integrator}: tick {k}"
                );
            }
        }
        let (l, u) = (
            world.bodies[0].surface_centre_of_mass(),
            world.bodies[1].surface_centre_of_mass(),
        );
        let kinetic: f64 = world.bodies.iter().map(|b| b.kinetic_energy()).sum();
        let off = (u - l).xy().norm();
        println!(
            "{integrator}: heavy organ at {:.4?} on the light one at {:.4?} ({:.1} mm off its centre); kinetic energy at 4.5 s {kinetic:.2e} J; {:?}",
            u.as_slice(),
            l.as_slice(),
            off * 1e3,
            world.counters.bodies
        );
        assert!(
            u.z > l.z + 0.015,
            "{integrator}: the heavy organ left the light one"
        );
        assert!(off < 0.005, "{integrator}: it slid {off} m off the centre");
        if integrator == "multirate" {
            assert!(kinetic < 1e-5, "{integrator}: still moving: {kinetic} J");
        }
    }
}

/// Two organs of the default parameters on the table, the smaller laid on the larger.
const SOFT_PAIR: &str = r#"
    [world]
    air_viscosity = 1.0
    [[obstacle]]
    name = "table"
    plane = { point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }
    friction = 0.5
    static_friction = 0.7
    [[body]]
    name = "lower"
    mesh = { ellipsoid = { radii = [0.07, 0.05, 0.03], subdivisions = 2 } }
    position = [0.0, 0.0, 0.0305]
    [[body]]
    name = "upper"
    mesh = { ellipsoid = { radii = [0.04, 0.03, 0.015], subdivisions = 2 } }
    position = [0.0, 0.0, 0.076]
"#;

/// A 5 kg organ dropped 1 cm onto a 0.06 kg one of a tenth of the default stiffnesses, which it
/// crushes flat against the table: nodes of the light one beyond the contact skin of the table at
/// the start of the response are pushed by the heavy one's impulses by millimetres in a tick.
const HEAVY_ON_FLIMSY: &str = r#"
    [[obstacle]]
    name = "table"
    plane = { point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }
    [[body]]
    name = "light"
    mesh = { ellipsoid = { radii = [0.08, 0.06, 0.03], subdivisions = 2 } }
    position = [0.0, 0.0, 0.0301]
    surface_mass = 0.02
    rigid_mass = 0.04
    surface_stiffness = 20.0
    link_stiffness = 10.0
    [[body]]
    name = "heavy"
    mesh = { ellipsoid = { radii = [0.06, 0.05, 0.04], subdivisions = 2 } }
    position = [0.0, 0.0, 0.11]
    surface_mass = 1.0
    rigid_mass = 4.0
    surface_stiffness = 80.0
    link_stiffness = 60.0
"#;

/// A soft organ pressed against the table by another: the response between the two organs may not
/// push the nodes between them into the table, which the obstacle pass put them on. Two cases:
/// - the default parameters (the lower organ flattens to a few millimetres under a second organ of
///   its own weight): without the table in the response's solve its nodes ended up to 1.1 mm inside
///   it at the end of every tick, to be pushed out by the next tick's obstacle pass, and the upper
///   organ jittered.
/// - [`HEAVY_ON_FLIMSY`]: with rows of the solve only for the nodes within the contact skin of the
///   table, nodes farther up were pushed through it, up to 2.9 mm, at the end of 803 of the first
///   1000 ticks; the rows now reach as far as twice the fastest listed node moves over the tick.
///   The net answered 80 collisions a tick there, most of them the same edges frozen at their
///   start tick after tick, until the response took edges that start within the skin of each
///   other and cross (see `edge_edge_crossed_from_near` in `src/contact/bodies.rs`).
///
///   How many it answers over the second half depends on the drop height by chance (any change
///   to the contact code or the CCD moves it by several a tick), so this case is dropped from
///   eight heights, 0 to 1 mm above the first, and their mean is asserted. Measured on 2026-12-05
///   at the eight heights: 13.8, 13.1, 12.6, 13.0, 15.4, 12.3, 14.1, 14.0 a tick (mean 13.5); with
///   `edge_edge_crossed_from_near` switched off (the broken variant): 59.0, 20.5, 33.3, 58.9,
///   58.2, 38.6, 52.9, 15.5 (mean 42.1). The bound, 25, lies between the means; no height is
///   asserted alone (the broken variant's least, 15.5, is barely above the sound one's most,
///   15.4). Before the obstacle rows of the response's solve started from last tick's impulses
///   (2026-12-05), the sound code answered 33.0 to 60.8 a tick here (mean 43.6), the broken
///   variant 67.2 to 91.4 (mean 77.7).
///
/// No node of either ends a tick below the table, and none is inside the other organ, at any
/// height.
#[test]
fn an_organ_pressed_against_the_table_by_another_is_not_pushed_into_it() {
    // The heavy organ's drop heights above the scene's (m).
    const RAISED: [f64; 8] = [0.0, 1e-5, 2e-5, 5e-5, 1e-4, 2e-4, 5e-4, 1e-3];
    // (name, scene, ticks, the heavy case)
    let mut cases = vec![(
        "default pair".to_string(),
        SOFT_PAIR.to_string(),
        1500,
        false,
    )];
    for dz in RAISED {
        let heavy_at = "position = [0.0, 0.0, 0.11]";
        assert!(HEAVY_ON_FLIMSY.contains(heavy_at));
        let text =
            HEAVY_ON_FLIMSY.replace(heavy_at, &format!("position = [0.0, 0.0, {}]", 0.11 + dz));
        cases.push((
            format!("5 kg on 0.06 kg, {:.2} mm higher", dz * 1e3),
            text,
            1000,
            true,
        ));
    }
    let mut heavy_collisions = Vec::new();
    for (name, text, ticks, heavy) in cases {
        let mut world = World::from_scene(&common::scene(&text));
        let mut lowest = f64::INFINITY;
        let (mut pressed, mut below, mut late_collisions) = (0, 0, 0);
        for k in 1..=ticks {
            world.step();
            if k > ticks / 2 {
                late_collisions += world.counters.bodies.collisions;
            }
            let mut lowest_now = f64::INFINITY;
            for body in &world.bodies {
                for p in &body.surface.position_in_world {
                    lowest_now = lowest_now.min(p.z);
                }
            }
            lowest = lowest.min(lowest_now);
            if lowest_now <= -1e-9 {
                below += 1;
            }
            // The upper organ's nodes reach the table's layer through the flattened lower one.
            let upper = &world.bodies[1].surface.position_in_world;
            if upper.iter().any(|p| p.z < 0.001) {
                pressed += 1;
            }
            if k % 50 == 0 {
                assert_eq!(common::nodes_inside_others(&world), 0, "{name}: tick {k}");
            }
        }
        let collisions_a_tick = late_collisions as f64 / (ticks / 2) as f64;
        println!(
            "{name}: lowest node over {ticks} ticks: {lowest:.3e} m, ticks with a node below the \
             table: {below}; ticks with the upper organ within 1 mm of the table: {pressed}; net \
             collisions a tick over the second half {collisions_a_tick:.1}; {:?}",
            world.counters.bodies
        );
        if heavy {
            heavy_collisions.push(collisions_a_tick);
        } else {
            // Two organs of the default parameters: the net has little to stop there.
            assert!(
                collisions_a_tick < 40.0,
                "{name}: {collisions_a_tick} net collisions a tick"
            );
        }
        assert!(
            pressed > ticks / 3,
            "{name}: the lower organ was not pressed flat: {pressed}"
        );
        assert!(
            lowest > -1e-9,
            "{name}: a node ended a tick {lowest} m into the table ({below} ticks)"
        );
    }
    // Edges of the heavy organ that started on the light one's and ran through them by more than
    // the skin were left to the net, which froze them every tick: 15 to 59 a tick (mean 42).
    let mean = heavy_collisions.iter().sum::<f64>() / heavy_collisions.len() as f64;
    println!(
        "5 kg on 0.06 kg: net collisions a tick over the second half {heavy_collisions:.1?}, mean {mean:.1}"
    );
    assert_eq!(heavy_collisions.len(), RAISED.len());
    assert!(
        mean < 25.0,
        "5 kg on 0.06 kg: {mean} net collisions a tick on average over the heights"
    );
}

/// What [`stacked_pair_pressed`] measures.
struct PairPressed {
    /// The upper organ's largest kinetic energy 0.5 to 1 s after the probe left (J).
    within_a_second: f64,
    /// The same, 3 to 5 s after the probe left (J).
    later: f64,
    /// How far the upper organ's surface reached into the probe while it went down (m).
    deepest_cut: f64,
    /// The largest change of the force fed back from a tick to the next, while the probe went
    /// down, from 10 ms after it struck the organ (N).
    largest_step: f64,
}

/// Two organs stacked (the lower one is pressed flat under the upper, its two sheets closer than
/// the contact skin) and pressed by a probe from 1.5 to 2.5 s (down to `deepest`, m), run to 6.5 s
/// after the probe left (see [`PairPressed`]); asserts that the probe pressed (above 0.5 N), that
/// the collision net has nothing to stop from 0.5 s after the probe left and that no node is ever
/// inside the other organ.
fn stacked_pair_pressed(lift: f64, link_damping: Option<f64>, deepest: f64) -> PairPressed {
    let pair = SOFT_PAIR.replace("0.076]", &format!("{:?}]", 0.076 + lift));
    let pair = match link_damping {
        Some(c) => pair.replace(
            "subdivisions = 2 } }\n",
            &format!("subdivisions = 2 }} }}\n    link_damping = {c:?}\n"),
        ),
        None => pair,
    };
    assert_eq!(
        pair.matches("link_damping").count(),
        if link_damping.is_some() { 2 } else { 0 }
    );
    let text = format!("{pair}\n{}", pressing_probe(0.03, deepest));
    let mut world = World::from_scene(&common::scene(&text));
    let (mut pressed, mut left) = (0.0f64, 0usize);
    let (mut deepest_cut, mut largest_step, mut last) = (0.0f64, 0.0f64, Vec3::zeros());
    let mut first_contact = None;
    let mut kinetic = vec![0.0; 9000];
    for (k, kinetic) in kinetic.iter_mut().enumerate().skip(1) {
        world.step();
        let feedback = world.tools[0].feedback.force_in_world;
        let force = feedback.norm();
        pressed = pressed.max(force);
        if force > 0.0 {
            left = k;
        }
        // The probe going down (from 1.5 to 2 s).
        if (1500..=2000).contains(&k) && force > 0.0 {
            deepest_cut = deepest_cut.max(-common::tool_clearance(&world, 1));
            // From 10 ms after the probe struck the organ (the impact's impulse passed).
            let first = *first_contact.get_or_insert(k);
            if k > first + 10 {
                largest_step = largest_step.max((feedback - last).norm());
            }
        }
        last = feedback;
        *kinetic = world.bodies[1].kinetic_energy();
        if left > 0 && k > left + 500 {
            assert_eq!(
                world.counters.bodies.collisions, 0,
                "net collisions at tick {k}"
            );
        }
        if k % 100 == 0 {
            assert_eq!(common::nodes_inside_others(&world), 0, "tick {k}");
        }
    }
    assert!(
        left > 1500 && left + 5000 < kinetic.len(),
        "the probe left at tick {left}"
    );
    let most = |from: usize, to: usize| {
        kinetic[left + from..left + to]
            .iter()
            .copied()
            .fold(0.0, f64::max)
    };
    let (within_a_second, later) = (most(500, 1000), most(3000, 5000));
    println!(
        "laid {:.2} mm higher: probe pressed up to {pressed:.3} N (the surface at most {:.4} mm into it, force change a tick up to {largest_step:.4} N, going down); upper organ's kinetic energy at most {within_a_second:.2e} J 0.5 to 1 s after the probe left, {later:.2e} J 3 to 5 s after",
        lift * 1e3,
        deepest_cut * 1e3
    );
    assert!(pressed > 0.5, "the probe did not press: {pressed} N");
    PairPressed {
        within_a_second,
        later,
        deepest_cut,
        largest_step,
    }
}

/// Two organs of the default parameters stacked and pressed ([`stacked_pair_pressed`]) come to rest
/// and stay at rest: the upper organ's kinetic energy stays below 1e-6 J from 3 to 5 s after the
/// probe left (1.2e-7 to 1.5e-7 J measured). They take longer than a second: 2.1e-4 to 2.4e-4 J
/// 0.5 to 1 s after the probe left (printed). That bounce of the upper organ's rigid component on
/// the links of its nodes held by the contact loses its energy at about their damping over its mass
/// (3 s⁻¹, the default link damping of 0.05 N·s/m a node): the scene's physics, not the contact's
/// (the damped pair of the next test comes to rest within the second).
/// The pair rested only while the response's solve had not converged: its four sweeps took the
/// obstacle's rows from nothing every tick, so the nodes of the upper organ over the lower one's
/// sheets on the table ended each solve still closing on them, at up to 23 mm/s, parted again
/// afterwards, and kept that velocity without moving: kinetic energy that was no motion, which
/// damped the bounce and, at 3 to 10 s, shook the pair up to 35 µJ again. Warm-started rows
/// converge: 1.2e-7 to 1.5e-7 J here, 3 to 5 s after the probe left (without the rows' warm start the
/// assertion fails).
/// The vertices of the upper organ pressed into the folds of the flattened lower one lie on two or
/// three of its faces; with one contact a vertex (its nearest face) the response pushed them through
/// the others, until a pressed vertex took a contact with each face it crossed (`crossed_too`). And
/// a vertex on the upper sheet, pushed a little into it over the tick, ends nearer the lower sheet,
/// behind which it started: its contact with that sheet pushed it out through the upper one, the
/// net stopped it at its start every tick (0.7 to 19 collisions a tick over five heights),
/// until the response passed over such a face for the next.
#[test]
fn two_soft_organs_stacked_and_pressed_come_to_rest_with_no_net_collision() {
    for lift in [0.0, 2e-5, 1e-4, 3e-4] {
        let PairPressed {
            later,
            deepest_cut,
            largest_step,
            ..
        } = stacked_pair_pressed(lift, None, 0.011);
        assert!(
            later < 1e-6,
            "the upper organ did not stay at rest: {later} J"
        );
        // The probe meets the upper organ's faces at every height: it does not sink between its
        // nodes (2.3 mm of its 6 mm radius while the faces met only tools finer than half of a
        // triangle's circle; on faces alone less than 0.0001 mm now, 0.004 mm before their
        // contacts were taken again in the later sweeps; 0.40 mm where a node it holds is a
        // corner), nor does the contact flicker between that node and the faces round it (0.4 to
        // 2 N from a tick to the next while the faces took a cut near a held corner from the free
        // corners alone; 0.016 N now, the force growing by 0.003 N a tick on average).
        assert!(
            deepest_cut < 0.1 * PROBE_RADIUS,
            "laid {lift} m higher: the surface went {deepest_cut} m into the probe"
        );
        assert!(
            largest_step < 0.05,
            "laid {lift} m higher: the force changed by {largest_step} N in a tick"
        );
    }
}

/// The same pair with four times the default link damping (0.2 N·s/m a node) comes to rest within a
/// second of the probe leaving: the upper organ's kinetic energy stays below 1e-5 J from 0.5 to 1 s
/// after it, and below 1e-8 J from 3 to 5 s, for a press of 0.8 N (the probe down to 15 mm).
/// Until 2026-12-07 the probe went down to 11 mm for the same force: it sank between the upper
/// organ's nodes, its faces meeting only tools finer than half of a triangle's circle. Kept out
/// by them now, it presses 1.33 N at 11 mm, and the pair is not at rest within the second there:
/// 1.44e-5 to 1.46e-5 J 0.5 to 1 s after the probe left (printed; see the README, **Contact between bodies**).
#[test]
fn two_damped_organs_stacked_and_pressed_come_to_rest_within_a_second() {
    for lift in [0.0, 1e-4] {
        let PairPressed {
            within_a_second,
            later,
            ..
        } = stacked_pair_pressed(lift, Some(0.2), 0.015);
        assert!(
            within_a_second < 1e-5,
            "the upper organ did not come to rest within a second: {within_a_second} J"
        );
        assert!(
            later < 1e-8,
            "the upper organ did not stay at rest: {later} J"
        );
    }
    let harder = stacked_pair_pressed(0.0, Some(0.2), 0.011).within_a_second;
    println!("pressed down to 11 mm: {harder:.2e} J 0.5 to 1 s after the probe left (not at rest)");
}

/// An organ ten times as heavy (3 kg) laid on a light one (0.3 kg, the bench's organs; the heavy one
/// the same shape, its masses, stiffnesses and dampings scaled by ten): it stays on the light one's
/// centre, from three drop heights 0.1 mm apart or less, and the collision net has nothing to stop
/// once it has landed (from 1 s on).
/// The light organ's nodes under it are thrown up by their links by more than the skin each
/// tick and end beside the heavy organ's vertices; until the response kept the contacts that start
/// the tick over a face (`started_near`), only the collision net caught them (5 collisions a tick),
/// and the heavy organ crept 26 mm off in 3.5 s.
///
/// The landing is damped (air viscosity 5 N s/m per node, not 1): undamped, the light organ is
/// pressed flat under it and throws the heavy one up by 10 to 20 mm a few times, and whether the
/// heavy one stays on the dome or slides off it (17 to 27 mm, with a friction of 0.4) turns on
/// 10 µm of drop height, in the code before the held contacts as after (see the README, "Ninth
/// session"): such a test passes or fails by chance. Without friction between the bodies this one
/// fails (18 to 66 mm off).
#[test]
fn an_organ_ten_times_heavier_stays_on_the_light_one() {
    let body = |name: &str, z: f64, scale: f64| {
        format!(
            "[[body]]\nname = \"{name}\"\nmesh = {{ ellipsoid = {{ radii = [0.04, 0.03, 0.015], subdivisions = 2 }} }}\nposition = [0.0, 0.0, {z:?}]\nsurface_mass = {:?}\nrigid_mass = {:?}\nsurface_stiffness = {:?}\nsurface_damping = {:?}\nlink_stiffness = {:?}\nlink_damping = {:?}\nfriction = 0.4\n",
            0.1 * scale,
            0.2 * scale,
            100.0 * scale,
            0.05 * scale,
            200.0 * scale,
            0.3 * scale
        )
    };
    for drop in [0.0, 1e-5, 1e-4] {
        let text = format!(
            "[world]\nair_viscosity = 5.0\n[[obstacle]]\nname = \"table\"\nplane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }}\nfriction = 0.5\nstatic_friction = 0.7\n{}{}",
            body("light", 0.0155, 1.0),
            body("heavy", 0.046 + drop, 10.0)
        );
        let mut world = World::from_scene(&common::scene(&text));
        let mut collisions = 0u64;
        for k in 1..=3500 {
            world.step();
            if k > 1000 {
                collisions += u64::from(world.counters.bodies.collisions);
            }
            if k % 50 == 0 {
                assert_eq!(common::nodes_inside_others(&world), 0, "tick {k}");
            }
        }
        let (l, h) = (
            world.bodies[0].surface_centre_of_mass(),
            world.bodies[1].surface_centre_of_mass(),
        );
        let off = (h - l).xy().norm();
        let kinetic: f64 = world.bodies.iter().map(|b| b.kinetic_energy()).sum();
        println!(
            "dropped from {:.3} mm higher: heavy organ {:.1} mm off the light one's centre at 3.5 s (centres at {:.1} and {:.1} mm), kinetic energy {kinetic:.2e} J, net collisions from 1 to 3.5 s {collisions}",
            drop * 1e3,
            off * 1e3,
            l.z * 1e3,
            h.z * 1e3
        );
        assert!(h.z > l.z + 0.01, "the heavy organ left the light one");
        assert!(off < 0.005, "it slid {off} m off the centre");
        assert_eq!(
            collisions, 0,
            "the net stopped what the response let through"
        );
    }
}

#[test]
fn four_stacked_organs_never_enter_each_other_and_the_guard_stays_quiet() {
    // Four soft organs stacked on the table: the bottom one is squashed by the weight of the three
    // above it — elastic energy it receives from them through the contact. That energy is work from
    // outside the body for its divergence guard (as a tool's is): the guard must not take it for a
    // divergence and snap the organ back to its rest shape, into the organ on top of it.
    let text = stack_of_four([0.04, 0.03, 0.015], 0.0155, 0.0305);
    let mut world = World::from_scene(&common::scene(&text));
    let mut squashed: f64 = f64::INFINITY;
    for k in 1..=1500 {
        world.step();
        let bottom = &world.bodies[0].surface.position_in_world;
        let top = bottom.iter().map(|p| p.z).fold(f64::NEG_INFINITY, f64::max);
        squashed = squashed.min(top);
        if k <= 400 && k % 10 == 0 || k % 100 == 0 {
            assert_eq!(common::nodes_inside_others(&world), 0, "tick {k}");
            assert_eq!(common::surfaces_crossing(&world), 0, "tick {k}");
        }
    }
    let events: Vec<u64> = world.guards.iter().map(|g| g.events).collect();
    println!(
        "the bottom organ squashed from 30 to {:.1} mm thick at most; guard events {events:?}",
        squashed * 1e3
    );
    // The stack does press the bottom organ (a third of its height or more).
    assert!(squashed < 0.02, "{squashed}");
    assert_eq!(events, [0, 0, 0, 0]);
}

/// Stacking: four flat organs (10 × 10 × 2 cm) laid one on another on the table stay stacked, in
/// their order, and come to rest (kinetic energy below 1e-5 J at 3.5 s); no node of one is ever
/// inside another. (The four thicker organs of the test above topple, as rigid ones would: the three
/// upper ones' centre of mass stands 4.5 cm over the lowest contact, above the 3 cm a rigid stack
/// of those ellipsoids stays upright with along their short axis — 1/h < 1/ρ₁ + 1/ρ₂, ρ = b²/c =
/// 6 cm; flat organs have ρ = 25 cm.)
#[test]
fn four_flat_organs_stacked_stay_stacked_and_come_to_rest() {
    let text = stack_of_four([0.05, 0.05, 0.01], 0.0105, 0.0205);
    let mut world = World::from_scene(&common::scene(&text));
    for k in 1..=3500 {
        world.step();
        if k % 50 == 0 {
            assert_eq!(common::nodes_inside_others(&world), 0, "tick {k}");
        }
    }
    let centres: Vec<_> = world
        .bodies
        .iter()
        .map(|b| b.surface_centre_of_mass())
        .collect();
    let kinetic: f64 = world.bodies.iter().map(|b| b.kinetic_energy()).sum();
    let drift = centres.iter().map(|c| c.xy().norm()).fold(0.0f64, f64::max);
    println!(
        "four flat organs stacked: centres at heights {:.1?} mm, largest horizontal drift {:.1} mm, kinetic energy {kinetic:.2e} J at 3.5 s, guard events {:?}",
        centres.iter().map(|c| c.z * 1e3).collect::<Vec<_>>(),
        drift * 1e3,
        world.guards.iter().map(|g| g.events).collect::<Vec<_>>()
    );
    for pair in centres.windows(2) {
        // Each organ above the one it was laid on, by more than half an organ's rest thickness.
        assert!(pair[1].z > pair[0].z + 0.01, "out of order: {centres:?}");
    }
    assert!(drift < 0.01, "the stack came apart: {centres:?}");
    assert!(kinetic < 1e-5, "still moving: {kinetic} J");
}

/// Organs placed with their surfaces crossing are found by `World::crossing_surfaces` (what
/// `palpa check`, `run` and `serve` warn of), pair by pair, where the test's own search of every
/// edge against every triangle finds crossings; stacked 0.5 mm apart, none is. And crossed surfaces
/// stay crossed: contact between bodies keeps surfaces from passing through each other, so it
/// cannot part them — why such a scene is warned of.
#[test]
fn organs_placed_crossing_are_found_pair_by_pair_and_stay_crossed() {
    let radii = [0.04, 0.03, 0.015];
    let apart = World::from_scene(&common::scene(&stack_of_four(radii, 0.0155, 0.0305)));
    assert!(
        apart.crossing_surfaces().is_empty(),
        "{:?}",
        apart.crossing_surfaces()
    );
    assert_eq!(common::surfaces_crossing(&apart), 0);
    // 4 mm into each other.
    let mut crossed = World::from_scene(&common::scene(&stack_of_four(radii, 0.0155, 0.026)));
    let found = crossed.crossing_surfaces();
    let pairs: Vec<(usize, usize)> = found.iter().map(|c| c.bodies).collect();
    assert_eq!(pairs, [(0, 1), (1, 2), (2, 3)], "{found:?}");
    for c in &found {
        // Where the lower organ's top meets the upper one's bottom.
        let (lower, upper) = (
            0.0155 + c.bodies.0 as f64 * 0.026,
            0.0155 + c.bodies.1 as f64 * 0.026,
        );
        let z = c.at_in_world.z;
        assert!(z > lower && z < upper, "{c:?}");
        assert!(c.triangle_pairs > 0);
    }
    assert!(common::surfaces_crossing(&crossed) > 0);
    for _ in 0..500 {
        crossed.step();
    }
    assert!(!crossed.crossing_surfaces().is_empty());
    assert!(common::surfaces_crossing(&crossed) > 0);
}

/// A flat organ (8 × 6 × 3 cm, 0.1 kg surface, `upper_rigid_mass` rigid) laid on the middle of a
/// wider one (14 × 10 × 6 cm) resting on the table, `lift` (m) higher than just touching it, both
/// with `integrator`.
fn organ_on_organ(integrator: &str, upper_rigid_mass: f64, lift: f64) -> String {
    let upper_z = 0.0765 + lift;
    format!(
        r#"
        [world]
        gravity = [0.0, 0.0, -9.81]
        air_viscosity = 1.0
        integrator = "{integrator}"
        [[body]]
        name = "lower"
        mesh = {{ ellipsoid = {{ radii = [0.07, 0.05, 0.03], subdivisions = 2 }} }}
        position = [0.0, 0.0, 0.03]
        surface_mass = 0.3
        rigid_mass = 1.0
        surface_stiffness = 200.0
        surface_damping = 0.1
        link_stiffness = 400.0
        link_damping = 0.5
        friction = 0.4
        [[body]]
        name = "upper"
        mesh = {{ ellipsoid = {{ radii = [0.04, 0.03, 0.015], subdivisions = 2 }} }}
        position = [0.0, 0.0, {upper_z:?}]
        surface_mass = 0.1
        rigid_mass = {upper_rigid_mass:?}
        surface_stiffness = 100.0
        surface_damping = 0.05
        link_stiffness = 200.0
        link_damping = 0.3
        friction = 0.4
        [[obstacle]]
        name = "table"
        plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }}
        friction = 0.5
        static_friction = 0.7
    "#
    )
}

/// Four organs (ellipsoids of `radii`) stacked on the table, the lowest centred at `bottom` (m)
/// and each `spacing` (m) above the one below.
fn stack_of_four(radii: [f64; 3], bottom: f64, spacing: f64) -> String {
    let mut text = String::from(
        "[world]\nair_viscosity = 1.0\n[[obstacle]]\nname = \"table\"\nplane = { point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }\nfriction = 0.5\nstatic_friction = 0.7\n",
    );
    let [a, b, c] = radii;
    for k in 0..4 {
        text += &format!(
            "[[body]]\nname = \"organ{k}\"\nmesh = {{ ellipsoid = {{ radii = [{a:?}, {b:?}, {c:?}], subdivisions = 2 }} }}\nposition = [0.0, 0.0, {:?}]\nsurface_mass = 0.1\nrigid_mass = 0.2\nsurface_stiffness = 100.0\nsurface_damping = 0.05\nlink_stiffness = 200.0\nlink_damping = 0.3\nfriction = 0.4\n",
            bottom + k as f64 * spacing
        );
    }
    text
}

/// The response's candidate pairs kept from tick to tick (listed again only where a body left its
/// slack) give the same result bits as pairs listed every tick: a block sliding down a tilted body
/// (it leaves its slack every tick once fast), four flat organs settling into a stack (they come
/// to rest, and the listing stops) and four rounded ones toppling from a tower. Every node's position and velocity is compared after every tick.
/// (Pairs listed every tick have no gaps from a held anchor: the net tests all of them, where the
/// kept lists pass over the pairs of bodies, and the triangle pairs, whose anchor boxes are
/// farther apart than the nodes left them; a triangle pair passed over wrongly changes the net's
/// count of candidate pairs.)
#[test]
fn candidate_pairs_kept_between_ticks_give_the_bits_of_pairs_listed_every_tick() {
    let stack = || {
        World::from_scene(&common::scene(&stack_of_four(
            [0.05, 0.05, 0.01],
            0.0105,
            0.0205,
        )))
    };
    let block = || block_on_tilted_slab(30f64.to_radians(), 0.3);
    // The bench's tower: rounded organs one on another that topple and slide, where the most
    // edges change sides and hold the sides they leave (held contacts, from last tick's list).
    let tower = || {
        World::from_scene(&common::scene(&stack_of_four(
            [0.04, 0.03, 0.015],
            0.0155,
            0.0305,
        )))
    };
    // (name, world, ticks, whether it comes to rest)
    let cases: [(&str, &dyn Fn() -> World, usize, bool); 3] = [
        ("sliding block", &block, 500, false),
        ("stack of four", &stack, 3000, true),
        ("toppling tower", &tower, 1500, false),
    ];
    for (name, make, ticks, rests) in cases {
        let mut kept = make();
        let mut listed = make();
        listed.set_candidate_cache(false);
        let (mut listings_kept, mut listings_every_tick, mut contacts) = (0u64, 0u64, 0u64);
        let (mut late_kept, mut late_every_tick) = (0u64, 0u64);
        for tick in 0..ticks {
            kept.step();
            listed.step();
            listings_kept += u64::from(kept.counters.bodies.listed_pairs);
            listings_every_tick += u64::from(listed.counters.bodies.listed_pairs);
            contacts += u64::from(kept.counters.bodies.contacts);
            if tick >= ticks / 2 {
                late_kept += u64::from(kept.counters.bodies.listed_pairs);
                late_every_tick += u64::from(listed.counters.bodies.listed_pairs);
            }
            assert_eq!(
                kept.counters.bodies,
                {
                    let mut c = listed.counters.bodies;
                    c.listed_pairs = kept.counters.bodies.listed_pairs;
                    c
                },
                "{name}, tick {tick}"
            );
            for (a, b) in kept.bodies.iter().zip(&listed.bodies) {
                let (sa, sb) = (&a.surface, &b.surface);
                for k in 0..sa.position_in_world.len() {
                    for d in 0..3 {
                        assert_eq!(
                            sa.position_in_world[k][d].to_bits(),
                            sb.position_in_world[k][d].to_bits(),
                            "{name}, tick {tick}, node {k}"
                        );
                        assert_eq!(
                            sa.velocity_in_world[k][d].to_bits(),
                            sb.velocity_in_world[k][d].to_bits(),
                            "{name}, tick {tick}, node {k}"
                        );
                    }
                }
            }
        }
        println!(
            "{name}: {contacts} contacts over {ticks} ticks; pairs listed {listings_kept} times kept, \
             {listings_every_tick} times listed every tick ({late_kept} and {late_every_tick} over the \
             second half)"
        );
        assert!(contacts > ticks as u64, "{name}: the bodies barely touch");
        // Kept pairs are listed again when the bodies move (the block gains more than the slack
        // a tick within a tenth of a second), and not once they rest.
        assert!(listings_kept > 1, "{name}");
        if rests {
            assert!(
                late_kept * 10 < late_every_tick,
                "{name}: {late_kept} listings kept against {late_every_tick} over the second half"
            );
        }
    }
}

/// A world cloned mid-run steps on to the same bits as the original: its scratch keeps the room
/// reserved for it (a clone that kept only the lists' contents would find its candidate lists and
/// contact list full and drop contacts). Four flat organs stacked, cloned at 0.3 s, then 0.5 s more.
#[test]
fn a_world_cloned_mid_run_steps_on_to_the_same_bits() {
    let mut world = World::from_scene(&common::scene(&stack_of_four(
        [0.05, 0.05, 0.01],
        0.0105,
        0.0205,
    )));
    for _ in 0..300 {
        world.step();
    }
    let mut copy = world.clone();
    let mut contacts = 0u64;
    for tick in 0..500 {
        world.step();
        copy.step();
        contacts += u64::from(world.counters.bodies.contacts);
        assert_eq!(copy.counters.bodies, world.counters.bodies, "tick {tick}");
        for (a, b) in world.bodies.iter().zip(&copy.bodies) {
            for (p, q) in a
                .surface
                .position_in_world
                .iter()
                .zip(&b.surface.position_in_world)
            {
                for d in 0..3 {
                    assert_eq!(p[d].to_bits(), q[d].to_bits(), "tick {tick}");
                }
            }
        }
    }
    assert!(
        contacts > 500,
        "{contacts} contacts: the organs do not touch"
    );
}

/// A body that may be torn or cut (its scratch keeps room for the pieces it may become) resting on
/// another: the collision net's per-node records of the spare bodies have no body yet, and the net
/// indexed the bodies near with them (a panic, index out of bounds, on the first tick the two came
/// within the skin). Both the tearing and the cutting case rest like any stack, no node inside the
/// other body.
#[test]
fn bodies_that_may_be_torn_or_cut_touch_others_like_any_body() {
    let pair = |extra: &str, tool: &str| {
        format!(
            r#"
            [[obstacle]]
            name = "table"
            plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }}
            [[body]]
            name = "a"
            mesh = {{ ellipsoid = {{ radii = [0.03, 0.025, 0.01], subdivisions = 2 }} }}
            position = [0.0, 0.0, 0.0101]
            surface_mass = 0.05
            rigid_mass = 0.1
            [[body]]
            name = "b"
            mesh = {{ ellipsoid = {{ radii = [0.03, 0.025, 0.01], subdivisions = 2 }} }}
            position = [0.0, 0.0, 0.0305]
            surface_mass = 0.05
            rigid_mass = 0.1
            {extra}
            {tool}
            "#
        )
    };
    let blade_far_away = r#"
        [[tool]]
        name = "scalpel"
        shape = { blade = { length = 0.03, thickness = 0.0005 } }
        script = [ { t = 0.0, position = [0.3, 0.3, 0.3] } ]
    "#;
    for (case, text) in [
        ("tearing", pair("tearing = { strain = 1000.0 }", "")),
        ("cutting", pair("cutting = {}", blade_far_away)),
    ] {
        let mut world = World::from_scene(&common::scene(&text));
        let mut contacts = 0u64;
        for k in 1..=1000 {
            world.step();
            contacts += u64::from(world.counters.bodies.contacts);
            if k % 50 == 0 {
                assert_eq!(common::nodes_inside_others(&world), 0, "{case}, tick {k}");
            }
        }
        let (a, b) = (
            world.bodies[0].surface_centre_of_mass(),
            world.bodies[1].surface_centre_of_mass(),
        );
        println!(
            "{case}: {} bodies, upper organ's centre {:.1} mm above the lower's, {:.1} mm off it; {contacts} contacts over 1 s",
            world.bodies.len(),
            (b - a).z * 1e3,
            (b - a).xy().norm() * 1e3
        );
        assert!(contacts > 1000, "{case}: the bodies never touched");
        assert!(
            (b - a).z > 0.01 && (b - a).xy().norm() < 0.005,
            "{case}: the upper organ left the lower"
        );
    }
}

/// The total momentum of the surface nodes and rigid components of every body (N s).
fn total_momentum(world: &World) -> palpa::Vec3 {
    let mut p = palpa::Vec3::zeros();
    for b in &world.bodies {
        p += common::surface_momentum(b) + b.rigid.velocity_in_world * b.rigid.mass;
    }
    p
}

/// Newton's third law in a collision: two bodies of unequal masses (1.2 and 0.25 kg) thrown at each
/// other in zero gravity, head on at 1 and 2 m/s each way (up to 4 mm a tick closing, past the skin:
/// the collision net answers hundreds of crossings a tick) and off-centre with the heavy one
/// spinning, keep their total momentum through the collision: with the symplectic integrator to
/// rounding (3e-14 N s of 1.9), with the implicit one to 3e-9 (asserted below 1e-8: its linear
/// solve's tolerance). The net used to stop each node of a collision with its own displacement's
/// velocity, which stopped the heavy organ's nodes as often as the light one's: the pair came apart
/// with its total momentum reversed (1.90 to −1.31 N s, symplectic). The multi-rate integrator's
/// sub-stepped nodes end a tick the response pushed them with their displacement's velocity, a
/// reset that is not shared between the two bodies: it lost 5 to 9 % (8.5e-2 N s at 2 m/s with
/// the spin; a lone spinning multi-rate body keeps its momentum to 1e-15). With last tick's contact
/// forces carried into the substeps the reset had less to change: 7.2e-3, 1.4e-2 and 3.4e-2 N s
/// (0.4 to 1.8 %). The variants tried in place of the reset are on the branch
/// `wip/multirate-momentum`. Since those nodes keep their velocity (no reset), and a spring between
/// a sub-stepped node and one that is not gives the two equal and opposite impulses over the step
/// (a lone deforming multi-rate body lost 5.3e-5 N s of 5.3e-2 in 0.3 s, now 8e-17): 1.1e-5,
/// 2.9e-3 and 3.4e-3 N s (0.001 to 0.18 %; asserted below 1e-2, which the code before fails at
/// 1.4e-2 and 3.4e-2).
#[test]
fn two_bodies_colliding_in_zero_gravity_keep_their_total_momentum() {
    let scene = |integrator: &str, speed: f64, spin: f64| {
        format!(
            r#"
            [world]
            gravity = [0.0, 0.0, 0.0]
            integrator = "{integrator}"
            [[body]]
            name = "heavy"
            mesh = {{ ellipsoid = {{ radii = [0.04, 0.03, 0.03], subdivisions = 3 }} }}
            position = [-0.1, 0.0, 0.0]
            velocity = [{speed:?}, 0.0, 0.0]
            angular_velocity = [0.0, 0.0, {spin:?}]
            [[body]]
            name = "light"
            mesh = {{ icosphere = {{ radius = 0.03, subdivisions = 2 }} }}
            position = [0.1, 0.005, 0.0]
            velocity = [{:?}, 0.0, 0.0]
            surface_mass = 0.05
            rigid_mass = 0.2
            "#,
            -speed
        )
    };
    for integrator in ["symplectic", "implicit", "multirate"] {
        for (speed, spin) in [(1.0, 0.0), (2.0, 0.0), (2.0, 20.0)] {
            let mut world = World::from_scene(&common::scene(&scene(integrator, speed, spin)));
            let before = total_momentum(&world);
            let (mut collisions, mut contacts) = (0u64, 0u64);
            for k in 1..=150 {
                world.step();
                collisions += u64::from(world.counters.bodies.collisions);
                contacts += u64::from(world.counters.bodies.contacts);
                if k % 50 == 0 {
                    assert_eq!(common::nodes_inside_others(&world), 0, "tick {k}");
                }
            }
            let after = total_momentum(&world);
            let change = (after - before).norm();
            println!(
                "{integrator}, {speed} m/s, spin {spin} rad/s: momentum {:.4?} -> {:.4?} N s (change {change:.2e}); {contacts} contacts, {collisions} net collisions over 0.15 s; velocities {:.3} and {:.3} m/s",
                before.as_slice(),
                after.as_slice(),
                world.bodies[0].rigid.velocity_in_world.x,
                world.bodies[1].rigid.velocity_in_world.x
            );
            assert!(collisions > 0 && contacts > 0, "they never met");
            let bound = match integrator {
                "symplectic" => 1e-12,
                "implicit" => 1e-8,
                _ => 1e-2,
            };
            assert!(
                change < bound,
                "{integrator}: the momentum changed by {change} N s"
            );
        }
    }
}

/// The divergence guard, restoring a body that touches others, puts its nodes back where they
/// started the step, not onto its rigid component's rest shape: two default organs stacked (the
/// lower one pressed flat by the upper), one node of the lower one given 500 m/s (a glitch past the
/// guard's speed limit): the guard acts, and no node of either organ is inside the other then or
/// over the next half second. Snapped onto its rest shape, the lower organ rose into the upper one
/// (the hard presses of a probe that ended with two organs crossed: the guard had acted).
#[test]
fn the_guard_restoring_an_organ_under_another_leaves_them_uncrossed() {
    let mut world = World::from_scene(&common::scene(SOFT_PAIR));
    for _ in 0..1500 {
        world.step();
    }
    assert_eq!(common::nodes_inside_others(&world), 0);
    let glitch = world.bodies[0].surface.mass.len() / 2;
    world.bodies[0].surface.velocity_in_world[glitch] = palpa::Vec3::new(0.0, 0.0, 500.0);
    world.step();
    assert_eq!(world.counters.guard_events, 1, "the guard did not act");
    let mut worst = common::nodes_inside_others(&world);
    for k in 1..=500 {
        world.step();
        if k % 10 == 0 {
            worst = worst.max(common::nodes_inside_others(&world));
        }
    }
    println!(
        "guard events {:?}; nodes inside the other organ at most {worst}",
        world.guards.iter().map(|g| g.events).collect::<Vec<_>>()
    );
    assert_eq!(worst, 0, "the restore left the organs crossed");
}

/// Two soft organs stacked on the table (a 642-node ellipsoid on a larger one) and an 8 mm probe
/// with no force limit following `script` (the lines of its key frames): the scene of the
/// crushing tests.
fn crushed_stack(script: &str) -> String {
    format!(
        r#"
[[body]]
name = "lower"
mesh = {{ ellipsoid = {{ radii = [0.07, 0.05, 0.03], subdivisions = 3 }} }}
position = [0.0, 0.0, 0.0301]
surface_mass = 0.3
rigid_mass = 1.0
surface_stiffness = 40.0
link_stiffness = 40.0

[[body]]
name = "upper"
mesh = {{ ellipsoid = {{ radii = [0.05, 0.04, 0.02], subdivisions = 3 }} }}
position = [0.0, 0.0, 0.0805]
surface_mass = 0.1
rigid_mass = 0.3
surface_stiffness = 30.0
link_stiffness = 30.0

[[obstacle]]
name = "table"
plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }}

[[tool]]
name = "probe"
shape = {{ sphere = {{ radius = 0.008 }} }}
script = [
{script}]
"#
    )
}

/// Two stacked 642-node organs (1.3 kg, 6 cm thick, under 0.4 kg, 4 cm thick) and a probe of 8 mm
/// radius with no force limit pushed down into the stack until its tip is 1.8 cm below the lower organ's
/// top: the upper organ is squashed through itself (the model has no contact
/// of a body with itself) and the probe holds nodes of both organs at once. A contact between
/// nodes the probe holds, on both sides, and a free node of small weight asked that node to move
/// by the inverse of its weight times the correction: the solve diverged to 1e15 m/s within a tick
/// and the guard acted 21 and 22 times on the two organs (tick 2 002 first). With the contacts'
/// amplification bounded (eight times), the free nodes still reached 19.5 m/s near tick 2 000: such a
/// contact asked them to undo its held nodes' own approach, about 2 m/s where the probe holds nodes
/// anew. Kept only from adding to that approach, no node was faster than 2.4 m/s (asserted below
/// 5 m/s; the probe itself moves at 6 cm/s) and the guard stays quiet. Since the net lets through
/// the collisions of triangles that cross already (2026-12-07), 3.5 m/s: the organs do end up
/// crossed where the probe holds both (README, "Twelfth session"), and those crossed parts now
/// move where they were held. (Undone when the probe lifts: the next test.)
#[test]
fn a_probe_crushing_one_organ_into_another_drives_no_node_to_the_guard() {
    let text = crushed_stack(
        "\
  { t = 0.0, position = [0.0, 0.0, 0.14] },\n\
  { t = 0.5, position = [0.0, 0.0, 0.14] },\n\
  { t = 1.5, position = [0.0, 0.0, 0.07] },\n\
  { t = 2.0, position = [0.0, 0.0, 0.05] },\n\
  { t = 2.5, position = [0.03, 0.0, 0.05] },\n\
",
    );
    let mut world = World::from_scene(&common::scene(&text));
    let (mut fastest, mut pressed) = (0.0f64, 0.0f64);
    for _ in 0..2100 {
        world.step();
        pressed = pressed.max(world.tools[0].feedback.force_in_world.norm());
        for body in &world.bodies {
            for v in &body.surface.velocity_in_world {
                fastest = fastest.max(v.norm());
            }
        }
    }
    let events: Vec<u64> = world.guards.iter().map(|g| g.events).collect();
    println!(
        "probe pressed up to {pressed:.2} N; fastest node {fastest:.1} m/s; guard events {events:?}"
    );
    assert!(
        pressed > 3.0,
        "the probe did not crush the stack: {pressed} N"
    );
    assert_eq!(events, [0, 0], "the guard acted");
    assert!(fastest < 5.0, "a node reached {fastest} m/s");
}

/// The crushing test's stack pressed harder and left: an 8 mm probe with no force limit pushed to
/// 4.5 cm above the table (its tip 1.2 cm into the lower organ), stroked 3 cm sideways, held there
/// until 4 s and lifted clear by 4.5 s. Under the press the probe holds nodes of both organs and
/// drags them through each other's surfaces, which the net cannot stop (it moves no node a tool
/// holds). Before the
/// untangling (`contact/untangle.rs`) the crossing outlived the press for good: 6 nodes of the
/// lower organ inside the upper and 10 of the upper inside the lower from the lift to the end,
/// twelve crossing edge–face pairs, the net answering 25–36 collisions a tick and the ticks
/// taking 2–3 ms. Now the nodes found inside are let out and pushed out, and a collision between
/// triangles that cross already is let through: from a quarter second into the lift no node is
/// inside the other organ, no edge of one passes through a face of the other, and from 5 s the net
/// answers nothing. (At 4 s the probe still holds both organs: whether that tick finds them crossed
/// turns on the press's last ticks — on 2026-12-08, with a budget of 64 boxes a CCD query and the
/// cut before a Newton root of then, 2 nodes and 24 pairs there, 0 by 4.25 s — so it is counted
/// under the press.)
#[test]
fn a_stack_crushed_through_itself_by_a_probe_comes_apart_when_it_lifts() {
    let text = crushed_stack(
        "\
  { t = 0.0, position = [0.0, 0.0, 0.14] },\n\
  { t = 0.5, position = [0.0, 0.0, 0.14] },\n\
  { t = 1.5, position = [0.0, 0.0, 0.07] },\n\
  { t = 2.0, position = [0.0, 0.0, 0.045] },\n\
  { t = 3.0, position = [0.03, 0.0, 0.045] },\n\
  { t = 4.0, position = [0.03, 0.0, 0.045] },\n\
  { t = 4.5, position = [0.03, 0.0, 0.14] },\n\
",
    );
    let mut world = World::from_scene(&common::scene(&text));
    let (mut crossed_under_press, mut inside_after, mut crossing_after) = (0, 0, 0);
    let (mut net_late, mut let_out) = (0u32, 0u32);
    for tick in 1..=6000u32 {
        world.step();
        let_out = let_out.max(world.counters.bodies.inside_nodes);
        if tick >= 5000 {
            net_late += world.counters.bodies.collisions;
        }
        if tick % 250 == 0 {
            let (inside, crossing) = (
                common::nodes_inside_others(&world),
                common::surfaces_crossing(&world),
            );
            if tick <= 4000 {
                crossed_under_press = crossed_under_press.max(inside + crossing);
            } else {
                inside_after = inside_after.max(inside);
                crossing_after = crossing_after.max(crossing);
            }
        }
    }
    let events: Vec<u64> = world.guards.iter().map(|g| g.events).collect();
    println!(
        "under the press: up to {crossed_under_press} nodes inside and crossing pairs; most nodes \
         let out at once {let_out}; from 4.25 s: {inside_after} nodes inside, {crossing_after} \
         crossing pairs; net collisions from 5 s {net_late}; guard events {events:?}"
    );
    // (The press does cross them: what is asserted below is undone, not avoided.)
    assert!(crossed_under_press > 0, "the press crossed nothing");
    assert!(let_out > 0, "no node was let out");
    assert_eq!(
        (inside_after, crossing_after),
        (0, 0),
        "still crossed after the lift"
    );
    assert_eq!(net_late, 0, "the net still answers collisions at rest");
    assert_eq!(events, [0, 0], "the guard acted");
}
