//! A session's latencies in bounded memory: the whole session's distribution in a histogram
//! of 1 % bins (its quantiles within 1 % of the exact ones, its worst exact), and the last
//! frames' values as they were, for the running figures.

use std::collections::VecDeque;

/// The smallest latency a bin holds apart (ms); less counts in the first bin.
const FLOOR_MS: f64 = 1e-3;
/// The ratio of one bin's upper edge to its lower one.
const RATIO: f64 = 1.01;
/// Bins: from 1 µs to beyond a day.
const BINS: usize = 2_600;
/// The last latencies kept as they were.
pub const RECENT: usize = 300;

/// Latencies (milliseconds) as a session records them.
#[derive(Debug, Clone)]
pub struct Latencies {
    counts: Vec<u64>,
    total: u64,
    worst: f64,
    recent: VecDeque<f64>,
}

impl Default for Latencies {
    fn default() -> Self {
        Latencies::new()
    }
}

impl Latencies {
    /// None recorded.
    pub fn new() -> Latencies {
        Latencies {
            counts: vec![0; BINS],
            total: 0,
            worst: 0.0,
            recent: VecDeque::with_capacity(RECENT),
        }
    }

    fn bin(ms: f64) -> usize {
        if ms <= FLOOR_MS || ms.is_nan() {
            return 0;
        }
        (((ms / FLOOR_MS).ln() / RATIO.ln()).ceil() as usize).min(BINS - 1)
    }

    /// Records one latency (a negative or NaN one counts as 0).
    pub fn record(&mut self, ms: f64) {
        let ms = if ms > 0.0 { ms } else { 0.0 };
        self.counts[Self::bin(ms)] += 1;
        self.total += 1;
        self.worst = self.worst.max(ms);
        if self.recent.len() == RECENT {
            self.recent.pop_front();
        }
        self.recent.push_back(ms);
    }

    /// How many were recorded.
    pub fn len(&self) -> u64 {
        self.total
    }

    /// Whether none were.
    pub fn is_empty(&self) -> bool {
        self.total == 0
    }

    /// The whole session's `q`-quantile (nearest rank; 0–1): the upper edge of its bin,
    /// within 1 % above the exact value and never above the worst; `q` = 1 is the worst,
    /// exactly. None when nothing was recorded.
    pub fn quantile(&self, q: f64) -> Option<f64> {
        if self.total == 0 {
            return None;
        }
        let rank = ((q * self.total as f64).ceil() as u64).clamp(1, self.total);
        let mut seen = 0;
        for (i, &c) in self.counts.iter().enumerate() {
            seen += c;
            if seen >= rank {
                let edge = if i == 0 {
                    FLOOR_MS
                } else {
                    FLOOR_MS * RATIO.powi(i as i32)
                };
                return Some(edge.min(self.worst));
            }
        }
        Some(self.worst)
    }

    /// The last [`RECENT`] latencies, oldest first.
    pub fn recent(&self) -> &VecDeque<f64> {
        &self.recent
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against the exact nearest-rank quantiles of the values themselves: within 1 %,
    /// never below, the worst exact; memory bounded whatever the count.
    #[test]
    fn quantiles_are_within_one_percent_of_the_exact_ones() {
        let mut l = Latencies::new();
        let mut all = Vec::new();
        let mut x = 0.37f64;
        let mut last = 0.0;
        for i in 0..50_000 {
            x = (x * 3.9 * (1.0 - x)).clamp(1e-6, 1.0 - 1e-6);
            let v = 0.2 + 30.0 * x * x + if i % 997 == 0 { 250.0 } else { 0.0 };
            l.record(v);
            all.push(v);
            last = v;
        }
        all.sort_by(f64::total_cmp);
        for q in [0.01, 0.5, 0.9, 0.99, 0.999, 1.0] {
            let exact = all[((q * all.len() as f64).ceil() as usize).clamp(1, all.len()) - 1];
            let got = l.quantile(q).unwrap();
            assert!(
                got >= exact && got <= exact * 1.0101,
                "q {q}: {got} against {exact}"
            );
        }
        assert_eq!(l.quantile(1.0), Some(*all.last().unwrap()));
        assert_eq!(l.len(), 50_000);
        assert_eq!(l.recent().len(), RECENT);
        assert_eq!(l.recent().back(), Some(&last));
        assert_eq!(Latencies::new().quantile(0.5), None);
        let mut z = Latencies::new();
        z.record(f64::NAN);
        z.record(-1.0);
        assert_eq!(z.quantile(1.0), Some(0.0));
    }
}
