//! The integrators against references: multi-rate on light nodes against the reference scheme at a
//! hundredth of the step, and the numerical damping of the implicit scheme against theory.

mod common;

use palpa::Vec3;
use palpa::body::{Body, BodyParams, Placement};
use palpa::dynamics::Integrator;
use palpa::scene::mesh::SurfaceMesh;
use palpa::scene::{WorldParams, parse_scene};
use palpa::world::World;

fn light_nodes(integrator: Integrator, dt: f64) -> World {
    light_nodes_with(integrator, dt, "1.0", "50.0")
}

fn light_nodes_with(integrator: Integrator, dt: f64, rigid_mass: &str, stiffness: &str) -> World {
    let path = common::repo_root().join("scenes/stress/light_nodes.toml");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replacen(
            "[world]",
            &format!("[world]\nintegrator = \"{}\"\ndt = {dt}", integrator.name()),
            1,
        )
        .replacen("rigid_mass = 1.0", &format!("rigid_mass = {rigid_mass}"), 1)
        .replacen(
            "surface_stiffness = 50.0",
            &format!("surface_stiffness = {stiffness}"),
            1,
        );
    World::from_scene(&parse_scene(&text, "light_nodes.toml", path.parent().unwrap()).unwrap())
}

/// A rigid component so light (1 g) that its coupling is sub-stepped, with the light node (springs
/// 4× stiffer) needing a finer step still: every node steps at the rigid component's pace, the light
/// node at its own finer one in between (not the whole body at the finest). Against the reference
/// scheme at 0.01 ms: 1.5e-4 m measured; a light node stepped only at the rigid component's pace
/// (its substeps between left out) is 6.4e-4 m off.
#[test]
fn multirate_steps_a_light_node_finer_than_a_sub_stepped_rigid_component() {
    let seconds = 0.3;
    let mut coarse = light_nodes_with(Integrator::Multirate, 0.001, "0.001", "200.0");
    let (substeps, _) = coarse.substeps_of(0);
    let rigid = coarse.rigid_substeps_of(0);
    assert!(
        rigid.is_some_and(|r| r >= 2 && r < substeps),
        "the rigid component is sub-stepped ({rigid:?}) coarser than the light node ({substeps})"
    );
    let mut fine = light_nodes_with(Integrator::Symplectic, 0.00001, "0.001", "200.0");
    assert!(
        fine.stability_margins()[0].margin > 0.0,
        "the reference is stable at 0.01 ms"
    );
    for _ in 0..(seconds / 0.001_f64).round() as usize {
        coarse.step();
    }
    for _ in 0..(seconds / 0.00001_f64).round() as usize {
        fine.step();
    }
    assert_eq!(coarse.guards[0].events, 0, "multirate needs no guard");
    let (a, b) = (&coarse.bodies[0], &fine.bodies[0]);
    let worst = a
        .surface
        .position_in_world
        .iter()
        .zip(&b.surface.position_in_world)
        .map(|(x, y)| (x - y).norm())
        .fold(0.0, f64::max);
    let rigid_gap = (a.rigid.position_in_world - b.rigid.position_in_world).norm();
    eprintln!(
        "multirate (rigid {rigid:?}, light node {substeps} substeps) vs symplectic at 0.01 ms after \
         {seconds} s: worst node {worst:e} m, rigid component {rigid_gap:e} m"
    );
    assert!(worst < 3e-4, "worst node {worst} m from the fine reference");
    assert!(
        rigid_gap < 1e-3,
        "rigid component {rigid_gap} m from the fine reference"
    );
}

#[test]
fn multirate_on_light_nodes_is_stable_and_close_to_the_fine_reference() {
    let seconds = 0.3;
    let mut coarse = light_nodes(Integrator::Multirate, 0.001);
    let (substeps, fast) = coarse.substeps_of(0);
    assert!(fast >= 1 && substeps >= 2, "the light node is sub-stepped");
    let mut explicit = light_nodes(Integrator::Symplectic, 0.001);
    let mut fine = light_nodes(Integrator::Symplectic, 0.00001);
    assert!(
        fine.stability_margins()[0].margin > 0.0,
        "the reference is stable at 0.01 ms"
    );
    for _ in 0..(seconds / 0.001_f64).round() as usize {
        coarse.step();
        explicit.step();
    }
    for _ in 0..(seconds / 0.00001_f64).round() as usize {
        fine.step();
    }
    assert_eq!(coarse.guards[0].events, 0, "multirate needs no guard");
    assert!(
        explicit.guards[0].events > 0,
        "the reference scheme at 1 ms diverges (and is guarded)"
    );
    let (a, b) = (&coarse.bodies[0].surface, &fine.bodies[0].surface);
    let worst = a
        .position_in_world
        .iter()
        .zip(&b.position_in_world)
        .map(|(x, y)| (x - y).norm())
        .fold(0.0, f64::max);
    let com = (coarse.bodies[0].surface_centre_of_mass() - fine.bodies[0].surface_centre_of_mass())
        .norm();
    eprintln!(
        "multirate at 1 ms vs symplectic at 0.01 ms after {seconds} s: worst node {worst:e} m, centre of mass {com:e} m"
    );
    assert!(worst < 1e-3, "worst node {worst} m from the fine reference");
}

#[test]
fn implicit_is_stable_on_a_stiff_node_and_damps_as_backward_euler_predicts() {
    // One node on a stiff link (100× the default link), no damping: ω Δt = 4.47 at 1 ms.
    let (k, m, dt) = (2000.0, 1e-4, 0.001);
    let mesh = SurfaceMesh {
        positions_in_body: vec![Vec3::zeros()],
        triangles: vec![],
    };
    let params = BodyParams {
        surface_mass: m,
        link_stiffness: k,
        link_damping: 0.0,
        fixed: true,
        ..BodyParams::default()
    };
    let mut world = World::new(WorldParams {
        gravity: Vec3::zeros(),
        dt,
        air_viscosity: 0.0,
        integrator: Integrator::Implicit,
        helper_thread: true,
        face_contact: true,
    });
    let mut body = Body::new("node", &mesh, &params, &Placement::default());
    body.surface.position_in_world[0] = Vec3::new(0.001, 0.0, 0.0);
    world.add_body(body);
    let omega_dt = (k / m).sqrt() * dt;
    assert!(omega_dt > 2.0, "past the explicit limit: {omega_dt}");
    // Backward Euler multiplies the amplitude by 1/|1 + iωΔt| per step (linear, undamped system).
    let per_step = 1.0 / (1.0 + omega_dt * omega_dt).sqrt();
    let energy = |w: &World| {
        let s = &w.bodies[0].surface;
        0.5 * k * s.position_in_world[0].norm_squared()
            + 0.5 * m * s.velocity_in_world[0].norm_squared()
    };
    let e0 = energy(&world);
    let steps = 3;
    for _ in 0..steps {
        world.step();
        assert!(world.bodies[0].is_finite());
    }
    // Energy ∝ amplitude²: the measured decay against the predicted one.
    let measured = (energy(&world) / e0).sqrt();
    let predicted = per_step.powi(steps);
    eprintln!(
        "implicit at ω Δt = {omega_dt:.2}: amplitude × {measured:.4e} after {steps} steps (predicted {predicted:.4e}); \
         per step {:.4}, i.e. {:.1} % of the amplitude lost per step where the exact motion loses none",
        measured.powf(1.0 / steps as f64),
        (1.0 - measured.powf(1.0 / steps as f64)) * 100.0
    );
    assert!(
        (measured / predicted - 1.0).abs() < 0.05,
        "measured {measured}, predicted {predicted}"
    );
    let (iterations, residual) = world.implicit_solve_of(0).unwrap();
    assert!(
        residual <= 1e-8 && iterations >= 1,
        "solve: {iterations} iterations, residual {residual}"
    );
}

#[test]
fn implicit_damping_of_a_stiff_body_free_vibration_is_measured() {
    // The stiff stress body, floating, with its surface pushed 1 mm off its rigid component and no
    // physical damping: the exact motion keeps its vibration energy; backward Euler removes some.
    let path = common::repo_root().join("scenes/stress/stiff.toml");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replacen("[world]", "[world]\nintegrator = \"implicit\"", 1)
        .replace("gravity = [0.0, 0.0, -9.81]", "gravity = [0.0, 0.0, 0.0]")
        .replace("surface_damping = 0.01", "surface_damping = 0.0")
        .replace("link_damping = 0.05", "link_damping = 0.0");
    let mut world =
        World::from_scene(&parse_scene(&text, "stiff.toml", path.parent().unwrap()).unwrap());
    world.obstacles.clear();
    for x in &mut world.bodies[0].surface.position_in_world {
        x.z += 0.001;
    }
    let gravity = Vec3::zeros();
    let vibration = |w: &World| palpa::dynamics::guard::body_energy(&w.bodies[0], &gravity);
    let e0 = vibration(&world);
    for _ in 0..20 {
        world.step();
    }
    let ratio = (vibration(&world) / e0).sqrt();
    eprintln!(
        "stiff body, implicit at 1 ms: vibration amplitude × {ratio:.3e} after 20 ms (undamped exact: × 1)"
    );
    assert!(world.guards[0].events == 0 && world.bodies[0].is_finite());
    assert!(ratio < 1.0, "backward Euler dissipates");
}

/// Sends each node of body 0 (placed at the origin) towards the origin at 20 /s times its position
/// and the nodes of one half 0.5 m/s sideways, steps 300 ticks, and returns the body's momentum
/// before (N s, checked to be above 1e-2: the body moves) and how much it changed.
fn deformed_for_300_ticks(world: &mut World) -> (f64, f64) {
    let surface = &mut world.bodies[0].surface;
    for i in 0..surface.mass.len() {
        let p = surface.position_in_world[i];
        let sideways = if p.x > 0.0 { 0.5 } else { 0.0 };
        surface.velocity_in_world[i] = -p * 20.0 + Vec3::new(sideways, 0.0, 0.0);
    }
    let momentum = |world: &World| {
        let b = &world.bodies[0];
        common::surface_momentum(b) + b.rigid.velocity_in_world * b.rigid.mass
    };
    let before = momentum(world);
    for _ in 0..300 {
        world.step();
    }
    let change = (momentum(world) - before).norm();
    assert!(before.norm() > 1e-2, "the body moves");
    (before.norm(), change)
}

/// A lone body deforming in zero gravity keeps its momentum under every integrator: each node of a
/// 642-node ellipsoid (82 of them sub-stepped twice by the multi-rate integrator) given a velocity
/// towards the centre (20 /s times its position) and the nodes of one half 0.5 m/s sideways, then
/// 0.3 s. A spring between a sub-stepped node and one that is not gave the two unequal impulses
/// (the first's over its substeps, from the other's interpolated path; the second's from the
/// start-of-step state): the multi-rate body lost 5.3e-5 N s of 5.3e-2, where the symplectic one
/// keeps it to 2e-17. The node not sub-stepped is now owed the difference: 8e-17 (asserted below
/// 1e-14 for both; implicit 6e-11, its linear solve's tolerance, asserted below 1e-9).
#[test]
fn a_lone_deforming_body_keeps_its_momentum_under_every_integrator() {
    for (integrator, bound) in [
        ("symplectic", 1e-14),
        ("multirate", 1e-14),
        ("implicit", 1e-9),
    ] {
        let text = format!(
            "[world]\ngravity = [0.0, 0.0, 0.0]\nintegrator = \"{integrator}\"\n\
             [[body]]\nmesh = {{ ellipsoid = {{ radii = [0.04, 0.03, 0.03], subdivisions = 3 }} }}\n"
        );
        let mut world = World::from_scene(&common::scene(&text));
        if integrator == "multirate" {
            let m = world.multirate(0).expect("a multi-rate body");
            assert!(
                !m.fast.is_empty() && m.fast.len() < world.bodies[0].node_count(),
                "some nodes sub-stepped, not all: {} of {}",
                m.fast.len(),
                world.bodies[0].node_count()
            );
        }
        let (before, change) = deformed_for_300_ticks(&mut world);
        println!("{integrator}: momentum {before:.4e} N s, changed by {change:.2e}");
        assert!(
            change < bound,
            "{integrator}: momentum changed by {change:e} N s"
        );
    }
}

/// The same with the rigid component sub-stepped and deep nodes stepping finer still: the SOFA liver
/// (`../shared/data/meshes/liver2.obj` at 0.1 scale, 1 170 nodes) with the default parameters,
/// whose small nodes make the multi-rate integrator step the rigid component and 818 nodes twice a
/// tick and 352 deep nodes eight times. Its nodes sent towards its centre and one half sideways, in
/// zero gravity, 0.3 s. A spring from a deep node to a coarser one gave the coarser one the force
/// of its own step's start for that whole step, and the deep one the force at each of its own
/// steps: the body lost 2.2e-4 N s of 4.7e-2. The coarser node is now owed the difference: 2.5e-8
/// (asserted below 1e-6). What is left is the deep nodes' link reactions the rigid component takes
/// at its next update, one interval later (bounded, not lost).
#[test]
fn a_deforming_body_with_deep_nodes_keeps_its_momentum() {
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let mesh = shared.join("data/meshes/liver2.obj");
    let text = format!(
        "[world]\ngravity = [0.0, 0.0, 0.0]\nintegrator = \"multirate\"\n\
         [[body]]\nmesh = {{ obj = \"{}\", scale = 0.1 }}\n",
        mesh.display()
    );
    let mut world = World::from_scene(&common::scene(&text));
    let m = world.multirate(0).expect("a multi-rate body");
    assert!(
        m.rigid_substepped && !m.deep.is_empty() && m.deep.len() < world.bodies[0].node_count(),
        "the rigid component sub-stepped, some nodes deeper: {} of {}",
        m.deep.len(),
        world.bodies[0].node_count()
    );
    let (before, change) = deformed_for_300_ticks(&mut world);
    println!(
        "momentum {before:.4e} N s, changed by {change:.2e}; guard events {}",
        world.counters.guard_events
    );
    assert!(change < 1e-6, "momentum changed by {change:e} N s");
}
