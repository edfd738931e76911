//! Deformable surfaces meet on their trajectories: no node of one body ever ends a tick inside
//! another, at rest (a ball dropped on an organ) or at speed (two balls thrown at each other).

mod common;

use palpa::Vec3;
use palpa::scene::load_scene;
use palpa::world::World;

/// Generalised winding number of `p` with respect to a closed mesh: 1 inside, 0 outside.
fn winding_number(p: &Vec3, positions: &[Vec3], triangles: &[[u32; 3]]) -> f64 {
    let mut total = 0.0;
    for t in triangles {
        let [a, b, c] = t.map(|v| positions[v as usize] - p);
        let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
        let numerator = a.dot(&b.cross(&c));
        let denominator = la * lb * lc + a.dot(&b) * lc + b.dot(&c) * la + c.dot(&a) * lb;
        total += 2.0 * numerator.atan2(denominator);
    }
    total / (4.0 * std::f64::consts::PI)
}

/// Nodes of each body inside another body.
fn nodes_inside_others(world: &World) -> usize {
    let mut count = 0;
    for (i, a) in world.bodies.iter().enumerate() {
        for (j, b) in world.bodies.iter().enumerate() {
            if i == j {
                continue;
            }
            count += a
                .surface
                .position_in_world
                .iter()
                .filter(|p| {
                    winding_number(p, &b.surface.position_in_world, &b.surface.triangles) > 0.5
                })
                .count();
        }
    }
    count
}

#[test]
fn a_ball_dropped_on_an_organ_never_enters_it() {
    let scene = load_scene(&common::repo_root().join("scenes/two_organs.toml")).unwrap();
    let mut world = World::from_scene(&scene);
    assert!(world.systems().body_contact);
    let mut collisions = 0;
    for k in 0..3000 {
        world.step();
        collisions += world.counters.bodies.collisions;
        assert_eq!(world.counters.bodies.overflows, 0);
        if k % 5 == 0 {
            assert_eq!(
                nodes_inside_others(&world),
                0,
                "interpenetration at tick {k}"
            );
        }
        assert!(world.bodies.iter().all(|b| b.is_finite()));
    }
    assert!(
        collisions > 100,
        "the bodies met: {collisions} collisions answered"
    );
}

#[test]
fn two_balls_thrown_at_each_other_at_1_m_per_s_do_not_pass_through() {
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
    let mut collisions = 0;
    for k in 0..300 {
        world.step();
        collisions += world.counters.bodies.collisions;
        assert_eq!(
            nodes_inside_others(&world),
            0,
            "interpenetration at tick {k}"
        );
        // The surfaces stay ordered along x: the left ball's rightmost node never passes the right
        // ball's leftmost one.
        let right_of_left = world.bodies[0]
            .surface
            .position_in_world
            .iter()
            .map(|p| p.x)
            .fold(f64::MIN, f64::max);
        let left_of_right = world.bodies[1]
            .surface
            .position_in_world
            .iter()
            .map(|p| p.x)
            .fold(f64::MAX, f64::min);
        assert!(
            right_of_left <= left_of_right + 0.01,
            "tick {k}: {right_of_left} vs {left_of_right}"
        );
    }
    assert!(collisions > 0);
    // They stopped each other: the surface centres no longer close in.
    let gap =
        world.bodies[1].surface_centre_of_mass().x - world.bodies[0].surface_centre_of_mass().x;
    assert!(gap > 0.0, "centres crossed: {gap}");
}
