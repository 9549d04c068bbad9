//! What a retargeting gives: the weights, the source and target shapes, and their errors.

use nalgebra::DMatrix;

/// Everything a retargeting run produced.
#[derive(Debug, Clone)]
pub struct Retargeted {
    /// Key columns per region (one entry without regions).
    pub keys: Vec<Vec<usize>>,
    /// Weights per region, k × frames.
    pub weights: Vec<DMatrix<f64>>,
    /// Source reconstruction (aligned), n × frames.
    pub source: DMatrix<f64>,
    /// Retargeted target (aligned frame), n_t × frames.
    pub target: DMatrix<f64>,
    /// `G(Q_t)` when the target is a warp.
    pub truth: Option<DMatrix<f64>>,
    /// Per frame `‖q − q̂‖²`.
    pub source_sq: Vec<f64>,
    /// Per frame `‖B_t − G(Q_t)‖²` when there is a truth.
    pub target_sq: Option<Vec<f64>>,
    /// Points per source shape.
    pub points: usize,
    /// Points per target shape.
    pub target_points: usize,
    /// Frames (summed over regions) where NNLS/bounded hit its iteration cap.
    pub unconverged: usize,
}

impl Retargeted {
    /// Source RMS per point.
    pub fn source_rms(&self) -> f64 {
        rms(&self.source_sq, self.points)
    }

    /// Target-domain RMS per point against `G(Q_t)`.
    pub fn target_rms(&self) -> Option<f64> {
        self.target_sq.as_ref().map(|e| rms(e, self.target_points))
    }

    /// Per-frame target-domain RMS.
    pub fn target_rms_per_frame(&self) -> Option<Vec<f64>> {
        self.target_sq.as_ref().map(|e| {
            e.iter()
                .map(|v| (v / self.target_points as f64).sqrt())
                .collect()
        })
    }

    /// Jitter: RMS second difference of the weights over time (all regions, the whole
    /// sequence as one segment; see [`keyshape_core::solve::jitter`]).
    pub fn jitter(&self) -> f64 {
        jitter(&self.weights)
    }

    /// Share of negative weights.
    pub fn negative_share(&self) -> f64 {
        let max = self
            .weights
            .iter()
            .flat_map(|w| w.iter())
            .fold(0.0f64, |m, v| m.max(v.abs()));
        let tol = keyshape_core::decompose::NEGATIVE_TOLERANCE * max;
        let (neg, all) = self.weights.iter().fold((0usize, 0usize), |(n, a), w| {
            (n + w.iter().filter(|v| **v < -tol).count(), a + w.len())
        });
        neg as f64 / all.max(1) as f64
    }
}

fn rms(sq: &[f64], points: usize) -> f64 {
    (sq.iter().sum::<f64>() / (sq.len() * points).max(1) as f64).sqrt()
}

/// RMS second difference over time of every weight track, the whole sequence as one
/// segment ([`keyshape_core::solve::jitter::weight_jitter_all`] takes clips into account).
pub fn jitter(weights: &[DMatrix<f64>]) -> f64 {
    let frames = weights.first().map_or(0, |w| w.ncols());
    keyshape_core::solve::jitter::weight_jitter_all(weights, std::slice::from_ref(&(0..frames)))
}
