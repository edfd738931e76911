//! Conformance of the CCD narrow phase (`palpa::collision::ccd`) with the public benchmark's sample
//! queries in `../shared/data/ccd-queries` (exact ground truth): no false negative in any file, and
//! the false positives of each file printed; in-plane vertex queries against exact integer ground
//! truth. Also the `palpa-ccd` binary: its JSON line for one
//! small file, its walk of a folder, and its refusal of bad input.
//!
//! Without the shared data the data-driven tests print `SKIPPED: …` and pass, unless
//! `PALPA_REQUIRE_SHARED=1` (as in CI), where they fail.
//!
//! The file parser here is deliberately separate from the binary's, so that the two check each
//! other.

use palpa::Vec3;
use palpa::collision::ccd::{
    CcdHit, CcdSettings, edge_edge_time_of_impact, vertex_face_time_of_impact,
};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The shared sample queries, or `None` (after saying so) when they are absent and not required.
fn shared_queries() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/ccd-queries");
    if dir.is_dir() {
        return Some(dir);
    }
    if std::env::var("PALPA_REQUIRE_SHARED").as_deref() == Ok("1") {
        panic!(
            "the CCD sample queries are required (PALPA_REQUIRE_SHARED=1) but {} is absent",
            dir.display()
        );
    }
    println!("SKIPPED: {} is absent", dir.display());
    None
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    VertexFace,
    EdgeEdge,
}

struct Query {
    points: [Vec3; 8],
    truth: bool,
}

fn csv_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|entry| entry.expect("directory entry").path())
        .collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            csv_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "csv") {
            out.push(path);
        }
    }
}

fn kind_of(path: &Path) -> Kind {
    match path
        .parent()
        .and_then(|p| p.file_name())
        .and_then(|n| n.to_str())
    {
        Some("vertex-face") => Kind::VertexFace,
        Some("edge-edge") => Kind::EdgeEdge,
        other => panic!("{}: unknown query kind {other:?}", path.display()),
    }
}

/// numerator / denominator, the denominator a power of two written in decimal (possibly > 2^63):
/// as f64 it parses exactly, and so the quotient is exact (the data stay far from underflow).
fn coordinate(numerator: &str, denominator: &str, at: &str) -> f64 {
    let n: i64 = numerator
        .parse()
        .unwrap_or_else(|_| panic!("{at}: {numerator}"));
    let d: f64 = denominator
        .parse()
        .unwrap_or_else(|_| panic!("{at}: {denominator}"));
    assert!(
        d >= 1.0 && d.to_bits() & ((1u64 << 52) - 1) == 0,
        "{at}: denominator {denominator} is not a power of two"
    );
    assert!(n.unsigned_abs() <= 1 << 53, "{at}: numerator {numerator}");
    let value = n as f64 / d;
    assert_eq!(value * d, n as f64, "{at}: inexact");
    value
}

fn read_queries(path: &Path) -> Vec<Query> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let rows: Vec<(Vec3, bool)> = text
        .lines()
        .enumerate()
        .filter(|(_, line)| !line.trim().is_empty())
        .map(|(i, line)| {
            let at = format!("{}:{}", path.display(), i + 1);
            let f: Vec<&str> = line.split(',').map(str::trim).collect();
            assert_eq!(f.len(), 7, "{at}: columns");
            let p = Vec3::new(
                coordinate(f[0], f[1], &at),
                coordinate(f[2], f[3], &at),
                coordinate(f[4], f[5], &at),
            );
            (p, f[6] == "1")
        })
        .collect();
    assert_eq!(rows.len() % 8, 0, "{}: rows", path.display());
    rows.chunks(8)
        .map(|q| Query {
            points: std::array::from_fn(|i| q[i].0),
            truth: q[0].1,
        })
        .collect()
}

fn run_query(kind: Kind, q: &Query, settings: &CcdSettings) -> Option<CcdHit> {
    let [x0, x1, x2, x3, x4, x5, x6, x7] = &q.points;
    match kind {
        Kind::VertexFace => vertex_face_time_of_impact(x0, x1, x2, x3, x4, x5, x6, x7, settings),
        Kind::EdgeEdge => edge_edge_time_of_impact(x0, x1, x2, x3, x4, x5, x6, x7, settings),
    }
}

/// The default settings, those with a budget no query reaches, and those with a budget of
/// [`SETTLED_WITHIN`] boxes.
fn budgets() -> [CcdSettings; 3] {
    let settings = CcdSettings::default();
    let with = |max_boxes| CcdSettings {
        max_boxes,
        ..settings
    };
    [settings, with(10_000), with(SETTLED_WITHIN)]
}

/// A xorshift64* stream from `seed`: the same queries on every machine.
fn xorshift(mut state: u64) -> impl FnMut() -> u64 {
    move || {
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        state.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 33
    }
}

/// (queries, positives, false negatives, false positives, most boxes a hit took) of one file with
/// the default settings, and the most boxes a hit takes with a budget that none reaches. Every
/// query must also be settled within [`SETTLED_WITHIN`] boxes: the same answer, to the bit, as
/// with a budget none reaches (a rejection's boxes are not reported; this bounds them too).
fn counts(path: &Path) -> (usize, usize, usize, usize, u32) {
    let kind = kind_of(path);
    let [settings, unbounded, half] = budgets();
    let (mut queries, mut positives, mut false_negatives, mut false_positives) = (0, 0, 0, 0);
    let mut most_boxes = 0;
    for (i, q) in read_queries(path).iter().enumerate() {
        let hit = run_query(kind, q, &settings);
        if let Some(h) = hit {
            assert!(
                (0.0..=1.0).contains(&h.time_of_impact) && h.boxes <= settings.max_boxes,
                "{} query {i}: {h:?}",
                path.display()
            );
        }
        let free = run_query(kind, q, &unbounded);
        assert_eq!(
            run_query(kind, q, &half),
            free,
            "{} query {i}: not settled within {SETTLED_WITHIN} boxes",
            path.display()
        );
        if let Some(h) = free {
            assert!(!h.exhausted, "{} query {i}: {h:?}", path.display());
            // The budget only moves the time of impact earlier.
            if let Some(bounded) = hit {
                assert!(
                    bounded.time_of_impact <= h.time_of_impact,
                    "{} query {i}",
                    path.display()
                );
            }
            most_boxes = most_boxes.max(h.boxes);
        }
        queries += 1;
        positives += usize::from(q.truth);
        false_negatives += usize::from(q.truth && hit.is_none());
        false_positives += usize::from(!q.truth && hit.is_some());
    }
    (
        queries,
        positives,
        false_negatives,
        false_positives,
        most_boxes,
    )
}

/// False positives over the whole shared set when issue 16 asked for a bounded worst case ("no
/// more than today"): the benchmark's near misses within about 1e-17 m.
const FALSE_POSITIVES_BEFORE: usize = 77;

/// The most boxes a hit of the shared set may take without a budget: 1 111 before the witness, the
/// coplanar rows and the time cuts at coordinate fronts (a pair of edges crossing in a common
/// plane); 184 with them.
const MOST_BOXES: u32 = 300;

/// Every query of the shared set, hit or not, is settled within this many boxes (the most a hit
/// takes is 59), the default budget since 2026-12-08 (half of it before): the budget changes
/// none of the shared set's answers (the worst query's time is its boxes times a box's cost).
/// Before the Newton cuts, the triangle's part across its hypotenuse and the start and end normals
/// (2026-12-04), hits took up to 184 boxes and the slowest rejections close to 128.
const SETTLED_WITHIN: u32 = 64;

#[test]
fn no_false_negative_in_any_sample_query_file() {
    // Settled within the default budget: the answers below are the default settings' too.
    const { assert!(SETTLED_WITHIN <= palpa::collision::ccd::DEFAULT_MAX_BOXES) };
    let Some(dir) = shared_queries() else { return };
    let mut files = Vec::new();
    csv_files(&dir, &mut files);
    assert!(!files.is_empty(), "no *.csv under {}", dir.display());
    let mut missed = Vec::new();
    let (mut all_queries, mut all_negatives, mut all_false_positives) = (0, 0, 0);
    let mut most_boxes = 0;
    for path in &files {
        let (queries, positives, false_negatives, false_positives, boxes) = counts(path);
        most_boxes = most_boxes.max(boxes);
        let name = path.strip_prefix(&dir).unwrap_or(path).display();
        println!(
            "{name}: {queries} queries, {positives} positives, {false_negatives} false negatives, \
             {false_positives} false positives"
        );
        if false_negatives > 0 {
            missed.push(format!("{name}: {false_negatives}"));
        }
        all_queries += queries;
        all_negatives += queries - positives;
        all_false_positives += false_positives;
    }
    println!(
        "all: {all_queries} queries, {all_false_positives} false positives out of {all_negatives} \
         negatives, at most {most_boxes} boxes for a hit"
    );
    assert!(missed.is_empty(), "false negatives: {missed:?}");
    assert!(
        all_false_positives <= FALSE_POSITIVES_BEFORE,
        "{all_false_positives} false positives, {FALSE_POSITIVES_BEFORE} before"
    );
    assert!(most_boxes <= MOST_BOXES, "a hit took {most_boxes} boxes");
}

/// Vertices sliding in the plane of a fixed triangle (every coordinate a multiple of 2⁻¹⁰, z = 0),
/// whose ground truth is exact in integers: the vertex meets the closed triangle (0, 0), (1, 0),
/// (0, 1) when some t of [0, 1] has x ≥ 0, y ≥ 0 and x + y ≤ 1, the earliest such t a fraction
/// of small integers. No false negative, each true hit no later than the earliest contact and
/// within 1e-5 of it, every query settled within the default budget. (A false positive is a path
/// passing within the tolerance of the triangle: a corner can be 6e-7 m from a path between
/// points of this grid; they are counted.) (A vertex crossing into the
/// triangle across its hypotenuse spent the whole budget of 128 boxes, 20 to 28 µs a query, before
/// the combination across the hypotenuse in the plane; `ccd.rs`.)
#[test]
fn vertices_sliding_in_the_triangles_plane_are_settled_with_exact_answers() {
    const SCALE: f64 = 1024.0;
    let mut next = xorshift(0x2545_f491_4f6c_dd1d);
    let (a, b, c) = (Vec3::zeros(), Vec3::x(), Vec3::y());
    let [settings, unbounded, half] = budgets();
    let (mut hits, mut most_boxes, mut false_positives) = (0, 0, 0);
    for i in 0..2000 {
        // Ends in [-0.25, 1.25]² (integers of 1/1024).
        let mut end = || [0, 0].map(|_| (next() % 1537) as i64 - 256);
        let (p, q) = (end(), end());
        // Each constraint as n + m t ≥ 0 (in 1/1024): x ≥ 0, y ≥ 0, 1 − x − y ≥ 0.
        let constraints = [
            (p[0], q[0] - p[0]),
            (p[1], q[1] - p[1]),
            (1024 - p[0] - p[1], (p[0] + p[1]) - (q[0] + q[1])),
        ];
        // The interval of t where all hold, its ends as fractions (numerator, denominator > 0).
        let (mut lo, mut hi) = ((0i64, 1i64), (1i64, 1i64));
        let mut possible = true;
        for (n, m) in constraints {
            if m == 0 {
                possible &= n >= 0;
            } else if m > 0 && -n * lo.1 > lo.0 * m {
                lo = (-n, m);
            } else if m < 0 && n * hi.1 < hi.0 * -m {
                hi = (n, -m);
            }
        }
        let truth = possible && lo.0 * hi.1 <= hi.0 * lo.1;
        let at = |v: [i64; 2]| Vec3::new(v[0] as f64 / SCALE, v[1] as f64 / SCALE, 0.0);
        let (p0, p1) = (at(p), at(q));
        let query = |settings: &CcdSettings| {
            vertex_face_time_of_impact(&p0, &a, &b, &c, &p1, &a, &b, &c, settings)
        };
        let hit = query(&settings);
        assert!(
            hit == query(&unbounded) && hit == query(&half),
            "query {i} ({p0:?} → {p1:?}): not settled within {SETTLED_WITHIN} boxes"
        );
        match hit {
            Some(_) if !truth => false_positives += 1,
            Some(h) => {
                let earliest = lo.0 as f64 / lo.1 as f64;
                assert!(
                    h.time_of_impact <= earliest && h.time_of_impact >= earliest - 1e-5,
                    "query {i} ({p0:?} → {p1:?}): {h:?}, the earliest contact at {earliest}"
                );
                hits += 1;
                most_boxes = most_boxes.max(h.boxes);
            }
            None => assert!(!truth, "query {i} ({p0:?} → {p1:?}): a contact missed"),
        }
    }
    println!(
        "{hits} of 2000 in-plane queries hit, at most {most_boxes} boxes for a hit; \
         {false_positives} false positives"
    );
    assert!(hits > 200, "too few contacts to tell: {hits}");
}

/// Edges translating in the plane z = 0 (ends on a grid of 2⁻¹⁰), against exact integer ground
/// truth: two segments moving in a plane first touch at the start or where an end of one meets the
/// other, so the earliest contact is the least of four such times (each a fraction of integers)
/// or 0. No false negative, each true hit no later than the earliest contact and within 1e-5 of
/// it. This guards the rule that rejects, in a coordinate plane, every box inside the domain that
/// starts after 0 (`ccd.rs`): it fails when the rule also takes boxes on a side. At most one query
/// spends the budget: 3 did before a box inside the domain that starts at 0 was examined at its
/// start alone (2026-12-08).
#[test]
fn edges_translating_in_a_plane_are_answered_with_exact_times() {
    const SCALE: f64 = 1024.0;
    type P = [i64; 2];
    let sub = |a: P, b: P| [a[0] - b[0], a[1] - b[1]];
    let cross =
        |a: P, b: P| i128::from(a[0]) * i128::from(b[1]) - i128::from(a[1]) * i128::from(b[0]);
    let dot =
        |a: P, b: P| i128::from(a[0]) * i128::from(b[0]) + i128::from(a[1]) * i128::from(b[1]);
    // The earliest t in [0, 1] (numerator, denominator > 0) at which the point p + t w lies on the
    // segment [c, d] (not of zero length), if any.
    let point_on_segment = |p: P, w: P, c: P, d: P| -> Option<(i128, i128)> {
        let (dc, pc) = (sub(d, c), sub(p, c));
        let (across, rate) = (cross(dc, pc), cross(dc, w));
        let length2 = dot(dc, dc);
        // Where along [c, d] the point is at t = n / m: dot(pc + t w, dc) / |dc|² in [0, 1].
        let along = |n: i128, m: i128| {
            let x = dot(pc, dc) * m + dot(w, dc) * n;
            (0..=length2 * m).contains(&x)
        };
        if rate != 0 {
            let (mut n, mut m) = (-across, rate);
            if m < 0 {
                (n, m) = (-n, -m);
            }
            ((0..=m).contains(&n) && along(n, m)).then_some((n, m))
        } else if across != 0 {
            None
        } else {
            // On the line all along: the earliest t whose place along [c, d] is in [0, 1].
            let (start, speed) = (dot(pc, dc), dot(w, dc));
            if (0..=length2).contains(&start) {
                Some((0, 1))
            } else if speed == 0 {
                None
            } else {
                let target = if start < 0 { 0 } else { length2 };
                let (mut n, mut m) = (target - start, speed);
                if m < 0 {
                    (n, m) = (-n, -m);
                }
                (0..=m).contains(&n).then_some((n, m))
            }
        }
    };
    let mut next = xorshift(0x9e37_79b9_7f4a_7c15);
    let settings = CcdSettings::default();
    let (mut hits, mut exhausted, mut false_positives) = (0, 0, 0);
    let mut tested = 0;
    while tested < 2000 {
        let mut point =
            |range: i64| [0, 0].map(|_| (next() % (2 * range as u64 + 1)) as i64 - range);
        let (a, b, c, d) = (
            point(768).map(|x| x + 512),
            point(768).map(|x| x + 512),
            point(768).map(|x| x + 512),
            point(768).map(|x| x + 512),
        );
        let w = point(1024);
        if a == b || c == d {
            continue;
        }
        tested += 1;
        let neg = |p: P| [-p[0], -p[1]];
        // At the start: either end of one on the other, or a proper crossing.
        let crossing = {
            let side = |p: P| cross(sub(b, a), sub(p, a)).signum();
            let other = |p: P| cross(sub(d, c), sub(p, c)).signum();
            side(c) * side(d) < 0 && other(a) * other(b) < 0
        };
        let events = [
            point_on_segment(a, w, c, d),
            point_on_segment(b, w, c, d),
            point_on_segment(c, neg(w), a, b),
            point_on_segment(d, neg(w), a, b),
        ];
        let earliest = if crossing {
            Some((0, 1))
        } else {
            events
                .into_iter()
                .flatten()
                .min_by(|x, y| (x.0 * y.1).cmp(&(y.0 * x.1)))
        };
        let at = |p: P| Vec3::new(p[0] as f64 / SCALE, p[1] as f64 / SCALE, 0.0);
        let moved = |p: P| at([p[0] + w[0], p[1] + w[1]]);
        let hit = edge_edge_time_of_impact(
            &at(a),
            &at(b),
            &at(c),
            &at(d),
            &moved(a),
            &moved(b),
            &at(c),
            &at(d),
            &settings,
        );
        match (hit, earliest) {
            (None, None) => {}
            (None, Some(t)) => {
                panic!("{a:?} {b:?} {c:?} {d:?} moving {w:?}: missed the contact at {t:?}")
            }
            (Some(_), None) => false_positives += 1,
            (Some(h), Some((n, m))) => {
                let t = n as f64 / m as f64;
                assert!(
                    h.time_of_impact <= t && (h.exhausted || h.time_of_impact >= t - 1e-5),
                    "{a:?} {b:?} {c:?} {d:?} moving {w:?}: {h:?}, the earliest contact at {t}"
                );
                hits += 1;
                exhausted += usize::from(h.exhausted);
            }
        }
    }
    println!(
        "{hits} of 2000 edges translating in a plane hit ({exhausted} exhausted); \
         {false_positives} false positives"
    );
    assert!(hits > 200, "too few contacts to tell: {hits}");
    assert!(exhausted <= 1, "{exhausted} queries spent the budget");
}

fn palpa_ccd(args: &[&Path]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_palpa-ccd"))
        .args(args)
        .output()
        .expect("run palpa-ccd")
}

#[test]
fn binary_reports_one_json_line_for_a_file() {
    let Some(dir) = shared_queries() else { return };
    let file = dir.join("unit-tests/edge-edge/data_0_1.csv");
    let output = palpa_ccd(&[&file]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    let stdout = String::from_utf8(output.stdout).expect("UTF-8 output");
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len(), 1, "{stdout}");
    let json: serde_json::Value = serde_json::from_str(lines[0]).expect("a JSON object");
    let object = json.as_object().expect("a JSON object");
    let mut keys: Vec<&str> = object.keys().map(String::as_str).collect();
    keys.sort_unstable();
    assert_eq!(
        keys,
        [
            "false_negatives",
            "false_positives",
            "file",
            "kind",
            "max_ns",
            "mean_ns",
            "ns_per_query",
            "p999_ns",
            "positives",
            "queries"
        ]
    );
    let (queries, positives, false_negatives, false_positives, _) = counts(&file);
    assert_eq!(queries, 20);
    assert_eq!(json["file"], file.display().to_string());
    assert_eq!(json["kind"], "edge-edge");
    assert_eq!(json["queries"], queries);
    assert_eq!(json["positives"], positives);
    assert_eq!(json["false_negatives"], false_negatives);
    assert_eq!(json["false_negatives"], 0);
    assert_eq!(json["false_positives"], false_positives);
    let ns = json["ns_per_query"].as_f64().expect("a number");
    assert!(ns > 0.0 && ns.is_finite(), "{ns}");
    let (mean, p999, max) = (
        json["mean_ns"].as_f64().expect("a number"),
        json["p999_ns"].as_f64().expect("a number"),
        json["max_ns"].as_f64().expect("a number"),
    );
    assert!(
        0.0 < mean && mean <= max && 0.0 < p999 && p999 <= max && max.is_finite(),
        "{mean} {p999} {max}"
    );
}

/// The lines of a successful run's standard output, each parsed as JSON, and the output itself.
fn json_lines(output: Output) -> (String, Vec<serde_json::Value>) {
    assert!(output.status.success(), "{output:?}");
    let stdout = String::from_utf8(output.stdout).expect("UTF-8 output");
    let lines = stdout
        .lines()
        .map(|l| serde_json::from_str(l).expect("JSON line"))
        .collect();
    (stdout, lines)
}

/// A scratch folder of its own for each test, under the target directory.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create scratch folder");
    dir
}

/// One vertex–face query (a point falling through a triangle), 8 rows with the given truth.
fn query_rows(truth: u8) -> String {
    [
        "1,4,1,4,1,1",
        "0,1,0,1,0,1",
        "1,1,0,1,0,1",
        "0,1,1,1,0,1",
        "1,4,1,4,-1,1",
        "0,1,0,1,0,1",
        "1,1,0,1,0,1",
        "0,1,1,1,0,1",
    ]
    .iter()
    .map(|row| format!("{row},{truth}\n"))
    .collect()
}

#[test]
fn binary_walks_folders_in_sorted_order() {
    let dir = scratch("walk");
    // The same 8 points: a vertex falling through a face (truth 1), and, read as two edges, an edge
    // sweeping beside the other one (truth 0).
    for (folder, name, truth) in [("vertex-face", "b.csv", 1), ("edge-edge", "a.csv", 0)] {
        let folder = dir.join("set").join(folder);
        std::fs::create_dir_all(&folder).expect("create folder");
        std::fs::write(folder.join(name), query_rows(truth)).expect("write query file");
        std::fs::write(folder.join("notes.txt"), "not a query file").expect("write");
    }
    let output = palpa_ccd(&[&dir]);
    let (stdout, lines) = json_lines(output);
    assert_eq!(lines.len(), 3, "{stdout}");
    // edge-edge sorts before vertex-face; notes.txt is not read; then the line over both.
    assert_eq!(lines[0]["kind"], "edge-edge");
    assert_eq!(lines[0]["positives"], 0);
    assert_eq!(lines[0]["false_positives"], 0);
    assert_eq!(lines[1]["kind"], "vertex-face");
    assert_eq!(lines[1]["positives"], 1);
    assert_eq!(lines[1]["false_negatives"], 0);
    for line in &lines[..2] {
        assert_eq!(line["queries"], 1);
    }
    assert_eq!(lines[2]["file"], "(all)");
    assert_eq!(lines[2]["kind"], "all");
    assert_eq!(lines[2]["queries"], 2);
    assert_eq!(lines[2]["positives"], 1);
    assert_eq!(lines[2]["false_positives"], 0);
    let max = lines[2]["max_ns"].as_f64().expect("a number");
    for line in &lines[..2] {
        assert!(line["max_ns"].as_f64().expect("a number") <= max);
    }
}

#[test]
fn binary_refuses_bad_input_naming_file_and_line() {
    let dir = scratch("bad");
    let folder = dir.join("vertex-face");
    std::fs::create_dir_all(&folder).expect("create folder");
    let cases = [
        (
            "columns.csv",
            query_rows(0).replacen("0,1,0,1,0,1,0", "0,1,0,1,0,0", 1),
            "line 2",
        ),
        (
            "number.csv",
            query_rows(0).replacen("1,1,0,1,0,1", "1,1,x,1,0,1", 1),
            "line 3",
        ),
        (
            "denominator.csv",
            query_rows(0).replacen("1,4,1,4,1,1", "1,3,1,4,1,1", 1),
            "line 1",
        ),
        (
            "truncated.csv",
            query_rows(0)
                .lines()
                .take(5)
                .map(|l| format!("{l}\n"))
                .collect(),
            "line 5",
        ),
    ];
    for (name, text, line) in cases {
        let path = folder.join(name);
        std::fs::write(&path, text).expect("write query file");
        let output = palpa_ccd(&[&path]);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success(), "{name}: accepted");
        assert!(
            stderr.contains(name) && stderr.contains(line),
            "{name}: {stderr}"
        );
        assert!(!stderr.contains("panicked"), "{name}: {stderr}");
    }
    // A missing file, and a file whose folder does not tell the kind.
    let unknown = dir.join("queries.csv");
    std::fs::write(&unknown, query_rows(1)).expect("write query file");
    for path in [dir.join("missing.csv"), unknown] {
        let output = palpa_ccd(&[&path]);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success(), "{}: accepted", path.display());
        assert!(stderr.contains(&path.display().to_string()), "{stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
}

/// A query file `name` holding `rows`, in a `vertex-face` folder of the test's own scratch folder.
fn vertex_face_file(test: &str, name: &str, rows: &str) -> PathBuf {
    let folder = scratch(test).join("vertex-face");
    std::fs::create_dir_all(&folder).expect("create folder");
    let file = folder.join(name);
    std::fs::write(&file, rows).expect("write query file");
    file
}

#[test]
fn binary_lists_every_query_when_asked() {
    let file = vertex_face_file("per_query", "two.csv", &(query_rows(1) + &query_rows(1)));
    let flag = Path::new("--queries");
    let output = palpa_ccd(&[flag, &file]);
    let (stdout, lines) = json_lines(output);
    // Two query lines, then the file's line.
    assert_eq!(lines.len(), 3, "{stdout}");
    for (index, line) in lines[..2].iter().enumerate() {
        assert_eq!(line["query"], index);
        assert_eq!(line["truth"], true);
        assert_eq!(line["hit"], true);
        assert_eq!(line["exhausted"], false);
        assert!(line["boxes"].as_u64().expect("a count") >= 1);
        // The point crosses the face at t = 1/2: a lower bound within the tolerance of it.
        let toi = line["time_of_impact"].as_f64().expect("a number");
        assert!((0.49..=0.5).contains(&toi), "{toi}");
        assert!(line["ns"].as_f64().expect("a number") > 0.0);
    }
    assert_eq!(lines[2]["queries"], 2);
}

#[test]
fn binary_takes_a_box_budget_and_refuses_a_bad_one() {
    let file = vertex_face_file("budget", "one.csv", &query_rows(1));
    let (queries, budget) = (Path::new("--queries"), Path::new("--max-boxes"));
    // One box is not enough to settle the point falling through the face: a hit, exhausted, at
    // the earliest time not yet resolved (the start); the default budget settles it.
    let (stdout, lines) = json_lines(palpa_ccd(&[queries, budget, Path::new("1"), &file]));
    assert_eq!(lines.len(), 2, "{stdout}");
    assert_eq!(lines[0]["hit"], true);
    assert_eq!(lines[0]["exhausted"], true);
    assert_eq!(lines[0]["boxes"], 1);
    assert_eq!(lines[0]["time_of_impact"], 0.0);
    let (_, lines) = json_lines(palpa_ccd(&[queries, &file]));
    assert_eq!(lines[0]["exhausted"], false);
    for bad in ["0", "-3", "many"] {
        let output = palpa_ccd(&[budget, Path::new(bad), &file]);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{bad}: {stderr}");
        assert!(stderr.contains("--max-boxes"), "{bad}: {stderr}");
    }
    let output = palpa_ccd(&[&file, budget]);
    assert_eq!(output.status.code(), Some(2), "{output:?}");
}
