//! `palpa-report`: error against run time (work–precision diagrams) for each integrator on canonical
//! scenes, the coarse-plus-subdivision body against uniformly fine ones, stability maps over link
//! stiffness × node mass with the analytic bound, and the stress scenes' outcomes. Writes a markdown
//! report, SVG plots, the raw CSVs and a JSON summary into `--out DIR`.

use palpa::report as plot;

use anyhow::{Context, Result};
use clap::Parser;
use palpa::Vec3;
use palpa::dynamics::assess::assess;
use palpa::scene::parse_scene;
use palpa::tool::{Tool, ToolInput, ToolPose, ToolShape};
use palpa::world::World;
use plot::{Progress, Series, loglog, machine, stability_map};
use serde_json::{Value, json};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Parser)]
#[command(
    name = "palpa-report",
    about = "Work-precision diagrams, subdivision precision, stability maps and stress outcomes"
)]
struct Cli {
    /// Output directory.
    #[arg(long, default_value = "report-out")]
    out: PathBuf,
    /// Fewer steps, sizes and repeats: a smoke test for CI.
    #[arg(long)]
    quick: bool,
    /// Timed repeats per run (the median is reported); default 3, 1 with --quick.
    #[arg(long)]
    repeats: Option<usize>,
}

const INTEGRATORS: [&str; 3] = ["symplectic", "multirate", "implicit"];

/// Samples are taken every 4 ms of simulated time (every step size used divides it).
const SAMPLE_S: f64 = 0.004;

/// What a run recorded.
struct Trajectory {
    /// Node positions at each sample (after the step that ends on it), tick 0 first.
    positions: Vec<Vec<Vec3>>,
    /// Mean feedback force of the first tool over each sample interval (N).
    forces: Vec<Vec3>,
    /// Wall time (s).
    wall: f64,
    guard_events: u64,
}

fn simulate(world: &mut World, duration: f64) -> Trajectory {
    let dt = world.params.dt;
    let per_sample = (SAMPLE_S / dt).round() as u64;
    let samples = (duration / SAMPLE_S).round() as u64;
    let mut positions = vec![world.bodies[0].surface.position_in_world.clone()];
    let mut forces = Vec::new();
    let start = Instant::now();
    for _ in 0..samples {
        let mut force = Vec3::zeros();
        for _ in 0..per_sample {
            world.step();
            if let Some(t) = world.tools.first() {
                force += t.feedback.force_in_world;
            }
        }
        positions.push(world.bodies[0].surface.position_in_world.clone());
        forces.push(force / per_sample as f64);
    }
    let wall = start.elapsed().as_secs_f64();
    Trajectory {
        positions,
        forces,
        wall,
        guard_events: world.guards.iter().map(|g| g.events).sum(),
    }
}

/// RMS over nodes of the position error at the final sample, and RMS over nodes and samples.
fn position_errors(run: &Trajectory, reference: &[Vec<Vec3>]) -> (f64, f64) {
    let mut sum = 0.0;
    let mut count = 0usize;
    for (a, b) in run.positions.iter().zip(reference).skip(1) {
        for (x, y) in a.iter().zip(b) {
            sum += (x - y).norm_squared();
            count += 1;
        }
    }
    let last = run.positions.len().min(reference.len()) - 1;
    let (a, b) = (&run.positions[last], &reference[last]);
    let final_sq: f64 = a.iter().zip(b).map(|(x, y)| (x - y).norm_squared()).sum();
    (
        (final_sq / a.len().max(1) as f64).sqrt(),
        (sum / count.max(1) as f64).sqrt(),
    )
}

/// Relative RMS error of the sampled feedback force.
fn force_error(run: &Trajectory, reference: &[Vec3]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (f, g) in run.forces.iter().zip(reference) {
        num += (f - g).norm_squared();
        den += g.norm_squared();
    }
    if den > 0.0 {
        (num / den).sqrt()
    } else {
        f64::NAN
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The damped oscillation of a body on its links: a fixed 42-node icosphere, all node masses
/// equal, every node moved by the same 5 mm at rest (edges keep their length), so each node is the
/// oscillator m x'' = −k x − c x' of its link, with a closed-form solution.
const OSC: (f64, f64, f64, f64) = (0.005, 20.0, 0.01, 0.005); // mass, k, c, displacement

fn oscillator(integrator: &str, dt: f64) -> World {
    let text = format!(
        r#"
        [world]
        gravity = [0.0, 0.0, 0.0]
        dt = {dt}
        integrator = "{integrator}"
        [[body]]
        name = "ball"
        mesh = {{ icosphere = {{ radius = 0.05, subdivisions = 1 }} }}
        fixed = true
        surface_stiffness = 50.0
        surface_damping = 0.0
        link_stiffness = {}
        link_damping = {}
        "#,
        OSC.1, OSC.2
    );
    let scene = parse_scene(&text, "oscillator.toml", Path::new(".")).expect("valid scene");
    let mut world = World::from_scene(&scene);
    let s = &mut world.bodies[0].surface;
    for i in 0..s.mass.len() {
        s.mass[i] = OSC.0;
        s.inverse_mass[i] = 1.0 / OSC.0;
        s.air_damping[i] = 0.0;
        s.position_in_world[i].z += OSC.3;
        s.next_position_in_world[i] = s.position_in_world[i];
    }
    world.reassemble();
    world
}

fn oscillator_exact(world: &World, duration: f64) -> Vec<Vec<Vec3>> {
    let (m, k, c, d0) = OSC;
    let w0 = (k / m).sqrt();
    let zeta = c / (2.0 * (k * m).sqrt());
    let wd = w0 * (1.0 - zeta * zeta).sqrt();
    let homologues = world.bodies[0].surface.homologue_in_world.clone();
    (0..=(duration / SAMPLE_S).round() as u64)
        .map(|n| {
            let t = n as f64 * SAMPLE_S;
            let d = (-zeta * w0 * t).exp()
                * (d0 * (wd * t).cos() + zeta * w0 * d0 / wd * (wd * t).sin());
            homologues
                .iter()
                .map(|h| h + Vec3::new(0.0, 0.0, d))
                .collect()
        })
        .collect()
}

fn inclined_plane(integrator: &str, dt: f64) -> World {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/inclined_plane.toml");
    let text = std::fs::read_to_string(&path).expect("scenes/inclined_plane.toml");
    let text = text
        .replacen("dt = 0.001", &format!("dt = {dt}"), 1)
        .replacen(
            "[world]",
            &format!("[world]\nintegrator = \"{integrator}\""),
            1,
        );
    let scene = parse_scene(&text, "inclined_plane.toml", Path::new(".")).expect("valid scene");
    World::from_scene(&scene)
}

/// Probe indentation and stroke on a fixed organ: down 3 mm in 0.2 s, 1 cm sideways in 0.3 s.
fn probe_scene(integrator: &str, dt: f64, level: u32) -> World {
    let text = format!(
        r#"
        [world]
        gravity = [0.0, 0.0, -9.81]
        dt = {dt}
        integrator = "{integrator}"
        [[body]]
        name = "organ"
        mesh = {{ icosphere = {{ radius = 0.05, subdivisions = {level} }} }}
        fixed = true
        surface_mass = 0.3
        surface_stiffness = 40.0
        surface_damping = 0.02
        link_stiffness = 30.0
        link_damping = 0.08
        friction = 0.3
        [[tool]]
        name = "probe"
        shape = {{ sphere = {{ radius = 0.008 }} }}
        input = "script"
        script = [
          {{ t = 0.0, position = [0.002, 0.001, 0.0585] }},
          {{ t = 0.2, position = [0.002, 0.001, 0.0555] }},
          {{ t = 0.5, position = [0.012, 0.001, 0.0555] }},
        ]
        "#
    );
    let scene = parse_scene(&text, "probe.toml", Path::new(".")).expect("valid scene");
    World::from_scene(&scene)
}

struct WorkPrecision {
    rows: Vec<Value>,
    orders: Vec<Value>,
}

fn work_precision(quick: bool, repeats: usize, progress: &mut Progress) -> WorkPrecision {
    let steps_ms: Vec<f64> = if quick {
        vec![4.0, 2.0, 1.0, 0.5]
    } else {
        vec![4.0, 2.0, 1.0, 0.5, 0.25, 0.125]
    };
    let finest = steps_ms.last().copied().unwrap_or(0.125) * 1e-3;
    let probe_level = if quick { 2 } else { 3 };
    type Make = Box<dyn Fn(&str, f64) -> World>;
    let scenes: Vec<(&str, f64, Make)> = vec![
        (
            "oscillator",
            if quick { 0.4 } else { 1.0 },
            Box::new(oscillator),
        ),
        (
            "inclined_plane",
            if quick { 0.3 } else { 0.6 },
            Box::new(inclined_plane),
        ),
        (
            "probe",
            if quick { 0.3 } else { 0.5 },
            Box::new(move |i: &str, dt: f64| probe_scene(i, dt, probe_level)),
        ),
    ];
    let mut rows = Vec::new();
    let mut orders = Vec::new();
    for (name, duration, make) in &scenes {
        // The reference: exact for the oscillator, else the paper's scheme at the finest step / 64.
        let (reference_positions, reference_forces, reference_kind) = if *name == "oscillator" {
            let world = make("symplectic", finest);
            (
                oscillator_exact(&world, *duration),
                Vec::new(),
                "analytic".to_string(),
            )
        } else {
            let dt = finest / 64.0;
            let mut world = make("symplectic", dt);
            let run = simulate(&mut world, *duration);
            (
                run.positions,
                run.forces,
                format!("symplectic at Δt = {:.4} ms", dt * 1e3),
            )
        };
        for integrator in INTEGRATORS {
            let mut previous: Option<(f64, f64, f64, f64)> = None;
            for &h_ms in &steps_ms {
                let dt = h_ms * 1e-3;
                let mut walls = Vec::new();
                let mut last = None;
                for _ in 0..repeats {
                    let mut world = make(integrator, dt);
                    let run = simulate(&mut world, *duration);
                    walls.push(run.wall / duration);
                    last = Some(run);
                }
                let run = last.expect("at least one repeat");
                let (e_final, e_l2) = position_errors(&run, &reference_positions);
                let f_l2 = if reference_forces.is_empty() {
                    f64::NAN
                } else {
                    force_error(&run, &reference_forces)
                };
                let cost = median(walls);
                rows.push(json!({
                    "scene": name,
                    "integrator": integrator,
                    "dt_ms": h_ms,
                    "reference": reference_kind,
                    "error_final_m": e_final,
                    "error_l2_m": e_l2,
                    "force_error_l2_rel": if f_l2.is_finite() { json!(f_l2) } else { Value::Null },
                    "seconds_per_simulated_second": cost,
                    "guard_events": run.guard_events,
                }));
                if let Some((h2, f2, l2, ff2)) = previous {
                    let p = |coarse: f64, fine: f64| (coarse / fine).log2() / (h2 / h_ms).log2();
                    orders.push(json!({
                        "scene": name,
                        "integrator": integrator,
                        "from_dt_ms": h2,
                        "to_dt_ms": h_ms,
                        "order_final": p(f2, e_final),
                        "order_l2": p(l2, e_l2),
                        "order_force_l2": if f_l2.is_finite() { json!(p(ff2, f_l2)) } else { Value::Null },
                    }));
                }
                previous = Some((h_ms, e_final, e_l2, f_l2));
                progress.step(&format!("{name} {integrator} {h_ms} ms"));
            }
        }
    }
    WorkPrecision { rows, orders }
}

/// The precision test's set-up (tests/refinement.rs): a fixed ball with mesh-independent mechanics
/// and a 5 mm probe pressed 4 mm between the coarse nodes; mean force over the last 0.1 s.
fn pressed_ball(level: u32, subdivision: bool) -> World {
    let key = if subdivision {
        "subdivision = { max_depth = 6, min_edge = 0.0015, coarsen_after = 5.0 }"
    } else {
        ""
    };
    let text = format!(
        r#"
        [world]
        gravity = [0.0, 0.0, 0.0]
        integrator = "multirate"
        [[body]]
        name = "ball"
        mesh = {{ icosphere = {{ radius = 0.05, subdivisions = {level} }} }}
        fixed = true
        surface_mass = 2.0
        surface_stiffness = 40.0
        surface_damping = 0.02
        friction = 0.0
        {key}
        "#
    );
    let scene = parse_scene(&text, "ball.toml", Path::new(".")).expect("valid scene");
    let mut world = World::from_scene(&scene);
    world.bodies[0].set_links_per_area(5e4, 200.0);
    world.reassemble();
    world.add_tool(Tool::new(
        "probe",
        ToolShape::Sphere { radius: 0.005 },
        ToolInput::Ipc,
        None,
    ));
    world
}

/// Presses at (x, y); returns the mean force and the wall time per simulated second.
fn press(world: &mut World, x: f64, y: f64) -> (f64, f64) {
    let top = (0.05f64 * 0.05 - x * x - y * y).sqrt();
    let mut sum = 0.0;
    let start = Instant::now();
    for k in 0..=1000 {
        let pressed = 0.004 * (k as f64 / 500.0).min(1.0);
        world.tools[0].set_target(
            ToolPose {
                position_in_world: Vec3::new(x, y, top + 0.005 - pressed),
                ..ToolPose::default()
            },
            0.0,
        );
        world.step();
        if k > 900 {
            sum += world.tools[0].feedback.force_in_world.z;
        }
    }
    (sum / 100.0, start.elapsed().as_secs_f64() / 1.001)
}

fn subdivision_precision(quick: bool, progress: &mut Progress) -> Vec<Value> {
    let points: &[(f64, f64)] = if quick {
        &[(0.006, 0.004)]
    } else {
        &[
            (0.006, 0.004),
            (0.003, 0.009),
            (-0.005, 0.007),
            (0.011, -0.002),
        ]
    };
    let reference_level = if quick { 5 } else { 6 };
    let mut variants: Vec<(String, u32, bool)> =
        vec![("coarse 162 + subdivision (area)".into(), 2, true)];
    for level in 2..reference_level {
        variants.push((format!("uniform level {level}"), level, false));
    }
    let mut rows = Vec::new();
    let references: Vec<(f64, f64)> = points
        .iter()
        .map(|&(x, y)| press(&mut pressed_ball(reference_level, false), x, y))
        .collect();
    let reference_nodes = pressed_ball(reference_level, false).bodies[0].node_count();
    progress.step("subdivision reference");
    for (name, level, subdivision) in variants {
        let mut errors = Vec::new();
        let mut costs = Vec::new();
        let mut nodes = 0;
        for (&(x, y), &(reference, _)) in points.iter().zip(&references) {
            let mut world = pressed_ball(level, subdivision);
            let (force, cost) = press(&mut world, x, y);
            nodes = nodes.max(world.bodies[0].node_count());
            errors.push((force - reference).abs() / reference);
            costs.push(cost);
        }
        rows.push(json!({
            "variant": name,
            "nodes": nodes,
            "mean_abs_force_error_rel": errors.iter().sum::<f64>() / errors.len() as f64,
            "worst_force_error_rel": errors.iter().cloned().fold(0.0, f64::max),
            "seconds_per_simulated_second": median(costs),
        }));
        progress.step(&name);
    }
    rows.push(json!({
        "variant": format!("reference: uniform level {reference_level}"),
        "nodes": reference_nodes,
        "mean_abs_force_error_rel": 0.0,
        "worst_force_error_rel": 0.0,
        "seconds_per_simulated_second": median(references.iter().map(|r| r.1).collect()),
    }));
    rows
}

/// A fixed 42-node icosphere, all node masses `mass`, links and edges of stiffness `k`, 2 % damping,
/// each node displaced in a fixed pseudo-random direction by 1 mm, or less for fast nodes so that the
/// exact motion stays under 5 cm/s (far inside the guard's speed bound: what the map shows is the
/// integrator, not the plausibility limits).
fn stability_cell(integrator: &str, k: f64, mass: f64) -> World {
    let c = 2.0 * 0.02 * (k * mass).sqrt();
    let text = format!(
        r#"
        [world]
        gravity = [0.0, 0.0, 0.0]
        integrator = "{integrator}"
        [[body]]
        name = "ball"
        mesh = {{ icosphere = {{ radius = 0.05, subdivisions = 1 }} }}
        fixed = true
        surface_stiffness = {k}
        surface_damping = {c}
        link_stiffness = {k}
        link_damping = {c}
        "#
    );
    let scene = parse_scene(&text, "cell.toml", Path::new(".")).expect("valid scene");
    let mut world = World::from_scene(&scene);
    let amplitude = (0.05 / (13.0 * k / mass).sqrt()).min(0.001);
    let s = &mut world.bodies[0].surface;
    for i in 0..s.mass.len() {
        s.mass[i] = mass;
        s.inverse_mass[i] = 1.0 / mass;
        s.air_damping[i] = 0.0;
        let a = (i as f64 * 2.399_963) % std::f64::consts::TAU;
        let b = ((i * 7919) % 13) as f64 / 13.0 * 2.0 - 1.0;
        let dir = Vec3::new(
            a.cos() * (1.0 - b * b).sqrt(),
            a.sin() * (1.0 - b * b).sqrt(),
            b,
        );
        s.position_in_world[i] += dir * amplitude;
        s.next_position_in_world[i] = s.position_in_world[i];
    }
    world.reassemble();
    world
}

fn logspace(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|k| lo * (hi / lo).powf(k as f64 / (n - 1).max(1) as f64))
        .collect()
}

fn stability_maps(quick: bool, out: &Path, progress: &mut Progress) -> Result<(Vec<Value>, Value)> {
    let n = if quick { 4 } else { 8 };
    let stiffness = logspace(1.0, 1e5, n);
    let masses = logspace(1e-6, 1e-1, n);
    let dt = 0.001;
    // Worst node of the 42-node icosphere: its link and six edges, Gershgorin: ω² = 13 k / m.
    let bound_mass = |k: f64| 13.0 * k * dt * dt / 4.0;
    let mut rows = Vec::new();
    let mut agreement = serde_json::Map::new();
    for integrator in INTEGRATORS {
        let mut cells = Vec::new();
        let (mut agree, mut total, mut stable_count, mut beyond) = (0, 0, 0, 0);
        for &k in &stiffness {
            for &m in &masses {
                let mut world = stability_cell(integrator, k, m);
                let run = assess(&mut world, 0.3);
                let stable = run.passes();
                let predicted = m > bound_mass(k);
                total += 1;
                agree += (predicted == stable) as u32;
                stable_count += stable as u32;
                beyond += (stable && !predicted) as u32;
                cells.push((k, m, stable));
                rows.push(json!({
                    "integrator": integrator,
                    "link_stiffness_n_per_m": k,
                    "node_mass_kg": m,
                    "stable": stable,
                    "guard_events": run.guard_events,
                    "finite": run.finite,
                    "explicit_bound_predicts_stable": predicted,
                }));
            }
        }
        agreement.insert(
            integrator.into(),
            json!({
                "cells": total,
                "stable": stable_count,
                "agree_with_explicit_bound": agree,
                "stable_beyond_explicit_bound": beyond,
            }),
        );
        let bound: Vec<(f64, f64)> = logspace(stiffness[0], stiffness[n - 1], 50)
            .into_iter()
            .map(|k| (k, bound_mass(k)))
            .collect();
        stability_map(
            &out.join(format!("stability_{integrator}.svg")),
            &format!("{integrator} at Δt = 1 ms (42 nodes, 2 % damping)"),
            "link and edge stiffness k (N/m)",
            "node mass m (kg)",
            &cells,
            &bound,
        )?;
        progress.step(&format!("stability map {integrator}"));
    }
    Ok((rows, Value::Object(agreement)))
}

fn extremes(quick: bool, progress: &mut Progress) -> Result<Vec<Value>> {
    let cases = [
        ("stiff.toml", 1.0f64),
        ("light_nodes.toml", 1.0),
        ("strip.toml", 1.0),
        ("degenerate.toml", 1.0),
        ("drop.toml", 1.0),
        ("teleport.toml", 1.5),
        ("dt4.toml", 2.0),
    ];
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/stress");
    let mut rows = Vec::new();
    for (file, seconds) in cases {
        let text = std::fs::read_to_string(dir.join(file))
            .with_context(|| format!("cannot read scenes/stress/{file}"))?;
        for integrator in INTEGRATORS {
            let text = text.replacen(
                "[world]",
                &format!("[world]\nintegrator = \"{integrator}\""),
                1,
            );
            let scene = parse_scene(&text, file, &dir).map_err(|e| anyhow::anyhow!("{e}"))?;
            let mut world = World::from_scene(&scene);
            let seconds = if quick { seconds.min(0.3) } else { seconds };
            let run = assess(&mut world, seconds);
            let outcome = if !run.finite {
                "non-finite".to_string()
            } else if run.passes() {
                "pass".to_string()
            } else {
                format!("guarded ({} events)", run.guard_events)
            };
            rows.push(json!({
                "scene": file,
                "integrator": integrator,
                "seconds": seconds,
                "outcome": outcome,
                "guard_events": run.guard_events,
                "worst_energy_excess_j": run.worst_energy_excess,
                "worst_stretch_over_size": run.worst_stretch_ratio,
                "worst_gap_m": if run.worst_gap.is_finite() { json!(run.worst_gap) } else { Value::Null },
            }));
        }
        progress.step(file);
    }
    Ok(rows)
}

fn csv(rows: &[Value], columns: &[&str]) -> String {
    let mut out = columns.join(",");
    out.push('\n');
    for row in rows {
        let cells: Vec<String> = columns
            .iter()
            .map(|c| match &row[*c] {
                Value::String(s) => s.replace(',', ";"),
                Value::Null => String::new(),
                v => v.to_string(),
            })
            .collect();
        out += &cells.join(",");
        out.push('\n');
    }
    out
}

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    let quick = cli.quick;
    let repeats = cli.repeats.unwrap_or(if quick { 1 } else { 3 }).max(1);
    let out = &cli.out;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let dts = if quick { 4 } else { 6 };
    let sub_variants = if quick { 4 } else { 6 };
    let mut progress = Progress::new("palpa-report", 3 * 3 * dts + sub_variants + 3 + 7);
    let started = Instant::now();

    let wp = work_precision(quick, repeats, &mut progress);
    let sub = subdivision_precision(quick, &mut progress);
    let (map, agreement) = stability_maps(quick, out, &mut progress)?;
    let ext = extremes(quick, &mut progress)?;

    write_plots(out, &wp, &sub)?;
    write_csvs(out, &wp, &sub, &map, &ext)?;
    let summary = json!({
        "command": format!("palpa-report{} --out {}", if quick { " --quick" } else { "" }, out.display()),
        "date": plot::utc_now(),
        "machine": machine(),
        "repeats": repeats,
        "wall_seconds": started.elapsed().as_secs_f64(),
        "work_precision": wp.rows,
        "orders": wp.orders,
        "subdivision": sub,
        "stability_map": map,
        "stability_bound_agreement": agreement,
        "extremes": ext,
    });
    std::fs::write(
        out.join("report.json"),
        serde_json::to_string_pretty(&summary)?,
    )?;
    let md = markdown(&summary);
    std::fs::write(out.join("report.md"), &md)?;
    println!("{md}");
    Ok(())
}

/// Error against run time (log–log), one curve per integrator, per scene; and the subdivision's
/// variants against uniform meshes.
fn write_plots(out: &Path, wp: &WorkPrecision, sub: &[Value]) -> Result<()> {
    for (scene, key, label) in [
        (
            "oscillator",
            "error_l2_m",
            "node position error, L2 over time (m)",
        ),
        (
            "inclined_plane",
            "error_l2_m",
            "node position error, L2 over time (m)",
        ),
        (
            "probe",
            "force_error_l2_rel",
            "feedback force error, relative L2 over time",
        ),
    ] {
        let series: Vec<Series> = INTEGRATORS
            .iter()
            .map(|i| Series {
                name: i.to_string(),
                points: wp
                    .rows
                    .iter()
                    .filter(|r| r["scene"] == scene && r["integrator"] == *i)
                    .map(|r| (num(&r["seconds_per_simulated_second"]), num(&r[key])))
                    .collect(),
                points_only: false,
            })
            .collect();
        loglog(
            &out.join(format!("work_precision_{scene}.svg")),
            &format!("{scene}: error against run time (Δt 4 ms → finest)"),
            "wall seconds per simulated second",
            label,
            &series,
        )?;
    }
    loglog(
        &out.join("work_precision_subdivision.svg"),
        "Probe press: coarse + subdivision against uniform meshes",
        "wall seconds per simulated second",
        "feedback force error (relative, mean over points)",
        &sub.iter()
            .filter(|r| num(&r["mean_abs_force_error_rel"]) > 0.0)
            .map(|r| Series {
                name: format!(
                    "{} ({} nodes)",
                    r["variant"].as_str().unwrap_or(""),
                    r["nodes"]
                ),
                points: vec![(
                    num(&r["seconds_per_simulated_second"]),
                    num(&r["mean_abs_force_error_rel"]),
                )],
                points_only: true,
            })
            .collect::<Vec<_>>(),
    )?;

    Ok(())
}

/// The tables of the report as CSV files.
fn write_csvs(
    out: &Path,
    wp: &WorkPrecision,
    sub: &[Value],
    map: &[Value],
    ext: &[Value],
) -> Result<()> {
    std::fs::write(
        out.join("work_precision.csv"),
        csv(
            &wp.rows,
            &[
                "scene",
                "integrator",
                "dt_ms",
                "reference",
                "error_final_m",
                "error_l2_m",
                "force_error_l2_rel",
                "seconds_per_simulated_second",
                "guard_events",
            ],
        ),
    )?;
    std::fs::write(
        out.join("convergence.csv"),
        csv(
            &wp.orders,
            &[
                "scene",
                "integrator",
                "from_dt_ms",
                "to_dt_ms",
                "order_final",
                "order_l2",
                "order_force_l2",
            ],
        ),
    )?;
    std::fs::write(
        out.join("subdivision.csv"),
        csv(
            sub,
            &[
                "variant",
                "nodes",
                "mean_abs_force_error_rel",
                "worst_force_error_rel",
                "seconds_per_simulated_second",
            ],
        ),
    )?;
    std::fs::write(
        out.join("stability_map.csv"),
        csv(
            map,
            &[
                "integrator",
                "link_stiffness_n_per_m",
                "node_mass_kg",
                "stable",
                "guard_events",
                "finite",
                "explicit_bound_predicts_stable",
            ],
        ),
    )?;
    std::fs::write(
        out.join("extremes.csv"),
        csv(
            ext,
            &[
                "scene",
                "integrator",
                "seconds",
                "outcome",
                "guard_events",
                "worst_energy_excess_j",
                "worst_stretch_over_size",
                "worst_gap_m",
            ],
        ),
    )?;
    Ok(())
}

fn markdown(s: &Value) -> String {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "# palpa-report\n\n`{}` — {} — {} — median of {} timed run(s)\n",
        s["command"].as_str().unwrap_or(""),
        s["date"].as_str().unwrap_or(""),
        s["machine"].as_str().unwrap_or(""),
        s["repeats"]
    );
    md += "## Error against run time\n\n\
           Errors: node positions, RMS over the nodes at the final time (`final`) and RMS over nodes and \
           4 ms samples (`L2`); feedback force (probe scene), relative RMS of its 4 ms means. References: \
           the closed-form damped oscillation for `oscillator`, the paper's scheme at the finest Δt / 64 \
           otherwise. Run time: wall seconds per simulated second. Order p = log2(e(2h)/e(h)).\n\n";
    for scene in ["oscillator", "inclined_plane", "probe"] {
        let _ = writeln!(
            md,
            "### {scene}\n\n![{scene}](work_precision_{scene}.svg)\n\n\
             | integrator | Δt (ms) | error final (m) | error L2 (m) | force error L2 | s per sim. s | guard | p (L2) |\n\
             | --- | --- | --- | --- | --- | --- | --- | --- |"
        );
        for r in s["work_precision"].as_array().into_iter().flatten() {
            if r["scene"] != scene {
                continue;
            }
            let order = s["orders"]
                .as_array()
                .into_iter()
                .flatten()
                .find(|o| {
                    o["scene"] == scene
                        && o["integrator"] == r["integrator"]
                        && o["to_dt_ms"] == r["dt_ms"]
                })
                .map_or(String::from("—"), |o| {
                    format!("{:.2}", num(&o["order_l2"]))
                });
            let _ = writeln!(
                md,
                "| {} | {} | {:.3e} | {:.3e} | {} | {:.4} | {} | {} |",
                r["integrator"].as_str().unwrap_or(""),
                r["dt_ms"],
                num(&r["error_final_m"]),
                num(&r["error_l2_m"]),
                r["force_error_l2_rel"]
                    .as_f64()
                    .map_or("—".into(), |v| format!("{v:.3e}")),
                num(&r["seconds_per_simulated_second"]),
                r["guard_events"],
                order
            );
        }
        md += "\n";
    }
    md += "## Coarse body with subdivision against uniformly fine bodies\n\n\
           The precision test's press (5 mm probe, 4 mm, between coarse nodes, links per unit area): \
           error of the held force against the finest uniform mesh, and run time.\n\n\
           ![subdivision](work_precision_subdivision.svg)\n\n\
           | variant | nodes | mean error | worst error | s per sim. s |\n| --- | --- | --- | --- | --- |\n";
    for r in s["subdivision"].as_array().into_iter().flatten() {
        let _ = writeln!(
            md,
            "| {} | {} | {:.1} % | {:.1} % | {:.4} |",
            r["variant"].as_str().unwrap_or(""),
            r["nodes"],
            100.0 * num(&r["mean_abs_force_error_rel"]),
            100.0 * num(&r["worst_force_error_rel"]),
            num(&r["seconds_per_simulated_second"])
        );
    }
    md += "\n## Stability maps at Δt = 1 ms\n\n\
           A fixed 42-node body, all node masses m, links and edges of stiffness k, 2 % damping, nodes \
           displaced 1 mm (less where the exact motion would exceed 5 cm/s), 0.3 s; a cell is stable when nothing is non-finite, the energy stays in its \
           budget, no node strays further than the body's size and the guard never acts. The line is \
           the explicit scheme's bound ω·Δt = 2 for the worst node (ω² = 13 k / m by Gershgorin).\n\n";
    for i in INTEGRATORS {
        let a = &s["stability_bound_agreement"][i];
        let _ = writeln!(
            md,
            "- `{i}`: {} of {} cells stable; {} cells on the side the explicit bound predicts; {} stable \
             beyond it. ![{i}](stability_{i}.svg)",
            a["stable"],
            a["cells"],
            a["agree_with_explicit_bound"],
            a["stable_beyond_explicit_bound"]
        );
    }
    md += "\n## Extreme cases (scenes/stress)\n\n| scene | symplectic | multirate | implicit |\n| --- | --- | --- | --- |\n";
    let ext = s["extremes"].as_array().cloned().unwrap_or_default();
    for chunk in ext.chunks(3) {
        let _ = writeln!(
            md,
            "| {} | {} |",
            chunk[0]["scene"].as_str().unwrap_or(""),
            chunk
                .iter()
                .map(|r| r["outcome"].as_str().unwrap_or("").to_string())
                .collect::<Vec<_>>()
                .join(" | ")
        );
    }
    md
}
