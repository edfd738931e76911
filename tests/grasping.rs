//! Grasping (issue 14): a grasper's jaws closing on an organ resting on the table catch it between
//! their inner faces and hold those nodes in the jaw frame; the organ leaves the table with the jaws,
//! feeds back its weight when held still, and is let go, all in one tick, when the jaws open past
//! `release_above`; it then falls at g and rests on the table again.

mod common;

use palpa::Vec3;
use palpa::contact::tool::{NO_TOOL, between_jaws};
use palpa::world::World;

/// Centre of mass of the whole organ (surface and rigid component).
fn centre_of_mass(world: &World) -> Vec3 {
    let body = &world.bodies[0];
    let surface = body.surface_mass();
    (body.surface_centre_of_mass() * surface + body.rigid.position_in_world * body.rigid.mass)
        / (surface + body.rigid.mass)
}

fn lowest_node(world: &World) -> f64 {
    world.bodies[0]
        .surface
        .position_in_world
        .iter()
        .map(|p| p.z)
        .fold(f64::INFINITY, f64::min)
}

/// `scenes/grasp_lift.toml`: the jaws come down open over the organ (1–2 s), close (2–2.6 s), lift
/// 5 cm (2.8–3.8 s), hold still (3.8–8.8 s) and open (8.8–8.9 s).
#[test]
fn jaws_take_the_organ_from_the_table_hold_it_and_put_it_down() {
    let scene = palpa::scene::load_scene(&common::repo_root().join("scenes/grasp_lift.toml"))
        .unwrap_or_else(|e| panic!("{e}"));
    let mut world = World::from_scene(&scene);
    let dt = world.params.dt;
    let weight = {
        let body = &world.bodies[0];
        9.81 * (body.surface_mass() + body.rigid.mass)
    };
    let mut resting = Vec3::zeros();
    let mut grasped_at = None;
    let mut jaws_holding = [0usize; 2];
    let mut held_in_jaw: Vec<(usize, Vec3)> = Vec::new();
    let mut drift: f64 = 0.0;
    let mut force_sum = Vec3::zeros();
    let mut force_samples = 0;
    let mut lifted_lowest = f64::INFINITY;
    let mut released_at = None;
    let mut heights = Vec::new();
    let mut free = Vec::new();
    for tick in 1..=12_000u64 {
        world.step();
        let tool = &world.tools[0];
        let s = &world.bodies[0].surface;
        if tick == 2000 {
            resting = centre_of_mass(&world);
        }
        if grasped_at.is_none() && tool.grasping {
            grasped_at = Some(tick);
            for c in &s.tool_contact {
                if c.grasp.is_some() {
                    jaws_holding[c.part as usize] += 1;
                }
            }
        }
        // The 5 s hold: the held nodes' drift in their jaw's frame, the lowest node, the feedback.
        if tick == 3800 {
            held_in_jaw = (0..s.tool_contact.len())
                .filter(|&i| s.tool_contact[i].grasp.is_some())
                .map(|i| (i, tool.pose.to_tool(&s.position_in_world[i])))
                .collect();
        }
        if (3800..8800).contains(&tick) {
            for (i, p) in &held_in_jaw {
                drift = drift.max((tool.pose.to_tool(&s.position_in_world[*i]) - p).norm());
            }
            lifted_lowest = lifted_lowest.min(lowest_node(&world));
        }
        if (8300..8800).contains(&tick) {
            force_sum += tool.feedback.force_in_world;
            force_samples += 1;
        }
        if tick > 8800 && released_at.is_none() && !tool.grasping {
            released_at = Some(tick);
            assert!(
                s.tool_contact.iter().all(|c| c.grasp.is_none()),
                "nodes still grasped in the tick the jaws let go"
            );
            assert!(tool.jaw > 0.5, "let go at the opening {} rad", tool.jaw);
        }
        if released_at.is_some() {
            heights.push(centre_of_mass(&world).z);
            // Free: touching neither the tool nor the table.
            free.push(
                s.tool_contact.iter().all(|c| c.tool == NO_TOOL) && lowest_node(&world) > 1e-4,
            );
        }
    }
    let grasped_at = grasped_at.expect("the closing jaws never grasped the organ");
    let mean_force = force_sum / force_samples as f64;
    // Free fall: the second difference of the centre of mass's height over the longest stretch of
    // free ticks after the release (at least 40 ms).
    let released_at = released_at.expect("the jaws never let go");
    let first_free = free
        .iter()
        .position(|&f| f)
        .expect("never free after release");
    let free_ticks = free[first_free..].iter().take_while(|&&f| f).count();
    assert!(free_ticks >= 41, "free for {free_ticks} ticks only");
    let n = (free_ticks - 1) & !1;
    let h = &heights[first_free..];
    let acceleration = (h[n] - 2.0 * h[n / 2] + h[0]) / (0.5 * n as f64 * dt).powi(2);
    let end = centre_of_mass(&world);
    println!(
        "grasped at t = {:.3} s ({} + {} nodes on the jaws); lowest node while held {:.4} m; \
         drift of the held nodes in the jaw frame {drift:.2e} m; mean feedback over the last 0.5 s \
         of the hold {:?} N (weight {weight:.5} N); let go at t = {:.3} s; falls at {acceleration:.4} \
         m/s² over {n} ms; rests at {:.5} m (rested at {:.5} m before)",
        grasped_at as f64 * dt,
        jaws_holding[0],
        jaws_holding[1],
        lifted_lowest,
        mean_force.as_slice(),
        released_at as f64 * dt,
        end.z,
        resting.z,
    );
    assert!(
        (2000..=2800).contains(&grasped_at) && jaws_holding[0] >= 2 && jaws_holding[1] >= 2,
        "grasped at tick {grasped_at} with {jaws_holding:?} nodes on the jaws"
    );
    // Lifted 5 cm: the organ is off the table for the whole hold, and its lowest point sits where
    // its rest shape hangs from the jaws (top pinched 5 cm higher).
    assert!(
        lifted_lowest > 0.03,
        "the organ did not leave the table: its lowest node at {lifted_lowest} m"
    );
    assert!(
        (mean_force.z + weight).abs() <= 0.02 * weight,
        "held still, the feedback {} N is not the weight {weight} N",
        mean_force.z
    );
    assert!(mean_force.x.abs() + mean_force.y.abs() < 0.02 * weight);
    assert!(
        drift < 0.5e-3,
        "held nodes drifted {drift} m in the jaw frame"
    );
    assert!(
        (acceleration + 9.81).abs() <= 0.01 * 9.81,
        "the released organ falls at {acceleration} m/s²"
    );
    // Back on the table, where it rested before.
    assert!(
        (end.z - resting.z).abs() < 1e-3 && lowest_node(&world) < 1e-4,
        "the organ rests at {} m, it rested at {} m before",
        end.z,
        resting.z
    );
}

/// Only tissue between the jaws is grasped: a node on a jaw's outer face, or beyond its tip, is not,
/// also when the jaws are closed.
#[test]
fn only_tissue_between_the_jaws_is_grasped() {
    let text = r#"
[[tool]]
name = "grasper"
shape = { grasper = { jaw_length = 0.01, radius = 0.001 } }
input = "script"
script = [{ t = 0.0, position = [0.0, 0.0, 0.0], jaw = 0.6 }]
"#;
    let mut world = World::from_scene(&common::scene(text));
    world.step();
    let tool = &world.tools[0];
    let half = 0.3f64;
    // Jaw 0's axis: through r (cos h, 0, −sin h) along (sin h, 0, cos h); inward (−cos h, 0, sin h).
    let r = 0.001;
    let (s, c) = (half.sin(), half.cos());
    let axis = |t: f64| Vec3::new(r * c + t * s, 0.0, -r * s + t * c);
    let inward = Vec3::new(-c, 0.0, s);
    let inner_face = axis(0.006) + inward * r;
    let outer_face = axis(0.006) - inward * r;
    let beyond_tip = axis(0.0105) + inward * r;
    assert!(between_jaws(tool, 0, &inner_face, half));
    assert!(!between_jaws(tool, 0, &outer_face, half));
    assert!(!between_jaws(tool, 0, &beyond_tip, half));
    // Mirror image for jaw 1.
    let mirror = |p: Vec3| Vec3::new(-p.x, p.y, p.z);
    assert!(between_jaws(tool, 1, &mirror(inner_face), half));
    assert!(!between_jaws(tool, 1, &mirror(outer_face), half));
    // Closed jaws lie on each other along x = 0: the outer faces are a jaw's width out.
    assert!(between_jaws(tool, 0, &Vec3::new(0.0, 0.0, 0.005), 0.0));
    assert!(!between_jaws(tool, 0, &Vec3::new(0.002, 0.0, 0.005), 0.0));
    assert!(!between_jaws(tool, 1, &Vec3::new(-0.002, 0.0, 0.005), 0.0));
}

/// The grasp scene replays bit for bit and two runs give the same trace.
#[test]
fn grasp_lift_replays_bit_for_bit() {
    let dir = std::env::temp_dir().join(format!("palpa-grasp-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let trace = common::session_replays(
        &common::repo_root().join("scenes/grasp_lift.toml"),
        "4",
        &dir,
    );
    // The organ was lifted within those 4 s (so the replay covers a grasp).
    let height = common::trace_column(&trace, "com_z");
    assert!(height.iter().cloned().fold(f64::MIN, f64::max) > 0.05);
    std::fs::remove_dir_all(&dir).ok();
}
