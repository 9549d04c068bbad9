//! The causal solve: each frame pulled towards its prediction from the past.

use super::kkt::kkt_residual;
use super::{Smoothed, Smoothing};
use crate::error::{Error, Result};
use crate::solve::active_set::{solve_frame, Bound, Gram, Workspace};
use crate::solve::Solver;
use nalgebra::DMatrix;
use rayon::prelude::*;
use std::ops::Range;

/// What every frame of a causal solve shares: the Gram forms with and without the prior.
pub struct CausalShared {
    pub(super) k: usize,
    pub(super) solver: Solver,
    pub(super) sm: Smoothing,
    pub(super) gram_l: Gram,
    pub(super) gram_0: Gram,
    pub(super) pinv_0: DMatrix<f64>,
    pub(super) chol_l: nalgebra::Cholesky<f64, nalgebra::Dyn>,
}

/// One segment's running state of a causal solve: the weights of the last two frames and
/// the active-set workspaces. Frames go in one at a time ([`CausalShared::step`]), so the
/// solve runs as the frames arrive (a streamed solve feeds it chunk after chunk).
pub struct CausalState {
    pub(super) ws0: Workspace,
    pub(super) wsl: Workspace,
    pub(super) prev: Vec<f64>,
    pub(super) prev2: Vec<f64>,
    /// Frames of the segment so far.
    pub frames: usize,
    /// Active-set iterations so far.
    pub iterations: u64,
    /// Frames that hit the active-set iteration cap.
    pub unconverged: usize,
}

impl CausalShared {
    /// From `G = SᵀS`, for `solver` under the prior `sm` (its mode is not looked at).
    pub fn new(g: &DMatrix<f64>, solver: Solver, sm: &Smoothing) -> Result<CausalShared> {
        sm.check()?;
        let k = g.nrows();
        let upper = match solver {
            Solver::Bounded => 1.0,
            _ => f64::INFINITY,
        };
        let mut gl = g.clone();
        for i in 0..k {
            gl[(i, i)] += sm.lambda;
        }
        let gram_l = Gram::from_matrix(&gl, upper);
        let gram_0 = Gram::from_matrix(g, upper);
        let pinv_0 = crate::solve::lstsq::gram_pseudo_inverse(g, None);
        let chol_l = gl
            .clone()
            .cholesky()
            .ok_or_else(|| Error::unfit("temporal prior: SᵀS + λI is not positive definite"))?;
        Ok(CausalShared {
            k,
            solver,
            sm: *sm,
            gram_l,
            gram_0,
            pinv_0,
            chol_l,
        })
    }

    /// A fresh segment's state.
    pub fn start(&self) -> CausalState {
        CausalState {
            ws0: Workspace::new(self.k),
            wsl: Workspace::new(self.k),
            prev: vec![0.0; self.k],
            prev2: vec![0.0; self.k],
            frames: 0,
            iterations: 0,
            unconverged: 0,
        }
    }

    /// The next frame's weights into `w` from its `bt = Sᵀq_t`.
    pub fn step(&self, st: &mut CausalState, bt: &[f64], w: &mut [f64]) {
        let (k, sm) = (self.k, &self.sm);
        let i = st.frames;
        // The prediction from the past; the segment's first frame has none.
        let pred: Option<Vec<f64>> = match (i, sm.order) {
            (0, _) => None,
            (1, _) | (_, 1) => Some(st.prev.clone()),
            _ => Some((0..k).map(|x| 2.0 * st.prev[x] - st.prev2[x]).collect()),
        };
        let rhs: Vec<f64> = match &pred {
            None => bt.to_vec(),
            Some(p) => (0..k).map(|x| bt[x] + sm.lambda * p[x]).collect(),
        };
        let out: Vec<f64> = match (self.solver, pred.is_some()) {
            (Solver::Ls, true) => self
                .chol_l
                .solve(&nalgebra::DVector::from_vec(rhs))
                .iter()
                .copied()
                .collect(),
            (Solver::Ls, false) => (&self.pinv_0 * nalgebra::DVector::from_vec(rhs))
                .iter()
                .copied()
                .collect(),
            (_, with_prior) => {
                let (gram, ws) = if with_prior {
                    (&self.gram_l, &mut st.wsl)
                } else {
                    (&self.gram_0, &mut st.ws0)
                };
                let mut w = vec![0.0; k];
                let mut state = vec![Bound::Lower; k];
                let rep = solve_frame(gram, &rhs, &mut w, &mut state, ws);
                st.iterations += u64::from(rep.iterations);
                st.unconverged += usize::from(!rep.converged);
                w
            }
        };
        std::mem::swap(&mut st.prev, &mut st.prev2);
        st.prev.copy_from_slice(&out);
        w.copy_from_slice(&out);
        st.frames += 1;
    }
}

pub(super) fn causal(
    g: &DMatrix<f64>,
    b: &DMatrix<f64>,
    solver: Solver,
    sm: &Smoothing,
    segments: &[Range<usize>],
) -> Result<Smoothed> {
    let k = g.nrows();
    let shared = CausalShared::new(g, solver, sm)?;
    let parts: Vec<(Vec<f64>, u64, usize)> = segments
        .par_iter()
        .map(|r| {
            let mut out = vec![0.0; r.len() * k];
            let mut st = shared.start();
            for (i, col) in r.clone().enumerate() {
                let bt: Vec<f64> = b.column(col).iter().copied().collect();
                shared.step(&mut st, &bt, &mut out[i * k..(i + 1) * k]);
            }
            (out, st.iterations, st.unconverged)
        })
        .collect();
    let mut weights = DMatrix::zeros(k, b.ncols());
    let (mut iterations, mut unconverged) = (0u64, 0usize);
    for (r, (w, it, bad)) in segments.iter().zip(parts) {
        weights.columns_mut(r.start, r.len()).copy_from_slice(&w);
        iterations += it;
        unconverged += bad;
    }
    if weights.iter().any(|v| !v.is_finite()) {
        return Err(Error::unfit(
            "temporal prior: non-finite weights (a frame holds NaN or infinity)",
        ));
    }
    // Causal weights satisfy per-frame KKT conditions; report the worst of them.
    let mut gl = g.clone();
    for i in 0..k {
        gl[(i, i)] += sm.lambda;
    }
    let mut kkt = 0.0f64;
    for r in segments {
        for (i, col) in r.clone().enumerate() {
            let pred: Vec<f64> = if i == 0 {
                Vec::new()
            } else if i == 1 || sm.order == 1 {
                weights.column(col - 1).iter().copied().collect()
            } else {
                (0..k)
                    .map(|x| 2.0 * weights[(x, col - 1)] - weights[(x, col - 2)])
                    .collect()
            };
            let (gm, rhs): (&DMatrix<f64>, Vec<f64>) = if pred.is_empty() {
                (g, b.column(col).iter().copied().collect())
            } else {
                (
                    &gl,
                    (0..k).map(|x| b[(x, col)] + sm.lambda * pred[x]).collect(),
                )
            };
            let w: Vec<f64> = weights.column(col).iter().copied().collect();
            kkt = kkt.max(kkt_residual(gm, 0.0, 1, &rhs, &w, solver));
        }
    }
    Ok(Smoothed {
        weights,
        iterations,
        kkt,
        unconverged,
        segments: segments.to_vec(),
    })
}
