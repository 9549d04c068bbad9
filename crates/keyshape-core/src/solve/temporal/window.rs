//! The banded factorisation's storage layout, row kernels and a windowed factor's
//! checkpoints.

use crate::error::Error;
use nalgebra::DMatrix;

/// A windowed factor's inputs and checkpoints.
pub(super) struct Redo {
    pub(super) g: DMatrix<f64>,
    pub(super) lambda: f64,
    pub(super) bands: Vec<Vec<f64>>,
    pub(super) ridge: f64,
    /// Rows `jB − p..jB` of every block `j ≥ 1` (B = [`WINDOW_BLOCK`]), block `j`'s at
    /// `ck[at[j − 1]..]`.
    pub(super) ck: Vec<f64>,
    pub(super) at: Vec<usize>,
    /// The other window buffer.
    pub(super) spare: Vec<f64>,
    pub(super) scratch: Scratch,
}

/// What computing a row of `L` reads.
pub(super) struct Inputs<'a> {
    pub(super) g: &'a DMatrix<f64>,
    pub(super) lambda: f64,
    pub(super) bands: &'a [Vec<f64>],
    pub(super) ridge: f64,
    pub(super) free: &'a [u32],
    pub(super) fstart: &'a [usize],
    pub(super) off: &'a [usize],
    pub(super) p: usize,
}

/// The row computation's work space.
#[derive(Default)]
pub(super) struct Scratch {
    pub(super) tmp: Vec<f64>,
    /// The outermost block of the current frame, computed but not stored.
    pub(super) edge: Vec<f64>,
    pub(super) lead: Vec<usize>,
}

impl Scratch {
    pub(super) fn new(k: usize) -> Scratch {
        Scratch {
            tmp: vec![0.0; k * k],
            edge: vec![0.0; k * k],
            lead: vec![0; k],
        }
    }
}

/// `a · b` over the shorter length, in four independent sums so the compiler can vectorise
/// it (a single running sum is a dependency chain it must keep in order).
pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
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
pub(super) fn tri(n: usize) -> usize {
    n * (n + 1) / 2
}

/// Calls `f(x, y)` for every pair with `a[x] == b[y]` (both sorted ascending).
pub(super) fn matches(a: &[u32], b: &[u32], mut f: impl FnMut(usize, usize)) {
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
pub(super) fn solve_lt(d: &[f64], inv: &[f64], u: &mut [f64]) {
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
pub(super) fn solve_l(d: &[f64], inv: &[f64], u: &mut [f64]) {
    for x in 0..u.len() {
        let v = u[x] - dot(&d[tri(x)..tri(x) + x], &u[..x]);
        u[x] = v * inv[x];
    }
}

/// `M ← M L⁻ᵀ` row by row, for `M` with `nc` columns and a packed lower triangle `d` with
/// reciprocal pivots `ic`: row `x` solves `L zᵀ = M[x, :]ᵀ`. A row's leading zeros stay zero
/// (forward substitution), and for order 1 `M` is λ times a selection, so most of each row
/// is skipped.
fn rows_times_lt_inverse(m: &mut [f64], nc: usize, d: &[f64], ic: &[f64]) {
    if nc == 0 {
        return;
    }
    for row in m.chunks_exact_mut(nc) {
        let Some(y0) = row.iter().position(|v| *v != 0.0) else {
            continue;
        };
        for y in y0..nc {
            let v = row[y] - dot(&row[y0..y], &d[tri(y) + y0..tri(y) + y]);
            row[y] = v * ic[y];
        }
    }
}

/// Cholesky in place of the lower triangle of the dense `n × n` row-major `m`, reciprocal
/// pivots into `inv`. Stops at a pivot that is not positive, returning it.
fn cholesky_lower(m: &mut [f64], n: usize, inv: &mut [f64]) -> std::result::Result<(), f64> {
    for x in 0..n {
        for y in 0..=x {
            let v = m[x * n + y] - dot(&m[x * n..x * n + y], &m[y * n..y * n + y]);
            if x == y {
                if !(v > 0.0 && v.is_finite()) {
                    return Err(v);
                }
                m[x * n + x] = v.sqrt();
                inv[x] = 1.0 / m[x * n + x];
            } else {
                m[x * n + y] = v * inv[y];
            }
        }
    }
    Ok(())
}

/// Computes frame `s`'s row of `L` into `l` — which holds the layout from offset `base` on,
/// frames `s − p..s` included — and its reciprocal pivots into `inv` (every frame's).
/// Stops at a pivot that is not positive, returning it.
pub(super) fn compute_row(
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
        // L_{s,c} = M L_{c,c}^{-T}.
        let d = &l[off[c * (p + 1)] - base..][..tri(nc)];
        rows_times_lt_inverse(m, nc, d, &inv[fstart[c]..fstart[c + 1]]);
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
    cholesky_lower(m, ns, &mut inv[fstart[s]..fstart[s + 1]])?;
    let o = off[s * (p + 1)] - base;
    for x in 0..ns {
        l[o + tri(x)..o + tri(x) + x + 1].copy_from_slice(&m[x * ns..x * ns + x + 1]);
    }
    Ok(())
}

/// The error of a pivot `v` at frame `s` that is not positive.
pub(super) fn not_definite(s: usize, v: f64) -> Error {
    Error::unfit(format!(
        "temporal prior: the banded system is not positive definite at frame {s} (pivot {v:e})"
    ))
}

/// Fills the storage layout of a factor of `t` frames (`k` weights each, band `p`) with
/// `fixed` masking weights out: each frame's free indices (`free`, from `fstart[s]`), and
/// where each stored block of `L` starts (`off`: per frame, its diagonal block and its
/// blocks against the `p − 1` frames before it). Returns the length of `L`.
pub(super) fn layout(
    fixed: &[bool],
    (k, t, p): (usize, usize, usize),
    free: &mut Vec<u32>,
    fstart: &mut Vec<usize>,
    off: &mut Vec<usize>,
) -> usize {
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
    total
}
