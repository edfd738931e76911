//! Tearing (issue 14): a surface spring stretched past `strain` breaks and the surface opens there
//! with the cut's topology machinery; a bounded number per tick, in a fixed order.

mod common;

use palpa::Vec3;
use palpa::contact::tool::{JawHold, ToolContact};
use palpa::topology::cut::check_surface;
use palpa::world::World;

/// Total mass and momentum of every body.
fn totals(world: &World) -> (f64, Vec3) {
    let mut mass = 0.0;
    let mut momentum = Vec3::zeros();
    for b in &world.bodies {
        mass += b.total_mass();
        momentum += b.rigid.velocity_in_world * b.rigid.mass;
        for (v, m) in b.surface.velocity_in_world.iter().zip(&b.surface.mass) {
            momentum += v * *m;
        }
    }
    (mass, momentum)
}

/// Holds nodes `held` in the grasper's frame (tool 0), as closed jaws holding them would.
fn hold(world: &mut World, held: &[usize]) {
    let pose = world.tools[0].pose;
    for &i in held {
        let p = world.bodies[0].surface.position_in_world[i];
        world.bodies[0].surface.tool_contact[i] = ToolContact {
            tool: 0,
            part: 0,
            point_in_tool: pose.to_tool(&p),
            grasp: Some(JawHold {
                side: 0.0,
                half_opening: 0.0,
            }),
        };
    }
    world.tools[0].grasping = true;
}

/// A sheet (a 10 cm × 10 cm × 4 mm box, 1 cm grid on its faces) held by stiff links to its fixed
/// rigid component, pulled up from the centre node of its top face at 5 mm/s from t = 0.1 s.
fn sheet(tearing: &str) -> String {
    format!(
        r#"
[world]
gravity = [0.0, 0.0, 0.0]
dt = 0.001

[[body]]
name = "sheet"
mesh = {{ box = {{ size = [0.1, 0.1, 0.004], subdivisions = 9 }} }}
surface_mass = 0.05
rigid_mass = 1.0
surface_stiffness = 5.0
surface_damping = 0.01
link_stiffness = 2000.0
link_damping = 0.5
fixed = true
integrator = "implicit"
{tearing}

[[tool]]
name = "grasper"
shape = {{ grasper = {{ jaw_length = 0.004, radius = 0.0005 }} }}
input = "script"
script = [
  {{ t = 0.0, position = [0.0, 0.0, 0.002], orientation = [1.0, 0.0, 0.0, 0.0], jaw = 0.0 }},
  {{ t = 0.1, position = [0.0, 0.0, 0.002], orientation = [1.0, 0.0, 0.0, 0.0], jaw = 0.0 }},
  {{ t = 4.1, position = [0.0, 0.0, 0.022], orientation = [1.0, 0.0, 0.0, 0.0], jaw = 0.0 }},
]
"#
    )
}

#[test]
fn a_sheet_pulled_from_its_centre_tears_at_the_predicted_displacement() {
    let strain: f64 = 0.3;
    let mut world = World::from_scene(&common::scene(&sheet(&format!(
        "tearing = {{ strain = {strain} }}"
    ))));
    let body = &world.bodies[0];
    // The centre node of the top face.
    let centre = (0..body.node_count())
        .min_by(|&a, &b| {
            let d = |i: usize| {
                let p = body.surface.position_in_world[i];
                p.x * p.x + p.y * p.y - p.z
            };
            d(a).total_cmp(&d(b))
        })
        .unwrap();
    let start = body.surface.position_in_world[centre];
    assert!(start.z > 0.0019 && start.x.abs() < 1e-9 && start.y.abs() < 1e-9);
    // The prediction: the neighbours held by their links, the centre's shortest spring (rest L)
    // reaches the strain when the centre has risen by L √((1 + strain)² − 1).
    let e = &body.edges;
    let shortest = (0..e.len())
        .filter(|&k| e.a[k] as usize == centre || e.b[k] as usize == centre)
        .map(|k| e.rest_length[k])
        .fold(f64::INFINITY, f64::min);
    let predicted = shortest * ((1.0 + strain) * (1.0 + strain) - 1.0).sqrt();
    hold(&mut world, &[centre]);
    let (mass0, _) = totals(&world);
    let mut first_tear = None;
    for _ in 0..4200 {
        let (mass_before, _) = totals(&world);
        // Where the held node is as the tick starts (a tear that separates a piece renumbers nodes).
        let height = world.bodies[0].surface.position_in_world[centre].z;
        world.step();
        let (mass_after, _) = totals(&world);
        if world.counters.tears > 0 {
            assert!(
                (mass_after - mass_before).abs() <= 1e-12 * mass_before,
                "mass {mass_before} → {mass_after} at a tear"
            );
            for b in &world.bodies {
                check_surface(b).unwrap();
            }
            if first_tear.is_none() {
                first_tear = Some(height - start.z);
            }
        }
    }
    let risen = first_tear.expect("the sheet did not tear");
    let boundary: u32 = world.bodies.iter().map(|b| b.boundary_edges).sum();
    println!(
        "sheet: shortest spring {:.3} mm, predicted tear at {:.4} mm, tore at {:.4} mm ({:+.2} %); \
         {} boundary edges, {} bodies; mass {mass0} → {}",
        shortest * 1e3,
        predicted * 1e3,
        risen * 1e3,
        100.0 * (risen / predicted - 1.0),
        boundary,
        world.bodies.len(),
        totals(&world).0
    );
    assert!(
        (risen - predicted).abs() <= 0.02 * predicted,
        "tore at {risen} m, predicted {predicted} m"
    );
    // The tear opened the surface (lips left) or punched the held patch out (a piece of its own).
    assert!(boundary > 0 || world.bodies.len() > 1);
    assert!((totals(&world).0 - mass0).abs() <= 1e-12 * mass0);
}

/// An organ held in place (fixed rigid component) pulled up by a grasper holding the nodes at its top.
fn pulled_organ(tearing: &str) -> String {
    format!(
        r#"
[world]
gravity = [0.0, 0.0, -9.81]
dt = 0.001

[[body]]
name = "organ"
mesh = {{ icosphere = {{ radius = 0.03, subdivisions = 3 }} }}
surface_mass = 0.2
rigid_mass = 1.0
surface_stiffness = 40.0
surface_damping = 0.05
link_stiffness = 200.0
link_damping = 0.2
fixed = true
integrator = "implicit"
{tearing}

[[tool]]
name = "grasper"
shape = {{ grasper = {{ jaw_length = 0.006, radius = 0.001 }} }}
input = "script"
script = [
  {{ t = 0.0, position = [0.0, 0.0, 0.031], orientation = [1.0, 0.0, 0.0, 0.0], jaw = 0.0 }},
  {{ t = 0.1, position = [0.0, 0.0, 0.031], orientation = [1.0, 0.0, 0.0, 0.0], jaw = 0.0 }},
  {{ t = 3.1, position = [0.0, 0.0, 0.061], orientation = [1.0, 0.0, 0.0, 0.0], jaw = 0.0 }},
]
"#
    )
}

struct Pull {
    /// Vertical feedback force each tick (N, the tissue pulling the grasper down: negative).
    force: Vec<f64>,
    /// First tick a spring tore, if any.
    first_tear: Option<usize>,
    boundary: u32,
    bodies: usize,
    /// Largest rise of the total energy over a tear tick beyond the tool's work (J), on ticks
    /// without and with a transection.
    worst_gain: f64,
    worst_transection_gain: f64,
}

fn pull(tearing: &str) -> Pull {
    let mut world = World::from_scene(&common::scene(&pulled_organ(tearing)));
    let body = &world.bodies[0];
    let held: Vec<usize> = (0..body.node_count())
        .filter(|&i| body.surface.position_in_world[i].z > 0.0285)
        .collect();
    assert!(held.len() >= 3, "{} nodes held", held.len());
    hold(&mut world, &held);
    let mut force = Vec::new();
    let mut first_tear = None;
    let mut worst_gain = f64::NEG_INFINITY;
    let mut worst_transection_gain = f64::NEG_INFINITY;
    let gravity = world.params.gravity;
    let energy = |world: &World| common::total_energy(&world.bodies, &gravity);
    for tick in 0..3200 {
        let (mass_before, _) = totals(&world);
        let before = energy(&world);
        world.step();
        force.push(world.tools[0].feedback.force_in_world.z);
        if world.counters.tears > 0 {
            first_tear.get_or_insert(tick);
            let (mass_after, _) = totals(&world);
            assert!((mass_after - mass_before).abs() <= 1e-12 * mass_before);
            for b in &world.bodies {
                check_surface(b).unwrap();
            }
            // The tool's work this tick: the tissue's force on it along its motion, reversed.
            let t = &world.tools[0];
            let work = -t
                .feedback
                .force_in_world
                .dot(&(t.pose.position_in_world - t.previous_pose.position_in_world));
            let gain = energy(&world) - before - work.abs();
            if world.counters.transections == 0 {
                worst_gain = worst_gain.max(gain);
            } else {
                worst_transection_gain = worst_transection_gain.max(gain);
            }
        }
    }
    Pull {
        force,
        first_tear,
        boundary: world.bodies.iter().map(|b| b.boundary_edges).sum(),
        bodies: world.bodies.len(),
        worst_gain,
        worst_transection_gain,
    }
}

#[test]
fn a_grasper_pulling_an_organ_tears_it_and_the_force_drops() {
    let torn = pull("tearing = { strain = 0.4 }");
    let whole = pull("");
    let tick = torn.first_tear.expect("nothing tore");
    // The felt pull (the tissue drags the grasper down: −z).
    let pull_at = |p: &Pull, t: usize| -p.force[t];
    let peak = (0..=tick).map(|t| pull_at(&torn, t)).fold(0.0, f64::max);
    // The release: the least pull within 0.5 s after the first tear.
    let after = (tick..tick + 500)
        .map(|t| pull_at(&torn, t))
        .fold(f64::INFINITY, f64::min);
    let untorn = pull_at(&whole, tick + 500);
    println!(
        "organ pulled 3 cm: first tear at tick {tick} (pull {:.3} N), peak {:.3} N, least within \
         0.5 s after {:.3} N ({} boundary edges, {} bodies at the end; largest energy gain over a \
         tear {:.3e} J, over a tear that separated a piece {:.3e} J); without tearing: {:.3} N \
         0.5 s after, {} boundary edges",
        pull_at(&torn, tick),
        peak,
        after,
        torn.boundary,
        torn.bodies,
        torn.worst_gain,
        torn.worst_transection_gain,
        untorn,
        whole.boundary
    );
    assert!(whole.first_tear.is_none() && whole.boundary == 0 && whole.bodies == 1);
    // The held top tore round the jaws and came away (a closed piece of its own).
    assert!(torn.bodies >= 2, "no piece came apart");
    // Rise, then release: within 0.5 s of the first tear the pull falls well below its peak, and
    // below the same pull on the organ that does not tear.
    assert!(peak > 0.5, "peak {peak} N");
    assert!(after < 0.7 * peak, "after {after} N, peak {peak} N");
    assert!(after < 0.5 * untorn, "after {after} N, untorn {untorn} N");
    // The piece that came away is not flung at the jaws: its rigid component starts where its links
    // balance (a push back of at most a quarter of the peak pull).
    assert!(after > -0.25 * peak, "rebound {after} N, peak {peak} N");
    assert!(
        torn.worst_gain <= 1e-9,
        "energy gained at a tear: {} J",
        torn.worst_gain
    );
    assert!(
        torn.worst_transection_gain <= 1e-9,
        "energy gained at a tear that separated a piece: {} J",
        torn.worst_transection_gain
    );
}

/// Bad `tearing` keys are refused with the line and what was expected.
#[test]
fn bad_tearing_keys_are_refused_clearly() {
    for (key, expected) in [
        ("tearing = { strain = 0.0 }", "`strain`"),
        ("tearing = { ticks = 0 }", "`ticks`"),
        ("tearing = { max_per_tick = 1000 }", "`max_per_tick`"),
        ("tearing = { snap = 1.0 }", "unknown field `snap`"),
    ] {
        common::assert_body_key_refused(key, expected);
    }
}

/// `scenes/tear.toml`: the closing jaws grasp the organ's top, the pull tears round the jaws (edges
/// open, shreds become bodies, the pull drops at a tear) until the grasped tissue comes away in the
/// jaws and the pull falls to its weight; mass conserved, the surface a manifold and no orphan node
/// at every tick, no negative energy; and the session replays bit for bit.
#[test]
fn the_tear_scene_grasps_pulls_and_tears_and_replays_bit_for_bit() {
    let path = common::repo_root().join("scenes/tear.toml");
    let scene = palpa::scene::load_scene(&path).unwrap_or_else(|e| panic!("{e}"));
    let mut world = World::from_scene(&scene);
    let (mass_before, _) = totals(&world);
    let mut grasped = 0;
    let mut pull: Vec<f64> = Vec::new();
    let mut tear_ticks = Vec::new();
    let mut tears = 0;
    for tick in 0..2500 {
        world.step();
        let tool = &world.tools[0];
        grasped = grasped.max(tool.feedback.grasped);
        pull.push(-tool.feedback.force_in_world.z);
        // The step's counters: springs torn this tick.
        if world.counters.tears > 0 {
            tears += world.counters.tears;
            if world.tools[0].grasping {
                tear_ticks.push(tick);
            }
            let (mass, _) = totals(&world);
            assert!((mass - mass_before).abs() <= 1e-12 * mass_before);
            for b in &world.bodies {
                check_surface(b).unwrap_or_else(|e| panic!("{}: {e}", b.name));
            }
        }
        for b in &world.bodies {
            assert!(
                b.kinetic_energy() >= 0.0,
                "{}: negative kinetic energy",
                b.name
            );
        }
    }
    // Rise, then release: the largest fall of the pull within 50 ms of a tear, against the pull
    // just before it.
    let largest_drop = tear_ticks
        .iter()
        .filter(|&&t| t >= 1)
        .map(|&t| {
            let least = pull[t..(t + 50).min(pull.len())]
                .iter()
                .fold(f64::INFINITY, |a, &b| a.min(b));
            pull[t - 1] - least
        })
        .fold(0.0, f64::max);
    let peak = pull.iter().fold(0.0f64, |a, &b| a.max(b));
    let end = *pull.last().unwrap();
    let held_weight: f64 = world
        .bodies
        .iter()
        .filter(|b| b.surface.tool_contact.iter().any(|c| c.grasp.is_some()))
        .map(|b| b.total_mass() * 9.81)
        .sum();
    let boundary: u32 = world.bodies.iter().map(|b| b.boundary_edges).sum();
    println!(
        "tear.toml 2.5 s: {grasped} nodes grasped, {} tears, {boundary} boundary edges, {} bodies, \
         peak pull {peak:.3} N, largest drop within 50 ms of a tear {largest_drop:.3} N, pull at \
         2.5 s {end:.3} N (weight of the bodies in the jaws {held_weight:.3} N)",
        tears,
        world.bodies.len(),
    );
    assert!(grasped >= 4, "{grasped} nodes grasped");
    assert!(world.bodies.len() >= 2);
    assert!(largest_drop > 0.5, "no drop of the pull at a tear");
    // The grasped tissue came away: the organ holds no grasped node, the jaws hold pieces, and the
    // pull is their weight.
    assert!(
        world.bodies[0]
            .surface
            .tool_contact
            .iter()
            .all(|c| c.grasp.is_none()),
        "the organ is still held"
    );
    assert!(held_weight > 0.0);
    assert!(
        end < 0.2 * peak && (end - held_weight).abs() < 0.2 * held_weight,
        "pull {end} N at the end, peak {peak} N, held weight {held_weight} N"
    );
    let dir = std::env::temp_dir().join(format!("palpa-tear-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let trace = common::session_replays(&path, "2.5", &dir);
    assert!(
        common::trace_column(&trace, "boundary_edges")
            .iter()
            .any(|&b| b > 0.0)
    );
    assert!(
        common::trace_column(&trace, "guard_events")
            .iter()
            .all(|&g| g == 0.0)
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Random pulls (meshes, held patches, directions, thresholds, per-tick bounds, integrators, held or
/// free organs): at every tick that tears, every body is an oriented manifold with no orphan node,
/// mass is conserved to 1e-12 and the energy does not grow beyond the tool's work; every state and
/// feedback stays finite.
#[test]
fn random_pulls_keep_every_invariant() {
    let mut rng = common::Rng(common::env_or("PALPA_SEED", 14));
    let integrators = ["multirate", "implicit", "symplectic"];
    let (mut cases_torn, mut total_tears, mut total_pieces) = (0, 0u64, 0usize);
    let cases: usize = common::env_or("PALPA_PULLS", 24);
    for case in 0..cases {
        let subdivisions = 2 + case % 2;
        let fixed = case % 4 != 3;
        let integrator = integrators[case % 3];
        let strain = 0.2 + 0.4 * rng.unit();
        let ticks = 1 + rng.below(20);
        let max_per_tick = 1 + rng.below(8);
        let d = rng.unit_vector();
        let pull = (d + rng.unit_vector() * 0.6).normalize() * (0.02 + 0.03 * rng.unit());
        let start = d * 0.031;
        let end = start + pull;
        let scene = format!(
            r#"
[world]
gravity = [0.0, 0.0, -9.81]
dt = 0.001

[[body]]
name = "organ"
mesh = {{ icosphere = {{ radius = 0.03, subdivisions = {subdivisions} }} }}
surface_mass = 0.2
rigid_mass = 1.0
surface_stiffness = 40.0
surface_damping = 0.05
link_stiffness = 200.0
link_damping = 0.2
fixed = {fixed}
integrator = "{integrator}"
tearing = {{ strain = {strain}, ticks = {ticks}, max_per_tick = {max_per_tick} }}

[[tool]]
name = "grasper"
shape = {{ grasper = {{ jaw_length = 0.006, radius = 0.001 }} }}
input = "script"
script = [
  {{ t = 0.0, position = [{}, {}, {}], orientation = [1.0, 0.0, 0.0, 0.0], jaw = 0.0 }},
  {{ t = 1.2, position = [{}, {}, {}], orientation = [1.0, 0.0, 0.0, 0.0], jaw = 0.0 }},
]
"#,
            start.x, start.y, start.z, end.x, end.y, end.z
        );
        let mut world = World::from_scene(&common::scene(&scene));
        let reach = 0.004 + 0.006 * rng.unit();
        let body = &world.bodies[0];
        let held: Vec<usize> = (0..body.node_count())
            .filter(|&i| (body.surface.position_in_world[i] - d * 0.03).norm() < reach)
            .collect();
        hold(&mut world, &held);
        let gravity = world.params.gravity;
        let energy = |world: &World| common::total_energy(&world.bodies, &gravity);
        let mut tears = 0;
        for tick in 0..1500 {
            let (mass_before, _) = totals(&world);
            let before = energy(&world);
            let guarded_before: u64 = world.guards.iter().map(|g| g.events).sum();
            world.step();
            let feedback = world.tools[0].feedback.force_in_world;
            assert!(
                feedback.iter().all(|f| f.is_finite()),
                "case {case}, tick {tick}: feedback {feedback:?}"
            );
            if world.counters.tears == 0 {
                continue;
            }
            tears += world.counters.tears;
            let context = format!(
                "case {case} ({integrator}, {subdivisions} subdivisions, fixed {fixed}, strain \
                 {strain:.3}, ticks {ticks}, max {max_per_tick}, {} held), tick {tick}",
                held.len()
            );
            let (mass_after, _) = totals(&world);
            assert!(
                (mass_after - mass_before).abs() <= 1e-12 * mass_before,
                "{context}: mass {mass_before} → {mass_after}"
            );
            for b in &world.bodies {
                check_surface(b).unwrap_or_else(|e| panic!("{context}, {}: {e}", b.name));
                assert!(b.is_finite(), "{context}: {} is not finite", b.name);
            }
            // Energy: not beyond the tool's work this tick, with the implicit integrator (the
            // explicit schemes' energy oscillates within a tick by O(ω Δt) of itself, tear or not;
            // skipped on a tick where a divergence guard acted).
            let guarded: u64 = world.guards.iter().map(|g| g.events).sum();
            if integrator == "implicit" && guarded == guarded_before {
                let t = &world.tools[0];
                let work = feedback
                    .dot(&(t.pose.position_in_world - t.previous_pose.position_in_world))
                    .abs();
                let gain = energy(&world) - before - work;
                assert!(gain <= 1e-9, "{context}: energy gained {gain} J");
            }
        }
        if tears > 0 {
            cases_torn += 1;
        }
        total_tears += u64::from(tears);
        total_pieces += world.bodies.len() - 1;
    }
    println!(
        "{cases} random pulls: {cases_torn} tore, {total_tears} tear ticks, {total_pieces} pieces"
    );
    assert!(
        cases_torn >= cases / 2,
        "only {cases_torn} of {cases} pulls tore"
    );
}
