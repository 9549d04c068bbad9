//! Multiquadric radial-basis-function space transform (paper 004 §2, Eqs. 1–3).

use crate::error::{Error, Result};
use crate::solve::jacobi;
use nalgebra::DMatrix;

/// `F(s) = Σ_i w_i h(‖s − s_i‖)` with `h(r) = sqrt(r² + sc_i²)` and `sc_i` the distance
/// from centre i to its nearest other centre (paper 004 Eq. 1), one weight vector per axis.
#[derive(Debug, Clone)]
pub struct Rbf {
    /// Dimensions of a point (2 or 3).
    pub dims: usize,
    /// Centres `s_i`, flat.
    pub centres: Vec<f64>,
    /// `sc_i²` per centre.
    pub sc2: Vec<f64>,
    /// Weights, N × dims.
    pub weights: DMatrix<f64>,
    /// Condition number of H (σ_max / σ_min).
    pub condition: f64,
}

fn dist2(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

impl Rbf {
    /// Trains on source points `src` → target points `dst` (flat, `dims` per point) by
    /// solving `H W = T` per axis (Eq. 3). H is symmetric but, with these per-centre widths,
    /// not positive definite in general, so it is solved through a (Jacobi) SVD: duplicate
    /// feature points make H singular and are an error naming them; a condition number
    /// above 1e12 is an error too (nearly coincident points), since the weights would be
    /// noise.
    pub fn fit(src: &[f64], dst: &[f64], dims: usize) -> Result<Rbf> {
        let n = src.len() / dims;
        if n == 0 || src.len() != dst.len() || src.len() % dims != 0 {
            return Err(Error::invalid(
                "RBF: source and target feature points differ in count",
            ));
        }
        let p = |i: usize| &src[i * dims..(i + 1) * dims];
        let mut sc2 = vec![f64::INFINITY; n];
        for i in 0..n {
            for j in 0..n {
                if i != j {
                    let d = dist2(p(i), p(j));
                    if d == 0.0 {
                        return Err(Error::unfit(format!(
                            "RBF: feature points {i} and {j} coincide (H is singular)"
                        )));
                    }
                    sc2[i] = sc2[i].min(d);
                }
            }
        }
        if n == 1 {
            sc2[0] = 1.0;
        }
        let h = DMatrix::from_fn(n, n, |j, i| (dist2(p(j), p(i)) + sc2[i]).sqrt());
        let svd = jacobi::svd(&h);
        let smax = svd.s.first().copied().unwrap_or(0.0);
        let smin = svd.s.last().copied().unwrap_or(0.0);
        let condition = if smin > 0.0 {
            smax / smin
        } else {
            f64::INFINITY
        };
        if condition > 1e12 {
            return Err(Error::unfit(format!(
                "RBF: feature points too close together (condition number of H {condition:.1e})"
            )));
        }
        let t = DMatrix::from_fn(n, dims, |j, d| dst[j * dims + d]);
        let sinv = DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(
            n,
            svd.s.iter().map(|s| 1.0 / s),
        ));
        let weights = &svd.v * sinv * svd.u.transpose() * t;
        Ok(Rbf {
            dims,
            centres: src.to_vec(),
            sc2,
            weights,
            condition,
        })
    }

    /// Maps one point.
    pub fn apply_point(&self, x: &[f64], out: &mut [f64]) {
        out.iter_mut().for_each(|v| *v = 0.0);
        for (i, c) in self.centres.chunks(self.dims).enumerate() {
            let h = (dist2(x, c) + self.sc2[i]).sqrt();
            for d in 0..self.dims {
                out[d] += self.weights[(i, d)] * h;
            }
        }
    }

    /// Maps a flat shape (`dims` values per point).
    pub fn apply(&self, shape: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; shape.len()];
        for (x, o) in shape.chunks(self.dims).zip(out.chunks_mut(self.dims)) {
            self.apply_point(x, o);
        }
        out
    }

    /// Maps every column of `shapes`, in parallel, into one new matrix (no copy per column).
    pub fn apply_all(&self, shapes: &DMatrix<f64>) -> DMatrix<f64> {
        use rayon::prelude::*;
        let n = shapes.nrows();
        let mut out = DMatrix::zeros(n, shapes.ncols());
        if n > 0 {
            out.as_mut_slice()
                .par_chunks_mut(n)
                .enumerate()
                .for_each(|(c, col)| {
                    let shape = shapes.column(c);
                    for (x, o) in shape
                        .as_slice()
                        .chunks(self.dims)
                        .zip(col.chunks_mut(self.dims))
                    {
                        self.apply_point(x, o);
                    }
                });
        }
        out
    }
}
