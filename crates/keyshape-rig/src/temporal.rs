//! The rig's offline temporal prior: with each frame's head pose from the
//! per-frame solve, the weights of a whole clip minimise
//!
//! `Σ_t ‖u_t − P_t(N + D w_t)‖² + μ-terms(w_t) + λ Σ_t ‖w_t − w_{t−1}‖²`
//!
//! (with the tapered prior, each frame's ridge `μ (1 − w_t)²` from its per-frame weights,
//! held fixed)
//! under their bounds — `solve --smooth`'s offline prior (order 1) with a Gram that changes
//! from frame to frame (each frame's camera sees the shapes differently), so the banded
//! factorisation of `solve::temporal`, which shares one Gram across frames, does not apply.
//! The problem is a strictly convex QP whose Hessian is block tridiagonal; it is solved by
//! symmetric block Gauss–Seidel: sweeps forward and backward over the clip, each frame's
//! bounded QP solved exactly (the frame's own problem plus `cλ‖w − w̄‖²`, w̄ the mean of its
//! c neighbours' current weights), warm-started, until no weight moves by more than
//! [`TOLERANCE`]. Block coordinate descent on a strictly convex QP converges to its unique
//! optimum; the rate depends on λ against the data's curvature (a shape's squared image
//! motion summed over the landmarks, thousands of px² on a face 100 px wide), so the λ a
//! face track wants converges in tens of sweeps (57 at λ = 300 px² on the 10k-frame
//! benchmark track: the slow modes are the weakly seen directions, where the pull along
//! time outweighs the landmarks'; 3.2× the per-frame solve's time there). Zero phase: the past and the future pull
//! alike, no lag. The tests check the result's KKT conditions.

use super::camera::Camera;
use super::{frame_depth, frame_points, FrameSolver};
use keyshape_core::solve::active_set::Bound;
use keyshape_core::solve::Solver;
use nalgebra::DMatrix;
use std::ops::Range;

/// A sweep ends the iteration when no weight moved by more than this (1e-7 took twice the
/// sweeps of 1e-5 on the 10k-frame benchmark track for a change below 1e-4; over-relaxing
/// the updates, ω = 1.6 and 1.8, took more sweeps, not fewer).
pub const TOLERANCE: f64 = 1e-6;
/// Sweeps at most (forward and backward count one each).
pub const MAX_SWEEPS: usize = 2000;

/// Solves the offline prior on the frames `clip` (columns of `track` and `weights`), from
/// the per-frame weights in `weights`, with `fs` set up for the clip's person (free shapes,
/// magnitude prior, exclusive pairs). Returns (sweeps, converged).
pub(super) fn offline_prior(
    fs: &mut FrameSolver,
    (track, depth): (&DMatrix<f64>, Option<&DMatrix<f64>>),
    clip: Range<usize>,
    (cameras, tzs): (&[Camera], &[f64]),
    weights: &mut DMatrix<f64>,
    lambda: f64,
) -> (usize, bool) {
    let len = clip.len();
    if len < 2 || lambda <= 0.0 || fs.free.is_empty() {
        return (0, true);
    }
    let m = fs.free.len();
    // The free shapes' weights, frame after frame (m per frame).
    let mut w = vec![0.0; m * len];
    for (t, f) in clip.clone().enumerate() {
        for (j, &s) in fs.free.iter().enumerate() {
            w[t * m + j] = weights[(s, f)];
        }
    }
    let upper = if fs.solver == Solver::Bounded {
        1.0
    } else {
        f64::INFINITY
    };
    // Each frame's magnitude prior: with the taper, the ridge the per-frame weights leave,
    // `μ (1 − w_t)²` (held fixed, so the clip's problem stays a convex QP).
    let base = fs.ridge.clone();
    let ridges: Vec<Vec<f64>> = (0..len)
        .map(|t| {
            base.iter()
                .zip(&fs.taper)
                .zip(&w[t * m..(t + 1) * m])
                .map(|((mu, &tapers), v)| {
                    if tapers {
                        mu * (1.0 - v.clamp(0.0, 1.0)).powi(2)
                    } else {
                        *mu
                    }
                })
                .collect()
        })
        .collect();
    let mut avg = vec![0.0; m];
    let mut done = (MAX_SWEEPS, false);
    for sweep in 0..MAX_SWEEPS {
        let mut moved = 0.0f64;
        for i in 0..len {
            let t = if sweep % 2 == 0 { i } else { len - 1 - i };
            let mut c = 0.0;
            avg.iter_mut().for_each(|a| *a = 0.0);
            for nb in [t.wrapping_sub(1), t + 1] {
                if nb < len {
                    c += 1.0;
                    for (a, v) in avg.iter_mut().zip(&w[nb * m..(nb + 1) * m]) {
                        *a += v;
                    }
                }
            }
            avg.iter_mut().for_each(|a| *a /= c);
            fs.lambda = c * lambda;
            fs.prev = Some(avg.clone());
            let cur = &w[t * m..(t + 1) * m];
            fs.w.copy_from_slice(cur);
            for (st, &v) in fs.state.iter_mut().zip(cur) {
                *st = if v <= 0.0 {
                    Bound::Lower
                } else if v >= upper {
                    Bound::Upper
                } else {
                    Bound::Free
                };
            }
            let f = clip.start + t;
            fs.depth = frame_depth(depth, f);
            fs.tz = tzs[f];
            fs.ridge.clone_from(&ridges[t]);
            fs.weights_for(&cameras[f], &frame_points(track, f));
            for (o, n) in w[t * m..(t + 1) * m].iter_mut().zip(&fs.w) {
                moved = moved.max((n - *o).abs());
                *o = *n;
            }
        }
        if moved <= TOLERANCE {
            done = (sweep + 1, true);
            break;
        }
    }
    fs.prev = None;
    fs.lambda = 0.0;
    fs.ridge = base;
    for (t, f) in clip.enumerate() {
        for (j, &s) in fs.free.iter().enumerate() {
            weights[(s, f)] = w[t * m + j];
        }
    }
    done
}
