//! What the bench and report tools share (`palpa-bench`, `palpa-report`; feature `cli`): SVG plots
//! (plotters, SVG backend, no system fonts needed), a progress bar, percentiles and fitted slopes,
//! and the machine and date a report names.

use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// A plot that could not be drawn or written, with plotters' account of why.
#[derive(Debug, thiserror::Error)]
#[error("cannot draw {}: {reason}", path.display())]
pub struct PlotError {
    /// The SVG file asked for.
    pub path: PathBuf,
    /// plotters' reason.
    pub reason: String,
}

impl PlotError {
    /// A failure drawing `path`, from plotters' error.
    fn at(path: &Path) -> impl Fn(&dyn std::fmt::Display) -> PlotError + '_ {
        move |e| PlotError {
            path: path.to_path_buf(),
            reason: e.to_string(),
        }
    }
}

/// One named curve.
pub struct Series {
    /// The curve's name in the legend.
    pub name: String,
    /// Its points (x, y).
    pub points: Vec<(f64, f64)>,
    /// Draw points only, no line.
    pub points_only: bool,
}

const COLOURS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

fn range_of(values: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite() && (!log || *v > 0.0)) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return if log { (1e-3, 1.0) } else { (0.0, 1.0) };
    }
    if log {
        (lo / 1.5, hi * 1.5)
    } else {
        let pad = ((hi - lo) * 0.05).max(1e-12);
        (lo - pad, hi + pad)
    }
}

/// A log-log plot of the series.
pub fn loglog(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> Result<(), PlotError> {
    let fail = PlotError::at(path);
    let root = SVGBackend::new(path, (800, 560)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let all = || series.iter().flat_map(|s| s.points.iter().copied());
    let (x0, x1) = range_of(all().map(|p| p.0), true);
    let (y0, y1) = range_of(all().map(|p| p.1), true);
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(72)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(|e| fail(&e))?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .x_labels(6)
        .y_labels(8)
        .x_label_formatter(&|v| format!("{v:.1e}"))
        .y_label_formatter(&|v| format!("{v:.1e}"))
        .draw()
        .map_err(|e| fail(&e))?;
    for (k, s) in series.iter().enumerate() {
        let colour = COLOURS[k % COLOURS.len()];
        let points: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|(x, y)| x.is_finite() && y.is_finite() && *x > 0.0 && *y > 0.0)
            .collect();
        if !s.points_only {
            chart
                .draw_series(LineSeries::new(points.clone(), colour.stroke_width(2)))
                .map_err(|e| fail(&e))?
                .label(s.name.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
                });
        }
        let marks = chart
            .draw_series(points.iter().map(|&p| Circle::new(p, 4, colour.filled())))
            .map_err(|e| fail(&e))?;
        if s.points_only {
            marks
                .label(s.name.clone())
                .legend(move |(x, y)| Circle::new((x + 10, y), 4, colour.filled()));
        }
    }
    // The legend goes where the curves are not: upper left when they rise.
    let rising = series
        .first()
        .map(|s| loglog_slope(&s.points) > 0.0)
        .unwrap_or(false);
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(if rising {
            SeriesLabelPosition::UpperLeft
        } else {
            SeriesLabelPosition::UpperRight
        })
        .draw()
        .map_err(|e| fail(&e))?;
    root.present().map_err(|e| fail(&e))
}

/// A histogram: bars of `counts` over bins of width `width` starting at `start` (x in the unit of
/// `x_label`), counts on a log axis.
pub fn histogram(
    path: &Path,
    title: &str,
    x_label: &str,
    bars: &[(f64, f64, u64)],
) -> Result<(), PlotError> {
    let fail = PlotError::at(path);
    let root = SVGBackend::new(path, (800, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let x0 = bars.iter().map(|b| b.0).fold(f64::INFINITY, f64::min);
    let x1 = bars.iter().map(|b| b.1).fold(f64::NEG_INFINITY, f64::max);
    let (x0, x1) = if x0.is_finite() && x1 > x0 {
        (x0, x1)
    } else {
        (0.0, 1.0)
    };
    let top = bars.iter().map(|b| b.2).max().unwrap_or(1).max(1) as f64 * 2.0;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(64)
        .build_cartesian_2d(x0..x1, (0.5..top).log_scale())
        .map_err(|e| fail(&e))?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc("count")
        .draw()
        .map_err(|e| fail(&e))?;
    chart
        .draw_series(bars.iter().filter(|b| b.2 > 0).map(|&(a, b, n)| {
            Rectangle::new([(a, 0.5), (b, n as f64)], COLOURS[0].mix(0.8).filled())
        }))
        .map_err(|e| fail(&e))?;
    root.present().map_err(|e| fail(&e))
}

/// Stable (green) and unstable (red) cells on log axes, with a bound drawn as a line.
pub fn stability_map(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    cells: &[(f64, f64, bool)],
    bound: &[(f64, f64)],
) -> Result<(), PlotError> {
    let fail = PlotError::at(path);
    let root = SVGBackend::new(path, (700, 560)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let (x0, x1) = range_of(cells.iter().map(|c| c.0), true);
    let (y0, y1) = range_of(cells.iter().map(|c| c.1), true);
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(72)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(|e| fail(&e))?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .x_label_formatter(&|v| format!("{v:.1e}"))
        .y_label_formatter(&|v| format!("{v:.1e}"))
        .draw()
        .map_err(|e| fail(&e))?;
    let green = RGBColor(44, 160, 44);
    let red = RGBColor(214, 39, 40);
    chart
        .draw_series(
            cells
                .iter()
                .filter(|c| c.2)
                .map(|c| Circle::new((c.0, c.1), 7, green.filled())),
        )
        .map_err(|e| fail(&e))?
        .label("stable")
        .legend(move |(x, y)| Circle::new((x + 10, y), 6, green.filled()));
    chart
        .draw_series(
            cells
                .iter()
                .filter(|c| !c.2)
                .map(|c| Cross::new((c.0, c.1), 7, red.stroke_width(3))),
        )
        .map_err(|e| fail(&e))?
        .label("unstable or guarded")
        .legend(move |(x, y)| Cross::new((x + 10, y), 6, red.stroke_width(3)));
    let line: Vec<(f64, f64)> = bound
        .iter()
        .copied()
        .filter(|&(x, y)| x >= x0 && x <= x1 && y >= y0 && y <= y1)
        .collect();
    chart
        .draw_series(LineSeries::new(line, BLACK.stroke_width(2)))
        .map_err(|e| fail(&e))?
        .label("analytic bound ω·Δt = 2")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::LowerRight)
        .draw()
        .map_err(|e| fail(&e))?;
    root.present().map_err(|e| fail(&e))
}

/// A simple progress bar on standard error.
pub struct Progress {
    total: usize,
    done: usize,
    label: String,
}

impl Progress {
    /// A bar named `label` for `total` steps, drawn at once.
    pub fn new(label: &str, total: usize) -> Self {
        let p = Self {
            total: total.max(1),
            done: 0,
            label: label.to_string(),
        };
        p.draw("");
        p
    }

    /// One step done; `what` is shown beside the bar.
    pub fn step(&mut self, what: &str) {
        self.done += 1;
        self.draw(what);
        if self.done >= self.total {
            eprintln!();
        }
    }

    fn draw(&self, what: &str) {
        let width = 30;
        let filled = width * self.done.min(self.total) / self.total;
        eprint!(
            "\r{} [{}{}] {}/{} {:<40}",
            self.label,
            "#".repeat(filled),
            " ".repeat(width - filled),
            self.done,
            self.total,
            what.chars().take(40).collect::<String>()
        );
    }
}

/// Least-squares slope of log y against log x.
pub fn loglog_slope(points: &[(f64, f64)]) -> f64 {
    let logs: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, y)| *x > 0.0 && *y > 0.0)
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    let n = logs.len() as f64;
    if n < 2.0 {
        return f64::NAN;
    }
    let mx = logs.iter().map(|p| p.0).sum::<f64>() / n;
    let my = logs.iter().map(|p| p.1).sum::<f64>() / n;
    let sxy: f64 = logs.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = logs.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    sxy / sxx
}

/// Percentile of sorted values, `q` in [0, 1] (nearest rank).
pub fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let rank = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1]
}

/// The machine, for reports: CPU model and count.
pub fn machine() -> String {
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    format!("{model}, {cpus} CPUs")
}

/// The date and time now, UTC, to the minute (`2026-12-06 10:30 UTC`), for reports.
pub fn utc_now() -> String {
    let format = time::macros::format_description!("[year]-[month]-[day] [hour]:[minute] UTC");
    time::OffsetDateTime::now_utc()
        .format(format)
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plot_that_cannot_be_written_names_its_file() {
        let path = Path::new("/nonexistent-palpa-dir/plot.svg");
        let series = [Series {
            name: "a".into(),
            points: vec![(1.0, 1.0), (10.0, 100.0)],
            points_only: false,
        }];
        let error = loglog(path, "t", "x", "y", &series).expect_err("no such folder");
        assert_eq!(error.path, path);
        assert!(
            error
                .to_string()
                .starts_with("cannot draw /nonexistent-palpa-dir/plot.svg: "),
            "{error}"
        );
        let written = std::env::temp_dir().join(format!("palpa-plot-{}.svg", std::process::id()));
        loglog(&written, "t", "x", "y", &series).expect("a writable folder");
        let svg = std::fs::read_to_string(&written).expect("the plot was written");
        std::fs::remove_file(&written).ok();
        assert!(svg.starts_with("<svg"), "{}", &svg[..svg.len().min(80)]);
    }
}
