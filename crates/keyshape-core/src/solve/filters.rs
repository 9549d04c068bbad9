//! Filters applied to weights after the solve — the usual fix for jitter, and the anchors
//! the temporal prior ([`super::temporal`]) is compared with. Each runs along time on every
//! row of a k × frames weight matrix, within segments, and the result is clamped back to
//! the solver's constraints.

use super::Solver;
use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};
use std::ops::Range;

/// A post-filter.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub enum PostFilter {
    /// Centred moving average over `window` frames (odd; zero phase, shrinks at the ends).
    MovingAverage {
        /// Frames averaged (odd, ≥ 1).
        window: usize,
    },
    /// Exponential moving average `y_t = α x_t + (1 − α) y_{t−1}` (causal).
    Exponential {
        /// Smoothing factor in (0, 1].
        alpha: f64,
    },
    /// The One Euro filter (Casiez, Roussel & Vogel, CHI 2012): a first-order low-pass whose
    /// cutoff rises with the speed of the raw signal, itself low-passed at `d_cutoff`
    /// (causal): `cutoff = min_cutoff + beta·|ẋ|`, `α = 1 / (1 + rate/(2π·cutoff))`.
    OneEuro {
        /// Cutoff at rest, Hz.
        min_cutoff: f64,
        /// Cutoff increase per unit of speed.
        beta: f64,
        /// Cutoff of the speed estimate, Hz.
        d_cutoff: f64,
        /// Frames per second.
        rate: f64,
    },
}

impl PostFilter {
    /// Name of the family (`moving-average`, `ema`, `one-euro`).
    pub fn family(&self) -> &'static str {
        match self {
            PostFilter::MovingAverage { .. } => "moving-average",
            PostFilter::Exponential { .. } => "ema",
            PostFilter::OneEuro { .. } => "one-euro",
        }
    }

    /// The curve a setting belongs to in a study: the family, and for One Euro its beta
    /// (`one-euro beta 0.5`), since beta changes the filter's character, not its strength.
    pub fn series(&self) -> String {
        match self {
            PostFilter::OneEuro { beta, .. } => format!("one-euro beta {beta}"),
            _ => self.family().to_string(),
        }
    }

    /// The setting in words (`window 5`, `alpha 0.3`, `min_cutoff 1 Hz beta 0.5`; no commas).
    pub fn setting(&self) -> String {
        match self {
            PostFilter::MovingAverage { window } => format!("window {window}"),
            PostFilter::Exponential { alpha } => format!("alpha {alpha}"),
            PostFilter::OneEuro {
                min_cutoff, beta, ..
            } => format!("min_cutoff {min_cutoff} Hz beta {beta}"),
        }
    }

    /// Checks the parameters.
    pub fn check(&self) -> Result<()> {
        let ok = match *self {
            PostFilter::MovingAverage { window } => window >= 1 && window % 2 == 1,
            PostFilter::Exponential { alpha } => alpha > 0.0 && alpha <= 1.0,
            PostFilter::OneEuro {
                min_cutoff,
                beta,
                d_cutoff,
                rate,
            } => {
                min_cutoff > 0.0
                    && min_cutoff.is_finite()
                    && beta >= 0.0
                    && beta.is_finite()
                    && d_cutoff > 0.0
                    && d_cutoff.is_finite()
                    && rate > 0.0
                    && rate.is_finite()
            }
        };
        if ok {
            Ok(())
        } else {
            Err(Error::bad_setting("filter", self.setting(), format!(
                "bad {} filter setting: {} (window odd ≥ 1; alpha in (0, 1]; cutoffs and rate > 0, beta ≥ 0)",
                self.family(),
                self.setting()
            )))
        }
    }

    /// Filters one signal.
    pub fn apply_signal(&self, x: &[f64]) -> Vec<f64> {
        let n = x.len();
        match *self {
            PostFilter::MovingAverage { window } => {
                let h = window / 2;
                (0..n)
                    .map(|t| {
                        // Shrink symmetrically at the ends so the filter stays zero-phase.
                        let r = h.min(t).min(n - 1 - t);
                        x[t - r..=t + r].iter().sum::<f64>() / (2 * r + 1) as f64
                    })
                    .collect()
            }
            PostFilter::Exponential { alpha } => {
                let mut y = Vec::with_capacity(n);
                for (t, &v) in x.iter().enumerate() {
                    let prev = if t == 0 { v } else { y[t - 1] };
                    y.push(alpha * v + (1.0 - alpha) * prev);
                }
                y
            }
            PostFilter::OneEuro {
                min_cutoff,
                beta,
                d_cutoff,
                rate,
            } => {
                let alpha = |cutoff: f64| {
                    let tau = 1.0 / (2.0 * std::f64::consts::PI * cutoff);
                    1.0 / (1.0 + tau * rate)
                };
                let mut y = Vec::with_capacity(n);
                let mut dx_hat = 0.0;
                for (t, &v) in x.iter().enumerate() {
                    if t == 0 {
                        y.push(v);
                        continue;
                    }
                    // The speed of the raw signal, as in the authors' reference code
                    // (`value − lastRawValue`); the speed against the filtered value would
                    // grow with the filter's own lag and undo the smoothing at low cutoffs.
                    let dx = (v - x[t - 1]) * rate;
                    let ad = alpha(d_cutoff);
                    dx_hat = ad * dx + (1.0 - ad) * dx_hat;
                    let a = alpha(min_cutoff + beta * dx_hat.abs());
                    y.push(a * v + (1.0 - a) * y[t - 1]);
                }
                y
            }
        }
    }

    /// Filters every row of `w` (k × frames) within each segment and clamps to `solver`'s
    /// constraints.
    pub fn apply(
        &self,
        w: &DMatrix<f64>,
        segments: &[Range<usize>],
        solver: Solver,
    ) -> Result<DMatrix<f64>> {
        self.check()?;
        let (lo, hi) = match solver {
            Solver::Ls => (f64::NEG_INFINITY, f64::INFINITY),
            Solver::Nnls => (0.0, f64::INFINITY),
            Solver::Bounded => (0.0, 1.0),
        };
        let mut out = w.clone();
        for r in segments {
            for i in 0..w.nrows() {
                let x: Vec<f64> = (r.start..r.end).map(|t| w[(i, t)]).collect();
                for (j, v) in self.apply_signal(&x).into_iter().enumerate() {
                    out[(i, r.start + j)] = v.clamp(lo, hi);
                }
            }
        }
        Ok(out)
    }
}

/// Zero-phase Gaussian low-pass of every row within segments (σ in frames, truncated at
/// 3σ, renormalised at the ends).
pub fn gaussian_lowpass(x: &DMatrix<f64>, segs: &[Range<usize>], sigma: f64) -> DMatrix<f64> {
    let lp = Lowpass::new(sigma);
    let mut out = x.clone();
    for r in segs {
        for t in r.clone() {
            out.set_column(t, &lp.frame(x, r, t));
        }
    }
    out
}

/// The Gaussian low-pass of one frame at a time (what [`gaussian_lowpass`] computes for
/// each frame), so a caller can filter a chunk of a long track without a filtered copy
/// of it all.
pub struct Lowpass {
    h: i64,
    kern: Vec<f64>,
}

impl Lowpass {
    /// The kernel for σ `sigma` frames (truncated at 3σ).
    pub fn new(sigma: f64) -> Self {
        let h = (3.0 * sigma).ceil() as i64;
        let kern = (-h..=h)
            .map(|d| (-(d * d) as f64 / (2.0 * sigma * sigma)).exp())
            .collect();
        Lowpass { h, kern }
    }

    /// Frame `t` of `x` filtered within its segment `r`.
    pub fn frame(&self, x: &DMatrix<f64>, r: &Range<usize>, t: usize) -> DVector<f64> {
        let h = self.h;
        let (mut acc, mut wsum) = (vec![0.0; x.nrows()], 0.0);
        for d in -h..=h {
            let u = t as i64 + d;
            if u < r.start as i64 || u >= r.end as i64 {
                continue;
            }
            let w = self.kern[(d + h) as usize];
            wsum += w;
            for (i, a) in acc.iter_mut().enumerate() {
                *a += w * x[(i, u as usize)];
            }
        }
        DVector::from_iterator(x.nrows(), acc.into_iter().map(|a| a / wsum))
    }
}
