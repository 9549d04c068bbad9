//! Clustering (paper 000 §4.2): k-means on the first 2 or 3 principal components.

use super::{Analysis, Heuristic, Selection};
use crate::error::{Error, Result};
use linfa::prelude::*;
use linfa_clustering::{KMeans as LinfaKMeans, KMeansInit};
use nalgebra::DMatrix;
use ndarray::Array2;
use rand::distributions::{Distribution, WeightedIndex};
use rand::SeedableRng;
use rand_xoshiro::Xoshiro256Plus;
use rayon::prelude::*;

/// Restarts of k-means; the best (lowest within-cluster sum of squares) is kept.
pub const RESTARTS: usize = 10;

/// linfa's k-means with [`RESTARTS`] k-means++ starts, ≤ 300 Lloyd iterations and a 1e-6
/// tolerance: the centroids (one row per cluster) of the run with the lowest inertia.
///
/// This is exactly `KMeans::params_with_rng(k, Xoshiro256Plus::seed_from_u64(seed))
/// .n_runs(10)` (tested bit for bit against it), with two differences in how it gets there:
///
/// * the k-means++ starts are drawn here, keeping each frame's distance to its nearest
///   centre chosen so far: `k` passes over the frames instead of linfa's `k²/2` (it
///   recomputes every distance to every centre for each new one). The draws are the same
///   (one `WeightedIndex` draw per centre, from the same generator in the same order, over
///   the same squared distances), so the starts are too;
/// * the 10 restarts then run in parallel, each as a one-run linfa fit from its start.
pub fn fit(data: &Array2<f64>, k: usize, seed: u64) -> Result<Array2<f64>> {
    let mut rng = Xoshiro256Plus::seed_from_u64(seed);
    let starts: Vec<Array2<f64>> = (0..RESTARTS)
        .map(|_| kmeans_plusplus(data, k, &mut rng))
        .collect::<Result<_>>()?;
    let dataset = DatasetBase::from(data.view());
    let runs: Vec<(f64, Array2<f64>)> = starts
        .into_par_iter()
        .map(|start| {
            let model = LinfaKMeans::params_with_rng(k, Xoshiro256Plus::seed_from_u64(seed))
                .n_runs(1)
                .max_n_iterations(300)
                .tolerance(1e-6)
                .init_method(KMeansInit::Precomputed(start))
                .fit(&dataset)
                .map_err(|e| Error::invalid(format!("k-means failed: {e}")))?;
            Ok((model.inertia(), model.centroids().clone()))
        })
        .collect::<Result<_>>()?;
    // linfa keeps the first run with the strictly lowest inertia.
    let mut best: Option<(f64, Array2<f64>)> = None;
    for (inertia, c) in runs {
        if best.as_ref().is_none_or(|(b, _)| inertia < *b) {
            best = Some((inertia, c));
        }
    }
    best.map(|(_, c)| c)
        .ok_or_else(|| Error::invalid("k-means: no run converged to a finite inertia"))
}

/// One k-means++ start, drawn as linfa draws it: the first centre uniformly (a
/// `WeightedIndex` over ones), each next one with probability proportional to its squared
/// distance to the nearest centre so far (frame 0 when every distance is 0, without a draw).
fn kmeans_plusplus(data: &Array2<f64>, k: usize, rng: &mut Xoshiro256Plus) -> Result<Array2<f64>> {
    let (n, d) = data.dim();
    let mut centres = Array2::zeros((k, d));
    let first = WeightedIndex::new(std::iter::repeat_n(1.0f64, n))
        .map_err(|e| Error::invalid(format!("k-means: {e}")))?
        .sample(rng);
    centres.row_mut(0).assign(&data.row(first));
    let mut nearest = vec![f64::INFINITY; n];
    for c in 1..k {
        let centre = centres.row(c - 1);
        for (t, best) in nearest.iter_mut().enumerate() {
            let row = data.row(t);
            let mut dist = 0.0;
            for a in 0..d {
                let diff = centre[a] - row[a];
                dist += diff * diff;
            }
            if dist < *best {
                *best = dist;
            }
        }
        let next = WeightedIndex::new(nearest.iter())
            .map(|w| w.sample(rng))
            .unwrap_or(0);
        centres.row_mut(c).assign(&data.row(next));
    }
    Ok(centres)
}

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
        let centroids = fit(&data, k, self.seed)?;
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
