//! The benchmark's measures: per shape, solved weights against the truth (Pearson r, MAE,
//! RMSE, peak reach, twin leakage, idle activation, jitter, lag), and their summary.

use keyshape_core::stats::correlation;
use nalgebra::DMatrix;
use serde::Serialize;

/// One shape's accuracy on one track.
#[derive(Debug, Clone, Serialize)]
pub struct ShapeAccuracy {
    /// The rig's name.
    pub shape: String,
    /// Does the truth use it?
    pub active: bool,
    /// Pearson r of solved against true weights (active shapes; NaN otherwise).
    pub r: f64,
    /// Mean absolute error.
    pub mae: f64,
    /// RMS error.
    pub rmse: f64,
    /// Mean solved weight where the truth is ≥ 0.99 (None: the truth never gets there).
    pub peak_reach: Option<f64>,
    /// The other side's mean solved weight on frames where this shape is ≥ 0.5 and the other
    /// side's truth is 0 (None: no twin, or no such frame).
    pub twin_leakage: Option<f64>,
    /// The largest solved weight of a shape the truth never uses (None: active).
    pub idle_activation: Option<f64>,
    /// RMS second difference of the solved weight, against the truth's.
    pub jitter: f64,
    /// The truth's jitter.
    pub true_jitter: f64,
    /// Frames by which the solved weight trails the truth (cross-correlation peak, ±10).
    pub lag: Option<i64>,
}

/// A track's summary: what a user reads first.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// Mean Pearson r over the active shapes.
    pub mean_r: f64,
    /// The lowest r among the active shapes, and its shape.
    pub worst_r: f64,
    /// See `worst_r`.
    pub worst_shape: String,
    /// RMS weight error over every shape and frame.
    pub rmse: f64,
    /// The largest weight of any shape the truth never uses, and its shape.
    pub max_idle: f64,
    /// See `max_idle`.
    pub max_idle_shape: String,
    /// The largest twin leakage.
    pub max_twin_leakage: f64,
    /// The lowest peak reach.
    pub min_peak_reach: Option<f64>,
    /// The largest lag (frames, either way) of an active shape.
    pub max_abs_lag: i64,
    /// The neutral the solve chose (its first clip's), measured against the truth; `None`
    /// without an identity. Filled by [`run`](super::run), not by [`measure`].
    pub neutral: Option<NeutralTruth>,
    /// A refined landmark map against the map the track was rendered through; `None`
    /// without refinement. Filled by [`run_refined`](super::run_refined).
    pub map: Option<MapTruth>,
}

/// A landmark map refined from a rendered track, against the map the track was rendered
/// through: how many landmarks sit on the render's vertex, and how far off the rest are.
#[derive(Debug, Clone, serde::Serialize)]
pub struct MapTruth {
    /// Landmarks that are mesh vertices (the ones a map places).
    pub landmarks: usize,
    /// Of those, on the render's vertex in the map solved with before refinement.
    pub right_before: usize,
    /// The same after.
    pub right_after: usize,
    /// Median distance from the render's vertex before refinement (rig units).
    pub median_off_before: f64,
    /// The same after.
    pub median_off_after: f64,
    /// Per round, the landmarks it moved.
    pub moved: Vec<usize>,
    /// Of the landmarks whose vertex changed, how many ended nearer the render's vertex.
    pub moved_nearer: usize,
    /// ... and how many farther from it.
    pub moved_farther: usize,
}

impl MapTruth {
    /// Compares the maps of `before` and `after` (rigs with `truth`'s points) with `truth`'s,
    /// over the landmarks of `truth` that are vertices of `positions`.
    pub fn of(
        positions: &[[f64; 3]],
        truth: &crate::Rig,
        before: &crate::Rig,
        after: &crate::Rig,
        moved: &[usize],
    ) -> MapTruth {
        let on_mesh: Vec<usize> = (0..truth.landmarks())
            .filter(|&l| positions.contains(&truth.neutral[l]))
            .collect();
        let dist =
            |a: &[f64; 3], b: &[f64; 3]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt();
        let stats = |rig: &crate::Rig| {
            let mut d: Vec<f64> = on_mesh
                .iter()
                .map(|&l| dist(&rig.neutral[l], &truth.neutral[l]))
                .collect();
            let right = d.iter().filter(|v| **v == 0.0).count();
            d.sort_by(f64::total_cmp);
            (right, d.get(d.len() / 2).copied().unwrap_or(0.0))
        };
        let (mut moved_nearer, mut moved_farther) = (0, 0);
        for &l in &on_mesh {
            let (b, a) = (
                dist(&before.neutral[l], &truth.neutral[l]),
                dist(&after.neutral[l], &truth.neutral[l]),
            );
            moved_nearer += usize::from(a < b);
            moved_farther += usize::from(a > b);
        }
        let (right_before, median_off_before) = stats(before);
        let (right_after, median_off_after) = stats(after);
        MapTruth {
            landmarks: on_mesh.len(),
            right_before,
            right_after,
            median_off_before,
            median_off_after,
            moved: moved.to_vec(),
            moved_nearer,
            moved_farther,
        }
    }
}

/// The chosen neutral frame against the truth: how much expression it truly held and how
/// far the head was truly turned, beside what the solve saw.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct NeutralTruth {
    /// The frame's column (a lead-in's middle frame).
    pub frame: usize,
    /// The true weights at the frame, summed (0 for a truly neutral frame).
    pub true_expression: f64,
    /// The true head turn at the frame, degrees from frontal.
    pub true_turn: f64,
    /// What the solve saw there ([`crate::NeutralView`]).
    pub view: crate::NeutralView,
}

/// The left/right twin of a shape name (`_L` ↔ `_R`), if the rig has it.
pub fn twin(rig_names: &[String], s: usize) -> Option<usize> {
    let n = &rig_names[s];
    let other = if let Some(b) = n.strip_suffix("_L") {
        format!("{b}_R")
    } else if let Some(b) = n.strip_suffix("_R") {
        format!("{b}_L")
    } else {
        return None;
    };
    rig_names.iter().position(|m| *m == other)
}

/// The RMS second difference of one series (the house's jitter, one segment).
fn rms2(x: &[f64]) -> f64 {
    let m = DMatrix::from_row_slice(1, x.len(), x);
    keyshape_core::solve::jitter::weight_jitter(&m, std::slice::from_ref(&(0..x.len())))
}

/// The shift in −`max`..=`max` frames by which `got` trails `truth` (the smoothing study's
/// cross-correlation lag, one segment).
fn lag(got: &[f64], truth: &[f64], max: i64) -> i64 {
    let (a, b) = (
        DMatrix::from_row_slice(1, got.len(), got),
        DMatrix::from_row_slice(1, truth.len(), truth),
    );
    keyshape_core::stats::lag(&a, &b, std::slice::from_ref(&(0..got.len())), max)
}

/// Every shape's accuracy of `solved` against `truth` (both k × frames, rig order), and the
/// summary.
pub fn measure(
    names: &[String],
    truth: &DMatrix<f64>,
    solved: &DMatrix<f64>,
) -> (Vec<ShapeAccuracy>, Summary) {
    let frames = truth.ncols();
    let mut rows = Vec::new();
    for s in 0..names.len() {
        let t: Vec<f64> = truth.row(s).iter().copied().collect();
        let g: Vec<f64> = solved.row(s).iter().copied().collect();
        let active = t.iter().any(|v| *v > 1e-9);
        let err: Vec<f64> = g.iter().zip(&t).map(|(a, b)| a - b).collect();
        let mae = err.iter().map(|e| e.abs()).sum::<f64>() / frames as f64;
        let rmse = (err.iter().map(|e| e * e).sum::<f64>() / frames as f64).sqrt();
        let at_peak: Vec<f64> = (0..frames)
            .filter(|&f| t[f] >= 0.99)
            .map(|f| g[f])
            .collect();
        let peak_reach =
            (!at_peak.is_empty()).then(|| at_peak.iter().sum::<f64>() / at_peak.len() as f64);
        let twin_leakage = twin(names, s).and_then(|o| {
            let on: Vec<f64> = (0..frames)
                .filter(|&f| t[f] >= 0.5 && truth[(o, f)] <= 1e-9)
                .map(|f| solved[(o, f)])
                .collect();
            (!on.is_empty()).then(|| on.iter().sum::<f64>() / on.len() as f64)
        });
        rows.push(ShapeAccuracy {
            shape: names[s].clone(),
            active,
            r: if active {
                correlation(&g, &t)
            } else {
                f64::NAN
            },
            mae,
            rmse,
            peak_reach,
            twin_leakage,
            idle_activation: (!active).then(|| g.iter().copied().fold(0.0, f64::max)),
            jitter: rms2(&g),
            true_jitter: rms2(&t),
            lag: active.then(|| lag(&g, &t, 10)),
        });
    }
    let act: Vec<&ShapeAccuracy> = rows.iter().filter(|r| r.active).collect();
    let mean_r = act
        .iter()
        .map(|r| if r.r.is_nan() { 0.0 } else { r.r })
        .sum::<f64>()
        / act.len().max(1) as f64;
    let worst = act
        .iter()
        .min_by(|a, b| a.r.total_cmp(&b.r))
        .map_or((f64::NAN, String::new()), |r| (r.r, r.shape.clone()));
    let all_sq: f64 = (truth - solved).iter().map(|e| e * e).sum();
    let idle = rows
        .iter()
        .filter_map(|r| r.idle_activation.map(|v| (v, r.shape.clone())))
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .unwrap_or((0.0, String::new()));
    let summary = Summary {
        mean_r,
        worst_r: worst.0,
        worst_shape: worst.1,
        rmse: (all_sq / truth.len().max(1) as f64).sqrt(),
        max_idle: idle.0,
        max_idle_shape: idle.1,
        max_twin_leakage: rows
            .iter()
            .filter_map(|r| r.twin_leakage)
            .fold(0.0, f64::max),
        min_peak_reach: rows
            .iter()
            .filter_map(|r| r.peak_reach)
            .min_by(f64::total_cmp),
        max_abs_lag: rows
            .iter()
            .filter_map(|r| r.lag.map(i64::abs))
            .max()
            .unwrap_or(0),
        neutral: None,
        map: None,
    };
    (rows, summary)
}
