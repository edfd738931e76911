//! Soft bodies dropped on a table settle: no node ends a step below the surface by more than 1e-6 m,
//! kinetic energy decays, and the body rests deformed but whole. Includes the real liver mesh from
//! the shared test data.

mod common;

use palpa::Vec3;
use palpa::scene::load_scene;
use palpa::world::World;

struct Settling {
    worst_gap: f64,
    peak_energy: f64,
    final_energy: f64,
}

fn drop_and_watch(world: &mut World, seconds: f64) -> Settling {
    let steps = (seconds / world.params.dt).round() as usize;
    let mut out = Settling {
        worst_gap: f64::INFINITY,
        peak_energy: 0.0,
        final_energy: 0.0,
    };
    let mut late_peak: f64 = 0.0;
    for k in 0..steps {
        world.step();
        let body = &world.bodies[0];
        assert!(body.is_finite(), "non-finite state at tick {}", world.tick);
        out.worst_gap = out.worst_gap.min(world.min_obstacle_gap(body).unwrap());
        let e = body.kinetic_energy();
        out.peak_energy = out.peak_energy.max(e);
        if k + 500 >= steps {
            late_peak = late_peak.max(e);
        }
    }
    out.final_energy = late_peak;
    out
}

/// Whole: no edge torn or collapsed, no triangle turned over against its rest orientation.
fn assert_whole(world: &World) {
    let body = &world.bodies[0];
    let s = &body.surface;
    for e in 0..body.edges.len() {
        let (a, b) = (body.edges.a[e] as usize, body.edges.b[e] as usize);
        let ratio =
            (s.position_in_world[b] - s.position_in_world[a]).norm() / body.edges.rest_length[e];
        assert!(
            (0.5..2.0).contains(&ratio),
            "edge {e} at {ratio} of its rest length"
        );
    }
    let r = body.rigid.world_from_body;
    for (t, &[a, b, c]) in s.triangles.iter().enumerate() {
        let [pa, pb, pc] = [a, b, c].map(|i| s.position_in_world[i as usize]);
        let [ra, rb, rc] = [a, b, c].map(|i| r * s.homologue_in_body[i as usize]);
        let now = (pb - pa).cross(&(pc - pa));
        let rest = (rb - ra).cross(&(rc - ra));
        assert!(now.dot(&rest) > 0.0, "triangle {t} turned over");
    }
}

/// Largest distance of a node from its homologue (m): how deformed the body is.
fn deformation(world: &World) -> f64 {
    let s = &world.bodies[0].surface;
    s.position_in_world
        .iter()
        .zip(&s.homologue_in_world)
        .map(|(x, h)| (x - h).norm())
        .fold(0.0, f64::max)
}

#[test]
fn soft_body_dropped_on_the_table_settles_deformed_but_whole() {
    let scene = load_scene(&common::repo_root().join("scenes/organ.toml")).unwrap();
    let mut world = World::from_scene(&scene);
    let rest_height = world.bodies[0].surface_centre_of_mass().z
        - world.min_obstacle_gap(&world.bodies[0]).unwrap();
    let r = drop_and_watch(&mut world, 4.0);
    eprintln!(
        "worst gap {:e} m, peak kinetic energy {:e} J, last 0.5 s peak {:e} J, deformation {:e} m",
        r.worst_gap,
        r.peak_energy,
        r.final_energy,
        deformation(&world)
    );
    assert!(
        r.worst_gap >= -1e-6,
        "a node ended a step {} m below the table",
        -r.worst_gap
    );
    assert!(
        r.final_energy < 0.01 * r.peak_energy,
        "kinetic energy did not decay"
    );
    assert!(
        deformation(&world) > 1e-3,
        "the body should rest deformed under its weight"
    );
    let com = world.bodies[0].surface_centre_of_mass();
    assert!(
        com.z > 0.0 && com.z < rest_height,
        "resting sagged above the table: {}",
        com.z
    );
    assert_whole(&world);
}

#[test]
fn soft_body_on_a_box_table_settles() {
    let scene = load_scene(&common::repo_root().join("scenes/table_rest.toml")).unwrap();
    let mut world = World::from_scene(&scene);
    let r = drop_and_watch(&mut world, 3.0);
    assert!(
        r.worst_gap >= -1e-6,
        "a node ended a step {} m inside the box",
        -r.worst_gap
    );
    assert!(r.final_energy < 0.01 * r.peak_energy);
    assert_whole(&world);
    // It rests on top of the table, centred where it was put.
    let com = world.bodies[0].surface_centre_of_mass();
    assert!((com - Vec3::new(0.0, 0.0, com.z)).norm() < 1e-3);
}

#[test]
fn liver_mesh_from_sofa_loads_and_settles_on_the_table() {
    if common::shared_dir().is_none() {
        return;
    }
    let scene = load_scene(&common::repo_root().join("scenes/liver.toml"))
        .unwrap_or_else(|e| panic!("{e}"));
    let mut world = World::from_scene(&scene);
    assert_eq!(world.bodies[0].node_count(), 1170);
    assert_eq!(world.bodies[0].surface.triangles.len(), 2336);
    // Scaled to decimetres: about 21 cm across.
    let xs = world.bodies[0]
        .surface
        .position_in_world
        .iter()
        .map(|p| p.x);
    let width = xs.clone().fold(f64::MIN, f64::max) - xs.fold(f64::MAX, f64::min);
    assert!((width - 0.2149).abs() < 1e-3, "width {width}");
    let r = drop_and_watch(&mut world, 5.0);
    eprintln!(
        "liver: worst gap {:e} m, peak kinetic energy {:e} J, last 0.5 s peak {:e} J",
        r.worst_gap, r.peak_energy, r.final_energy
    );
    assert!(
        r.worst_gap >= -1e-6,
        "a node ended a step {} m below the table",
        -r.worst_gap
    );
    assert!(
        r.final_energy < 0.05 * r.peak_energy,
        "kinetic energy did not decay"
    );
    assert_whole(&world);
}
