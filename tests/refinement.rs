//! Adaptive subdivision driven by contact.

mod common;

use palpa::Vec3;
use palpa::tool::{Tool, ToolInput, ToolPose, ToolShape};
use palpa::world::World;

const RADIUS: f64 = 0.05;

/// Lumped rest area of every node (a third of each triangle around it).
fn lumped_areas(world: &World) -> Vec<f64> {
    let s = &world.bodies[0].surface;
    let mut areas = vec![0.0; s.mass.len()];
    for t in &s.triangles {
        let [a, b, c] = t.map(|v| s.homologue_in_body[v as usize]);
        let area = 0.5 * (b - a).cross(&(c - a)).norm();
        for v in t {
            areas[*v as usize] += area / 3.0;
        }
    }
    areas
}

/// A fixed ball of the given icosphere level whose parameters do not depend on the mesh: surface
/// mass spread by area, the same spring constant on every edge (a triangle lattice's membrane modulus
/// does not depend on its edge length), and links of a given stiffness and damping per unit area.
fn ball(level: u32, subdivision: &str, integrator: &str) -> World {
    let scene = common::scene(&format!(
        r#"
        [world]
        gravity = [0.0, 0.0, 0.0]
        integrator = "{integrator}"
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
    // Links per unit area: 1.5e5 N/m³ and 600 N·s/m³.
    let areas = lumped_areas(&world);
    let s = &mut world.bodies[0].surface;
    for (i, a) in areas.iter().enumerate() {
        s.link_stiffness[i] = 1.5e5 * a;
        s.link_damping[i] = 600.0 * a;
    }
    let probe = Tool::new(
        "probe",
        ToolShape::Sphere { radius: 0.003 },
        ToolInput::Ipc,
        None,
    );
    world.add_tool(probe);
    world
}

/// Presses the probe 3 mm along −z into the top of the ball at a point between nodes, holds it, and
/// returns the mean upward force over the last 100 ms of the hold.
fn press(world: &mut World) -> f64 {
    let (x, y) = (0.006, 0.004);
    let top = (RADIUS * RADIUS - x * x - y * y).sqrt();
    let r = 0.003;
    let at = |z: f64| ToolPose {
        position_in_world: Vec3::new(x, y, z),
        ..ToolPose::default()
    };
    let mut sum = 0.0;
    for k in 0..=1000 {
        let depth = 0.003 * (k as f64 / 500.0).min(1.0);
        world.tools[0].set_target(at(top + r + 0.0005 - depth - 0.0005), 0.0);
        world.step();
        if k > 900 {
            sum += world.tools[0].feedback.force_in_world.z;
        }
    }
    sum / 100.0
}

#[test]
fn precision_of_a_coarse_body_with_subdivision_against_a_fine_one() {
    let mut fine = ball(5, "", "multirate");
    let fine_force = press(&mut fine);
    for level in [3, 4] {
        let mut w = ball(level, "", "multirate");
        let f = press(&mut w);
        eprintln!(
            "level {level}: {f:.5} N, {} held",
            w.tools[0].feedback.contacts
        );
    }
    let mut coarse = ball(2, "", "multirate");
    let coarse_force = press(&mut coarse);
    eprintln!(
        "fine {fine_force:.5} N ({} nodes, {} held), coarse {coarse_force:.5} N",
        fine.bodies[0].node_count(),
        fine.tools[0].feedback.contacts
    );
    for rule in ["angle", "constant_kl", "area"] {
        let mut refined = ball(
            2,
            &format!(
                "subdivision = {{ rule = \"{rule}\", max_depth = 6, min_edge = 0.0015, coarsen_after = 5.0 }}"
            ),
            "multirate",
        );
        let force = press(&mut refined);
        let r = refined.refinements[0].as_ref().unwrap();
        eprintln!(
            "{rule}: {force:.5} N ({:+.1} %), {} nodes, counters {:?}, guard {}",
            100.0 * (force - fine_force) / fine_force,
            refined.bodies[0].node_count(),
            r.counters,
            refined.guards[0].events
        );
    }
}
