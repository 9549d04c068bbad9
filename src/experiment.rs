//! Scripted experiments: a TOML spec (input, points, alignment, methods, k range, solvers,
//! outputs) run headless. This module parses and runs; [`crate::report`] writes the files.
//!
//! ```toml
//! title = "Paper 000 Fig. 6: liveportrait_d6, lips"
//! input = "../../shared/data/mediapipe_face_tracks/liveportrait_d6.csv"  # relative to this file; "builtin" for the built-in sequence
//! points = "lips"            # optional: point groups; default the whole face
//! align = true               # optional, default true
//! methods = ["spread", "kmeans2", "kmeans3", "hull", "greedy", "random"]
//! k = "2..24"                # or [2, 24], or 12
//! solvers = ["nnls", "ls"]
//! seed = 7                   # optional
//! shortlist = 8              # optional (greedy with nnls/bounded)
//! png = true                 # optional: write curves_<solver>.png
//! ```

use crate::decompose::{prepare, PrepareOptions};
use crate::error::{Error, Result};
use crate::io::{builtin_sequence, read_sequence, ReadOptions};
use crate::keyshapes::curves::{sweep, CurveRow};
use crate::keyshapes::{axes_needed, Analysis, KeyOptions, Method};
use crate::sequence::Format;
use crate::solve::Solver;
use nalgebra::DMatrix;
use serde::{Deserialize, Deserializer, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// An experiment file.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Spec {
    /// Title for plots and the report.
    pub title: String,
    /// Input sequence, relative to the spec file, or `builtin`.
    pub input: String,
    /// Force an input format.
    #[serde(default)]
    pub format: Option<Format>,
    /// 2 or 3.
    #[serde(default = "two")]
    pub dims: usize,
    /// Point groups (e.g. `lips`); None = whole face.
    #[serde(default)]
    pub points: Option<String>,
    /// Remove 2-D head motion first.
    #[serde(default = "yes")]
    pub align: bool,
    /// Key-shape methods for error curves (empty: no curves).
    #[serde(default, deserialize_with = "methods", serialize_with = "method_names")]
    pub methods: Vec<Method>,
    /// Inclusive k range of the curves.
    #[serde(default = "k_default", deserialize_with = "k_range")]
    pub k: (usize, usize),
    /// Solvers of the curves.
    #[serde(default = "nnls_only")]
    pub solvers: Vec<Solver>,
    /// A retargeting study (paper 000 Figs. 4–5), optional.
    #[serde(default)]
    pub retarget: Option<RetargetSpec>,
    /// Paper 002 orthogonality table, optional.
    #[serde(default)]
    pub modes: Option<ModesSpec>,
    /// Paper 002 soft-KNN intensity study (the input must be a py-feat table), optional.
    #[serde(default)]
    pub intensity: Option<crate::intensity::StudySettings>,
    /// Paper 002 trajectory mapping onto a second person and the ICT morph targets, optional.
    #[serde(default)]
    pub map: Option<MapSpec>,
    /// Seed for kmeans and random.
    #[serde(default = "seven")]
    pub seed: u64,
    /// Greedy shortlist for nnls/bounded.
    #[serde(default = "eight")]
    pub shortlist: usize,
    /// Write PNG plots.
    #[serde(default = "yes")]
    pub png: bool,
}

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
    #[serde(default = "zero_noise")]
    pub trace_noise: Vec<f64>,
    /// Frames in the strip of worst frames (0 = none).
    #[serde(default = "four")]
    pub strip: usize,
}

/// `[modes]`: the orthogonality table (paper 002 Table 2).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModesSpec {
    /// Actions file, relative to the spec.
    pub actions: String,
    /// Modes of each model.
    #[serde(default = "ten")]
    pub modes: usize,
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
    #[serde(default = "ten")]
    pub modes: usize,
    /// Folder of the ICT face (optional).
    #[serde(default)]
    pub morph: Option<String>,
}

fn ten() -> usize {
    10
}

fn zero_noise() -> Vec<f64> {
    vec![0.0]
}
fn four() -> usize {
    4
}
fn k_default() -> (usize, usize) {
    (2, 24)
}
fn nnls_only() -> Vec<Solver> {
    vec![Solver::Nnls]
}

fn method<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<Method, D::Error> {
    Method::parse(&String::deserialize(d)?).map_err(serde::de::Error::custom)
}

fn method_name<S: serde::Serializer>(m: &Method, s: S) -> std::result::Result<S::Ok, S::Error> {
    s.serialize_str(&m.name())
}

fn two() -> usize {
    2
}
fn yes() -> bool {
    true
}
fn seven() -> u64 {
    7
}
fn eight() -> usize {
    8
}

fn methods<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<Vec<Method>, D::Error> {
    let names = Vec::<String>::deserialize(d)?;
    names
        .iter()
        .map(|n| Method::parse(n).map_err(serde::de::Error::custom))
        .collect()
}

fn method_names<S: serde::Serializer>(m: &[Method], s: S) -> std::result::Result<S::Ok, S::Error> {
    s.collect_seq(m.iter().map(Method::name))
}

fn k_range<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<(usize, usize), D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum K {
        One(usize),
        Pair([usize; 2]),
        Text(String),
    }
    let bad = |s: &str| {
        serde::de::Error::custom(format!(
            "'{s}' is not a k range: write \"2..24\", [2, 24] or 12"
        ))
    };
    let k = K::deserialize(d).map_err(|_| {
        serde::de::Error::custom(
            "not a k range: write a whole number (12), a string \"2..24\" or an array [2, 24]",
        )
    })?;
    match k {
        K::One(k) => Ok((k, k)),
        K::Pair([a, b]) => Ok((a, b)),
        K::Text(t) => {
            let parts: Vec<&str> = t.split("..").collect();
            let num = |s: &str| {
                s.trim()
                    .trim_start_matches('=')
                    .parse::<usize>()
                    .map_err(|_| bad(&t))
            };
            match parts.as_slice() {
                [a, b] => Ok((num(a)?, num(b)?)),
                [a] => num(a).map(|k| (k, k)),
                _ => Err(bad(&t)),
            }
        }
    }
}

impl Spec {
    /// Reads and validates a spec; errors name the file, line, column and key.
    pub fn from_path(path: &Path) -> Result<(Spec, PathBuf)> {
        let text = crate::io::read_text(path)?;
        let spec = Spec::from_str(path, &text)?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Ok((spec, base))
    }

    /// Parses spec text (`path` only names the file in errors).
    pub fn from_str(path: &Path, text: &str) -> Result<Spec> {
        let spec: Spec = toml::from_str(text).map_err(|e| {
            let (line, col) = e.span().map_or((0, 0), |s| line_col(text, s.start));
            Error::parse(path, line, col, e.message().to_string())
        })?;
        let at = |key: &str, msg: String| {
            let (line, col) = find_key(text, key);
            Error::parse(path, line, col, format!("{key}: {msg}"))
        };
        if spec.k.0 == 0 || spec.k.0 > spec.k.1 {
            return Err(at(
                "k",
                format!("range {}..{} is empty or starts at 0", spec.k.0, spec.k.1),
            ));
        }
        let studies = spec.retarget.is_some()
            || spec.modes.is_some()
            || spec.intensity.is_some()
            || spec.map.is_some();
        if spec.methods.is_empty() && !studies {
            return Err(at("methods", "name at least one method (or add a [retarget], [modes], [intensity] or [map] table)".into()));
        }
        if spec.solvers.is_empty() {
            return Err(at("solvers", "name at least one solver".into()));
        }
        if let Some(r) = &spec.retarget {
            if r.solvers.is_empty()
                || r.k == 0
                || r.trace_noise.iter().any(|v| !(v.is_finite() && *v >= 0.0))
            {
                return Err(at(
                    "retarget",
                    "needs k ≥ 1, at least one solver, and trace_noise values ≥ 0".into(),
                ));
            }
        }
        if spec.dims != 2 && spec.dims != 3 {
            return Err(at("dims", format!("must be 2 or 3, got {}", spec.dims)));
        }
        Ok(spec)
    }
}

/// 1-based line and column of a byte offset.
fn line_col(text: &str, offset: usize) -> (u64, u64) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() as u64 + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) as u64 + 1;
    (line, col)
}

/// Line and column of `key = …` at the start of a line (0, 0 if absent).
fn find_key(text: &str, key: &str) -> (u64, u64) {
    for (i, l) in text.lines().enumerate() {
        let t = l.trim_start();
        if t.strip_prefix(key)
            .is_some_and(|r| r.trim_start().starts_with('='))
        {
            return (i as u64 + 1, (l.len() - t.len()) as u64 + 1);
        }
    }
    (0, 0)
}

/// What a run produced, in memory.
#[derive(Debug, Clone, Serialize)]
pub struct Outcome {
    /// The spec as run.
    pub spec: Spec,
    /// The input path as resolved.
    pub input: String,
    /// Valid frames analysed.
    pub frames: usize,
    /// Points per shape.
    pub points: usize,
    /// Failed frames left out.
    pub failed_frames: usize,
    /// Share of variance on the first principal axes.
    pub explained_variance: Vec<f64>,
    /// The curves.
    pub rows: Vec<CurveRow>,
    /// Seconds per stage: read, prepare, pca, sweep.
    pub timings: Vec<(String, f64)>,
    /// Retargeting study rows (one per trace-noise level and solver).
    pub retarget: Vec<RetargetRow>,
    /// The frames where the first solver distorts most, for the strip picture.
    #[serde(skip)]
    pub strip: Option<Strip>,
    /// Paper 002 orthogonality tables.
    #[serde(skip)]
    pub orthogonality: Option<crate::modes::OrthogonalityStudy>,
    /// Paper 002 intensity study.
    pub intensity: Option<crate::intensity::Study>,
    /// Paper 002 mapping.
    #[serde(skip)]
    pub map: Option<MapOutcome>,
}

/// A morph-target face ready to export: neutral positions, faces, the used targets (name,
/// dense offsets) and their weights (targets × frames).
#[derive(Debug, Clone)]
pub struct MorphFace {
    /// Neutral positions.
    pub neutral: Vec<[f64; 3]>,
    /// Faces.
    pub faces: Vec<Vec<usize>>,
    /// Used targets.
    pub targets: Vec<(String, Vec<[f64; 3]>)>,
    /// Weights, targets × frames.
    pub weights: DMatrix<f64>,
}

/// What `[map]` produced.
#[derive(Debug, Clone)]
pub struct MapOutcome {
    /// The mode alignment used.
    pub alignment: crate::trajectory::ModeAlignment,
    /// Action names and their normalised trajectories (actions × frames).
    pub actions: Vec<String>,
    /// Trajectories.
    pub trajectories: DMatrix<f64>,
    /// Frame numbers.
    pub frames: Vec<i64>,
    /// Frames per second.
    pub fps: f64,
    /// The morph face, if asked: neutral positions, faces, used targets (name, dense
    /// offsets) and their weights (targets × frames).
    pub morph: Option<MorphFace>,
}

/// One retargeting result.
#[derive(Debug, Clone, Serialize)]
pub struct RetargetRow {
    /// Solver.
    pub solver: String,
    /// Tracing noise on the target key shapes, in inter-ocular distances.
    pub trace_noise: f64,
    /// Key frames (frame numbers).
    pub keys: Vec<i64>,
    /// Source RMS per point.
    pub source_rms: f64,
    /// Target-domain RMS per point against G(Q_t).
    pub target_rms: f64,
    /// Mean squared second difference of the weights.
    pub jitter: f64,
    /// Share of negative weights.
    pub negative_share: f64,
    /// Largest |w|.
    pub max_abs_weight: f64,
}

/// Shapes for a strip of frames (aligned coordinates): per frame the tracked shape, the
/// ground truth G(q) and, per solver, the source reconstruction and the retargeted shape.
#[derive(Debug, Clone)]
pub struct Strip {
    /// Tracing noise level used.
    pub trace_noise: f64,
    /// Frame numbers.
    pub frames: Vec<i64>,
    /// Drawing contours (selection indices).
    pub polylines: Vec<Vec<usize>>,
    /// Values per point.
    pub dims: usize,
    /// Tracked shapes (n × strip frames).
    pub tracked: DMatrix<f64>,
    /// Ground truth G(q).
    pub truth: DMatrix<f64>,
    /// Per solver: what it made of the strip's frames.
    pub solvers: Vec<StripSolver>,
}

/// One solver's shapes in a [`Strip`].
#[derive(Debug, Clone)]
pub struct StripSolver {
    /// Solver name.
    pub name: String,
    /// Source reconstruction (n × strip frames).
    pub source: DMatrix<f64>,
    /// Retargeted shapes.
    pub target: DMatrix<f64>,
    /// Target-domain RMS per strip frame.
    pub target_rms: Vec<f64>,
}

/// Runs a spec whose relative paths are relative to `base`.
pub fn run(spec: &Spec, base: &Path, tick: &(dyn Fn(usize, usize) + Sync)) -> Result<Outcome> {
    let mut timings = Vec::new();
    let t = Instant::now();
    let (seq, input) = if spec.input == "builtin" {
        (builtin_sequence()?, crate::io::BUILTIN_NAME.to_string())
    } else {
        let p = base.join(&spec.input);
        let opts = ReadOptions {
            format: spec.format,
            dims: spec.dims,
        };
        (read_sequence(&p, &opts)?, p.display().to_string())
    };
    timings.push(("read".to_string(), t.elapsed().as_secs_f64()));
    let t = Instant::now();
    let prep = prepare(
        &seq,
        &PrepareOptions {
            points: spec.points.clone(),
            align: spec.align,
        },
    )?;
    timings.push(("prepare".to_string(), t.elapsed().as_secs_f64()));
    let t = Instant::now();
    let axes = axes_needed(&spec.methods, spec.k.1);
    let an = Analysis::with_axes(prep.seq.coords.clone(), prep.seq.points, axes)?;
    timings.push(("pca".to_string(), t.elapsed().as_secs_f64()));
    let t = Instant::now();
    let opts = KeyOptions {
        solver: spec.solvers[0],
        seed: spec.seed,
        shortlist: spec.shortlist,
    };
    let rows = if spec.methods.is_empty() {
        Vec::new()
    } else {
        sweep(
            &an,
            &spec.methods,
            spec.k.0..=spec.k.1,
            &spec.solvers,
            &opts,
            tick,
        )?
    };
    timings.push(("sweep".to_string(), t.elapsed().as_secs_f64()));
    let t = Instant::now();
    let (retarget, strip) = match &spec.retarget {
        Some(r) => retarget_study(r, &seq, &prep, &an, &opts)?,
        None => (Vec::new(), None),
    };
    timings.push(("retarget".to_string(), t.elapsed().as_secs_f64()));
    let t = Instant::now();
    let orthogonality = match &spec.modes {
        Some(m) => {
            let full = prepare(
                &seq,
                &PrepareOptions {
                    points: None,
                    align: spec.align,
                },
            )?;
            let layout = full
                .layout
                .as_ref()
                .ok_or_else(|| Error::invalid("[modes] needs a known layout"))?;
            let regions = crate::modes::ModeRegions::builtin(layout)?.points(layout)?;
            let actions = crate::modes::Actions::read(&base.join(&m.actions))?;
            Some(crate::modes::orthogonality_study(
                &full.seq.coords,
                &full.seq.frames,
                full.seq.dims,
                &regions,
                &actions,
                m.modes,
            )?)
        }
        None => None,
    };
    let intensity = match &spec.intensity {
        Some(st) => Some(crate::intensity::study(&base.join(&spec.input), st)?),
        None => None,
    };
    let map = match &spec.map {
        Some(m) => Some(map_study(m, &seq, base, spec.align)?),
        None => None,
    };
    timings.push(("paper002".to_string(), t.elapsed().as_secs_f64()));
    Ok(Outcome {
        spec: spec.clone(),
        input,
        frames: an.frames(),
        points: an.points,
        failed_frames: seq.failed.len(),
        explained_variance: an.pca.explained_ratio().into_iter().take(6).collect(),
        rows,
        timings,
        retarget,
        strip,
        orthogonality,
        intensity,
        map,
    })
}

fn map_study(
    m: &MapSpec,
    seq: &crate::sequence::Sequence,
    base: &Path,
    align: bool,
) -> Result<MapOutcome> {
    use crate::trajectory::{person_model, trajectories, ModeAlignment};
    let model_of = |s: &crate::sequence::Sequence,
                    actions: &str|
     -> Result<(crate::trajectory::PersonModel, crate::decompose::Prepared)> {
        let prep = prepare(
            s,
            &PrepareOptions {
                points: None,
                align,
            },
        )?;
        let layout = prep
            .layout
            .as_ref()
            .ok_or_else(|| Error::invalid("[map] needs a known layout"))?;
        let regions = crate::modes::ModeRegions::builtin(layout)?.points(layout)?;
        let acts = crate::modes::Actions::read(&base.join(actions))?;
        Ok((
            person_model(
                &prep.seq.coords,
                &prep.seq.frames,
                prep.seq.dims,
                &regions,
                &acts,
                m.modes,
            )?,
            prep,
        ))
    };
    let (src, prep) = model_of(seq, &m.actions)?;
    let tseq = read_sequence(&base.join(&m.target_sequence), &ReadOptions::default())?;
    let (tgt, _) = model_of(&tseq, &m.target_actions)?;
    let alignment = ModeAlignment::by_actions(&src, &tgt);
    let traj = trajectories(&src, &prep.seq.coords);
    let actions: Vec<String> = src.actions.iter().map(|a| a.0.clone()).collect();
    let at = DMatrix::from_fn(actions.len(), traj.ncols(), |i, t| {
        src.actions[i].2 * traj[(src.actions[i].1, t)]
    });
    let morph = match &m.morph {
        None => None,
        Some(dir) => {
            let dir = base.join(dir);
            let mesh = crate::io::obj::read_obj(&dir.join("neutral_face.obj"))?;
            let targets = crate::morph::MorphTargets::read(
                &dir.join("expressions.csv"),
                &dir.join("expression_deltas.csv"),
                mesh.positions.len(),
            )?;
            let w = crate::morph::MorphMapping::builtin()?.weights(&targets, &actions, &at)?;
            let (targets, weights) = targets.used_dense(&w, mesh.positions.len());
            Some(MorphFace {
                neutral: mesh.positions,
                faces: mesh.faces,
                targets,
                weights,
            })
        }
    };
    Ok(MapOutcome {
        alignment,
        actions,
        trajectories: at,
        frames: prep.seq.frames.clone(),
        fps: seq.fps().unwrap_or(30.0),
        morph,
    })
}

/// Paper 000 Figs. 4–5 on the built-in target: the same key frames, each solver, each
/// tracing-noise level; the strip shows the highest noise level's worst frames for the
/// first solver.
fn retarget_study(
    r: &RetargetSpec,
    seq: &crate::sequence::Sequence,
    prep: &crate::decompose::Prepared,
    an: &Analysis,
    opts: &KeyOptions,
) -> Result<(Vec<RetargetRow>, Option<Strip>)> {
    use crate::retarget::{retarget, setup, KeyPlan, Target};
    let keys = if an.proj.nrows() >= crate::keyshapes::axes_needed(&[r.method], r.k) {
        r.method.heuristic(opts).select(an, r.k)?.columns
    } else {
        let an2 = Analysis::with_axes(an.coords.clone(), an.points, axes_needed(&[r.method], r.k))?;
        r.method.heuristic(opts).select(&an2, r.k)?.columns
    };
    let key_frames: Vec<i64> = keys.iter().map(|&c| prep.seq.frames[c]).collect();
    let (g, iod) = setup::builtin_target(seq, prep)?;
    let mut rows = Vec::new();
    let mut last = Vec::new();
    let top_noise = r.trace_noise.iter().copied().fold(0.0, f64::max);
    for &noise in &r.trace_noise {
        for &solver in &r.solvers {
            let target = Target::Warp {
                g: g.clone(),
                trace_noise: noise * iod,
            };
            let res = retarget(
                &prep.seq.coords,
                prep.seq.dims,
                &KeyPlan::Global(keys.clone()),
                &target,
                None,
                solver,
            )?;
            rows.push(RetargetRow {
                solver: solver.name().into(),
                trace_noise: noise,
                keys: key_frames.clone(),
                source_rms: res.source_rms(),
                target_rms: res.target_rms().unwrap_or(f64::NAN),
                jitter: res.jitter(),
                negative_share: res.negative_share(),
                max_abs_weight: res
                    .weights
                    .iter()
                    .flat_map(|w| w.iter())
                    .fold(0.0, |m, v| m.max(v.abs())),
            });
            if noise == top_noise {
                last.push((solver, res));
            }
        }
    }
    if r.strip == 0 || last.is_empty() {
        return Ok((rows, None));
    }
    let first = last[0].1.target_rms_per_frame().unwrap_or_default();
    let mut order: Vec<usize> = (0..first.len()).collect();
    order.sort_by(|&a, &b| first[b].total_cmp(&first[a]));
    let mut cols: Vec<usize> = order.into_iter().take(r.strip).collect();
    cols.sort_unstable();
    let polylines = prep
        .layout
        .as_ref()
        .map(|l| setup::polylines_for(l, &prep.point_indices))
        .unwrap_or_default();
    let truth = last[0]
        .1
        .truth
        .clone()
        .unwrap_or_else(|| prep.seq.coords.clone());
    let strip = Strip {
        trace_noise: top_noise,
        frames: cols.iter().map(|&c| prep.seq.frames[c]).collect(),
        polylines,
        dims: prep.seq.dims,
        tracked: prep.seq.coords.select_columns(&cols),
        truth: truth.select_columns(&cols),
        solvers: last
            .iter()
            .map(|(s, res)| {
                let per = res.target_rms_per_frame().unwrap_or_default();
                StripSolver {
                    name: s.name().to_string(),
                    source: res.source.select_columns(&cols),
                    target: res.target.select_columns(&cols),
                    target_rms: cols.iter().map(|&c| per[c]).collect(),
                }
            })
            .collect(),
    };
    Ok((rows, Some(strip)))
}
