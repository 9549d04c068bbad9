//! The block-banded Cholesky factorisation of the offline prior's Hessian, whole or a
//! window at a time.

use super::window::{
    compute_row, dot, layout, matches, not_definite, solve_l, solve_lt, tri, Inputs, Redo, Scratch,
};
use crate::error::Result;
use nalgebra::DMatrix;
use std::ops::Range;

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
    pub(super) t: usize,
    pub(super) p: usize,
    /// Free variable indices (within a frame) of every frame, concatenated (`u32`: a
    /// frames-long list, and no G has 2³² rows).
    pub(super) free: Vec<u32>,
    /// `free[fstart[s]..fstart[s + 1]]` are frame `s`'s.
    pub(super) fstart: Vec<usize>,
    /// Start (in the whole factor's layout) of `L_{s,s}` (packed lower triangle, row after
    /// row) at `off[s * (p + 1)]` and of `L_{s,s−j}` (row-major, `n_s × n_{s−j}`) at
    /// `off[s * (p + 1) + j]`, `0 < j < p`.
    pub(super) off: Vec<usize>,
    /// The whole factor's length.
    pub(super) total: usize,
    /// The rows of frames `win`: entry `x` of the layout is `l[x − off[win.start·(p + 1)]]`.
    pub(super) l: Vec<f64>,
    pub(super) win: Range<usize>,
    /// `1 / L_{s,s}[x, x]` of every free variable (compact order): substitution multiplies
    /// by it, keeping a division's latency off the recurrences' critical path.
    pub(super) inv: Vec<f64>,
    /// `λ·band_p(s)`: the outermost block's scale at frame `s`.
    pub(super) outer: Vec<f64>,
    /// The mask it was factorised with (`fixed[s * k + i]`), for [`Self::factor_reusing`]
    /// (empty when windowed: there is no whole factor to copy from).
    pub(super) fixed: Vec<bool>,
    /// Block rows copied from the earlier factorisation instead of computed.
    pub(super) copied: usize,
    /// Windowed: what recomputing rows needs.
    pub(super) redo: Option<Box<Redo>>,
    /// The substitutions' work vector, kept between solves.
    pub(super) y: Vec<f64>,
}

/// Segments (or halves of a two-ended factorisation) this long or longer keep their factor
/// a window at a time (see [`BandedSystem`]).
pub const WINDOW_FRAMES: usize = 1 << 16;

/// Frames per block of a windowed factor.
pub const WINDOW_BLOCK: usize = 1024;

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
    pub(super) fn build(
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
        let (l, mut inv, mut free, mut fstart, mut off, mut outer, fixed_copy, redo, y) =
            match recycle {
                Some(r) => (
                    r.l, r.inv, r.free, r.fstart, r.off, r.outer, r.fixed, r.redo, r.y,
                ),
                None => Default::default(),
            };
        let total = layout(fixed, (k, t, p), &mut free, &mut fstart, &mut off);
        inv.resize(free.len(), 0.0);
        inv.truncate(free.len());
        outer.clear();
        outer.extend((0..t).map(|s| if p > 0 { lambda * bands[p][s] } else { 0.0 }));
        let sys = BandedSystem {
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
            fixed: fixed_copy,
            copied: 0,
            redo: None,
            y,
        };
        if windowed {
            sys.fill_windowed(g, lambda, bands, ridge, redo)
        } else {
            sys.fill_whole(g, lambda, bands, fixed, ridge, prev)
        }
    }

    /// Factors a window at a time from the start, keeping a checkpoint of `p` rows at each
    /// window's start (`redo` lends its storage).
    fn fill_windowed(
        mut self,
        g: &DMatrix<f64>,
        lambda: f64,
        bands: &[Vec<f64>],
        ridge: f64,
        redo: Option<Box<Redo>>,
    ) -> Result<BandedSystem> {
        let k = g.nrows();
        let (t, p) = (self.t, self.p);
        self.l.clear();
        self.fixed = Vec::new();
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
        self.redo = Some(redo);
        for a in (0..t).step_by(WINDOW_BLOCK) {
            self.load(a.saturating_sub(p), (a + WINDOW_BLOCK).min(t))
                .map_err(|(s, v)| not_definite(s, v))?;
            if a > 0 {
                // The checkpoint: rows a − p..a, which the window now starts with.
                let len = self.off[a * (p + 1)] - self.off[(a - p) * (p + 1)];
                if let Some(redo) = self.redo.as_mut() {
                    redo.at.push(redo.ck.len());
                    redo.ck.extend_from_slice(&self.l[..len]);
                }
            }
        }
        Ok(self)
    }

    /// Factors every row, copying a row of `prev` (the last iteration's factor) where the
    /// masks of its frame and the `p` before it, and those frames' rows, are the same.
    fn fill_whole(
        mut self,
        g: &DMatrix<f64>,
        lambda: f64,
        bands: &[Vec<f64>],
        fixed: &[bool],
        ridge: f64,
        prev: Option<&BandedSystem>,
    ) -> Result<BandedSystem> {
        let k = g.nrows();
        let (t, p, total) = (self.t, self.p, self.total);
        // Every entry is written below: no need to clear what is kept.
        self.l.resize(total, 0.0);
        self.l.truncate(total);
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
        let BandedSystem {
            free,
            fstart,
            off,
            l,
            inv,
            ..
        } = &mut self;
        for s in 0..t {
            let inputs_same = same_mask[s.saturating_sub(p)..=s].iter().all(|v| *v)
                && same_row[s.saturating_sub(p)..s].iter().all(|v| *v);
            if let (Some(o), true) = (prev, inputs_same) {
                let src = row_range(&o.off, s, o.l.len());
                let dst = row_range(off, s, total);
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
                free,
                fstart,
                off,
                p,
            };
            compute_row(&x, s, l, 0, inv, &mut sc).map_err(|v| not_definite(s, v))?;
            if let (Some(o), true) = (prev, same_mask[s.saturating_sub(p)..=s].iter().all(|v| *v)) {
                let old = &o.l[row_range(&o.off, s, o.l.len())];
                let new = &l[row_range(off, s, total)];
                same_row[s] = old.len() == new.len()
                    && old.iter().zip(new).all(|(a, b)| a.to_bits() == b.to_bits());
            }
        }
        self.win = 0..t;
        self.fixed.clear();
        self.fixed.extend_from_slice(fixed);
        self.copied = copied;
        Ok(self)
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
    pub(super) fn row_start(&self, s: usize) -> usize {
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
    pub(super) fn load(&mut self, a: usize, b: usize) -> std::result::Result<(), (usize, f64)> {
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
    pub(super) fn gather_into(
        &self,
        rhs: &[f64],
        k: usize,
        frame: impl Fn(usize) -> usize,
        y: &mut Vec<f64>,
    ) {
        y.clear();
        for s in 0..self.t {
            let f = frame(s);
            for &i in &self.free[self.fstart[s]..self.fstart[s + 1]] {
                y.push(rhs[f * k + i as usize]);
            }
        }
    }

    /// Writes compact values back into the free entries of a flat vector.
    pub(super) fn scatter(&self, y: &[f64], rhs: &mut [f64], k: usize) {
        self.scatter_map(y, rhs, k, |s| s)
    }

    /// [`Self::scatter`] into a vector whose frame `frame(s)` is this system's frame `s`.
    pub(super) fn scatter_map(
        &self,
        y: &[f64],
        rhs: &mut [f64],
        k: usize,
        frame: impl Fn(usize) -> usize,
    ) {
        for s in 0..self.t {
            let f = frame(s);
            for (c, &i) in (self.fstart[s]..self.fstart[s + 1]).zip(&self.free[self.fstart[s]..]) {
                rhs[f * k + i as usize] = y[c];
            }
        }
    }

    /// Frame `s`'s free variable indices.
    pub(super) fn free_of(&self, s: usize) -> &[u32] {
        &self.free[self.fstart[s]..self.fstart[s + 1]]
    }

    /// Index in `l` of the block at layout offset index `j` of frame `s`.
    pub(super) fn at(&self, s: usize, j: usize) -> usize {
        self.off[s * (self.p + 1) + j] - self.row_start(self.win.start)
    }

    /// `L_{s,s}` packed, and its reciprocal pivots.
    pub(super) fn diag(&self, s: usize) -> (&[f64], &[f64]) {
        let ns = self.fstart[s + 1] - self.fstart[s];
        (
            &self.l[self.at(s, 0)..][..tri(ns)],
            &self.inv[self.fstart[s]..self.fstart[s + 1]],
        )
    }

    /// `y ← L⁻¹ y` on compact vectors, from frame `s0` on: `y` holds frames `s0..` only
    /// (compact index minus `fstart[s0]`) and is zero before them, as is the result.
    pub(super) fn forward(&mut self, y: &mut [f64], s0: usize) {
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
    pub(super) fn forward_rows(&self, y: &mut [f64], s0: usize, rows: Range<usize>) {
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
    pub(super) fn backward(&mut self, y: &mut [f64]) {
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
    pub(super) fn backward_rows(&self, y: &mut [f64], rows: Range<usize>) {
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
