//! Jitter, one definition for every report: the RMS of the second
//! temporal difference, within segments (a clip boundary or a gap in the frame numbers is
//! not motion). For weights it is per weight (weight units per frame²); for retargeted points
//! per point, the RMS length of a point's second difference (px per frame²).

use nalgebra::DMatrix;
use std::ops::Range;

/// The sum of squared second differences of the columns of `x` within `segs`, and how many
/// columns contributed.
fn second_differences(x: &DMatrix<f64>, segs: &[Range<usize>]) -> (f64, usize) {
    let (mut acc, mut n) = (0.0, 0usize);
    for r in segs {
        for t in r.start + 1..r.end.saturating_sub(1) {
            acc += (x.column(t + 1) - x.column(t) * 2.0 + x.column(t - 1)).norm_squared();
            n += 1;
        }
    }
    (acc, n)
}

/// `sqrt(Σ_t ‖x_{t+1} − 2 x_t + x_{t−1}‖² / (per · count))` over the frames `t` inside
/// `segs`: per value with `per` = the rows of `x`, per point with `per` = points. 0 when no
/// segment has three frames.
pub fn jitter(x: &DMatrix<f64>, segs: &[Range<usize>], per: usize) -> f64 {
    let (acc, n) = second_differences(x, segs);
    if n == 0 || per == 0 {
        0.0
    } else {
        (acc / (n * per) as f64).sqrt()
    }
}

/// The weights' jitter: [`jitter`] per weight.
pub fn weight_jitter(w: &DMatrix<f64>, segs: &[Range<usize>]) -> f64 {
    jitter(w, segs, w.nrows())
}

/// The jitter of several weight matrices of one sequence taken together (the regions of a
/// region-based solve), each over `segs`.
pub fn weight_jitter_all(weights: &[DMatrix<f64>], segs: &[Range<usize>]) -> f64 {
    let (acc, n) = weights.iter().fold((0.0, 0usize), |(a, n), w| {
        let (s, c) = second_differences(w, segs);
        (a + s, n + c * w.nrows())
    });
    if n == 0 {
        0.0
    } else {
        (acc / n as f64).sqrt()
    }
}

#[cfg(test)]
// One segment spanning the whole series is what these tests mean.
#[allow(clippy::single_range_in_vec_init)]
mod tests {
    use super::*;

    /// w_t = t² has second difference 2 everywhere: jitter 2, in every spelling.
    #[test]
    fn a_parabola_has_jitter_two_and_a_line_none() {
        let w = DMatrix::from_fn(3, 10, |_, t| (t * t) as f64);
        let all = [0..10];
        assert!((weight_jitter(&w, &all) - 2.0).abs() < 1e-12);
        assert!((weight_jitter_all(&[w.clone(), w.clone()], &all) - 2.0).abs() < 1e-12);
        // Two points of (x, y) = (t², t²) per column: each point's second difference has
        // length 2√2.
        let pts = DMatrix::from_fn(4, 10, |_, t| (t * t) as f64);
        assert!((jitter(&pts, &all, 2) - 8f64.sqrt()).abs() < 1e-12);
        let line = DMatrix::from_fn(2, 10, |i, t| (i + 3 * t) as f64);
        assert_eq!(weight_jitter(&line, &all), 0.0);
        assert_eq!(weight_jitter(&w, &[0..2, 2..4]), 0.0);
    }

    /// A jump between two segments is not motion: a step at the boundary leaves jitter 0.
    #[test]
    fn segment_boundaries_are_not_motion() {
        let w = DMatrix::from_fn(1, 8, |_, t| if t < 4 { 0.0 } else { 1.0 });
        assert_eq!(weight_jitter(&w, &[0..4, 4..8]), 0.0);
        assert!(weight_jitter(&w, &[0..8]) > 0.0);
    }
}
