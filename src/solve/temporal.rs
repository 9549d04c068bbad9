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

use super::active_set::{solve_frame, Bound, Gram, Workspace};
use super::{solve_batch, SolveOptions, Solver};
use crate::error::{Error, Result};
use nalgebra::DMatrix;
use rayon::prelude::*;
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
            return Err(Error::invalid(format!(
                "smoothing λ must be a finite number ≥ 0, got {}",
                self.lambda
            )));
        }
        if self.order != 1 && self.order != 2 {
            return Err(Error::invalid(format!(
                "smoothing order must be 1 (first difference) or 2 (second difference), got {}",
                self.order
            )));
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

/// The bands of `DᵀD` for `t` frames: `band[j][i]` is entry `(i, i − j)`, j = 0..=order.
pub fn difference_bands(order: usize, t: usize) -> Vec<Vec<f64>> {
    let coef: &[f64] = if order == 1 {
        &[-1.0, 1.0]
    } else {
        &[1.0, -2.0, 1.0]
    };
    let mut band = vec![vec![0.0; t]; order + 1];
    if t > order {
        // Row r of D touches frames r..=r+order.
        for r in 0..t - order {
            for a in 0..=order {
                for b in 0..=a {
                    band[a - b][r + a] += coef[a] * coef[b];
                }
            }
        }
    }
    band
}

/// A symmetric positive definite block-banded matrix `H = I ⊗ G + λ·DᵀD ⊗ I (+ δI)` over
/// one segment, with some variables fixed (eliminated), factorised by block Cholesky over
/// the free variables only. Frame `s`'s block has as many rows as it has free variables, so
/// with NNLS's typical sparse weights the cost falls with the cube of the free count: about
/// `frames · (order + 1) · n³` for `n` free weights per frame, linear in frames.
///
/// Storage is what the substitutions must read, no more: the diagonal blocks `L_{s,s}` as
/// packed lower triangles, and the blocks `L_{s,s−j}` for `0 < j < order` densely. The
/// outermost block is never stored: `H`'s block there is `λ·band_order(s)` times a selection
/// `P` of the variables free in both frames, and nothing is subtracted from it, so
/// `L_{s,s−order} = λ·band_order(s)·P·L_{c,c}^{−T}` (c = s − order) — the substitutions
/// apply it as a triangular solve with `L_{c,c}`, which they read anyway. For order 1 that
/// leaves `n(n + 1)/2` values per frame instead of `2n²`: the substitutions and the
/// factorisation are bound by memory traffic, not arithmetic, at these block sizes.
///
/// **Long segments** ([`WINDOW_FRAMES`] frames or more) keep `L` a window at a time: the
/// factorisation keeps, of every block of [`WINDOW_BLOCK`] frames, only the `order` rows
/// before it (a checkpoint), and a substitution recomputes each block's rows from its
/// checkpoint when it reaches the block (forwards in order, backwards in reverse). The
/// rows recomputed are the rows first computed, bit for bit (the same operations on the
/// same inputs), so a solve gives the same numbers either way; the factor's memory no
/// longer grows with the frames (222 values per frame at k = 12, order 2, was 1.8 kB per
/// frame), and each solve costs one more pass of the factorisation.
pub struct BandedSystem {
    t: usize,
    p: usize,
    /// Free variable indices (within a frame) of every frame, concatenated (`u32`: a
    /// frames-long list, and no G has 2³² rows).
    free: Vec<u32>,
    /// `free[fstart[s]..fstart[s + 1]]` are frame `s`'s.
    fstart: Vec<usize>,
    /// Start (in the whole factor's layout) of `L_{s,s}` (packed lower triangle, row after
    /// row) at `off[s * (p + 1)]` and of `L_{s,s−j}` (row-major, `n_s × n_{s−j}`) at
    /// `off[s * (p + 1) + j]`, `0 < j < p`.
    off: Vec<usize>,
    /// The whole factor's length.
    total: usize,
    /// The rows of frames `win`: entry `x` of the layout is `l[x − off[win.start·(p + 1)]]`.
    l: Vec<f64>,
    win: Range<usize>,
    /// `1 / L_{s,s}[x, x]` of every free variable (compact order): substitution multiplies
    /// by it, keeping a division's latency off the recurrences' critical path.
    inv: Vec<f64>,
    /// `λ·band_p(s)`: the outermost block's scale at frame `s`.
    outer: Vec<f64>,
    /// The mask it was factorised with (`fixed[s * k + i]`), for [`Self::factor_reusing`]
    /// (empty when windowed: there is no whole factor to copy from).
    fixed: Vec<bool>,
    /// Block rows copied from the earlier factorisation instead of computed.
    copied: usize,
    /// Windowed: what recomputing rows needs.
    redo: Option<Box<Redo>>,
    /// The substitutions' work vector, kept between solves.
    y: Vec<f64>,
}

/// Segments (or halves of a two-ended factorisation) this long or longer keep their factor
/// a window at a time (see [`BandedSystem`]).
pub const WINDOW_FRAMES: usize = 1 << 16;

/// Frames per block of a windowed factor.
pub const WINDOW_BLOCK: usize = 1024;

/// A windowed factor's inputs and checkpoints.
struct Redo {
    g: DMatrix<f64>,
    lambda: f64,
    bands: Vec<Vec<f64>>,
    ridge: f64,
    /// Rows `jB − p..jB` of every block `j ≥ 1` (B = [`WINDOW_BLOCK`]), block `j`'s at
    /// `ck[at[j − 1]..]`.
    ck: Vec<f64>,
    at: Vec<usize>,
    /// The other window buffer.
    spare: Vec<f64>,
    scratch: Scratch,
}

/// What computing a row of `L` reads.
struct Inputs<'a> {
    g: &'a DMatrix<f64>,
    lambda: f64,
    bands: &'a [Vec<f64>],
    ridge: f64,
    free: &'a [u32],
    fstart: &'a [usize],
    off: &'a [usize],
    p: usize,
}

/// The row computation's work space.
#[derive(Default)]
struct Scratch {
    tmp: Vec<f64>,
    /// The outermost block of the current frame, computed but not stored.
    edge: Vec<f64>,
    lead: Vec<usize>,
}

impl Scratch {
    fn new(k: usize) -> Scratch {
        Scratch {
            tmp: vec![0.0; k * k],
            edge: vec![0.0; k * k],
            lead: vec![0; k],
        }
    }
}

/// `a · b` over the shorter length, in four independent sums so the compiler can vectorise
/// it (a single running sum is a dependency chain it must keep in order).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    if n < 8 {
        // Short rows (the common case: a handful of free weights per frame): the setup of
        // the four sums costs more than it saves.
        let mut acc = 0.0;
        for i in 0..n {
            acc += a[i] * b[i];
        }
        return acc;
    }
    let mut acc = [0.0f64; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for i in 0..4 {
            acc[i] += x[i] * y[i];
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// Entries in a packed lower triangle of order `n`; row `x` starts at `tri(x)`.
fn tri(n: usize) -> usize {
    n * (n + 1) / 2
}

/// Calls `f(x, y)` for every pair with `a[x] == b[y]` (both sorted ascending).
fn matches(a: &[u32], b: &[u32], mut f: impl FnMut(usize, usize)) {
    let (mut x, mut y) = (0, 0);
    while x < a.len() && y < b.len() {
        match a[x].cmp(&b[y]) {
            std::cmp::Ordering::Equal => {
                f(x, y);
                x += 1;
                y += 1;
            }
            std::cmp::Ordering::Less => x += 1,
            std::cmp::Ordering::Greater => y += 1,
        }
    }
}

/// `u ← L⁻ᵀ u` for a packed lower triangle `d` with reciprocal pivots `inv`.
fn solve_lt(d: &[f64], inv: &[f64], u: &mut [f64]) {
    let n = u.len();
    for x in (0..n).rev() {
        let mut v = u[x];
        for z in x + 1..n {
            v -= d[tri(z) + x] * u[z];
        }
        u[x] = v * inv[x];
    }
}

/// `u ← L⁻¹ u` for a packed lower triangle `d` with reciprocal pivots `inv`.
fn solve_l(d: &[f64], inv: &[f64], u: &mut [f64]) {
    for x in 0..u.len() {
        let v = u[x] - dot(&d[tri(x)..tri(x) + x], &u[..x]);
        u[x] = v * inv[x];
    }
}

/// Computes frame `s`'s row of `L` into `l` — which holds the layout from offset `base` on,
/// frames `s − p..s` included — and its reciprocal pivots into `inv` (every frame's).
/// Stops at a pivot that is not positive, returning it.
fn compute_row(
    x: &Inputs,
    s: usize,
    l: &mut [f64],
    base: usize,
    inv: &mut [f64],
    sc: &mut Scratch,
) -> std::result::Result<(), f64> {
    let (g, lambda, bands, p) = (x.g, x.lambda, x.bands, x.p);
    let (free, fstart, off) = (x.free, x.fstart, x.off);
    let n = |s: usize| fstart[s + 1] - fstart[s];
    let Scratch { tmp, edge, lead } = sc;
    let fs = &free[fstart[s]..fstart[s + 1]];
    let ns = fs.len();
    for j in (1..=p.min(s)).rev() {
        let c = s - j;
        let fc = &free[fstart[c]..fstart[c + 1]];
        let nc = fc.len();
        let m = &mut tmp[..ns * nc];
        // A_{s,c} = λ·band_j(s)·I restricted to the free rows of s and columns of c.
        m.fill(0.0);
        let v = lambda * bands[j][s];
        if v != 0.0 {
            matches(fs, fc, |x, y| m[x * nc + y] = v);
        }
        // − Σ_{r = s−p}^{c−1} L_{s,r} L_{c,r}ᵀ (c − r < p: stored; s − r = p: `edge`).
        for r in s.saturating_sub(p)..c {
            let nr = n(r);
            let ls = if s - r == p {
                &edge[..ns * nr]
            } else {
                &l[off[s * (p + 1) + (s - r)] - base..][..ns * nr]
            };
            let lc = &l[off[c * (p + 1) + (c - r)] - base..][..nc * nr];
            for x in 0..ns {
                let row = &ls[x * nr..(x + 1) * nr];
                for y in 0..nc {
                    m[x * nc + y] -= dot(row, &lc[y * nr..(y + 1) * nr]);
                }
            }
        }
        // L_{s,c} = M L_{c,c}^{-T}: row x solves L_{c,c} zᵀ = M[x, :]ᵀ. A row's
        // leading zeros stay zero (forward substitution), and for order 1 M is
        // λ times a selection, so most of each row is skipped.
        let d = &l[off[c * (p + 1)] - base..][..tri(nc)];
        let ic = &inv[fstart[c]..fstart[c + 1]];
        for x in 0..ns {
            let row = &mut m[x * nc..(x + 1) * nc];
            let Some(y0) = row.iter().position(|v| *v != 0.0) else {
                continue;
            };
            for y in y0..nc {
                let v = row[y] - dot(&row[y0..y], &d[tri(y) + y0..tri(y) + y]);
                row[y] = v * ic[y];
            }
        }
        if j == p {
            edge[..ns * nc].copy_from_slice(m);
        } else {
            let o = off[s * (p + 1) + j] - base;
            l[o..o + ns * nc].copy_from_slice(m);
        }
    }
    // Diagonal: A_{s,s} − Σ_{r = s−p}^{s−1} L_{s,r} L_{s,r}ᵀ, then Cholesky.
    let m = &mut tmp[..ns * ns];
    let diag = lambda * bands[0][s] + x.ridge;
    for x in 0..ns {
        for y in 0..=x {
            m[x * ns + y] = g[(fs[x] as usize, fs[y] as usize)] + if x == y { diag } else { 0.0 };
        }
    }
    for r in s.saturating_sub(p)..s {
        let nr = n(r);
        let ls = if s - r == p {
            &edge[..ns * nr]
        } else {
            &l[off[s * (p + 1) + (s - r)] - base..][..ns * nr]
        };
        // Leading zeros of each row (from the selection structure above).
        for (x, z) in lead[..ns].iter_mut().enumerate() {
            *z = ls[x * nr..(x + 1) * nr]
                .iter()
                .position(|v| *v != 0.0)
                .unwrap_or(nr);
        }
        for x in 0..ns {
            let rx = &ls[x * nr..(x + 1) * nr];
            for y in 0..=x {
                let z = lead[x].max(lead[y]);
                if z < nr {
                    m[x * ns + y] -= dot(&rx[z..], &ls[y * nr + z..(y + 1) * nr]);
                }
            }
        }
    }
    let is = &mut inv[fstart[s]..fstart[s + 1]];
    for x in 0..ns {
        for y in 0..=x {
            let v = m[x * ns + y] - dot(&m[x * ns..x * ns + y], &m[y * ns..y * ns + y]);
            if x == y {
                if !(v > 0.0 && v.is_finite()) {
                    return Err(v);
                }
                m[x * ns + x] = v.sqrt();
                is[x] = 1.0 / m[x * ns + x];
            } else {
                m[x * ns + y] = v * is[y];
            }
        }
    }
    let o = off[s * (p + 1)] - base;
    for x in 0..ns {
        l[o + tri(x)..o + tri(x) + x + 1].copy_from_slice(&m[x * ns..x * ns + x + 1]);
    }
    Ok(())
}

/// The error of a pivot `v` at frame `s` that is not positive.
fn not_definite(s: usize, v: f64) -> Error {
    Error::invalid(format!(
        "temporal prior: the banded system is not positive definite at frame {s} (pivot {v:e})"
    ))
}

impl BandedSystem {
    /// Factorises `H` with `fixed[s * k + i]` variables eliminated; `ridge` is added to the
    /// diagonal of the free variables. Errors if a pivot is not positive.
    pub fn factor(
        g: &DMatrix<f64>,
        lambda: f64,
        bands: &[Vec<f64>],
        fixed: &[bool],
        ridge: f64,
    ) -> Result<BandedSystem> {
        Self::factor_reusing(g, lambda, bands, fixed, ridge, None, None)
    }

    /// [`Self::factor`], copying from `prev` — a factorisation of the same `H` (same `g`, λ,
    /// bands and ridge) under another mask — every block row whose inputs are bit for bit
    /// the same: frame `s`'s row of `L` depends only on the masks of frames `s − p..=s` and
    /// on the rows of frames `s − p..s`. A row that is recomputed is compared with the old
    /// one, so where a change of mask has died out (the recurrence contracts) copying
    /// resumes. The result is identical to [`Self::factor`]'s, not an approximation; the
    /// active-set iterations, whose masks change in fewer frames each time, get cheaper.
    /// `recycle`, a factorisation no longer needed, gives its storage (a fresh allocation
    /// of the factor's size costs a page fault every 4 KB). A windowed factor (a segment
    /// of [`WINDOW_FRAMES`] or more) copies nothing: it has no whole factor to copy from.
    pub fn factor_reusing(
        g: &DMatrix<f64>,
        lambda: f64,
        bands: &[Vec<f64>],
        fixed: &[bool],
        ridge: f64,
        prev: Option<&BandedSystem>,
        recycle: Option<BandedSystem>,
    ) -> Result<BandedSystem> {
        let windowed = bands[0].len() >= WINDOW_FRAMES;
        Self::build(g, lambda, bands, fixed, ridge, prev, recycle, windowed)
    }

    /// [`Self::factor`], keeping `L` a window at a time whatever the segment's length (as
    /// `factor` does from [`WINDOW_FRAMES`] frames on): the same solves in less memory.
    pub fn factor_windowed(
        g: &DMatrix<f64>,
        lambda: f64,
        bands: &[Vec<f64>],
        fixed: &[bool],
        ridge: f64,
    ) -> Result<BandedSystem> {
        Self::build(g, lambda, bands, fixed, ridge, None, None, true)
    }

    #[allow(clippy::too_many_arguments)]
    fn build(
        g: &DMatrix<f64>,
        lambda: f64,
        bands: &[Vec<f64>],
        fixed: &[bool],
        ridge: f64,
        prev: Option<&BandedSystem>,
        recycle: Option<BandedSystem>,
        windowed: bool,
    ) -> Result<BandedSystem> {
        let k = g.nrows();
        let t = bands[0].len();
        let p = bands.len() - 1;
        let windowed = windowed && p > 0;
        // The old factor's storage, the rest of it dropped before anything is allocated.
        // Every allocation is reused from `recycle`, and its memory with it: a long
        // segment's iterations then take no new frames-long blocks from the allocator.
        let (mut l, mut inv, mut free, mut fstart, mut off, mut outer, mut fixed_copy, redo, y) =
            match recycle {
                Some(r) => (
                    r.l, r.inv, r.free, r.fstart, r.off, r.outer, r.fixed, r.redo, r.y,
                ),
                None => Default::default(),
            };
        free.clear();
        fstart.clear();
        for s in 0..t {
            fstart.push(free.len());
            free.extend((0..k).filter(|&i| !fixed[s * k + i]).map(|i| i as u32));
        }
        fstart.push(free.len());
        let n = |s: usize| fstart[s + 1] - fstart[s];
        off.clear();
        off.resize(t * (p + 1), 0);
        let mut total = 0;
        for s in 0..t {
            off[s * (p + 1)] = total;
            total += tri(n(s));
            for j in 1..=p.min(s) {
                if j < p {
                    off[s * (p + 1) + j] = total;
                    total += n(s) * n(s - j);
                }
            }
        }
        inv.resize(free.len(), 0.0);
        inv.truncate(free.len());
        outer.clear();
        outer.extend((0..t).map(|s| if p > 0 { lambda * bands[p][s] } else { 0.0 }));
        if windowed {
            l.clear();
            let mut redo = redo.unwrap_or_else(|| {
                Box::new(Redo {
                    g: g.clone(),
                    lambda,
                    bands: Vec::new(),
                    ridge,
                    ck: Vec::new(),
                    at: Vec::new(),
                    spare: Vec::new(),
                    scratch: Scratch::new(k),
                })
            });
            redo.g.clone_from(g);
            redo.lambda = lambda;
            redo.ridge = ridge;
            redo.bands.truncate(bands.len());
            for (d, b) in redo.bands.iter_mut().zip(bands) {
                d.clear();
                d.extend_from_slice(b);
            }
            for b in &bands[redo.bands.len()..] {
                redo.bands.push(b.clone());
            }
            redo.ck.clear();
            redo.at.clear();
            redo.scratch = Scratch::new(k);
            let mut sys = BandedSystem {
                t,
                p,
                free,
                fstart,
                off,
                total,
                l,
                win: 0..0,
                inv,
                outer,
                fixed: Vec::new(),
                copied: 0,
                redo: Some(redo),
                y,
            };
            for a in (0..t).step_by(WINDOW_BLOCK) {
                sys.load(a.saturating_sub(p), (a + WINDOW_BLOCK).min(t))
                    .map_err(|(s, v)| not_definite(s, v))?;
                if a > 0 {
                    // The checkpoint: rows a − p..a, which the window now starts with.
                    let len = sys.off[a * (p + 1)] - sys.off[(a - p) * (p + 1)];
                    if let Some(redo) = sys.redo.as_mut() {
                        redo.at.push(redo.ck.len());
                        redo.ck.extend_from_slice(&sys.l[..len]);
                    }
                }
            }
            return Ok(sys);
        }
        // Every entry is written below: no need to clear what is kept.
        l.resize(total, 0.0);
        l.truncate(total);
        let mut sc = Scratch::new(k);
        let prev = prev.filter(|o| o.t == t && o.p == p && o.fixed.len() == fixed.len());
        // same_mask[s]: frame s's mask is the old one; same_row[s]: so is its row of L.
        let same_mask: Vec<bool> = match prev {
            Some(o) => (0..t)
                .map(|s| o.fixed[s * k..(s + 1) * k] == fixed[s * k..(s + 1) * k])
                .collect(),
            None => vec![false; t],
        };
        let mut same_row = vec![false; t];
        let mut copied = 0;
        // The row of frame s (its stored blocks) occupies one contiguous range.
        let row_range = |off: &[usize], s: usize, len: usize| {
            let a = off[s * (p + 1)];
            let b = if s + 1 < t {
                off[(s + 1) * (p + 1)]
            } else {
                len
            };
            a..b
        };
        for s in 0..t {
            let inputs_same = same_mask[s.saturating_sub(p)..=s].iter().all(|v| *v)
                && same_row[s.saturating_sub(p)..s].iter().all(|v| *v);
            if let (Some(o), true) = (prev, inputs_same) {
                let src = row_range(&o.off, s, o.l.len());
                let dst = row_range(&off, s, total);
                l[dst].copy_from_slice(&o.l[src]);
                inv[fstart[s]..fstart[s + 1]].copy_from_slice(&o.inv[o.fstart[s]..o.fstart[s + 1]]);
                same_row[s] = true;
                copied += 1;
                continue;
            }
            let x = Inputs {
                g,
                lambda,
                bands,
                ridge,
                free: &free,
                fstart: &fstart,
                off: &off,
                p,
            };
            compute_row(&x, s, &mut l, 0, &mut inv, &mut sc).map_err(|v| not_definite(s, v))?;
            if let (Some(o), true) = (prev, same_mask[s.saturating_sub(p)..=s].iter().all(|v| *v)) {
                let old = &o.l[row_range(&o.off, s, o.l.len())];
                let new = &l[row_range(&off, s, total)];
                same_row[s] = old.len() == new.len()
                    && old.iter().zip(new).all(|(a, b)| a.to_bits() == b.to_bits());
            }
        }
        Ok(BandedSystem {
            t,
            p,
            free,
            fstart,
            off,
            total,
            l,
            win: 0..t,
            inv,
            outer,
            fixed: {
                fixed_copy.clear();
                fixed_copy.extend_from_slice(fixed);
                fixed_copy
            },
            copied,
            redo: None,
            y,
        })
    }

    /// Whether the factor is kept a window at a time (see [`BandedSystem`]).
    pub fn is_windowed(&self) -> bool {
        self.redo.is_some()
    }

    /// Values of `L` held now: the whole factor, or a windowed factor's window and
    /// checkpoints.
    pub fn stored_values(&self) -> usize {
        self.l.len() + self.redo.as_ref().map_or(0, |r| r.ck.len())
    }

    /// Start of frame `s`'s row in the layout (`total` for `s = t`).
    fn row_start(&self, s: usize) -> usize {
        if s < self.t {
            self.off[s * (self.p + 1)]
        } else {
            self.total
        }
    }

    /// A windowed factor: makes the window frames `a..b`, taking each row from the current
    /// window if it has it, else from a checkpoint, else computing it (in order, so a
    /// computed row finds its `p` predecessors in the new window: `a` must be 0, a block's
    /// start minus `p`, or inside the current window).
    /// Stops at the first pivot that is not positive, returning its frame and value: only
    /// the factorisation's own pass can meet one, since a row recomputed later is the row
    /// computed (and checked) then.
    fn load(&mut self, a: usize, b: usize) -> std::result::Result<(), (usize, f64)> {
        if self.win.start <= a && b <= self.win.end {
            return Ok(());
        }
        let p = self.p;
        let base = self.row_start(a);
        let len = self.row_start(b) - base;
        let old = self.row_start(self.win.start);
        let Some(redo) = self.redo.as_mut() else {
            // A whole factor's window is every frame.
            return Ok(());
        };
        let mut nl = std::mem::take(&mut redo.spare);
        nl.clear();
        nl.resize(len, 0.0);
        let x = Inputs {
            g: &redo.g,
            lambda: redo.lambda,
            bands: &redo.bands,
            ridge: redo.ridge,
            free: &self.free,
            fstart: &self.fstart,
            off: &self.off,
            p,
        };
        let row = |s: usize| {
            let a = x.off[s * (p + 1)];
            let b = if s + 1 < self.t {
                x.off[(s + 1) * (p + 1)]
            } else {
                self.total
            };
            a..b
        };
        for s in a..b {
            let r = row(s);
            let dst = r.start - base..r.end - base;
            if self.win.contains(&s) {
                nl[dst].copy_from_slice(&self.l[r.start - old..r.end - old]);
                continue;
            }
            // Checkpoint j holds rows jB − p..jB.
            let j = s / WINDOW_BLOCK + 1;
            if s + p >= j * WINDOW_BLOCK && j <= redo.at.len() {
                let c0 = row(j * WINDOW_BLOCK - p).start;
                let src = redo.at[j - 1] + r.start - c0;
                nl[dst].copy_from_slice(&redo.ck[src..src + r.len()]);
                continue;
            }
            compute_row(&x, s, &mut nl, base, &mut self.inv, &mut redo.scratch)
                .map_err(|v| (s, v))?;
        }
        redo.spare = std::mem::replace(&mut self.l, nl);
        self.win = a..b;
        Ok(())
    }

    /// Solves `H x = rhs` in place (`rhs` flat, frame after frame); the entries of fixed
    /// variables are left as they are (their rows are the identity).
    pub fn solve(&mut self, rhs: &mut [f64]) {
        let k = rhs.len() / self.t.max(1);
        let mut y = std::mem::take(&mut self.y);
        self.gather_into(rhs, k, |s| s, &mut y);
        self.forward(&mut y, 0);
        self.backward(&mut y);
        self.scatter(&y, rhs, k);
        self.y = y;
    }

    /// [`Self::gather`] from a vector whose frame `frame(s)` is this system's frame `s`, into
    /// `y` (its storage reused).
    fn gather_into(&self, rhs: &[f64], k: usize, frame: impl Fn(usize) -> usize, y: &mut Vec<f64>) {
        y.clear();
        for s in 0..self.t {
            let f = frame(s);
            for &i in &self.free[self.fstart[s]..self.fstart[s + 1]] {
                y.push(rhs[f * k + i as usize]);
            }
        }
    }

    /// Writes compact values back into the free entries of a flat vector.
    fn scatter(&self, y: &[f64], rhs: &mut [f64], k: usize) {
        self.scatter_map(y, rhs, k, |s| s)
    }

    /// [`Self::scatter`] into a vector whose frame `frame(s)` is this system's frame `s`.
    fn scatter_map(&self, y: &[f64], rhs: &mut [f64], k: usize, frame: impl Fn(usize) -> usize) {
        for s in 0..self.t {
            let f = frame(s);
            for (c, &i) in (self.fstart[s]..self.fstart[s + 1]).zip(&self.free[self.fstart[s]..]) {
                rhs[f * k + i as usize] = y[c];
            }
        }
    }

    /// Frame `s`'s free variable indices.
    fn free_of(&self, s: usize) -> &[u32] {
        &self.free[self.fstart[s]..self.fstart[s + 1]]
    }

    /// Index in `l` of the block at layout offset index `j` of frame `s`.
    fn at(&self, s: usize, j: usize) -> usize {
        self.off[s * (self.p + 1) + j] - self.row_start(self.win.start)
    }

    /// `L_{s,s}` packed, and its reciprocal pivots.
    fn diag(&self, s: usize) -> (&[f64], &[f64]) {
        let ns = self.fstart[s + 1] - self.fstart[s];
        (
            &self.l[self.at(s, 0)..][..tri(ns)],
            &self.inv[self.fstart[s]..self.fstart[s + 1]],
        )
    }

    /// `y ← L⁻¹ y` on compact vectors, from frame `s0` on: `y` holds frames `s0..` only
    /// (compact index minus `fstart[s0]`) and is zero before them, as is the result.
    fn forward(&mut self, y: &mut [f64], s0: usize) {
        if self.redo.is_none() {
            return self.forward_rows(y, s0, s0..self.t);
        }
        let p = self.p;
        for a in (s0 / WINDOW_BLOCK * WINDOW_BLOCK..self.t).step_by(WINDOW_BLOCK) {
            let b = (a + WINDOW_BLOCK).min(self.t);
            // Cannot fail: these rows factorised once (see `load`).
            let _ = self.load(a.saturating_sub(p), b);
            self.forward_rows(y, s0, a.max(s0)..b);
        }
    }

    /// [`Self::forward`]'s recurrence over frames `rows`, which the window holds with the
    /// `p` frames before them.
    fn forward_rows(&self, y: &mut [f64], s0: usize, rows: Range<usize>) {
        let (p, fs) = (self.p, &self.fstart);
        let base = fs[s0];
        let n = |s: usize| fs[s + 1] - fs[s];
        let mut u: Vec<f64> = Vec::new();
        for s in rows {
            let ns = n(s);
            for r in s.saturating_sub(p).max(s0)..s {
                let nr = n(r);
                let (head, tail) = y.split_at_mut(fs[s] - base);
                let yr = &head[fs[r] - base..fs[r] - base + nr];
                if s - r < p {
                    let a = &self.l[self.at(s, s - r)..][..ns * nr];
                    for x in 0..ns {
                        tail[x] -= dot(&a[x * nr..(x + 1) * nr], yr);
                    }
                } else {
                    // L_{s,r} y_r = v·P·(L_{r,r}^{-T} y_r).
                    let v = self.outer[s];
                    if v == 0.0 {
                        continue;
                    }
                    if u.len() < nr {
                        u.resize(nr, 0.0);
                    }
                    let ur = &mut u[..nr];
                    ur.copy_from_slice(yr);
                    let (d, ir) = self.diag(r);
                    solve_lt(d, ir, ur);
                    matches(self.free_of(s), self.free_of(r), |x, z| {
                        tail[x] -= v * ur[z]
                    });
                }
            }
            let (d, is) = self.diag(s);
            solve_l(d, is, &mut y[fs[s] - base..fs[s] - base + ns]);
        }
    }

    /// `y ← L⁻ᵀ y` on compact vectors (all frames).
    fn backward(&mut self, y: &mut [f64]) {
        if self.redo.is_none() {
            return self.backward_rows(y, 0..self.t);
        }
        let (t, p) = (self.t, self.p);
        let blocks = t.div_ceil(WINDOW_BLOCK);
        for j in (0..blocks).rev() {
            let a = j * WINDOW_BLOCK;
            let b = (a + WINDOW_BLOCK).min(t);
            // Cannot fail: these rows factorised once (see `load`).
            let _ = self.load(a.saturating_sub(p), (b + p).min(t));
            self.backward_rows(y, a..b);
        }
    }

    /// [`Self::backward`]'s recurrence over frames `rows` (in reverse), which the window
    /// holds with the `p` frames after them.
    fn backward_rows(&self, y: &mut [f64], rows: Range<usize>) {
        let (t, p, fs) = (self.t, self.p, &self.fstart);
        let n = |s: usize| fs[s + 1] - fs[s];
        let mut u: Vec<f64> = Vec::new();
        for s in rows.rev() {
            let ns = n(s);
            for m in s + 1..(s + p + 1).min(t) {
                let nm = n(m);
                let (head, tail) = y.split_at_mut(fs[m]);
                let ym = &tail[..nm];
                let ys = &mut head[fs[s]..fs[s] + ns];
                if m - s < p {
                    let a = &self.l[self.at(m, m - s)..][..nm * ns];
                    for z in 0..nm {
                        let c = ym[z];
                        if c != 0.0 {
                            for (v, lv) in ys.iter_mut().zip(&a[z * ns..(z + 1) * ns]) {
                                *v -= lv * c;
                            }
                        }
                    }
                } else {
                    // L_{m,s}ᵀ y_m = v·L_{s,s}^{-1}·(Pᵀ y_m).
                    let v = self.outer[m];
                    if v == 0.0 {
                        continue;
                    }
                    if u.len() < ns {
                        u.resize(ns, 0.0);
                    }
                    let us = &mut u[..ns];
                    us.fill(0.0);
                    matches(self.free_of(m), self.free_of(s), |z, x| us[x] = ym[z]);
                    let (d, is) = self.diag(s);
                    solve_l(d, is, us);
                    for (a, b) in ys.iter_mut().zip(us.iter()) {
                        *a -= v * b;
                    }
                }
            }
            let (d, is) = self.diag(s);
            solve_lt(d, is, &mut y[fs[s]..fs[s] + ns]);
        }
    }
}

/// Segments at least this long are factorised from both ends at once (see
/// [`SegmentSystem`]); shorter ones in one sweep. Fixed, so results do not depend on the
/// thread count.
pub const SPLIT_FRAMES: usize = 4096;

/// One segment's `H` factorised for repeated solves: in one forward sweep, or — for long
/// segments — from both ends at once, the two halves in parallel, meeting at a separator of
/// `order` frames whose Schur complement is factorised densely ("burn at both ends").
/// Exact either way: the two differ only by rounding.
// One value per factorisation: the variants' sizes do not matter.
#[allow(clippy::large_enum_variant)]
pub enum SegmentSystem {
    /// One forward sweep.
    One(BandedSystem),
    /// Two halves and a separator.
    Split(Box<Split>),
}

/// The two-ended factorisation: frames `0..m` forward (`a`), frames `m + p..t` backward
/// (`b`, built on the time-reversed frames), separator frames `m..m + p`.
pub struct Split {
    k: usize,
    t: usize,
    p: usize,
    m: usize,
    a: BandedSystem,
    b: BandedSystem,
    /// Flat indices (`s * k + i`) of the separator's free variables.
    sep: Vec<usize>,
    /// `L_a⁻¹ H_{a,sep}` on `a`'s last `p` frames (compact rows × separator columns).
    xa: DMatrix<f64>,
    /// The same for `b`'s last (the original's first after the separator) `p` frames.
    xb: DMatrix<f64>,
    /// Cholesky factor of the separator's Schur complement.
    c: Option<nalgebra::Cholesky<f64, nalgebra::Dyn>>,
}

impl SegmentSystem {
    /// Factorises as [`BandedSystem::factor`], from both ends when `split` and the segment
    /// is long enough to hold two halves and a separator.
    pub fn factor(
        g: &DMatrix<f64>,
        lambda: f64,
        bands: &[Vec<f64>],
        fixed: &[bool],
        ridge: f64,
        split: bool,
    ) -> Result<SegmentSystem> {
        Self::factor_reusing(g, lambda, bands, fixed, ridge, split, None, None)
    }

    /// [`Self::factor`], reusing the rows of `prev` (the same `H` under another mask) that
    /// come out bit for bit the same, and the storage of `recycle`, as
    /// [`BandedSystem::factor_reusing`] does.
    #[allow(clippy::too_many_arguments)]
    pub fn factor_reusing(
        g: &DMatrix<f64>,
        lambda: f64,
        bands: &[Vec<f64>],
        fixed: &[bool],
        ridge: f64,
        split: bool,
        prev: Option<&SegmentSystem>,
        recycle: Option<SegmentSystem>,
    ) -> Result<SegmentSystem> {
        let k = g.nrows();
        let t = bands[0].len();
        let p = bands.len() - 1;
        if !split || t < 4 * p + 4 || p == 0 {
            let old = match prev {
                Some(SegmentSystem::One(o)) => Some(o),
                _ => None,
            };
            let spare = match recycle {
                Some(SegmentSystem::One(o)) => Some(o),
                _ => None,
            };
            return Ok(SegmentSystem::One(BandedSystem::factor_reusing(
                g, lambda, bands, fixed, ridge, old, spare,
            )?));
        }
        let m = (t - p) / 2;
        let nb = t - m - p;
        // The halves' bands: a is the leading block as it stands; b is the trailing block
        // with time reversed (DᵀD is symmetric, so entry (i, i − j) of the reversed block is
        // the original's entry (t − 1 − i + j, t − 1 − i)).
        let bands_a: Vec<Vec<f64>> = bands.iter().map(|b| b[..m].to_vec()).collect();
        let bands_b: Vec<Vec<f64>> = (0..=p)
            .map(|j| {
                (0..nb)
                    .map(|i| if i >= j { bands[j][t - 1 - i + j] } else { 0.0 })
                    .collect()
            })
            .collect();
        let fixed_a = &fixed[..m * k];
        let fixed_b: Vec<bool> = (0..nb)
            .flat_map(|i| fixed[(t - 1 - i) * k..(t - i) * k].iter().copied())
            .collect();
        let (old_a, old_b) = match prev {
            Some(SegmentSystem::Split(o)) if o.m == m && o.t == t => (Some(&o.a), Some(&o.b)),
            _ => (None, None),
        };
        let (spare_a, spare_b) = match recycle {
            Some(SegmentSystem::Split(o)) => {
                let o = *o;
                (Some(o.a), Some(o.b))
            }
            _ => (None, None),
        };
        let (ra, rb) = rayon::join(
            || BandedSystem::factor_reusing(g, lambda, &bands_a, fixed_a, ridge, old_a, spare_a),
            || BandedSystem::factor_reusing(g, lambda, &bands_b, &fixed_b, ridge, old_b, spare_b),
        );
        let (mut a, mut b) = (ra?, rb?);
        let sep: Vec<usize> = (m * k..(m + p) * k).filter(|&v| !fixed[v]).collect();
        let ns = sep.len();
        // H's entry between frames r < c (c − r ≤ p) on one variable: λ·band[c − r][c].
        let coupling = |r: usize, c: usize| lambda * bands[c - r][c];
        // X_a = L_a⁻¹ H_{a,sep}: columns live on a's last p frames.
        let a0 = m - p;
        let a_len = a.fstart[m] - a.fstart[a0];
        let mut xa = DMatrix::zeros(a_len, ns);
        let b0 = nb - p;
        let b_len = b.fstart[nb] - b.fstart[b0];
        let mut xb = DMatrix::zeros(b_len, ns);
        for (j, &v) in sep.iter().enumerate() {
            let (s, i) = (v / k, v % k);
            let mut col = vec![0.0; a_len];
            for r in a0..m {
                if s - r <= p {
                    if let Some(x) = a.free[a.fstart[r]..a.fstart[r + 1]]
                        .iter()
                        .position(|&f| f as usize == i)
                    {
                        col[a.fstart[r] - a.fstart[a0] + x] = coupling(r, s);
                    }
                }
            }
            a.forward(&mut col, a0);
            xa.column_mut(j).copy_from_slice(&col);
            let mut col = vec![0.0; b_len];
            for ib in b0..nb {
                let orig = t - 1 - ib;
                if orig - s <= p {
                    if let Some(x) = b.free[b.fstart[ib]..b.fstart[ib + 1]]
                        .iter()
                        .position(|&f| f as usize == i)
                    {
                        col[b.fstart[ib] - b.fstart[b0] + x] = coupling(s, orig);
                    }
                }
            }
            b.forward(&mut col, b0);
            xb.column_mut(j).copy_from_slice(&col);
        }
        let c = if ns == 0 {
            None
        } else {
            let mut h = DMatrix::zeros(ns, ns);
            for (x, &u) in sep.iter().enumerate() {
                for (y, &v) in sep.iter().enumerate() {
                    let (su, iu, sv, iv) = (u / k, u % k, v / k, v % k);
                    let mut e = if su == sv { g[(iu, iv)] } else { 0.0 };
                    if iu == iv && su.abs_diff(sv) <= p {
                        let (lo, hi) = (su.min(sv), su.max(sv));
                        e += lambda * bands[hi - lo][hi];
                        if lo == hi {
                            e += ridge;
                        }
                    }
                    h[(x, y)] = e;
                }
            }
            h -= xa.tr_mul(&xa) + xb.tr_mul(&xb);
            Some(h.cholesky().ok_or_else(|| {
                Error::invalid(
                    "temporal prior: the separator's Schur complement is not positive definite",
                )
            })?)
        };
        Ok(SegmentSystem::Split(Box::new(Split {
            k,
            t,
            p,
            m,
            a,
            b,
            sep,
            xa,
            xb,
            c,
        })))
    }

    /// Block rows (frames) copied from the earlier factorisation `factor_reusing` was given,
    /// instead of computed: what the reuse saved.
    pub fn copied_rows(&self) -> usize {
        match self {
            SegmentSystem::One(b) => b.copied,
            SegmentSystem::Split(sp) => sp.a.copied + sp.b.copied,
        }
    }

    /// Whether its factors are kept a window at a time (see [`BandedSystem`]).
    pub fn is_windowed(&self) -> bool {
        match self {
            SegmentSystem::One(b) => b.is_windowed(),
            SegmentSystem::Split(sp) => sp.a.is_windowed() || sp.b.is_windowed(),
        }
    }

    /// Solves `H x = rhs` in place, as [`BandedSystem::solve`].
    pub fn solve(&mut self, rhs: &mut [f64]) {
        match self {
            SegmentSystem::One(b) => b.solve(rhs),
            SegmentSystem::Split(sp) => sp.solve(rhs),
        }
    }
}

impl Split {
    fn solve(&mut self, rhs: &mut [f64]) {
        let (k, t, p, m) = (self.k, self.t, self.p, self.m);
        let nb = t - m - p;
        // b's frame i is frame t − 1 − i.
        let rev = |i: usize| t - 1 - i;
        let mut ya = std::mem::take(&mut self.a.y);
        let mut yb = std::mem::take(&mut self.b.y);
        self.a.gather_into(&rhs[..m * k], k, |s| s, &mut ya);
        self.b.gather_into(rhs, k, rev, &mut yb);
        let (sa, sb) = (&mut self.a, &mut self.b);
        rayon::join(|| sa.forward(&mut ya, 0), || sb.forward(&mut yb, 0));
        let (a0, b0) = (self.a.fstart[m - p], self.b.fstart[nb - p]);
        let xs = match &self.c {
            None => nalgebra::DVector::zeros(0),
            Some(c) => {
                let r = nalgebra::DVector::from_iterator(
                    self.sep.len(),
                    self.sep.iter().map(|&v| rhs[v]),
                ) - self
                    .xa
                    .tr_mul(&nalgebra::DVector::from_column_slice(&ya[a0..]))
                    - self
                        .xb
                        .tr_mul(&nalgebra::DVector::from_column_slice(&yb[b0..]));
                c.solve(&r)
            }
        };
        if !xs.is_empty() {
            let da = &self.xa * &xs;
            let db = &self.xb * &xs;
            for (v, d) in ya[a0..].iter_mut().zip(da.iter()) {
                *v -= d;
            }
            for (v, d) in yb[b0..].iter_mut().zip(db.iter()) {
                *v -= d;
            }
        }
        let (sa, sb) = (&mut self.a, &mut self.b);
        rayon::join(|| sa.backward(&mut ya), || sb.backward(&mut yb));
        self.a.scatter(&ya, &mut rhs[..m * k], k);
        self.b.scatter_map(&yb, rhs, k, rev);
        (self.a.y, self.b.y) = (ya, yb);
        for (&v, x) in self.sep.iter().zip(xs.iter()) {
            rhs[v] = *x;
        }
    }
}

/// `H w` for one segment (`w` flat, frame after frame).
fn hessian_times(g: &DMatrix<f64>, lambda: f64, bands: &[Vec<f64>], w: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; w.len()];
    hessian_times_into(g, lambda, bands, w, &mut out);
    out
}

/// [`hessian_times`] into `out` (as long as `w`; every entry is written).
fn hessian_times_into(
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
fn hessian_quadratic(
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
fn kkt_with(
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
fn kkt_from(
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

/// Segments must partition the frames in order: the first starts at 0, each next one where
/// the one before ends, none empty, the last ends at `frames` (an overlap would solve a
/// frame twice and leave another at zero).
fn check_segments(segments: &[Range<usize>], frames: usize) -> Result<()> {
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
    plain: &super::Solution,
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
    let b = super::chunked_product(&s.transpose(), q);
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

fn offline(
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
    fn cols<'a>(m: &'a DMatrix<f64>, r: &Range<usize>) -> &'a [f64] {
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
struct Caps {
    /// Each primal–dual active-set run.
    active_set: usize,
    /// Projected Newton.
    newton: usize,
}

impl Caps {
    const DEFAULT: Caps = Caps {
        active_set: PDAS_ITERATIONS,
        newton: NEWTON_ITERATIONS,
    };
}

/// One segment offline.
fn segment(
    g: &DMatrix<f64>,
    b: &[f64],
    w0: &[f64],
    solver: Solver,
    sm: &Smoothing,
    caps: Caps,
) -> Result<SegmentResult> {
    let k = g.nrows();
    let t = b.len() / k;
    let bands = difference_bands(sm.order, t);
    let gmax = (0..k).map(|i| g[(i, i)]).fold(0.0f64, f64::max);
    // A ridge far below every scale that matters keeps rank-deficient S factorisable (the
    // prior leaves S's null directions constant in time undetermined).
    let ridge = 1e-12 * (gmax + sm.lambda * if sm.order == 1 { 4.0 } else { 16.0 });
    let upper = if solver == Solver::Bounded {
        1.0
    } else {
        f64::INFINITY
    };
    // The last factorisation, from which the next one copies the rows that do not change.
    // (and the one before it, whose storage the next one takes).
    let cache: std::cell::RefCell<Option<SegmentSystem>> = std::cell::RefCell::new(None);
    let spare: std::cell::RefCell<Option<SegmentSystem>> = std::cell::RefCell::new(None);
    // `values`: the fixed variables' values (None: all 0, as NNLS fixes them).
    let solve_with = |fixed: &[bool], values: Option<&[f64]>| -> Result<Vec<f64>> {
        let mut sys = SegmentSystem::factor_reusing(
            g,
            sm.lambda,
            &bands,
            fixed,
            ridge,
            t >= SPLIT_FRAMES,
            cache.borrow().as_ref(),
            spare.borrow_mut().take(),
        )?;
        // rhs = b − H·v (v: fixed values, 0 elsewhere); fixed rows take their values.
        // (With every fixed value 0, H·v = 0 and the product is skipped.)
        let values = values.filter(|v| v.iter().any(|x| *x != 0.0));
        let mut rhs: Vec<f64> = match values {
            None => b.to_vec(),
            Some(v) => {
                let hv = hessian_times(g, sm.lambda, &bands, v);
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
            *spare.borrow_mut() = Some(sys);
        } else {
            *spare.borrow_mut() = cache.borrow_mut().replace(sys);
        }
        if let Some(v) = values {
            for ((r, f), x) in rhs.iter_mut().zip(fixed).zip(v) {
                if *f {
                    *r = *x;
                }
            }
        }
        Ok(rhs)
    };
    if solver == Solver::Ls {
        let w = solve_with(&vec![false; b.len()], None)?;
        let res = kkt_residual(g, sm.lambda, sm.order, b, &w, solver);
        return Ok((w, 1, res, true));
    }
    // Primal–dual active set from the per-frame solution: a few banded solves when it
    // works (order 1 nearly always). It can cycle when the Hessian is not an M-matrix (the
    // second-difference prior at large λ); then projected Newton, which decreases the
    // objective at every step and so cannot cycle, takes over from the same start.
    let pdas = |start: &[f64], cap: usize| -> Result<Option<(Vec<f64>, u64)>> {
        let c = gmax.max(f64::MIN_POSITIVE);
        let mut w = start.to_vec();
        let mut prev: Option<(Vec<bool>, Vec<bool>)> = None;
        for it in 1..=cap {
            let mut grad = hessian_times(g, sm.lambda, &bands, &w);
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
            w = solve_with(&fixed, values.as_deref())?;
            prev = Some((at_lower, at_upper));
        }
        Ok(None)
    };
    let mut iterations = 0u64;
    if let Some((w, it)) = pdas(w0, caps.active_set)? {
        iterations += it;
        let res = kkt_residual(g, sm.lambda, sm.order, b, &w, solver);
        if res < KKT_TOLERANCE {
            return Ok((w, iterations, res, true));
        }
    } else {
        iterations += caps.active_set as u64;
    }
    // Projected Newton factorises into the storage the active-set steps leave (one
    // system held at a time, not three); their last factor has no rows it could copy.
    {
        let cached = cache.borrow_mut().take();
        let mut spare = spare.borrow_mut();
        if spare.is_none() {
            *spare = cached;
        }
    }
    let (w, it) = projected_newton(
        g,
        sm,
        &bands,
        b,
        w0,
        upper,
        ridge,
        solver,
        &spare,
        caps.newton,
    )?;
    iterations += it;
    let res = kkt_residual(g, sm.lambda, sm.order, b, &w, solver);
    if res < KKT_TOLERANCE {
        return Ok((w, iterations, res, true));
    }
    // Near the optimum the active set from projected Newton is (nearly) the optimal one, and
    // one or two primal–dual steps from it finish exactly.
    if let Some((wp, it)) = pdas(&w, caps.active_set)? {
        iterations += it;
        let rp = kkt_residual(g, sm.lambda, sm.order, b, &wp, solver);
        if rp < res {
            return Ok((wp, iterations, rp, rp < KKT_TOLERANCE));
        }
    } else {
        iterations += caps.active_set as u64;
    }
    Ok((w, iterations, res, res < KKT_TOLERANCE))
}

/// The relative KKT residual ([`kkt_residual`]) at which a constrained offline solve stops.
pub const KKT_TOLERANCE: f64 = 1e-10;

/// Active-set iterations before projected Newton takes over.
const PDAS_ITERATIONS: usize = 40;

/// Projected-Newton iterations at most.
const NEWTON_ITERATIONS: usize = 500;

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
fn projected_newton(
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
        // Armijo along the projection arc (σ = 1e-4, halving).
        let mut alpha = 1.0;
        let mut accepted = false;
        for _ in 0..60 {
            let delta = |i: usize| project(w[i] + alpha * d[i]) - w[i];
            // The decrease from the step Δ itself, −gᵀΔ − ½ΔᵀHΔ: no cancellation between
            // two nearly equal objective values near the optimum.
            let decrease = -(0..n).map(|i| grad(&hw, i) * delta(i)).sum::<f64>()
                - 0.5 * hessian_quadratic(g, sm.lambda, bands, delta);
            let predicted: f64 = (0..n)
                .map(|i| {
                    if binding[i] {
                        -grad(&hw, i) * delta(i)
                    } else {
                        -alpha * grad(&hw, i) * d[i]
                    }
                })
                .sum();
            if decrease >= 1e-4 * predicted {
                accepted = true;
                break;
            }
            alpha *= 0.5;
        }
        if !accepted {
            // No decrease left at working precision.
            return Ok((w, it as u64));
        }
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

/// What every frame of a causal solve shares: the Gram forms with and without the prior.
pub struct CausalShared {
    k: usize,
    solver: Solver,
    sm: Smoothing,
    gram_l: Gram,
    gram_0: Gram,
    pinv_0: DMatrix<f64>,
    chol_l: nalgebra::Cholesky<f64, nalgebra::Dyn>,
}

/// One segment's running state of a causal solve: the weights of the last two frames and
/// the active-set workspaces. Frames go in one at a time ([`CausalShared::step`]), so the
/// solve runs as the frames arrive (a streamed solve feeds it chunk after chunk).
pub struct CausalState {
    ws0: Workspace,
    wsl: Workspace,
    prev: Vec<f64>,
    prev2: Vec<f64>,
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
        let pinv_0 = super::lstsq::gram_pseudo_inverse(g, None);
        let chol_l = gl
            .clone()
            .cholesky()
            .ok_or_else(|| Error::invalid("temporal prior: SᵀS + λI is not positive definite"))?;
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

fn causal(
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
        return Err(Error::invalid(
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

#[cfg(test)]
mod tests {
    use super::*;

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
