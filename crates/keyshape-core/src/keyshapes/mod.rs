//! Key-shape selection (paper 000 §4.2): which frames of the sequence to use as key shapes.
//!
//! Every heuristic works on the PCA projection of the (aligned) shapes and returns frame
//! columns of the sequence, since an artist must model each key shape. One trait,
//! [`Heuristic`], one result type, [`Selection`]; [`Method`] names them for the CLI and
//! experiment files. Reconstruction error (paper 000 Eq. 5) of a key set is evaluated from
//! the frames' Gram matrix `QᵀQ` ([`Analysis::error`]), so trying many key sets costs
//! k × k and k × frames work each, not a pass over the shapes.

pub mod curves;
mod greedy;
mod hull;
pub mod kmeans;
mod random;
mod spread;

pub use greedy::{greedy_gram, greedy_ls_feature_space, greedy_path, greedy_subsampled, Greedy};
pub use hull::Hull;
pub use kmeans::KMeans;
pub use random::Random;
pub use spread::Spread;

use crate::error::{setting, Error, Result};
use crate::pca::Pca;
use crate::solve::active_set::Gram;
use crate::solve::{active_set_from_gram, lstsq, Solver};
use nalgebra::DMatrix;
use std::collections::HashSet;
use std::sync::OnceLock;

/// A 128-bit digest of the bits of `v`: two SipHash passes with different keys.
fn digest(v: &[f64]) -> (u64, u64) {
    use std::hash::{Hash, Hasher};
    let mut a = std::collections::hash_map::DefaultHasher::new();
    let mut b = std::collections::hash_map::DefaultHasher::new();
    0x5bd1_e995_u64.hash(&mut b);
    for x in v {
        let bits = x.to_bits();
        bits.hash(&mut a);
        bits.hash(&mut b);
    }
    (a.finish(), b.finish())
}

/// Largest sequence for which the frames' Gram matrix (frames² values) is formed; longer
/// sequences evaluate errors from the shapes directly, and `greedy` works without it
/// ([`greedy_path`]).
pub const GRAM_LIMIT: usize = 6000;

/// Key shapes chosen: frames of the sequence, or (`kmeansN-mean`) shapes that are not frames.
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// Column indices of the chosen frames (into the analysed sequence), in choice order.
    /// For `kmeansN-mean`, the frame nearest each cluster centre (for reference only: the
    /// key shapes are `shapes`).
    pub columns: Vec<usize>,
    /// k-means only: the cluster centres in PCA coordinates (pcs × k), which are not frames.
    pub centres: Option<DMatrix<f64>>,
    /// `kmeansN-mean` only: the key shapes themselves, each cluster's mean shape in full
    /// coordinates (paper 000 §4.2's "center of mass"), one per column.
    pub shapes: Option<DMatrix<f64>>,
    /// `kmeansN-mean` only: frames in each cluster.
    pub sizes: Option<Vec<usize>>,
}

impl Selection {
    /// Key shapes that are frames.
    pub fn frames(columns: Vec<usize>) -> Selection {
        Selection {
            columns,
            centres: None,
            shapes: None,
            sizes: None,
        }
    }

    /// The key frames, or an error naming `method` when its key shapes are not frames
    /// (`what` says what needed frames).
    pub fn key_frames(&self, method: &Method, what: &str) -> Result<&[usize]> {
        if self.shapes.is_some() {
            return Err(Error::invalid(format!(
                "{method} keys are cluster mean shapes, not frames, and {what} needs key frames (an artist redraws frames); use {} for the frame nearest each centre",
                method.name().trim_end_matches("-mean")
            )));
        }
        Ok(&self.columns)
    }

    /// The key shapes of `an` as columns (dims · points × k).
    pub fn key_shapes(&self, an: &Analysis) -> DMatrix<f64> {
        match &self.shapes {
            Some(s) => s.clone(),
            None => an.coords.select_columns(&self.columns),
        }
    }
}

/// A key-shape heuristic.
pub trait Heuristic {
    /// Name as the CLI writes it (`spread`, `kmeans2`, …).
    fn name(&self) -> String;
    /// Chooses `k` key frames. Heuristics whose k is fixed by the data (`hull`) ignore it.
    fn select(&self, an: &Analysis, k: usize) -> Result<Selection>;
}

/// The heuristics by name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Maximum spread along principal components.
    Spread,
    /// k-means on the first `pcs` principal components.
    KMeans {
        /// Number of principal components clustered.
        pcs: usize,
        /// Key shapes are the clusters' mean shapes (paper 000's "center of mass",
        /// `kmeansN-mean`) instead of the frames nearest the centres (`kmeansN`).
        mean: bool,
    },
    /// Frames on the convex hull of the first two principal components.
    Hull,
    /// Forward selection that most lowers Eq. (5) at each step (ours, beyond the paper).
    Greedy,
    /// Uniformly random distinct frames (seeded): the floor.
    Random,
}

impl std::str::FromStr for Method {
    type Err = crate::error::Error;

    /// As [`Method::parse`].
    fn from_str(s: &str) -> crate::error::Result<Method> {
        Method::parse(s)
    }
}

impl Method {
    /// The methods of paper 000's Fig. 6 plus ours, in plotting order.
    pub const ALL: [Method; 8] = [
        Method::Spread,
        Method::KMeans {
            pcs: 2,
            mean: false,
        },
        Method::KMeans {
            pcs: 3,
            mean: false,
        },
        Method::KMeans { pcs: 2, mean: true },
        Method::KMeans { pcs: 3, mean: true },
        Method::Hull,
        Method::Greedy,
        Method::Random,
    ];

    /// Parses `spread`, `kmeans2`, `kmeans3`, `kmeansN`, `kmeansN-mean`, `hull`, `greedy`,
    /// `random`.
    pub fn parse(s: &str) -> Result<Method> {
        let t = s.trim().to_ascii_lowercase();
        let (base, mean) = match t.strip_suffix("-mean") {
            Some(b) => (b, true),
            None => (t.as_str(), false),
        };
        let m = match base {
            "spread" if !mean => Method::Spread,
            "hull" if !mean => Method::Hull,
            "greedy" if !mean => Method::Greedy,
            "random" if !mean => Method::Random,
            "kmeans" => Method::KMeans { pcs: 2, mean },
            _ => match base.strip_prefix("kmeans").map(str::parse::<usize>) {
                Some(Ok(pcs)) if (1..=64).contains(&pcs) => Method::KMeans { pcs, mean },
                _ => {
                    return Err(Error::bad_setting("method", s, format!(
                        "unknown key-shape method '{s}' (expected spread, kmeans2, kmeans3, kmeansN, kmeansN-mean, hull, greedy or random)"
                    )))
                }
            },
        };
        Ok(m)
    }

    /// The name [`Method::parse`] reads.
    pub fn name(&self) -> String {
        match self {
            Method::Spread => "spread".into(),
            Method::KMeans { pcs, mean: false } => format!("kmeans{pcs}"),
            Method::KMeans { pcs, mean: true } => format!("kmeans{pcs}-mean"),
            Method::Hull => "hull".into(),
            Method::Greedy => "greedy".into(),
            Method::Random => "random".into(),
        }
    }

    /// The heuristic with these options.
    pub fn heuristic(&self, opts: &KeyOptions) -> Box<dyn Heuristic + Send + Sync> {
        match *self {
            Method::Spread => Box::new(Spread),
            Method::KMeans { pcs, mean } => Box::new(KMeans {
                pcs,
                seed: opts.seed,
                mean,
                seeding: kmeans::Seeding::LAB,
            }),
            Method::Hull => Box::new(Hull),
            Method::Greedy => Box::new(Greedy {
                solver: opts.solver,
                shortlist: opts.shortlist,
            }),
            Method::Random => Box::new(Random { seed: opts.seed }),
        }
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.name())
    }
}

/// Options shared by the heuristics.
#[derive(Debug, Clone, Copy)]
pub struct KeyOptions {
    /// Solver whose Eq. (5) error `greedy` minimises.
    pub solver: Solver,
    /// Seed for `kmeans` and `random`.
    pub seed: u64,
    /// `greedy` with nnls/bounded: exact solves for this many candidates per step, ranked
    /// by least-squares gain (0 = every frame: exact greedy, slow).
    pub shortlist: usize,
}

impl Default for KeyOptions {
    fn default() -> Self {
        KeyOptions {
            solver: Solver::Nnls,
            seed: 7,
            shortlist: 8,
        }
    }
}

/// Principal axes an analysis must keep for `methods` up to `kmax` key shapes: spread uses
/// ⌈k/2⌉, `kmeansN` uses N, and never fewer than [`DEFAULT_AXES`] when a method works in
/// PCA space. Greedy and random do not read the projection, so alone they keep the 3 that
/// [`Analysis::with_axes`] always keeps (on a 300,000-frame track, 7 MB instead of 58).
pub fn axes_needed(methods: &[Method], kmax: usize) -> usize {
    let pca_space = methods
        .iter()
        .any(|m| !matches!(m, Method::Greedy | Method::Random));
    let floor = if pca_space {
        DEFAULT_AXES.max(kmax.div_ceil(2))
    } else {
        3
    };
    methods.iter().fold(floor, |a: usize, m| match m {
        Method::KMeans { pcs, .. } => a.max(*pcs),
        _ => a,
    })
}

/// Number of distinct columns (shapes) of `m`, by a 128-bit digest of each column's bits.
pub fn distinct_shapes(m: &DMatrix<f64>) -> usize {
    let mut seen = HashSet::with_capacity(m.ncols());
    for c in m.column_iter() {
        seen.insert(digest(c.as_slice()));
    }
    seen.len()
}

/// The one check of "enough distinct frames for what is asked": `what` needs at least
/// `need` distinct shapes among the columns of a sequence with `distinct` of them in
/// `frames` frames. Every path that fits a PCA, a hull or a model on a track goes through
/// it, so a one-frame or a repeated track is refused with this message, never a panic.
pub fn need_distinct(distinct: usize, frames: usize, need: usize, what: &str) -> Result<()> {
    if distinct >= need {
        return Ok(());
    }
    Err(Error::unfit(format!(
        "{what} needs at least {need} distinct shapes, but the sequence has {distinct} ({frames} frame{}{})",
        if frames == 1 { "" } else { "s" },
        if frames > distinct && distinct > 0 { ", the rest repeats" } else { "" }
    )))
}

/// A prepared sequence with what every heuristic needs: its PCA, the projection, the
/// number of distinct shapes, and (lazily) the frames' Gram matrix.
#[derive(Debug)]
pub struct Analysis {
    /// Shapes, one per column (dims · points × frames).
    pub coords: DMatrix<f64>,
    /// Points per shape (for per-point RMS).
    pub points: usize,
    /// PCA of the shapes.
    pub pca: Pca,
    /// Coordinates of every frame on the leading axes (axes × frames).
    pub proj: DMatrix<f64>,
    /// Number of distinct shapes among the frames.
    pub distinct: usize,
    /// `‖q_t‖²` per frame.
    pub sq_norms: Vec<f64>,
    /// Outer-iteration cap per frame of the nnls/bounded solves behind `error`,
    /// `weights_and_error`, the `selection_*` methods and what is built on them (the error
    /// curves, greedy selection); `None`: the solver's default `3k + 20`, which no problem
    /// met so far reaches. A frame stopped by it makes the error an error, never a wrong
    /// point on a curve.
    pub max_iterations: Option<u32>,
    gram: OnceLock<DMatrix<f64>>,
}

/// Principal axes [`Analysis::new`] keeps (spread uses k/2 of them, so k ≤ 48; use
/// [`Analysis::with_axes`] for more).
pub const DEFAULT_AXES: usize = 24;

impl Analysis {
    /// Fits the PCA (leading [`DEFAULT_AXES`] axes) and projects every frame.
    pub fn new(coords: DMatrix<f64>, points: usize) -> Result<Analysis> {
        Analysis::with_axes(coords, points, DEFAULT_AXES)
    }

    /// As [`Analysis::new`], keeping `axes` principal axes.
    pub fn with_axes(coords: DMatrix<f64>, points: usize, axes: usize) -> Result<Analysis> {
        // More axes than the data spans add nothing (and a huge request must not overflow).
        let axes = axes.min(coords.nrows().min(coords.ncols()));
        let pca = Pca::fit_leading(&coords, axes.max(3))?;
        let proj = pca.project(&coords, axes.max(3));
        // Distinct shapes counted by a 128-bit digest of each column's bits, not a copy of
        // the coordinates (two distinct shapes share a digest with probability ~2⁻¹²⁸).
        let distinct = distinct_shapes(&coords);
        let sq_norms = coords.column_iter().map(|c| c.norm_squared()).collect();
        Ok(Analysis {
            distinct,
            coords,
            points,
            pca,
            proj,
            sq_norms,
            max_iterations: None,
            gram: OnceLock::new(),
        })
    }

    /// Number of frames.
    pub fn frames(&self) -> usize {
        self.coords.ncols()
    }

    /// [`need_distinct`] on this sequence.
    pub fn need_distinct(&self, need: usize, what: &str) -> Result<()> {
        need_distinct(self.distinct, self.frames(), need, what)
    }

    /// Checks that `k` key shapes can be chosen.
    pub fn check_k(&self, k: usize) -> Result<()> {
        if k == 0 {
            return Err(Error::bad_setting("k", k, "k must be at least 1"));
        }
        if k > self.distinct {
            return Err(Error::bad_setting("k", k, format!(
                "k = {k} key shapes asked for, but the sequence has only {} distinct shapes ({} frames)",
                self.distinct,
                self.frames()
            )));
        }
        Ok(())
    }

    /// The frames' Gram matrix `QᵀQ` (frames × frames), formed on first use.
    pub fn frame_gram(&self) -> Result<&DMatrix<f64>> {
        if self.frames() > GRAM_LIMIT {
            return Err(Error::invalid(format!(
                "the frames' Gram matrix is formed for at most {GRAM_LIMIT} frames; this sequence has {}",
                self.frames()
            )));
        }
        Ok(self
            .gram
            .get_or_init(|| self.coords.transpose() * &self.coords))
    }

    /// Refuses an empty key set (its "error" would be ‖Q‖², a point at k = 0 on a curve) and
    /// key columns out of range.
    fn check_keys(&self, keys: &[usize]) -> Result<()> {
        if keys.is_empty() {
            return Err(Error::invalid(
                "no key shapes: Eq. (5) needs at least one key column",
            ));
        }
        if let Some(&bad) = keys.iter().find(|&&c| c >= self.frames()) {
            return Err(Error::invalid(format!(
                "key column {bad} out of range (0..{})",
                self.frames()
            )));
        }
        Ok(())
    }

    /// `G = SᵀS` and `B = SᵀQ` for key columns `keys`.
    fn products(&self, keys: &[usize]) -> Result<(DMatrix<f64>, DMatrix<f64>)> {
        self.check_keys(keys)?;
        if self.frames() <= GRAM_LIMIT {
            let k = self.frame_gram()?;
            let b = k.select_rows(keys);
            let g = b.select_columns(keys);
            Ok((g, b))
        } else {
            let s = self.coords.select_columns(keys);
            Ok((s.tr_mul(&s), s.transpose() * &self.coords))
        }
    }

    /// Paper 000 Eq. (5), `E = Σ_t ‖Q_t − S w_t‖²`, for key columns `keys` under `solver`,
    /// computed from inner products: `‖q‖² − 2 wᵀb + wᵀ G w` per frame.
    pub fn error(&self, keys: &[usize], solver: Solver) -> Result<f64> {
        if self.frames() <= GRAM_LIMIT {
            return self.weights_and_error(keys, solver).map(|(_, e)| e);
        }
        self.check_keys(keys)?;
        let s = self.coords.select_columns(keys);
        let st = s.transpose();
        self.error_in_blocks(
            &s.tr_mul(&s),
            |a, m| &st * self.coords.columns(a, m),
            solver,
            &format!("key columns {keys:?}"),
        )
    }

    /// The Eq. (5) error from `G` and `B = SᵀQ` formed block by block (`b(start, len)`), so a
    /// long track never holds a keys × frames matrix, let alone three: the blocks are a
    /// multiple of the solver's chunk, so every frame is solved (warm starts included)
    /// exactly as [`Self::solve_products`] solves it, and the sum runs in the same order.
    fn error_in_blocks<F>(&self, g: &DMatrix<f64>, b: F, solver: Solver, what: &str) -> Result<f64>
    where
        F: Fn(usize, usize) -> DMatrix<f64>,
    {
        const BLOCK: usize = 16 * crate::solve::CHUNK;
        let pinv = (solver == Solver::Ls).then(|| lstsq::gram_pseudo_inverse(g, None));
        let upper = if solver == Solver::Bounded {
            1.0
        } else {
            f64::INFINITY
        };
        let gram = (solver != Solver::Ls).then(|| Gram::from_matrix(g, upper));
        let n = self.frames();
        let mut e = 0.0;
        let mut bad = 0usize;
        for a in (0..n).step_by(BLOCK) {
            let m = BLOCK.min(n - a);
            let bb = b(a, m);
            let w = match (&pinv, &gram) {
                (Some(p), _) => p * &bb,
                (None, Some(gr)) => {
                    let (w, unconverged, _) =
                        active_set_from_gram(gr, &bb, true, self.max_iterations);
                    bad += unconverged;
                    w
                }
                (None, None) => unreachable!("a solver is either LS or constrained"),
            };
            let gw = g * &w;
            for t in 0..m {
                let (wt, bt, gwt) = (w.column(t), bb.column(t), gw.column(t));
                e += (self.sq_norms[a + t] - 2.0 * wt.dot(&bt) + wt.dot(&gwt)).max(0.0);
            }
        }
        if bad > 0 {
            return Err(Error::unfit(format!(
                "{solver} did not converge on {bad} frames (iteration cap) for {what}"
            )));
        }
        if !e.is_finite() {
            return Err(Error::unfit("reconstruction error is not finite"));
        }
        Ok(e)
    }

    /// The weights (k × frames) and Eq. (5) error of key columns `keys` under `solver`.
    pub fn weights_and_error(&self, keys: &[usize], solver: Solver) -> Result<(DMatrix<f64>, f64)> {
        let (g, b) = self.products(keys)?;
        self.solve_products(&g, &b, solver, &format!("key columns {keys:?}"))
    }

    /// The weights and Eq. (5) error of a selection: its key frames, or its key shapes
    /// when they are not frames (`kmeansN-mean`).
    pub fn selection_weights_and_error(
        &self,
        sel: &Selection,
        solver: Solver,
    ) -> Result<(DMatrix<f64>, f64)> {
        match &sel.shapes {
            None => self.weights_and_error(&sel.columns, solver),
            Some(s) => {
                if s.nrows() != self.coords.nrows() {
                    return Err(Error::invalid(format!(
                        "key shapes have {} values, the frames {}",
                        s.nrows(),
                        self.coords.nrows()
                    )));
                }
                let (g, b) = (s.tr_mul(s), s.tr_mul(&self.coords));
                self.solve_products(&g, &b, solver, "the cluster mean shapes")
            }
        }
    }

    /// Eq. (5) of a selection (see [`Analysis::selection_weights_and_error`]).
    pub fn selection_error(&self, sel: &Selection, solver: Solver) -> Result<f64> {
        match &sel.shapes {
            None => self.error(&sel.columns, solver),
            Some(s) if self.frames() > GRAM_LIMIT && s.nrows() == self.coords.nrows() => self
                .error_in_blocks(
                    &s.tr_mul(s),
                    |a, m| s.tr_mul(&self.coords.columns(a, m)),
                    solver,
                    "the cluster mean shapes",
                ),
            Some(_) => self
                .selection_weights_and_error(sel, solver)
                .map(|(_, e)| e),
        }
    }

    /// Weights from `G = SᵀS`, `B = SᵀQ` and the Eq. (5) error from inner products.
    fn solve_products(
        &self,
        g: &DMatrix<f64>,
        b: &DMatrix<f64>,
        solver: Solver,
        what: &str,
    ) -> Result<(DMatrix<f64>, f64)> {
        let keys = what;
        let w = match solver {
            Solver::Ls => lstsq::gram_pseudo_inverse(g, None) * b,
            Solver::Nnls | Solver::Bounded => {
                let upper = if solver == Solver::Nnls {
                    f64::INFINITY
                } else {
                    1.0
                };
                let (w, unconverged, _) = active_set_from_gram(
                    &Gram::from_matrix(g, upper),
                    b,
                    true,
                    self.max_iterations,
                );
                // An unconverged frame would put a wrong point on an error curve.
                if unconverged > 0 {
                    return Err(Error::unfit(format!(
                        "{solver} did not converge on {unconverged} frames (iteration cap) for {keys}"
                    )));
                }
                w
            }
        };
        let gw = g * &w;
        let mut e = 0.0;
        for t in 0..w.ncols() {
            let (wt, bt, gwt) = (w.column(t), b.column(t), gw.column(t));
            e += (self.sq_norms[t] - 2.0 * wt.dot(&bt) + wt.dot(&gwt)).max(0.0);
        }
        if !e.is_finite() {
            return Err(Error::unfit("reconstruction error is not finite"));
        }
        Ok((w, e))
    }

    /// `sqrt(E / (frames · points))`: per-point RMS in input units.
    pub fn rms(&self, total_sq_error: f64) -> f64 {
        (total_sq_error / (self.frames() * self.points).max(1) as f64).sqrt()
    }

    /// Errors if fewer than `n` principal axes carry variance.
    fn need_axes(&self, n: usize, what: &str) -> Result<()> {
        if self.proj.nrows() < n {
            return Err(Error::unfit(format!(
                "{what} needs {n} principal axes, but only {} are available (the shapes vary along fewer: choose fewer principal components, e.g. a smaller {} or kmeans2)",
                self.proj.nrows(),
                setting("pcs")
            )));
        }
        Ok(())
    }
}
