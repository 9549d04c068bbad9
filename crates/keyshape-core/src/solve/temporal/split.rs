//! Long segments factorised from both ends at once (the two-ended split).

use super::banded::BandedSystem;
use crate::error::{Error, Result};
use nalgebra::DMatrix;

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
    pub(super) k: usize,
    pub(super) t: usize,
    pub(super) p: usize,
    pub(super) m: usize,
    pub(super) a: BandedSystem,
    pub(super) b: BandedSystem,
    /// Flat indices (`s * k + i`) of the separator's free variables.
    pub(super) sep: Vec<usize>,
    /// `L_a⁻¹ H_{a,sep}` on `a`'s last `p` frames (compact rows × separator columns).
    pub(super) xa: DMatrix<f64>,
    /// The same for `b`'s last (the original's first after the separator) `p` frames.
    pub(super) xb: DMatrix<f64>,
    /// Cholesky factor of the separator's Schur complement.
    pub(super) c: Option<nalgebra::Cholesky<f64, nalgebra::Dyn>>,
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
        let (bands_a, bands_b) = half_bands(bands, m, nb);
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
        let (xa, xb) = separator_columns(&mut a, &mut b, &sep, (k, t, p, m, nb), lambda, bands);
        let c = if sep.is_empty() {
            None
        } else {
            Some(schur_factor(
                g,
                lambda,
                bands,
                ridge,
                &sep,
                (k, p),
                &xa,
                &xb,
            )?)
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
    pub(super) fn solve(&mut self, rhs: &mut [f64]) {
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

/// The two halves' bands (`bands`: the whole segment's, `t` frames, band `p`): `a` is the
/// leading `m` frames as they stand; `b` the trailing `nb` frames with time reversed (DᵀD
/// is symmetric, so entry (i, i − j) of the reversed block is the original's entry
/// (t − 1 − i + j, t − 1 − i)).
fn half_bands(bands: &[Vec<f64>], m: usize, nb: usize) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let t = bands[0].len();
    let p = bands.len() - 1;
    let bands_a: Vec<Vec<f64>> = bands.iter().map(|b| b[..m].to_vec()).collect();
    let bands_b: Vec<Vec<f64>> = (0..=p)
        .map(|j| {
            (0..nb)
                .map(|i| if i >= j { bands[j][t - 1 - i + j] } else { 0.0 })
                .collect()
        })
        .collect();
    (bands_a, bands_b)
}

/// `X_a = L_a⁻¹ H_{a,sep}` and `X_b = L_b⁻¹ H_{b,sep}`: one column per free separator
/// variable of `sep`, living on each half's `p` frames next to the separator.
fn separator_columns(
    a: &mut BandedSystem,
    b: &mut BandedSystem,
    sep: &[usize],
    (k, t, p, m, nb): (usize, usize, usize, usize, usize),
    lambda: f64,
    bands: &[Vec<f64>],
) -> (DMatrix<f64>, DMatrix<f64>) {
    // H's entry between frames r < c (c − r ≤ p) on one variable: λ·band[c − r][c].
    let coupling = |r: usize, c: usize| lambda * bands[c - r][c];
    let a0 = m - p;
    let a_len = a.fstart[m] - a.fstart[a0];
    let mut xa = DMatrix::zeros(a_len, sep.len());
    let b0 = nb - p;
    let b_len = b.fstart[nb] - b.fstart[b0];
    let mut xb = DMatrix::zeros(b_len, sep.len());
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
    (xa, xb)
}

/// The Cholesky factor of the separator's Schur complement `H_sep − X_aᵀX_a − X_bᵀX_b`
/// (`sep`: its free variables, not empty).
#[allow(clippy::too_many_arguments)]
fn schur_factor(
    g: &DMatrix<f64>,
    lambda: f64,
    bands: &[Vec<f64>],
    ridge: f64,
    sep: &[usize],
    (k, p): (usize, usize),
    xa: &DMatrix<f64>,
    xb: &DMatrix<f64>,
) -> Result<nalgebra::Cholesky<f64, nalgebra::Dyn>> {
    let ns = sep.len();
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
    h -= xa.tr_mul(xa) + xb.tr_mul(xb);
    h.cholesky().ok_or_else(|| {
        Error::unfit("temporal prior: the separator's Schur complement is not positive definite")
    })
}
