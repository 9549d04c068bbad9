//! The rig-solve study: (i) recovery of known weights from synthetic
//! tracks rendered through the rig under a moving head with landmark noise, per solver and
//! noise level; (ii) agreement with a peer's ARKit-style scores (py-feat's) on a real track.

use keyshape_core::error::{Error, Result};
use keyshape_core::solve::Solver;
use keyshape_core::stats::correlation;
use keyshape_rig::camera::Camera;
use keyshape_rig::livelink::arkit_name;
use keyshape_rig::{solve_rig, Identity, Neutral, Rig, RigOptions};
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use serde::Serialize;

pub use super::spec::{default_shapes, RigStudySettings};

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
        return Err(Error::bad_setting(
            "frames",
            st.frames,
            "[rig] frames must be at least 2",
        ));
    }
    for &n in &st.noise_px {
        keyshape_core::limits::NOISE_PX.check("noise_px", n)?;
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
    /// How the neutral frame was chosen (`auto`, `least-active`; `-` without an identity).
    pub neutral: String,
    /// ARKit name (the peer's column, lower camel case).
    pub shape: String,
    /// `all` (every frame pooled) or a clip label of the track.
    pub clip: String,
    /// Pearson r over the frames; None when either series is constant there (a frozen
    /// shape, one held at a bound throughout, or a score the peer never moves), where r is
    /// undefined.
    pub r: Option<f64>,
}

/// A peer score counts as moved when its standard deviation over the track is at least
/// this (2 % of its [0, 1] range); the summary is taken over such shapes only — a score the
/// peer holds near one value gives a correlation that measures noise.
pub const PEER_MOVES_SD: f64 = 0.02;

/// Ridge λ of the calibrated references (on standardised features).
pub const CEILING_RIDGE: f64 = 10.0;

/// Whether a 68-point 2-D track can see the ARKit shape `name` at all: eye gaze
/// (`eyeLook…`) moves the pupils, which iBUG-68 does not track.
pub fn seen_by_68_points(name: &str) -> bool {
    !name.starts_with("eyeLook")
}

/// One setting's agreement with the peer, over the shapes the peer moves and a 68-point
/// track can see (fixed by the peer's data before any solve: see [`PEER_MOVES_SD`]).
#[derive(Debug, Clone, Serialize)]
pub struct PeerSummary {
    /// `identity/neutral` of the rig solve, or a calibrated reference (`ridge: …`).
    pub setting: String,
    /// Shapes in the set.
    pub shapes: usize,
    /// Mean over the set of the pooled r (a shape the setting holds constant counts 0).
    pub mean_r: f64,
    /// Median over the set of the pooled r (the same convention).
    pub median_r: f64,
    /// Median over clips of the clip's mean r (over the set's shapes the peer moves in that
    /// clip; constant on our side counts 0); None without clips.
    pub clip_mean_r: Option<f64>,
    /// RMS 2-D landmark error of the solve (track units); None for the references.
    pub rms: Option<f64>,
}

fn lower_first(s: &str) -> String {
    let mut c = s.chars();
    c.next().map_or(String::new(), |h| {
        h.to_lowercase().collect::<String>() + c.as_str()
    })
}

fn std_dev(v: &[f64]) -> f64 {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n).sqrt()
}

fn median_of(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    (v[v.len() / 2] + v[(v.len() - 1) / 2]) / 2.0
}

/// Leave-one-group-out ridge regression of `y` (frames × outputs) on `x` (frames ×
/// features): for each group, features standardised on the other groups' frames (a
/// constant feature is dropped), outputs centred, `W = (XᵀX + λI)⁻¹ XᵀY`, and the group's
/// frames predicted. Returns frames × outputs.
pub fn leave_one_group_out_ridge(
    x: &DMatrix<f64>,
    y: &DMatrix<f64>,
    groups: &[Vec<usize>],
    lambda: f64,
) -> DMatrix<f64> {
    let (n, p) = (x.nrows(), x.ncols());
    let mut pred = DMatrix::zeros(n, y.ncols());
    for held in groups {
        let mut train = vec![true; n];
        for &f in held {
            train[f] = false;
        }
        let rows: Vec<usize> = (0..n).filter(|&f| train[f]).collect();
        if rows.is_empty() {
            continue;
        }
        let m = rows.len() as f64;
        let mu: Vec<f64> = (0..p)
            .map(|j| rows.iter().map(|&f| x[(f, j)]).sum::<f64>() / m)
            .collect();
        let sd: Vec<f64> = (0..p)
            .map(|j| {
                (rows
                    .iter()
                    .map(|&f| (x[(f, j)] - mu[j]).powi(2))
                    .sum::<f64>()
                    / m)
                    .sqrt()
            })
            .collect();
        let feat = |f: usize, j: usize| {
            if sd[j] > 0.0 {
                (x[(f, j)] - mu[j]) / sd[j]
            } else {
                0.0
            }
        };
        let xt = DMatrix::from_fn(rows.len(), p, |i, j| feat(rows[i], j));
        let ym: Vec<f64> = (0..y.ncols())
            .map(|k| rows.iter().map(|&f| y[(f, k)]).sum::<f64>() / m)
            .collect();
        let yt = DMatrix::from_fn(rows.len(), y.ncols(), |i, k| y[(rows[i], k)] - ym[k]);
        let mut g = xt.transpose() * &xt;
        for j in 0..p {
            g[(j, j)] += lambda;
        }
        let Some(ch) = g.cholesky() else { continue };
        let w = ch.solve(&(xt.transpose() * yt));
        for &f in held {
            for k in 0..y.ncols() {
                let v: f64 = (0..p).map(|j| feat(f, j) * w[(j, k)]).sum();
                pred[(f, k)] = v + ym[k];
            }
        }
    }
    pred
}

/// Study (ii): the rig solve of `track` (bounded; no identity, and the offset and RBF
/// identities each with the `least-active` and `auto` neutral) against the peer's
/// ARKit-style score columns `scores` (name → per-frame values, in py-feat's lower camel
/// case), pooled and per clip of `clips` (a label per frame); rig shapes split left/right
/// where the peer has one column are averaged. The summary adds, with two clips or more,
/// two calibrated references that are *fitted to the peer* (leave one clip out, ridge
/// [`CEILING_RIDGE`]): from the default solve's weights, and from the Procrustes-aligned
/// landmarks — how much of the peer's scores the solve's weights and the track hold at all.
pub fn against_peer(
    rig: &Rig,
    track: &DMatrix<f64>,
    scores: &[(String, Vec<f64>)],
    clips: Option<&[String]>,
) -> Result<(Vec<PeerRow>, Vec<PeerSummary>)> {
    let frames = track.ncols();
    let sum = Summariser {
        groups: clip_groups(frames, clips),
        // The summary's set, from the peer's data alone.
        set: (0..scores.len())
            .filter(|&j| seen_by_68_points(&scores[j].0) && std_dev(&scores[j].1) >= PEER_MOVES_SD)
            .collect(),
        scores,
    };
    let groups = &sum.groups;
    let mut rows = Vec::new();
    let mut summary = Vec::new();
    let mut default_weights = None;
    for (identity, neutral) in [
        (Identity::None, Neutral::Auto),
        (Identity::Offset, Neutral::LeastActive),
        (Identity::Offset, Neutral::Auto),
        (Identity::Rbf, Neutral::LeastActive),
        (Identity::Rbf, Neutral::Auto),
    ] {
        let opts = RigOptions {
            identity,
            neutral,
            ..Default::default()
        };
        let neutral_name = match (identity, neutral) {
            (Identity::None, _) => "-",
            (_, Neutral::LeastActive) => "least-active",
            _ => "auto",
        };
        let r = solve_rig(rig, track, &[], &opts)?;
        let ours_of = peer_columns(rig, &r.weights, scores);
        for ((name, peer), ours) in scores.iter().zip(&ours_of) {
            let Some(ours) = ours else { continue };
            for (clip, fr) in groups {
                let a: Vec<f64> = fr.iter().map(|&f| ours[f]).collect();
                let b: Vec<f64> = fr.iter().map(|&f| peer[f]).collect();
                let constant = a.iter().all(|&v| v == a[0]) || b.iter().all(|&v| v == b[0]);
                rows.push(PeerRow {
                    identity: identity.name().into(),
                    neutral: neutral_name.into(),
                    shape: name.clone(),
                    clip: clip.clone(),
                    r: (!constant).then(|| correlation(&a, &b)),
                });
            }
        }
        let rms = (r.rms.iter().map(|e| e * e).sum::<f64>() / frames as f64).sqrt();
        let ours = |j: usize| ours_of[j].clone().filter(|a| a.iter().any(|&v| v != a[0]));
        summary.push(sum.summarise(
            format!("{}/{neutral_name}", identity.name()),
            &ours,
            Some(rms),
        ));
        if (identity, neutral) == (Identity::Offset, Neutral::Auto) {
            default_weights = Some(r.weights);
        }
    }
    if groups.len() > 2 {
        let w = default_weights.unwrap_or_else(|| DMatrix::zeros(rig.k(), frames));
        summary.extend(sum.ceilings(track, &w)?);
    }
    Ok((rows, summary))
}

/// The frames of the whole track ("all"), then of each clip in order of first appearance
/// (`clips`: a label per frame).
fn clip_groups(frames: usize, clips: Option<&[String]>) -> Vec<(String, Vec<usize>)> {
    let mut groups: Vec<(String, Vec<usize>)> = vec![("all".into(), (0..frames).collect())];
    if let Some(labels) = clips {
        for (f, l) in labels.iter().enumerate() {
            match groups.iter_mut().skip(1).find(|g| g.0 == *l) {
                Some(g) => g.1.push(f),
                None => groups.push((l.clone(), vec![f])),
            }
        }
    }
    groups
}

/// Per peer column: the mean of the rig's shapes of that name (`weights`: shapes ×
/// frames); None when the rig has none.
fn peer_columns(
    rig: &Rig,
    weights: &DMatrix<f64>,
    scores: &[(String, Vec<f64>)],
) -> Vec<Option<Vec<f64>>> {
    scores
        .iter()
        .map(|(name, _)| {
            let src: Vec<usize> = (0..rig.k())
                .filter(|&i| {
                    let a = lower_first(&arkit_name(&rig.names[i]));
                    a == *name || a == format!("{name}Left") || a == format!("{name}Right")
                })
                .collect();
            (!src.is_empty()).then(|| {
                (0..weights.ncols())
                    .map(|f| src.iter().map(|&s| weights[(s, f)]).sum::<f64>() / src.len() as f64)
                    .collect()
            })
        })
        .collect()
}

/// The peer study's summary rows: the peer's columns in the summary's `set`, the clip
/// groups (the whole track first).
struct Summariser<'a> {
    groups: Vec<(String, Vec<usize>)>,
    set: Vec<usize>,
    scores: &'a [(String, Vec<f64>)],
}

impl Summariser<'_> {
    /// One summary row: `ours(j)` against peer column `j`, pooled and per clip.
    fn summarise(
        &self,
        setting: String,
        ours: &dyn Fn(usize) -> Option<Vec<f64>>,
        rms: Option<f64>,
    ) -> PeerSummary {
        let (set, groups, scores) = (&self.set, &self.groups, self.scores);
        let pooled: Vec<f64> = set
            .iter()
            .map(|&j| ours(j).map_or(0.0, |a| correlation(&a, &scores[j].1)))
            .collect();
        let clip_mean_r = (groups.len() > 1).then(|| {
            let per: Vec<f64> = groups[1..]
                .iter()
                .filter_map(|(_, fr)| {
                    let rs: Vec<f64> = set
                        .iter()
                        .filter_map(|&j| {
                            let b: Vec<f64> = fr.iter().map(|&f| scores[j].1[f]).collect();
                            if b.iter().all(|&v| v == b[0]) {
                                return None;
                            }
                            Some(ours(j).map_or(0.0, |a| {
                                let a: Vec<f64> = fr.iter().map(|&f| a[f]).collect();
                                correlation(&a, &b)
                            }))
                        })
                        .collect();
                    (!rs.is_empty()).then(|| rs.iter().sum::<f64>() / rs.len() as f64)
                })
                .collect();
            median_of(per)
        });
        PeerSummary {
            setting,
            shapes: set.len(),
            mean_r: pooled.iter().sum::<f64>() / pooled.len().max(1) as f64,
            median_r: median_of(pooled),
            clip_mean_r,
            rms,
        }
    }

    /// The two references fitted to the peer (leave one clip out, ridge
    /// [`CEILING_RIDGE`]): from the default solve's weights `w`, and from the
    /// Procrustes-aligned landmarks of `track`.
    fn ceilings(&self, track: &DMatrix<f64>, w: &DMatrix<f64>) -> Result<Vec<PeerSummary>> {
        let (set, scores) = (&self.set, self.scores);
        let held: Vec<Vec<usize>> = self.groups[1..].iter().map(|g| g.1.clone()).collect();
        let y = DMatrix::from_fn(track.ncols(), set.len(), |f, k| scores[set[k]].1[f]);
        let aligned = keyshape_core::align::procrustes(track, 2)?.coords;
        let mut out = Vec::new();
        for (setting, x) in [
            (
                "ridge: the offset/auto weights → peer, leave one clip out",
                w.transpose(),
            ),
            (
                "ridge: aligned landmarks → peer, leave one clip out",
                aligned.transpose(),
            ),
        ] {
            let pred = leave_one_group_out_ridge(&x, &y, &held, CEILING_RIDGE);
            let ours = |j: usize| {
                set.iter()
                    .position(|&s| s == j)
                    .map(|k| pred.column(k).iter().copied().collect::<Vec<f64>>())
            };
            out.push(self.summarise(setting.into(), &ours, None));
        }
        Ok(out)
    }
}
