//! The per-frame steps of paper 002 §4.1: the soft K-nearest-neighbour proportions, the
//! median-3 filter and the least-squares polynomial.

use keyshape_core::error::{Error, Result};
use nalgebra::{DMatrix, DVector};

/// Soft KNN: for each query column, the share of its `k` nearest training columns
/// (Euclidean) in each class (`labels[i]` < `classes`). Rows: classes; columns: queries.
pub fn soft_knn(
    train: &DMatrix<f64>,
    labels: &[usize],
    classes: usize,
    query: &DMatrix<f64>,
    k: usize,
) -> Result<DMatrix<f64>> {
    if train.ncols() != labels.len() || train.nrows() != query.nrows() {
        return Err(Error::invalid(
            "KNN: training features, labels and queries do not match",
        ));
    }
    if k == 0 || k > train.ncols() {
        return Err(Error::bad_setting(
            "k",
            k,
            format!("KNN: K = {k} needs 1..={} training frames", train.ncols()),
        ));
    }
    if let Some(&bad) = labels.iter().find(|&&l| l >= classes) {
        return Err(Error::invalid(format!(
            "KNN: label {bad} out of range (0..{classes})"
        )));
    }
    let mut out = DMatrix::zeros(classes, query.ncols());
    for q in 0..query.ncols() {
        let qc = query.column(q);
        let mut d: Vec<(f64, usize)> = (0..train.ncols())
            .map(|i| ((train.column(i) - qc).norm_squared(), i))
            .collect();
        d.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for &(_, i) in &d[..k] {
            out[(labels[i], q)] += 1.0 / k as f64;
        }
    }
    Ok(out)
}

/// Median filter with window 3; the ends keep their values.
pub fn median3(x: &[f64]) -> Vec<f64> {
    (0..x.len())
        .map(|i| {
            if i == 0 || i + 1 == x.len() {
                return x[i];
            }
            let mut w = [x[i - 1], x[i], x[i + 1]];
            w.sort_by(f64::total_cmp);
            w[1]
        })
        .collect()
}

/// Least-squares polynomial of `degree` through `(t, x[t])`, t scaled to \[−1, 1\] for
/// conditioning, evaluated at every t. The degree drops to fit short signals.
pub fn polyfit_smooth(x: &[f64], degree: usize) -> Vec<f64> {
    let n = x.len();
    if n < 2 {
        return x.to_vec();
    }
    let deg = degree.min(n - 1);
    let t = |i: usize| 2.0 * i as f64 / (n - 1) as f64 - 1.0;
    let a = DMatrix::from_fn(n, deg + 1, |i, j| t(i).powi(j as i32));
    let y = DVector::from_column_slice(x);
    let qr = a.clone().qr();
    match qr.r().solve_upper_triangular(&qr.q().tr_mul(&y)) {
        Some(c) => (&a * c).iter().copied().collect(),
        None => x.to_vec(),
    }
}
