//! The ranges of numeric settings, declared once. A flag of the command line and the key
//! of an experiment file that set the same thing check their value against the same
//! [`Limit`], so neither accepts what the other refuses, and no value reaches an
//! allocation or a loop sized by it unchecked (`strip = 2⁶¹` overflowed a capacity,
//! `clean_sigma = 1e300` a kernel, `noise_px = 1e154` ran for minutes).

use crate::error::{setting, Error, Result};

/// A closed range `[lo, hi]` (or `(lo, hi]` when `lo_open`) in `unit`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limit {
    /// The smallest value.
    pub lo: f64,
    /// Whether `lo` itself is refused.
    pub lo_open: bool,
    /// The largest value.
    pub hi: f64,
    /// What the number counts, for the message.
    pub unit: &'static str,
}

impl Limit {
    /// `v` when it lies in the range; else an error naming the setting `name` (spelled
    /// as the caller's flag or key), the value and the range.
    pub fn check(&self, name: &str, v: f64) -> Result<f64> {
        if self.contains(v) {
            return Ok(v);
        }
        Err(Error::bad_setting(
            name,
            v,
            format!("{} {}", setting(name), self.why(v)),
        ))
    }

    /// Does `v` lie in the range (a finite number)?
    pub fn contains(&self, v: f64) -> bool {
        let above_lo = if self.lo_open {
            v > self.lo
        } else {
            v >= self.lo
        };
        v.is_finite() && above_lo && v <= self.hi
    }

    /// [`Limit::check`] for a count.
    pub fn check_count(&self, name: &str, v: u64) -> Result<usize> {
        let f = v as f64;
        let above_lo = if self.lo_open {
            f > self.lo
        } else {
            f >= self.lo
        };
        if above_lo && f <= self.hi {
            return usize::try_from(v)
                .map_err(|_| Error::bad_setting(name, v, "count beyond this machine"));
        }
        Err(Error::bad_setting(
            name,
            v,
            format!("{} {}", setting(name), self.why_count(v)),
        ))
    }

    /// Why `v` is refused, without the setting's name (for a message that names it
    /// already): "1e300: give 0 to 1000 pixels".
    pub fn why(&self, v: f64) -> String {
        let shown = if v.is_finite() && (v.abs() >= 1e9 || (v != 0.0 && v.abs() < 1e-4)) {
            format!("{v:e}")
        } else {
            format!("{v}")
        };
        format!("{shown}: give {} {}", self.describe(), self.unit)
    }

    /// [`Limit::why`] for a count.
    pub fn why_count(&self, v: u64) -> String {
        format!("{v}: give {} {}", self.describe(), self.unit)
    }

    /// The range in words: "0 to 1000", "more than 0 and at most 1000".
    pub fn describe(&self) -> String {
        if self.lo_open {
            format!("more than {} and at most {}", self.lo, self.hi)
        } else {
            format!("{} to {}", self.lo, self.hi)
        }
    }
}

/// Landmark noise σ of a rendered benchmark track (`rig-accuracy --noise`, `[rig]
/// noise_px`).
pub const NOISE_PX: Limit = Limit {
    lo: 0.0,
    lo_open: false,
    hi: 1000.0,
    unit: "pixels",
};

/// σ of the Gaussian low-pass that makes the smoothing study's clean reference
/// (`smooth --clean-sigma`, `[smooth] clean_sigma`).
pub const CLEAN_SIGMA: Limit = Limit {
    lo: 0.0,
    lo_open: true,
    hi: 1000.0,
    unit: "frames",
};

/// Frames in the retarget study's strip of worst frames (`[retarget] strip`).
pub const STRIP_FRAMES: Limit = Limit {
    lo: 0.0,
    lo_open: false,
    hi: 1000.0,
    unit: "frames",
};

/// λ of the rig's temporal prior (`rig --smooth`, `rig-accuracy --smooth`, `[rig] smooth`,
/// the lab's `l` on the rig): beyond 1e4 the weights barely change and the solve stops
/// converging (its sweeps reach their cap); `--smooth 1e300` ran for half a minute.
pub const RIG_SMOOTH: Limit = Limit {
    lo: 0.0,
    lo_open: false,
    hi: 1e4,
    unit: "(λ of the temporal prior)",
};

/// Shards of a corpus run (`run --shard i/n`, `merge`).
pub const SHARDS: Limit = Limit {
    lo: 1.0,
    lo_open: false,
    hi: 1_000_000.0,
    unit: "shards",
};

/// Degree of the intensity study's smoothing polynomial (`intensity --degree`,
/// `[intensity] degree`): paper 002 uses 5; beyond 12 the monomial fit on a clip loses its
/// conditioning and the solve falls back to the raw signal, which `--degree 50` returned
/// without a word.
pub const POLY_DEGREE: Limit = Limit {
    lo: 0.0,
    lo_open: false,
    hi: 12.0,
    unit: "(polynomial degree)",
};

/// A replayed file's frames per second (`live --rate`): one frame a minute to ten
/// thousand a second. `--rate 1e-20` passed the old (0, 10000] check and its frame period
/// (1e20 s) panicked the reader thread.
pub const LIVE_RATE: Limit = Limit {
    lo: 1.0 / 60.0,
    lo_open: false,
    hi: 10_000.0,
    unit: "frames per second",
};

/// Frames of a benchmark's generated or repeated track (`bench nnls|rig|transfer|smooth|
/// scale --frames`, `bench nnls --baseline-frames`): `2⁶¹` overflowed a capacity, and
/// `bench scale` had no bound at all (13 GB of staging).
pub const BENCH_FRAMES: Limit = Limit {
    lo: 1.0,
    lo_open: false,
    hi: 1_000_000.0,
    unit: "frames",
};

/// Other counts of a benchmark: key shapes, repeats, points, k-means restarts, the largest
/// k of a sweep.
pub const BENCH_COUNT: Limit = Limit {
    lo: 1.0,
    lo_open: false,
    hi: 10_000.0,
    unit: "(a count)",
};

/// Seconds a benchmark runs (`bench live --seconds`).
pub const BENCH_SECONDS: Limit = Limit {
    lo: 0.0,
    lo_open: true,
    hi: 3600.0,
    unit: "seconds",
};

/// The frame rate a benchmark sends at (`bench live --fps`).
pub const BENCH_FPS: Limit = Limit {
    lo: 0.0,
    lo_open: true,
    hi: 10_000.0,
    unit: "frames per second",
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_limit_takes_its_ends_and_refuses_what_lies_beyond_and_nan() {
        assert_eq!(NOISE_PX.check("noise", 0.0).ok(), Some(0.0));
        assert_eq!(NOISE_PX.check("noise", 1000.0).ok(), Some(1000.0));
        for v in [-1.0, f64::NAN, 1e300, 2f64.powi(61), f64::INFINITY, 1000.5] {
            assert!(NOISE_PX.check("noise", v).is_err(), "{v}");
        }
        assert!(CLEAN_SIGMA.check("clean_sigma", 0.0).is_err());
        assert!(CLEAN_SIGMA.check("clean_sigma", 1e-9).is_ok());
        assert!(SHARDS.check_count("shard", 0).is_err());
        assert!(SHARDS.check_count("shard", 1 << 61).is_err());
        assert_eq!(SHARDS.check_count("shard", 1_000_000).ok(), Some(1_000_000));
        let e = STRIP_FRAMES
            .check_count("strip", 1 << 61)
            .map(|_| ())
            .unwrap_err()
            .to_string();
        assert_eq!(e, "strip 2305843009213693952: give 0 to 1000 frames");
    }

    #[test]
    fn an_open_lower_end_refuses_itself_for_counts_too() {
        let l = Limit {
            lo: 0.0,
            lo_open: true,
            hi: 10.0,
            unit: "things",
        };
        assert!(l.check_count("n", 0).is_err());
        assert_eq!(l.check_count("n", 1).ok(), Some(1));
        assert_eq!(l.check_count("n", 10).ok(), Some(10));
        assert!(l.check_count("n", 11).is_err());
        assert!(l.check("x", 0.0).is_err());
        assert_eq!(l.check("x", 1e-9).ok(), Some(1e-9));
        assert_eq!(l.describe(), "more than 0 and at most 10");
    }

    #[test]
    fn a_refused_value_is_shown_as_it_reads_best() {
        let why = |v: f64| NOISE_PX.why(v);
        assert_eq!(why(1e300), "1e300: give 0 to 1000 pixels");
        assert_eq!(why(-2e9), "-2e9: give 0 to 1000 pixels");
        assert_eq!(why(1e9), "1e9: give 0 to 1000 pixels");
        assert_eq!(why(5e-5), "5e-5: give 0 to 1000 pixels");
        assert_eq!(why(-5e-5), "-5e-5: give 0 to 1000 pixels");
        assert_eq!(why(1e-4), "0.0001: give 0 to 1000 pixels");
        assert_eq!(why(999_999_999.0), "999999999: give 0 to 1000 pixels");
        assert_eq!(why(0.0), "0: give 0 to 1000 pixels");
        assert_eq!(why(-1.0), "-1: give 0 to 1000 pixels");
        assert_eq!(why(f64::NAN), "NaN: give 0 to 1000 pixels");
        assert_eq!(why(f64::INFINITY), "inf: give 0 to 1000 pixels");
    }
}
