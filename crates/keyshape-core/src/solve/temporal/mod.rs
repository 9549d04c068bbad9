//! A temporal prior inside the solver: weights that are smooth in time without a filter's
//! lag.
//!
//! **Offline** (the whole sequence at once):
//! `E(W) = Σ_t ‖S w_t − q_t‖² + λ Σ_t ‖(D w)_t‖²`, with `D` the first difference
//! (`w_t − w_{t−1}`, order 1) or the second difference (`w_{t+1} − 2w_t + w_{t−1}`, order 2),
//! under the solver's constraints (`ls`: none, `nnls`: w ≥ 0, `bounded`: 0 ≤ w ≤ 1). Its
//! Hessian `H = I ⊗ SᵀS + λ DᵀD ⊗ I` is block-banded (block bandwidth = order), so one
//! solve is a block-banded Cholesky factorisation, linear in frames
//! ([`BandedSystem`]). `ls` needs one solve. The constrained problems use a primal–dual
//! active set method (Hintermüller, Ito & Kunisch 2003): starting from the per-frame
//! solution's active set, each iteration fixes the variables the current multipliers say
//! are at a bound, solves for the others with the banded factorisation, and updates the
//! sets; it stops when the sets no longer change (then the KKT conditions hold exactly up to
//! rounding), and [`kkt_residual`] reports how well they hold.
//!
//! **Causal** (one frame at a time, for live use): `w_t = argmin ‖S w − q_t‖² + λ ‖w − p_t‖²`
//! under the same constraints, with the prediction `p_t = w_{t−1}` (order 1) or
//! `2w_{t−1} − w_{t−2}` (order 2): Gram `SᵀS + λI`, right side `Sᵀq_t + λ p_t`.
//!
//! Segments (clips, or runs of frames split by failed frames) are independent: no
//! smoothing across their boundaries. λ has the units of the squared coordinates (px² for
//! pixel tracks) per unit of weight change.

use crate::error::{Error, Result};
use nalgebra::DMatrix;
use std::ops::Range;

/// Offline (whole sequence) or causal (frame by frame).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SmoothMode {
    /// The whole sequence at once.
    Offline,
    /// Each frame from the past only.
    Causal,
}

impl std::str::FromStr for SmoothMode {
    type Err = crate::error::Error;

    /// The option's spelling on the command line and in experiment files.
    fn from_str(s: &str) -> crate::error::Result<SmoothMode> {
        match s {
            "offline" => Ok(SmoothMode::Offline),
            "causal" => Ok(SmoothMode::Causal),
            _ => Err(crate::error::Error::bad_setting(
                "smooth_mode",
                s,
                format!("'{s}': choose offline or causal"),
            )),
        }
    }
}

impl SmoothMode {
    /// `offline` or `causal`.
    pub fn name(self) -> &'static str {
        match self {
            SmoothMode::Offline => "offline",
            SmoothMode::Causal => "causal",
        }
    }
}

/// The temporal prior.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Smoothing {
    /// Weight of the prior, ≥ 0 (0 = the unsmoothed solve).
    pub lambda: f64,
    /// 1 (first difference: motion) or 2 (second difference: acceleration).
    pub order: usize,
    /// Offline or causal.
    pub mode: SmoothMode,
}

impl Smoothing {
    /// Checks λ (finite, ≥ 0) and the order (1 or 2).
    pub fn check(&self) -> Result<()> {
        if !(self.lambda.is_finite() && self.lambda >= 0.0) {
            return Err(Error::bad_setting(
                "smooth_lambda",
                self.lambda,
                format!(
                    "smoothing λ must be a finite number ≥ 0, got {}",
                    self.lambda
                ),
            ));
        }
        if self.order != 1 && self.order != 2 {
            return Err(Error::bad_setting(
                "smooth_order",
                self.order,
                format!(
                    "smoothing order must be 1 (first difference) or 2 (second difference), got {}",
                    self.order
                ),
            ));
        }
        Ok(())
    }

    /// The objective in words, for reports.
    pub fn objective(&self) -> String {
        let prior = match (self.mode, self.order) {
            (SmoothMode::Offline, 1) => "Σ_t ‖w_t − w_{t−1}‖²",
            (SmoothMode::Offline, _) => "Σ_t ‖w_{t+1} − 2w_t + w_{t−1}‖²",
            (SmoothMode::Causal, 1) => "‖w_t − w_{t−1}‖² per frame",
            (SmoothMode::Causal, _) => "‖w_t − (2w_{t−1} − w_{t−2})‖² per frame",
        };
        format!("Σ_t ‖S w_t − q_t‖² + λ {prior}, segments independent")
    }
}

/// What a smoothed solve produced.
#[derive(Debug, Clone)]
pub struct Smoothed {
    /// k × frames.
    pub weights: DMatrix<f64>,
    /// Offline: active-set iterations summed over segments (1 per segment for `ls`);
    /// causal: active-set iterations summed over frames.
    pub iterations: u64,
    /// The KKT residual of the objective, relative (see [`kkt_residual`]).
    pub kkt: f64,
    /// Offline: segments that did not reach [`KKT_TOLERANCE`]; causal: frames that hit the
    /// active-set iteration cap (the KKT residual says how far off either is).
    pub unconverged: usize,
    /// The segments solved (frame column ranges).
    pub segments: Vec<Range<usize>>,
}

/// Segments of a track: a new one starts where the segment label changes (clips) or where
/// the frame number jumps by more than the track's usual step (failed frames removed).
pub fn segments(frames: &[i64], labels: Option<&[String]>) -> Vec<Range<usize>> {
    if frames.is_empty() {
        return Vec::new();
    }
    let step = frames
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0)
        .min()
        .unwrap_or(1);
    let mut out = Vec::new();
    let mut start = 0;
    for t in 1..frames.len() {
        let label_change = labels.is_some_and(|l| l[t] != l[t - 1]);
        if label_change || frames[t] - frames[t - 1] != step {
            out.push(start..t);
            start = t;
        }
    }
    out.push(start..frames.len());
    out
}

mod banded;
mod bands;
mod causal;
mod kkt;
mod offline;
mod split;
mod window;

pub use banded::{BandedSystem, WINDOW_BLOCK, WINDOW_FRAMES};
pub use bands::difference_bands;
pub use causal::{CausalShared, CausalState};
pub use kkt::kkt_residual;
pub use offline::{smooth_from, solve_smooth, KKT_TOLERANCE};
pub use split::{SegmentSystem, Split, SPLIT_FRAMES};

#[cfg(test)]
mod tests {
    use super::kkt::{hessian_quadratic, hessian_times};
    use super::offline::{
        offline, projected_newton, segment, Caps, NEWTON_ITERATIONS, PDAS_ITERATIONS,
    };
    use super::*;
    use crate::solve::Solver;

    /// Projected Newton reaches the KKT conditions by itself (the offline path lets the
    /// active-set steps finish from its point, which would hide a projected Newton that
    /// stalls), on an order-2 NNLS and a bounded problem with many weights at their bounds.
    #[test]
    fn projected_newton_alone_reaches_the_kkt_conditions() {
        let k = 3;
        let s = DMatrix::from_fn(8, k, |i, j| {
            ((i * 5 + j * 3) % 7) as f64 / 3.0 + (i == j) as u8 as f64
        });
        let g = s.tr_mul(&s);
        for (solver, upper) in [(Solver::Nnls, f64::INFINITY), (Solver::Bounded, 1.0)] {
            for lambda in [10.0, 1e4] {
                let t = 300;
                let bands = difference_bands(2, t);
                // Targets that swing through zero and past one: bounds bind on long runs.
                let q = DMatrix::from_fn(8, t, |i, f| {
                    let x = f as f64 / 20.0;
                    (x + i as f64).sin() * 3.0 + 0.4 * ((f * 7 + i) % 5) as f64 - 0.8
                });
                let b: Vec<f64> = s.tr_mul(&q).as_slice().to_vec();
                let w0 = vec![0.5; t * k];
                let sm = Smoothing {
                    lambda,
                    order: 2,
                    mode: SmoothMode::Offline,
                };
                let gmax = (0..k).map(|i| g[(i, i)]).fold(0.0f64, f64::max);
                let ridge = 1e-12 * (gmax + lambda * 16.0);
                let spare = std::cell::RefCell::new(None);
                let (w, it) = projected_newton(
                    &g,
                    &sm,
                    &bands,
                    &b,
                    &w0,
                    upper,
                    ridge,
                    solver,
                    &spare,
                    NEWTON_ITERATIONS,
                )
                .unwrap();
                let res = kkt_residual(&g, lambda, 2, &b, &w, solver);
                assert!(
                    res < KKT_TOLERANCE && it < NEWTON_ITERATIONS as u64,
                    "{solver:?} λ {lambda}: KKT residual {res:e} after {it} iterations"
                );
                let at_bounds = w.iter().filter(|&&v| v == 0.0 || v == upper).count();
                assert!(
                    at_bounds > t / 10,
                    "{solver:?} λ {lambda}: only {at_bounds} at bounds"
                );
            }
        }
    }

    /// Projected Newton counts the steps it took: with the optimum strictly inside the box
    /// no variable binds, so one Newton step lands on it (1 step), and a start on it takes
    /// none (0), for both orders and both constrained solvers.
    #[test]
    fn projected_newton_counts_one_step_to_an_interior_optimum() {
        let k = 2;
        let g = DMatrix::from_row_slice(2, 2, &[3.0, 0.5, 0.5, 2.0]);
        for order in [1, 2] {
            for (solver, upper) in [(Solver::Nnls, f64::INFINITY), (Solver::Bounded, 1.0)] {
                let t = 40;
                let bands = difference_bands(order, t);
                let lambda = 5.0;
                let truth: Vec<f64> = (0..t * k)
                    .map(|i| 0.5 + 0.3 * ((i as f64) * 0.7).sin())
                    .collect();
                let b = hessian_times(&g, lambda, &bands, &truth);
                let sm = Smoothing {
                    lambda,
                    order,
                    mode: SmoothMode::Offline,
                };
                let spare = std::cell::RefCell::new(None);
                let run = |w0: &[f64]| {
                    projected_newton(
                        &g,
                        &sm,
                        &bands,
                        &b,
                        w0,
                        upper,
                        0.0,
                        solver,
                        &spare,
                        NEWTON_ITERATIONS,
                    )
                    .unwrap()
                };
                let (w, it) = run(&vec![0.5; t * k]);
                let err = w
                    .iter()
                    .zip(&truth)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max);
                assert!(err < 1e-9, "order {order} {solver:?}: off by {err}");
                assert_eq!(it, 1, "order {order} {solver:?}");
                let (_, it) = run(&truth);
                assert_eq!(it, 0, "order {order} {solver:?}: from the optimum");
            }
        }
    }

    /// A problem on which bounds bind over long runs (order 2, λ = 10⁴): the targets swing
    /// through zero and past one. Returns (G, b = Sᵀq, frames).
    fn binding_problem(t: usize) -> (DMatrix<f64>, Vec<f64>) {
        let k = 3;
        let s = DMatrix::from_fn(8, k, |i, j| {
            ((i * 5 + j * 3) % 7) as f64 / 3.0 + (i == j) as u8 as f64
        });
        let q = DMatrix::from_fn(8, t, |i, f| {
            let x = f as f64 / 20.0;
            (x + i as f64).sin() * 3.0 + 0.4 * ((f * 7 + i) % 5) as f64 - 0.8
        });
        (s.tr_mul(&s), s.tr_mul(&q).as_slice().to_vec())
    }

    /// Projected Newton alone on a segment, with the ridge and bound `segment` uses.
    fn newton_alone(
        g: &DMatrix<f64>,
        b: &[f64],
        w0: &[f64],
        solver: Solver,
        sm: &Smoothing,
        cap: usize,
    ) -> (Vec<f64>, u64) {
        let k = g.nrows();
        let bands = difference_bands(sm.order, b.len() / k);
        let gmax = (0..k).map(|i| g[(i, i)]).fold(0.0f64, f64::max);
        let ridge = 1e-12 * (gmax + sm.lambda * if sm.order == 1 { 4.0 } else { 16.0 });
        let upper = if solver == Solver::Bounded {
            1.0
        } else {
            f64::INFINITY
        };
        let spare = std::cell::RefCell::new(None);
        projected_newton(g, sm, &bands, b, w0, upper, ridge, solver, &spare, cap).unwrap()
    }

    /// The hand-worked segment: one key shape (`G = 1`), λ = 0.5, order 1, so that two
    /// frames give `H = [[1.5, −0.5], [−0.5, 1.5]]`.
    fn two_frames_by_hand() -> (DMatrix<f64>, Smoothing) {
        let sm = Smoothing {
            lambda: 0.5,
            order: 1,
            mode: SmoothMode::Offline,
        };
        (DMatrix::from_element(1, 1, 1.0), sm)
    }

    /// Projected Newton's binding set, worked by hand on one key shape, two frames, λ = 0.5,
    /// order 1 (`H = [[1.5, −0.5], [−0.5, 1.5]]`): from a start on the optimal face, a
    /// variable at a bound whose gradient pushes outwards binds, the other takes the Newton
    /// step with it held, and the optimum is reached in exactly one step. Freeing the
    /// binding variable instead sends the full Newton step out of the box, and its
    /// projection is not the optimum (bounded: (1, 0.9); NNLS: no move at all).
    #[test]
    fn projected_newton_holds_a_variable_pushed_out_of_the_box_and_lands_in_one_step() {
        let (g, sm) = two_frames_by_hand();
        // (solver, b, start, optimum). Bounded, b = (3, 0.2) from (1, 0): g = (−1.5, −0.7),
        // frame 1 binds at 1, 1.5·w₂ = 0.2 + 0.5. Its mirror, b = (0.2, 3) from (0, 1).
        // NNLS, b = (1, −1) from (0.5, 0): g = (−0.25, 0.75), frame 2 binds at 0,
        // 1.5·w₁ = 1.
        let cases = [
            (Solver::Bounded, [3.0, 0.2], [1.0, 0.0], [1.0, 0.7 / 1.5]),
            (Solver::Bounded, [0.2, 3.0], [0.0, 1.0], [0.7 / 1.5, 1.0]),
            (Solver::Nnls, [1.0, -1.0], [0.5, 0.0], [2.0 / 3.0, 0.0]),
        ];
        for (solver, b, w0, want) in cases {
            let (w, it) = newton_alone(&g, &b, &w0, solver, &sm, NEWTON_ITERATIONS);
            let off = (0..2).map(|t| (w[t] - want[t]).abs()).fold(0.0, f64::max);
            // 1e-11: the ridge, 1e-12·(G + 4λ), shifts a free weight by ~1e-12.
            assert!(off < 1e-11, "{solver:?} b = {b:?}: w = {w:?}");
            assert_eq!(it, 1, "{solver:?} b = {b:?}");
            // The bound weight is exactly at its bound, not near it.
            let bound = if solver == Solver::Nnls { 0.0 } else { 1.0 };
            assert!(w.contains(&bound), "{solver:?} b = {b:?}: w = {w:?}");
        }
    }

    /// The offline fallback, stage by stage, with the caps cut so that each stage is the
    /// one that finishes (or none does): the active set from the per-frame start, projected
    /// Newton from the same start, the active set again from projected Newton's point. The
    /// iterations reported are the sum over the stages that ran, the point is the last
    /// stage's that improved, and "converged" is whether its KKT residual is below the
    /// tolerance. (With the default caps the active set almost always finishes first; this
    /// path is the one the second-difference prior at large λ takes.)
    #[test]
    fn the_offline_fallback_counts_every_stage_and_returns_the_finishing_point() {
        let t = 120;
        let (g, b) = binding_problem(t);
        let w0 = vec![0.5; b.len()];
        for solver in [Solver::Nnls, Solver::Bounded] {
            let sm = Smoothing {
                lambda: 1e4,
                order: 2,
                mode: SmoothMode::Offline,
            };
            let run = |active_set, newton| {
                segment(&g, &b, &w0, solver, &sm, Caps { active_set, newton }).unwrap()
            };
            // Nothing finishes: three active-set steps that change the set (from this
            // start the active set needs 23 for NNLS and cycles for bounded), no Newton
            // step (its point is the clamped start), the same three steps again from
            // there. The start is returned, unconverged, after 3 + 0 + 3 steps.
            let (w, it, res, ok) = run(3, 0);
            assert!(!ok && res >= KKT_TOLERANCE, "{solver:?}: {res:e}");
            assert_eq!(it, 3 + 3, "{solver:?}");
            assert_eq!(w, w0, "{solver:?}");
            assert_eq!(res, kkt_residual(&g, sm.lambda, 2, &b, &w0, solver));
            // Projected Newton finishes: the cut active set's 3 steps plus Newton's own.
            let (wn, itn) = newton_alone(&g, &b, &w0, solver, &sm, NEWTON_ITERATIONS);
            let rn = kkt_residual(&g, sm.lambda, 2, &b, &wn, solver);
            assert!(
                rn < KKT_TOLERANCE && itn > 2,
                "{solver:?}: {rn:e} after {itn}"
            );
            let (w, it, res, ok) = run(3, NEWTON_ITERATIONS);
            assert!(ok, "{solver:?}");
            assert_eq!(it, 3 + itn, "{solver:?}");
            assert_eq!((w, res), (wn.clone(), rn), "{solver:?}");
            // Newton stopped one step short: the active set from its point finishes within
            // its cap (one or two steps, then the same set again), and its point, the
            // better one, is returned as converged.
            let (ws, its) = newton_alone(&g, &b, &w0, solver, &sm, itn as usize - 1);
            let rs = kkt_residual(&g, sm.lambda, 2, &b, &ws, solver);
            assert!(rs >= KKT_TOLERANCE, "{solver:?}: {rs:e}");
            assert_eq!(its, itn - 1);
            let (w, it, res, ok) = run(3, itn as usize - 1);
            assert!(ok && res < KKT_TOLERANCE && res < rs, "{solver:?}: {res:e}");
            let finish = it - 3 - (itn - 1);
            assert!((1..3).contains(&finish), "{solver:?}: {it} iterations");
            assert_eq!(res, kkt_residual(&g, sm.lambda, 2, &b, &w, solver));
            let off = w
                .iter()
                .zip(&wn)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            // (The same optimum: both are within the KKT tolerance of it, on a system
            // whose condition number at λ = 10⁴ turns that into ~1e-8 in the weights.)
            assert!(off < 1e-6, "{solver:?}: {off:e} from Newton's optimum");
        }
    }

    /// `offline` sums the segments' iterations and counts the segments that did not
    /// converge: one segment whose optimum is inside the box (the active set finishes in
    /// one step from it) beside one that cannot finish under the cut caps.
    #[test]
    fn offline_counts_the_segments_that_did_not_converge() {
        let k = 3;
        let (g, b_bind) = binding_problem(60);
        let sm = Smoothing {
            lambda: 1e4,
            order: 2,
            mode: SmoothMode::Offline,
        };
        let inner = 40;
        let truth: Vec<f64> = (0..inner * k)
            .map(|i| 0.5 + 0.3 * ((i as f64) * 0.7).sin())
            .collect();
        let b_in = hessian_times(&g, sm.lambda, &difference_bands(2, inner), &truth);
        let b = DMatrix::from_iterator(k, 60 + inner, b_bind.iter().chain(&b_in).copied());
        // The inner segment starts at its optimum: one step, which the next confirms.
        let start = DMatrix::from_iterator(
            k,
            60 + inner,
            std::iter::repeat_n(0.5, 60 * k).chain(truth.iter().copied()),
        );
        let segments = [0..60, 60..60 + inner];
        for solver in [Solver::Nnls, Solver::Bounded] {
            let cut = Caps {
                active_set: 3,
                newton: 0,
            };
            let r = offline(&g, &b, &start, solver, &sm, &segments, cut).unwrap();
            assert_eq!(r.unconverged, 1, "{solver:?}");
            // The binding segment cut at 3 + 3 active-set steps (no Newton step), the inner one 1.
            assert_eq!(r.iterations, 3 + 3 + 1, "{solver:?}");
            let inside = r.weights.columns(60, inner);
            let off = inside
                .iter()
                .zip(&truth)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            // (Off by the segment's ridge, 1e-12 of 16λ on the diagonal: ~6e-9 here.)
            assert!(
                off < 1e-7,
                "{solver:?}: the inner segment is off by {off:e}"
            );
            assert!(r.kkt >= KKT_TOLERANCE);
            let r = offline(&g, &b, &start, solver, &sm, &segments, Caps::DEFAULT).unwrap();
            assert_eq!(r.unconverged, 0, "{solver:?}");
            assert!(r.kkt < KKT_TOLERANCE, "{solver:?}");
        }
    }

    /// The primal–dual active set by itself (projected Newton capped at 0 steps, so it
    /// cannot rescue a wrong active-set point), on segments worked by hand — one key shape,
    /// two frames, λ = 0.5, order 1, `H = [[1.5, −0.5], [−0.5, 1.5]]` — from starts off the
    /// optimum; and on the 120-frame NNLS problem the active set finishes by itself.
    #[test]
    fn the_active_set_alone_finishes_from_any_start() {
        let (g, sm) = two_frames_by_hand();
        let alone = Caps {
            active_set: PDAS_ITERATIONS,
            newton: 0,
        };
        // (solver, b, optimum). NNLS, b = (1, −1): frame 2 at 0, 1.5·w₁ = 1. Bounded,
        // b = (3, 0.2): frame 1 at 1, 1.5·w₂ = 0.2 + 0.5·1. Bounded, b = (3, 3): both at 1.
        // Bounded, b = (0.9, 0.3): both free, inside the box.
        let cases = [
            (Solver::Nnls, [1.0, -1.0], [2.0 / 3.0, 0.0]),
            (Solver::Bounded, [3.0, 0.2], [1.0, 0.7 / 1.5]),
            (Solver::Bounded, [3.0, 3.0], [1.0, 1.0]),
            (Solver::Bounded, [0.9, 0.3], [0.75, 0.45]),
        ];
        for (solver, b, want) in cases {
            for w0 in [[0.0, 0.0], [0.5, 0.5], [1.0, 0.0], [0.0, 1.0], [0.9, 0.1]] {
                let (w, it, res, ok) = segment(&g, &b, &w0, solver, &sm, alone).unwrap();
                let off = (0..2).map(|t| (w[t] - want[t]).abs()).fold(0.0, f64::max);
                // 1e-11: the segment's ridge, 1e-12·(G + 4λ), shifts a free weight by ~1e-12.
                assert!(
                    off < 1e-11 && ok && res < 1e-12,
                    "{solver:?} b = {b:?} from {w0:?}: w = {w:?}, KKT {res:e}"
                );
                assert!(
                    (1..=3).contains(&it),
                    "{solver:?} b = {b:?} from {w0:?}: {it} iterations"
                );
            }
        }
        let (g, b) = binding_problem(120);
        let sm = Smoothing {
            lambda: 1e4,
            order: 2,
            mode: SmoothMode::Offline,
        };
        let w0 = vec![0.5; b.len()];
        let (w, it, res, ok) = segment(&g, &b, &w0, Solver::Nnls, &sm, alone).unwrap();
        assert!(ok && res < KKT_TOLERANCE, "KKT {res:e} after {it}");
        assert!(it < PDAS_ITERATIONS as u64);
        let (wn, _) = newton_alone(&g, &b, &w0, Solver::Nnls, &sm, NEWTON_ITERATIONS);
        let off = w
            .iter()
            .zip(&wn)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(off < 1e-6, "{off:e} from Newton's optimum");
    }

    /// `vᵀHv` without `Hv`: the dense `H = I ⊗ G + λ DᵀD ⊗ I` built entry by entry is the
    /// oracle, on lengths that end inside, on and just past a chunk, for both orders.
    #[test]
    fn the_quadratic_form_is_v_h_v() {
        let k = 3;
        let g = DMatrix::from_row_slice(3, 3, &[4.0, 1.0, -0.5, 1.0, 3.0, 0.25, -0.5, 0.25, 2.0]);
        for order in [1, 2] {
            for t in [1, 2, 5, 2047, 2048, 2049, 4100] {
                let bands = difference_bands(order, t);
                let lambda = 7.5;
                let v: Vec<f64> = (0..t * k)
                    .map(|i| ((i * 37 + 11) % 23) as f64 / 7.0 - 1.5)
                    .collect();
                let got = hessian_quadratic(&g, lambda, &bands, |i| v[i]);
                let hv = hessian_times(&g, lambda, &bands, &v);
                let via_product: f64 = v.iter().zip(&hv).map(|(a, b)| a * b).sum();
                assert!(
                    (got - via_product).abs() <= 1e-12 * via_product.abs(),
                    "order {order}, {t} frames: {got} vs {via_product}"
                );
                if t <= 5 {
                    // Dense: DᵀD from the difference operator itself.
                    let rows = t.saturating_sub(order);
                    let mut dm = DMatrix::<f64>::zeros(rows, t);
                    for r in 0..rows {
                        let c: &[f64] = if order == 1 {
                            &[-1.0, 1.0]
                        } else {
                            &[1.0, -2.0, 1.0]
                        };
                        for (j, x) in c.iter().enumerate() {
                            dm[(r, r + j)] = *x;
                        }
                    }
                    let dtd = dm.transpose() * &dm;
                    let mut dense = 0.0;
                    for s in 0..t {
                        for u in 0..t {
                            for i in 0..k {
                                for j in 0..k {
                                    let h = if s == u { g[(i, j)] } else { 0.0 }
                                        + if i == j { lambda * dtd[(s, u)] } else { 0.0 };
                                    dense += v[s * k + i] * h * v[u * k + j];
                                }
                            }
                        }
                    }
                    assert!(
                        (got - dense).abs() <= 1e-12 * dense.abs().max(1.0),
                        "order {order}, {t} frames: {got} vs dense {dense}"
                    );
                }
            }
        }
    }
}
