//! Measures that compare two signals: the correlation coefficient (paper 002's evaluation)
//! and the lag between two weight tracks.

use nalgebra::DMatrix;
use std::ops::Range;

/// Paper 002 Eq. (10): the correlation coefficient of two signals (Pearson; 0 when either
/// is constant).
pub fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    if n < 2 {
        return 0.0;
    }
    let (ma, mb) = (
        a[..n].iter().sum::<f64>() / n as f64,
        b[..n].iter().sum::<f64>() / n as f64,
    );
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let (da, db) = (a[i] - ma, b[i] - mb);
        sab += da * db;
        saa += da * da;
        sbb += db * db;
    }
    if saa <= 0.0 || sbb <= 0.0 {
        0.0
    } else {
        sab / (saa * sbb).sqrt()
    }
}

/// The shift in −`max`..=`max` frames maximising the cross-correlation of `a` with `b`
/// (rows mean-removed, summed over rows, within segments): positive when `a` trails `b`.
pub fn lag(a: &DMatrix<f64>, b: &DMatrix<f64>, segs: &[Range<usize>], max: i64) -> i64 {
    // Each row's mean in each segment, subtracted where the products are taken (no
    // mean-removed copies of the two series).
    let means = |m: &DMatrix<f64>| -> Vec<Vec<f64>> {
        segs.iter()
            .map(|r| {
                (0..m.nrows())
                    .map(|i| {
                        (r.start..r.end).map(|t| m[(i, t)]).sum::<f64>() / r.len().max(1) as f64
                    })
                    .collect()
            })
            .collect()
    };
    let (ma, mb) = (means(a), means(b));
    let mut best = (f64::NEG_INFINITY, 0i64);
    for d in -max..=max {
        let mut acc = 0.0;
        for (r, (ma, mb)) in segs.iter().zip(ma.iter().zip(&mb)) {
            for t in r.clone() {
                let u = t as i64 - d;
                if u < r.start as i64 || u >= r.end as i64 {
                    continue;
                }
                for i in 0..a.nrows() {
                    acc += (a[(i, t)] - ma[i]) * (b[(i, u as usize)] - mb[i]);
                }
            }
        }
        // Ties go to the smaller shift.
        if acc > best.0 + 1e-12 * acc.abs() || (acc >= best.0 && d.abs() < best.1.abs()) {
            best = (acc, d);
        }
    }
    best.1
}

/// `v` with `digits` significant digits, never in exponent form for the sizes an error
/// takes (1.05, 0.00123, 123): an error in normalised coordinates (0.0012) must not read
/// 0.00 under a fixed two decimals.
pub fn sig(v: f64, digits: usize) -> String {
    if !v.is_finite() || v == 0.0 {
        return format!("{v}");
    }
    let mag = v.abs().log10().floor() as i32;
    let decimals = (digits as i32 - 1 - mag).max(0) as usize;
    if !(-6..=15).contains(&mag) {
        return format!("{v:.*e}", digits.saturating_sub(1));
    }
    format!("{v:.decimals$}")
}

#[cfg(test)]
mod sig_tests {
    use super::sig;

    #[test]
    fn three_significant_digits_at_every_scale() {
        assert_eq!(sig(1.0512, 3), "1.05");
        assert_eq!(sig(0.0012345, 3), "0.00123");
        assert_eq!(sig(123.456, 3), "123");
        assert_eq!(sig(12345.6, 3), "12346");
        assert_eq!(sig(-0.5, 2), "-0.50");
        assert_eq!(sig(0.0, 3), "0");
        assert_eq!(sig(1.5e-9, 3), "1.50e-9");
    }
}
