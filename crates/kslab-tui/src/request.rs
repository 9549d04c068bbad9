//! What the lab asks its worker and what it gets back: the settings of a request and the
//! computed result. The state ([`super::state`]) and the worker ([`super::compute`]) both
//! use these types, so they live here and the dependency runs one way: compute → state →
//! request.

use keyshape_core::keyshapes::Method;
use keyshape_core::solve::Solver;
use nalgebra::DMatrix;

/// What the user chose.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// Point groups (`all`, `lips`, …).
    pub points: String,
    /// Key-shape heuristic.
    pub method: Method,
    /// Number of key shapes (ignored by hull).
    pub k: usize,
    /// Solver driving the target.
    pub solver: Solver,
    /// λ of the offline first-difference temporal prior (0 = off, the per-frame solve).
    pub smooth: f64,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            points: "lips".into(),
            method: Method::Spread,
            k: 12,
            solver: Solver::Nnls,
            smooth: 0.0,
        }
    }
}

/// The λ steps of the `l` / `L` keys: off, then decades (px² per unit of weight change).
pub const SMOOTH_STEPS: [f64; 8] = [0.0, 1.0, 10.0, 100.0, 1e3, 1e4, 1e5, 1e6];

/// One solver's view of the sequence.
#[derive(Debug, Clone)]
pub struct SolverView {
    /// The solver.
    pub solver: Solver,
    /// k × frames.
    pub weights: DMatrix<f64>,
    /// Source reconstruction (aligned).
    pub recon: DMatrix<f64>,
    /// Retargeted target (aligned).
    pub target: DMatrix<f64>,
    /// Per-frame source RMS.
    pub frame_rms: Vec<f64>,
    /// Per-frame target-domain RMS.
    pub frame_target_rms: Vec<f64>,
    /// Whole-sequence source RMS.
    pub source_rms: f64,
    /// Whole-sequence target RMS.
    pub target_rms: f64,
    /// Weight jitter: RMS second difference of the weights within clips
    /// ([`keyshape_core::solve::jitter`]).
    pub jitter: f64,
    /// Jitter of the retargeted target points: RMS second difference per point
    /// (units/frame²), within segments.
    pub target_jitter: f64,
}

/// A finished request.
#[derive(Debug, Clone)]
pub struct Computed {
    /// Request id.
    pub id: u64,
    /// The settings it answers.
    pub settings: Settings,
    /// Frame numbers.
    pub frames: Vec<i64>,
    /// Key columns.
    pub keys: Vec<usize>,
    /// Values per point.
    pub dims: usize,
    /// Drawing contours.
    pub polylines: Vec<Vec<usize>>,
    /// Tracked shapes (aligned).
    pub tracked: DMatrix<f64>,
    /// Ground truth G(q).
    pub truth: DMatrix<f64>,
    /// The chosen solver first, then LS and NNLS (for the split view) when different.
    pub views: Vec<SolverView>,
    /// Seconds the request took.
    pub seconds: f64,
    /// The head motion alignment removed, per frame (None when nothing was removed).
    pub head: Option<Vec<keyshape_core::align::Similarity>>,
}

impl Computed {
    /// The view of a solver, if computed.
    pub fn view(&self, s: Solver) -> Option<&SolverView> {
        self.views.iter().find(|v| v.solver == s)
    }
}
