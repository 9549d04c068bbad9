//! Blend-weight solvers for key shapes S (n × k, one key shape per column) shared by every
//! frame q (a column of Q): `min ‖S w − q‖²` per frame, with
//!
//! * [`Solver::Ls`]: no constraint, paper 000 Eq. (3), rank-revealing SVD;
//! * [`Solver::Nnls`]: `w ≥ 0`, paper 000 Eq. (4), Lawson–Hanson from the Gram matrix;
//! * [`Solver::Bounded`]: `0 ≤ w ≤ 1`, as morph-target rigs use.
//!
//! Batches run in parallel (rayon) over chunks of frames; within a chunk the active-set
//! solvers start each frame from the previous frame's active set, which tracked sequences
//! make a good guess. Chunks have a fixed size, so results do not depend on thread count.

pub mod active_set;
pub mod chol;
pub mod filters;
pub(crate) mod jacobi;
pub mod jitter;
pub mod lstsq;
pub mod temporal;
pub mod textbook;

use crate::error::{Error, Result};
use active_set::{Bound, Gram, Workspace};
use nalgebra::DMatrix;
use rayon::prelude::*;

/// Frames per parallel chunk.
pub const CHUNK: usize = 256;

/// Which constraint the weights obey.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Solver {
    /// Unconstrained least squares (Eq. 3).
    Ls,
    /// Non-negative least squares (Eq. 4).
    Nnls,
    /// Weights in [0, 1].
    Bounded,
}

impl std::str::FromStr for Solver {
    type Err = crate::error::Error;

    /// As [`Solver::parse`].
    fn from_str(s: &str) -> crate::error::Result<Solver> {
        Solver::parse(s)
    }
}

impl Solver {
    /// All solvers.
    pub const ALL: [Solver; 3] = [Solver::Ls, Solver::Nnls, Solver::Bounded];

    /// Name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Solver::Ls => "ls",
            Solver::Nnls => "nnls",
            Solver::Bounded => "bounded",
        }
    }

    /// Parses a name as [`Solver::name`] writes it.
    pub fn parse(s: &str) -> Result<Solver> {
        Solver::ALL
            .into_iter()
            .find(|v| v.name().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| {
                Error::bad_setting(
                    "solver",
                    s,
                    format!("unknown solver '{s}' (expected ls, nnls or bounded)"),
                )
            })
    }
}

impl std::fmt::Display for Solver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Solver settings.
#[derive(Debug, Clone, Copy)]
pub struct SolveOptions {
    /// The constraint.
    pub solver: Solver,
    /// LS only: relative singular-value cutoff (default [`lstsq::default_rcond`]).
    pub rcond: Option<f64>,
    /// Active-set only: start each frame from the previous frame's active set.
    pub warm_start: bool,
    /// Active-set only: outer iterations a frame may take (default `3k + 20`); frames
    /// stopped by it are counted in [`Solution::unconverged`].
    pub max_iterations: Option<u32>,
}

impl SolveOptions {
    /// Defaults for a solver.
    pub fn new(solver: Solver) -> Self {
        SolveOptions {
            solver,
            rcond: None,
            warm_start: true,
            max_iterations: None,
        }
    }
}

/// Weights for a batch and what the solver saw.
#[derive(Debug, Clone)]
pub struct Solution {
    /// k × frames.
    pub weights: DMatrix<f64>,
    /// Numerical rank of S (SVD, same cutoff as LS).
    pub rank: usize,
    /// Condition number of S (σ_max / σ_min).
    pub condition: f64,
    /// Active-set frames stopped by the iteration cap (still feasible, maybe not optimal).
    pub unconverged: usize,
    /// Active-set outer iterations summed over frames.
    pub iterations: u64,
}

/// Solves every column of `q` against the key shapes `s`.
pub fn solve_batch(s: &DMatrix<f64>, q: &DMatrix<f64>, opts: &SolveOptions) -> Result<Solution> {
    let (n, k) = s.shape();
    if k == 0 {
        return Err(Error::invalid("no key shapes"));
    }
    if q.nrows() != n {
        return Err(Error::invalid(format!(
            "frames have {} values, key shapes {n}",
            q.nrows()
        )));
    }
    // Only S is scanned up front: a NaN or infinity in a frame reaches `Sᵀq` and the
    // weights, which are checked after the solve, so the batch makes one pass over Q.
    if s.iter().any(|v| !v.is_finite()) {
        return Err(Error::invalid("key shapes contain NaN or infinity"));
    }
    let pinv = lstsq::pseudo_inverse(s, opts.rcond)?;
    let mut sol = Solution {
        weights: DMatrix::zeros(k, q.ncols()),
        rank: pinv.rank,
        condition: pinv.condition,
        unconverged: 0,
        iterations: 0,
    };
    match opts.solver {
        Solver::Ls => {
            sol.weights = chunked_product(&pinv.pinv, q);
        }
        Solver::Nnls | Solver::Bounded => {
            let upper = if opts.solver == Solver::Nnls {
                f64::INFINITY
            } else {
                1.0
            };
            let (w, unconverged, iterations) =
                active_set_batch(s, q, upper, opts.warm_start, opts.max_iterations);
            sol.weights = w;
            sol.unconverged = unconverged;
            sol.iterations = iterations;
        }
    }
    let bad =
        (0..sol.weights.ncols()).find(|&j| sol.weights.column(j).iter().any(|v| !v.is_finite()));
    if let Some(j) = bad {
        return Err(Error::unfit(format!(
            "frame column {j}: non-finite weights (the frame holds NaN or infinity)"
        )));
    }
    Ok(sol)
}

/// `a · q` computed over column chunks in parallel.
pub fn chunked_product(a: &DMatrix<f64>, q: &DMatrix<f64>) -> DMatrix<f64> {
    let (k, n) = (a.nrows(), q.ncols());
    let mut out = DMatrix::zeros(k, n);
    out.as_mut_slice()
        .par_chunks_mut(k * CHUNK)
        .enumerate()
        .for_each(|(c, dst)| {
            let start = c * CHUNK;
            let m = dst.len() / k.max(1);
            let block = a * q.columns(start, m);
            dst.copy_from_slice(block.as_slice());
        });
    out
}

/// Batch active-set solve; returns (weights, unconverged, iterations). `Sᵀq` is formed per
/// chunk of frames as a blocked GEMM. `cap`: outer iterations per frame (`None`: `3k + 20`).
pub fn active_set_batch(
    s: &DMatrix<f64>,
    q: &DMatrix<f64>,
    upper: f64,
    warm: bool,
    cap: Option<u32>,
) -> (DMatrix<f64>, usize, u64) {
    let gram = Gram::new(s, upper);
    // Sᵀ once: `st * q` runs as a blocked GEMM, `s.tr_mul(q)` as column dot products.
    let st = s.transpose();
    chunked_active_set(&gram, q.ncols(), warm, cap, |start, m| {
        &st * q.columns(start, m)
    })
}

/// Batch active-set solve from a precomputed Gram form: `gram` from `G = SᵀS` and
/// `b = Sᵀq` (k × frames) — for callers that already hold inner products, such as key-shape
/// searches working from the frames' Gram matrix `QᵀQ`. `cap` is the outer-iteration cap
/// per frame (`None`: the default `3k + 20`); returns the weights, the frames it stopped
/// and the total iterations.
pub fn active_set_from_gram(
    gram: &Gram,
    b: &DMatrix<f64>,
    warm: bool,
    cap: Option<u32>,
) -> (DMatrix<f64>, usize, u64) {
    chunked_active_set(gram, b.ncols(), warm, cap, |start, m| {
        b.columns(start, m).clone_owned()
    })
}

/// Runs [`active_set::solve_frame`] over `frames` frames in parallel chunks; `rhs(start, m)`
/// gives `Sᵀq` for frames `start..start + m`.
fn chunked_active_set<F>(
    gram: &Gram,
    frames: usize,
    warm: bool,
    cap: Option<u32>,
    rhs: F,
) -> (DMatrix<f64>, usize, u64)
where
    F: Fn(usize, usize) -> DMatrix<f64> + Sync,
{
    let k = gram.k;
    let mut out = DMatrix::zeros(k, frames);
    let stats: Vec<(usize, u64)> = out
        .as_mut_slice()
        .par_chunks_mut(k * CHUNK)
        .enumerate()
        .map(|(c, dst)| {
            let m = dst.len() / k;
            let b = rhs(c * CHUNK, m);
            let mut ws = Workspace::new(k);
            if let Some(c) = cap {
                ws = ws.with_cap(c);
            }
            let mut state = vec![Bound::Lower; k];
            let mut w = vec![0.0; k];
            let (mut bad, mut iters) = (0usize, 0u64);
            for f in 0..m {
                if !warm {
                    state.iter_mut().for_each(|s| *s = Bound::Lower);
                    w.iter_mut().for_each(|v| *v = 0.0);
                }
                let bf = b.column(f);
                if bf.iter().any(|v| !v.is_finite()) {
                    // A NaN/inf frame: report it through non-finite weights.
                    dst[f * k..(f + 1) * k]
                        .iter_mut()
                        .for_each(|v| *v = f64::NAN);
                    continue;
                }
                let r = active_set::solve_frame(gram, bf.as_slice(), &mut w, &mut state, &mut ws);
                bad += usize::from(!r.converged);
                iters += u64::from(r.iterations);
                dst[f * k..(f + 1) * k].copy_from_slice(&w);
            }
            (bad, iters)
        })
        .collect();
    let unconverged = stats.iter().map(|s| s.0).sum();
    let iterations = stats.iter().map(|s| s.1).sum();
    (out, unconverged, iterations)
}

/// Squared residual `‖q − S w‖²` of every frame, computed directly (no Gram shortcut, so
/// tiny residuals keep their precision).
pub fn residuals(s: &DMatrix<f64>, w: &DMatrix<f64>, q: &DMatrix<f64>) -> Vec<f64> {
    let n = q.ncols();
    let mut out = vec![0.0; n];
    out.par_chunks_mut(CHUNK).enumerate().for_each(|(c, dst)| {
        let start = c * CHUNK;
        let m = dst.len();
        let r = q.columns(start, m) - s * w.columns(start, m);
        for (d, col) in dst.iter_mut().zip(r.column_iter()) {
            *d = col.norm_squared();
        }
    });
    out
}
