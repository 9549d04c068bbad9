//! The sections of an experiment file beside the curves' keys, each with its defaults: the
//! file's format in one place (the studies take these, or plain parameters made from
//! them). A key a section does not have is refused.

use keyshape_actions::intensity::{Centring, Evaluation, StudySettings};
use keyshape_actions::modes::Boundary;
use keyshape_actions::trajectory::Normalisation;
use keyshape_core::keyshapes::Method;
use keyshape_core::solve::Solver;
use serde::{Deserialize, Serialize};

use super::{method, method_name};

/// `[retarget]`: LS against NNLS through a target face.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RetargetSpec {
    /// Heuristic choosing the key frames.
    #[serde(deserialize_with = "method", serialize_with = "method_name")]
    pub method: Method,
    /// Number of key shapes.
    pub k: usize,
    /// Solvers compared (the first is the one whose distortion the strip shows).
    pub solvers: Vec<Solver>,
    /// Tracing noise levels on the built-in target, in inter-ocular distances.
    #[serde(default = "noise_free")]
    pub trace_noise: Vec<f64>,
    /// Frames in the strip of worst frames (0 = none).
    #[serde(default = "default_strip")]
    pub strip: usize,
}

/// `[modes]`: the orthogonality table (paper 002 Table 2).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModesSpec {
    /// Actions file, relative to the spec.
    pub actions: String,
    /// Modes of each model.
    #[serde(default = "default_modes")]
    pub modes: usize,
    /// Region boundaries: `blended` (the paper's, default) or `disjoint`.
    #[serde(default)]
    pub boundary: Boundary,
    /// Averaging-filter radius of blended boundaries, a fraction of the face's size.
    #[serde(default)]
    pub blend_radius: Option<f64>,
}

/// `[intensity]`: paper 002's soft-KNN intensity study, read into
/// [`StudySettings`](keyshape_actions::intensity::StudySettings); a key left out takes the
/// study's default.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IntensitySpec {
    /// Training clips, inclusive range (split evaluation only; default 1..14).
    #[serde(default)]
    pub train_clips: Option<(usize, usize)>,
    /// K of the soft KNN.
    #[serde(default = "intensity_k")]
    pub k: usize,
    /// Polynomial degree.
    #[serde(default = "intensity_degree")]
    pub degree: usize,
    /// Labelling threshold on the scores.
    #[serde(default = "intensity_threshold")]
    pub threshold: f64,
    /// Reference shape subtracted per clip: `clip-mean`, `causal` or `neutral`.
    #[serde(default)]
    pub centring: Centring,
    /// Frames of the neutral segment (`centring = "neutral"` only).
    #[serde(default)]
    pub neutral_frames: Option<usize>,
    /// `split` or `leave-one-clip-out`.
    #[serde(default)]
    pub evaluation: Evaluation,
}

impl IntensitySpec {
    /// The study's parameters.
    pub fn settings(&self) -> StudySettings {
        StudySettings {
            train_clips: self.train_clips,
            k: self.k,
            degree: self.degree,
            threshold: self.threshold,
            centring: self.centring,
            neutral_frames: self.neutral_frames,
            evaluation: self.evaluation,
        }
    }
}

/// The intensity study's defaults, from the study's own.
fn intensity_k() -> usize {
    StudySettings::default().k
}
fn intensity_degree() -> usize {
    StudySettings::default().degree
}
fn intensity_threshold() -> f64 {
    StudySettings::default().threshold
}

/// `[map]`: trajectories onto a second person's model and onto morph targets.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapSpec {
    /// Source actions file.
    pub actions: String,
    /// Second person's sequence.
    pub target_sequence: String,
    /// Second person's actions.
    pub target_actions: String,
    /// Modes of each model.
    #[serde(default = "default_modes")]
    pub modes: usize,
    /// Folder of the ICT face (optional).
    #[serde(default)]
    pub morph: Option<String>,
    /// Region boundaries: `blended` (the paper's, default) or `disjoint`.
    #[serde(default)]
    pub boundary: Boundary,
    /// Averaging-filter radius of blended boundaries, a fraction of the face's size.
    #[serde(default)]
    pub blend_radius: Option<f64>,
    /// Trajectory normalisation: `two-sided` (the paper's, default) or `one-sided`.
    #[serde(default)]
    pub normalisation: Normalisation,
}

/// Modes of each model by default.
fn default_modes() -> usize {
    10
}

/// The built-in target traced without noise.
fn noise_free() -> Vec<f64> {
    vec![0.0]
}
/// Frames in the strip of worst frames by default.
fn default_strip() -> usize {
    4
}
/// `[smooth]`: the jitter-against-error study of the temporal prior and post-filters. A filter family's setting list left out (`None`) takes its
/// defaults; a family left out of `filters` is not run, and naming its settings then is an
/// error (an option that cannot take effect).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SmoothStudySettings {
    /// Heuristic choosing the key frames.
    #[serde(
        deserialize_with = "super::method",
        serialize_with = "super::method_name"
    )]
    pub method: Method,
    /// Key shapes (default 12; refused with `hull`, which gives its own k).
    #[serde(default)]
    pub k: Option<usize>,
    /// Solver.
    #[serde(default = "nnls")]
    pub solver: Solver,
    /// λ values of the prior.
    #[serde(default = "default_lambdas")]
    pub lambdas: Vec<f64>,
    /// Post-filter families to compare: `moving-average`, `ema`, `one-euro` (default all).
    #[serde(default = "all_families")]
    pub filters: Vec<String>,
    /// Moving-average windows (odd; default 3, 5, 9, 15, 25).
    #[serde(default)]
    pub windows: Option<Vec<usize>>,
    /// Exponential moving-average factors (default 0.7, 0.5, 0.3, 0.15, 0.08).
    #[serde(default)]
    pub alphas: Option<Vec<f64>>,
    /// One Euro minimum cutoffs, Hz (each with every beta of `one_euro_betas`, speed
    /// cutoff 1 Hz; default 8, 4, 2, 1, 0.5).
    #[serde(default)]
    pub one_euro_cutoffs: Option<Vec<f64>>,
    /// One Euro betas (cutoff increase per unit of weight speed, Hz per 1/s): one curve
    /// each (default 0.05, 0.5).
    #[serde(default)]
    pub one_euro_betas: Option<Vec<f64>>,
    /// Standard deviation (frames) of the zero-phase Gaussian low-pass that makes the clean
    /// reference.
    #[serde(default = "default_sigma")]
    pub clean_sigma: f64,
}

/// The post-filter families, in the order the study runs them.
pub const FAMILIES: [&str; 3] = ["moving-average", "ema", "one-euro"];

pub(crate) fn all_families() -> Vec<String> {
    FAMILIES.iter().map(|f| f.to_string()).collect()
}
fn nnls() -> Solver {
    Solver::Nnls
}
pub(crate) fn default_lambdas() -> Vec<f64> {
    vec![1.0, 10.0, 100.0, 1000.0, 10000.0]
}
pub(crate) fn default_sigma() -> f64 {
    2.0
}

/// `[rig]`: the rig-solve study (recovery of known weights; agreement with py-feat's scores).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigStudySettings {
    /// Shapes driven in the synthetic tracks (rig names).
    #[serde(default = "default_shapes")]
    pub shapes: Vec<String>,
    /// Frames per synthetic track.
    #[serde(default = "rig_frames")]
    pub frames: usize,
    /// Landmark noise levels, standard deviation in pixels (the rig is drawn at 8 px/cm,
    /// an inter-ocular distance of about 71 px).
    #[serde(default = "rig_noise")]
    pub noise_px: Vec<f64>,
    /// Solvers compared.
    #[serde(default = "rig_solvers")]
    pub solvers: Vec<Solver>,
    /// Causal temporal priors λ also tried with the bounded solver (none by default).
    #[serde(default)]
    pub smooth: Vec<f64>,
    /// Seed of the weights and the noise.
    #[serde(default = "rig_seed")]
    pub seed: u64,
    /// Also correlate the input's own rig solve with its ARKit-style score columns
    /// (py-feat's `mouthSmileLeft` …), for each identity.
    #[serde(default)]
    pub against_input_scores: bool,
}

/// The dozen shapes the recovery study drives by default.
pub fn default_shapes() -> Vec<String> {
    [
        "jawOpen",
        "mouthSmile_L",
        "mouthSmile_R",
        "browInnerUp_L",
        "eyeBlink_L",
        "eyeBlink_R",
        "mouthRollUpper",
        "browDown_R",
        "mouthFunnel",
        "cheekPuff_L",
        "mouthStretch_L",
        "noseSneer_L",
    ]
    .map(String::from)
    .to_vec()
}
fn rig_frames() -> usize {
    300
}
fn rig_noise() -> Vec<f64> {
    vec![0.0, 0.5, 1.0, 2.0]
}
fn rig_solvers() -> Vec<Solver> {
    vec![Solver::Ls, Solver::Nnls, Solver::Bounded]
}
fn rig_seed() -> u64 {
    7
}
