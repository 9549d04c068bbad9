//! The per-frame Gram blocks of a rig, reused by every frame, and a frame of the track as
//! image points (and depths).

use crate::camera::Camera;
use nalgebra::DMatrix;

/// The per-frame Gram blocks `Σᵢ D_{k,i,a} D_{l,i,b}` of a rig, reused by every frame.
pub(crate) struct Blocks {
    pub(crate) k: usize,
    /// (a, a) blocks, then (a, b) + (b, a) for a < b: (0,1), (0,2), (1,2).
    pub(crate) g: [Vec<f64>; 6],
    /// Flat deltas, k × (68·3), row-major.
    pub(crate) d: Vec<f64>,
    /// Per landmark, the weight of its squared error.
    pub(crate) lw: Vec<f64>,
}

impl Blocks {
    /// `lw`: per landmark, the weight of its squared error.
    pub(crate) fn new(deltas: &[Vec<[f64; 3]>], lw: &[f64]) -> Blocks {
        let k = deltas.len();
        let n = deltas.first().map_or(0, Vec::len);
        let mut d = vec![0.0; k * n * 3];
        for (s, ds) in deltas.iter().enumerate() {
            for (i, o) in ds.iter().enumerate() {
                d[s * n * 3 + i * 3..s * n * 3 + i * 3 + 3].copy_from_slice(o);
            }
        }
        let pair = |a: usize, b: usize| {
            let mut m = vec![0.0; k * k];
            for p in 0..k {
                for q in 0..k {
                    let mut v = 0.0;
                    for (i, wi) in lw.iter().enumerate().take(n) {
                        v += wi * d[p * n * 3 + i * 3 + a] * d[q * n * 3 + i * 3 + b];
                    }
                    m[p * k + q] = v;
                }
            }
            m
        };
        let sym = |a: usize, b: usize| {
            let (x, y) = (pair(a, b), pair(b, a));
            x.iter().zip(&y).map(|(u, v)| u + v).collect::<Vec<f64>>()
        };
        Blocks {
            k,
            g: [
                pair(0, 0),
                pair(1, 1),
                pair(2, 2),
                sym(0, 1),
                sym(0, 2),
                sym(1, 2),
            ],
            d,
            lw: lw.to_vec(),
        }
    }

    /// `AᵀWA` for camera `c`: `s² Σ M_ab G^{ab}` with `M = R₂ᵀ R₂ + wz r₃ r₃ᵀ` (`wz` the
    /// weight of the depth rows, 0 for a 2-D track).
    pub(crate) fn gram(&self, c: &Camera, wz: f64, out: &mut [f64]) {
        let r = &c.r;
        let m = |a: usize, b: usize| {
            r[(0, a)] * r[(0, b)] + r[(1, a)] * r[(1, b)] + wz * r[(2, a)] * r[(2, b)]
        };
        let coef = [m(0, 0), m(1, 1), m(2, 2), m(0, 1), m(0, 2), m(1, 2)];
        let s2 = c.s * c.s;
        let f = coef.map(|cf| s2 * cf);
        let [g0, g1, g2, g3, g4, g5] = &self.g;
        for (i, o) in out.iter_mut().enumerate() {
            *o = f[0] * g0[i]
                + f[1] * g1[i]
                + f[2] * g2[i]
                + f[3] * g3[i]
                + f[4] * g4[i]
                + f[5] * g5[i];
        }
    }

    /// `AᵀWr` for camera `c` and per-landmark image residuals `res` (y up), with the depth
    /// residuals `dres` weighted by `wz` when the track has depth.
    pub(crate) fn rhs(
        &self,
        c: &Camera,
        res: &[[f64; 2]],
        dres: Option<(&[f64], f64)>,
        out: &mut [f64],
    ) {
        let n = res.len();
        let r = &c.r;
        let mut v = vec![0.0; n * 3];
        for (i, e) in res.iter().enumerate() {
            let ez = dres.map_or(0.0, |(d, wz)| wz * d[i]);
            for a in 0..3 {
                v[i * 3 + a] =
                    self.lw[i] * c.s * (r[(0, a)] * e[0] + r[(1, a)] * e[1] + r[(2, a)] * ez);
            }
        }
        for (p, o) in out.iter_mut().enumerate().take(self.k) {
            *o = dot(&self.d[p * n * 3..(p + 1) * n * 3], &v);
        }
    }
}

/// `Σ aᵢ bᵢ` over equal-length slices, in four running sums (which the compiler keeps in
/// vector registers; one running sum would serialise every addition).
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    let mut acc = [0.0; 4];
    for (x, y) in ca.zip(cb) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// Frame `f` of a depth track (one row per landmark, towards the viewer), if there is one.
pub(crate) fn frame_depth(depth: Option<&DMatrix<f64>>, f: usize) -> Option<Vec<f64>> {
    depth.map(|d| d.column(f).iter().copied().collect())
}

/// The track's frame `f` as image points with y up.
pub(crate) fn frame_points(track: &DMatrix<f64>, f: usize) -> Vec<[f64; 2]> {
    (0..track.nrows() / 2)
        .map(|i| [track[(2 * i, f)], -track[(2 * i + 1, f)]])
        .collect()
}
