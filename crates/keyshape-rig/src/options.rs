//! How a rig is solved: the identity, the neutral, the landmark weights, the priors and
//! their recommended values.

use crate::LANDMARKS;
use keyshape_core::error::{Error, Result};
use keyshape_core::solve::Solver;
use std::ops::Range;

/// The Huber threshold of [`RigOptions::robust`], in median landmark RMS residuals.
pub const ROBUST_C: f64 = 1.0;

/// How the person's neutral face is told apart from the rig's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Identity {
    /// The rig as it is.
    None,
    /// The neutral frame's 2-D residual, lifted into the rig at that frame's camera and
    /// added to the rig's neutral landmarks; the shapes' offsets are the rig's.
    Offset,
    /// The same neutral, and the shapes' offsets carried over by paper 004's multiquadric
    /// RBF from the rig's neutral landmarks onto the person's (`F(N + Dₖ) − F(N)`, with F the
    /// identity plus an RBF of the neutral's displacement), so a wider mouth gets a wider
    /// smile.
    Rbf,
}

impl std::str::FromStr for Identity {
    type Err = keyshape_core::error::Error;

    /// As [`Identity::parse`].
    fn from_str(s: &str) -> keyshape_core::error::Result<Identity> {
        Identity::parse(s)
    }
}

impl Identity {
    /// Parses `none`, `offset` or `rbf`.
    pub fn parse(s: &str) -> Result<Identity> {
        match s.trim().to_ascii_lowercase().as_str() {
            "none" => Ok(Identity::None),
            "offset" => Ok(Identity::Offset),
            "rbf" => Ok(Identity::Rbf),
            _ => Err(Error::bad_setting(
                "identity",
                s,
                format!("unknown identity '{s}' (expected none, offset or rbf)"),
            )),
        }
    }

    /// The name [`Identity::parse`] reads.
    pub fn name(self) -> &'static str {
        match self {
            Identity::None => "none",
            Identity::Offset => "offset",
            Identity::Rbf => "rbf",
        }
    }
}

/// The iBUG-68 landmark groups `--landmark-weight` names, with their landmark ranges.
pub const LANDMARK_GROUPS: [(&str, Range<usize>); 6] = [
    ("jaw", 0..17),
    ("brows", 17..27),
    ("nose", 27..36),
    ("eyes", 36..48),
    ("lips", 48..60),
    ("mouth", 60..68),
];

/// Per-landmark weights from `GROUP=W` settings (GROUP a name of [`LANDMARK_GROUPS`] or a
/// landmark number 0–67; later settings win over earlier ones); unnamed landmarks weigh 1.
pub fn landmark_weights<S: AsRef<str>>(settings: &[S]) -> Result<[f64; LANDMARKS]> {
    let mut lw = [1.0; LANDMARKS];
    for s in settings {
        let s = s.as_ref();
        let (group, w) = s.split_once('=').ok_or_else(|| {
            Error::bad_setting("landmark_weights", s, format!(
                "landmark weight '{s}': expected GROUP=W (GROUP one of jaw, brows, nose, eyes, lips, mouth or a landmark number)"
            ))
        })?;
        let (group, w) = (group.trim(), w.trim());
        let w: f64 = w
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite() && *v >= 0.0)
            .ok_or_else(|| {
                Error::bad_setting(
                    "landmark_weights",
                    s,
                    format!(
                        "landmark weight '{s}': the weight must be a finite number ≥ 0, not '{w}'"
                    ),
                )
            })?;
        let range = match LANDMARK_GROUPS.iter().find(|(n, _)| *n == group) {
            Some((_, r)) => r.clone(),
            None => match group.parse::<usize>() {
                Ok(i) if i < LANDMARKS => i..i + 1,
                _ => {
                    return Err(Error::bad_setting("landmark_weights", s, format!(
                        "landmark weight '{s}': '{group}' is not a group (jaw, brows, nose, eyes, lips, mouth) or a landmark number 0–67"
                    )))
                }
            },
        };
        lw[range].iter_mut().for_each(|v| *v = w);
    }
    Ok(lw)
}

/// Which frame is the person's neutral.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Neutral {
    /// The frame whose identity best explains the performance (lowest landmark error of a
    /// solve from it; see [`NEUTRAL_CANDIDATES`](crate::NEUTRAL_CANDIDATES)).
    Auto,
    /// The frame whose first-pass weights (the rig as it is, every shape free) sum lowest.
    LeastActive,
    /// This column of the track.
    Column(usize),
    /// The columns `start..end`, a recorded neutral lead-in: each frame's residual from the
    /// rig's neutral, at its own head pose, averaged into one identity (the landmark noise
    /// of one frame becomes the person's shape otherwise; averaging n frames divides its
    /// variance by n).
    Span(usize, usize),
}

/// The unit of [`RigOptions::smooth`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SmoothUnit {
    /// Squared track units (pixels) per unit weight²: λ as given.
    #[default]
    Pixels,
    /// A fraction of the squared inter-ocular distance (the magnitude prior's, from the
    /// same frames): λ × IOD². A face twice the size in the image needs four times the λ
    /// in pixels for the same pull; in this unit it needs the same.
    Iod,
}

/// Options of [`solve_rig`](crate::solve_rig).
#[derive(Debug, Clone, Copy)]
pub struct RigOptions {
    /// The weights' constraint.
    pub solver: Solver,
    /// The person's identity.
    pub identity: Identity,
    /// The neutral frame (with an identity other than `None`).
    pub neutral: Neutral,
    /// Shapes whose determination (the share of their landmark motion that no combination
    /// of the other shapes explains, at the neutral frame's camera) is below this are frozen
    /// at 0.
    pub min_determination: f64,
    /// Gauss–Newton steps per frame at most.
    pub max_steps: usize,
    /// Temporal prior λ (≥ 0, squared image units per unit weight²; 0 is off), in
    /// `smooth_mode`: causal, each frame minimises its landmark error plus
    /// `λ‖w − w_prev‖²`, `w_prev` the previous frame's weights; offline, each clip's weights
    /// minimise the sum of the frames' errors plus `λ Σ_t ‖w_t − w_{t−1}‖²` (see
    /// [`temporal`](crate::temporal)). Never across clips.
    pub smooth: f64,
    /// What `smooth` is measured in: squared track units (pixels), or a fraction of the
    /// squared inter-ocular distance the magnitude prior is scaled by, so that the same
    /// setting pulls alike on a small face and a large one ([`RigOptions::lambda`]).
    pub smooth_unit: SmoothUnit,
    /// Offline (the whole clip, zero phase) or causal (the past only, for live use).
    pub smooth_mode: keyshape_core::solve::temporal::SmoothMode,
    /// Per landmark (iBUG order), the weight of its squared error in the fit (≥ 0; all 1 is
    /// the plain least-squares fit). The camera's starting fit ignores them.
    pub landmark_weights: [f64; LANDMARKS],
    /// Robust landmark weights: after the solve, each landmark's residual over the frames
    /// (its mean taken out: the identity's share) is measured, and landmarks the rig
    /// explains much worse than the median one — a tracker point the landmark map puts on
    /// the wrong vertex moves unlike it — are down-weighted (Huber, `min(1, cσ / sᵢ)` with
    /// σ the median landmark's RMS and c = [`ROBUST_C`]) and the track solved again, twice.
    /// Not causal (it needs the whole track).
    pub robust: bool,
    /// The magnitude prior (≥ 0): each frame minimises its landmark error plus `μ‖w‖²`,
    /// `μ = prior × IOD²`, IOD the track's median distance between the outer eye corners
    /// (landmarks 36 and 45), so the prior does not depend on the image's scale. What the
    /// landmarks cannot tell apart is settled towards zero instead of by chance.
    pub prior: f64,
    /// The offline, zero-phase temporal prior: after the solve, each clip's weights are
    /// smoothed by a Gaussian of this σ in frames, forwards and backwards alike (no lag;
    /// needs the whole file, so not for live use); 0 is off. The weights stay within their
    /// bounds (a Gaussian average of bounded weights is bounded) and the landmark error is
    /// recomputed for the smoothed weights.
    pub zero_phase: f64,
    /// The magnitude prior tapers off as a shape comes on: each shape's `μ w²` becomes
    /// `μ w² (1 − 4w/3 + w²/2)`, whose pull `2μ w (1 − w)²` is the ridge's near 0 and fades
    /// to nothing at full weight, so a shape the landmarks clearly show reaches its peak
    /// (a plain ridge shrinks every peak, most the shapes that move the landmarks least:
    /// blinks, brows). At the camera the plain-ridge solve reaches, the ridge is reweighted
    /// to `μ (1 − w)²` from the last weights and the weights solved again, [`TAPER_STEPS`]
    /// times: a local linear approximation of the penalty taken twice (Zou & Li 2008's
    /// one-step estimator, once more). Gaze shapes held by [`GAZE_DAMPING`](crate::GAZE_DAMPING) keep the plain
    /// ridge. Off without a prior.
    pub taper: bool,
    /// Causal: each frame's weights depend on that frame, the frames before it and the
    /// neutral frames only — the magnitude prior's scale is measured on the neutral frames
    /// instead of the whole track, no zero-phase or offline smoothing, and the neutral is
    /// a given frame or lead-in (not searched for over the file). What a live solve
    /// ([`live::LiveSolver`](crate::live::LiveSolver)) computes, frame by frame, for a track whose first frames are
    /// its calibration.
    pub causal: bool,
}

/// Reweightings of the tapered prior per frame ([`RigOptions::taper`]). Tuned on the
/// benchmark: one step leaves the 68-point wink peaks at 0.82, two reach 0.86; iterating to
/// the fixed point raises them little more while shapes the performance never uses climb at
/// 1 px noise (idle 0.51 → 0.62 over seeds 1–8: the penalty is not convex, and a shape
/// noise turns on loses its prior).
pub const TAPER_STEPS: usize = 2;
/// The tapered prior's reweighting stops when no weight moves by more than this.
pub const TAPER_TOLERANCE: f64 = 1e-7;

/// The magnitude prior `kslab rig` uses by default: μ = 0.0026 × IOD², 30 px² at an
/// inter-ocular distance of 107 px — tuned on the accuracy benchmark (`kslab rig-accuracy`;
/// docs/src/rig_accuracy.md, "Rig accuracy against ground truth").
pub const RECOMMENDED_PRIOR: f64 = 0.0026;

/// The magnitude prior of the live (causal) path (`kslab live`, `kslab rig --live`): μ =
/// 0.004 × IOD², tuned on `kslab rig-accuracy --live` on its own (68 points, seeds 1–20).
/// Against the offline default's 0.0026 it keeps mean r within 0.003 at 0.5 px, and at 1 px
/// the seeds on which a shape the performance never uses reaches 0.5 fall from 20 of 80 to
/// 3 (all on the smooth performance). A causal solve has no zero-phase smoothing after it
/// to calm what noise turns on; 0.006 costs smooth 0.006 of mean r at 0.5 px.
pub const LIVE_PRIOR: f64 = 0.004;

/// The causal temporal prior of the live path (`kslab live`, `kslab rig --live`), in
/// [`SmoothUnit::Iod`]: λ = 0.0026 × IOD², 30 px² at the accuracy benchmark's 107 px. Tuned
/// on `kslab rig-accuracy --live` (68 points, seeds 1–20): it brings the causal path's mean r
/// within 0.01 of the offline default's at 0.5 px on every kind, and its lag is one frame
/// (docs/src/rig_accuracy.md, "The causal path tuned on its own").
pub const LIVE_SMOOTH: f64 = 0.0026;

/// The zero-phase σ (frames) `kslab rig` uses for files by default: 1 frame, tuned on the
/// benchmark (2 frames already flattens speech-rate jaw motion).
pub const RECOMMENDED_ZERO_PHASE: f64 = 1.0;

impl RigOptions {
    /// The options that win the accuracy benchmark for an offline file: the magnitude prior
    /// (gaze held, exclusive pairs), no shape frozen, the zero-phase temporal prior.
    pub fn recommended() -> RigOptions {
        RigOptions {
            min_determination: 0.0,
            prior: RECOMMENDED_PRIOR,
            zero_phase: RECOMMENDED_ZERO_PHASE,
            taper: true,
            ..RigOptions::default()
        }
    }

    /// [`RigOptions::recommended`] for live use: causal, so no zero-phase smoothing, the
    /// live path's own magnitude prior ([`LIVE_PRIOR`]) and the causal temporal prior
    /// ([`LIVE_SMOOTH`] × IOD²).
    pub fn live() -> RigOptions {
        RigOptions {
            zero_phase: 0.0,
            causal: true,
            prior: LIVE_PRIOR,
            smooth: LIVE_SMOOTH,
            smooth_unit: SmoothUnit::Iod,
            smooth_mode: keyshape_core::solve::temporal::SmoothMode::Causal,
            ..RigOptions::recommended()
        }
    }

    /// The temporal prior's λ in squared track units, for a face whose inter-ocular
    /// distance is `iod` (the magnitude prior's: the track's median, or a causal solve's
    /// neutral frames').
    pub fn lambda(&self, iod: f64) -> f64 {
        match self.smooth_unit {
            SmoothUnit::Pixels => self.smooth,
            SmoothUnit::Iod => self.smooth * iod * iod,
        }
    }
}

impl Default for RigOptions {
    fn default() -> Self {
        RigOptions {
            solver: Solver::Bounded,
            identity: Identity::Offset,
            neutral: Neutral::Auto,
            min_determination: 0.02,
            max_steps: 50,
            smooth: 0.0,
            smooth_unit: SmoothUnit::Pixels,
            smooth_mode: keyshape_core::solve::temporal::SmoothMode::Causal,
            landmark_weights: [1.0; LANDMARKS],
            prior: 0.0,
            zero_phase: 0.0,
            taper: false,
            causal: false,
            robust: false,
        }
    }
}
