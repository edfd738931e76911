//! Loop statistics over one-second windows: tick compute time (min, mean, max, 99th percentile from a
//! fixed 1 µs histogram, so nothing is sorted or allocated on the tick), wake-up lateness, and the
//! running totals of synchronicity misses, rejected inputs and disconnects.

use crate::ipc::payload::StatsV1;

/// Histogram bins (1 µs each); longer ticks land in the last bin.
const BINS: usize = 5000;

/// The `q` quantile (0 < q ≤ 1) of `count` times binned 1 µs a bin in `histogram`: the upper edge
/// of the bin it falls in (a conservative quantile at 1 µs resolution), at most `max_us`, the
/// longest time; 0 when nothing was binned.
pub fn histogram_quantile_us(histogram: &[u32], count: u64, q: f64, max_us: f64) -> f64 {
    let rank = ((q * count as f64).ceil() as u64).max(1);
    let mut seen = 0u64;
    for (bin, &c) in histogram.iter().enumerate() {
        seen += c as u64;
        if seen >= rank && c > 0 {
            return ((bin + 1) as f64).min(max_us.max(bin as f64));
        }
    }
    0.0
}

/// Accumulates one window.
#[derive(Clone, Debug)]
pub struct LoopStats {
    histogram: Vec<u32>,
    lateness_histogram: Vec<u32>,
    count: u64,
    sum_us: f64,
    min_us: f64,
    max_us: f64,
    lateness_sum_us: f64,
    lateness_max_us: f64,
    /// Total ticks whose compute exceeded the period.
    pub synchronicity_misses: u64,
}

impl Default for LoopStats {
    fn default() -> Self {
        Self {
            histogram: vec![0; BINS],
            lateness_histogram: vec![0; BINS],
            count: 0,
            sum_us: 0.0,
            min_us: f64::INFINITY,
            max_us: 0.0,
            lateness_sum_us: 0.0,
            lateness_max_us: 0.0,
            synchronicity_misses: 0,
        }
    }
}

impl LoopStats {
    /// Records one tick: its compute time and how late it woke, µs; `period_us` decides a miss.
    pub fn record(&mut self, compute_us: f64, lateness_us: f64, period_us: f64) {
        let bin = (compute_us.max(0.0) as usize).min(BINS - 1);
        self.histogram[bin] += 1;
        self.lateness_histogram[(lateness_us.max(0.0) as usize).min(BINS - 1)] += 1;
        self.count += 1;
        self.sum_us += compute_us;
        self.min_us = self.min_us.min(compute_us);
        self.max_us = self.max_us.max(compute_us);
        self.lateness_sum_us += lateness_us;
        self.lateness_max_us = self.lateness_max_us.max(lateness_us);
        if compute_us > period_us {
            self.synchronicity_misses += 1;
        }
    }

    /// Ticks of the current window per 1 µs bin of compute time (the last bin holds the longer ones).
    pub fn compute_histogram(&self) -> &[u32] {
        &self.histogram
    }

    /// Ticks of the current window per 1 µs bin of wake-up lateness.
    pub fn lateness_histogram(&self) -> &[u32] {
        &self.lateness_histogram
    }

    /// Ticks recorded in the current window.
    pub fn window_ticks(&self) -> u64 {
        self.count
    }

    /// Fills the window's figures into `out` (totals and identity fields are the caller's) and starts
    /// a new window.
    pub fn close_window(&mut self, out: &mut StatsV1) {
        let n = self.count.max(1) as f64;
        out.window_ticks = self.count;
        out.compute_min_us = if self.count > 0 { self.min_us } else { 0.0 };
        out.compute_mean_us = self.sum_us / n;
        out.compute_max_us = self.max_us;
        out.compute_p99_us = histogram_quantile_us(&self.histogram, self.count, 0.99, self.max_us);
        out.lateness_mean_us = self.lateness_sum_us / n;
        out.lateness_max_us = self.lateness_max_us;
        out.synchronicity_misses = self.synchronicity_misses;
        for c in self
            .histogram
            .iter_mut()
            .chain(self.lateness_histogram.iter_mut())
        {
            *c = 0;
        }
        self.count = 0;
        self.sum_us = 0.0;
        self.min_us = f64::INFINITY;
        self.max_us = 0.0;
        self.lateness_sum_us = 0.0;
        self.lateness_max_us = 0.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_figures() {
        let mut stats = LoopStats::default();
        for k in 0..1000 {
            // 990 ticks of 10.x µs, 10 of 1500 µs (misses at a 1000 µs period).
            let compute = if k % 100 == 0 {
                1500.0
            } else {
                10.0 + (k % 7) as f64 * 0.1
            };
            stats.record(compute, 2.0, 1000.0);
        }
        let mut out = StatsV1::default();
        stats.close_window(&mut out);
        assert_eq!(out.window_ticks, 1000);
        assert_eq!(out.compute_max_us, 1500.0);
        assert_eq!(out.compute_min_us, 10.0);
        assert_eq!(out.compute_p99_us, 11.0);
        assert_eq!(out.synchronicity_misses, 10);
        assert_eq!(out.lateness_mean_us, 2.0);
        stats.record(20.0, 0.0, 1000.0);
        stats.close_window(&mut out);
        assert_eq!(out.window_ticks, 1);
        assert_eq!(out.synchronicity_misses, 10);
    }
}
