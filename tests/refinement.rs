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
fn ball(level: u32, subdivision: &str, integrator: &str, kappa: f64, probe_radius: f64) -> World {
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
        s.link_stiffness[i] = kappa * a;
        s.link_damping[i] = kappa / 250.0 * a;
    }
    let probe = Tool::new(
        "probe",
        ToolShape::Sphere {
            radius: probe_radius,
        },
        ToolInput::Ipc,
        None,
    );
    world.add_tool(probe);
    world
}

/// Presses the probe 3 mm along −z into the top of the ball at a point between nodes, holds it, and
/// returns the mean upward force over the last 100 ms of the hold.
fn press(world: &mut World, r: f64, depth_max: f64) -> f64 {
    press_at(world, r, depth_max, 0.006, 0.004)
}

fn press_at(world: &mut World, r: f64, depth_max: f64, x: f64, y: f64) -> f64 {
    let top = (RADIUS * RADIUS - x * x - y * y).sqrt();
    let at = |z: f64| ToolPose {
        position_in_world: Vec3::new(x, y, z),
        ..ToolPose::default()
    };
    let mut sum = 0.0;
    for k in 0..=1000 {
        let depth = depth_max * (k as f64 / 500.0).min(1.0);
        world.tools[0].set_target(at(top + r + 0.0005 - depth - 0.0005), 0.0);
        world.step();
        if k > 900 {
            sum += world.tools[0].feedback.force_in_world.z;
        }
    }
    sum / 100.0
}

#[test]
fn precision_explore() {
    for (kappa, r, d) in [(1.5e5, 0.004, 0.003), (5e4, 0.005, 0.004)] {
        for (x, y) in [
            (0.006, 0.004),
            (0.003, 0.009),
            (-0.005, 0.007),
            (0.011, -0.002),
        ] {
            let mut fine = ball(5, "", "multirate", kappa, r);
            let fine_force = press_at(&mut fine, r, d, x, y);
            let mut coarse = ball(2, "", "multirate", kappa, r);
            let coarse_force = press_at(&mut coarse, r, d, x, y);
            let mut line = format!(
                "kappa {kappa:e} r {r} d {d} at {x},{y}: fine {fine_force:.5} N, coarse {:+.1} %",
                100.0 * (coarse_force - fine_force) / fine_force
            );
            for (name, key) in [
                (
                    "tol2e-5",
                    "subdivision = { tolerance = 2e-5, max_depth = 8, min_edge = 0.001, coarsen_after = 5.0 }",
                ),
                (
                    "tol1e-4",
                    "subdivision = { max_depth = 6, min_edge = 0.0015, coarsen_after = 5.0 }",
                ),
            ] {
                let mut refined = ball(2, key, "multirate", kappa, r);
                let force = press_at(&mut refined, r, d, x, y);
                line += &format!(
                    ", {name} {:+.1} % ({} nodes)",
                    100.0 * (force - fine_force) / fine_force,
                    refined.bodies[0].node_count()
                );
            }
            eprintln!("{line}");
        }
    }
}

#[test]
fn debug_case() {
    let (kappa, r, d, x, y) = (1.5e5, 0.004, 0.003, -0.005, 0.007);
    let mut w = ball(
        2,
        "subdivision = { max_depth = 6, min_edge = 0.0015, coarsen_after = 5.0 }",
        "multirate",
        kappa,
        r,
    );
    let f = press_at(&mut w, r, d, x, y);
    let c = w.tools[0].pose.position_in_world;
    let b = &w.bodies[0];
    eprintln!(
        "f {f} counters {:?} contacts {}",
        w.refinements[0].as_ref().unwrap().counters,
        w.tools[0].feedback.contacts
    );
    for i in 0..b.node_count() {
        let rel = b.surface.position_in_world[i] - c;
        if rel.norm() < 0.02 {
            eprintln!(
                "node {i} rel {:?} dist-r {:.2} mm held {}",
                rel.map(|v| (v * 1e4).round() / 10.0),
                (rel.norm() - r) * 1e3,
                b.surface.tool_contact[i].tool != u32::MAX
            );
        }
    }
}
