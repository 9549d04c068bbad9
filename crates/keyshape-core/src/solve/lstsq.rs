//! Unconstrained least squares, paper 000 Eq. (3): `min ‖S w − q‖²`.

use crate::error::{Error, Result};
use nalgebra::DMatrix;

/// The pseudo-inverse of S by (one-sided Jacobi) SVD with a rank cutoff, plus what the cutoff found.
#[derive(Debug, Clone)]
pub struct PseudoInverse {
    /// `S⁺` (k × n).
    pub pinv: DMatrix<f64>,
    /// Singular values kept.
    pub rank: usize,
    /// σ_max / σ_min over all singular values (∞ when S is rank deficient).
    pub condition: f64,
}

/// Default relative cutoff: singular values below `max(n, k) · ε · σ_max` count as zero,
/// the convention of LAPACK's `gelsd` and NumPy's `lstsq`. Duplicate key shapes then share
/// their weight (minimum-norm solution) instead of blowing up.
pub fn default_rcond(n: usize, k: usize) -> f64 {
    n.max(k) as f64 * f64::EPSILON
}

/// Rank-revealing pseudo-inverse of `s` (n × k).
pub fn pseudo_inverse(s: &DMatrix<f64>, rcond: Option<f64>) -> Result<PseudoInverse> {
    let (n, k) = s.shape();
    let rcond = rcond.unwrap_or_else(|| default_rcond(n, k));
    if !(0.0..1.0).contains(&rcond) {
        return Err(Error::bad_setting(
            "rcond",
            rcond,
            format!("rcond must be in [0, 1), got {rcond}"),
        ));
    }
    let svd = super::jacobi::svd(s);
    let sv = &svd.s;
    let smax = sv.iter().copied().fold(0.0, f64::max);
    let smin = sv.iter().copied().fold(f64::INFINITY, f64::min);
    let cut = rcond * smax;
    let mut pinv = DMatrix::zeros(k, n);
    let mut rank = 0;
    for (i, &sigma) in sv.iter().enumerate() {
        if sigma > cut && sigma > 0.0 {
            rank += 1;
            // pinv += v_i (1/σ_i) u_iᵀ
            pinv.ger(1.0 / sigma, &svd.v.column(i), &svd.u.column(i), 1.0);
        }
    }
    let condition = if smin > 0.0 {
        smax / smin
    } else {
        f64::INFINITY
    };
    Ok(PseudoInverse {
        pinv,
        rank,
        condition,
    })
}

/// The normal-equation solve `(SᵀS) w = Sᵀq` by Cholesky, for well-conditioned S only.
/// It is the speed baseline for the batch solvers and a test oracle for LS.
pub fn normal_equations(s: &DMatrix<f64>, q: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    let chol = s
        .tr_mul(s)
        .cholesky()
        .ok_or_else(|| Error::unfit("SᵀS is not positive definite (dependent key shapes)"))?;
    Ok(chol.solve(&s.tr_mul(q)))
}

/// [`normal_equations`] over column chunks in parallel (the batch speed baseline).
pub fn normal_equations_batch(s: &DMatrix<f64>, q: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    use rayon::prelude::*;
    let k = s.ncols();
    let chol = s
        .tr_mul(s)
        .cholesky()
        .ok_or_else(|| Error::unfit("SᵀS is not positive definite (dependent key shapes)"))?;
    let st = s.transpose();
    let mut out = DMatrix::zeros(k, q.ncols());
    out.as_mut_slice()
        .par_chunks_mut(k * super::CHUNK)
        .enumerate()
        .for_each(|(c, dst)| {
            let m = dst.len() / k;
            let w = chol.solve(&(&st * q.columns(c * super::CHUNK, m)));
            dst.copy_from_slice(w.as_slice());
        });
    Ok(out)
}

/// `G⁺` for a symmetric positive semi-definite Gram matrix `G = SᵀS`, by symmetric
/// eigendecomposition. Eigenvalues below `max(k·ε, rcond²)·λ_max` count as zero: through
/// the Gram matrix the condition number is squared, so directions of S with
/// `σ < sqrt(k·ε)·σ_max` (≈ 5e-8 for k = 24) are treated as null. Used where only the
/// inner products are at hand (error curves from the frames' Gram matrix).
pub fn gram_pseudo_inverse(g: &DMatrix<f64>, rcond: Option<f64>) -> DMatrix<f64> {
    let k = g.nrows();
    let eig = nalgebra::SymmetricEigen::new(g.clone());
    let lmax = eig.eigenvalues.iter().copied().fold(0.0, f64::max);
    let r = rcond.unwrap_or_else(|| default_rcond(k, k));
    let cut = (k as f64 * f64::EPSILON).max(r * r) * lmax;
    let mut out = DMatrix::zeros(k, k);
    for (i, &l) in eig.eigenvalues.iter().enumerate() {
        if l > cut && l > 0.0 {
            let v = eig.eigenvectors.column(i);
            out.ger(1.0 / l, &v, &v, 1.0);
        }
    }
    out
}
