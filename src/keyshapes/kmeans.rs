//! Clustering (paper 000 §4.2): k-means on the first 2 or 3 principal components.

use super::{Analysis, Heuristic, Selection};
use crate::error::{Error, Result};
use linfa::prelude::*;
use linfa_clustering::KMeans as LinfaKMeans;
use nalgebra::DMatrix;
use ndarray::Array2;
use rand::SeedableRng;
use rand_xoshiro::Xoshiro256Plus;

/// k-means (linfa-clustering, k-means++ start, 10 seeded runs, ≤ 300 iterations) on the
/// projection onto `pcs` axes. The paper takes the cluster centres as key shapes, but a
/// centre is not a frame an artist can model; the key shape is the frame nearest each
/// centre (in PCA space). When two centres share a nearest frame, the later one takes its
/// nearest unused frame. The centres themselves come back in [`Selection::centres`].
#[derive(Debug, Clone, Copy)]
pub struct KMeans {
    /// Principal components clustered.
    pub pcs: usize,
    /// Seed for the initialisation; the same seed gives the same clusters.
    pub seed: u64,
}

impl Heuristic for KMeans {
    fn name(&self) -> String {
        format!("kmeans{}", self.pcs)
    }

    fn select(&self, an: &Analysis, k: usize) -> Result<Selection> {
        an.check_k(k)?;
        an.need_axes(self.pcs, &self.name())?;
        let n = an.frames();
        let data = Array2::from_shape_fn((n, self.pcs), |(t, a)| an.proj[(a, t)]);
        let rng = Xoshiro256Plus::seed_from_u64(self.seed);
        let model = LinfaKMeans::params_with_rng(k, rng)
            .n_runs(10)
            .max_n_iterations(300)
            .tolerance(1e-6)
            .fit(&DatasetBase::from(data.clone()))
            .map_err(|e| Error::invalid(format!("k-means failed: {e}")))?;
        let centroids = model.centroids();
        let mut taken = vec![false; n];
        let mut columns = Vec::with_capacity(k);
        for c in 0..k {
            let dist = |t: usize| -> f64 {
                (0..self.pcs)
                    .map(|a| (data[(t, a)] - centroids[(c, a)]).powi(2))
                    .sum()
            };
            let best = (0..n)
                .filter(|&t| !taken[t])
                .min_by(|&i, &j| dist(i).total_cmp(&dist(j)).then(i.cmp(&j)))
                .ok_or_else(|| Error::invalid("k-means: more centres than frames"))?;
            taken[best] = true;
            columns.push(best);
        }
        let centres = DMatrix::from_fn(self.pcs, k, |a, c| centroids[(c, a)]);
        Ok(Selection {
            columns,
            centres: Some(centres),
        })
    }
}
