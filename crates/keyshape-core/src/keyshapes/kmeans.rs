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

/// How k-means starts and restarts: the k-means++ start (each centre drawn with
/// probability proportional to its squared distance to the nearest centre so far), with
/// `trials` candidates drawn per centre and the one that most lowers the sum of those
/// distances kept, and `restarts` runs from independent starts, the one with the lowest
/// inertia kept.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Seeding {
    /// Independent starts; the lowest inertia wins.
    pub restarts: usize,
    /// Candidates per centre: `None` for 2 + ⌊ln k⌋ (the greedy k-means++ of Arthur and
    /// Vassilvitskii, scikit-learn's default), `Some(1)` for plain k-means++ (linfa's).
    pub trials: Option<usize>,
}

impl Seeding {
    /// What the lab uses: greedy k-means++, 3 restarts. On the real tracks its inertia is
    /// that of 10 plain k-means++ restarts (linfa's default) to within 1 % on average, for
    /// less than a third of the work (see BENCHMARKS.md, "The Fig. 6 sweep").
    pub const LAB: Seeding = Seeding {
        restarts: 3,
        trials: None,
    };
    /// linfa's own `KMeans::params_with_rng(k, rng)`: 10 plain k-means++ restarts.
    pub const LINFA: Seeding = Seeding {
        restarts: 10,
        trials: Some(1),
    };

    /// Candidates drawn per centre for `k` clusters.
    pub fn trials(&self, k: usize) -> usize {
        self.trials
            .unwrap_or(2 + (k as f64).ln().floor() as usize)
            .max(1)
    }
}

/// k-means with [`Seeding::LAB`]: the centroids (one row per cluster).
pub fn fit(data: &Array2<f64>, k: usize, seed: u64) -> Result<Array2<f64>> {
    fit_with(data, k, seed, Seeding::LAB)
}

/// k-means on the rows of `data`: starts drawn here from a `Xoshiro256Plus` seeded with
/// `seed`, one after another, then each run as a one-run linfa fit (≤ 300 Lloyd
/// iterations, tolerance 1e-6) from its start, the runs in parallel; the first run with the
/// strictly lowest inertia is kept, as linfa keeps it.
///
/// With [`Seeding::LINFA`] this is linfa's own 10-run fit (tested against it): the draws
/// are linfa's (one `WeightedIndex` draw per centre, from the same generator in the same
/// order, over the same squared distances), but each frame keeps its distance to the
/// nearest centre so far, so a start takes `k` passes over the frames instead of linfa's
/// `k²/2`.
pub fn fit_with(data: &Array2<f64>, k: usize, seed: u64, seeding: Seeding) -> Result<Array2<f64>> {
    if seeding.restarts == 0 {
        return Err(Error::bad_setting(
            "restarts",
            seeding.restarts,
            "k-means needs at least one restart",
        ));
    }
    let mut rng = Xoshiro256Plus::seed_from_u64(seed);
    let trials = seeding.trials(k);
    let starts: Vec<Array2<f64>> = (0..seeding.restarts)
        .map(|_| {
            kmeans_plusplus(data, k, trials, &mut rng)
                .map(|rows| data.select(ndarray::Axis(0), &rows))
        })
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
                .map_err(|e| Error::unfit(format!("k-means failed: {e}")))?;
            Ok((model.inertia(), model.centroids().clone()))
        })
        .collect::<Result<_>>()?;
    let mut best: Option<(f64, Array2<f64>)> = None;
    for (inertia, c) in runs {
        if best.as_ref().is_none_or(|(b, _)| inertia < *b) {
            best = Some((inertia, c));
        }
    }
    best.map(|(_, c)| c)
        .ok_or_else(|| Error::unfit("k-means: no run converged to a finite inertia"))
}

/// Squared distance from row `centre` to row `t` of `data`, summed over the axes in order
/// (as linfa's `L2Dist::rdistance` sums it).
fn sq_dist(data: &Array2<f64>, centre: usize, t: usize) -> f64 {
    let (c, r) = (data.row(centre), data.row(t));
    let mut dist = 0.0;
    for a in 0..data.ncols() {
        let diff = c[a] - r[a];
        dist += diff * diff;
    }
    dist
}

/// One k-means++ start (rows of `data` as centres): the first centre uniformly (a
/// `WeightedIndex` over ones); for each next one, `trials` candidates drawn with
/// probability proportional to their squared distance to the nearest centre so far, and
/// the candidate leaving the lowest sum of those distances kept (the first on a tie). When
/// every distance is 0 the centre is frame 0, without a draw, as in linfa. With one trial
/// this is linfa's k-means++, draw for draw.
pub fn kmeans_plusplus(
    data: &Array2<f64>,
    k: usize,
    trials: usize,
    rng: &mut Xoshiro256Plus,
) -> Result<Vec<usize>> {
    let n = data.nrows();
    let first = WeightedIndex::new(std::iter::repeat_n(1.0f64, n))
        .map_err(|e| Error::unfit(format!("k-means: {e}")))?
        .sample(rng);
    let mut chosen = vec![first];
    let mut nearest: Vec<f64> = (0..n).map(|t| sq_dist(data, first, t)).collect();
    let (mut trial, mut kept) = (vec![0.0; n], vec![0.0; n]);
    for _ in 1..k {
        let Ok(w) = WeightedIndex::new(nearest.iter()) else {
            chosen.push(0);
            continue;
        };
        let mut best: Option<(f64, usize)> = None;
        for _ in 0..trials.max(1) {
            let cand = w.sample(rng);
            let mut pot = 0.0;
            for (t, (x, &near)) in trial.iter_mut().zip(&nearest).enumerate() {
                *x = near.min(sq_dist(data, cand, t));
                pot += *x;
            }
            if best.is_none_or(|(b, _)| pot < b) {
                best = Some((pot, cand));
                std::mem::swap(&mut kept, &mut trial);
            }
        }
        let Some((_, cand)) = best else {
            return Err(Error::unfit("k-means++: no candidate drawn"));
        };
        std::mem::swap(&mut nearest, &mut kept);
        chosen.push(cand);
    }
    Ok(chosen)
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
    /// Starts and restarts ([`Seeding::LAB`] unless a benchmark compares them).
    pub seeding: Seeding,
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
        let centroids = fit_with(&data, k, self.seed, self.seeding)?;
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
            return Err(Error::unfit(format!(
                "k-means: cluster {c} of {k} has no frames, so it has no mean shape (choose a smaller k)"
            )));
        }
        let mut col = sums.column_mut(c);
        col /= n as f64;
    }
    Ok((sums, sizes))
}
