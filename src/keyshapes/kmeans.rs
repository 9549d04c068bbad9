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
/// projection onto `pcs` axes. Two variants:
///
/// * `kmeansN` (`mean: false`): a centre is not a frame an artist can model, so the key
///   shape is the frame nearest each centre (in PCA space). When two centres share a nearest
///   frame, the later one takes its nearest unused frame.
/// * `kmeansN-mean` (`mean: true`): the paper's own choice (§4.2, "the center of mass of
///   each cluster is chosen as a key shape"): each cluster's mean shape in full coordinates,
///   in [`Selection::shapes`], with its size in [`Selection::sizes`]. A frame belongs to the
///   cluster whose centre is nearest in the clustered axes. The nearest frames still come
///   back in `columns`, for reference.
///
/// The centres themselves come back in [`Selection::centres`].
#[derive(Debug, Clone, Copy)]
pub struct KMeans {
    /// Principal components clustered.
    pub pcs: usize,
    /// Seed for the initialisation; the same seed gives the same clusters.
    pub seed: u64,
    /// Key shapes are the clusters' mean shapes, not frames.
    pub mean: bool,
}

impl Heuristic for KMeans {
    fn name(&self) -> String {
        if self.mean {
            format!("kmeans{}-mean", self.pcs)
        } else {
            format!("kmeans{}", self.pcs)
        }
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
        let (shapes, sizes) = if self.mean {
            let (s, n) = cluster_means(an, &centres)?;
            (Some(s), Some(n))
        } else {
            (None, None)
        };
        Ok(Selection {
            columns,
            centres: Some(centres),
            shapes,
            sizes,
        })
    }
}

/// Each cluster's mean shape (full coordinates, one column per centre) and size: a frame
/// belongs to the centre nearest it on the clustered axes (ties to the lower centre).
pub(super) fn cluster_means(
    an: &Analysis,
    centres: &DMatrix<f64>,
) -> Result<(DMatrix<f64>, Vec<usize>)> {
    let (pcs, k) = centres.shape();
    let mut sums = DMatrix::zeros(an.coords.nrows(), k);
    let mut sizes = vec![0usize; k];
    for t in 0..an.frames() {
        let dist = |c: usize| -> f64 {
            (0..pcs)
                .map(|a| (an.proj[(a, t)] - centres[(a, c)]).powi(2))
                .sum()
        };
        let best = (0..k)
            .min_by(|&i, &j| dist(i).total_cmp(&dist(j)).then(i.cmp(&j)))
            .ok_or_else(|| Error::invalid("k-means: no centres"))?;
        let mut col = sums.column_mut(best);
        col += an.coords.column(t);
        sizes[best] += 1;
    }
    for (c, &n) in sizes.iter().enumerate() {
        if n == 0 {
            return Err(Error::invalid(format!(
                "k-means: cluster {c} of {k} has no frames, so it has no mean shape (choose a smaller k)"
            )));
        }
        let mut col = sums.column_mut(c);
        col /= n as f64;
    }
    Ok((sums, sizes))
}
