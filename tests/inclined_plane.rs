//! The paper's inclined-plane test: a block on a plane tilted by θ stays put when tan θ is below the
//! static coefficient, and otherwise slides with acceleration g (sin θ − μ cos θ).

mod common;

use palpa::Vec3;
use palpa::world::World;

/// A 10 x 10 x 6 cm block resting (just touching) on a plane tilted by `theta` about y.
fn block_on_slope(theta: f64, friction: f64, static_friction: f64) -> World {
    let normal = Vec3::new(theta.sin(), 0.0, theta.cos());
    let centre = normal * 0.03;
    let text = format!(
        r#"
        [world]
        gravity = [0.0, 0.0, -9.81]
        [[body]]
        name = "block"
        mesh = {{ box = {{ size = [0.1, 0.1, 0.06], subdivisions = 2 }} }}
        position = [{}, {}, {}]
        orientation = [{}, 0.0, {}, 0.0]
        surface_mass = 0.5
        rigid_mass = 1.0
        surface_stiffness = 300.0
        surface_damping = 0.2
        link_stiffness = 300.0
        link_damping = 0.5
        [[obstacle]]
        name = "slope"
        plane = {{ point = [0.0, 0.0, 0.0], normal = [{}, {}, {}] }}
        friction = {friction}
        static_friction = {static_friction}
        "#,
        centre.x,
        centre.y,
        centre.z,
        (theta / 2.0).cos(),
        (theta / 2.0).sin(),
        normal.x,
        normal.y,
        normal.z
    );
    World::from_scene(&common::scene(&text))
}

fn downhill(theta: f64) -> Vec3 {
    Vec3::new(theta.cos(), 0.0, -theta.sin())
}

#[test]
fn block_below_the_static_friction_angle_stays_put() {
    // tan 20° = 0.364 < μ_s = 0.6.
    let theta = 20f64.to_radians();
    let mut world = block_on_slope(theta, 0.5, 0.6);
    // The block first settles into its elastic sag (links and springs take up the tangential part of
    // its weight: about 0.8 mm of shear, most of it within 0.3 s); from then on a stuck block must not
    // creep, and the nodes on the plane must not slip at all.
    for _ in 0..500 {
        world.step();
    }
    let settled = world.bodies[0].surface_centre_of_mass();
    let plane = &world.obstacles[0].shape;
    let surface = &world.bodies[0].surface;
    let touching: Vec<(usize, Vec3)> = (0..surface.position_in_world.len())
        .filter(|&i| plane.signed_distance(&surface.position_in_world[i]) < 1e-6)
        .map(|i| (i, surface.position_in_world[i]))
        .collect();
    assert!(
        touching.len() >= 8,
        "the bottom face rests on the plane: {} nodes",
        touching.len()
    );
    let mut worst: f64 = 0.0;
    for _ in 0..2000 {
        world.step();
        let com = world.bodies[0].surface_centre_of_mass();
        worst = worst.max((com - settled).dot(&downhill(theta)).abs());
        assert!(world.min_obstacle_gap(&world.bodies[0]).unwrap() > -1e-6);
    }
    let mut slip: f64 = 0.0;
    for (i, start) in &touching {
        let now = world.bodies[0].surface.position_in_world[*i];
        slip = slip.max((now - start).dot(&downhill(theta)).abs());
    }
    eprintln!(
        "drift over 2 s: {worst:e} m, slip of the {} nodes on the plane: {slip:e} m",
        touching.len()
    );
    assert!(
        worst < 1e-3,
        "the block crept {worst} m down a slope it should stick to"
    );
    assert!(slip < 1e-6, "nodes on the plane slipped {slip} m");
}

#[test]
fn block_above_the_friction_angle_slides_at_g_sin_minus_mu_cos() {
    for (theta_deg, mu) in [(30.0f64, 0.3), (25.0, 0.2), (35.0, 0.5)] {
        let theta = theta_deg.to_radians();
        let mut world = block_on_slope(theta, mu, mu);
        for _ in 0..200 {
            world.step();
        }
        let (mut times, mut s) = (Vec::new(), Vec::new());
        for _ in 0..1000 {
            world.step();
            times.push(world.time());
            s.push(
                world.bodies[0]
                    .surface_centre_of_mass()
                    .dot(&downhill(theta)),
            );
        }
        let a = common::fitted_acceleration(&times, &s);
        let expected = 9.81 * (theta.sin() - mu * theta.cos());
        let relative = (a - expected).abs() / expected;
        eprintln!(
            "θ = {theta_deg}°, μ = {mu}: a = {a:.4} m/s², expected {expected:.4} ({:.2} %)",
            relative * 100.0
        );
        assert!(
            relative < 0.05,
            "θ = {theta_deg}°, μ = {mu}: a = {a}, expected {expected}"
        );
    }
}
