//! Centred principal component analysis (paper 000, §4.2: every key-shape heuristic works
//! on the PCA projection of the shapes).
//!
//! Computed from the symmetric eigendecomposition of the smaller of the two Gram matrices
//! (`X Xᵀ`, coordinates², or `XᵀX`, frames²) of the centred data X. On the 1,008-frame,
//! 468-point d6 track that took 0.44 s against 1.2 s for nalgebra's full SVD, with the same
//! leading variances to 15 digits; nalgebra's SVD is also avoided for its accuracy problems
//! on small matrices (see `solve::jacobi`).

use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector, SymmetricEigen};

/// A fitted PCA of shapes stored one per column.
#[derive(Debug, Clone)]
pub struct Pca {
    /// Mean shape.
    pub mean: DVector<f64>,
    /// Principal axes as unit columns, largest variance first (only axes with variance).
    pub components: DMatrix<f64>,
    /// Variance along each axis (eigenvalue / (frames − 1)).
    pub variances: Vec<f64>,
    /// Total variance (trace of the covariance), for explained-variance ratios.
    pub total_variance: f64,
}

/// The column mean and the columns minus it.
fn centre(coords: &DMatrix<f64>) -> (DVector<f64>, DMatrix<f64>) {
    let mean = coords.column_mean();
    let mut x = coords.clone();
    for mut c in x.column_iter_mut() {
        c -= &mean;
    }
    (mean, x)
}

impl Pca {
    /// Fits a centred PCA to the columns of `coords`.
    pub fn fit(coords: &DMatrix<f64>) -> Result<Pca> {
        let (rows, n) = coords.shape();
        if n < 2 {
            return Err(Error::unfit("PCA needs at least 2 frames"));
        }
        let small_side = rows <= n;
        let denom = (n - 1) as f64;
        // With fewer coordinates than frames (long tracks), X Xᵀ is summed over blocks of
        // centred columns, never holding a centred copy of them all; otherwise the frames'
        // XᵀX needs the centred copy, which is then small.
        let (mean, x) = if small_side {
            (coords.column_mean(), DMatrix::zeros(0, 0))
        } else {
            centre(coords)
        };
        let (gram, total_variance) = if small_side {
            let mut g = DMatrix::<f64>::zeros(rows, rows);
            let mut total = 0.0;
            const BLOCK: usize = 4096;
            for start in (0..n).step_by(BLOCK) {
                let w = BLOCK.min(n - start);
                let mut b = coords.columns(start, w).clone_owned();
                for mut c in b.column_iter_mut() {
                    c -= &mean;
                }
                total += b.norm_squared();
                g += &b * b.transpose();
            }
            (g, total / denom)
        } else {
            let t = x.norm_squared() / denom;
            (x.transpose() * &x, t)
        };
        Ok(Pca::from_gram(
            gram,
            mean,
            total_variance,
            (rows, n),
            (!small_side).then_some(&x),
        ))
    }

    /// The full PCA of `n` columns of `rows` values each, made block by block by
    /// `block(start, width)` (columns `start..start + width`) and never held together: what
    /// [`Pca::fit`] gives for the matrix of those columns, bit for bit (the same blocks of
    /// 4,096 columns, the same sums in the same order). For data generated on the fly,
    /// such as paper 002's region training set (four shapes per frame). Needs `rows ≤ n`.
    pub fn fit_blocks(
        rows: usize,
        n: usize,
        block: &dyn Fn(usize, usize) -> DMatrix<f64>,
    ) -> Result<Pca> {
        if n < 2 {
            return Err(Error::unfit("PCA needs at least 2 frames"));
        }
        if rows > n {
            return Err(Error::invalid(format!(
                "a block-wise PCA needs at least as many columns as values per column ({n} < {rows})"
            )));
        }
        const BLOCK: usize = 4096;
        // The mean as `column_mean` adds it: a·col + out per column, in order.
        let denom_mean = 1.0 / n as f64;
        let mut mean = DVector::<f64>::zeros(rows);
        for start in (0..n).step_by(BLOCK) {
            let b = block(start, BLOCK.min(n - start));
            for c in b.column_iter() {
                mean.axpy(denom_mean, &c, 1.0);
            }
        }
        let mut g = DMatrix::<f64>::zeros(rows, rows);
        let mut total = 0.0;
        for start in (0..n).step_by(BLOCK) {
            let mut b = block(start, BLOCK.min(n - start));
            for mut c in b.column_iter_mut() {
                c -= &mean;
            }
            total += b.norm_squared();
            g += &b * b.transpose();
        }
        let denom = (n - 1) as f64;
        Ok(Pca::from_gram(g, mean, total / denom, (rows, n), None))
    }

    /// Axes from the Gram matrix of the centred data: `X Xᵀ` (rows × rows), or `XᵀX`
    /// (n × n) with `x` the centred data, whose axes are then `X v`.
    fn from_gram(
        gram: DMatrix<f64>,
        mean: DVector<f64>,
        total_variance: f64,
        (rows, n): (usize, usize),
        x: Option<&DMatrix<f64>>,
    ) -> Pca {
        let denom = (n - 1) as f64;
        let eig = SymmetricEigen::new(gram);
        let mut order: Vec<usize> = (0..eig.eigenvalues.len()).collect();
        order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
        let top = eig.eigenvalues[order[0]].max(0.0);
        let keep: Vec<usize> = order
            .into_iter()
            .filter(|&j| eig.eigenvalues[j] > top * 1e-13 * rows.max(n) as f64)
            .collect();
        let mut components = DMatrix::zeros(rows, keep.len());
        for (c, &j) in keep.iter().enumerate() {
            let v = eig.eigenvectors.column(j);
            let mut axis = match x {
                None => v.clone_owned(),
                Some(x) => x * v,
            };
            let norm = axis.norm();
            if norm > 0.0 {
                axis /= norm;
            }
            // Deterministic sign: the largest-magnitude coordinate is positive.
            let imax = axis.iamax();
            if axis[imax] < 0.0 {
                axis = -axis;
            }
            components.set_column(c, &axis);
        }
        let variances = keep.iter().map(|&j| eig.eigenvalues[j] / denom).collect();
        Pca {
            mean,
            components,
            variances,
            total_variance,
        }
    }

    /// The leading `r` axes only, by block subspace iteration (block of r + 12 vectors,
    /// Householder re-orthonormalisation, Rayleigh–Ritz) on the centred data, never forming
    /// a covariance matrix. Stops when every kept pair has `‖C v − λ v‖ ≤ 1e-10 · λ₁`; if 100
    /// rounds do not get there, or the problem is small, it falls back to [`Pca::fit`].
    /// Much faster than the full decomposition when r is a small part of the rank; with
    /// at most 8 (r + 12) coordinates per frame the full one is used (it is then cheaper).
    pub fn fit_leading(coords: &DMatrix<f64>, r: usize) -> Result<Pca> {
        let (rows, n) = coords.shape();
        let r = r.min(rows.min(n));
        let l = r + 12;
        // The full decomposition costs rows² · n (plus rows³), one round here 2 · rows · n · l:
        // with few coordinates (68 points: 136) the full fit is cheaper than two rounds,
        // and it does not depend on how well the spectrum separates.
        if n < 2 || rows.min(n) <= 2 * l || (rows <= n && rows <= 8 * l) {
            let mut p = Pca::fit(coords)?;
            p.truncate(r);
            return Ok(p);
        }
        // Centred implicitly (X = Q − μ1ᵀ), so no copy of the coordinates is made:
        // X v = Q v − μ (1ᵀ v) and Xᵀ u = Qᵀ u − 1 (μᵀ u).
        let mean = coords.column_mean();
        let denom = (n - 1) as f64;
        let total_variance = coords
            .column_iter()
            .map(|c| (c - &mean).norm_squared())
            .sum::<f64>()
            / denom;
        let x_times = |v: &DMatrix<f64>| -> DMatrix<f64> {
            let mut out = coords * v;
            for (j, s) in v.row_sum().iter().enumerate() {
                out.column_mut(j).axpy(-s, &mean, 1.0);
            }
            out
        };
        let xt_times = |u: &DMatrix<f64>| -> DMatrix<f64> {
            // (uᵀQ)ᵀ: a plain product runs the blocked kernel, which tr_mul does not.
            let mut out = (u.transpose() * coords).transpose();
            let mu = u.tr_mul(&mean);
            for (j, s) in mu.iter().enumerate() {
                out.column_mut(j).add_scalar_mut(-s);
            }
            out
        };
        // Deterministic start: a fixed pseudo-random block (splitmix64).
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut start = DMatrix::<f64>::zeros(n, l);
        for v in start.iter_mut() {
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            *v = ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        }
        let mut q = x_times(&start).qr().q();
        for _ in 0..100 {
            let z = x_times(&xt_times(&q)); // C·Q (times n − 1)
            let b = q.tr_mul(&z);
            let b = (&b + b.transpose()) * 0.5;
            let eig = SymmetricEigen::new(b);
            let mut order: Vec<usize> = (0..l).collect();
            order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
            let top = eig.eigenvalues[order[0]].max(f64::MIN_POSITIVE);
            let keep: Vec<usize> = order
                .iter()
                .copied()
                .take(r)
                .filter(|&j| eig.eigenvalues[j] > top * 1e-13 * rows.max(n) as f64)
                .collect();
            let u = eig.eigenvectors.select_columns(&keep);
            let v = &q * &u;
            let zv = &z * &u;
            let converged = keep.iter().enumerate().all(|(c, &j)| {
                (zv.column(c) - v.column(c) * eig.eigenvalues[j]).norm() <= 1e-10 * top
            });
            if converged {
                let mut components = v;
                for mut axis in components.column_iter_mut() {
                    let imax = axis.iamax();
                    if axis[imax] < 0.0 {
                        axis.neg_mut();
                    }
                }
                let variances = keep.iter().map(|&j| eig.eigenvalues[j] / denom).collect();
                return Ok(Pca {
                    mean,
                    components,
                    variances,
                    total_variance,
                });
            }
            q = z.qr().q();
        }
        let mut p = Pca::fit(coords)?;
        p.truncate(r);
        Ok(p)
    }

    /// Keeps the leading `r` axes.
    pub fn truncate(&mut self, r: usize) {
        let r = r.min(self.components.ncols());
        self.components = self.components.columns(0, r).clone_owned();
        self.variances.truncate(r);
    }

    /// Share of the total variance each axis explains.
    pub fn explained_ratio(&self) -> Vec<f64> {
        self.variances
            .iter()
            .map(|v| {
                if self.total_variance > 0.0 {
                    v / self.total_variance
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// Coordinates of each column of `coords` on the first `n` axes (n × frames).
    pub fn project(&self, coords: &DMatrix<f64>, n: usize) -> DMatrix<f64> {
        let n = n.min(self.components.ncols());
        // Cᵀ(Q − μ1ᵀ) = CᵀQ − (Cᵀμ)1ᵀ: no centred copy of the coordinates.
        let c = self.components.columns(0, n);
        let mut p = c.transpose() * coords;
        let cm = c.tr_mul(&self.mean);
        for mut col in p.column_iter_mut() {
            col -= &cm;
        }
        p
    }
}
