//! A tracked performance solved onto a blendshape rig (issue 16): the rig's 68 landmark
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
pub mod gltf_rig;
pub mod livelink;
pub mod study;
pub mod temporal;

use crate::cosker::morph::MorphTargets;
use crate::error::{Error, Result};
use crate::retarget::rbf::Rbf;
use crate::solve::active_set::{self, Bound, Gram, Workspace};
use crate::solve::chol::solve_spd;
use crate::solve::Solver;
use camera::{fit_camera, Camera};
use nalgebra::DMatrix;
use std::ops::Range;
use std::path::Path;

/// Landmarks per rig (iBUG / Multi-PIE 68, in that order).
pub const LANDMARKS: usize = 68;

pub use crate::sequence::mediapipe_to_ibug68;
pub use correspondence::{read_correspondence, read_landmark_vertices};

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
    pub fn read_ict_parts(dir: &Path) -> Result<(crate::io::obj::Mesh, MorphTargets, Vec<usize>)> {
        if !dir.is_dir() {
            return Err(Error::file(
                dir,
                "is not a rig folder (neutral_face.obj, expressions.csv, expression_deltas.csv, landmarks_multipie68.csv)",
            ));
        }
        let mesh = crate::io::obj::read_obj(&dir.join("neutral_face.obj"))?;
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

impl Identity {
    /// Parses `none`, `offset` or `rbf`.
    pub fn parse(s: &str) -> Result<Identity> {
        match s.trim().to_ascii_lowercase().as_str() {
            "none" => Ok(Identity::None),
            "offset" => Ok(Identity::Offset),
            "rbf" => Ok(Identity::Rbf),
            _ => Err(Error::invalid(format!(
                "unknown identity '{s}' (expected none, offset or rbf)"
            ))),
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
            Error::invalid(format!(
                "landmark weight '{s}': expected GROUP=W (GROUP one of jaw, brows, nose, eyes, lips, mouth or a landmark number)"
            ))
        })?;
        let (group, w) = (group.trim(), w.trim());
        let w: f64 = w
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite() && *v >= 0.0)
            .ok_or_else(|| {
                Error::invalid(format!(
                    "landmark weight '{s}': the weight must be a finite number ≥ 0, not '{w}'"
                ))
            })?;
        let range = match LANDMARK_GROUPS.iter().find(|(n, _)| *n == group) {
            Some((_, r)) => r.clone(),
            None => match group.parse::<usize>() {
                Ok(i) if i < LANDMARKS => i..i + 1,
                _ => {
                    return Err(Error::invalid(format!(
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
    pub smooth_mode: crate::solve::temporal::SmoothMode,
    /// Per landmark (iBUG order), the weight of its squared error in the fit (≥ 0; all 1 is
    /// the plain least-squares fit). The camera's starting fit ignores them.
    pub landmark_weights: [f64; LANDMARKS],
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
/// README, "Rig accuracy against ground truth").
pub const RECOMMENDED_PRIOR: f64 = 0.0026;

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

    /// [`RigOptions::recommended`] for live use: causal, so no zero-phase smoothing.
    pub fn live() -> RigOptions {
        RigOptions {
            zero_phase: 0.0,
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
            smooth_mode: crate::solve::temporal::SmoothMode::Causal,
            landmark_weights: [1.0; LANDMARKS],
            prior: 0.0,
            zero_phase: 0.0,
            taper: false,
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

/// The per-frame Gram blocks `Σᵢ D_{k,i,a} D_{l,i,b}` of a rig, reused by every frame.
struct Blocks {
    k: usize,
    /// (a, a) blocks, then (a, b) + (b, a) for a < b: (0,1), (0,2), (1,2).
    g: [Vec<f64>; 6],
    /// Flat deltas, k × (68·3), row-major.
    d: Vec<f64>,
    /// Per landmark, the weight of its squared error.
    lw: Vec<f64>,
}

impl Blocks {
    /// `lw`: per landmark, the weight of its squared error.
    fn new(deltas: &[Vec<[f64; 3]>], lw: &[f64]) -> Blocks {
        let k = deltas.len();
        let n = deltas.first().map_or(0, Vec::len);
        let mut d = vec![0.0; k * n * 3];
        for (s, ds) in deltas.iter().enumerate() {
            for (i, o) in ds.iter().enumerate() {
                d[s * n * 3 + i * 3..s * n * 3 + i * 3 + 3].copy_from_slice(o);
            }
        }
        let pair = |a: usize, b: usize| {
            let mut m = vec![0.0; k * k];
            for p in 0..k {
                for q in 0..k {
                    let mut v = 0.0;
                    for (i, wi) in lw.iter().enumerate().take(n) {
                        v += wi * d[p * n * 3 + i * 3 + a] * d[q * n * 3 + i * 3 + b];
                    }
                    m[p * k + q] = v;
                }
            }
            m
        };
        let sym = |a: usize, b: usize| {
            let (x, y) = (pair(a, b), pair(b, a));
            x.iter().zip(&y).map(|(u, v)| u + v).collect::<Vec<f64>>()
        };
        Blocks {
            k,
            g: [
                pair(0, 0),
                pair(1, 1),
                pair(2, 2),
                sym(0, 1),
                sym(0, 2),
                sym(1, 2),
            ],
            d,
            lw: lw.to_vec(),
        }
    }

    /// `AᵀWA` for camera `c`: `s² Σ M_ab G^{ab}` with `M = R₂ᵀ R₂ + wz r₃ r₃ᵀ` (`wz` the
    /// weight of the depth rows, 0 for a 2-D track).
    fn gram(&self, c: &Camera, wz: f64, out: &mut [f64]) {
        let r = &c.r;
        let m = |a: usize, b: usize| {
            r[(0, a)] * r[(0, b)] + r[(1, a)] * r[(1, b)] + wz * r[(2, a)] * r[(2, b)]
        };
        let coef = [m(0, 0), m(1, 1), m(2, 2), m(0, 1), m(0, 2), m(1, 2)];
        let s2 = c.s * c.s;
        let f = coef.map(|cf| s2 * cf);
        let [g0, g1, g2, g3, g4, g5] = &self.g;
        for (i, o) in out.iter_mut().enumerate() {
            *o = f[0] * g0[i]
                + f[1] * g1[i]
                + f[2] * g2[i]
                + f[3] * g3[i]
                + f[4] * g4[i]
                + f[5] * g5[i];
        }
    }

    /// `AᵀWr` for camera `c` and per-landmark image residuals `res` (y up), with the depth
    /// residuals `dres` weighted by `wz` when the track has depth.
    fn rhs(&self, c: &Camera, res: &[[f64; 2]], dres: Option<(&[f64], f64)>, out: &mut [f64]) {
        let n = res.len();
        let r = &c.r;
        let mut v = vec![0.0; n * 3];
        for (i, e) in res.iter().enumerate() {
            let ez = dres.map_or(0.0, |(d, wz)| wz * d[i]);
            for a in 0..3 {
                v[i * 3 + a] =
                    self.lw[i] * c.s * (r[(0, a)] * e[0] + r[(1, a)] * e[1] + r[(2, a)] * ez);
            }
        }
        for (p, o) in out.iter_mut().enumerate().take(self.k) {
            *o = dot(&self.d[p * n * 3..(p + 1) * n * 3], &v);
        }
    }
}

/// `Σ aᵢ bᵢ` over equal-length slices, in four running sums (which the compiler keeps in
/// vector registers; one running sum would serialise every addition).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    let mut acc = [0.0; 4];
    for (x, y) in ca.zip(cb) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// The track's median distance between the outer eye corners (`eyes`: the two landmarks,
/// as [`Rig::eyes`] gives them; iBUG 36 and 45 on a 68-point track), the scale the
/// magnitude prior is given in.
pub fn track_iod(track: &DMatrix<f64>, eyes: [usize; 2]) -> f64 {
    let [a, b] = eyes;
    let mut d: Vec<f64> = (0..track.ncols())
        .map(|f| {
            let (dx, dy) = (
                track[(2 * b, f)] - track[(2 * a, f)],
                track[(2 * b + 1, f)] - track[(2 * a + 1, f)],
            );
            (dx * dx + dy * dy).sqrt()
        })
        .collect();
    d.sort_by(f64::total_cmp);
    d.get(d.len() / 2).copied().unwrap_or(0.0)
}

/// How much more the magnitude prior holds the gaze shapes (`eyeLook*`) when the rig reads
/// no iris (iBUG 68, MediaPipe 468): eye gaze then moves the landmarks only through the
/// lids, and a free gaze shape explains lid and brow motion instead of the shapes that made
/// it. With iris centres (478 points) the gaze shapes are held like any other.
pub const GAZE_DAMPING: f64 = 100.0;

/// Is this a gaze shape (ARKit's eyeLookIn/Out/Up/Down)?
pub fn is_gaze(name: &str) -> bool {
    name.starts_with("eyeLook")
}

/// Pairs of shapes that undo each other and are never on together in a performance: the
/// jaw and the mouth to either side, smile against frown, blink against wide, and each eye's
/// gaze in against out and up against down (ARKit names, one side each).
pub const EXCLUSIVE: [(&str, &str); 12] = [
    ("jawLeft", "jawRight"),
    ("mouthLeft", "mouthRight"),
    ("mouthSmile_L", "mouthFrown_L"),
    ("mouthSmile_R", "mouthFrown_R"),
    ("eyeBlink_L", "eyeWide_L"),
    ("eyeBlink_R", "eyeWide_R"),
    ("eyeLookIn_L", "eyeLookOut_L"),
    ("eyeLookIn_R", "eyeLookOut_R"),
    ("eyeLookUp_L", "eyeLookDown_L"),
    ("eyeLookUp_R", "eyeLookDown_R"),
    ("mouthRollLower", "mouthShrugLower"),
    ("mouthRollUpper", "mouthShrugUpper"),
];

/// The [`EXCLUSIVE`] pairs among the free shapes, as free indices with their γ.
fn exclusive_pairs(rig: &Rig, free: &[usize], ridge: &[f64]) -> Vec<(usize, usize, f64)> {
    let at = |name: &str| free.iter().position(|&s| rig.names[s] == name);
    EXCLUSIVE
        .iter()
        .filter_map(|(a, b)| {
            let (a, b) = (at(a)?, at(b)?);
            Some((a, b, 2.0 * (ridge[a] * ridge[b]).sqrt()))
        })
        .filter(|p| p.2 > 0.0)
        .collect()
}

/// Per free shape (`free`, rig order), the magnitude prior's μ: `opts.prior × IOD²`, times
/// [`GAZE_DAMPING`] for gaze shapes.
fn magnitude_prior(track: &DMatrix<f64>, opts: &RigOptions, rig: &Rig, free: &[usize]) -> Vec<f64> {
    let mu = match rig.eyes() {
        Some(eyes) => opts.prior * track_iod(track, eyes).powi(2),
        // solve_rig refuses a prior without the eye corners.
        None => 0.0,
    };
    let damp = !rig.sees_pupils();
    free.iter()
        .map(|&s| {
            if damp && is_gaze(&rig.names[s]) {
                GAZE_DAMPING * mu
            } else {
                mu
            }
        })
        .collect()
}

/// Per free shape, does its magnitude prior taper ([`RigOptions::taper`])? Every shape with
/// a prior but the gaze shapes [`GAZE_DAMPING`] holds.
fn tapering(rig: &Rig, opts: &RigOptions, free: &[usize], ridge: &[f64]) -> Vec<bool> {
    let damped = !rig.sees_pupils();
    free.iter()
        .zip(ridge)
        .map(|(&s, &mu)| opts.taper && mu > 0.0 && !(damped && is_gaze(&rig.names[s])))
        .collect()
}

/// Frame `f` of a depth track (one row per landmark, towards the viewer), if there is one.
fn frame_depth(depth: Option<&DMatrix<f64>>, f: usize) -> Option<Vec<f64>> {
    depth.map(|d| d.column(f).iter().copied().collect())
}

/// The track's frame `f` as image points with y up.
fn frame_points(track: &DMatrix<f64>, f: usize) -> Vec<[f64; 2]> {
    (0..track.nrows() / 2)
        .map(|i| [track[(2 * i, f)], -track[(2 * i + 1, f)]])
        .collect()
}

/// One frame's solver state, reused from frame to frame (the warm start).
struct FrameSolver<'a> {
    rig: &'a Rig,
    blocks: Blocks,
    /// Shapes solved for (not frozen), in rig order.
    free: Vec<usize>,
    solver: Solver,
    max_steps: usize,
    w: Vec<f64>,
    state: Vec<Bound>,
    ws: Workspace,
    cam: Option<Camera>,
    /// The causal temporal prior: λ and the previous frame's weights (free shapes), which
    /// each frame's weights are pulled towards (`λ‖w − w_prev‖²` added to the error).
    lambda: f64,
    prev: Option<Vec<f64>>,
    /// The magnitude prior: per free shape, μᵢ in `Σ μᵢ wᵢ²` added to the error.
    ridge: Vec<f64>,
    /// Mutually exclusive pairs (free indices a, b) and γ in `γ w_a w_b` added to the error:
    /// with γ = 2√(μ_a μ_b) the pair's prior is `(√μ_a w_a + √μ_b w_b)²`, convex, and shapes
    /// that undo each other (smile and frown) pay for being on together.
    pairs: Vec<(usize, usize, f64)>,
    /// The frame's depth observations (towards the viewer, track units) when the track has
    /// depth (`--dims 3`): each landmark's third row, `s r₃·p + tz`, is fitted too.
    depth: Option<Vec<f64>>,
    /// The depth offset (MediaPipe's z has its origin near the head's centre).
    tz: f64,
    /// The weight of a depth row's squared error against an image row's.
    depth_weight: f64,
    /// Per free shape, does the magnitude prior taper off ([`RigOptions::taper`])?
    taper: Vec<bool>,
}

impl<'a> FrameSolver<'a> {
    fn new(rig: &'a Rig, free: Vec<usize>, solver: Solver, max_steps: usize, lw: &[f64]) -> Self {
        let sub: Vec<Vec<[f64; 3]>> = free.iter().map(|&s| rig.deltas[s].clone()).collect();
        let m = free.len();
        FrameSolver {
            rig,
            blocks: Blocks::new(&sub, lw),
            free,
            solver,
            max_steps,
            w: vec![0.0; m],
            state: vec![Bound::Lower; m],
            ws: Workspace::new(m),
            cam: None,
            lambda: 0.0,
            prev: None,
            ridge: vec![0.0; m],
            pairs: Vec::new(),
            depth: None,
            tz: 0.0,
            depth_weight: 1.0,
            taper: vec![false; m],
        }
    }

    /// The depth rows' weight: `depth_weight` with depth, 0 without.
    fn wz(&self) -> f64 {
        if self.depth.is_some() {
            self.depth_weight
        } else {
            0.0
        }
    }

    /// The depth residuals `d − (s r₃·p + tz)` of the posed landmarks `x` under `cam`.
    fn depth_residuals(&self, cam: &Camera, x: &[[f64; 3]]) -> Option<Vec<f64>> {
        let d = self.depth.as_ref()?;
        Some(
            x.iter()
                .zip(d)
                .map(|(p, z)| z - (cam.depth(p) + self.tz))
                .collect(),
        )
    }

    /// The depth offset that best fits the current weights under `cam` (the mean residual).
    fn fit_tz(&mut self, cam: &Camera) {
        self.tz = 0.0;
        let x = self.rig.posed(&self.full_weights());
        if let Some(r) = self.depth_residuals(cam, &x) {
            self.tz = r.iter().sum::<f64>() / r.len().max(1) as f64;
        }
    }

    fn full_weights(&self) -> Vec<f64> {
        let mut w = vec![0.0; self.rig.k()];
        for (j, &s) in self.free.iter().enumerate() {
            w[s] = self.w[j];
        }
        w
    }

    /// The squared landmark error of the current weights under `cam`, each landmark's
    /// term weighted by `lw` (all 1: the plain error).
    fn sq_error_with(&self, cam: &Camera, u: &[[f64; 2]], lw: &[f64]) -> f64 {
        let posed = self.rig.posed(&self.full_weights());
        let image: f64 = posed
            .iter()
            .zip(u)
            .zip(lw)
            .map(|((p, q), wi)| {
                let e = cam.project(p);
                wi * ((e[0] - q[0]).powi(2) + (e[1] - q[1]).powi(2))
            })
            .sum();
        let depth = self.depth_residuals(cam, &posed).map_or(0.0, |r| {
            self.depth_weight * r.iter().zip(lw).map(|(e, wi)| wi * e * e).sum::<f64>()
        });
        image + depth
    }

    /// The plain squared landmark error (what is reported).
    fn sq_error(&self, cam: &Camera, u: &[[f64; 2]]) -> f64 {
        let posed = self.rig.posed(&self.full_weights());
        posed
            .iter()
            .zip(u)
            .map(|(p, q)| {
                let e = cam.project(p);
                (e[0] - q[0]).powi(2) + (e[1] - q[1]).powi(2)
            })
            .sum()
    }

    /// What the steps minimise: the weighted squared landmark error plus the prior's term.
    fn objective(&self, cam: &Camera, u: &[[f64; 2]]) -> f64 {
        let prior = match &self.prev {
            Some(p) if self.lambda > 0.0 => {
                self.lambda
                    * self
                        .w
                        .iter()
                        .zip(p)
                        .map(|(a, b)| (a - b).powi(2))
                        .sum::<f64>()
            }
            _ => 0.0,
        };
        let magnitude: f64 = self
            .w
            .iter()
            .zip(&self.ridge)
            .map(|(w, r)| r * w * w)
            .sum::<f64>()
            + self
                .pairs
                .iter()
                .map(|&(a, b, g)| g * self.w[a] * self.w[b])
                .sum::<f64>();
        self.sq_error_with(cam, u, &self.blocks.lw) + prior + magnitude
    }

    /// One Gauss–Newton step of camera and weights together, linearised at the current
    /// camera `cam` and weights: the camera's six parameters (scale, a small rotation ω with
    /// `R ← R exp([ω]×)`, translation) are eliminated by their Schur complement, the weights
    /// solved under their bounds on what is left (warm-started active set), then the camera
    /// step recovered. Returns the camera the full step reaches.
    fn step(&mut self, cam: &Camera, u: &[[f64; 2]]) -> (Camera, f64) {
        let m = self.free.len();
        let x = self.rig.posed(&self.full_weights());
        let n = u.len();
        let r = &cam.r;
        let lw = &self.blocks.lw;
        // With depth, a third row per landmark (`s r₃·p + tz`) and a seventh camera
        // parameter, the depth offset tz.
        let dres = self.depth_residuals(cam, &self.rig.neutral);
        let (rows, np) = if dres.is_some() { (3, 7) } else { (2, 6) };
        let wz = self.wz();
        // The model is linear in w: the right side is the residual plus A·w, and with
        // A·w = s R (x − N) that is the residual of the neutral, u − proj(N).
        //
        // Hcw = Jᵀ W A and bw = Aᵀ W r never form A (rows per landmark × m): each of the
        // camera's Jacobian rows, and the right side, is pulled back through s R onto the
        // rig's coordinates (`v`, np + 1 rows of 3 per landmark), and then met with every
        // shape's deltas in one contiguous dot product.
        let mut hcc = DMatrix::<f64>::zeros(np, np);
        let mut bc = nalgebra::DVector::<f64>::zeros(np);
        let len = 3 * n;
        let mut v = vec![0.0; (np + 1) * len];
        for i in 0..n {
            let p = x[i];
            let e = cam.project(&self.rig.neutral[i]);
            for row in 0..rows {
                let (rhs, wi) = match row {
                    0 | 1 => (u[i][row] - e[row], lw[i]),
                    _ => (dres.as_ref().map_or(0.0, |d| d[i]), wz * lw[i]),
                };
                let rr = [r[(row, 0)], r[(row, 1)], r[(row, 2)]];
                // ∂/∂ω of s·rr·(I + [ω]×)p = s·rr·(ω × p) = s·(p × rr)·ω.
                let c = [
                    p[1] * rr[2] - p[2] * rr[1],
                    p[2] * rr[0] - p[0] * rr[2],
                    p[0] * rr[1] - p[1] * rr[0],
                ];
                let proj = rr[0] * p[0] + rr[1] * p[1] + rr[2] * p[2];
                let j = [
                    proj,
                    cam.s * c[0],
                    cam.s * c[1],
                    cam.s * c[2],
                    if row == 0 { 1.0 } else { 0.0 },
                    if row == 1 { 1.0 } else { 0.0 },
                    if row == 2 { 1.0 } else { 0.0 },
                ];
                for a in 0..np {
                    bc[a] += wi * j[a] * rhs;
                    for b in 0..np {
                        hcc[(a, b)] += wi * j[a] * j[b];
                    }
                    let f = wi * cam.s * j[a];
                    if f != 0.0 {
                        let at = a * len + 3 * i;
                        for (o, q) in v[at..at + 3].iter_mut().zip(&rr) {
                            *o += f * q;
                        }
                    }
                }
                let f = wi * cam.s * rhs;
                let at = np * len + 3 * i;
                for (o, q) in v[at..at + 3].iter_mut().zip(&rr) {
                    *o += f * q;
                }
            }
        }
        let d = &self.blocks.d;
        let mut hcw_flat = vec![0.0; np * m];
        let mut bw = vec![0.0; m];
        for jj in 0..m {
            let dj = &d[jj * len..(jj + 1) * len];
            for p in 0..np {
                hcw_flat[p * m + jj] = dot(&v[p * len..(p + 1) * len], dj);
            }
            bw[jj] = dot(&v[np * len..(np + 1) * len], dj);
        }
        let hcw = DMatrix::from_row_slice(np, m, &hcw_flat);
        let mut g = vec![0.0; m * m];
        self.blocks.gram(cam, wz, &mut g);
        let Some(hinv) = hcc.try_inverse() else {
            return (*cam, self.tz);
        };
        // Schur complement: G' = Hww − Hcwᵀ Hcc⁻¹ Hcw, b' = bw − Hcwᵀ Hcc⁻¹ bc.
        let t = &hinv * &hcw; // np × m
        let tb = &hinv * &bc;
        for p in 0..m {
            for q in 0..m {
                let mut v = 0.0;
                for c in 0..np {
                    v += hcw[(c, p)] * t[(c, q)];
                }
                g[p * m + q] -= v;
            }
            let mut v = 0.0;
            for c in 0..np {
                v += hcw[(c, p)] * tb[c];
            }
            bw[p] -= v;
        }
        if m > 0 {
            self.solve_weights(g, bw);
        }
        // Camera step: Hcc δ = bc − Hcw w.
        let hw = &hcw * nalgebra::DVector::from_column_slice(&self.w);
        let delta = &hinv * (bc - hw);
        let omega = nalgebra::Vector3::new(delta[1], delta[2], delta[3]);
        let rot = nalgebra::Rotation3::new(omega);
        let tz = if np == 7 { self.tz + delta[6] } else { self.tz };
        (
            Camera {
                s: cam.s + delta[0],
                r: cam.r * rot.matrix(),
                t: [cam.t[0] + delta[4], cam.t[1] + delta[5]],
            },
            tz,
        )
    }

    /// The best weights for camera `cam` (the model is linear in them: exact), warm-started
    /// from the current ones, under the plain magnitude prior.
    fn weights_for(&mut self, cam: &Camera, u: &[[f64; 2]]) {
        if let Some((g, b)) = self.normal_equations(cam, u) {
            self.solve_weights(g, b);
        }
    }

    /// [`FrameSolver::weights_for`] with the magnitude prior tapered where it does
    /// ([`RigOptions::taper`]; the plain solve where it does not).
    fn tapered_weights_for(&mut self, cam: &Camera, u: &[[f64; 2]]) {
        if let Some((g, b)) = self.normal_equations(cam, u) {
            if self.taper.iter().any(|&t| t) {
                self.solve_tapered(g, b);
            } else {
                self.solve_weights(g, b);
            }
        }
    }

    /// The weights' normal equations `G w = b` at camera `cam` (without the priors), or
    /// `None` when no shape is free.
    fn normal_equations(&self, cam: &Camera, u: &[[f64; 2]]) -> Option<(Vec<f64>, Vec<f64>)> {
        let m = self.free.len();
        if m == 0 {
            return None;
        }
        let res: Vec<[f64; 2]> = self
            .rig
            .neutral
            .iter()
            .zip(u)
            .map(|(p, q)| {
                let e = cam.project(p);
                [q[0] - e[0], q[1] - e[1]]
            })
            .collect();
        let mut g = vec![0.0; m * m];
        let wz = self.wz();
        self.blocks.gram(cam, wz, &mut g);
        let mut b = vec![0.0; m];
        let dres = self.depth_residuals(cam, &self.rig.neutral);
        self.blocks
            .rhs(cam, &res, dres.as_deref().map(|d| (d, wz)), &mut b);
        Some((g, b))
    }

    /// [`FrameSolver::solve_weights`] with the tapered magnitude prior: the ridge of each
    /// tapering shape reweighted to `μ (1 − w)²` from the current weights and the weights
    /// solved again, [`TAPER_STEPS`] times (fewer when no weight moves by more than
    /// [`TAPER_TOLERANCE`]). Each step is the local linear approximation of the tapered
    /// penalty `μ w² (1 − 4w/3 + w²/2)`, whose gradient is `2μ w (1 − w)²`, at the last
    /// weights. Returns the ridge of the last solve (the weights meet its KKT conditions).
    fn solve_tapered(&mut self, g: Vec<f64>, b: Vec<f64>) -> Vec<f64> {
        let base = self.ridge.clone();
        let mut used = base.clone();
        for _ in 0..TAPER_STEPS {
            for ((r, mu), (w, t)) in self
                .ridge
                .iter_mut()
                .zip(&base)
                .zip(self.w.iter().zip(&self.taper))
            {
                if *t {
                    *r = mu * (1.0 - w.clamp(0.0, 1.0)).powi(2);
                }
            }
            let before = self.w.clone();
            used.clone_from(&self.ridge);
            self.solve_weights(g.clone(), b.clone());
            let moved = before
                .iter()
                .zip(&self.w)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            if moved <= TAPER_TOLERANCE {
                break;
            }
        }
        self.ridge = base;
        used
    }

    /// Solves `G w = b` under the solver's bounds into `self.w` (G gets a whisper of ridge,
    /// 1e-9 of its mean diagonal, far below any taken shape's curvature, so nearly dependent
    /// shapes stay solvable).
    fn solve_weights(&mut self, mut g: Vec<f64>, mut b: Vec<f64>) {
        let m = self.free.len();
        let ridge = 1e-9 * (0..m).map(|i| g[i * m + i]).sum::<f64>() / m as f64;
        for i in 0..m {
            g[i * m + i] += ridge + self.ridge[i];
        }
        for &(a, b, gamma) in &self.pairs {
            g[a * m + b] += gamma / 2.0;
            g[b * m + a] += gamma / 2.0;
        }
        if let (Some(p), true) = (&self.prev, self.lambda > 0.0) {
            for i in 0..m {
                g[i * m + i] += self.lambda;
                b[i] += self.lambda * p[i];
            }
        }

        match self.solver {
            Solver::Ls => {
                if solve_spd(&mut g, m, &mut b) {
                    self.w.copy_from_slice(&b);
                }
            }
            Solver::Nnls | Solver::Bounded => {
                let upper = if self.solver == Solver::Bounded {
                    1.0
                } else {
                    f64::INFINITY
                };
                let gram = Gram::from_row_major(m, g, upper);
                // Each call has its own Gram: the workspace's cached factor is stale.
                self.ws.forget_factor();
                active_set::solve_frame(&gram, &b, &mut self.w, &mut self.state, &mut self.ws);
            }
        }
    }

    /// Camera and weights of frame `u` to convergence: from the previous frame's weights and
    /// a fresh camera fit, each step takes the camera's Gauss–Newton step of the joint
    /// problem ([`FrameSolver::step`]), backtracked until the error falls, with the weights
    /// solved exactly for each trial camera (variable projection: the error never rises);
    /// then, at the camera reached, the weights under the tapered prior where it tapers.
    /// Returns (steps, converged, squared error).
    fn solve(&mut self, u: &[[f64; 2]]) -> Result<(u32, bool, f64)> {
        let (cam, it, ok) = self.gauss_newton(u)?;
        if self.taper.iter().any(|&t| t) {
            self.tapered_weights_for(&cam, u);
        }
        self.cam = Some(cam);
        Ok((it, ok, self.sq_error(&cam, u)))
    }

    /// [`FrameSolver::solve`]'s Gauss–Newton steps, under the plain magnitude prior:
    /// (camera, steps, converged).
    fn gauss_newton(&mut self, u: &[[f64; 2]]) -> Result<(Camera, u32, bool)> {
        let mut cam = fit_camera(&self.rig.posed(&self.full_weights()), u)?;
        self.fit_tz(&cam);
        self.weights_for(&cam, u);
        let mut err = self.objective(&cam, u);
        for it in 1..=self.max_steps {
            let (w0, state0, tz0) = (self.w.clone(), self.state.clone(), self.tz);
            let (full, tz_full) = self.step(&cam, u);
            let mut accepted = None;
            let mut alpha = 1.0;
            for _ in 0..12 {
                let trial = cam.toward(&full, alpha);
                self.w.copy_from_slice(&w0);
                self.state.copy_from_slice(&state0);
                self.tz = tz0 + alpha * (tz_full - tz0);
                self.weights_for(&trial, u);
                let e = self.objective(&trial, u);
                if e < err {
                    accepted = Some((trial, e));
                    break;
                }
                alpha *= 0.5;
            }
            let Some((next, e)) = accepted else {
                self.w = w0;
                self.state = state0;
                self.tz = tz0;
                return Ok((cam, it as u32, true));
            };
            let small = err - e <= 1e-12 * err;
            cam = next;
            err = e;
            if small {
                return Ok((cam, it as u32, true));
            }
        }
        Ok((cam, self.max_steps as u32, false))
    }
}

/// Per-shape image motion and determination at camera `cam`. Shapes are taken greedily by a
/// pivoted Cholesky factorisation of the Gram matrix: at each step the shape with the most
/// image motion left unexplained by the shapes already taken, while that share is at least
/// `min_det`; the rest are frozen (a 2-D view cannot tell them from the taken ones). A shape's
/// determination is then `1 / (Gₖₖ (G⁻¹)ₖₖ)` against every taken shape but itself (for a
/// frozen shape: against all taken shapes).
pub fn identifiability(rig: &Rig, cam: &Camera, min_det: f64) -> Vec<ShapeReport> {
    identifiability_weighted(rig, cam, min_det, &vec![1.0; rig.landmarks()])
}

/// [`identifiability`] with each landmark's squared motion weighted by `lw` (as the solve
/// weights its error): image motion is then the weighted RMS.
pub fn identifiability_weighted(
    rig: &Rig,
    cam: &Camera,
    min_det: f64,
    lw: &[f64],
) -> Vec<ShapeReport> {
    let k = rig.k();
    let blocks = Blocks::new(&rig.deltas, lw);
    let mut g = vec![0.0; k * k];
    blocks.gram(cam, 0.0, &mut g);
    let total: f64 = lw.iter().sum();
    let motion: Vec<f64> = (0..k).map(|i| (g[i * k + i] / total).sqrt()).collect();
    // Pivoted Cholesky: `l` holds the taken shapes' columns of the factor.
    let mut resid: Vec<f64> = (0..k).map(|i| g[i * k + i]).collect();
    let mut taken: Vec<usize> = Vec::new();
    let mut l: Vec<Vec<f64>> = Vec::new();
    loop {
        let pick = (0..k)
            .filter(|i| !taken.contains(i) && g[i * k + i] > 0.0)
            .map(|i| (i, resid[i] / g[i * k + i]))
            .filter(|&(_, share)| share >= min_det.max(1e-12))
            // Ties go to the rig's earlier shape.
            .max_by(|a, b| resid[a.0].total_cmp(&resid[b.0]).then(b.0.cmp(&a.0)));
        let Some((p, _)) = pick else { break };
        let d = resid[p].sqrt();
        let col: Vec<f64> = (0..k)
            .map(|i| {
                let v = g[i * k + p] - l.iter().map(|c| c[i] * c[p]).sum::<f64>();
                v / d
            })
            .collect();
        for i in 0..k {
            resid[i] -= col[i] * col[i];
        }
        l.push(col);
        taken.push(p);
    }
    let frozen: Vec<bool> = (0..k).map(|i| !taken.contains(&i)).collect();
    let det: Vec<f64> = (0..k)
        .map(|i| {
            let others: Vec<usize> = taken.iter().copied().filter(|&j| j != i).collect();
            let gii = g[i * k + i];
            if gii.is_nan() || gii <= 0.0 {
                return 0.0;
            }
            if others.is_empty() {
                return 1.0;
            }
            // 1 − (explained share) = residual of column i against the others, over Gᵢᵢ.
            let m = others.len();
            let sub = DMatrix::from_fn(m, m, |a, b| g[others[a] * k + others[b]]);
            let rhs = nalgebra::DVector::from_fn(m, |a, _| g[others[a] * k + i]);
            match sub.cholesky() {
                Some(c) => {
                    let x = c.solve(&rhs);
                    ((gii - rhs.dot(&x)) / gii).clamp(0.0, 1.0)
                }
                None => 0.0,
            }
        })
        .collect();
    (0..k)
        .map(|i| ShapeReport {
            name: rig.names[i].clone(),
            image_motion: motion[i],
            determination: det[i],
            frozen: frozen[i],
        })
        .collect()
}

/// Solves every frame of `track` (iBUG-68 2-D points, 136 × frames, image axes) onto `rig`.
/// `clips` (consecutive column ranges covering the track, or empty for one clip) may hold
/// different people: with `Neutral::Auto` each clip takes its identity from its own least
/// active frame; an explicit neutral column gives every clip that frame's identity.
pub fn solve_rig(
    rig: &Rig,
    track: &DMatrix<f64>,
    clips: &[Range<usize>],
    opts: &RigOptions,
) -> Result<RigSolve> {
    let n = rig.landmarks();
    if track.nrows() != 2 * n && track.nrows() != 3 * n {
        return Err(Error::invalid(format!(
            "the rig reads {n} landmarks (2 or 3 rows each), but the track has {} rows: select the rig's points (Rig::points) from the track first",
            track.nrows(),
        )));
    }
    // A track with depth (x, y, z per landmark): its image rows, and its depth rows with
    // the sign turned to point towards the viewer (MediaPipe's z is more negative closer).
    let (image, depth) = if track.nrows() == 3 * n {
        let xy: Vec<usize> = (0..n).flat_map(|i| [3 * i, 3 * i + 1]).collect();
        let z: Vec<usize> = (0..n).map(|i| 3 * i + 2).collect();
        (track.select_rows(&xy), Some(-track.select_rows(&z)))
    } else {
        (track.clone(), None)
    };
    let track = &image;
    let depth = depth.as_ref();
    if track.ncols() == 0 {
        return Err(Error::invalid("the track has no frames"));
    }
    if let Some((i, v)) = track.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(Error::invalid(format!(
            "frame column {}: landmark {} is {v}",
            i / track.nrows(),
            (i % track.nrows()) / 2
        )));
    }
    if let Some(c) = (0..track.ncols())
        .find(|&c| crate::sequence::degenerate_shape(track.column(c).as_slice(), 2))
    {
        return Err(Error::invalid(format!(
            "frame column {c}: all {n} landmarks coincide, so no camera can be fitted to it"
        )));
    }
    if !(opts.min_determination >= 0.0 && opts.min_determination < 1.0) {
        return Err(Error::invalid(format!(
            "the minimum determination must be in [0, 1), not {}",
            opts.min_determination
        )));
    }
    if !(opts.zero_phase.is_finite() && (0.0..=1000.0).contains(&opts.zero_phase)) {
        return Err(Error::invalid(format!(
            "the zero-phase σ must be a number of frames in [0, 1000], not {}",
            opts.zero_phase
        )));
    }
    if !(opts.prior.is_finite() && opts.prior >= 0.0) {
        return Err(Error::invalid(format!(
            "the magnitude prior must be a number ≥ 0, not {}",
            opts.prior
        )));
    }
    if !(opts.smooth.is_finite() && opts.smooth >= 0.0) {
        return Err(Error::invalid(format!(
            "the temporal prior λ must be a number ≥ 0, not {}",
            opts.smooth
        )));
    }
    if let Some((i, w)) = opts
        .landmark_weights
        .iter()
        .enumerate()
        .find(|(_, w)| !(w.is_finite() && **w >= 0.0))
    {
        return Err(Error::invalid(format!(
            "landmark {i}'s weight must be a finite number ≥ 0, not {w}"
        )));
    }
    let lw = rig_landmark_weights(rig, opts)?;
    if opts.prior > 0.0 && rig.eyes().is_none() {
        let [a, b] = correspondence::eye_corners(rig.layout).unwrap_or([36, 45]);
        return Err(Error::invalid(format!(
            "the magnitude prior is scaled by the outer eye corners (track points {a} and {b}), which the rig's correspondence leaves out: name them, or set the prior to 0"
        )));
    }
    let weighted = lw.iter().filter(|w| **w > 0.0).count();
    if weighted < 4 {
        return Err(Error::invalid(format!(
            "the landmark weights leave {weighted} landmarks with weight > 0; the head pose needs at least 4"
        )));
    }
    let whole = std::iter::once(0..track.ncols()).collect::<Vec<_>>();
    let clips: &[Range<usize>] = if clips.is_empty() { &whole[..] } else { clips };
    if clips.iter().any(|c| c.end > track.ncols() || c.is_empty())
        || clips.windows(2).any(|w| w[0].end != w[1].start)
        || clips[0].start != 0
        || clips[clips.len() - 1].end != track.ncols()
    {
        return Err(Error::invalid(
            "rig solve: clips must cover the frames in order",
        ));
    }
    if let Neutral::Column(c) = opts.neutral {
        if c >= track.ncols() {
            return Err(Error::invalid(format!(
                "neutral frame column {c} is past the track's {} frames",
                track.ncols()
            )));
        }
    }
    if let Neutral::Span(a, b) = opts.neutral {
        if a >= b || b > track.ncols() {
            return Err(Error::invalid(format!(
                "neutral frame columns {a}..{b} are not a stretch of the track's {} frames",
                track.ncols()
            )));
        }
    }
    let all: Vec<usize> = (0..rig.k()).collect();
    // Pass 1 (without an identity, or to find the least active frames): the rig as it is,
    // every shape free.
    let first = match (opts.identity, opts.neutral) {
        (Identity::None, _) | (_, Neutral::LeastActive) => Some(run(
            rig,
            track,
            &[(0..track.ncols(), rig.clone())],
            all,
            opts,
            &lw,
            depth,
        )?),
        _ => None,
    };
    let least_active = |c: &Range<usize>, first: &RigSolve| {
        c.clone()
            .min_by(|&a, &b| {
                let s = |f: usize| first.weights.column(f).sum();
                s(a).total_cmp(&s(b))
            })
            .unwrap_or(c.start)
    };
    let (people, neutrals): (Vec<(Range<usize>, Rig)>, Vec<usize>) =
        match (opts.identity, opts.neutral, &first) {
            (Identity::None, _, _) => (vec![(0..track.ncols(), rig.clone())], Vec::new()),
            (id, Neutral::Column(n), _) => (
                vec![(
                    0..track.ncols(),
                    person_rig(rig, track, depth, n..n + 1, id)?,
                )],
                vec![n],
            ),
            (id, Neutral::Span(a, b), _) => (
                vec![(0..track.ncols(), person_rig(rig, track, depth, a..b, id)?)],
                vec![(a + b) / 2],
            ),
            (id, auto, first) => {
                let mut people = Vec::new();
                let mut neutrals = Vec::new();
                for c in clips {
                    let n = match first {
                        Some(first) if auto == Neutral::LeastActive => least_active(c, first),
                        _ => best_explaining(rig, track, depth, c.clone(), opts, &lw)?,
                    };
                    people.push((c.clone(), person_rig(rig, track, depth, n..n + 1, id)?));
                    neutrals.push(n);
                }
                (people, neutrals)
            }
        };
    // Identifiability at the first clip's neutral view (the rig and the view decide it,
    // not the person); the frozen shapes are the same in every clip.
    let cam_n = match (neutrals.first(), &first) {
        (Some(&n), _) => fit_camera(&people[0].1.neutral, &frame_points(track, n))?,
        (None, Some(first)) => first.cameras[0],
        (None, None) => fit_camera(&rig.neutral, &frame_points(track, 0))?,
    };
    let shapes = identifiability_weighted(&people[0].1, &cam_n, opts.min_determination, &lw);
    let free: Vec<usize> = (0..rig.k()).filter(|&s| !shapes[s].frozen).collect();
    let mut out = run(rig, track, &people, free, opts, &lw, depth)?;
    out.shapes = shapes;
    out.neutrals = neutrals;
    out.people = people;
    Ok(out)
}

/// Per landmark, the weight of its squared error: `opts.landmark_weights` (iBUG numbering)
/// read at the rig's points on a 68-point layout; on other layouts they must all be 1.
fn rig_landmark_weights(rig: &Rig, opts: &RigOptions) -> Result<Vec<f64>> {
    if rig.layout == LANDMARKS {
        return Ok(rig
            .points
            .iter()
            .map(|&p| opts.landmark_weights.get(p).copied().unwrap_or(1.0))
            .collect());
    }
    if opts.landmark_weights.iter().any(|&w| w != 1.0) {
        return Err(Error::invalid(format!(
            "landmark weights name the 68 iBUG landmarks; this rig reads a {}-point track",
            rig.layout
        )));
    }
    Ok(vec![1.0; rig.landmarks()])
}

/// Of `frames`, those that look neutral: lips no more parted and brows no higher than the
/// median of `frames` (each as a fraction of the frame's inter-ocular distance: the inner
/// lips' gap, iBUG 62–66 / MediaPipe 13–14; each brow's middle above its upper lid, iBUG
/// 19–37 and 24–44 / MediaPipe 105–159 and 334–386). A frame with parted lips or raised
/// brows is then never the neutral. All of `frames` when the rig does not read those
/// points (or the eye corners).
fn neutral_looking(rig: &Rig, track: &DMatrix<f64>, frames: Vec<usize>) -> Vec<usize> {
    let (lips, brows): ([usize; 2], [[usize; 2]; 2]) = match rig.layout {
        68 => ([62, 66], [[19, 37], [24, 44]]),
        _ => ([13, 14], [[105, 159], [334, 386]]),
    };
    let at = |p: usize| rig.points.iter().position(|&q| q == p);
    let (Some(eyes), Some(l0), Some(l1)) = (rig.eyes(), at(lips[0]), at(lips[1])) else {
        return frames;
    };
    let brows: Option<Vec<[usize; 2]>> = brows
        .iter()
        .map(|[b, e]| Some([at(*b)?, at(*e)?]))
        .collect();
    let Some(brows) = brows else { return frames };
    let pt = |i: usize, f: usize| [track[(2 * i, f)], track[(2 * i + 1, f)]];
    let dist = |a: [f64; 2], b: [f64; 2]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
    let measure = |f: usize| {
        let iod = dist(pt(eyes[0], f), pt(eyes[1], f)).max(f64::MIN_POSITIVE);
        let gap = dist(pt(l0, f), pt(l1, f)) / iod;
        let raise = brows
            .iter()
            .map(|[b, e]| dist(pt(*b, f), pt(*e, f)))
            .sum::<f64>()
            / (2.0 * iod);
        (gap, raise)
    };
    let m: Vec<(f64, f64)> = frames.iter().map(|&f| measure(f)).collect();
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    if m.is_empty() {
        return frames;
    }
    let (g, r) = (
        median(m.iter().map(|x| x.0).collect()),
        median(m.iter().map(|x| x.1).collect()),
    );
    let kept: Vec<usize> = frames
        .iter()
        .zip(&m)
        .filter(|(_, x)| x.0 <= g && x.1 <= r)
        .map(|(&f, _)| f)
        .collect();
    if kept.is_empty() {
        frames
    } else {
        kept
    }
}

/// Neutral candidates tried per clip by [`Neutral::Auto`] (all frames of shorter clips).
pub const NEUTRAL_CANDIDATES: usize = 48;
/// Frames of a clip each candidate is scored on (all frames of shorter clips).
pub const NEUTRAL_SCORED_FRAMES: usize = 64;

/// `count` evenly spaced members of `r` (all of them when it has no more), in order.
fn evenly_spaced(r: Range<usize>, count: usize) -> Vec<usize> {
    let len = r.len();
    if len <= count {
        return r.collect();
    }
    (0..count)
        .map(|i| r.start + (i * (len - 1) + (count - 1) / 2) / (count - 1))
        .collect()
}

/// The frame of `clip` whose identity best explains the clip ([`Neutral::Auto`]): for each
/// of up to [`NEUTRAL_CANDIDATES`] evenly spaced candidates, the person's rig from that
/// frame, its identifiability, and a solve (no temporal prior) of up to
/// [`NEUTRAL_SCORED_FRAMES`] evenly spaced frames; the candidate with the lowest total
/// (weighted) squared landmark error, centred over the scored frames, wins, ties to the
/// earlier frame. A neutral face is one from which the rest of the performance is reached
/// with the weights inside their bounds; a frame that already holds an expression (raised
/// brows, say) leaves every frame with less of it unexplained. Centred: the candidate's own
/// landmark noise becomes part of the person and leaves every scored frame the same
/// residual, which the centring takes out; uncentred, that noise decided between
/// candidates (on the benchmark's blinks it took a frame inside the held smile over the
/// lead-in). The search scores with the plain ridge, not the tapered prior (tapered, it
/// took the held smile again).
fn best_explaining(
    rig: &Rig,
    track: &DMatrix<f64>,
    depth: Option<&DMatrix<f64>>,
    clip: Range<usize>,
    opts: &RigOptions,
    lw: &[f64],
) -> Result<usize> {
    use rayon::prelude::*;
    let candidates = neutral_looking(rig, track, evenly_spaced(clip.clone(), NEUTRAL_CANDIDATES));
    let scored = evenly_spaced(clip, NEUTRAL_SCORED_FRAMES);
    let scores: Vec<Result<(usize, f64)>> = candidates
        .par_iter()
        .map(|&n| -> Result<(usize, f64)> {
            let person = person_rig(rig, track, depth, n..n + 1, opts.identity)?;
            let cam = fit_camera(&person.neutral, &frame_points(track, n))?;
            let shapes = identifiability_weighted(&person, &cam, opts.min_determination, lw);
            let free: Vec<usize> = (0..rig.k()).filter(|&s| !shapes[s].frozen).collect();
            let mut fs = FrameSolver::new(&person, free, opts.solver, opts.max_steps.max(1), lw);
            fs.ridge = magnitude_prior(track, opts, rig, &fs.free);
            fs.pairs = exclusive_pairs(rig, &fs.free, &fs.ridge);
            let mut total = 0.0;
            // The (weighted) image residuals summed over the scored frames.
            let mut sum = vec![0.0; 2 * lw.len()];
            for &f in &scored {
                let u = frame_points(track, f);
                fs.depth = frame_depth(depth, f);
                fs.solve(&u)?;
                let cam = fs.cam.unwrap_or(cam);
                total += fs.sq_error_with(&cam, &u, lw);
                let posed = person.posed(&fs.full_weights());
                for (i, (p, q)) in posed.iter().zip(&u).enumerate() {
                    let e = cam.project(p);
                    sum[2 * i] += lw[i].sqrt() * (e[0] - q[0]);
                    sum[2 * i + 1] += lw[i].sqrt() * (e[1] - q[1]);
                }
            }
            // Centred: what every scored frame leaves alike is not counted.
            total -= sum.iter().map(|x| x * x).sum::<f64>() / scored.len().max(1) as f64;
            Ok((n, total))
        })
        .collect();
    // A candidate that cannot be a neutral (its solve fails) is passed over; the search
    // fails only when every candidate does, with the first one's error.
    let best = scores
        .iter()
        .filter_map(|s| s.as_ref().ok())
        .filter(|s| !s.1.is_nan())
        .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
        .map(|s| s.0);
    match best {
        Some(n) => Ok(n),
        None => match scores.into_iter().find_map(|s| s.err()) {
            Some(e) => Err(e),
            None => Ok(candidates[0]),
        },
    }
}

/// The person's rig from the neutral frames `frames` (one, or a recorded lead-in).
fn person_rig(
    rig: &Rig,
    track: &DMatrix<f64>,
    depth: Option<&DMatrix<f64>>,
    frames: Range<usize>,
    id: Identity,
) -> Result<Rig> {
    // A neutral frame is the person with no expression: its weights are 0 by definition,
    // and its head pose is the rig's neutral fitted to it. Each frame's residual, lifted
    // into the rig's frame, is averaged over `frames`.
    let count = frames.len().max(1) as f64;
    let posed = &rig.neutral;
    let mut neutral = rig.neutral.clone();
    for n in frames {
        let u = frame_points(track, n);
        let cam = fit_camera(posed, &u)?;
        // With depth, its residual too (after the best depth offset, the mean).
        let r3 = [cam.r[(2, 0)], cam.r[(2, 1)], cam.r[(2, 2)]];
        let dz: Option<Vec<f64>> = frame_depth(depth, n).map(|d| {
            let r: Vec<f64> = d.iter().zip(posed).map(|(z, p)| z - cam.depth(p)).collect();
            let mean = r.iter().sum::<f64>() / r.len().max(1) as f64;
            r.iter().map(|v| v - mean).collect()
        });
        // The residual, lifted into the rig's frame in the image plane of the neutral
        // camera (and along its depth axis, with depth).
        for (i, p) in neutral.iter_mut().enumerate() {
            let e = cam.project(&posed[i]);
            let d = [(u[i][0] - e[0]) / cam.s, (u[i][1] - e[1]) / cam.s];
            let z = dz.as_ref().map_or(0.0, |z| z[i] / cam.s);
            for a in 0..3 {
                p[a] += (cam.r[(0, a)] * d[0] + cam.r[(1, a)] * d[1] + r3[a] * z) / count;
            }
        }
    }
    let mut person = Rig {
        neutral,
        ..rig.clone()
    };
    if id == Identity::Rbf {
        // The RBF interpolates the identity's displacement (person − rig at the landmarks),
        // so the map is the identity plus a smooth correction: multiquadrics alone do not
        // reproduce the identity map between their centres.
        let src: Vec<f64> = rig.neutral.iter().flatten().copied().collect();
        let disp: Vec<f64> = person
            .neutral
            .iter()
            .zip(&rig.neutral)
            .flat_map(|(p, q)| [p[0] - q[0], p[1] - q[1], p[2] - q[2]])
            .collect();
        let f = Rbf::fit(&src, &disp, 3)?;
        let mut at = [0.0; 3];
        for d in person.deltas.iter_mut() {
            for (i, o) in d.iter_mut().enumerate() {
                if *o == [0.0; 3] {
                    continue;
                }
                let x = [
                    rig.neutral[i][0] + o[0],
                    rig.neutral[i][1] + o[1],
                    rig.neutral[i][2] + o[2],
                ];
                f.apply_point(&x, &mut at);
                // F(N + D) − F(N) with F(x) = x + disp(x), and disp(N) the landmark's own.
                let base = [disp[3 * i], disp[3 * i + 1], disp[3 * i + 2]];
                *o = [
                    o[0] + at[0] - base[0],
                    o[1] + at[1] - base[1],
                    o[2] + at[2] - base[2],
                ];
            }
        }
    }
    Ok(person)
}

/// Smooths the columns `clip` of `w` along time by a Gaussian of `sigma` frames (radius
/// ⌈3σ⌉, the kernel renormalised where it passes the clip's ends): zero phase, no lag.
pub fn zero_phase(w: &mut DMatrix<f64>, clip: Range<usize>, sigma: f64) {
    // The smoothing study's zero-phase low-pass, over this one clip.
    let part = w.columns(clip.start, clip.len()).into_owned();
    let smooth = crate::experiment::smoothing::gaussian_lowpass(
        &part,
        std::slice::from_ref(&(0..clip.len())),
        sigma,
    );
    w.columns_mut(clip.start, clip.len()).copy_from(&smooth);
}

/// The per-frame RMS landmark error of `weights` on the frames `clip`, under the frames'
/// cameras (after the weights were changed by a temporal prior).
fn recompute_rms(
    person: &Rig,
    track: &DMatrix<f64>,
    clip: Range<usize>,
    cameras: &[Camera],
    weights: &DMatrix<f64>,
    rms: &mut [f64],
) {
    let n = person.landmarks();
    for f in clip {
        let w: Vec<f64> = weights.column(f).iter().copied().collect();
        let u = frame_points(track, f);
        let e: f64 = person
            .posed(&w)
            .iter()
            .zip(&u)
            .map(|(p, q)| {
                let x = cameras[f].project(p);
                (x[0] - q[0]).powi(2) + (x[1] - q[1]).powi(2)
            })
            .sum();
        rms[f] = (e / n as f64).sqrt();
    }
}

/// One pass over the frames with the shapes `free`, each clip with its person's rig (warm
/// starts do not cross clips).
fn run(
    rig: &Rig,
    track: &DMatrix<f64>,
    people: &[(Range<usize>, Rig)],
    free: Vec<usize>,
    opts: &RigOptions,
    lw: &[f64],
    depth: Option<&DMatrix<f64>>,
) -> Result<RigSolve> {
    let frames = track.ncols();
    let mut tzs = vec![0.0; frames];
    let n = rig.landmarks();
    let mut weights = DMatrix::zeros(rig.k(), frames);
    let (mut cameras, mut rms, mut steps) = (Vec::new(), Vec::new(), Vec::new());
    let mut unconverged = 0;
    let offline =
        opts.smooth > 0.0 && opts.smooth_mode == crate::solve::temporal::SmoothMode::Offline;
    let (mut sweeps, mut sweeps_unconverged) = (0, 0);
    for (clip, person) in people {
        let mut fs = FrameSolver::new(person, free.clone(), opts.solver, opts.max_steps.max(1), lw);
        fs.lambda = if offline { 0.0 } else { opts.smooth };
        fs.ridge = magnitude_prior(track, opts, rig, &fs.free);
        fs.pairs = exclusive_pairs(rig, &fs.free, &fs.ridge);
        fs.taper = tapering(rig, opts, &fs.free, &fs.ridge);
        for f in clip.clone() {
            let u = frame_points(track, f);
            fs.depth = frame_depth(depth, f);
            let (it, ok, e) = fs.solve(&u)?;
            tzs[f] = fs.tz;
            unconverged += usize::from(!ok);
            steps.push(it);
            rms.push((e / n as f64).sqrt());
            let w = fs.full_weights();
            if w.iter().any(|v| !v.is_finite()) {
                return Err(Error::invalid(format!(
                    "frame column {f}: the rig solve produced non-finite weights"
                )));
            }
            weights.column_mut(f).copy_from_slice(&w);
            fs.prev = Some(fs.w.clone());
            cameras.push(fs.cam.unwrap_or(Camera {
                s: 1.0,
                r: nalgebra::Matrix3::identity(),
                t: [0.0, 0.0],
            }));
        }
        if offline {
            let (n_sweeps, ok) = temporal::offline_prior(
                &mut fs,
                (track, depth),
                clip.clone(),
                (&cameras, &tzs),
                &mut weights,
                opts.smooth,
            );
            sweeps = sweeps.max(n_sweeps);
            sweeps_unconverged += usize::from(!ok);
            recompute_rms(person, track, clip.clone(), &cameras, &weights, &mut rms);
        }
    }
    if opts.zero_phase > 0.0 {
        for (clip, person) in people {
            zero_phase(&mut weights, clip.clone(), opts.zero_phase);
            recompute_rms(person, track, clip.clone(), &cameras, &weights, &mut rms);
        }
    }
    Ok(RigSolve {
        weights,
        cameras,
        rms,
        steps,
        unconverged,
        sweeps,
        sweeps_unconverged,
        shapes: Vec::new(),
        neutrals: Vec::new(),
        people: Vec::new(),
    })
}

#[cfg(test)]
mod tests {

    /// The tapered prior's weights meet the KKT conditions of the bounded problem with the
    /// ridge its last step used; that ridge is `μ (1 − w)²` of weights in [0, 1] for the
    /// tapering shapes (so never above μ) and μ for the others; and a shape the data clearly
    /// turns on comes nearer its full weight than under the plain ridge.
    #[test]
    fn the_tapered_prior_meets_its_kkt_conditions() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(39);
        let (n, m) = (8, 5);
        let rig = super::Rig {
            names: (0..m).map(|s| format!("s{s}")).collect(),
            neutral: vec![[0.0; 3]; n],
            deltas: (0..m)
                .map(|_| (0..n).map(|_| [rng.gen_range(-1.0..1.0); 3]).collect())
                .collect(),
            points: (0..n).collect(),
            layout: n,
        };
        for trial in 0..200 {
            let mut fs = super::FrameSolver::new(
                &rig,
                (0..m).collect(),
                super::Solver::Bounded,
                50,
                &vec![1.0; n],
            );
            let a = nalgebra::DMatrix::<f64>::from_fn(2 * m, m, |_, _| rng.gen_range(-1.0..1.0));
            let gram = a.transpose() * &a;
            let g: Vec<f64> = (0..m * m).map(|k| gram[(k / m, k % m)]).collect();
            let truth: Vec<f64> = (0..m).map(|_| rng.gen_range(-0.3..1.3)).collect();
            let b: Vec<f64> = (0..m)
                .map(|i| (0..m).map(|j| gram[(i, j)] * truth[j]).sum())
                .collect();
            let mu = rng.gen_range(0.05..2.0);
            fs.ridge = vec![mu; m];
            fs.taper = (0..m).map(|j| j != m - 1).collect();
            fs.pairs = vec![(0, 1, 2.0 * mu)];
            let used = fs.solve_tapered(g.clone(), b.clone());
            assert_eq!(fs.ridge, vec![mu; m], "the base ridge is restored");
            assert_eq!(used[m - 1], mu, "a shape that does not taper keeps μ");
            for &r in &used[..m - 1] {
                assert!((0.0..=mu).contains(&r), "trial {trial}: {r} against μ {mu}");
            }
            // KKT of (G + diag(used) + pairs) w = b in the unit box.
            let w = fs.w.clone();
            let whisper = 1e-9 * (0..m).map(|i| g[i * m + i]).sum::<f64>() / m as f64;
            for i in 0..m {
                let mut h = -b[i] + (used[i] + whisper) * w[i];
                for j in 0..m {
                    h += g[i * m + j] * w[j];
                }
                h += match i {
                    0 => mu * w[1],
                    1 => mu * w[0],
                    _ => 0.0,
                };
                let v = if w[i] <= 1e-12 {
                    (-h).max(0.0)
                } else if w[i] >= 1.0 - 1e-12 {
                    h.max(0.0)
                } else {
                    h.abs()
                };
                assert!(v < 1e-9, "trial {trial}: shape {i} KKT violation {v}");
            }
        }
        // One shape the data puts at 1 (curvature 2, μ 1): the plain ridge leaves 2/3, the
        // taper's two steps μ(1 − 2/3)² → 0.947 and then 0.9986.
        let mut one = super::FrameSolver::new(&rig, vec![0], super::Solver::Bounded, 50, &[1.0; 8]);
        one.ridge = vec![1.0];
        one.taper = vec![true];
        one.solve_weights(vec![2.0], vec![2.0]);
        assert!((one.w[0] - 2.0 / 3.0).abs() < 1e-6, "{}", one.w[0]);
        one.solve_tapered(vec![2.0], vec![2.0]);
        assert!((one.w[0] - 0.9986).abs() < 1e-3, "{}", one.w[0]);
    }

    #[test]
    fn a_frame_names_its_largest_weights_largest_first() {
        let names: Vec<String> = ["a", "b", "c", "d"].iter().map(|s| s.to_string()).collect();
        assert_eq!(
            super::largest_weights(&names, &[0.2, 0.9, 0.005, 0.4], 3),
            "b .90, d .40, a .20"
        );
        assert_eq!(super::largest_weights(&names, &[0.0; 4], 3), "");
    }

    use super::evenly_spaced;

    #[test]
    fn evenly_spaced_candidates_keep_both_ends_and_never_repeat() {
        assert_eq!(evenly_spaced(5..9, 48), vec![5, 6, 7, 8]);
        assert_eq!(evenly_spaced(0..0, 3), Vec::<usize>::new());
        for (r, count) in [
            (0..477, 48),
            (100..1000, 48),
            (3..53, 49),
            (0..100_000, 160),
        ] {
            let v = evenly_spaced(r.clone(), count);
            assert_eq!(v.len(), count);
            assert_eq!((v[0], v[count - 1]), (r.start, r.end - 1));
            assert!(v.windows(2).all(|w| w[0] < w[1]), "{v:?}");
            // Gaps differ by at most one frame.
            let gaps: Vec<usize> = v.windows(2).map(|w| w[1] - w[0]).collect();
            let (lo, hi) = (gaps.iter().min().unwrap(), gaps.iter().max().unwrap());
            assert!(hi - lo <= 1, "{gaps:?}");
        }
    }
}
