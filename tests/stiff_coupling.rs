//! Regression for issue 12, finding 2: a stiff rigid coupling diverged with every integrator, the
//! implicit one included, because the rigid component was stepped explicitly. The scene
//! (`scenes/stress/stiff_links.toml`): a 162-node sphere, r 4 cm, surface 0.05 kg, rigid 0.05 kg,
//! surface and link stiffness 5e4 N/m, dampings 5, dropped 6 cm onto a table at 1 ms — the rigid
//! component's ω·Δt on its links is about 12.7 (limit 2).
//!
//! Implicit (nodes and rigid component solved together) and multirate (the rigid component
//! sub-stepped with the nodes) must hold the energy below 1.2× the energy the drop releases, come to
//! rest on the table, and never put a node below it. The explicit reference cannot: the divergence
//! guard must contain it (finite state, the body where the scene put it) and say so (events counted,
//! its flag on the tick).

mod common;

use palpa::dynamics::Integrator;
use palpa::dynamics::guard::body_energy;
use palpa::world::World;

fn world_with(integrator: Integrator) -> World {
    World::from_scene(&common::scene_file_with_integrator(
        "scenes/stress/stiff_links.toml",
        integrator.name(),
    ))
}

struct Run {
    /// Largest energy above the resting state, over the energy the drop releases.
    worst_energy_ratio: f64,
    /// Lowest node height over the run (m).
    lowest_node: f64,
    /// Smallest kinetic energy from 0.5 s on (J): the drop lands at about 0.11 s.
    resting_kinetic: f64,
    /// Height of the rigid component's centre at the end (m).
    final_height: f64,
    /// Largest distance of the rigid component from its start (m).
    farthest: f64,
    guard_events: u64,
    ticks_flagged: u64,
    finite: bool,
}

fn drop_for(integrator: Integrator, seconds: f64) -> Run {
    let mut world = world_with(integrator);
    let gravity = world.params.gravity;
    let body = &world.bodies[0];
    let total_mass = body.total_mass();
    let start = body.rigid.position_in_world;
    let radius = 0.04;
    // At rest on the table the centre is one radius up (the stiff sphere barely flattens).
    let resting_energy = total_mass * gravity.norm() * radius;
    let released = body_energy(body, &gravity) - resting_energy;
    assert!(
        (released - total_mass * 9.81 * 0.06).abs() < 1e-9,
        "a 6 cm drop of 0.1 kg: {released} J"
    );
    let mut run = Run {
        worst_energy_ratio: 0.0,
        lowest_node: f64::INFINITY,
        resting_kinetic: f64::INFINITY,
        final_height: 0.0,
        farthest: 0.0,
        guard_events: 0,
        ticks_flagged: 0,
        finite: true,
    };
    let ticks = (seconds / world.params.dt).round() as u64;
    for _ in 0..ticks {
        world.step();
        let body = &world.bodies[0];
        if !body.is_finite() {
            run.finite = false;
            break;
        }
        if world.counters.guard_events > 0 {
            run.ticks_flagged += 1;
        }
        let energy = body_energy(body, &gravity) - resting_energy;
        run.worst_energy_ratio = run.worst_energy_ratio.max(energy / released);
        for x in &body.surface.position_in_world {
            run.lowest_node = run.lowest_node.min(x.z);
        }
        if world.tick >= 500 {
            run.resting_kinetic = run
                .resting_kinetic
                .min(body.kinetic_energy() + body.rigid.kinetic_energy());
        }
        run.farthest = run
            .farthest
            .max((body.rigid.position_in_world - start).norm());
    }
    let body = &world.bodies[0];
    run.final_height = body.rigid.position_in_world.z;
    run.guard_events = world.guards[0].events;
    eprintln!(
        "{}: energy ≤ {:.3}× released, lowest node {:.2e} m, resting kinetic {:.2e} J, centre at {:.4} m, \
         farthest {:.3} m, guard {} events on {} ticks",
        integrator.name(),
        run.worst_energy_ratio,
        run.lowest_node,
        run.resting_kinetic,
        run.final_height,
        run.farthest,
        run.guard_events,
        run.ticks_flagged
    );
    run
}

fn assert_stable(integrator: Integrator) {
    let run = drop_for(integrator, 3.0);
    assert!(run.finite, "{}: state became non-finite", integrator.name());
    assert_eq!(
        run.guard_events,
        0,
        "{}: the guard acted",
        integrator.name()
    );
    assert!(
        run.worst_energy_ratio < 1.2,
        "{}: energy reached {:.3}× the released energy",
        integrator.name(),
        run.worst_energy_ratio
    );
    assert!(
        run.lowest_node > -1e-6,
        "{}: a node went {:.3e} m below the table",
        integrator.name(),
        run.lowest_node
    );
    // An icosphere balances on a few nodes: it may later tip onto a face and roll (energy going
    // down, not up), as a polyhedron does; what is asked is that the impact's motion dies out.
    assert!(
        run.resting_kinetic < 1e-9,
        "{}: never came to rest after the impact ({:.3e} J)",
        integrator.name(),
        run.resting_kinetic
    );
    assert!(
        (run.final_height - 0.04).abs() < 2e-3,
        "{}: not resting on the table (centre at {} m)",
        integrator.name(),
        run.final_height
    );
}

#[test]
fn stiff_rigid_coupling_is_stable_with_the_implicit_integrator() {
    assert_stable(Integrator::Implicit);
}

#[test]
fn stiff_rigid_coupling_is_stable_with_the_multirate_integrator() {
    let world = world_with(Integrator::Multirate);
    let substeps = world.rigid_substeps_of(0);
    assert!(
        substeps.is_some_and(|s| s >= 8),
        "the rigid component must be sub-stepped: {substeps:?}"
    );
    assert_stable(Integrator::Multirate);
}

#[test]
fn stiff_rigid_coupling_under_the_explicit_scheme_is_contained_by_the_guard() {
    let run = drop_for(Integrator::Symplectic, 1.0);
    assert!(run.finite, "non-finite state escaped the guard");
    assert!(run.guard_events > 0, "the explicit scheme cannot hold this");
    assert_eq!(
        run.guard_events, run.ticks_flagged,
        "every event is reported on its tick"
    );
    assert!(
        run.farthest < 0.2,
        "the body left its scene: {} m from its start",
        run.farthest
    );
    assert!(
        run.lowest_node > -0.01,
        "the body fell through the table ({} m)",
        run.lowest_node
    );
    // Between restores the energy stays within the guard's budget: the initial energy plus half of
    // it plus 0.05 J (E₀ = 0.098 J above the table, the released energy 0.059 J): 2.70× the released.
    let allowed = (1.5 * 0.0981 + 0.05 - 0.0392) / 0.0589;
    assert!(
        run.worst_energy_ratio < allowed,
        "energy left the guard's budget: {:.3}× the released energy (allowed {allowed:.2})",
        run.worst_energy_ratio
    );
}

#[test]
fn check_states_the_rigid_margin_of_the_stiff_scene() {
    let world = world_with(Integrator::Symplectic);
    let m = world.stability_margins()[0];
    // Two-body modes against the whole surface (reduced mass μ = 0.025 kg): translation
    // √(Σk / μ) Δt = √(162·5e4 / 0.025)·1e-3 = 18.0; rotation, the worse, with the solid sphere's
    // I = 2/5 M r², the surface shell's 2/3 m_s r² and the links' arms at r = 4 cm: about 25.5.
    assert!(
        (24.5..26.5).contains(&m.rigid_omega_dt),
        "rigid ω·Δt on its links: {}",
        m.rigid_omega_dt
    );
    assert!(m.rigid_margin < 0.0);
}
