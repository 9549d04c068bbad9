//! The rig-solve study (issue 16 item 7): (i) recovery of known weights from synthetic
//! tracks rendered through the rig under a moving head with landmark noise, per solver and
//! noise level; (ii) agreement with a peer's ARKit-style scores (py-feat's) on a real track.

use super::camera::Camera;
use super::livelink::arkit_name;
use super::{solve_rig, Identity, Rig, RigOptions};
use crate::cosker::intensity::correlation;
use crate::error::{Error, Result};
use crate::solve::Solver;
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

/// `[rig]` of an experiment.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigStudySettings {
    /// Shapes driven in the synthetic tracks (rig names).
    #[serde(default = "default_shapes")]
    pub shapes: Vec<String>,
    /// Frames per synthetic track.
    #[serde(default = "default_frames")]
    pub frames: usize,
    /// Landmark noise levels, standard deviation in pixels (the rig is drawn at 8 px/cm,
    /// an inter-ocular distance of about 71 px).
    #[serde(default = "default_noise")]
    pub noise_px: Vec<f64>,
    /// Solvers compared.
    #[serde(default = "default_solvers")]
    pub solvers: Vec<Solver>,
    /// Causal temporal priors λ also tried with the bounded solver (none by default).
    #[serde(default)]
    pub smooth: Vec<f64>,
    /// Seed of the weights and the noise.
    #[serde(default = "default_seed")]
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
fn default_frames() -> usize {
    300
}
fn default_noise() -> Vec<f64> {
    vec![0.0, 0.5, 1.0, 2.0]
}
fn default_solvers() -> Vec<Solver> {
    vec![Solver::Ls, Solver::Nnls, Solver::Bounded]
}
fn default_seed() -> u64 {
    7
}

/// One shape's recovery at one solver and noise level.
#[derive(Debug, Clone, Serialize)]
pub struct RecoveryRow {
    /// Solver.
    pub solver: String,
    /// Landmark noise σ (px).
    pub noise_px: f64,
    /// Rig shape.
    pub shape: String,
    /// Pearson r of solved against true weights over the frames.
    pub r: f64,
    /// RMS error of the weight.
    pub rmse: f64,
    /// Frozen by the identifiability check (its weight is then 0).
    pub frozen: bool,
}

/// Smooth random weights in [0, 0.8]: per shape, a seeded sum of three sinusoids of random
/// frequency (periods of 1–10 s at 30 fps) and phase, squashed.
fn smooth_weights(frames: usize, shapes: usize, rng: &mut impl Rng) -> Vec<Vec<f64>> {
    (0..shapes)
        .map(|_| {
            let parts: Vec<(f64, f64, f64)> = (0..3)
                .map(|_| {
                    let period = rng.gen_range(30.0..300.0);
                    (
                        std::f64::consts::TAU / period,
                        rng.gen_range(0.0..std::f64::consts::TAU),
                        rng.gen_range(0.3..1.0),
                    )
                })
                .collect();
            let norm: f64 = parts.iter().map(|p| p.2).sum();
            (0..frames)
                .map(|t| {
                    let v: f64 = parts
                        .iter()
                        .map(|(w, ph, a)| a * (w * t as f64 + ph).sin())
                        .sum::<f64>()
                        / norm;
                    0.8 * (0.5 + 0.5 * v).clamp(0.0, 1.0)
                })
                .collect()
        })
        .collect()
}

/// Head poses sweeping yaw ±20°, pitch ±10°, roll ±5° at incommensurate rates.
pub fn head_sweep(frames: usize) -> Vec<Camera> {
    (0..frames)
        .map(|f| {
            let t = f as f64 / frames.max(1) as f64;
            Camera::from_angles(
                8.0,
                20f64.to_radians() * (2.0 * std::f64::consts::TAU * t).sin(),
                10f64.to_radians() * (3.0 * std::f64::consts::TAU * t + 1.0).sin(),
                5f64.to_radians() * (5.0 * std::f64::consts::TAU * t + 2.0).sin(),
                [320.0, -240.0],
            )
        })
        .collect()
}

/// Study (i): per solver and noise level, each driven shape's correlation and RMS error, on
/// tracks rendered through `rig` itself (the person is the rig: identity `none`).
pub fn recovery(rig: &Rig, st: &RigStudySettings) -> Result<Vec<RecoveryRow>> {
    let idx: Vec<usize> =
        st.shapes
            .iter()
            .map(|n| {
                rig.names.iter().position(|m| m == n).ok_or_else(|| {
                    Error::invalid(format!("[rig] shapes: the rig has no shape '{n}'"))
                })
            })
            .collect::<Result<_>>()?;
    if st.frames < 2 {
        return Err(Error::invalid("[rig] frames must be at least 2"));
    }
    if let Some(n) = st.noise_px.iter().find(|n| !(n.is_finite() && **n >= 0.0)) {
        return Err(Error::invalid(format!(
            "[rig] noise_px: {n} is not a noise level"
        )));
    }
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(st.seed);
    let series = smooth_weights(st.frames, idx.len(), &mut rng);
    let mut truth = DMatrix::zeros(rig.k(), st.frames);
    for (j, &s) in idx.iter().enumerate() {
        for f in 0..st.frames {
            truth[(s, f)] = series[j][f];
        }
    }
    let clean = rig.render(&truth, &head_sweep(st.frames));
    let mut rows = Vec::new();
    for &noise in &st.noise_px {
        let mut track = clean.clone();
        for v in track.iter_mut() {
            let (u1, u2): (f64, f64) = (rng.gen_range(f64::EPSILON..1.0), rng.gen());
            *v += noise * (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
        }
        let runs: Vec<(Solver, f64)> = st
            .solvers
            .iter()
            .map(|&s| (s, 0.0))
            .chain(st.smooth.iter().map(|&l| (Solver::Bounded, l)))
            .collect();
        for (solver, smooth) in runs {
            let opts = RigOptions {
                solver,
                identity: Identity::None,
                smooth,
                ..Default::default()
            };
            let r = solve_rig(rig, &track, &[], &opts)?;
            for (j, &s) in idx.iter().enumerate() {
                let got: Vec<f64> = r.weights.row(s).iter().copied().collect();
                let rmse = (got
                    .iter()
                    .zip(&series[j])
                    .map(|(a, b)| (a - b).powi(2))
                    .sum::<f64>()
                    / st.frames as f64)
                    .sqrt();
                rows.push(RecoveryRow {
                    solver: if smooth > 0.0 {
                        format!("bounded+causal λ={smooth}")
                    } else {
                        solver.name().into()
                    },
                    noise_px: noise,
                    shape: st.shapes[j].clone(),
                    r: correlation(&got, &series[j]),
                    rmse,
                    frozen: r.shapes[s].frozen,
                });
            }
        }
    }
    Ok(rows)
}

/// One shape's agreement with the peer's score.
#[derive(Debug, Clone, Serialize)]
pub struct PeerRow {
    /// Identity used.
    pub identity: String,
    /// ARKit name (the peer's column, lower camel case).
    pub shape: String,
    /// `all` (every frame pooled) or a clip label of the track.
    pub clip: String,
    /// Pearson r over the frames; None when either series is constant there (a frozen
    /// shape, one held at a bound throughout, or a score the peer never moves), where r is
    /// undefined.
    pub r: Option<f64>,
}

/// Study (ii): the rig solve of `track` (bounded, each identity) against the peer's
/// ARKit-style score columns `scores` (name → per-frame values, in py-feat's lower camel
/// case), pooled and per clip of `clips` (a label per frame); rig shapes split left/right
/// where the peer has one column are averaged.
pub fn against_peer(
    rig: &Rig,
    track: &DMatrix<f64>,
    scores: &[(String, Vec<f64>)],
    clips: Option<&[String]>,
) -> Result<Vec<PeerRow>> {
    let mut groups: Vec<(String, Vec<usize>)> = vec![("all".into(), (0..track.ncols()).collect())];
    if let Some(labels) = clips {
        for (f, l) in labels.iter().enumerate() {
            match groups.iter_mut().skip(1).find(|g| g.0 == *l) {
                Some(g) => g.1.push(f),
                None => groups.push((l.clone(), vec![f])),
            }
        }
    }
    let mut rows = Vec::new();
    for identity in [Identity::None, Identity::Offset, Identity::Rbf] {
        let opts = RigOptions {
            identity,
            ..Default::default()
        };
        let r = solve_rig(rig, track, &[], &opts)?;
        for (name, peer) in scores {
            let lower = |s: &str| {
                let mut c = s.chars();
                c.next().map_or(String::new(), |h| {
                    h.to_lowercase().collect::<String>() + c.as_str()
                })
            };
            let src: Vec<usize> = (0..rig.k())
                .filter(|&i| {
                    let a = lower(&arkit_name(&rig.names[i]));
                    a == *name || a == format!("{name}Left") || a == format!("{name}Right")
                })
                .collect();
            if src.is_empty() {
                continue;
            }
            let ours: Vec<f64> = (0..track.ncols())
                .map(|f| src.iter().map(|&s| r.weights[(s, f)]).sum::<f64>() / src.len() as f64)
                .collect();
            for (clip, frames) in &groups {
                let a: Vec<f64> = frames.iter().map(|&f| ours[f]).collect();
                let b: Vec<f64> = frames.iter().map(|&f| peer[f]).collect();
                let constant = a.iter().all(|&v| v == a[0]) || b.iter().all(|&v| v == b[0]);
                rows.push(PeerRow {
                    identity: identity.name().into(),
                    shape: name.clone(),
                    clip: clip.clone(),
                    r: (!constant).then(|| correlation(&a, &b)),
                });
            }
        }
    }
    Ok(rows)
}
