//! The offline solve: per segment, the primal–dual active set, then projected Newton
//! where it cycles.

use super::bands::difference_bands;
use super::causal::causal;
use super::kkt::{hessian_quadratic, hessian_times, hessian_times_into, kkt_from, kkt_residual};
use super::split::{SegmentSystem, SPLIT_FRAMES};
use super::{SmoothMode, Smoothed, Smoothing};
use crate::error::{Error, Result};
use crate::solve::{solve_batch, SolveOptions, Solver};
use nalgebra::DMatrix;
use rayon::prelude::*;
use std::cell::RefCell;
use std::ops::Range;

/// Segments must partition the frames in order: the first starts at 0, each next one where
/// the one before ends, none empty, the last ends at `frames` (an overlap would solve a
/// frame twice and leave another at zero).
pub(super) fn check_segments(segments: &[Range<usize>], frames: usize) -> Result<()> {
    let mut end = 0;
    for r in segments {
        if r.start != end {
            return Err(Error::invalid(format!(
                "segments must cover the {frames} frames in order, one after another: \
                 {r:?} follows frame {end}"
            )));
        }
        if r.end <= r.start {
            return Err(Error::invalid(format!("segment {r:?} holds no frames")));
        }
        end = r.end;
    }
    if end != frames {
        return Err(Error::invalid(format!(
            "segments cover {end} of {frames} frames"
        )));
    }
    Ok(())
}

/// Solves with the temporal prior. `segments` split the frames (columns of `q`); λ = 0 is
/// the plain per-frame solve exactly.
pub fn solve_smooth(
    s: &DMatrix<f64>,
    q: &DMatrix<f64>,
    solver: Solver,
    smoothing: &Smoothing,
    segments: &[Range<usize>],
) -> Result<Smoothed> {
    smoothing.check()?;
    check_segments(segments, q.ncols())?;
    let plain = solve_batch(s, q, &SolveOptions::new(solver))?;
    smooth_from(s, q, &plain, solver, smoothing, segments)
}

/// [`solve_smooth`] from the plain per-frame solution already at hand (the starting point
/// of the constrained solves; returned as is for λ = 0).
pub fn smooth_from(
    s: &DMatrix<f64>,
    q: &DMatrix<f64>,
    plain: &crate::solve::Solution,
    solver: Solver,
    smoothing: &Smoothing,
    segments: &[Range<usize>],
) -> Result<Smoothed> {
    smoothing.check()?;
    check_segments(segments, q.ncols())?;
    if smoothing.lambda == 0.0 {
        return Ok(Smoothed {
            weights: plain.weights.clone(),
            iterations: plain.iterations,
            kkt: 0.0,
            unconverged: plain.unconverged,
            segments: segments.to_vec(),
        });
    }
    let g = s.tr_mul(s);
    // Sᵀ once: `st * q` runs as blocked GEMMs (in parallel chunks), `s.tr_mul(q)` as column
    // dot products.
    let b = crate::solve::chunked_product(&s.transpose(), q);
    match smoothing.mode {
        SmoothMode::Offline => offline(
            &g,
            &b,
            &plain.weights,
            solver,
            smoothing,
            segments,
            Caps::DEFAULT,
        ),
        SmoothMode::Causal => causal(&g, &b, solver, smoothing, segments),
    }
}

pub(super) fn offline(
    g: &DMatrix<f64>,
    b: &DMatrix<f64>,
    start: &DMatrix<f64>,
    solver: Solver,
    sm: &Smoothing,
    segments: &[Range<usize>],
    caps: Caps,
) -> Result<Smoothed> {
    let k = g.nrows();
    // A segment's frames are contiguous columns (column-major storage): no copies.
    pub(super) fn cols<'a>(m: &'a DMatrix<f64>, r: &Range<usize>) -> &'a [f64] {
        &m.as_slice()[r.start * m.nrows()..r.end * m.nrows()]
    }
    let parts: Vec<Result<SegmentResult>> = segments
        .par_iter()
        .map(|r| segment(g, cols(b, r), cols(start, r), solver, sm, caps))
        .collect();
    // One segment: its weights become the matrix instead of being copied into one.
    let one = segments.len() == 1;
    let mut weights = DMatrix::zeros(k, if one { 0 } else { b.ncols() });
    let (mut iterations, mut kkt, mut unconverged) = (0u64, 0.0f64, 0usize);
    for (r, part) in segments.iter().zip(parts) {
        let (w, it, res, ok) = part?;
        if one {
            weights = DMatrix::from_vec(k, b.ncols(), w);
        } else {
            weights.columns_mut(r.start, r.len()).copy_from_slice(&w);
        }
        iterations += it;
        kkt = kkt.max(res);
        unconverged += usize::from(!ok);
    }
    Ok(Smoothed {
        weights,
        iterations,
        kkt,
        unconverged,
        segments: segments.to_vec(),
    })
}

/// One segment's (weights, iterations, KKT residual, converged).
type SegmentResult = (Vec<f64>, u64, f64, bool);

/// The iteration caps of an offline segment's solve.
#[derive(Debug, Clone, Copy)]
pub(super) struct Caps {
    /// Each primal–dual active-set run.
    pub(super) active_set: usize,
    /// Projected Newton.
    pub(super) newton: usize,
}

impl Caps {
    pub(super) const DEFAULT: Caps = Caps {
        active_set: PDAS_ITERATIONS,
        newton: NEWTON_ITERATIONS,
    };
}

/// One segment offline.
pub(super) fn segment(
    g: &DMatrix<f64>,
    b: &[f64],
    w0: &[f64],
    solver: Solver,
    sm: &Smoothing,
    caps: Caps,
) -> Result<SegmentResult> {
    let seg = Segment::new(g, b, solver, sm);
    let kkt = |w: &[f64]| kkt_residual(g, sm.lambda, sm.order, b, w, solver);
    if solver == Solver::Ls {
        let w = seg.solve_with(&vec![false; b.len()], None)?;
        let res = kkt(&w);
        return Ok((w, 1, res, true));
    }
    // Primal–dual active set from the per-frame solution: a few banded solves when it
    // works (order 1 nearly always). It can cycle when the Hessian is not an M-matrix (the
    // second-difference prior at large λ); then projected Newton, which decreases the
    // objective at every step and so cannot cycle, takes over from the same start.
    let mut iterations = 0u64;
    if let Some((w, it)) = seg.pdas(w0, caps.active_set)? {
        iterations += it;
        let res = kkt(&w);
        if res < KKT_TOLERANCE {
            return Ok((w, iterations, res, true));
        }
    } else {
        iterations += caps.active_set as u64;
    }
    // Projected Newton factorises into the storage the active-set steps leave (one
    // system held at a time, not three); their last factor has no rows it could copy.
    {
        let cached = seg.cache.borrow_mut().take();
        let mut spare = seg.spare.borrow_mut();
        if spare.is_none() {
            *spare = cached;
        }
    }
    let (w, it) = projected_newton(
        g,
        sm,
        &seg.bands,
        b,
        w0,
        seg.upper,
        seg.ridge,
        solver,
        &seg.spare,
        caps.newton,
    )?;
    iterations += it;
    let res = kkt(&w);
    if res < KKT_TOLERANCE {
        return Ok((w, iterations, res, true));
    }
    // Near the optimum the active set from projected Newton is (nearly) the optimal one, and
    // one or two primal–dual steps from it finish exactly.
    if let Some((wp, it)) = seg.pdas(&w, caps.active_set)? {
        iterations += it;
        let rp = kkt(&wp);
        if rp < res {
            return Ok((wp, iterations, rp, rp < KKT_TOLERANCE));
        }
    } else {
        iterations += caps.active_set as u64;
    }
    Ok((w, iterations, res, res < KKT_TOLERANCE))
}

/// One segment's problem (Gram `g`, right-hand side `b` of its `t` frames, the prior's
/// bands) and the factorisations its solves reuse.
struct Segment<'a> {
    g: &'a DMatrix<f64>,
    b: &'a [f64],
    sm: &'a Smoothing,
    t: usize,
    bands: Vec<Vec<f64>>,
    /// The Gram's largest diagonal entry: the active-set steps' scale.
    gmax: f64,
    ridge: f64,
    /// The weights' upper bound (1 for the bounded solver, else none).
    upper: f64,
    /// The last factorisation, from which the next one copies the rows that do not change.
    cache: RefCell<Option<SegmentSystem>>,
    /// The one before it, whose storage the next one takes.
    spare: RefCell<Option<SegmentSystem>>,
}

impl<'a> Segment<'a> {
    fn new(g: &'a DMatrix<f64>, b: &'a [f64], solver: Solver, sm: &'a Smoothing) -> Self {
        let k = g.nrows();
        let t = b.len() / k;
        let gmax = (0..k).map(|i| g[(i, i)]).fold(0.0f64, f64::max);
        Segment {
            g,
            b,
            sm,
            t,
            bands: difference_bands(sm.order, t),
            gmax,
            // A ridge far below every scale that matters keeps rank-deficient S
            // factorisable (the prior leaves S's null directions constant in time
            // undetermined).
            ridge: 1e-12 * (gmax + sm.lambda * if sm.order == 1 { 4.0 } else { 16.0 }),
            upper: if solver == Solver::Bounded {
                1.0
            } else {
                f64::INFINITY
            },
            cache: RefCell::new(None),
            spare: RefCell::new(None),
        }
    }

    /// The solve with the `fixed` variables held at `values` (None: all 0, as NNLS fixes
    /// them) and the rest free.
    fn solve_with(&self, fixed: &[bool], values: Option<&[f64]>) -> Result<Vec<f64>> {
        let (g, b, sm) = (self.g, self.b, self.sm);
        let mut sys = SegmentSystem::factor_reusing(
            g,
            sm.lambda,
            &self.bands,
            fixed,
            self.ridge,
            self.t >= SPLIT_FRAMES,
            self.cache.borrow().as_ref(),
            self.spare.borrow_mut().take(),
        )?;
        // rhs = b − H·v (v: fixed values, 0 elsewhere); fixed rows take their values.
        // (With every fixed value 0, H·v = 0 and the product is skipped.)
        let values = values.filter(|v| v.iter().any(|x| *x != 0.0));
        let mut rhs: Vec<f64> = match values {
            None => b.to_vec(),
            Some(v) => {
                let hv = hessian_times(g, sm.lambda, &self.bands, v);
                b.iter().zip(&hv).map(|(x, y)| x - y).collect()
            }
        };
        for (r, f) in rhs.iter_mut().zip(fixed) {
            if *f {
                *r = 0.0;
            }
        }
        sys.solve(&mut rhs);
        if sys.is_windowed() {
            // Nothing to copy from a windowed factor: keep only its storage.
            *self.spare.borrow_mut() = Some(sys);
        } else {
            *self.spare.borrow_mut() = self.cache.borrow_mut().replace(sys);
        }
        if let Some(v) = values {
            for ((r, f), x) in rhs.iter_mut().zip(fixed).zip(v) {
                if *f {
                    *r = *x;
                }
            }
        }
        Ok(rhs)
    }

    /// Primal–dual active set from `start`, at most `cap` steps: the weights and the steps
    /// taken when the active set repeats, None when the cap is reached first.
    fn pdas(&self, start: &[f64], cap: usize) -> Result<Option<(Vec<f64>, u64)>> {
        let (g, b, sm, upper) = (self.g, self.b, self.sm, self.upper);
        let c = self.gmax.max(f64::MIN_POSITIVE);
        let mut w = start.to_vec();
        let mut prev: Option<(Vec<bool>, Vec<bool>)> = None;
        for it in 1..=cap {
            let mut grad = hessian_times(g, sm.lambda, &self.bands, &w);
            for (x, y) in grad.iter_mut().zip(b) {
                *x -= y;
            }
            let at_lower: Vec<bool> = (0..w.len()).map(|i| grad[i] - c * w[i] > 0.0).collect();
            let at_upper: Vec<bool> = (0..w.len())
                .map(|i| upper.is_finite() && !at_lower[i] && -grad[i] - c * (upper - w[i]) > 0.0)
                .collect();
            if prev
                .as_ref()
                .is_some_and(|(l, u)| *l == at_lower && *u == at_upper)
            {
                return Ok(Some((w, it as u64 - 1)));
            }
            let fixed: Vec<bool> = at_lower
                .iter()
                .zip(&at_upper)
                .map(|(l, u)| *l || *u)
                .collect();
            let values: Option<Vec<f64>> = at_upper.iter().any(|u| *u).then(|| {
                at_upper
                    .iter()
                    .map(|&u| if u { upper } else { 0.0 })
                    .collect()
            });
            // Neither the gradient nor the old point is needed by the solve.
            drop(grad);
            drop(std::mem::take(&mut w));
            w = self.solve_with(&fixed, values.as_deref())?;
            prev = Some((at_lower, at_upper));
        }
        Ok(None)
    }
}

/// The relative KKT residual ([`kkt_residual`]) at which a constrained offline solve stops.
pub const KKT_TOLERANCE: f64 = 1e-10;

/// Active-set iterations before projected Newton takes over.
pub(super) const PDAS_ITERATIONS: usize = 40;

/// Projected-Newton iterations at most.
pub(super) const NEWTON_ITERATIONS: usize = 500;

/// Projected Newton (Bertsekas 1982, *SIAM J. Control Optim.* 20(2)) on `½wᵀHw − bᵀw`
/// over the box `[0, upper]`, from `w0` clamped into the box. Each iteration takes the
/// variables that sit within ε of a bound with the gradient pushing outwards as *binding*,
/// solves the Newton system on the others with the banded factorisation (so the step is
/// exact on the current face), moves the binding ones by a diagonally scaled gradient step,
/// and projects back with an Armijo backtracking search along the projection arc. The
/// objective falls at every step, so unlike the primal–dual active set it cannot cycle; once
/// the binding set is the optimal one a full step lands on the optimum. Stops when the KKT
/// residual is below [`KKT_TOLERANCE`] or a step no longer changes `w`. Returns the point
/// and the iterations taken.
#[allow(clippy::too_many_arguments)]
pub(super) fn projected_newton(
    g: &DMatrix<f64>,
    sm: &Smoothing,
    bands: &[Vec<f64>],
    b: &[f64],
    w0: &[f64],
    upper: f64,
    ridge: f64,
    solver: Solver,
    recycle: &std::cell::RefCell<Option<SegmentSystem>>,
    cap: usize,
) -> Result<(Vec<f64>, u64)> {
    let k = g.nrows();
    let n = b.len();
    // diag H, for the scaled step of the binding variables (computed where needed: a
    // long segment holds as few frames-long vectors as it can).
    let hdiag =
        |i: usize| (g[(i % k, i % k)] + sm.lambda * bands[0][i / k] + ridge).max(f64::MIN_POSITIVE);
    let hmax = (0..n).map(hdiag).fold(0.0f64, |m, v| m.max(v));
    let project = |v: f64| v.clamp(0.0, upper);
    let mut w: Vec<f64> = w0.iter().map(|v| project(*v)).collect();
    // Three frames-long vectors (w, `hw = H w`, d) and the binding mask: `H w` is taken
    // afresh at every step (the KKT check reads it too), the gradient `hw − b` entry by
    // entry where it is used, and the line search's step Δ = project(w + αd) − w entry by
    // entry too (it needs only gᵀΔ and ΔᵀHΔ). The factor's storage is reused from step to
    // step.
    let grad = |hw: &[f64], i: usize| hw[i] - b[i];
    let mut hw = vec![0.0; n];
    let mut binding = vec![false; n];
    let mut d = vec![0.0; n];
    for it in 1..=cap {
        hessian_times_into(g, sm.lambda, bands, &w, &mut hw);
        if kkt_from(g, sm.lambda, sm.order, b, &w, &hw, solver) < KKT_TOLERANCE {
            return Ok((w, it as u64 - 1));
        }
        // ε: the size of a projected gradient step, capped (Bertsekas' ε_k).
        let step = (0..n)
            .map(|i| (w[i] - project(w[i] - grad(&hw, i) / hmax)).abs())
            .fold(0.0f64, f64::max);
        let eps = step.min(1e-3);
        for (i, v) in binding.iter_mut().enumerate() {
            let gi = grad(&hw, i);
            *v = (w[i] <= eps && gi > 0.0) || (w[i] >= upper - eps && gi < 0.0);
        }
        for i in 0..n {
            d[i] = if binding[i] { 0.0 } else { -grad(&hw, i) };
        }
        let mut sys = SegmentSystem::factor_reusing(
            g,
            sm.lambda,
            bands,
            &binding,
            ridge,
            n / k.max(1) >= SPLIT_FRAMES,
            None,
            recycle.borrow_mut().take(),
        )?;
        sys.solve(&mut d);
        *recycle.borrow_mut() = Some(sys);
        for i in 0..n {
            if binding[i] {
                d[i] = -grad(&hw, i) / hdiag(i);
            }
        }
        let Some(alpha) = armijo_along_arc(g, sm.lambda, bands, b, &w, &hw, &d, &binding, upper)
        else {
            // No decrease left at working precision.
            return Ok((w, it as u64));
        };
        let mut moved = false;
        for i in 0..n {
            let v = project(w[i] + alpha * d[i]);
            moved |= v != w[i];
            w[i] = v;
        }
        if !moved {
            return Ok((w, it as u64));
        }
    }
    Ok((w, cap as u64))
}

/// The Armijo step along the projection arc `project(w + αd)` (σ = 1e-4, halving from
/// α = 1), given `hw = H w` and the binding mask; `None` when 60 halvings find no decrease.
#[allow(clippy::too_many_arguments)]
fn armijo_along_arc(
    g: &DMatrix<f64>,
    lambda: f64,
    bands: &[Vec<f64>],
    b: &[f64],
    w: &[f64],
    hw: &[f64],
    d: &[f64],
    binding: &[bool],
    upper: f64,
) -> Option<f64> {
    let n = b.len();
    let grad = |i: usize| hw[i] - b[i];
    let mut alpha = 1.0;
    for _ in 0..60 {
        let delta = |i: usize| (w[i] + alpha * d[i]).clamp(0.0, upper) - w[i];
        // The decrease from the step Δ itself, −gᵀΔ − ½ΔᵀHΔ: no cancellation between
        // two nearly equal objective values near the optimum.
        let decrease = -(0..n).map(|i| grad(i) * delta(i)).sum::<f64>()
            - 0.5 * hessian_quadratic(g, lambda, bands, delta);
        let predicted: f64 = (0..n)
            .map(|i| {
                if binding[i] {
                    -grad(i) * delta(i)
                } else {
                    -alpha * grad(i) * d[i]
                }
            })
            .sum();
        if decrease >= 1e-4 * predicted {
            return Some(alpha);
        }
        alpha *= 0.5;
    }
    None
}
