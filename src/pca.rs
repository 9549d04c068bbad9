//! Centred principal component analysis through nalgebra's SVD (paper 000, §4.2: every
//! key-shape heuristic works on the PCA projection of the shapes).

use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};

/// A fitted PCA of shapes stored one per column.
#[derive(Debug, Clone)]
pub struct Pca {
    /// Mean shape.
    pub mean: DVector<f64>,
    /// Principal axes as unit columns, largest variance first.
    pub components: DMatrix<f64>,
    /// Variance along each axis (σ² / (frames − 1)).
    pub variances: Vec<f64>,
}

impl Pca {
    /// Fits a centred PCA to the columns of `coords`.
    pub fn fit(coords: &DMatrix<f64>) -> Result<Pca> {
        let (rows, n) = coords.shape();
        if n < 2 {
            return Err(Error::invalid("PCA needs at least 2 frames"));
        }
        let mean = coords.column_mean();
        let mut centred = coords.clone();
        for mut c in centred.column_iter_mut() {
            c -= &mean;
        }
        let svd = centred.svd(true, false);
        let u = svd
            .u
            .ok_or_else(|| Error::invalid("SVD did not return the principal axes"))?;
        let mut order: Vec<usize> = (0..svd.singular_values.len()).collect();
        order.sort_by(|&a, &b| svd.singular_values[b].total_cmp(&svd.singular_values[a]));
        let r = order.len().min(rows);
        let components = DMatrix::from_fn(rows, r, |i, j| u[(i, order[j])]);
        let variances = order[..r]
            .iter()
            .map(|&j| svd.singular_values[j].powi(2) / (n - 1) as f64)
            .collect();
        Ok(Pca {
            mean,
            components,
            variances,
        })
    }

    /// Share of the total variance each axis explains.
    pub fn explained_ratio(&self) -> Vec<f64> {
        let total: f64 = self.variances.iter().sum();
        self.variances
            .iter()
            .map(|v| if total > 0.0 { v / total } else { 0.0 })
            .collect()
    }

    /// Coordinates of each column of `coords` on the first `n` axes (n × frames).
    pub fn project(&self, coords: &DMatrix<f64>, n: usize) -> DMatrix<f64> {
        let n = n.min(self.components.ncols());
        let mut centred = coords.clone();
        for mut c in centred.column_iter_mut() {
            c -= &self.mean;
        }
        self.components.columns(0, n).transpose() * centred
    }
}
