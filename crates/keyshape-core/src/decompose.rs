//! Facial decomposition (paper 000 §4.1): the frames of a prepared sequence as weighted
//! combinations of key shapes taken from the sequence itself, absolute (Eq. 3/4) or as
//! deltas from a neutral frame (`q − N = Σ wᵢ (Sᵢ − N)`).

use crate::align::{procrustes_owned, Similarity};
use crate::error::{setting, Error, Result};
use crate::sequence::{Layout, Sequence};
use crate::solve::temporal::{smooth_from, Smoothed, Smoothing};
use crate::solve::{residuals, solve_batch, SolveOptions, Solver};
use nalgebra::DMatrix;

/// How to prepare a sequence before decomposing it.
#[derive(Debug, Clone, Default)]
pub struct PrepareOptions {
    /// A group selection such as `lips` or `eyes,brows` (None = every point).
    pub points: Option<String>,
    /// Remove 2-D similarity head motion (generalised Procrustes).
    pub align: bool,
}

impl PrepareOptions {
    /// Every point, head motion removed: where most analyses start.
    pub fn all_aligned() -> PrepareOptions {
        PrepareOptions {
            points: None,
            align: true,
        }
    }

    /// The points of `group` (`lips`, `eyes,brows` …), head motion removed.
    pub fn group_aligned(group: &str) -> PrepareOptions {
        PrepareOptions {
            points: Some(group.into()),
            align: true,
        }
    }
}

/// A sequence ready for decomposition: points selected, head motion removed and kept.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// The selected (and, when asked, aligned) shapes.
    pub seq: Sequence,
    /// Per frame: aligned → image coordinates (None when not aligned).
    pub head: Option<Vec<Similarity>>,
    /// Indices of the kept points in the original layout.
    pub point_indices: Vec<usize>,
    /// The layout of the original points, when one is built in for the point count.
    pub layout: Option<Layout>,
}

/// Aligns the whole face (more points give a steadier fit than the selected group alone),
/// then keeps the selected points.
pub fn prepare(seq: &Sequence, opts: &PrepareOptions) -> Result<Prepared> {
    prepare_owned(seq.clone(), opts)
}

/// [`prepare`] on a sequence the caller gives up: aligned in place, so a long track is held
/// once, not twice (the input and its aligned copy).
pub fn prepare_owned(seq: Sequence, opts: &PrepareOptions) -> Result<Prepared> {
    let layout = Layout::for_points(seq.points);
    let point_indices = match (&opts.points, &layout) {
        (None, _) => (0..seq.points).collect(),
        (Some(spec), Some(l)) => l.select(spec)?,
        (Some(spec), None) => {
            return Err(Error::bad_setting(
                "points",
                spec,
                format!(
                    "{} {spec}: no built-in layout has {} points (MediaPipe has 468, iBUG 68)",
                    setting("points"),
                    seq.points
                ),
            ))
        }
    };
    let (base, head) = if opts.align {
        // Name the frame and file, not an internal column, when a shape cannot be aligned.
        seq.check_geometry()?;
        let mut seq = seq;
        let coords = std::mem::replace(&mut seq.coords, DMatrix::zeros(0, 0));
        let al = procrustes_owned(coords, seq.dims)
            .map_err(|e| Error::file(&seq.source, e.to_string()))?;
        seq.coords = al.coords;
        (seq, Some(al.head))
    } else {
        (seq, None)
    };
    let points = base.points;
    let selected = if point_indices.len() == points {
        base
    } else {
        base.select_points(&point_indices)?
    };
    Ok(Prepared {
        seq: selected,
        head,
        point_indices,
        layout,
    })
}

/// Weights of every frame on a set of key shapes, with the reconstruction error.
#[derive(Debug, Clone)]
pub struct Decomposition {
    /// Column indices (into the prepared sequence) of the key shapes.
    pub key_columns: Vec<usize>,
    /// Column index of the neutral frame in delta mode.
    pub neutral: Option<usize>,
    /// The solver used.
    pub solver: Solver,
    /// k × frames.
    pub weights: DMatrix<f64>,
    /// Per frame `‖q − q̂‖²` (paper 000 Eq. 5 summed over frames).
    pub sq_error: Vec<f64>,
    /// Points per shape (for per-point RMS).
    pub points: usize,
    /// Numerical rank of the key-shape matrix.
    pub rank: usize,
    /// Its condition number.
    pub condition: f64,
    /// Frames the active-set solver stopped early on.
    pub unconverged: usize,
}

impl Decomposition {
    /// Per-frame RMS error per point, in the input's units: `sqrt(‖q − q̂‖² / points)`.
    pub fn rms(&self) -> Vec<f64> {
        self.sq_error
            .iter()
            .map(|e| (e / self.points as f64).sqrt())
            .collect()
    }

    /// Paper 000 Eq. (5): `E = Σ_t ‖Q_t − F(w, S)‖²`.
    pub fn total_sq_error(&self) -> f64 {
        self.sq_error.iter().sum()
    }

    /// `sqrt(E / (frames · points))`.
    pub fn overall_rms(&self) -> f64 {
        (self.total_sq_error() / (self.sq_error.len() * self.points).max(1) as f64).sqrt()
    }

    /// Mean of the per-frame RMS.
    pub fn mean_rms(&self) -> f64 {
        let r = self.rms();
        r.iter().sum::<f64>() / r.len().max(1) as f64
    }

    /// Share of weights below zero; a weight within rounding of zero
    /// ([`NEGATIVE_TOLERANCE`] × the largest |w|) does not count.
    pub fn negative_share(&self) -> f64 {
        let n = self.weights.len().max(1);
        let tol = NEGATIVE_TOLERANCE * self.max_abs_weight();
        self.weights.iter().filter(|&&w| w < -tol).count() as f64 / n as f64
    }

    /// Largest |w|.
    pub fn max_abs_weight(&self) -> f64 {
        self.weights.iter().fold(0.0, |m, w| m.max(w.abs()))
    }
}

/// A weight counts as negative below −this × the largest |w|: an LS weight of −3e-14 is
/// rounding, not a negative weight.
pub const NEGATIVE_TOLERANCE: f64 = 1e-9;

/// Solves weights for every frame of `prep` (its selected, aligned shapes) on the key
/// shapes at the columns `key_columns`; with `neutral`, on deltas from that frame.
pub fn decompose(
    prep: &Prepared,
    key_columns: &[usize],
    neutral: Option<usize>,
    opts: &SolveOptions,
) -> Result<Decomposition> {
    decompose_coords(
        &prep.seq.coords,
        prep.seq.points,
        key_columns,
        neutral,
        opts,
    )
}

/// [`decompose`] with a temporal prior over `segments` (frame column ranges) in the
/// coordinates the solve uses (deltas from the neutral in delta mode); also returns what
/// the smoothed solve reported.
pub fn decompose_smoothed(
    prep: &Prepared,
    key_columns: &[usize],
    neutral: Option<usize>,
    opts: &SolveOptions,
    smoothing: Option<(&Smoothing, &[std::ops::Range<usize>])>,
) -> Result<(Decomposition, Option<Smoothed>)> {
    solve_columns(
        &prep.seq.coords,
        prep.seq.points,
        key_columns,
        neutral,
        opts,
        smoothing,
    )
}

/// [`decompose`] on a matrix of shapes (one column each, `points` points of two or three
/// coordinates): the algebra without a prepared sequence, for shapes made by hand.
pub fn decompose_coords(
    coords: &DMatrix<f64>,
    points: usize,
    key_columns: &[usize],
    neutral: Option<usize>,
    opts: &SolveOptions,
) -> Result<Decomposition> {
    solve_columns(coords, points, key_columns, neutral, opts, None).map(|(d, _)| d)
}

/// Refuses an empty, too long, out-of-range or repeated key-column list, and a neutral
/// that is also a key shape; `n` is the number of frame columns.
fn check_key_columns(n: usize, key_columns: &[usize], neutral: Option<usize>) -> Result<()> {
    if key_columns.is_empty() {
        return Err(Error::invalid("no key shapes given"));
    }
    if key_columns.len() > n {
        return Err(Error::invalid(format!(
            "{} key shapes asked for, but the sequence has only {n} valid frames",
            key_columns.len()
        )));
    }
    let mut seen = std::collections::HashSet::new();
    for &c in key_columns.iter().chain(neutral.iter()) {
        if c >= n {
            return Err(Error::invalid(format!(
                "key column {c} out of range (0..{n})"
            )));
        }
    }
    for &c in key_columns {
        if !seen.insert(c) {
            return Err(Error::invalid(format!(
                "key frame column {c} is listed twice"
            )));
        }
    }
    if let Some(nc) = neutral {
        if key_columns.contains(&nc) {
            return Err(Error::invalid(
                "the neutral frame cannot also be a key shape (its delta is zero)",
            ));
        }
    }
    Ok(())
}

fn solve_columns(
    coords: &DMatrix<f64>,
    points: usize,
    key_columns: &[usize],
    neutral: Option<usize>,
    opts: &SolveOptions,
    smoothing: Option<(&Smoothing, &[std::ops::Range<usize>])>,
) -> Result<(Decomposition, Option<Smoothed>)> {
    let n = coords.ncols();
    check_key_columns(n, key_columns, neutral)?;
    let mut s = coords.select_columns(key_columns);
    let deltas;
    let q = match neutral {
        None => coords,
        Some(nc) => {
            let base = coords.column(nc).clone_owned();
            for mut c in s.column_iter_mut() {
                c -= &base;
            }
            let mut d = coords.clone();
            for mut c in d.column_iter_mut() {
                c -= &base;
            }
            deltas = d;
            &deltas
        }
    };
    let mut sol = solve_batch(&s, q, opts)?;
    let smoothed = match smoothing {
        Some((sm, segs)) if sm.lambda > 0.0 => {
            let (rank, condition) = (sol.rank, sol.condition);
            let r = smooth_from(&s, q, &sol, opts.solver, sm, segs)?;
            sol = crate::solve::Solution {
                weights: r.weights.clone(),
                rank,
                condition,
                // Per-frame caps do not apply to a whole-segment solve: its own count
                // (segments that did not settle) is in the returned `Smoothed`.
                unconverged: 0,
                iterations: r.iterations,
            };
            Some(r)
        }
        Some((sm, _)) => {
            sm.check()?;
            None
        }
        None => None,
    };
    let sq_error = residuals(&s, &sol.weights, q);
    if let Some(t) = (0..n)
        .find(|&t| !sq_error[t].is_finite() || sol.weights.column(t).iter().any(|w| !w.is_finite()))
    {
        return Err(Error::unfit(format!(
            "the solve gave non-finite weights or error at frame column {t} (coordinates too large or degenerate key shapes); nothing written"
        )));
    }
    Ok((
        Decomposition {
            key_columns: key_columns.to_vec(),
            neutral,
            solver: opts.solver,
            weights: sol.weights,
            sq_error,
            points,
            rank: sol.rank,
            condition: sol.condition,
            unconverged: sol.unconverged,
        },
        smoothed,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::ErrorKind;
    use crate::solve::Solver;

    /// Five 2-point shapes (4 coordinates each), frame 4 = frame 1 + frame 2.
    fn shapes() -> DMatrix<f64> {
        DMatrix::from_column_slice(
            4,
            5,
            &[
                0.0, 0.0, 0.0, 0.0, //
                1.0, 0.0, 0.0, 0.5, //
                0.0, 1.0, 0.5, 0.0, //
                2.0, 2.0, 0.0, 1.0, //
                1.0, 1.0, 0.5, 0.5,
            ],
        )
    }

    /// Each bad key list is refused with its own message, before any solve; a good one
    /// solves frame 4 as frame 1 + frame 2.
    #[test]
    fn key_columns_are_checked_before_the_solve() {
        let q = shapes();
        let opts = SolveOptions::new(Solver::Nnls);
        let refused = |keys: &[usize], neutral: Option<usize>, needle: &str| {
            let e = decompose_coords(&q, 2, keys, neutral, &opts).unwrap_err();
            assert_eq!(e.kind(), ErrorKind::Invalid, "{keys:?}: {e}");
            assert!(e.to_string().contains(needle), "{keys:?}: {e}");
        };
        refused(&[], None, "no key shapes given");
        refused(&[0, 1, 2, 3, 4, 0], None, "6 key shapes asked for");
        refused(&[1, 5], None, "key column 5 out of range (0..5)");
        refused(&[1, 2], Some(7), "key column 7 out of range (0..5)");
        refused(&[1, 2, 1], None, "key frame column 1 is listed twice");
        refused(
            &[1, 2],
            Some(2),
            "the neutral frame cannot also be a key shape",
        );
        let d = decompose_coords(&q, 2, &[1, 2], Some(0), &opts).unwrap();
        assert!((d.weights[(0, 4)] - 1.0).abs() < 1e-9, "{}", d.weights);
        assert!((d.weights[(1, 4)] - 1.0).abs() < 1e-9, "{}", d.weights);
        assert!(d.sq_error[4] < 1e-18);
    }
}
