//! Self-contact (a body's `self_contact` key): a soft organ dropped, crushed or folded does not
//! pass through itself, and the contact gives the body no energy.

mod common;

use palpa::Vec3;
use palpa::world::World;

/// What a run saw: samples whose surface crossed itself, the most crossings in one sample, the
/// largest rise of the bodies' total energy from one tick to the next (J), and net collisions.
struct Seen {
    crossed_samples: usize,
    most_crossings: usize,
    largest_rise: f64,
    collisions: u64,
    overflows: u64,
    guard_events: u32,
    /// Times a body was listed again between two rounds of the net, and ticks that ended with a
    /// listing that did not hold.
    listed_again: u64,
    unlisted: u64,
}

fn run(world: &mut World, ticks: usize, every: usize) -> Seen {
    let gravity = Vec3::new(0.0, 0.0, -9.81);
    let mut seen = Seen {
        crossed_samples: 0,
        most_crossings: 0,
        largest_rise: f64::NEG_INFINITY,
        collisions: 0,
        overflows: 0,
        guard_events: 0,
        listed_again: 0,
        unlisted: 0,
    };
    let mut energy = common::total_energy(&world.bodies, &gravity);
    for tick in 1..=ticks {
        world.step();
        let now = common::total_energy(&world.bodies, &gravity);
        seen.largest_rise = seen.largest_rise.max(now - energy);
        energy = now;
        seen.collisions += u64::from(world.counters.bodies.collisions);
        seen.overflows += u64::from(world.counters.bodies.overflows);
        seen.guard_events += world.counters.guard_events;
        seen.listed_again += u64::from(world.counters.bodies.self_listed_again);
        seen.unlisted += u64::from(world.counters.bodies.self_unlisted);
        if tick % every == 0 {
            let crossings: usize = world.bodies.iter().map(common::self_crossings).sum();
            seen.crossed_samples += usize::from(crossings > 0);
            seen.most_crossings = seen.most_crossings.max(crossings);
        }
    }
    seen
}

/// What self-contact must give `what`: no sample crossed, no list full, every tick's far listing
/// holding for the trajectories the net left, no guard event, and an energy that never rises from
/// one tick to the next (beyond rounding).
fn assert_held(seen: &Seen, what: &str) {
    assert_eq!(seen.crossed_samples, 0, "{what} crossed itself");
    assert_eq!(
        seen.unlisted, 0,
        "{what}: the net left trajectories its far listing does not hold"
    );
    assert_eq!(seen.overflows, 0, "{what}: a list was full");
    assert_eq!(seen.guard_events, 0, "{what}: the guard stepped in");
    assert!(
        seen.largest_rise <= 1e-9,
        "{what}: the energy rose by {} J in a tick",
        seen.largest_rise
    );
}

/// A ball of the default parameters (radius 2 cm) dropped from 0.5 m onto the table: it lands at
/// 3.1 m/s and flattens until its top meets its bottom.
fn dropped_ball(self_contact: bool) -> World {
    World::from_scene(&common::dropped_ball(self_contact))
}

/// Measured (2026-12-05): without self-contact the ball's top passes through its bottom at the
/// landing (6 samples of 140 crossed, at most 920 edge–triangle crossings); with it none crosses
/// (8 608 net collisions over the 0.7 s), and the energy falls at every tick either way.
/// With it the body is listed again between rounds 37 times on 25 ticks (2026-12-05, later).
#[test]
fn a_soft_ball_dropped_on_the_table_does_not_pass_through_itself() {
    let without = run(&mut dropped_ball(false), 700, 5);
    let with = run(&mut dropped_ball(true), 700, 5);
    println!(
        "without self-contact: {} samples crossed (at most {} crossings), largest energy rise {:e} J; with: {} crossed, {} net collisions, {} overflows, listed again {} times, largest rise {:e} J",
        without.crossed_samples,
        without.most_crossings,
        without.largest_rise,
        with.crossed_samples,
        with.collisions,
        with.overflows,
        with.listed_again,
        with.largest_rise
    );
    // The case is one where the surface does fold through itself.
    assert!(without.crossed_samples > 0 && without.most_crossings > 100);
    assert!(with.collisions > 0, "self-contact never answered");
    assert_held(&with, "the ball");
    // A node the net moves may leave its centred trajectory by more than the far listing's
    // slack: the body is then listed again between rounds, and every tick ends with a listing
    // that holds. At 3.1 m/s a node stopped short did so 37 times (without listing again, 25
    // ticks did not hold); the net's impulses (2026-12-06) leave it less often: not at all from
    // 0.5 m, twice from 3 m (7.7 m/s at the landing), the case that keeps the path tested.
    let mut from_high = World::from_scene(&common::scene(
        &common::scene_text_of_dropped_ball(true).replace("0.5]", "3.0]"),
    ));
    let high = run(&mut from_high, 1200, 5);
    println!(
        "from 3 m: {} crossed, {} net collisions, listed again {} times",
        high.crossed_samples, high.collisions, high.listed_again
    );
    assert!(high.listed_again > 0, "the case no longer leaves the slack");
    assert_held(&high, "the ball dropped from 3 m");
}

/// The same bits on every run, and from a world cloned mid-run.
#[test]
fn self_contact_gives_the_same_bits_every_run() {
    let bits = |world: &World| -> Vec<u64> {
        world.bodies[0]
            .surface
            .position_in_world
            .iter()
            .flat_map(|p| p.iter().map(|c| c.to_bits()).collect::<Vec<_>>())
            .collect()
    };
    let mut first = dropped_ball(true);
    for _ in 0..330 {
        first.step();
    }
    let mut copy = first.clone();
    let mut second = dropped_ball(true);
    for _ in 0..330 {
        second.step();
    }
    assert_eq!(bits(&first), bits(&second));
    for _ in 0..20 {
        first.step();
        copy.step();
    }
    assert!(first.counters.bodies.collisions > 0, "not in self-contact");
    assert_eq!(bits(&first), bits(&copy));
}

/// The shipped liver (`scenes/liver.toml`, the SOFA liver mesh, 1 170 nodes, soft) dropped onto the
/// table: its thin lobes fold through each other on landing without self-contact (measured: 12 of
/// 40 samples over 0.4 s, at most 65 crossings); with it, none of 100 over a second, and the
/// energy falls at every tick.
#[test]
fn the_shipped_liver_with_self_contact_lands_without_folding_through_itself() {
    if common::shared_dir().is_none() {
        return;
    }
    let mut scene = palpa::load_scene(&common::repo_root().join("scenes/liver.toml"))
        .unwrap_or_else(|e| panic!("{e}"));
    let without = run(&mut World::from_scene(&scene), 400, 10);
    scene.bodies[0].params.self_contact = true;
    let with = run(&mut World::from_scene(&scene), 1000, 10);
    println!(
        "liver without self-contact: {} samples of 40 crossed (at most {}); with: {} of 100, {} net collisions, {} overflows, largest energy rise {:e} J",
        without.crossed_samples,
        without.most_crossings,
        with.crossed_samples,
        with.collisions,
        with.overflows,
        with.largest_rise
    );
    assert!(without.crossed_samples > 0, "the case no longer folds");
    assert_held(&with, "the liver");
}

/// A body whose topology changes under the tool (`scenes/probe_refine.toml`: adaptive subdivision
/// under a probe) with self-contact on: the lists follow the new triangles, with no overflow and
/// no crossing.
#[test]
fn self_contact_follows_subdivision() {
    let mut scene = palpa::load_scene(&common::repo_root().join("scenes/probe_refine.toml"))
        .unwrap_or_else(|e| panic!("{e}"));
    scene.bodies[0].params.self_contact = true;
    let mut world = World::from_scene(&scene);
    let seen = run(&mut world, 2000, 50);
    let version = world.bodies[0].topology_version;
    println!(
        "probe_refine: topology version {version}, {} triangles; {} samples crossed, {} overflows, {} guard events",
        world.bodies[0].surface.triangles.len(),
        seen.crossed_samples,
        seen.overflows,
        seen.guard_events
    );
    assert!(version > 0, "no topology change");
    assert_eq!(seen.overflows, 0);
    assert_eq!(seen.crossed_samples, 0);
    assert_eq!(seen.guard_events, 0);
}

/// Self-contact with cutting or tearing is refused where it is written (the two sides of a cut
/// start touching, which the net would answer as a collision at every tick: measured on
/// `scenes/incision.toml`, 1 600 net collisions a tick).
#[test]
fn self_contact_with_cutting_or_tearing_is_refused() {
    for extra in ["cutting = {}", "tearing = { strain = 0.5 }"] {
        let text = format!(
            r#"
            [[body]]
            name = "organ"
            mesh = {{ icosphere = {{ radius = 0.03, subdivisions = 2 }} }}
            {extra}
            self_contact = true
            "#
        );
        let error = palpa::parse_scene(&text, "organ.toml", &common::repo_root())
            .err()
            .unwrap_or_else(|| panic!("{extra}: accepted"))
            .to_string();
        assert!(
            error.contains("organ.toml:6:")
                && error.contains("`self_contact` cannot be combined with `cutting` or `tearing`"),
            "{extra}: {error}"
        );
    }
}

/// Two balls, one dropped from 0.3 m onto the other resting on the table: the body–body net and
/// each body's own pairs in the same rounds. Measured (2026-12-05): without self-contact the balls'
/// surfaces cross themselves (26 653 edge–triangle crossings over 60 samples) and a tick gained up
/// to 0.42 J; with it, no crossing, no node of one inside the other, and the largest gain in a tick
/// was 8.0e-4 J (the net stopped collisions short with the nodes' mean velocity, which fed a
/// contact it held at every tick). Since the net answers with inelastic impulses (2026-12-06),
/// no tick gains energy in either run (largest change of a tick −9.8e-5 J without self-contact);
/// without self-contact the surfaces still cross themselves (7 594 crossings): asserted below
/// 1e-6 J a tick in both runs.
#[test]
fn a_ball_dropped_on_another_with_self_contact_enters_neither_it_nor_itself() {
    let run = |self_contact: bool| {
        let mut world = World::from_scene(&common::scene(&format!(
            r#"
            [world]
            gravity = [0.0, 0.0, -9.81]
            [[body]]
            name = "lower"
            mesh = {{ ellipsoid = {{ radii = [0.03, 0.03, 0.015], subdivisions = 3 }} }}
            position = [0.0, 0.0, 0.0151]
            self_contact = {self_contact}
            [[body]]
            name = "upper"
            mesh = {{ ellipsoid = {{ radii = [0.02, 0.02, 0.02], subdivisions = 3 }} }}
            position = [0.005, 0.0, 0.3]
            self_contact = {self_contact}
            [[obstacle]]
            name = "table"
            plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }}
            "#
        )));
        let gravity = Vec3::new(0.0, 0.0, -9.81);
        let mut energy = common::total_energy(&world.bodies, &gravity);
        let (mut rise, mut contacts, mut inside, mut crossed, mut overflows) =
            (f64::NEG_INFINITY, 0u64, 0, 0, 0u64);
        for tick in 1..=600 {
            world.step();
            let now = common::total_energy(&world.bodies, &gravity);
            rise = rise.max(now - energy);
            energy = now;
            contacts += u64::from(world.counters.bodies.contacts);
            overflows += u64::from(world.counters.bodies.overflows);
            if tick % 10 == 0 {
                inside += common::nodes_inside_others(&world);
                crossed += world
                    .bodies
                    .iter()
                    .map(common::self_crossings)
                    .sum::<usize>();
            }
        }
        println!(
            "two balls, self-contact {self_contact}: {contacts} contacts, {inside} nodes inside the other and {crossed} self-crossings over 60 samples, {overflows} overflows, largest energy rise {rise:e} J"
        );
        assert!(contacts > 0, "they never met");
        (inside, crossed, overflows, rise)
    };
    let (_, crossed_without, _, rise_without) = run(false);
    assert!(crossed_without > 0, "the case no longer crosses");
    assert!(
        rise_without < 1e-6,
        "without self-contact the energy rose by {rise_without} J in a tick"
    );
    let (inside, crossed, overflows, rise) = run(true);
    assert_eq!(inside, 0);
    assert_eq!(crossed, 0);
    assert_eq!(overflows, 0);
    assert!(rise < 1e-6, "the energy rose by {rise} J in a tick");
}

/// Self-contact keeps the body's momentum: the ball of `dropped_ball` (0.5 m, lands at 3.1 m/s)
/// on a frictionless table, dropped straight down, 2 s. Nothing outside the body pushes it
/// sideways, so its horizontal momentum must stay what it was: zero. The net used to stop a fold's
/// nodes with their own shortened displacements' velocities, which does not keep momentum: the
/// ball left its landing with 0.19 N s of horizontal momentum (of 1.6 N s it lands with) and
/// glided off (2026-12-06). Its inelastic impulses keep the four nodes' momentum; the table takes
/// the share of a node the impulse would push behind it (it holds such a node). Measured
/// (2026-12-06): at most 3.4e-3 N s over the 2 s, the centre 4.5 mm off its axis; asserted below
/// 1e-2 N s, and no crossing.
#[test]
fn a_ball_folding_on_itself_on_a_frictionless_table_keeps_its_horizontal_momentum() {
    let text = format!(
        "{}\nfriction = 0.0\nstatic_friction = 0.0\n",
        include_str!("../scenes/self_fold.toml")
            .lines()
            .filter(|l| !l.starts_with("friction") && !l.starts_with("static_friction"))
            .collect::<Vec<_>>()
            .join("\n")
    );
    let mut world = World::from_scene(&common::scene(&text));
    assert!(
        world.bodies[0].params.self_contact_on(),
        "the shipped scene has self-contact on"
    );
    let (mut most, mut collisions, mut crossed) = (0.0f64, 0u64, 0);
    for tick in 1..=2000 {
        world.step();
        collisions += u64::from(world.counters.bodies.collisions);
        let b = &world.bodies[0];
        let p = common::surface_momentum(b) + b.rigid.velocity_in_world * b.rigid.mass;
        most = most.max((p.x * p.x + p.y * p.y).sqrt());
        if tick % 20 == 0 {
            crossed += common::self_crossings(b);
        }
    }
    let centre = world.bodies[0].rigid.position_in_world;
    println!(
        "self-folding ball on a frictionless table: most horizontal momentum {most:.3e} N s, \
         centre {:.2} mm off its axis after 2 s, {collisions} net collisions, {crossed} crossings",
        (centre.x * centre.x + centre.y * centre.y).sqrt() * 1e3
    );
    assert!(collisions > 0, "the ball never folded onto itself");
    assert_eq!(crossed, 0);
    assert!(most < 1e-2, "horizontal momentum {most} N s");
}
