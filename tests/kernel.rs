//! The force kernel (`palpa::dynamics::kernel`): its edge batches are a valid colouring, its forces
//! and energy are the model's, and its SIMD and scalar paths give the same bits — for one pass on
//! random states and for whole runs of the shipped scenes, topology changes included.

mod common;

use common::Rng;
use palpa::Vec3;
use palpa::body::Body;
use palpa::dynamics::guard::body_energy;
use palpa::dynamics::kernel::{
    EdgeBatches, ForceKernel, LANES, NodePass, SPLIT_NODES, simd_available,
};
use palpa::scene::load_scene;
use palpa::world::World;

fn organ(subdivisions: u32, extra: &str) -> World {
    World::from_scene(&common::scene(&format!(
        r#"
        [[body]]
        name = "organ"
        mesh = {{ icosphere = {{ radius = 0.05, subdivisions = {subdivisions} }} }}
        position = [0.0, 0.0, 0.1]
        air_viscosity = 0.5
        {extra}
        "#
    )))
}

/// Every node moved up to 3 mm and given a random velocity, so that every spring and link works.
fn shake(body: &mut Body, rng: &mut Rng) {
    let s = &mut body.surface;
    for i in 0..s.position_in_world.len() {
        s.position_in_world[i] += rng.unit_vector() * (0.003 * rng.unit());
        s.velocity_in_world[i] = rng.unit_vector() * (0.2 * rng.unit());
    }
}

/// The forces of MODEL.md §2 written out plainly, one edge and one node at a time.
fn plain_forces(body: &Body, gravity: &Vec3) -> Vec<Vec3> {
    let s = &body.surface;
    let r = &body.rigid;
    let rotation = r.world_from_body.to_rotation_matrix();
    let omega = r.angular_velocity_in_world();
    let mut f: Vec<Vec3> = (0..s.mass.len())
        .map(|i| {
            let arm = rotation * s.homologue_in_body[i];
            let link = (r.position_in_world + arm - s.position_in_world[i]) * s.link_stiffness[i]
                + (r.velocity_in_world + omega.cross(&arm) - s.velocity_in_world[i])
                    * s.link_damping[i];
            gravity * s.mass[i] - s.velocity_in_world[i] * s.air_damping[i] + link
        })
        .collect();
    let e = &body.edges;
    for k in 0..e.len() {
        let (a, b) = (e.a[k] as usize, e.b[k] as usize);
        let d = s.position_in_world[b] - s.position_in_world[a];
        let u = d.normalize();
        let magnitude = e.stiffness[k] * (d.norm() - e.rest_length[k])
            + e.damping[k] * (s.velocity_in_world[b] - s.velocity_in_world[a]).dot(&u);
        f[a] += u * magnitude;
        f[b] -= u * magnitude;
    }
    f
}

/// How many lanes of `batches` hold each edge of `body`; asserts that no batch holds a node twice.
fn lanes_per_edge(batches: &EdgeBatches, body: &Body, context: &str) -> Vec<u32> {
    let mut seen = vec![0u32; body.edges.len()];
    for batch in batches.lanes() {
        let mut ends = Vec::new();
        for &k in batch {
            if k == u32::MAX {
                continue;
            }
            seen[k as usize] += 1;
            ends.push(body.edges.a[k as usize]);
            ends.push(body.edges.b[k as usize]);
        }
        let count = ends.len();
        ends.sort_unstable();
        ends.dedup();
        assert_eq!(
            ends.len(),
            count,
            "{context}: a batch touches a node twice: {batch:?}"
        );
    }
    seen
}

#[test]
fn the_batches_colour_every_edge_once_with_distinct_ends() {
    for subdivisions in [0, 2, 4] {
        let mut world = organ(subdivisions, "");
        // The batches are built by the first pass.
        world.step();
        let body = &world.bodies[0];
        let batches = world.force_kernel(0).unwrap().batches();
        let seen = lanes_per_edge(batches, body, "after the first pass");
        assert!(
            seen.iter().all(|&n| n == 1),
            "every edge in exactly one lane"
        );
        let occupancy = batches.occupancy();
        println!(
            "{} nodes, {} edges: {} batches of {LANES}, occupancy {occupancy:.3}",
            body.node_count(),
            body.edges.len(),
            batches.len()
        );
        // Small meshes pack less well (a node of degree 5 or 6 in 30 edges).
        assert!(occupancy >= if subdivisions >= 2 { 0.95 } else { 0.7 });
    }
}

/// Checks `kernel`'s batches against `body`: every edge in exactly one lane, no node twice in a
/// batch, and the forces they give equal to a fresh colouring's (to rounding: the order of the sums
/// differs). Returns the largest force difference over the largest force.
fn check_batches(kernel: &ForceKernel, body: &Body, gravity: &Vec3, context: &str) -> f64 {
    let seen = lanes_per_edge(kernel.batches(), body, context);
    for (k, &n) in seen.iter().enumerate() {
        let (a, b) = (body.edges.a[k], body.edges.b[k]);
        let expected = u32::from(a != b);
        assert_eq!(n, expected, "{context}: edge {k} ({a}, {b}) in {n} lanes");
    }
    let forces = |mut kernel: ForceKernel| {
        let mut body = body.clone();
        kernel.edge_forces(&body);
        kernel.node_pass(&mut body, gravity, 1e-3, NodePass::Forces);
        body.surface.force_in_world
    };
    let (followed, fresh) = (forces(kernel.clone()), forces(ForceKernel::new(body)));
    let scale = fresh.iter().map(|f| f.norm()).fold(1e-12, f64::max);
    let worst = followed
        .iter()
        .zip(&fresh)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(
        worst <= 1e-12 * scale,
        "{context}: forces {worst:e} N from a fresh colouring's (largest {scale:e} N)"
    );
    worst / scale
}

/// A topology change (subdivision and coarsening, cuts, a transection, tearing) patches the batches
/// where the edges changed rather than colouring them all again: after every step that changed a
/// body's edges, the patched batches hold each edge once, with distinct ends in a batch, and give a
/// fresh colouring's forces.
#[test]
fn the_batches_follow_every_topology_change() {
    let (mut patches, mut rebuilds, mut checks) = (0, 0, 0);
    let mut worst: f64 = 0.0;
    for (name, ticks) in [
        ("scenes/probe_refine.toml", 1500),
        ("scenes/incision.toml", 2500),
        ("scenes/transection.toml", 1500),
        ("scenes/tear.toml", 2500),
    ] {
        let scene = load_scene(&common::repo_root().join(name)).unwrap_or_else(|e| panic!("{e}"));
        let mut world = World::from_scene(&scene);
        let gravity = world.params.gravity;
        let mut versions: Vec<u64> = Vec::new();
        for tick in 0..ticks {
            world.step();
            for (b, body) in world.bodies.iter().enumerate() {
                if versions.get(b) == Some(&body.topology_version) {
                    continue;
                }
                if b < versions.len() {
                    versions[b] = body.topology_version;
                } else {
                    versions.push(body.topology_version);
                }
                // The world patches at the next step's force pass: do it here on a copy.
                let mut kernel = world.force_kernel(b).unwrap().clone();
                kernel.refresh(body);
                let context = format!("{name}, tick {tick}, {}", body.name);
                worst = worst.max(check_batches(&kernel, body, &gravity, &context));
                checks += 1;
            }
        }
        let (mut scene_patches, mut scene_rebuilds) = (0, 0);
        for b in 0..world.bodies.len() {
            let (p, r) = world.force_kernel(b).unwrap().batches().history();
            scene_patches += p;
            scene_rebuilds += r;
        }
        println!("{name}: {scene_patches} patches, {scene_rebuilds} full colourings");
        // Colourings: each body's first, and one after each transection (it renumbers the nodes).
        let expected = world.bodies.len() as u64 + world.bodies.len() as u64 - 1;
        assert!(
            scene_rebuilds <= expected,
            "{name}: {scene_rebuilds} full colourings, {expected} expected at most"
        );
        patches += scene_patches;
        rebuilds += scene_rebuilds;
    }
    println!(
        "{checks} topology changes checked: {patches} patches, {rebuilds} full colourings; \
         largest force difference {worst:.1e} of the largest force"
    );
    assert!(patches >= 60, "only {patches} patches");
}

#[test]
fn forces_and_energy_are_the_models() {
    let mut rng = Rng(7);
    // 10 242 nodes: a body whose passes are cut in two parts (`SPLIT_NODES`).
    for subdivisions in [1, 3, 5] {
        let mut world = organ(subdivisions, "");
        let gravity = world.params.gravity;
        let body = &mut world.bodies[0];
        shake(body, &mut rng);
        let expected = plain_forces(body, &gravity);
        let energy = body_energy(body, &gravity);
        let mut kernel = ForceKernel::new(body);
        kernel.edge_forces(body);
        kernel.node_pass(body, &gravity, 1e-3, NodePass::Forces);
        let scale = expected.iter().map(|f| f.norm()).fold(0.0, f64::max);
        let worst = expected
            .iter()
            .zip(&body.surface.force_in_world)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        println!("largest force difference {worst:.2e} N of {scale:.2e} N");
        assert!(worst <= 1e-12 * scale, "{worst} of {scale}");
        let gap = (kernel.energy - energy).abs();
        println!("energy {:.12e} J, kernel {:.12e} J", energy, kernel.energy);
        assert!(gap <= 1e-12 * energy.abs().max(1e-9), "{gap}");
    }
}

#[test]
fn simd_and_scalar_passes_give_the_same_bits() {
    if !simd_available() {
        eprintln!("no SIMD path on this machine: the scalar path is the only one");
        return;
    }
    let mut rng = Rng(11);
    for subdivisions in [0, 2, 4] {
        let mut world = organ(subdivisions, "");
        let gravity = world.params.gravity;
        shake(&mut world.bodies[0], &mut rng);
        let mut results = Vec::new();
        for simd in [true, false] {
            let mut body = world.bodies[0].clone();
            let mut kernel = ForceKernel::new(&body);
            kernel.set_simd(simd);
            assert_eq!(kernel.uses_simd(), simd);
            kernel.edge_forces(&body);
            kernel.node_pass(&mut body, &gravity, 1e-3, NodePass::IntegrateAll);
            let bits: Vec<u64> = body
                .surface
                .force_in_world
                .iter()
                .chain(&body.surface.velocity_in_world)
                .chain(&body.surface.next_position_in_world)
                .flat_map(|v| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>())
                .chain([kernel.energy.to_bits(), kernel.edge_energy.to_bits()])
                .collect();
            results.push(bits);
        }
        assert!(results[0] == results[1], "{subdivisions}: the paths differ");
    }
}

/// FNV-1a over every node's position and velocity after every tick.
fn run_digest(mut world: World, ticks: u64) -> u64 {
    steps_digest(&mut world, ticks)
}

/// [`run_digest`] on a world kept by the caller.
fn steps_digest(world: &mut World, ticks: u64) -> u64 {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    for _ in 0..ticks {
        world.step();
        for body in &world.bodies {
            let s = &body.surface;
            for v in s.position_in_world.iter().chain(&s.velocity_in_world) {
                for x in v.iter() {
                    for byte in x.to_bits().to_le_bytes() {
                        hash ^= byte as u64;
                        hash = hash.wrapping_mul(0x0000_0100_0000_01b3);
                    }
                }
            }
        }
    }
    hash
}

#[test]
fn whole_runs_match_bit_for_bit_on_both_paths() {
    if !simd_available() {
        eprintln!("no SIMD path on this machine: the scalar path is the only one");
        return;
    }
    // Palpation with subdivision, a cut and a transection, tearing, several bodies on ligaments:
    // the batches are rebuilt on every topology change.
    for (name, ticks) in [
        ("scenes/probe_refine.toml", 600),
        ("scenes/incision.toml", 1500),
        ("scenes/transection.toml", 1200),
        ("scenes/tear.toml", 1200),
        ("scenes/two_organs.toml", 300),
    ] {
        let scene = load_scene(&common::repo_root().join(name)).unwrap_or_else(|e| panic!("{e}"));
        let mut digests = Vec::new();
        for simd in [true, false] {
            let mut world = World::from_scene(&scene);
            world.set_simd(simd);
            digests.push(run_digest(world, ticks));
        }
        println!("{name}: {:016x} / {:016x}", digests[0], digests[1]);
        assert_eq!(
            digests[0], digests[1],
            "{name}: SIMD and scalar runs differ"
        );
    }
}

#[test]
fn a_large_body_gives_the_same_bits_with_and_without_the_helper_thread_on_both_paths() {
    // 10 242 nodes (above `SPLIT_NODES`): the force passes are cut in two parts, the second
    // offered to the world's helper thread. Symplectic, with the nodes' mass of the default organ
    // (no node would be sub-stepped): the kernel's forces are the ones integrated. Shaken, it lands on a table: every part of the pass
    // works (springs, links, integration, the table's contacts read the node blocks).
    let scene_text = r#"
        [world]
        integrator = "symplectic"
        [[body]]
        name = "organ"
        mesh = { icosphere = { radius = 0.05, subdivisions = 5 } }
        position = [0.0, 0.0, 0.052]
        surface_mass = 3.19
        air_viscosity = 0.5
        [[obstacle]]
        name = "table"
        plane = { point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }
        "#;
    let scene = common::scene(scene_text);
    assert!(World::from_scene(&scene).bodies[0].node_count() >= SPLIT_NODES);
    let paths: &[bool] = if simd_available() {
        &[true, false]
    } else {
        &[false]
    };
    let mut digests = Vec::new();
    for &simd in paths {
        for helper in [true, false] {
            // Every node shaken alike in each run, so that every spring works from the start.
            let start = |world: &mut World| {
                world.set_simd(simd);
                world.set_helper_thread(helper);
                shake(&mut world.bodies[0], &mut Rng(5));
            };
            let mut world = World::from_scene(&scene);
            start(&mut world);
            let mut check = World::from_scene(&scene);
            start(&mut check);
            let digest = run_digest(world, 300);
            // The same world again: the same bits whichever thread took each part this time.
            assert_eq!(
                digest,
                run_digest(check, 300),
                "simd {simd}, helper {helper}: runs differ"
            );
            println!("simd {simd}, helper {helper}: {digest:016x}");
            digests.push(digest);
        }
    }
    assert!(
        digests.iter().all(|&d| d == digests[0]),
        "the paths or the helper change the bits: {digests:x?}"
    );
    // The helper was offered the parts (whether it ran them depends on the machine's load).
    let mut world = World::from_scene(&scene);
    for _ in 0..10 {
        world.step();
    }
    let (posted, taken) = world.helper_counts();
    println!("helper: {taken} of {posted} parts");
    assert_eq!(posted, 20, "two parts a tick offered to the helper");
    assert!(taken <= posted);
    // The scene key turns it off.
    let text = scene_text.replace("[world]", "[world]\nhelper_thread = false");
    let mut world = World::from_scene(&common::scene(&text));
    for _ in 0..10 {
        world.step();
    }
    assert_eq!(world.helper_counts(), (0, 0), "helper_thread = false");
}

#[test]
fn a_large_body_cut_and_subdivided_gives_the_same_bits_with_and_without_the_helper_thread() {
    // The incision scene with its organ at 10 242 nodes: the blade cuts it and subdivision refines
    // it under the probe while its passes are cut in two (the batches are patched and the node
    // count changes between ticks).
    let path = common::repo_root().join("scenes/incision.toml");
    let text = std::fs::read_to_string(&path)
        .expect("scenes/incision.toml")
        .replace("subdivisions = 3 }", "subdivisions = 5 }")
        .replace("surface_mass = 0.3", "surface_mass = 4.79");
    assert!(
        text.contains("subdivisions = 5 }"),
        "the incision scene's mesh changed"
    );
    let scene = common::scene(&text);
    let mut digests = Vec::new();
    for helper in [true, false] {
        let mut world = World::from_scene(&scene);
        world.set_helper_thread(helper);
        let nodes = world.bodies[0].node_count();
        assert!(nodes >= SPLIT_NODES);
        let digest = steps_digest(&mut world, 900);
        let grown = world.bodies[0].node_count();
        println!(
            "helper {helper}: {nodes} → {grown} nodes, {:?} parts, {digest:016x}",
            world.helper_counts()
        );
        assert!(grown > nodes, "no cut or subdivision in 0.9 s");
        assert_eq!(world.helper_counts().0 > 0, helper);
        digests.push(digest);
    }
    assert_eq!(digests[0], digests[1], "the helper changes the bits");
}

#[test]
fn the_held_node_list_is_what_a_sweep_finds_after_every_step() {
    // Palpation with subdivision and coarsening, a grasp and its release, a cut with a resistance
    // and a transection, tearing under a grasper, two tools on several bodies.
    let mut scenes: Vec<(String, palpa::Scene, u64)> = [
        ("scenes/probe_refine.toml", 1500),
        ("scenes/grasp_lift.toml", 5000),
        ("scenes/incision.toml", 2500),
        ("scenes/transection.toml", 1500),
        ("scenes/tear.toml", 2500),
    ]
    .into_iter()
    .map(|(name, ticks)| {
        let scene = load_scene(&common::repo_root().join(name)).unwrap_or_else(|e| panic!("{e}"));
        (name.to_string(), scene, ticks)
    })
    .collect();
    // The incision with the probe pressing beside the blade's path while it cuts: the nodes it
    // holds stay held through the cuts round them.
    let incision = std::fs::read_to_string(common::repo_root().join("scenes/incision.toml"))
        .expect("scenes/incision.toml");
    let probe_script = "  { t = 0.0, position = [0.0, 0.03, 0.12] },
  { t = 2.0, position = [0.0, 0.006, 0.10] },
  { t = 3.0, position = [0.0, 0.006, 0.062] },";
    assert!(
        incision.contains(probe_script),
        "the incision's probe script changed"
    );
    let pressing = incision.replace(
        probe_script,
        "  { t = 0.0, position = [0.01, 0.008, 0.10] },
  { t = 0.4, position = [0.01, 0.008, 0.072] },
  { t = 3.0, position = [0.01, 0.008, 0.072] },",
    );
    scenes.push((
        "incision with the probe pressing beside the cut".into(),
        common::scene(&pressing),
        2000,
    ));
    scenes.push((
        "laparoscopy with the demo's tools".into(),
        common::laparoscopy_with_demo_tools(3.0),
        3000,
    ));
    for (name, scene, ticks) in scenes {
        let mut world = World::from_scene(&scene);
        let (mut most, mut checks) = (0usize, 0u64);
        for _ in 0..ticks {
            world.step();
            for b in 0..world.bodies.len() {
                let (held, sweep) = world.held_nodes_and_sweep(b);
                assert_eq!(held, sweep, "{name}, tick {}, body {b}", world.tick);
                most = most.max(held.len());
                checks += 1;
            }
        }
        let (sweeps, follows) = (0..world.bodies.len())
            .map(|b| world.held_list_counts(b))
            .fold((0, 0), |(s, f), (a, b)| (s + a, f + b));
        println!(
            "{name}: {checks} checks, up to {most} nodes held; the list swept {sweeps} times, \
             {follows} topology changes followed from their record"
        );
        // The tear scene tears where the grasper holds, the probe presses beside the incision:
        // the list follows the tears and cuts.
        if name.contains("tear") || name.contains("pressing") {
            assert!(
                follows > 0,
                "{name}: no topology change followed from its record"
            );
        }
        // Blades cut through without holding; every other scene's tool holds nodes at some point.
        if !name.ends_with("incision.toml") && !name.contains("transection") {
            assert!(most > 0, "{name}: a tool holds nodes at some point");
        }
    }
}
