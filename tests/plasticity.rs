//! Plasticity (issue 14): links stretched past `yield` let their homologues flow towards their nodes at
//! `creep` times the excess, at most `max` from their original place, so a press leaves a dent.

mod common;

use palpa::Vec3;
use palpa::dynamics::plasticity::largest_set;
use palpa::world::World;

/// Radius of the organ (m) and of the probe (m).
const ORGAN_RADIUS: f64 = 0.03;
const PROBE_RADIUS: f64 = 0.01;
/// How deep the probe presses below the organ's surface (m).
const PRESS: f64 = 0.008;
/// Times of the press (s): settle, come down, hold, lift, settle again.
const TOUCH: f64 = 0.5;
const DOWN: f64 = 1.0;
const HOLD_END: f64 = 3.0;
const LIFTED: f64 = 3.5;
const END: f64 = 5.5;
/// The probe starts this far above the surface (m).
const CLEARANCE: f64 = 0.005;

/// A fixed organ (its rigid component held, an organ attached to the wall) and a probe on the line
/// through the organ's centre and `top`, pressing `PRESS` deep from `DOWN` to `HOLD_END`.
fn press_scene(top: Vec3, dt: f64, plasticity: &str) -> String {
    let n = top.normalize();
    let at = |depth: f64| n * (ORGAN_RADIUS + PROBE_RADIUS - depth);
    let key =
        |t: f64, p: Vec3| format!("  {{ t = {t}, position = [{}, {}, {}] }},\n", p.x, p.y, p.z);
    let mut script = String::new();
    script += &key(0.0, at(-CLEARANCE));
    script += &key(TOUCH, at(-CLEARANCE));
    script += &key(DOWN, at(PRESS));
    script += &key(HOLD_END, at(PRESS));
    script += &key(LIFTED, at(-CLEARANCE));
    format!(
        r#"
[world]
gravity = [0.0, 0.0, -9.81]
dt = {dt}

[[body]]
name = "organ"
mesh = {{ icosphere = {{ radius = {ORGAN_RADIUS}, subdivisions = 3 }} }}
surface_mass = 0.3
rigid_mass = 1.0
surface_stiffness = 10.0
surface_damping = 0.02
link_stiffness = 300.0
link_damping = 0.3
fixed = true
integrator = "implicit"
{plasticity}

[[tool]]
name = "probe"
shape = {{ sphere = {{ radius = {PROBE_RADIUS} }} }}
input = "script"
script = [
{script}]
"#
    )
}

/// The node farthest along +z of a fresh organ (where the probe presses).
fn top_node(world: &World) -> (usize, Vec3) {
    let s = &world.bodies[0].surface;
    let mut best = 0;
    for i in 0..s.position_in_world.len() {
        if s.position_in_world[i].z > s.position_in_world[best].z {
            best = i;
        }
    }
    (best, s.position_in_world[best])
}

/// Depth of the probe below the organ's original surface on its axis at time `t` (m; negative above).
fn probe_depth(t: f64) -> f64 {
    let lerp = |t0: f64, t1: f64, a: f64, b: f64| a + (b - a) * ((t - t0) / (t1 - t0));
    if t <= TOUCH {
        -CLEARANCE
    } else if t <= DOWN {
        lerp(TOUCH, DOWN, -CLEARANCE, PRESS)
    } else if t <= HOLD_END {
        PRESS
    } else if t <= LIFTED {
        lerp(HOLD_END, LIFTED, PRESS, -CLEARANCE)
    } else {
        -CLEARANCE
    }
}

/// The rule's prediction for the node under the probe: it is held at the probe's depth while the
/// probe is deeper than its homologue's set (the link pulls it back to the set otherwise), and the
/// set flows at `creep` times the excess of the stretch over `yield`, at most `max`; integrated with
/// 10 µs steps of the exact exponential.
fn predicted_set(yield_stretch: f64, creep: f64, max: f64) -> f64 {
    let step = 1e-5;
    let mut set: f64 = 0.0;
    let mut t = 0.0;
    while t < END {
        let stretch = probe_depth(t + 0.5 * step) - set;
        if stretch > yield_stretch {
            set += (stretch - yield_stretch) * -(-creep * step).exp_m1();
            set = set.min(max);
        }
        t += step;
    }
    set
}

struct Pressed {
    /// How far the top node stays in after the probe left (m, along the outward normal).
    dent: f64,
    /// Its homologue's set along the normal (m).
    set: f64,
    /// Largest set of any homologue (m).
    largest: f64,
    /// Homologues that flowed during the whole run (node-ticks).
    flows: u64,
}

fn press(dt: f64, plasticity: &str) -> Pressed {
    let probe = World::from_scene(&common::scene(&press_scene(
        Vec3::new(0.0, 0.0, 1.0),
        dt,
        "",
    )));
    let (top, top_at) = top_node(&probe);
    let n = top_at.normalize();
    let mut world = World::from_scene(&common::scene(&press_scene(top_at, dt, plasticity)));
    assert_eq!(top_node(&world).0, top);
    let ticks = (END / dt).round() as u64;
    let settle = (TOUCH / dt).round() as u64;
    let mut rest = Vec3::zeros();
    let mut flows = 0;
    for tick in 0..ticks {
        if tick == settle {
            rest = world.bodies[0].surface.position_in_world[top];
        }
        world.step();
        flows += world.counters.plastic_flows as u64;
        assert!(
            world.bodies[0].surface.position_in_world[top]
                .iter()
                .all(|v| v.is_finite()),
            "tick {tick}"
        );
    }
    let body = &world.bodies[0];
    Pressed {
        dent: (rest - body.surface.position_in_world[top]).dot(&n),
        set: -body.surface.plastic_offset_in_body[top].dot(&n),
        largest: largest_set(body),
        flows,
    }
}

const PLASTIC: &str = "plasticity = { yield = 0.002, creep = 1.0, max = 0.01 }";

#[test]
fn a_press_past_yield_leaves_the_dent_the_rule_predicts_at_every_step() {
    let predicted = predicted_set(0.002, 1.0, 0.01);
    let coarse = press(0.001, PLASTIC);
    let fine = press(0.0005, PLASTIC);
    println!(
        "8 mm press held 2 s: predicted set {:.4} mm; dt 1 ms: dent {:.4} mm, set {:.4} mm, \
         largest {:.4} mm, {} flows; dt 0.5 ms: dent {:.4} mm, set {:.4} mm",
        predicted * 1e3,
        coarse.dent * 1e3,
        coarse.set * 1e3,
        coarse.largest * 1e3,
        coarse.flows,
        fine.dent * 1e3,
        fine.set * 1e3,
    );
    assert!(coarse.flows > 0);
    for (label, run) in [("1 ms", &coarse), ("0.5 ms", &fine)] {
        assert!(
            (run.dent - predicted).abs() <= 0.05 * predicted,
            "{label}: dent {} mm against the predicted {} mm",
            run.dent * 1e3,
            predicted * 1e3
        );
    }
    assert!(
        (coarse.dent - fine.dent).abs() <= 0.02 * fine.dent,
        "dent at 1 ms {} mm, at 0.5 ms {} mm",
        coarse.dent * 1e3,
        fine.dent * 1e3
    );
}

#[test]
fn the_set_stops_at_max() {
    let max = 0.003;
    let run = press(
        0.001,
        "plasticity = { yield = 0.002, creep = 1.0, max = 0.003 }",
    );
    println!(
        "max 3 mm: set {:.6} mm, largest {:.6} mm, dent {:.4} mm",
        run.set * 1e3,
        run.largest * 1e3,
        run.dent * 1e3
    );
    assert!(
        run.largest <= max * (1.0 + 1e-12),
        "largest set {}",
        run.largest
    );
    assert!(run.set >= max * (1.0 - 1e-9), "set {} below max", run.set);
    assert!(
        (run.dent - max).abs() <= 0.05 * max,
        "dent {} mm",
        run.dent * 1e3
    );
}

#[test]
fn below_yield_nothing_stays() {
    // The same press with the yield above the deepest stretch.
    let run = press(
        0.001,
        "plasticity = { yield = 0.012, creep = 1.0, max = 0.01 }",
    );
    let elastic = press(0.001, "");
    println!(
        "below yield: largest set {:.3e} m, dent {:.3e} m (elastic body: {:.3e} m)",
        run.largest, run.dent, elastic.dent
    );
    assert_eq!(run.flows, 0);
    assert!(run.largest < 1e-6, "set {} m", run.largest);
    assert!(run.dent.abs() < 1e-6, "dent {} m", run.dent);
}

#[test]
fn ten_minutes_without_load_leave_no_set() {
    // An organ held by its rigid component (attached), under its own weight only: its links stretch
    // by m g / k (0.18 mm here), below the 1 mm yield, so nothing may flow in 10 simulated minutes.
    let scene = r#"
[world]
gravity = [0.0, 0.0, -9.81]
dt = 0.001

[[body]]
name = "organ"
mesh = { icosphere = { radius = 0.03, subdivisions = 2 } }
surface_mass = 0.3
rigid_mass = 1.0
surface_stiffness = 40.0
surface_damping = 0.05
link_stiffness = 100.0
link_damping = 0.2
fixed = true
plasticity = { yield = 0.001, creep = 1.0, max = 0.01 }
"#;
    let mut world = World::from_scene(&common::scene(scene));
    let in_body = |world: &World| -> Vec<Vec3> {
        let body = &world.bodies[0];
        let r = &body.rigid;
        body.surface
            .position_in_world
            .iter()
            .map(|x| r.world_from_body.inverse() * (x - r.position_in_world))
            .collect()
    };
    let mut flows = 0u64;
    let mut largest_stretch: f64 = 0.0;
    let mut settled = Vec::new();
    for tick in 0..600_000u64 {
        world.step();
        flows += world.counters.plastic_flows as u64;
        if tick == 4_999 {
            settled = in_body(&world);
        }
        if tick >= 5_000 && tick % 1000 == 0 {
            let body = &world.bodies[0];
            let r = &body.rigid;
            for (x, h) in body
                .surface
                .position_in_world
                .iter()
                .zip(&body.surface.homologue_in_body)
            {
                let stretch = (x - (r.position_in_world + r.world_from_body * h)).norm();
                largest_stretch = largest_stretch.max(stretch);
            }
        }
    }
    let last = in_body(&world);
    let drift = settled
        .iter()
        .zip(&last)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    let set = largest_set(&world.bodies[0]);
    println!(
        "10 min at rest: largest stretch {:.4} mm, {flows} flows, largest set {set:.3e} m, \
         shape drift from 5 s to 600 s {drift:.3e} m",
        largest_stretch * 1e3
    );
    assert!(largest_stretch > 0.0 && largest_stretch < 0.001);
    assert!(set < 1e-6, "set {set} m");
    assert!(drift < 1e-6, "drift {drift} m");
}

/// `scenes/plastic.toml` twice gives the same trace bytes, its recording replays bit for bit, and
/// the set it reports rises during the press and stays after it.
#[test]
fn the_plastic_scene_is_deterministic_and_replays_bit_for_bit() {
    let dir = std::env::temp_dir().join(format!("palpa_plastic_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = common::session_replays(&common::repo_root().join("scenes/plastic.toml"), "5", &dir);
    let set = common::trace_column(&text, "plastic_set");
    let (at_1s, at_3s, last) = (set[1000], set[3000], set[set.len() - 1]);
    println!("plastic.toml: set {at_1s:.3e} m at 1 s, {at_3s:.3e} m at 3 s, {last:.3e} m at 5 s");
    assert!(at_1s < at_3s && at_3s > 0.004 && at_3s <= last && last < 0.01);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Bad `plasticity` keys are refused with the line and what was expected.
#[test]
fn bad_plasticity_keys_are_refused_clearly() {
    for (key, expected) in [
        ("plasticity = { yield = -0.001 }", "`yield`"),
        ("plasticity = { creep = -1.0 }", "`creep`"),
        ("plasticity = { max = -0.01 }", "`max`"),
        ("plasticity = { flow = 1.0 }", "unknown field `flow`"),
    ] {
        common::assert_body_key_refused(key, expected);
    }
}
