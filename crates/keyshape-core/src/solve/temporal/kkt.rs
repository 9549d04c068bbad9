//! The offline problem's Hessian products, objective and KKT residual.

use super::bands::difference_bands;
use crate::solve::Solver;
use nalgebra::DMatrix;
use rayon::prelude::*;

/// `H w` for one segment (`w` flat, frame after frame).
pub(super) fn hessian_times(
    g: &DMatrix<f64>,
    lambda: f64,
    bands: &[Vec<f64>],
    w: &[f64],
) -> Vec<f64> {
    let mut out = vec![0.0; w.len()];
    hessian_times_into(g, lambda, bands, w, &mut out);
    out
}

/// [`hessian_times`] into `out` (as long as `w`; every entry is written).
pub(super) fn hessian_times_into(
    g: &DMatrix<f64>,
    lambda: f64,
    bands: &[Vec<f64>],
    w: &[f64],
    out: &mut [f64],
) {
    let k = g.nrows();
    let t = bands[0].len();
    let p = bands.len() - 1;
    if k == 0 {
        return;
    }
    // Row-wise, in chunks of frames run in parallel: frame s's entries are
    // G·w_s + Σ_{|j| ≤ p} λ·DᵀD[s, s + j]·w_{s+j}; G·W of a chunk as one matrix product
    // (`w` is W, k × t, column-major: frame after frame).
    const CHUNK: usize = 2048;
    out.par_chunks_mut(CHUNK * k)
        .enumerate()
        .for_each(|(ci, o)| {
            let s0 = ci * CHUNK;
            let n = o.len() / k;
            let wv = nalgebra::DMatrixView::from_slice(&w[s0 * k..(s0 + n) * k], k, n);
            let mut ov = nalgebra::DMatrixViewMut::from_slice(o, k, n);
            g.mul_to(&wv, &mut ov);
            for s in s0..s0 + n {
                let row = &mut o[(s - s0) * k..(s - s0 + 1) * k];
                let mut add = |c: f64, f: usize| {
                    if c != 0.0 {
                        for (v, x) in row.iter_mut().zip(&w[f * k..(f + 1) * k]) {
                            *v += c * x;
                        }
                    }
                };
                add(lambda * bands[0][s], s);
                for j in 1..=p {
                    if j <= s {
                        add(lambda * bands[j][s], s - j);
                    }
                    if s + j < t {
                        add(lambda * bands[j][s + j], s + j);
                    }
                }
            }
        });
}

/// `vᵀ H v` for one segment, with `v`'s entries given by `v(i)` (flat index, frame after
/// frame) and never stored: a chunk of frames at a time, in parallel, the chunks' sums
/// added in order (the same figure on any number of threads).
pub(super) fn hessian_quadratic(
    g: &DMatrix<f64>,
    lambda: f64,
    bands: &[Vec<f64>],
    v: impl Fn(usize) -> f64 + Sync,
) -> f64 {
    let k = g.nrows();
    let t = bands[0].len();
    let p = bands.len() - 1;
    if k == 0 {
        return 0.0;
    }
    const CHUNK: usize = 2048;
    let parts: Vec<f64> = (0..t.div_ceil(CHUNK))
        .into_par_iter()
        .map(|ci| {
            let s0 = ci * CHUNK;
            let s1 = (s0 + CHUNK).min(t);
            // The chunk's frames and the `p` before them.
            let f0 = s0.saturating_sub(p);
            let vals: Vec<f64> = (f0 * k..s1 * k).map(&v).collect();
            let at = |s: usize| &vals[(s - f0) * k..(s - f0 + 1) * k];
            let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
            let mut gv = vec![0.0; k];
            let mut acc = 0.0;
            for s in s0..s1 {
                let vs = at(s);
                for (i, o) in gv.iter_mut().enumerate() {
                    *o = (0..k).map(|j| g[(i, j)] * vs[j]).sum();
                }
                let mut band = bands[0][s] * dot(vs, vs);
                for j in 1..=p.min(s) {
                    band += 2.0 * bands[j][s] * dot(vs, at(s - j));
                }
                acc += dot(vs, &gv) + lambda * band;
            }
            acc
        })
        .collect();
    parts.iter().sum()
}

/// The KKT residual of the offline objective (halved: `½wᵀHw − bᵀw`) at `w` for one
/// segment, relative: the largest violation — |gradient| of a variable inside its bounds,
/// the wrong-signed gradient of one at a bound, or the distance outside the bounds — over
/// `max|b| + max(diag H)·max|w|` (1 when both are 0).
pub fn kkt_residual(
    g: &DMatrix<f64>,
    lambda: f64,
    order: usize,
    b: &[f64],
    w: &[f64],
    solver: Solver,
) -> f64 {
    let k = g.nrows();
    let t = b.len() / k.max(1);
    let bands = difference_bands(order, t);
    let mut hw = vec![0.0; w.len()];
    kkt_with(g, lambda, order, &bands, b, w, solver, &mut hw)
}

/// [`kkt_residual`] with the segment's bands at hand and `hw` as scratch (as long as `w`).
#[allow(clippy::too_many_arguments)]
pub(super) fn kkt_with(
    g: &DMatrix<f64>,
    lambda: f64,
    order: usize,
    bands: &[Vec<f64>],
    b: &[f64],
    w: &[f64],
    solver: Solver,
    hw: &mut [f64],
) -> f64 {
    if g.nrows() == 0 {
        hw.fill(0.0);
    }
    hessian_times_into(g, lambda, bands, w, hw);
    kkt_from(g, lambda, order, b, w, hw, solver)
}

/// [`kkt_residual`] with `H w` at hand.
pub(super) fn kkt_from(
    g: &DMatrix<f64>,
    lambda: f64,
    order: usize,
    b: &[f64],
    w: &[f64],
    hw: &[f64],
    solver: Solver,
) -> f64 {
    let k = g.nrows();
    let upper = if solver == Solver::Bounded {
        1.0
    } else {
        f64::INFINITY
    };
    let wmax = w.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let hmax = (0..k).map(|i| g[(i, i)]).fold(0.0f64, f64::max)
        + lambda * if order == 1 { 4.0 } else { 16.0 };
    let bmax = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let scale = bmax + hmax * wmax;
    let scale = if scale > 0.0 { scale } else { 1.0 };
    let tight = 1e-12 * wmax.max(1.0);
    let mut worst = 0.0f64;
    for i in 0..w.len() {
        let gi = hw[i] - b[i];
        let v = match solver {
            Solver::Ls => gi.abs(),
            _ => {
                if w[i] < 0.0 || w[i] > upper {
                    (-w[i]).max(w[i] - upper) * hmax
                } else if w[i] <= tight {
                    (-gi).max(0.0)
                } else if upper.is_finite() && w[i] >= upper - tight {
                    gi.max(0.0)
                } else {
                    gi.abs()
                }
            }
        };
        worst = worst.max(v);
    }
    worst / scale
}
