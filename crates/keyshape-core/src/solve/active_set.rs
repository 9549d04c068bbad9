//! Lawson–Hanson active-set least squares with bounds `0 ≤ w ≤ u`, worked from the Gram
//! matrix `G = SᵀS` and `b = Sᵀq` (Bro & De Jong's "fast NNLS"), so a batch of frames that
//! share the key shapes S pays for S once. With `u = ∞` this is NNLS, paper 000 Eq. (4)
//! (Lawson & Hanson 1974, ch. 23); with `u = 1` it is the bounded-variable variant
//! (Stark & Parker's BVLS) that morph-target rigs want.
//!
//! Optimality (KKT) with `g = b − G w = Sᵀ(q − S w)`: `g_i ≤ tol` where `w_i = 0`,
//! `g_i ≥ −tol` where `w_i = u`, `|g_i| ≤ tol` where `0 < w_i < u`.

use super::chol::solve_spd;

/// Where a variable sits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Bound {
    /// At 0.
    Lower,
    /// Strictly between the bounds (the "passive" set).
    Free,
    /// At the upper bound.
    Upper,
}

/// The shared part of a batch: `G = SᵀS` row-major and the column norms of S.
#[derive(Debug, Clone)]
pub struct Gram {
    /// k.
    pub k: usize,
    /// `SᵀS`, row-major.
    pub g: Vec<f64>,
    /// Column norms of S.
    pub norms: Vec<f64>,
    /// Largest column norm of S.
    pub max_norm: f64,
    /// Upper bound on every weight (`f64::INFINITY` for NNLS).
    pub upper: f64,
}

impl Gram {
    /// Builds the Gram form for key shapes `s` (one per column) and an upper bound.
    pub fn new(s: &nalgebra::DMatrix<f64>, upper: f64) -> Gram {
        Gram::from_matrix(&s.tr_mul(s), upper)
    }

    /// The Gram form from `G = SᵀS` itself (k × k, symmetric).
    pub fn from_matrix(gm: &nalgebra::DMatrix<f64>, upper: f64) -> Gram {
        let k = gm.ncols();
        // Symmetric: the column-major storage is the row-major matrix.
        Gram::from_row_major(k, gm.as_slice().to_vec(), upper)
    }

    /// The Gram form from a symmetric `k × k` matrix stored row-major (or column-major: the
    /// same for a symmetric matrix).
    pub fn from_row_major(k: usize, g: Vec<f64>, upper: f64) -> Gram {
        let norms: Vec<f64> = (0..k).map(|i| g[i * k + i].sqrt()).collect();
        let max_norm = norms.iter().copied().fold(0.0, f64::max);
        Gram {
            k,
            g,
            norms,
            max_norm,
            upper,
        }
    }

    /// The stopping tolerance on the gradient `g = Sᵀ(q − Sw)` for a frame with `b = Sᵀq`:
    /// `1000 · ε · k · max‖Sᵢ‖ · max(‖q‖, max‖Sᵢ‖)`, where ‖q‖ is estimated from below by
    /// `maxᵢ |bᵢ| / ‖Sᵢ‖` (exact when q is a multiple of a key shape), so no pass over q is
    /// needed.
    pub fn tolerance(&self, b: &[f64]) -> f64 {
        let qnorm = b
            .iter()
            .zip(&self.norms)
            .filter(|(_, n)| **n > 0.0)
            .map(|(bi, n)| bi.abs() / n)
            .fold(0.0, f64::max);
        1e3 * f64::EPSILON * self.k.max(1) as f64 * self.max_norm * qnorm.max(self.max_norm)
    }
}

/// Scratch space reused across frames, including the Cholesky factor of `G_FF` for the
/// current free set. The factor follows the order in which variables became free, so a
/// variable added extends it by one row (O(p²)), a variable removed keeps the rows before
/// it, and a frame whose free set equals the previous frame's reuses it whole.
#[derive(Debug, Clone)]
pub struct Workspace {
    /// Fallback dense system for the ridge path.
    a: Vec<f64>,
    /// Lower Cholesky factor, row-major with stride k, rows in `free` order.
    l: Vec<f64>,
    /// Leading rows of `l` that are up to date.
    valid: usize,
    z: Vec<f64>,
    grad: Vec<f64>,
    /// Free variables in factor order.
    free: Vec<usize>,
    in_free: Vec<bool>,
    /// Nonzero weights (gradient scratch).
    nz: Vec<usize>,
    excluded: Vec<bool>,
    /// Outer iterations a frame may take before it is reported unconverged.
    cap: u32,
}

impl Workspace {
    /// Scratch for k key shapes, with the default iteration cap `3k + 20`.
    pub fn new(k: usize) -> Workspace {
        Workspace {
            a: vec![0.0; k * k],
            l: vec![0.0; k * k],
            valid: 0,
            z: vec![0.0; k],
            grad: vec![0.0; k],
            free: Vec::with_capacity(k),
            in_free: vec![false; k],
            nz: Vec::with_capacity(k),
            excluded: vec![false; k],
            cap: 3 * k as u32 + 20,
        }
    }

    /// Sets the outer-iteration cap per frame (the default is `3k + 20`, which no problem
    /// met so far reaches): a frame stopped by it keeps feasible weights and reports
    /// `converged: false`.
    pub(crate) fn with_cap(mut self, cap: u32) -> Workspace {
        self.cap = cap;
        self
    }
}

impl Workspace {
    /// Forgets the cached factorisation of the free set: call it before solving with a Gram
    /// matrix other than the previous call's (the cache assumes one Gram for a whole batch).
    pub fn forget_factor(&mut self) {
        self.valid = 0;
    }
}

/// What one frame's solve did.
#[derive(Debug, Clone, Copy, Default)]
pub struct FrameReport {
    /// Outer iterations (variables freed).
    pub iterations: u32,
    /// False when the iteration cap stopped it (w is still feasible).
    pub converged: bool,
}

/// Solves one frame. `w` and `state` carry a feasible warm start in (e.g. the previous
/// frame's answer, or zeros / all-Lower) and the solution out.
pub fn solve_frame(
    gram: &Gram,
    b: &[f64],
    w: &mut [f64],
    state: &mut [Bound],
    ws: &mut Workspace,
) -> FrameReport {
    let k = gram.k;
    let tol = gram.tolerance(b);
    ws.excluded.iter_mut().for_each(|e| *e = false);
    if state.iter().any(|s| *s != Bound::Lower) {
        inner(gram, b, w, state, ws, None);
    }
    let cap = ws.cap;
    let mut report = FrameReport::default();
    loop {
        gradient(gram, b, w, state, ws);
        let mut pick = None;
        let mut best = tol;
        for i in 0..k {
            let v = match state[i] {
                Bound::Lower => ws.grad[i],
                Bound::Upper => -ws.grad[i],
                Bound::Free => continue,
            };
            if v > best && !ws.excluded[i] {
                best = v;
                pick = Some(i);
            }
        }
        let Some(j) = pick else {
            report.converged = true;
            return report;
        };
        // Optimality first: a frame that is optimal after exactly `cap` steps converged.
        if report.iterations >= cap {
            return report;
        }
        report.iterations += 1;
        let from = state[j];
        state[j] = Bound::Free;
        if inner(gram, b, w, state, ws, Some(j)) {
            ws.excluded.iter_mut().for_each(|e| *e = false);
        } else {
            // Rounding made the freed variable step the wrong way: put it back and leave
            // it out of the next pick (Lawson & Hanson's safeguard).
            state[j] = from;
            ws.excluded[j] = true;
        }
    }
}

/// `grad_i = b_i − (G w)_i` for the variables at a bound (the only ones the pick reads),
/// summing over the nonzero weights only: O((k − p) · nnz) instead of O(k²).
fn gradient(gram: &Gram, b: &[f64], w: &[f64], state: &[Bound], ws: &mut Workspace) {
    let k = gram.k;
    ws.nz.clear();
    ws.nz.extend((0..k).filter(|&j| w[j] != 0.0));
    for i in 0..k {
        if state[i] == Bound::Free {
            continue;
        }
        let row = &gram.g[i * k..(i + 1) * k];
        let mut v = b[i];
        for &j in &ws.nz {
            v -= row[j] * w[j];
        }
        ws.grad[i] = v;
    }
}

/// The LH inner loop: solve on the free set, step back to the boundary while the solution
/// leaves the box. Returns false if `added`'s first solve already pointed out of the box.
fn inner(
    gram: &Gram,
    b: &[f64],
    w: &mut [f64],
    state: &mut [Bound],
    ws: &mut Workspace,
    added: Option<usize>,
) -> bool {
    let (k, u) = (gram.k, gram.upper);
    for round in 0..=k + 1 {
        sync_free(state, ws);
        let p = ws.free.len();
        if p == 0 {
            return true;
        }
        sub_solve(gram, b, state, ws);
        let z = &ws.z[..p];
        if round == 0 {
            if let Some(j) = added {
                let pos = ws.free.iter().position(|&i| i == j).unwrap_or(0);
                let wrong = if w[j] <= 0.0 {
                    z[pos] <= w[j]
                } else {
                    z[pos] >= w[j]
                };
                if wrong {
                    return false;
                }
            }
        }
        if z.iter().all(|&v| v > 0.0 && v < u) {
            for (&i, &v) in ws.free.iter().zip(z) {
                w[i] = v;
            }
            return true;
        }
        // Largest step from w towards z that stays in the box.
        // `hit` is the variable whose bound stops the step; it goes to that bound exactly.
        let (mut alpha, mut hit) = (f64::INFINITY, usize::MAX);
        for (&i, &v) in ws.free.iter().zip(z) {
            let a = if v <= 0.0 {
                w[i] / (w[i] - v)
            } else if v >= u {
                (u - w[i]) / (v - w[i])
            } else {
                continue;
            };
            if a < alpha {
                alpha = a;
                hit = i;
            }
        }
        let alpha = alpha.clamp(0.0, 1.0);
        for (idx, &i) in ws.free.iter().enumerate() {
            w[i] += alpha * (ws.z[idx] - w[i]);
            if i == hit || w[i] <= 0.0 {
                w[i] = if i == hit && ws.z[idx] >= u { u } else { 0.0 };
                state[i] = if w[i] == u {
                    Bound::Upper
                } else {
                    Bound::Lower
                };
            } else if w[i] >= u {
                w[i] = u;
                state[i] = Bound::Upper;
            }
        }
    }
    true
}

/// Brings `ws.free` in line with `state`: survivors keep their order, newly free variables
/// are appended; factor rows from the first dropped variable on become stale.
fn sync_free(state: &[Bound], ws: &mut Workspace) {
    let mut kept = 0;
    let mut valid = ws.valid.min(ws.free.len());
    for r in 0..ws.free.len() {
        let i = ws.free[r];
        if state[i] == Bound::Free {
            ws.free[kept] = i;
            kept += 1;
        } else {
            ws.in_free[i] = false;
            valid = valid.min(r);
        }
    }
    ws.free.truncate(kept);
    for i in 0..state.len() {
        if state[i] == Bound::Free && !ws.in_free[i] {
            ws.in_free[i] = true;
            ws.free.push(i);
        }
    }
    ws.valid = valid;
}

/// Extends the Cholesky factor of `G_FF` over the stale rows. False when a new column is
/// (to working precision) in the span of the ones before it.
fn factor(gram: &Gram, ws: &mut Workspace) -> bool {
    let (k, p) = (gram.k, ws.free.len());
    for r in ws.valid..p {
        let i = ws.free[r];
        for c in 0..r {
            let j = ws.free[c];
            let mut v = gram.g[i * k + j];
            for m in 0..c {
                v -= ws.l[r * k + m] * ws.l[c * k + m];
            }
            ws.l[r * k + c] = v / ws.l[c * k + c];
        }
        let gii = gram.g[i * k + i];
        let mut d = gii;
        for m in 0..r {
            d -= ws.l[r * k + m] * ws.l[r * k + m];
        }
        if d.is_nan() || d <= f64::EPSILON * (p as f64) * gii {
            ws.valid = r;
            return false;
        }
        ws.l[r * k + r] = d.sqrt();
    }
    ws.valid = p;
    true
}

/// Solves `G_FF z = b_F − G_FU u` into `ws.z[..p]` (in `ws.free` order) from the cached
/// factor. A singular `G_FF` (duplicate key shapes both free) falls back to a dense solve
/// with a tiny ridge, 1e-12, 1e-8, then 1e-4 of its largest diagonal.
fn sub_solve(gram: &Gram, b: &[f64], state: &[Bound], ws: &mut Workspace) {
    let (k, p) = (gram.k, ws.free.len());
    let g = &gram.g;
    for (r, &i) in ws.free.iter().enumerate() {
        let mut v = b[i];
        if gram.upper.is_finite() {
            for j in 0..k {
                if state[j] == Bound::Upper {
                    v -= g[i * k + j] * gram.upper;
                }
            }
        }
        ws.z[r] = v;
    }
    if factor(gram, ws) {
        super::chol::solve_factored(&ws.l, k, p, &mut ws.z);
        return;
    }
    let rhs: Vec<f64> = ws.z[..p].to_vec();
    for ridge in [1e-12, 1e-8, 1e-4] {
        let mut dmax = 0.0f64;
        for (r, &i) in ws.free.iter().enumerate() {
            for (c, &j) in ws.free.iter().enumerate() {
                ws.a[r * p + c] = g[i * k + j];
            }
            dmax = dmax.max(g[i * k + i]);
        }
        for r in 0..p {
            ws.a[r * p + r] += ridge * dmax.max(f64::MIN_POSITIVE);
        }
        ws.z[..p].copy_from_slice(&rhs);
        if solve_spd(&mut ws.a[..p * p], p, &mut ws.z[..p]) {
            return;
        }
    }
    ws.z[..p].iter_mut().for_each(|v| *v = 0.0);
}
