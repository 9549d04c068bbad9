//! The parts of one Gauss–Newton step of camera and weights
//! ([`FrameSolver::step`](super::FrameSolver::step)): the camera's normal equations, the
//! coupling of camera and weights pulled back onto the rig's coordinates, and the Schur
//! complement that eliminates the camera.

use super::blocks::dot;
use super::Camera;
use nalgebra::DMatrix;

/// The camera's normal equations and the pulled-back rows of one Gauss–Newton step: with
/// `x` the posed rig and `neutral` its neutral (rig coordinates), `u` the tracked points,
/// `lw` the landmark weights and `wz` a depth row's weight, `dres` the depth residuals (a
/// third row per landmark and a seventh parameter, `np` = 7, when given). Returns `Hcc`,
/// `bc`, and `v`: per camera parameter and for the right side, each landmark's row pulled
/// back through `s R` onto the rig's coordinates (`np + 1` blocks of `3 n`).
pub(super) fn camera_rows(
    cam: &Camera,
    x: &[[f64; 3]],
    neutral: &[[f64; 3]],
    u: &[[f64; 2]],
    (lw, wz): (&[f64], f64),
    dres: Option<&[f64]>,
    np: usize,
) -> (DMatrix<f64>, nalgebra::DVector<f64>, Vec<f64>) {
    let n = u.len();
    let r = &cam.r;
    let rows = if dres.is_some() { 3 } else { 2 };
    let mut hcc = DMatrix::<f64>::zeros(np, np);
    let mut bc = nalgebra::DVector::<f64>::zeros(np);
    let len = 3 * n;
    let mut v = vec![0.0; (np + 1) * len];
    for i in 0..n {
        let p = x[i];
        let e = cam.project(&neutral[i]);
        for row in 0..rows {
            let (rhs, wi) = match row {
                0 | 1 => (u[i][row] - e[row], lw[i]),
                _ => (dres.map_or(0.0, |d| d[i]), wz * lw[i]),
            };
            let rr = [r[(row, 0)], r[(row, 1)], r[(row, 2)]];
            // ∂/∂ω of s·rr·(I + [ω]×)p = s·rr·(ω × p) = s·(p × rr)·ω.
            let c = [
                p[1] * rr[2] - p[2] * rr[1],
                p[2] * rr[0] - p[0] * rr[2],
                p[0] * rr[1] - p[1] * rr[0],
            ];
            let proj = rr[0] * p[0] + rr[1] * p[1] + rr[2] * p[2];
            let j = [
                proj,
                cam.s * c[0],
                cam.s * c[1],
                cam.s * c[2],
                if row == 0 { 1.0 } else { 0.0 },
                if row == 1 { 1.0 } else { 0.0 },
                if row == 2 { 1.0 } else { 0.0 },
            ];
            for a in 0..np {
                bc[a] += wi * j[a] * rhs;
                for b in 0..np {
                    hcc[(a, b)] += wi * j[a] * j[b];
                }
                let f = wi * cam.s * j[a];
                if f != 0.0 {
                    let at = a * len + 3 * i;
                    for (o, q) in v[at..at + 3].iter_mut().zip(&rr) {
                        *o += f * q;
                    }
                }
            }
            let f = wi * cam.s * rhs;
            let at = np * len + 3 * i;
            for (o, q) in v[at..at + 3].iter_mut().zip(&rr) {
                *o += f * q;
            }
        }
    }
    (hcc, bc, v)
}

/// `Hcw = Jᵀ W A` and `bw = Aᵀ W r` from the pulled-back rows `v` (see [`camera_rows`]),
/// each met with every free shape's deltas `d` (`m` blocks of `len`) in one contiguous dot
/// product, never forming `A`.
pub(super) fn pull_back(
    d: &[f64],
    v: &[f64],
    m: usize,
    np: usize,
    len: usize,
) -> (DMatrix<f64>, Vec<f64>) {
    let mut hcw_flat = vec![0.0; np * m];
    let mut bw = vec![0.0; m];
    for jj in 0..m {
        let dj = &d[jj * len..(jj + 1) * len];
        for p in 0..np {
            hcw_flat[p * m + jj] = dot(&v[p * len..(p + 1) * len], dj);
        }
        bw[jj] = dot(&v[np * len..(np + 1) * len], dj);
    }
    let hcw = DMatrix::from_row_slice(np, m, &hcw_flat);
    (hcw, bw)
}

/// The Schur complement of the camera block: `G ← G − Hcwᵀ Hcc⁻¹ Hcw` (`g`, m × m row
/// major) and `bw ← bw − Hcwᵀ Hcc⁻¹ bc`.
pub(super) fn schur_complement(
    hinv: &DMatrix<f64>,
    hcw: &DMatrix<f64>,
    bc: &nalgebra::DVector<f64>,
    g: &mut [f64],
    bw: &mut [f64],
) {
    let m = hcw.ncols();
    let np = hcw.nrows();
    // Schur complement: G' = Hww − Hcwᵀ Hcc⁻¹ Hcw, b' = bw − Hcwᵀ Hcc⁻¹ bc.
    let t = hinv * hcw; // np × m
    let tb = hinv * bc;
    for p in 0..m {
        for q in 0..m {
            let mut v = 0.0;
            for c in 0..np {
                v += hcw[(c, p)] * t[(c, q)];
            }
            g[p * m + q] -= v;
        }
        let mut v = 0.0;
        for c in 0..np {
            v += hcw[(c, p)] * tb[c];
        }
        bw[p] -= v;
    }
}
