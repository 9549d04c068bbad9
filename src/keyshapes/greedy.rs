//! Greedy forward selection (ours, beyond the paper): at each step add the frame that most
//! lowers paper 000 Eq. (5). The paper notes that the optimal key set is a combinatorial
//! search; greedy shows how far each heuristic is from a direct search of it.

use super::{Analysis, Heuristic, Selection};
use crate::error::{Error, Result};
use crate::solve::Solver;
use nalgebra::DMatrix;

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
pub fn greedy_path(
    an: &Analysis,
    kmax: usize,
    solver: Solver,
    shortlist: usize,
) -> Result<(Vec<usize>, Vec<f64>)> {
    an.check_k(kmax)?;
    let mut kr = an.frame_gram()?.clone();
    let n = kr.ncols();
    let top = (0..n).map(|c| kr[(c, c)]).fold(0.0, f64::max);
    let mut chosen: Vec<usize> = Vec::with_capacity(kmax);
    let mut taken = vec![false; n];
    let mut errors = Vec::with_capacity(kmax);
    let mut weights = DMatrix::<f64>::zeros(0, n);
    let k_full = an.frame_gram()?;
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
            return Err(Error::invalid(format!(
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
            best.ok_or_else(|| Error::invalid("greedy: no candidate"))?
        };
        // K_R ← K_R − u uᵀ with u = K_R[:, c] / sqrt(K_R[c, c]).
        if kr[(pick, pick)] > 0.0 {
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
    // R[c, t] = ⟨q_c, r_t⟩ with r_t the current residual of frame t.
    let r = if chosen.is_empty() {
        k_full.clone()
    } else {
        k_full - k_full.select_columns(chosen) * weights
    };
    let n = k_full.ncols();
    (0..n)
        .filter(|&c| !taken[c] && k_full[(c, c)] > 1e-12 * top)
        .map(|c| {
            let qq = k_full[(c, c)];
            let gain: f64 = r
                .row(c)
                .iter()
                .map(|&rc| {
                    let a = (rc / qq).clamp(0.0, upper);
                    2.0 * a * rc - a * a * qq
                })
                .sum();
            (c, gain)
        })
        .collect()
}
