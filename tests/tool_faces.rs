//! Tools finer than the mesh: contact of a tool with the triangles between a body's nodes
//! (`palpa::contact::tool_faces`). Without it a probe or a shaft slips between the nodes of a coarse
//! mesh — no force, the surface passing through the tool; with it the triangles keep the tool out,
//! the force fed back is the tissue's, and the momentum the tissue gets is what the device feels.
//!
//! Figures: `cargo test --release --test tool_faces -- --nocapture`.

mod common;

use palpa::Vec3;
use palpa::world::World;

/// A fixed ball (radius 5 cm, 162 nodes: edges about 2 cm).
const FIXED_BALL: &str = r#"
[[body]]
name = "ball"
mesh = { icosphere = { radius = 0.05, subdivisions = 2 } }
position = [0.0, 0.0, 0.0]
surface_mass = 0.1
rigid_mass = 0.5
surface_stiffness = 30.0
surface_damping = 0.02
link_stiffness = 20.0
link_damping = 0.05
fixed = true
"#;

/// A fixed ball (radius 5 cm, 162 nodes: edges about 2 cm) in zero gravity, and a tool aimed at
/// the middle of its topmost triangle, from 1 cm above the surface down to `press` m below where
/// the triangle's middle was, in 0.5 s, then held. `along`: the tool's tip is that far from the
/// middle, its axis (+z of the tool) turned to point along it (a shaft laid across the triangle).
fn pressed_ball(face_contact: bool, tool_shape: &str, along: Vec3, press: f64) -> (World, Vec3) {
    let world_section =
        format!("[world]\ngravity = [0.0, 0.0, 0.0]\nface_contact = {face_contact}\n");
    // Where the topmost triangle's middle is.
    let probe_world = World::from_scene(&common::scene(&format!("{world_section}{FIXED_BALL}")));
    let s = &probe_world.bodies[0].surface;
    let middle = |t: &[u32; 3]| {
        t.iter()
            .map(|&v| s.position_in_world[v as usize])
            .sum::<Vec3>()
            / 3.0
    };
    let top = s
        .triangles
        .iter()
        .map(middle)
        .max_by(|a, b| a.z.total_cmp(&b.z))
        .expect("triangles");
    let start = top + along + Vec3::new(0.0, 0.0, 0.01);
    let end = top + along - Vec3::new(0.0, 0.0, press);
    let turn = nalgebra::UnitQuaternion::rotation_between(&Vec3::z(), &along)
        .unwrap_or_else(nalgebra::UnitQuaternion::identity);
    let text = format!(
        "{world_section}{FIXED_BALL}
[[tool]]
name = \"tool\"
shape = {tool_shape}
script = [
  {{ t = 0.0, position = [{}, {}, {}], orientation = {q} }},
  {{ t = 0.5, position = [{}, {}, {}], orientation = {q} }},
]
",
        start.x,
        start.y,
        start.z,
        end.x,
        end.y,
        end.z,
        q = format!("[{}, {}, {}, {}]", turn.w, turn.i, turn.j, turn.k)
    );
    (World::from_scene(&common::scene(&text)), top)
}

/// Σ over the nodes of the links' force on them (N): at rest, with no gravity and springs that
/// cancel in pairs, what holds the body against the tool.
fn link_force_sum(world: &World) -> Vec3 {
    let s = &world.bodies[0].surface;
    (0..s.position_in_world.len()).fold(Vec3::zeros(), |sum, i| {
        sum + (s.homologue_in_world[i] - s.position_in_world[i]) * s.link_stiffness[i]
    })
}

#[test]
fn a_tool_finer_than_the_mesh_presses_the_triangles_between_the_nodes() {
    for (name, shape, along, press) in [
        (
            "probe r 2 mm",
            "{ sphere = { radius = 0.002 } }",
            Vec3::zeros(),
            0.006,
        ),
        (
            "shaft r 1.5 mm laid across",
            "{ capsule = { radius = 0.0015, length = 0.04 } }",
            Vec3::new(0.02, 0.0, 0.0),
            0.005,
        ),
    ] {
        for face_contact in [false, true] {
            let (mut world, top) = pressed_ball(face_contact, shape, along, press);
            let mut least: f64 = f64::INFINITY;
            let mut first_contact = None;
            let mut inside_ticks = 0;
            for tick in 0..2500 {
                world.step();
                let tool = &world.tools[0];
                if tool.feedback.contacts > 0 && first_contact.is_none() {
                    first_contact = Some(tick);
                }
                if tick > 100 {
                    least = least.min(common::tool_clearance(&world, 0));
                }
                let b = &world.bodies[0];
                let w = common::winding_number(
                    &tool.pose.position_in_world,
                    &b.surface.position_in_world,
                    &b.surface.triangles,
                );
                inside_ticks += usize::from(w.abs() > 0.5);
            }
            let tool = &world.tools[0];
            let feedback = tool.feedback.force_in_world;
            let links = link_force_sum(&world);
            let below = top.z - tool.pose.position_in_world.z;
            println!(
                "{name}, face contact {face_contact}: tip {below:.4} m below the triangle's middle, \
                 first contact at tick {first_contact:?}, least clearance {least:.3e} m, tip inside \
                 the surface on {inside_ticks} ticks; at 2.5 s feedback [{:.5} {:.5} {:.5}] N \
                 ({} contacts, {} faces), Σ link forces [{:.5} {:.5} {:.5}] N",
                feedback.x,
                feedback.y,
                feedback.z,
                tool.feedback.contacts,
                tool.feedback.faces,
                links.x,
                links.y,
                links.z
            );
            if !face_contact {
                // The control: the tool goes between the nodes into the body, feeling nothing.
                assert_eq!(feedback, Vec3::zeros(), "{name}: nothing stops the tool");
                assert!(
                    least < -0.5 * 0.0015,
                    "{name}: the surface passes through the tool"
                );
                continue;
            }
            assert!(first_contact.is_some(), "{name}: the tool met the surface");
            assert_eq!(
                inside_ticks, 0,
                "{name}: the tool's tip stays outside the body"
            );
            // The projection is linear along the contact's direction and the triangle turns
            // under it: what is left is of the order of 0.1 µm (printed), against a tool of 1.5
            // to 2 mm and the millimetres it went into the body without the faces.
            assert!(
                least > -1e-6,
                "{name}: a triangle cut {least:.3e} m into the tool"
            );
            assert!(
                tool.feedback.faces > 0,
                "{name}: the faces carry the contact"
            );
            // At rest the tool holds the body against its links: the feedback is their sum.
            assert!(
                feedback.z > 0.05,
                "{name}: the body pushes the tool back up"
            );
            let error = (feedback - links).norm() / links.norm();
            assert!(
                error < 1e-3,
                "{name}: the feedback is the force of the tissue ({error:.2e} relative)"
            );
        }
    }
}

/// The default organ's parameters (642 nodes, edges about 8 mm) on the table, a probe of 1.5 mm
/// radius pressed 8 mm into its top between the nodes and stroked 2 cm sideways in a second,
/// then lifted; returns, per tick, the feedback force and contact count and whether the probe's
/// centre was inside the organ.
fn thin_probe_stroke(face_contact: bool) -> Vec<(Vec3, u32, bool)> {
    force_contacts_inside(thin_probe_stroke_with(face_contact, 0.3))
}

/// (force, contacts, inside) of each tick.
fn force_contacts_inside(ticks: Vec<StrokeTick>) -> Vec<(Vec3, u32, bool)> {
    ticks
        .into_iter()
        .map(|t| (t.force, t.contacts, t.inside))
        .collect()
}

/// The scene `bodies_and_tools` (an organ and the probe stroking it) on a table, with the world's
/// `face_contact`.
fn on_the_table(face_contact: bool, bodies_and_tools: &str) -> String {
    format!(
        r#"
[world]
face_contact = {face_contact}

[[obstacle]]
name = "table"
plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }}
friction = 0.4
static_friction = 0.6
{bodies_and_tools}"#
    )
}

/// A tick of [`thin_probe_stroke_with`].
struct StrokeTick {
    force: Vec3,
    contacts: u32,
    faces: u32,
    normal_force: f64,
    friction_force: f64,
    sliding: u32,
    inside: bool,
}

/// [`thin_probe_stroke`] with the organ's `friction` against tools.
fn thin_probe_stroke_with(face_contact: bool, friction: f64) -> Vec<StrokeTick> {
    let text = format!(
        r#"
[[body]]
name = "organ"
mesh = {{ ellipsoid = {{ radii = [0.08, 0.05, 0.04], subdivisions = 3 }} }}
position = [0.0, 0.0, 0.041]
surface_mass = 0.3
rigid_mass = 1.2
surface_stiffness = 40.0
surface_damping = 0.01
link_stiffness = 15.0
link_damping = 0.04
friction = {friction}

[[tool]]
name = "probe"
shape = {{ sphere = {{ radius = 0.0015 }} }}
script = [
  {{ t = 0.0, position = [0.0013, 0.0021, 0.10] }},
  {{ t = 0.8, position = [0.0013, 0.0021, 0.0835] }},
  {{ t = 1.5, position = [0.0013, 0.0021, 0.055] }},
  {{ t = 2.5, position = [0.0213, 0.0021, 0.055] }},
  {{ t = 3.0, position = [0.0213, 0.0021, 0.10] }},
]
"#
    );
    stroke_ticks(&on_the_table(face_contact, &text), 3000)
}

/// `ticks` ticks of the scene `text`, whose first tool strokes its first body: what the tool
/// feels each tick, and whether its centre is inside the body.
fn stroke_ticks(text: &str, ticks: usize) -> Vec<StrokeTick> {
    let mut world = World::from_scene(&common::scene(text));
    (0..ticks)
        .map(|_| {
            world.step();
            let tool = &world.tools[0];
            let s = &world.bodies[0].surface;
            let inside = common::winding_number(
                &tool.pose.position_in_world,
                &s.position_in_world,
                &s.triangles,
            )
            .abs()
                > 0.5;
            let f = &tool.feedback;
            StrokeTick {
                force: f.force_in_world,
                contacts: f.contacts,
                faces: f.faces,
                normal_force: f.normal_force,
                friction_force: f.friction_force,
                sliding: f.sliding,
                inside,
            }
        })
        .collect()
}

/// A stroke's ticks (force, contacts, inside) from the probe's first contact to the end of the
/// stroke, the ticks without contact among them, and the ticks of the whole run with the probe
/// inside.
struct Pressed<'a> {
    first: usize,
    pressed: &'a [(Vec3, u32, bool)],
    without_contact: usize,
    inside: usize,
}

/// [`Pressed`] of `ticks`, whose stroke ends at tick `end`.
fn pressed_until(ticks: &[(Vec3, u32, bool)], end: usize) -> Pressed<'_> {
    let first = ticks
        .iter()
        .position(|t| t.1 > 0)
        .expect("the probe met the organ");
    let pressed = &ticks[first..end];
    Pressed {
        first,
        pressed,
        without_contact: pressed.iter().filter(|t| t.1 == 0).count(),
        inside: ticks.iter().filter(|t| t.2).count(),
    }
}

/// The probe stays on the surface through the press and the stroke, and what the device feels
/// changes smoothly: without the faces it sinks between the nodes into the organ.
#[test]
fn a_fine_probe_stroked_over_a_coarse_organ_stays_on_its_surface() {
    let control = thin_probe_stroke(false);
    let inside_without = control.iter().filter(|t| t.2).count();
    let ticks = thin_probe_stroke(true);
    // From the first contact to the end of the stroke (tick 2 500), then the lift.
    let Pressed {
        first,
        pressed,
        without_contact,
        inside,
    } = pressed_until(&ticks, 2500);
    let mut jumps: Vec<f64> = pressed
        .windows(2)
        .map(|w| (w[1].0 - w[0].0).norm())
        .collect();
    jumps.sort_by(f64::total_cmp);
    let (p99, largest) = (jumps[jumps.len() * 99 / 100], jumps[jumps.len() - 1]);
    let strongest = pressed.iter().map(|t| t.0.norm()).fold(0.0, f64::max);
    let at_stroke_end = ticks[2499].0;
    println!(
        "without the faces: the probe's centre inside the organ on {inside_without} ticks of \
         3 000; with them: first contact at tick {first}, {without_contact} ticks without contact \
         from it to the stroke's end, inside on {inside} ticks; feedback up to {strongest:.3} N, \
         [{:.3} {:.3} {:.3}] N at the stroke's end; change from tick to tick p99 {p99:.4} N, \
         largest {largest:.4} N",
        at_stroke_end.x, at_stroke_end.y, at_stroke_end.z
    );
    assert!(
        inside_without > 500,
        "the control: without the faces the probe sinks into the organ"
    );
    assert_eq!(inside, 0, "the probe's centre went inside the organ");
    assert_eq!(without_contact, 0, "the probe lost the surface");
    assert!(
        at_stroke_end.z > 0.2,
        "pressed 8 mm, the organ pushes the probe up"
    );
    // A haptic device renders what it is sent at 1 kHz: no step of more than a tenth of the force.
    assert!(p99 < 0.03, "feedback jitter: p99 {p99} N a tick");
    assert!(largest < 0.15, "feedback jump: {largest} N in a tick");
}

/// What the device feels is the impulse the tissue got: a free ball (no gravity, no table) pushed
/// by a fine probe on a face, with no node held, changes its momentum (surface and rigid component)
/// by minus the feedback's impulse, tick by tick.
#[test]
fn the_momentum_a_pushed_body_gets_is_the_impulse_the_tool_feels() {
    let text = r#"
[world]
gravity = [0.0, 0.0, 0.0]

[[body]]
name = "ball"
mesh = { icosphere = { radius = 0.05, subdivisions = 2 } }
surface_mass = 0.1
rigid_mass = 0.5
surface_stiffness = 30.0
link_stiffness = 20.0

[[tool]]
name = "probe"
shape = { sphere = { radius = 0.002 } }
script = [
  { t = 0.0, position = [0.0011, 0.0007, 0.058] },
  { t = 0.4, position = [0.0011, 0.0007, 0.038] },
]
"#;
    let mut world = World::from_scene(&common::scene(text));
    let momentum = |w: &World| {
        let b = &w.bodies[0];
        common::surface_momentum(b) + b.rigid.velocity_in_world * b.rigid.mass
    };
    let dt = world.params.dt;
    let (mut worst, mut impulse, mut faces_only) = (0.0f64, Vec3::zeros(), true);
    for _ in 0..400 {
        let before = momentum(&world);
        world.step();
        let fb = world.tools[0].feedback;
        faces_only &= fb.contacts == fb.faces;
        let given = fb.force_in_world * dt;
        impulse += given;
        worst = worst.max((momentum(&world) - before + given).norm());
    }
    let total = momentum(&world);
    println!(
        "impulse felt {:.4e} N·s, momentum gained [{:.4e} {:.4e} {:.4e}] N·s; worst tick's \
         mismatch {worst:.2e} N·s",
        impulse.norm(),
        total.x,
        total.y,
        total.z
    );
    assert!(
        faces_only,
        "a node was held: the test is of the faces alone"
    );
    assert!(impulse.norm() > 1e-3, "the probe pushed the ball");
    assert!(
        worst < 1e-12 * impulse.norm().max(1.0),
        "momentum and feedback disagree by {worst:e} N·s in a tick"
    );
}

/// A tick of [`probe_press`]: the feedback force's bits, the contacts, the face candidates.
type PressTick = ([u64; 3], u32, u32);

/// `scenes/probe_press.toml` with `face_contact` set: per tick, the feedback force's bits, the
/// contacts, and the face broad phase's candidates; and the end positions' bits.
fn probe_press(face_contact: bool) -> (Vec<PressTick>, Vec<[u64; 3]>) {
    let text = std::fs::read_to_string(common::repo_root().join("scenes/probe_press.toml"))
        .expect("scenes/probe_press.toml");
    assert!(text.contains("dt = 0.001\n"));
    let text = text.replacen(
        "dt = 0.001\n",
        &format!("dt = 0.001\nface_contact = {face_contact}\n"),
        1,
    );
    let mut world = World::from_scene(&common::scene(&text));
    let ticks = (0..3500)
        .map(|_| {
            world.step();
            let f = &world.tools[0].feedback;
            (
                f.force_in_world.map(f64::to_bits).into(),
                f.contacts,
                world.counters.tool_face_candidates,
            )
        })
        .collect();
    let ends = world.bodies[0]
        .surface
        .position_in_world
        .iter()
        .map(|p| p.map(f64::to_bits).into())
        .collect();
    (ticks, ends)
}

/// A tool coarser than every triangle of a body (the shipped 8 mm probe on a 642-node organ) is
/// the paper's contact zone's alone: with `face_contact` on, the stage skips it before its broad
/// phase (no candidate on any tick), and the run is the same bits as with it off.
#[test]
fn a_tool_coarser_than_every_triangle_costs_the_face_stage_nothing() {
    let (off, off_ends) = probe_press(false);
    let (on, on_ends) = probe_press(true);
    let touching = on.iter().filter(|t| t.1 > 0).count();
    let candidates: u32 = on.iter().map(|t| t.2).sum();
    println!("probe_press: {touching} ticks in contact, {candidates} face candidates");
    assert!(
        touching > 1000,
        "the probe presses the organ ({touching} ticks)"
    );
    assert_eq!(
        candidates, 0,
        "a coarse tool is skipped before the broad phase"
    );
    assert!(
        off.iter().zip(&on).all(|(a, b)| a.0 == b.0 && a.1 == b.1),
        "feedback differs with the faces on"
    );
    assert_eq!(off_ends, on_ends, "positions differ with the faces on");
}

/// Friction between a tool and the faces it presses: the fine probe's stroke over the coarse
/// organ (its stroke carried by faces alone) is dragged back, each triangle's friction within the
/// Coulomb cone of its normal force; with `friction = 0` nothing drags it.
#[test]
fn the_faces_drag_a_stroking_probe_within_the_coulomb_cone() {
    // The stroke along +x, from t = 1.5 s to 2.5 s (ticks 1 600 to 2 450: well within it).
    let summary = |mu: f64| {
        let ticks = thin_probe_stroke_with(true, mu);
        let worst_cone = ticks
            .iter()
            .map(|t| t.friction_force - mu * t.normal_force)
            .fold(f64::NEG_INFINITY, f64::max);
        let stroke = &ticks[1600..2450];
        let n = stroke.len() as f64;
        let mean = |f: &dyn Fn(&StrokeTick) -> f64| stroke.iter().map(f).sum::<f64>() / n;
        let faces_only = stroke
            .iter()
            .all(|t| t.contacts > 0 && t.contacts == t.faces);
        let sliding: u32 = stroke.iter().map(|t| t.sliding).sum();
        let (fx, normal, friction) = (
            mean(&|t| t.force.x),
            mean(&|t| t.normal_force),
            mean(&|t| t.friction_force),
        );
        println!(
            "friction {mu}: over the stroke mean force along it {fx:.4} N, Σ normal {normal:.4} N, \
             Σ friction {friction:.4} N, {sliding} sliding triangle-ticks; friction less μ × \
             normal at most {worst_cone:.2e} N on any tick"
        );
        assert!(faces_only, "the stroke is carried by the faces alone");
        (fx, friction, sliding, worst_cone)
    };
    let (fx_free, friction_free, _, _) = summary(0.0);
    assert_eq!(
        friction_free, 0.0,
        "frictionless faces give no tangential force"
    );
    assert!(fx_free > 0.0, "the control: nothing holds the probe back");
    for mu in [0.3, 0.8] {
        let (fx, friction, sliding, worst_cone) = summary(mu);
        assert!(
            fx < 0.0,
            "friction {mu}: the stroke is not dragged back ({fx} N)"
        );
        assert!(friction > 0.0 && sliding > 0, "friction {mu}: nothing slid");
        assert!(
            worst_cone <= 1e-12,
            "friction {mu}: {worst_cone} N outside the Coulomb cone"
        );
    }
}

/// A probe faster than its diameter: a 2 mm probe struck at 6 m/s (6 mm a tick) into the middle
/// of a triangle of the fixed 162-node ball (its centre 3 mm over the triangle at the end of one
/// tick, 3 mm under it at the end of the next), then held there. At the end of the tick it
/// crossed the triangle it is wholly behind it, so the end-of-tick test alone lets it through; the
/// sweep of its centre over the tick finds the triangle it crossed, which goes in ahead of it.
#[test]
fn a_probe_struck_faster_than_its_diameter_does_not_pass_between_the_nodes() {
    let run = |face_contact: bool| {
        // Where the topmost triangle's middle is.
        let (_, top) = pressed_ball(false, "{ sphere = { radius = 0.002 } }", Vec3::zeros(), 0.0);
        let body = format!(
            "[world]\ngravity = [0.0, 0.0, 0.0]\nface_contact = {face_contact}\n{FIXED_BALL}
[[tool]]
name = \"probe\"
shape = {{ sphere = {{ radius = 0.002 }} }}
script = [
  {{ t = 0.0, position = [{x}, {y}, {}] }},
  {{ t = 0.1, position = [{x}, {y}, {}] }},
  {{ t = 0.102, position = [{x}, {y}, {}] }},
]
",
            top.z + 0.009,
            top.z + 0.009,
            top.z - 0.003,
            x = top.x,
            y = top.y,
        );
        let mut world = World::from_scene(&common::scene(&body));
        let (mut inside, mut least, mut first) = (0, f64::INFINITY, None);
        for tick in 0..1500 {
            world.step();
            let s = &world.bodies[0].surface;
            let p = world.tools[0].pose.position_in_world;
            if common::winding_number(&p, &s.position_in_world, &s.triangles).abs() > 0.5 {
                inside += 1;
            }
            if tick > 1000 {
                least = least.min(common::tool_clearance(&world, 0));
            }
            if first.is_none() && world.tools[0].feedback.contacts > 0 {
                first = Some(tick);
            }
        }
        let force = world.tools[0].feedback.force_in_world;
        println!(
            "probe struck at 6 m/s, faces {face_contact}: centre inside the ball on {inside} of 1 500 \
             ticks, first contact at tick {first:?}, least clearance after 1 s {least:.3e} m, \
             feedback at 1.5 s [{:.4} {:.4} {:.4}] N, Σ links [{:.4} {:.4} {:.4}] N",
            force.x,
            force.y,
            force.z,
            link_force_sum(&world).x,
            link_force_sum(&world).y,
            link_force_sum(&world).z
        );
        (inside, least, force, link_force_sum(&world))
    };
    let (inside_without, _, _, _) = run(false);
    assert!(
        inside_without > 1000,
        "the control: without the faces the probe goes in"
    );
    let (inside, least, force, links) = run(true);
    assert_eq!(inside, 0, "the probe's centre went inside the ball");
    assert!(
        least > -1e-6,
        "the surface {least} m into the probe at rest"
    );
    assert!(
        (force - links).norm() < 1e-3 * links.norm(),
        "at rest the feedback is the tissue's force"
    );
}

/// A very soft 642-node organ (the laparoscopy uterus's parameters, no `subdivision`) on a table,
/// a 5 mm probe pressed 5 mm into its top (0.5 to 0.75 s), stroked 2 cm sideways in 0.5 s and
/// lifted away: per tick, (feedback force, contacts and faces, probe centre inside the surface).
fn soft_organ_stroke(face_contact: bool) -> Vec<(Vec3, u32, bool)> {
    let text = r#"
[[body]]
name = "uterus"
mesh = { ellipsoid = { radii = [0.025, 0.037, 0.022], subdivisions = 3 } }
position = [0.0, 0.0, 0.0225]
surface_mass = 0.06
rigid_mass = 0.03
surface_stiffness = 12.0
surface_damping = 0.02
link_stiffness = 50.0
link_damping = 0.05
friction = 0.3

[[tool]]
name = "probe"
shape = { sphere = { radius = 0.0025 } }
script = [
  { t = 0.0, position = [0.0, -0.01, 0.06] },
  { t = 0.5, position = [0.0, -0.01, 0.0495] },
  { t = 0.75, position = [0.0, -0.01, 0.0395] },
  { t = 1.25, position = [0.0, 0.01, 0.0395] },
  { t = 1.75, position = [0.0, 0.01, 0.07] },
]
"#;
    force_contacts_inside(stroke_ticks(&on_the_table(face_contact, text), 1800))
}

/// A probe about as wide as a soft organ's triangles, pressed deep and stroked: the triangles
/// keep it out (it fits between their corners, its radius below their circle's). When the faces
/// met only tools finer than half that circle, the organ's surface closed over it: no contact on
/// 425 of the 615 ticks from the first contact to the end of the stroke, the probe inside the
/// organ on 584 ticks (as with nodes only), and the organ hanging on it as it lifted (−0.42 N).
#[test]
fn a_probe_pressed_deep_into_a_soft_organ_and_stroked_stays_on_its_surface() {
    let control = soft_organ_stroke(false);
    let inside_without = control.iter().filter(|t| t.2).count();
    let ticks = soft_organ_stroke(true);
    // From the first contact to the end of the stroke (tick 1 250); then the lift.
    let Pressed {
        first,
        pressed,
        without_contact,
        inside,
    } = pressed_until(&ticks, 1250);
    let steps: Vec<f64> = pressed
        .windows(2)
        .map(|w| (w[1].0 - w[0].0).norm())
        .collect();
    let largest_step = steps.iter().copied().fold(0.0, f64::max);
    let deepest = pressed.iter().map(|t| t.0.z).fold(0.0, f64::max);
    let lift_pull = ticks[1250..].iter().map(|t| t.0.z).fold(0.0, f64::min);
    println!(
        "soft organ, 5 mm probe pressed 5 mm and stroked 2 cm: first contact at tick {first}; \
         {without_contact} of {} ticks without contact to the end of the stroke; probe inside on \
         {inside} ticks (without the faces {inside_without}); force up to {deepest:.3} N, largest \
         change a tick {largest_step:.4} N; on the lift, the most downward force {lift_pull:.2e} N",
        pressed.len()
    );
    assert!(
        inside_without > 100,
        "without the faces the probe should go into this organ: {inside_without} ticks"
    );
    assert_eq!(without_contact, 0, "the probe lost the organ");
    assert_eq!(inside, 0, "the probe went into the organ");
    assert!(deepest > 0.1, "the probe did not press: {deepest} N");
    // A surface closed over the probe would pull the organ up with it as it lifts.
    assert!(
        lift_pull > -1e-3,
        "the organ hangs on the probe: {lift_pull} N"
    );
}
