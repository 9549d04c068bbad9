//! Greedy forward selection (ours, beyond the paper): at each step add the frame that most
//! lowers paper 000 Eq. (5). The paper notes that the optimal key set is a combinatorial
//! search; greedy shows how far each heuristic is from a direct search of it.

use super::{Analysis, Heuristic, Selection, GRAM_LIMIT};
use crate::error::{Error, Result};
use crate::solve::Solver;
use nalgebra::DMatrix;
use rayon::prelude::*;

/// Greedy forward selection under `solver`.
///
/// Least squares is exact and cheap from the frames' Gram matrix K: with `K_R` the Gram
/// matrix of the residuals after projecting out the chosen frames, adding frame c lowers
/// the error by `‖K_R[:, c]‖² / K_R[c, c]`, and choosing it is a rank-one update of `K_R`.
/// For NNLS and bounded weights the gain has no closed form. Each step ranks every frame
/// by the gain of adding it alone with the other weights frozen — per frame
/// `max over a ∈ [0, u] of 2a⟨r_t, q_c⟩ − a²‖q_c‖²`, a lower bound on the true gain, all
/// frames at once from `K − K[:, keys] W` — then solves exactly for the best `shortlist`
/// candidates and keeps the best (`shortlist` = 0 solves for every frame).
#[derive(Debug, Clone, Copy)]
pub struct Greedy {
    /// The solver whose error is minimised.
    pub solver: Solver,
    /// Exact solves per step for nnls/bounded (0 = all frames).
    pub shortlist: usize,
}

impl Heuristic for Greedy {
    fn name(&self) -> String {
        "greedy".into()
    }

    fn select(&self, an: &Analysis, k: usize) -> Result<Selection> {
        let (columns, _) = greedy_path(an, k, self.solver, self.shortlist)?;
        Ok(Selection::frames(columns))
    }
}

/// The greedy choice of `kmax` frames and Eq. (5) after each addition.
///
/// Up to [`GRAM_LIMIT`] frames this works from the frames' Gram matrix. Beyond it, where
/// that matrix would not fit (80 GB at 100,000 frames), least squares runs
/// [`greedy_ls_feature_space`] — the same choice, exactly, from a values × values matrix —
/// and nnls/bounded run the Gram-matrix greedy on an evenly spaced subsample of
/// [`GRAM_LIMIT`] frames ([`greedy_subsampled`]): candidates and the residuals that rank
/// them come from the subsample (an approximation), the errors reported are exact, on every
/// frame.
pub fn greedy_path(
    an: &Analysis,
    kmax: usize,
    solver: Solver,
    shortlist: usize,
) -> Result<(Vec<usize>, Vec<f64>)> {
    if an.frames() > GRAM_LIMIT {
        return if solver == Solver::Ls {
            greedy_ls_feature_space(an, kmax)
        } else {
            greedy_subsampled(an, kmax, solver, shortlist, GRAM_LIMIT)
        };
    }
    greedy_gram(an, kmax, solver, shortlist)
}

/// Least-squares greedy without the frames × frames Gram matrix, choosing exactly what the
/// Gram-matrix greedy chooses. With `B` an orthonormal basis of the chosen frames and
/// `r_c = q_c − B Bᵀ q_c` the residual of candidate `c`, its gain is
/// `‖Qᵀ r_c‖² / ‖r_c‖² = r_cᵀ C r_c / ‖r_c‖²` with `C = Q Qᵀ` (values × values). Writing
/// `C = W Wᵀ` (its eigenvectors scaled by √λ), `Wᵀ r_c = Z[:, c] − (Wᵀ B) a_c` with
/// `Z = Wᵀ Q` formed once and `a_c = Bᵀ q_c` grown by one row per step, so each step costs
/// O(frames · values · k) and memory is two matrices of the coordinates' size.
pub fn greedy_ls_feature_space(an: &Analysis, kmax: usize) -> Result<(Vec<usize>, Vec<f64>)> {
    an.check_k(kmax)?;
    let q = &an.coords;
    let (d, n) = q.shape();
    let c = q * q.transpose();
    let eig = nalgebra::SymmetricEigen::new(c);
    let lmax = eig.eigenvalues.iter().copied().fold(0.0, f64::max);
    let keep: Vec<usize> = (0..d)
        .filter(|&i| eig.eigenvalues[i] > lmax * 1e-15 * d as f64)
        .collect();
    let mut w = DMatrix::<f64>::zeros(d, keep.len());
    for (j, &i) in keep.iter().enumerate() {
        w.set_column(j, &(eig.eigenvectors.column(i) * eig.eigenvalues[i].sqrt()));
    }
    let z = w.tr_mul(q);
    let top = an.sq_norms.iter().copied().fold(0.0, f64::max);
    let m = keep.len();
    // Filled one row (column) per step: Bᵀ Q, the orthonormal basis B of the chosen
    // frames, and Wᵀ B.
    let mut a = DMatrix::<f64>::zeros(kmax, n);
    let mut b = DMatrix::<f64>::zeros(d, kmax);
    let mut wb = DMatrix::<f64>::zeros(m, kmax);
    let mut taken = vec![false; n];
    let mut chosen = Vec::with_capacity(kmax);
    let mut errors = Vec::with_capacity(kmax);
    for j in 0..kmax {
        let (aj, wbj) = (a.rows(0, j), wb.columns(0, j));
        let scored: Vec<(usize, f64)> = (0..n)
            .into_par_iter()
            .filter_map(|c| {
                if taken[c] {
                    return None;
                }
                let ac = aj.column(c);
                let rr = an.sq_norms[c] - ac.norm_squared();
                if rr <= 1e-12 * top {
                    return None;
                }
                let v = z.column(c) - wbj * ac;
                Some((c, v.norm_squared() / rr))
            })
            .collect();
        let Some(&(pick, _)) = scored
            .iter()
            .max_by(|x, y| x.1.total_cmp(&y.1).then(y.0.cmp(&x.0)))
        else {
            return Err(Error::unfit(format!(
                "greedy: only {} linearly independent shapes, {kmax} asked for",
                chosen.len()
            )));
        };
        // The new basis vector: the pick's residual, orthogonalised twice for stability.
        let mut r = q.column(pick).clone_owned();
        for _ in 0..2 {
            let bj = b.columns(0, j);
            let coef = bj.tr_mul(&r);
            r -= bj * coef;
        }
        let norm = r.norm();
        if norm.is_nan() || norm <= 0.0 {
            return Err(Error::unfit(
                "greedy: a chosen frame lies in the span of the others",
            ));
        }
        r /= norm;
        a.row_mut(j).copy_from(&r.tr_mul(q));
        wb.column_mut(j).copy_from(&w.tr_mul(&r));
        b.column_mut(j).copy_from(&r);
        taken[pick] = true;
        chosen.push(pick);
        errors.push(an.weights_and_error(&chosen, Solver::Ls)?.1);
    }
    Ok((chosen, errors))
}

/// Greedy on an evenly spaced subsample of at most `limit` frames (every ⌈frames /
/// limit⌉-th, from the first): its choice, mapped back to the whole sequence, and the
/// exact Eq. (5) error of each prefix on every frame.
pub fn greedy_subsampled(
    an: &Analysis,
    kmax: usize,
    solver: Solver,
    shortlist: usize,
    limit: usize,
) -> Result<(Vec<usize>, Vec<f64>)> {
    an.check_k(kmax)?;
    let n = an.frames();
    let step = n.div_ceil(limit.max(1));
    let sub: Vec<usize> = (0..n).step_by(step).collect();
    let small = Analysis::with_axes(an.coords.select_columns(&sub), an.points, 3)?;
    let (keys, _) = greedy_gram(&small, kmax, solver, shortlist)?;
    // The subsample's Gram matrix (up to 288 MB) goes before the exact errors allocate
    // theirs (k × frames products), so the two never add up.
    drop(small);
    let chosen: Vec<usize> = keys.iter().map(|&c| sub[c]).collect();
    let errors = (1..=chosen.len())
        .map(|k| an.error(&chosen[..k], solver))
        .collect::<Result<Vec<f64>>>()?;
    Ok((chosen, errors))
}

/// The greedy choice from the frames' Gram matrix (at most [`GRAM_LIMIT`] frames).
pub fn greedy_gram(
    an: &Analysis,
    kmax: usize,
    solver: Solver,
    shortlist: usize,
) -> Result<(Vec<usize>, Vec<f64>)> {
    an.check_k(kmax)?;
    let k_full = an.frame_gram()?;
    // The residuals' Gram matrix K_R, updated each step, only for least squares: the
    // constrained gains work from K itself, so nnls/bounded keep one frames × frames matrix.
    let mut kr = if solver == Solver::Ls {
        k_full.clone()
    } else {
        DMatrix::zeros(0, 0)
    };
    let n = k_full.ncols();
    let top = (0..n).map(|c| k_full[(c, c)]).fold(0.0, f64::max);
    let mut chosen: Vec<usize> = Vec::with_capacity(kmax);
    let mut taken = vec![false; n];
    let mut errors = Vec::with_capacity(kmax);
    let mut weights = DMatrix::<f64>::zeros(0, n);
    for _ in 0..kmax {
        let mut gains: Vec<(usize, f64)> = if solver == Solver::Ls {
            // Exact least-squares gain of every remaining frame.
            (0..n)
                .filter(|&c| !taken[c] && kr[(c, c)] > 1e-12 * top)
                .map(|c| (c, kr.column(c).norm_squared() / kr[(c, c)]))
                .collect()
        } else {
            constrained_gains(k_full, &chosen, &weights, &taken, top, solver)
        };
        if gains.is_empty() {
            return Err(Error::unfit(format!(
                "greedy: only {} linearly independent shapes, {kmax} asked for",
                chosen.len()
            )));
        }
        gains.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        let (pick, w, e) = if solver == Solver::Ls {
            let mut keys = chosen.clone();
            keys.push(gains[0].0);
            let (w, e) = an.weights_and_error(&keys, solver)?;
            (gains[0].0, w, e)
        } else {
            let m = if shortlist == 0 {
                gains.len()
            } else {
                shortlist.min(gains.len())
            };
            let mut best: Option<(usize, DMatrix<f64>, f64)> = None;
            for &(c, _) in &gains[..m] {
                let mut keys = chosen.clone();
                keys.push(c);
                let (w, e) = an.weights_and_error(&keys, solver)?;
                if best.as_ref().is_none_or(|b| e < b.2) {
                    best = Some((c, w, e));
                }
            }
            best.ok_or_else(|| Error::unfit("greedy: no candidate"))?
        };
        // K_R ← K_R − u uᵀ with u = K_R[:, c] / sqrt(K_R[c, c]).
        if solver == Solver::Ls && kr[(pick, pick)] > 0.0 {
            let u = kr.column(pick) / kr[(pick, pick)].sqrt();
            kr.ger(-1.0, &u, &u, 1.0);
        }
        taken[pick] = true;
        chosen.push(pick);
        weights = w;
        errors.push(e);
    }
    Ok((chosen, errors))
}

/// Lower bounds on the constrained gain of adding each remaining frame (see [`Greedy`]).
fn constrained_gains(
    k_full: &DMatrix<f64>,
    chosen: &[usize],
    weights: &DMatrix<f64>,
    taken: &[bool],
    top: f64,
    solver: Solver,
) -> Vec<(usize, f64)> {
    let upper = if solver == Solver::Bounded {
        1.0
    } else {
        f64::INFINITY
    };
    // R[c, t] = ⟨q_c, r_t⟩ = K[c, t] − Σ_j K[c, key_j] W[j, t], with r_t the current
    // residual of frame t, one row at a time (never a second frames × frames matrix).
    let kc = k_full.select_columns(chosen);
    let j = chosen.len();
    let n = k_full.ncols();
    (0..n)
        .into_par_iter()
        .filter(|&c| !taken[c] && k_full[(c, c)] > 1e-12 * top)
        .map(|c| {
            let qq = k_full[(c, c)];
            let kcol = k_full.column(c);
            let mut gain = 0.0;
            for t in 0..n {
                let mut rc = kcol[t];
                for i in 0..j {
                    rc -= kc[(c, i)] * weights[(i, t)];
                }
                let a = (rc / qq).clamp(0.0, upper);
                gain += 2.0 * a * rc - a * a * qq;
            }
            (c, gain)
        })
        .collect()
}
