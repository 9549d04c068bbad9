//! A tracked performance solved onto a blendshape rig: the rig's 68 landmark
//! vertices under a per-frame scaled orthographic camera, fitted jointly with the shape
//! weights, warm-started from the previous frame, with the person's identity taken from a
//! neutral frame and the shapes a 2-D track cannot see frozen.
//!
//! eos's `fit_blendshapes_to_landmarks_nnls` alternates a camera fit and an NNLS solve. On
//! the 55-shape ICT rig that alternation crawls (the camera and the shapes trade motion), so
//! each step here is a Gauss–Newton step of camera and weights together, the camera's six
//! parameters eliminated by their Schur complement, backtracked with the weights solved
//! exactly (under their bounds) for each trial camera: the error never rises, and on
//! noise-free renders it converges to the rendered weights (tested to 1e-6).

pub mod accuracy;
pub mod camera;
pub mod correspondence;
mod frame;
pub mod gltf_rig;
mod identifiability;
pub mod live;
pub mod livelink;
mod neutral;
pub mod plausibility;
mod prior;
pub mod refine;
mod solve;
pub mod temporal;

use frame::{frame_depth, frame_points, FrameSolver};
pub use identifiability::{identifiability, identifiability_weighted};
pub use neutral::{
    NeutralView, NEUTRAL_CANDIDATES, NEUTRAL_LIPS_WARN, NEUTRAL_SCORED_FRAMES,
    NEUTRAL_TURN_WARN_DEG,
};
pub use prior::{is_gaze, track_iod, EXCLUSIVE, GAZE_DAMPING};
pub use solve::{solve_rig, solve_rig_observed, zero_phase};

use camera::Camera;
use keyshape_core::error::{Error, Result};
use keyshape_core::solve::Solver;
use keyshape_io::morph::MorphTargets;
use nalgebra::DMatrix;
use std::ops::Range;
use std::path::Path;

/// The Huber threshold of [`RigOptions::robust`], in median landmark RMS residuals.
pub const ROBUST_C: f64 = 1.0;

/// Landmarks per rig (iBUG / Multi-PIE 68, in that order).
pub const LANDMARKS: usize = 68;

pub use correspondence::{read_correspondence, read_landmark_vertices};
pub use keyshape_core::sequence::mediapipe_to_ibug68;

/// The `n` largest weights of one frame (at least 0.01), largest first, as "name .83"
/// — what a picture of the frame names.
pub fn largest_weights(names: &[String], w: &[f64], n: usize) -> String {
    let mut order: Vec<usize> = (0..w.len().min(names.len()))
        .filter(|&i| w[i] >= 0.01)
        .collect();
    order.sort_by(|&a, &b| w[b].total_cmp(&w[a]).then(a.cmp(&b)));
    order
        .iter()
        .take(n)
        .map(|&i| {
            format!(
                "{} {}",
                names[i],
                format!("{:.2}", w[i]).trim_start_matches('0')
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// A blendshape rig seen through its landmark vertices.
#[derive(Debug, Clone)]
pub struct Rig {
    /// Shape names, as the rig names them.
    pub names: Vec<String>,
    /// Landmark positions of the neutral face.
    pub neutral: Vec<[f64; 3]>,
    /// Per shape, the landmarks' offsets from the neutral.
    pub deltas: Vec<Vec<[f64; 3]>>,
    /// Per landmark, the track point it is read from (the tracker's numbering: iBUG 0–67,
    /// MediaPipe 0–477); the solve takes the track's points in this order.
    pub points: Vec<usize>,
    /// The track layout's point count (68, 468 or 478; see [`correspondence::LAYOUTS`]).
    pub layout: usize,
}

impl Rig {
    /// Reads the ICT FaceKit folder layout (`../shared/data/ict_facekit_face`):
    /// `neutral_face.obj`, `expressions.csv`, `expression_deltas.csv` and
    /// `landmarks_multipie68.csv`.
    pub fn read_ict(dir: &Path) -> Result<Rig> {
        let (mesh, morph, marks) = Rig::read_ict_parts(dir)?;
        Rig::from_parts(&mesh.positions, &morph, &marks)
    }

    /// The ICT folder's mesh, morph targets and landmark vertices, as read by
    /// [`Rig::read_ict`] (for exports that need the whole mesh).
    pub fn read_ict_parts(
        dir: &Path,
    ) -> Result<(keyshape_io::obj::Mesh, MorphTargets, Vec<usize>)> {
        if !dir.is_dir() {
            return Err(Error::file(
                dir,
                "is not a rig folder (neutral_face.obj, expressions.csv, expression_deltas.csv, landmarks_multipie68.csv)",
            ));
        }
        keyshape_io::atomic::register_input(dir);
        let mesh = keyshape_io::obj::read_obj(&dir.join("neutral_face.obj"))?;
        let n = mesh.positions.len();
        let marks = read_landmark_vertices(&dir.join("landmarks_multipie68.csv"), n)?;
        let morph = MorphTargets::read(
            &dir.join("expressions.csv"),
            &dir.join("expression_deltas.csv"),
            n,
        )?;
        Ok((mesh, morph, marks))
    }

    /// A rig from mesh positions, sparse morph targets and the vertices of the 68 iBUG
    /// landmarks, in landmark order.
    pub fn from_parts(
        positions: &[[f64; 3]],
        morph: &MorphTargets,
        marks: &[usize],
    ) -> Result<Rig> {
        let pairs: Vec<(usize, usize)> = marks.iter().copied().enumerate().collect();
        Rig::from_correspondence(positions, morph, 68, &pairs)
    }

    /// A rig reading a track of `layout` points (68, 468 or 478) through `pairs` (track
    /// point, mesh vertex): each named point is the landmark at its vertex; the others are
    /// left out.
    pub fn from_correspondence(
        positions: &[[f64; 3]],
        morph: &MorphTargets,
        layout: usize,
        pairs: &[(usize, usize)],
    ) -> Result<Rig> {
        correspondence::check_against_track(pairs, layout, "the rig's correspondence")?;
        if let Some(&(l, v)) = pairs.iter().find(|p| p.1 >= positions.len()) {
            return Err(Error::invalid(format!(
                "rig: landmark {l} names vertex {v}, but the mesh has {} vertices",
                positions.len()
            )));
        }
        let marks: Vec<usize> = pairs.iter().map(|p| p.1).collect();
        let neutral: Vec<[f64; 3]> = marks.iter().map(|&v| positions[v]).collect();
        for (l, p) in neutral.iter().enumerate() {
            if p.iter().any(|c| !c.is_finite()) {
                return Err(Error::invalid(format!(
                    "rig: landmark {} (vertex {}) has a non-finite position",
                    pairs[l].0, marks[l]
                )));
            }
        }
        let mut at: Vec<Vec<usize>> = vec![Vec::new(); positions.len()];
        for (l, &v) in marks.iter().enumerate() {
            at[v].push(l);
        }
        let mut deltas = vec![vec![[0.0; 3]; marks.len()]; morph.names.len()];
        for (s, d) in morph.deltas.iter().enumerate() {
            for &(v, o) in d {
                for &l in at.get(v).map_or(&[][..], Vec::as_slice) {
                    deltas[s][l] = o;
                }
            }
        }
        if morph.names.is_empty() {
            return Err(Error::invalid("rig: no shapes"));
        }
        morph
            .check_scale(positions)
            .map_err(|e| Error::invalid(format!("rig: {e}")))?;
        Ok(Rig {
            names: morph.names.clone(),
            neutral,
            deltas,
            points: pairs.iter().map(|p| p.0).collect(),
            layout,
        })
    }

    /// Number of landmarks.
    pub fn landmarks(&self) -> usize {
        self.neutral.len()
    }

    /// The landmarks (indices into [`Rig::neutral`]) of the outer eye corners, subject's
    /// right then left, if the rig reads both.
    pub fn eyes(&self) -> Option<[usize; 2]> {
        let [a, b] = correspondence::eye_corners(self.layout)?;
        let at = |p: usize| self.points.iter().position(|&q| q == p);
        Some([at(a)?, at(b)?])
    }

    /// Does the rig read an iris centre (so eye gaze moves its landmarks)?
    pub fn sees_pupils(&self) -> bool {
        self.layout == 478
            && self
                .points
                .iter()
                .any(|p| correspondence::IRIS_CENTRES.contains(p))
    }

    /// Number of shapes.
    pub fn k(&self) -> usize {
        self.names.len()
    }

    /// The landmarks posed by `w` (no clamping).
    pub fn posed(&self, w: &[f64]) -> Vec<[f64; 3]> {
        let mut out = self.neutral.clone();
        for (d, &wk) in self.deltas.iter().zip(w) {
            if wk == 0.0 {
                continue;
            }
            for (o, dl) in out.iter_mut().zip(d) {
                for a in 0..3 {
                    o[a] += wk * dl[a];
                }
            }
        }
        out
    }

    /// Renders a 2-D track (image axes, y down) of the rig posed by `weights` (k × frames)
    /// under per-frame cameras: the oracle of the recovery tests and the synthetic study.
    pub fn render(&self, weights: &DMatrix<f64>, cams: &[Camera]) -> DMatrix<f64> {
        let mut out = DMatrix::zeros(2 * self.landmarks(), weights.ncols());
        for f in 0..weights.ncols() {
            let w: Vec<f64> = weights.column(f).iter().copied().collect();
            for (i, p) in self.posed(&w).iter().enumerate() {
                let u = cams[f].project(p);
                out[(2 * i, f)] = u[0];
                out[(2 * i + 1, f)] = -u[1];
            }
        }
        out
    }
}

impl<'a> From<&'a Rig> for std::borrow::Cow<'a, Rig> {
    fn from(r: &'a Rig) -> Self {
        std::borrow::Cow::Borrowed(r)
    }
}

impl From<Rig> for std::borrow::Cow<'static, Rig> {
    fn from(r: Rig) -> Self {
        std::borrow::Cow::Owned(r)
    }
}

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
    /// solve from it; see [`NEUTRAL_CANDIDATES`]).
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

/// Options of [`solve_rig`].
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
    /// [`temporal`]). Never across clips.
    pub smooth: f64,
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
    /// one-step estimator, once more). Gaze shapes held by [`GAZE_DAMPING`] keep the plain
    /// ridge. Off without a prior.
    pub taper: bool,
    /// Causal: each frame's weights depend on that frame, the frames before it and the
    /// neutral frames only — the magnitude prior's scale is measured on the neutral frames
    /// instead of the whole track, no zero-phase or offline smoothing, and the neutral is
    /// a given frame or lead-in (not searched for over the file). What a live solve
    /// ([`live::LiveSolver`]) computes, frame by frame, for a track whose first frames are
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

    /// [`RigOptions::recommended`] for live use: causal, so no zero-phase smoothing, and
    /// the live path's own magnitude prior ([`LIVE_PRIOR`]).
    pub fn live() -> RigOptions {
        RigOptions {
            zero_phase: 0.0,
            causal: true,
            prior: LIVE_PRIOR,
            ..RigOptions::recommended()
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

/// How well a 2-D view determines one shape.
#[derive(Debug, Clone, PartialEq)]
pub struct ShapeReport {
    /// The rig's name for it.
    pub name: String,
    /// RMS landmark motion in the image at weight 1, in track units (px).
    pub image_motion: f64,
    /// `1 / (Gₖₖ (G⁻¹)ₖₖ)` over the shapes not frozen before it: 1 when no other shape moves
    /// the landmarks alike, 0 when others explain its motion entirely.
    pub determination: f64,
    /// Held at 0 by the solve.
    pub frozen: bool,
}

/// A rig solve of every frame.
#[derive(Debug, Clone)]
pub struct RigSolve {
    /// k × frames, in the rig's shape order (frozen shapes are 0).
    pub weights: DMatrix<f64>,
    /// Per frame, the fitted camera.
    pub cameras: Vec<Camera>,
    /// Per frame, RMS 2-D landmark error (track units).
    pub rms: Vec<f64>,
    /// Per frame, Gauss–Newton steps used.
    pub steps: Vec<u32>,
    /// Sweeps of the offline temporal prior (the most any clip took; 0 when it is off).
    pub sweeps: usize,
    /// Clips whose offline temporal prior stopped at [`temporal::MAX_SWEEPS`].
    pub sweeps_unconverged: usize,
    /// Frames whose steps stopped at the cap.
    pub unconverged: usize,
    /// Per shape, identifiability.
    pub shapes: Vec<ShapeReport>,
    /// The neutral column of each clip's identity (empty with `Identity::None`; one with
    /// an explicit neutral).
    pub neutrals: Vec<usize>,
    /// Per entry of `neutrals`, how that frame looks (head pose, the expression the rig as
    /// it is sees in it); for a lead-in, its middle frame.
    pub neutral_views: Vec<NeutralView>,
    /// The rig each range of frames was solved with: the person's (the rig with the
    /// identity applied), or the rig itself with `Identity::None`.
    pub people: Vec<(Range<usize>, Rig)>,
}

impl RigSolve {
    /// The rig frame `f` was solved with (see [`RigSolve::people`]).
    pub fn person_of(&self, f: usize) -> Option<&Rig> {
        self.people
            .iter()
            .find(|(r, _)| r.contains(&f))
            .map(|(_, p)| p)
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_frame_names_its_largest_weights_largest_first() {
        let names: Vec<String> = ["a", "b", "c", "d"].iter().map(|s| s.to_string()).collect();
        assert_eq!(
            super::largest_weights(&names, &[0.2, 0.9, 0.005, 0.4], 3),
            "b .90, d .40, a .20"
        );
        assert_eq!(super::largest_weights(&names, &[0.0; 4], 3), "");
    }
}
