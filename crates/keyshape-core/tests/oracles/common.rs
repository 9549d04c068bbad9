//! Oracles shared by the core's tests.

use keyshape_core::solve::active_set::Gram;
use nalgebra::{DMatrix, DVector};
use std::path::PathBuf;

/// `shared/data/<rel>` beside the repository (`keyshape_io::shared_data`).
pub fn shared(rel: &str) -> PathBuf {
    keyshape_io::shared_data(rel).unwrap()
}

/// Checks the KKT conditions of `min ‖S w − q‖², 0 ≤ w ≤ upper` and returns the worst
/// violation relative to `max‖Sᵢ‖·‖q‖`.
pub fn kkt_violation(s: &DMatrix<f64>, q: &DVector<f64>, w: &DVector<f64>, upper: f64) -> f64 {
    let g = s.tr_mul(&(q - s * w));
    let scale = Gram::new(s, upper).max_norm * q.norm().max(1e-300);
    let mut worst = 0.0f64;
    for i in 0..w.len() {
        assert!(
            w[i] >= 0.0 && w[i] <= upper,
            "w[{i}] = {} outside [0, {upper}]",
            w[i]
        );
        let v = if w[i] == 0.0 {
            g[i].max(0.0)
        } else if w[i] == upper {
            (-g[i]).max(0.0)
        } else {
            g[i].abs()
        };
        worst = worst.max(v / scale);
    }
    worst
}

/// `‖S w − q‖²`.
pub fn objective(s: &DMatrix<f64>, q: &DVector<f64>, w: &DVector<f64>) -> f64 {
    (s * w - q).norm_squared()
}

/// The bounded least-squares optimum by enumerating every assignment of each variable to
/// {at 0, free, at upper} (3^k, or 2^k for NNLS). Tiny k only.
pub fn brute_force(s: &DMatrix<f64>, q: &DVector<f64>, upper: f64) -> f64 {
    let k = s.ncols();
    let states = if upper.is_finite() { 3usize } else { 2 };
    let mut best = f64::INFINITY;
    for code in 0..states.pow(k as u32) {
        let mut c = code;
        let mut st = vec![0usize; k];
        for v in st.iter_mut() {
            *v = c % states;
            c /= states;
        }
        let free: Vec<usize> = (0..k).filter(|&i| st[i] == 1).collect();
        let mut w = DVector::zeros(k);
        for i in 0..k {
            if st[i] == 2 {
                w[i] = upper;
            }
        }
        if !free.is_empty() {
            let sf = s.select_columns(&free);
            let r = q - s * &w;
            // Householder QR (not nalgebra's SVD, see src/solve/jacobi.rs); subsets with
            // dependent columns are skipped: a subset without the dependent column reaches
            // the same objective.
            let qr = sf.clone().qr();
            let rr = qr.r();
            if rr.diagonal().iter().any(|d| d.abs() < 1e-10 * sf.norm()) {
                continue;
            }
            let Some(z) = rr.solve_upper_triangular(&qr.q().tr_mul(&r)) else {
                continue;
            };
            if z.iter().any(|&v| v < -1e-9 || v > upper + 1e-9) {
                continue;
            }
            for (&i, &v) in free.iter().zip(z.iter()) {
                w[i] = v.clamp(0.0, upper);
            }
        }
        best = best.min(objective(s, q, &w));
    }
    best
}
