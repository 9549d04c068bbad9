//! A textbook per-frame Lawson–Hanson NNLS that works on S itself (no Gram reuse, no warm
//! start): the speed baseline for the batch solver and an independent test oracle.

use nalgebra::{DMatrix, DVector};

/// Solves `min ‖S w − q‖², w ≥ 0` for one frame. Each inner solve is a Householder QR
/// least-squares solve on the passive columns, as in Lawson & Hanson (1974), ch. 23, algorithm NNLS.
pub fn nnls(s: &DMatrix<f64>, q: &DVector<f64>) -> DVector<f64> {
    let k = s.ncols();
    let mut w = DVector::zeros(k);
    let mut passive = vec![false; k];
    let scale = s.column_iter().map(|c| c.norm()).fold(0.0, f64::max) * q.norm().max(1e-300);
    let tol = 1e3 * f64::EPSILON * k.max(1) as f64 * scale.max(f64::MIN_POSITIVE);
    for _ in 0..3 * k + 20 {
        let g = s.tr_mul(&(q - s * &w));
        let pick = (0..k)
            .filter(|&i| !passive[i] && g[i] > tol)
            .max_by(|&a, &b| g[a].total_cmp(&g[b]));
        let Some(j) = pick else { break };
        passive[j] = true;
        for _ in 0..=k {
            let idx: Vec<usize> = (0..k).filter(|&i| passive[i]).collect();
            if idx.is_empty() {
                break;
            }
            let sp = s.select_columns(&idx);
            // Householder QR of the passive columns: R z = Qᵀ q.
            let qr = sp.qr();
            let Some(zp) = qr.r().solve_upper_triangular(&qr.q().tr_mul(q)) else {
                break;
            };
            if zp.iter().all(|&v| v > 0.0) {
                for (&i, &v) in idx.iter().zip(zp.iter()) {
                    w[i] = v;
                }
                break;
            }
            let (mut alpha, mut hit) = (f64::INFINITY, usize::MAX);
            for (&i, &v) in idx.iter().zip(zp.iter()) {
                if v <= 0.0 && w[i] / (w[i] - v) < alpha {
                    alpha = w[i] / (w[i] - v);
                    hit = i;
                }
            }
            let alpha = alpha.min(1.0);
            for (&i, &v) in idx.iter().zip(zp.iter()) {
                w[i] += alpha * (v - w[i]);
                if i == hit || w[i] <= 0.0 {
                    w[i] = 0.0;
                    passive[i] = false;
                }
            }
        }
    }
    w
}
