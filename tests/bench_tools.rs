//! `palpa-bench` and `palpa-report` in their `--quick` modes: they run, write their files, and the
//! figures in them parse, are finite and hang together (the paper's scheme converges at order 1 on
//! the damped oscillator; the explicit bound predicts where the paper's scheme is stable).
//!
//! What the benchmarks time (round trips, the floor, answered shares, step times, slopes) depends on
//! the machine and its load, and is reported by the tools, not asserted here: these tests check
//! counts, internal consistency and the accuracy figures, which do not depend on the clock.

mod common;

use serde_json::Value;
use std::path::Path;
use std::process::Command;
use std::sync::Mutex;

/// The tools time things: one at a time.
static SERIAL: Mutex<()> = Mutex::new(());

fn run(exe: &str, args: &[&str]) {
    let output = Command::new(exe)
        .args(args)
        .output()
        .expect("the tool starts");
    assert!(
        output.status.success(),
        "{exe} {args:?} failed:\n{}\n{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
}

fn json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn finite(v: &Value) -> f64 {
    let x = v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"));
    assert!(x.is_finite(), "not finite: {v}");
    x
}

fn out_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("palpa_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn bench_latency_quick_writes_consistent_figures() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let dir = out_dir("bench_latency");
    run(
        env!("CARGO_BIN_EXE_palpa-bench"),
        &["latency", "--quick", "--out", dir.to_str().unwrap()],
    );
    for file in [
        "latency.md",
        "latency_round_trip.svg",
        "latency_tick_compute.svg",
        "latency_timings.csv",
    ] {
        assert!(dir.join(file).is_file(), "{file} written");
    }
    let r = json(&dir.join("latency.json"));
    // The device sends one pose per tick of its 3 s (however late it wakes); some are answered.
    let sent = finite(&r["poses_sent"]);
    let answered = finite(&r["poses_answered"]);
    assert_eq!(sent, 3000.0);
    assert!(
        0.0 < answered && answered <= sent,
        "{answered} of {sent} answered"
    );
    let rt = &r["round_trip_us"];
    let (median, p99, p999, max) = (
        finite(&rt["median"]),
        finite(&rt["p99"]),
        finite(&rt["p99_9"]),
        finite(&rt["max"]),
    );
    assert!(
        0.0 < median && median <= p99 && p99 <= p999 && p999 <= max,
        "{rt}"
    );
    let floor = finite(&r["floor_ping_pong_us"]["median"]);
    assert!(floor > 0.0, "floor {floor} µs");
    assert!(
        (finite(&r["ratio_median_round_trip_to_floor"]) - median / floor).abs()
            < 1e-6 * median / floor
    );
    let d = &r["daemon"];
    assert!(finite(&d["ticks"]) > 0.0);
    let (mean, p99c, maxc) = (
        finite(&d["compute_mean_us"]),
        finite(&d["compute_p99_us"]),
        finite(&d["compute_max_us"]),
    );
    assert!(0.0 < mean && mean <= maxc && p99c <= maxc, "{d}");
    assert!(finite(&d["share_of_median_round_trip"]) > 0.0);
    finite(&d["lateness_mean_us"]);
    finite(&d["synchronicity_misses"]);
    // The histogram file sums to the ticks.
    let csv = std::fs::read_to_string(dir.join("latency_timings.csv")).unwrap();
    let ticks: u64 = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).unwrap().parse::<u64>().unwrap())
        .sum();
    assert_eq!(ticks as f64, finite(&d["ticks"]));
}

#[test]
fn bench_scaling_quick_writes_consistent_figures() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let dir = out_dir("bench_scaling");
    run(
        env!("CARGO_BIN_EXE_palpa-bench"),
        &["scaling", "--quick", "--out", dir.to_str().unwrap()],
    );
    assert!(dir.join("scaling.md").is_file() && dir.join("scaling.svg").is_file());
    let r = json(&dir.join("scaling.json"));
    let rows = r["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 6);
    for row in rows {
        let median = finite(&row["median_us"]);
        assert!(median > 0.0);
        let (p99, p999, max) = (
            finite(&row["p99_us"]),
            finite(&row["p999_us"]),
            finite(&row["max_us"]),
        );
        assert!(median <= p99 && p99 <= p999 && p999 <= max, "{row}");
        let stages = row["stages_mean_us"].as_object().unwrap();
        assert!(!stages.is_empty(), "{row}");
        assert!(stages.values().map(finite).all(|t| t >= 0.0), "{row}");
        if row["probe"] == true {
            assert!(
                finite(&row["contacts"]) > 0.0,
                "the probe is in contact: {row}"
            );
        }
    }
    // The fitted slope is reported (README, Performance); its value depends on the machine.
    finite(&r["slope_without_probe"]);
}

#[test]
fn report_quick_writes_consistent_figures() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let dir = out_dir("report");
    run(
        env!("CARGO_BIN_EXE_palpa-report"),
        &["--quick", "--out", dir.to_str().unwrap()],
    );
    for file in [
        "report.md",
        "work_precision.csv",
        "convergence.csv",
        "subdivision.csv",
        "stability_map.csv",
        "extremes.csv",
        "work_precision_oscillator.svg",
        "work_precision_inclined_plane.svg",
        "work_precision_probe.svg",
        "work_precision_subdivision.svg",
        "stability_symplectic.svg",
        "stability_multirate.svg",
        "stability_implicit.svg",
    ] {
        assert!(dir.join(file).is_file(), "{file} written");
    }
    let r = json(&dir.join("report.json"));
    let rows = r["work_precision"].as_array().unwrap();
    assert_eq!(
        rows.len(),
        3 * 3 * 4,
        "three scenes, three integrators, four steps"
    );
    for row in rows {
        assert!(
            finite(&row["error_l2_m"]) > 0.0 && finite(&row["seconds_per_simulated_second"]) > 0.0
        );
    }
    // The paper's scheme is first order on the damped oscillation (exact reference).
    let order = r["orders"]
        .as_array()
        .unwrap()
        .iter()
        .find(|o| {
            o["scene"] == "oscillator" && o["integrator"] == "symplectic" && o["to_dt_ms"] == 0.5
        })
        .expect("an order for 1 → 0.5 ms");
    let p = finite(&order["order_l2"]);
    let p_final = finite(&order["order_final"]);
    assert!((0.8..1.2).contains(&p), "observed order {p}");
    assert!(
        (0.8..1.2).contains(&p_final),
        "observed order at the final time {p_final}"
    );
    // The error falls with the step on the oscillator for every integrator.
    for integrator in ["symplectic", "multirate", "implicit"] {
        let errors: Vec<f64> = rows
            .iter()
            .filter(|x| x["scene"] == "oscillator" && x["integrator"] == integrator)
            .map(|x| finite(&x["error_l2_m"]))
            .collect();
        assert!(
            errors.windows(2).all(|w| w[1] < w[0]),
            "{integrator}: {errors:?}"
        );
    }
    // Coarse + subdivision beats the same coarse mesh without it, within 10 % of the reference.
    let sub = r["subdivision"].as_array().unwrap();
    let error_of = |name: &str| {
        finite(
            &sub.iter()
                .find(|x| x["variant"].as_str().unwrap().starts_with(name))
                .unwrap()["mean_abs_force_error_rel"],
        )
    };
    assert!(error_of("coarse 162 + subdivision") < 0.10);
    assert!(error_of("uniform level 2") > 0.5);
    // The explicit bound predicts where the paper's scheme is stable; the others go beyond it.
    let a = &r["stability_bound_agreement"];
    let cells = finite(&a["symplectic"]["cells"]);
    assert!(
        finite(&a["symplectic"]["agree_with_explicit_bound"]) >= 0.9 * cells,
        "{a}"
    );
    assert!(
        finite(&a["multirate"]["stable_beyond_explicit_bound"]) > 0.0,
        "{a}"
    );
    assert!(
        finite(&a["implicit"]["stable"]) >= finite(&a["symplectic"]["stable"]),
        "{a}"
    );
    let extremes = r["extremes"].as_array().unwrap();
    assert_eq!(extremes.len(), 21);
    assert!(extremes.iter().all(|x| x["outcome"] != "non-finite"));
}

#[test]
fn bench_cut_quick_writes_consistent_figures() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let dir = out_dir("bench_cut");
    run(
        env!("CARGO_BIN_EXE_palpa-bench"),
        &["cut", "--quick", "--out", dir.to_str().unwrap()],
    );
    assert!(dir.join("cut.md").is_file() && dir.join("cut_ticks.svg").is_file());
    let r = json(&dir.join("cut.json"));
    assert_eq!(finite(&r["nodes"]), 2562.0);
    // The blade drew a cut: lips of some 10 cm (edges of about 4 mm: tens of boundary edges).
    assert!(
        finite(&r["boundary_edges"]) >= 40.0,
        "{}",
        r["boundary_edges"]
    );
    for variant in ["with_cut", "without_cut"] {
        let v = &r[variant];
        assert_eq!(finite(&v["samples"]), 1000.0, "{variant}: the draw's ticks");
        let (p50, p999, max) = (
            finite(&v["p50_us"]),
            finite(&v["p999_us"]),
            finite(&v["max_us"]),
        );
        assert!(0.0 < p50 && p50 <= p999 && p999 <= max, "{variant}: {v}");
    }
    let steps = &r["incision_step"];
    assert_eq!(finite(&steps["samples"]), finite(&r["cut_ticks_per_run"]));
    assert!(finite(&steps["samples"]) > 0.0);
    // The transection scene's tube separates (at the tick the cutting tests find), in two bodies.
    assert_eq!(finite(&r["transection"]["bodies_after"]), 2.0);
    assert!(finite(&r["transection"]["stage"]["mean_us"]) > 0.0);
}

#[test]
fn bench_bodies_quick_writes_consistent_figures() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let dir = out_dir("bench_bodies");
    run(
        env!("CARGO_BIN_EXE_palpa-bench"),
        &["bodies", "--quick", "--out", dir.to_str().unwrap()],
    );
    let r = json(&dir.join("bodies.json"));
    let layouts = r["layouts"].as_array().expect("layouts");
    // `--quick`: two 162-node organs of the bench's parameters apart, touching and stacked, then
    // two of the uterus's and two of the default parameters apart and stacked.
    assert_eq!(layouts.len(), 7);
    let expected = [
        ("bench", "apart"),
        ("bench", "touching"),
        ("bench", "stacked"),
        ("uterus", "apart"),
        ("uterus", "stacked"),
        ("default", "apart"),
        ("default", "stacked"),
    ];
    for (row, (parameters, layout)) in layouts.iter().zip(expected) {
        assert_eq!(row["parameters"], parameters);
        assert_eq!(row["layout"], layout);
        assert_eq!(finite(&row["nodes_per_body"]), 162.0);
        let (tick, stage) = (finite(&row["tick_us"]), finite(&row["body_contact_us"]));
        assert!(tick > 0.0 && stage >= 0.0 && stage < tick, "{row}");
    }
    // Organs apart touch nothing; stacked, each rests on the other.
    for (apart, stacked) in [(0, 2), (3, 4), (5, 6)] {
        assert_eq!(finite(&layouts[apart]["contacts_per_tick"]), 0.0);
        assert!(finite(&layouts[stacked]["contacts_per_tick"]) > 10.0);
        // Each ratio is to the apart row of its own parameters.
        let ratio = finite(&layouts[stacked]["ratio_to_apart"]);
        let expected = finite(&layouts[stacked]["tick_us"]) / finite(&layouts[apart]["tick_us"]);
        assert!(
            (ratio - expected).abs() <= 1e-9 * expected,
            "{ratio} {expected}"
        );
    }
    assert_eq!(finite(&r["laparoscopy"]["samples"]), 5500.0);
    // The ball's landing: 200 ticks, held by the response's contacts (the net answered 7 765
    // collisions there before the response took over the pairs it answers).
    assert_eq!(finite(&r["landing"]["samples"]), 200.0);
    let net = finite(&r["landing_net_collisions_per_run"]);
    assert!(
        net < 100.0,
        "the net answered {net} collisions over the landing"
    );
    assert!(
        std::fs::read_to_string(dir.join("bodies.md"))
            .unwrap()
            .contains("two_organs landing")
    );
    // The crushed pair, 162 nodes a body with `--quick`: 500 ticks, the net's answers a tick.
    let crushed = r["crushed"].as_array().expect("crushed");
    assert_eq!(crushed.len(), 1);
    assert_eq!(finite(&crushed[0]["nodes_per_body"]), 162.0);
    assert_eq!(finite(&crushed[0]["ticks"]["samples"]), 500.0);
    finite(&crushed[0]["net_collisions_per_tick"]);
    let _ = std::fs::remove_dir_all(&dir);
}
