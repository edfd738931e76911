//! `palpa-ccd FILE_OR_DIR...`: runs the CCD narrow phase ([`palpa::collision::ccd`]) on query files
//! of the public CCD benchmark (Wang et al. 2021, sample queries; format in
//! `shared/data/ccd-queries/README.md`) and prints one JSON object per file, one per line:
//!
//! `{"file":…,"kind":"vertex-face"|"edge-edge","queries":N,"positives":N,"false_negatives":N,"false_positives":N,"ns_per_query":X,"mean_ns":X,"p999_ns":X,"max_ns":X}`
//!
//! and, when more than one file was read, a last line over all of them with `"file":"(all)"` and
//! `"kind":"all"` (its `ns_per_query` the files' means weighted by their queries).
//!
//! A directory is walked recursively in sorted order and its `*.csv` files are read; a file named on
//! the command line is read whatever its name. The kind of a file's queries is the name of the folder
//! that holds it (`vertex-face` or `edge-edge`). `positives` counts the ground-truth collisions;
//! `ns_per_query` is the mean wall time of one library call, the file's queries being run repeatedly
//! (at least once, and for at least [`MIN_TIMING`] in all) so that short files still time well.
//! `mean_ns`, `p999_ns` and `max_ns` are the distribution of the time of one query: each query is
//! timed on its own, [`QUERY_ROUNDS`] rounds of enough calls to last [`QUERY_SPAN`], its time being
//! the least of the rounds' means (what the query costs, not what the machine's other work added);
//! a round goes over all of a file's queries, so one query's rounds are apart in time.
//! Parsing is not timed. Bad input stops the run with a message naming the file and line, exit 1.
//!
//! With `--queries`, every query also gets a line of its own before its file's line:
//! `{"file":…,"query":I,"truth":B,"hit":B,"exhausted":B,"boxes":N,"time_of_impact":X,"ns":X}`
//! (I counts from 0 in the file's order; `ns` is the query's time as above) — to find the costly
//! ones.
//!
//! `--max-boxes N` sets [`CcdSettings::max_boxes`] (the most boxes one query examines; the library's
//! default otherwise): past it a query is reported as a hit, `exhausted`, at the earliest time not
//! yet resolved — to see what a budget costs in time and in false positives.

mod query_file;

use palpa::collision::ccd::{
    CcdHit, CcdSettings, edge_edge_time_of_impact, vertex_face_time_of_impact,
};
use query_file::{Kind, Query, QueryFileError, parse_query_file};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// Least total time spent timing one file's queries.
const MIN_TIMING: Duration = Duration::from_millis(20);
/// Rounds of the per-query timing; the least round counts.
const QUERY_ROUNDS: usize = 5;
/// Least duration of one round of one query's calls.
const QUERY_SPAN: Duration = Duration::from_micros(20);

const USAGE: &str = "usage: palpa-ccd [--queries] [--max-boxes N] FILE_OR_DIR...\n\
    Runs palpa's CCD narrow phase on CCD benchmark query files (CSV, 8 rows per query) and prints\n\
    one JSON line per file. A directory is searched recursively for *.csv files; the query kind is\n\
    the name of each file's folder: vertex-face or edge-edge. --queries adds a line per query\n\
    (truth, hit, boxes examined, time in ns). --max-boxes sets the most boxes one query examines\n\
    (the library's default when not given; past it a query reports a conservative hit).";

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.is_empty() {
        eprintln!("{USAGE}");
        return ExitCode::from(2);
    }
    if args.iter().any(|a| a == "-h" || a == "--help") {
        println!("{USAGE}");
        return ExitCode::SUCCESS;
    }
    let mut per_query = false;
    let mut settings = CcdSettings::default();
    let mut paths = Vec::new();
    let mut args = args.into_iter();
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--queries" => per_query = true,
            "--max-boxes" => match args.next().map(|n| n.parse::<u32>()) {
                Some(Ok(n)) if n > 0 => settings.max_boxes = n,
                _ => {
                    eprintln!(
                        "palpa-ccd: --max-boxes takes a whole number of boxes above 0\n{USAGE}"
                    );
                    return ExitCode::from(2);
                }
            },
            _ => paths.push(arg),
        }
    }
    if paths.is_empty() {
        eprintln!("{USAGE}");
        return ExitCode::from(2);
    }
    match run(&paths, per_query, &settings) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("palpa-ccd: {error}");
            ExitCode::FAILURE
        }
    }
}

/// Why a run stopped. Each message names the file (as given or found) where there is one, and is
/// the whole message, the cause included, so no variant has a `#[source]` that a printer of the
/// error chain would repeat. (A thiserror enum rather than `anyhow`: this binary is built without
/// the `cli` feature too, where `anyhow` is not a dependency.)
#[derive(Debug, thiserror::Error)]
enum CcdError {
    #[error("{}: cannot open: {error}", path.display())]
    Open { path: PathBuf, error: io::Error },
    #[error("{}: cannot list: {error}", path.display())]
    List { path: PathBuf, error: io::Error },
    #[error("{}: no *.csv query file in this folder", path.display())]
    NoQueryFile { path: PathBuf },
    #[error(
        "{}: cannot tell the query kind: the file's folder must be named vertex-face or edge-edge",
        path.display()
    )]
    UnknownKind { path: PathBuf },
    #[error("{}: cannot read: {error}", path.display())]
    Read { path: PathBuf, error: io::Error },
    #[error("{}: {error}", path.display())]
    Parse {
        path: PathBuf,
        error: QueryFileError,
    },
    #[error("cannot write to standard output: {error}")]
    Write { error: io::Error },
}

fn run(args: &[String], per_query: bool, settings: &CcdSettings) -> Result<(), CcdError> {
    // Every file and its kind first, so that a wrong argument fails before any output.
    let mut files = Vec::new();
    for arg in args {
        collect_files(Path::new(arg), &mut files)?;
    }
    let files = files
        .into_iter()
        .map(|path| Ok((kind_of(&path)?, path)))
        .collect::<Result<Vec<_>, CcdError>>()?;
    let mut out = std::io::stdout().lock();
    let several = files.len() > 1;
    let mut all = Report::default();
    let mut all_times = Vec::new();
    let mut bulk_ns = 0.0;
    for (kind, path) in files {
        let text = std::fs::read_to_string(&path).map_err(|error| CcdError::Read {
            path: path.clone(),
            error,
        })?;
        let queries = parse_query_file(&text).map_err(|error| CcdError::Parse {
            path: path.clone(),
            error,
        })?;
        let (report, times) = evaluate(kind, &queries, settings);
        if per_query {
            for (index, (q, ns)) in queries.iter().zip(&times).enumerate() {
                let line = query_line(&path.display().to_string(), index, kind, q, *ns, settings);
                if !write_line(&mut out, &line)? {
                    return Ok(());
                }
            }
        }
        let line = report.to_json(&path.display().to_string(), kind.name(), &times);
        all.add(&report);
        bulk_ns += report.ns_per_query * report.queries as f64;
        all_times.extend_from_slice(&times);
        if !write_line(&mut out, &line)? {
            return Ok(());
        }
    }
    if several {
        all.ns_per_query = bulk_ns / all.queries.max(1) as f64;
        let line = all.to_json("(all)", "all", &all_times);
        write_line(&mut out, &line)?;
    }
    Ok(())
}

/// Writes and flushes one line (so that a long run shows its progress); false when the reader has
/// gone (`palpa-ccd … | head`): nothing more to say.
fn write_line(out: &mut impl Write, line: &str) -> Result<bool, CcdError> {
    match writeln!(out, "{line}").and_then(|()| out.flush()) {
        Ok(()) => Ok(true),
        Err(e) if e.kind() == io::ErrorKind::BrokenPipe => Ok(false),
        Err(error) => Err(CcdError::Write { error }),
    }
}

fn mean(values: &[f64]) -> f64 {
    if values.is_empty() {
        0.0
    } else {
        values.iter().sum::<f64>() / values.len() as f64
    }
}

/// Adds `path` if it is a file, or the `*.csv` files under it, recursively in sorted order.
fn collect_files(path: &Path, files: &mut Vec<PathBuf>) -> Result<(), CcdError> {
    let metadata = std::fs::metadata(path).map_err(|error| CcdError::Open {
        path: path.to_path_buf(),
        error,
    })?;
    if !metadata.is_dir() {
        files.push(path.to_path_buf());
        return Ok(());
    }
    let before = files.len();
    walk(path, files)?;
    if files.len() == before {
        return Err(CcdError::NoQueryFile {
            path: path.to_path_buf(),
        });
    }
    Ok(())
}

fn walk(dir: &Path, files: &mut Vec<PathBuf>) -> Result<(), CcdError> {
    let read_error = |error: io::Error| CcdError::List {
        path: dir.to_path_buf(),
        error,
    };
    let mut entries = std::fs::read_dir(dir)
        .map_err(read_error)?
        .map(|entry| entry.map(|e| e.path()))
        .collect::<Result<Vec<_>, _>>()
        .map_err(read_error)?;
    // Byte order of the names: the same on every machine, unlike the order of read_dir.
    entries.sort();
    for entry in entries {
        if entry.is_dir() {
            walk(&entry, files)?;
        } else if entry.extension().is_some_and(|e| e == "csv") {
            files.push(entry);
        }
    }
    Ok(())
}

/// The kind of a file's queries, from the name of its folder.
fn kind_of(path: &Path) -> Result<Kind, CcdError> {
    let folder = path
        .parent()
        .and_then(|p| p.file_name())
        .and_then(|n| n.to_str());
    match folder {
        Some("vertex-face") => Ok(Kind::VertexFace),
        Some("edge-edge") => Ok(Kind::EdgeEdge),
        _ => Err(CcdError::UnknownKind {
            path: path.to_path_buf(),
        }),
    }
}

/// Counts and timing of one file.
#[derive(Default)]
struct Report {
    queries: usize,
    positives: usize,
    false_negatives: usize,
    false_positives: usize,
    ns_per_query: f64,
}

impl Report {
    fn add(&mut self, other: &Report) {
        self.queries += other.queries;
        self.positives += other.positives;
        self.false_negatives += other.false_negatives;
        self.false_positives += other.false_positives;
    }

    /// The JSON line, with the distribution of the per-query `times` (ns).
    fn to_json(&self, file: &str, kind: &str, times: &[f64]) -> String {
        let mut sorted = times.to_vec();
        sorted.sort_by(f64::total_cmp);
        let p999 = if sorted.is_empty() {
            0.0
        } else {
            let rank = (0.999 * sorted.len() as f64).ceil() as usize;
            sorted[rank.clamp(1, sorted.len()) - 1]
        };
        format!(
            "{{\"file\":{},\"kind\":\"{}\",\"queries\":{},\"positives\":{},\"false_negatives\":{},\"false_positives\":{},\"ns_per_query\":{:.1},\"mean_ns\":{:.1},\"p999_ns\":{:.1},\"max_ns\":{:.1}}}",
            json_string(file),
            kind,
            self.queries,
            self.positives,
            self.false_negatives,
            self.false_positives,
            self.ns_per_query,
            mean(&sorted),
            p999,
            sorted.last().copied().unwrap_or(0.0),
        )
    }
}

fn detect(kind: Kind, q: &Query, settings: &CcdSettings) -> bool {
    query_hit(kind, q, settings).is_some()
}

fn query_hit(kind: Kind, q: &Query, settings: &CcdSettings) -> Option<CcdHit> {
    let [x0, x1, x2, x3, x4, x5, x6, x7] = &q.points;
    match kind {
        Kind::VertexFace => vertex_face_time_of_impact(x0, x1, x2, x3, x4, x5, x6, x7, settings),
        Kind::EdgeEdge => edge_edge_time_of_impact(x0, x1, x2, x3, x4, x5, x6, x7, settings),
    }
}

/// The `--queries` line of one query.
fn query_line(
    file: &str,
    index: usize,
    kind: Kind,
    q: &Query,
    ns: f64,
    settings: &CcdSettings,
) -> String {
    let hit = query_hit(kind, q, settings);
    format!(
        "{{\"file\":{},\"query\":{},\"truth\":{},\"hit\":{},\"exhausted\":{},\"boxes\":{},\"time_of_impact\":{},\"ns\":{:.1}}}",
        json_string(file),
        index,
        q.truth,
        hit.is_some(),
        hit.is_some_and(|h| h.exhausted),
        hit.map_or(0, |h| h.boxes),
        hit.map_or(-1.0, |h| h.time_of_impact),
        ns,
    )
}

/// The time of each query (ns): the least over [`QUERY_ROUNDS`] rounds of the mean of enough calls
/// to last [`QUERY_SPAN`]. The rounds go over all the queries in turn, so that one query's rounds
/// are apart in time and a stall of the machine (a shared VM's) cannot fall on all of them.
fn time_queries(kind: Kind, queries: &[Query], settings: &CcdSettings) -> Vec<f64> {
    let mut best = vec![f64::INFINITY; queries.len()];
    for _ in 0..QUERY_ROUNDS {
        for (q, best) in queries.iter().zip(best.iter_mut()) {
            let mut calls = 0u32;
            let start = Instant::now();
            loop {
                std::hint::black_box(detect(kind, std::hint::black_box(q), settings));
                calls += 1;
                if start.elapsed() >= QUERY_SPAN {
                    break;
                }
            }
            *best = best.min(start.elapsed().as_nanos() as f64 / f64::from(calls));
        }
    }
    best
}

fn evaluate(kind: Kind, queries: &[Query], settings: &CcdSettings) -> (Report, Vec<f64>) {
    let mut report = Report {
        queries: queries.len(),
        ..Report::default()
    };
    for q in queries {
        let hit = detect(kind, q, settings);
        report.positives += usize::from(q.truth);
        report.false_negatives += usize::from(q.truth && !hit);
        report.false_positives += usize::from(!q.truth && hit);
    }
    if queries.is_empty() {
        return (report, Vec::new());
    }
    let times = time_queries(kind, queries, settings);
    let mut calls = 0usize;
    let start = Instant::now();
    loop {
        let mut found = 0usize;
        for q in queries {
            found += usize::from(detect(kind, std::hint::black_box(q), settings));
        }
        std::hint::black_box(found);
        calls += queries.len();
        if start.elapsed() >= MIN_TIMING {
            break;
        }
    }
    report.ns_per_query = start.elapsed().as_nanos() as f64 / calls as f64;
    (report, times)
}

/// A JSON string literal.
fn json_string(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c if u32::from(c) < 0x20 => out.push_str(&format!("\\u{:04x}", u32::from(c))),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}
