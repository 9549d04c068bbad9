//! Scripted experiments: a TOML spec (input, points, alignment, methods, k range, solvers,
//! outputs) run headless. [`spec`] parses and checks the file, [`run`] runs it, [`studies`]
//! holds the studies beside the curves; [`crate::report`] writes the files.
//!
//! ```toml
//! title = "Paper 000 Fig. 6: liveportrait_d6, lips"
//! input = "../../shared/data/mediapipe_face_tracks/liveportrait_d6.csv"  # relative to this file; "builtin" for the built-in sequence
//! points = "lips"            # optional: point groups; default the whole face
//! align = true               # optional, default true
//! methods = ["spread", "kmeans2", "kmeans3", "kmeans2-mean", "hull", "greedy", "random"]
//! compare_raw = true         # optional: the curves on raw coordinates too, side by side
//! k = "2..24"                # or [2, 24], or 12
//! solvers = ["nnls", "ls"]
//! seed = 7                   # optional
//! shortlist = 8              # optional (greedy with nnls/bounded)
//! png = true                 # optional: write curves_<solver>.png
//! ```

pub mod corpus;
pub mod smoothing;
pub mod spec;
pub mod studies;

pub use spec::{MapSpec, ModesSpec, RetargetSpec, Spec};
pub use studies::{MapOutcome, MorphFace, RetargetRow, Strip, StripSolver};

use keyshape_core::decompose::{prepare, PrepareOptions};
use keyshape_core::error::{Error, Result};
use keyshape_core::keyshapes::curves::{sweep, CurveRow};
use keyshape_core::keyshapes::{axes_needed, Analysis, KeyOptions};
use keyshape_io::{builtin_sequence, read_sequence, ReadOptions};
use serde::Serialize;
use std::path::Path;
use std::time::Instant;
use studies::{map_study, retarget_study};

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
    /// The curves on raw (unaligned) coordinates, when `compare_raw` asks for them.
    pub raw_rows: Vec<CurveRow>,
    /// Seconds per stage: read, prepare, pca, sweep.
    pub timings: Vec<(String, f64)>,
    /// Retargeting study rows (one per trace-noise level and solver).
    pub retarget: Vec<RetargetRow>,
    /// The frames where the first solver distorts most, for the strip picture.
    #[serde(skip)]
    pub strip: Option<Strip>,
    /// Paper 002 orthogonality tables.
    #[serde(skip)]
    pub orthogonality: Option<keyshape_actions::modes::OrthogonalityStudy>,
    /// Paper 002 intensity study.
    pub intensity: Option<keyshape_actions::intensity::Study>,
    /// Paper 002 mapping.
    #[serde(skip)]
    pub map: Option<MapOutcome>,
    /// The smoothing study.
    pub smoothing: Vec<smoothing::SmoothRow>,
    /// The rig study's recovery rows.
    pub rig_recovery: Vec<keyshape_rig::study::RecoveryRow>,
    /// The rig study's agreement with the input's own scores.
    pub rig_peer: Vec<keyshape_rig::study::PeerRow>,
    /// Study (ii)'s summary per setting, with the calibrated references.
    pub rig_peer_summary: Vec<keyshape_rig::study::PeerSummary>,
}

/// Runs a spec whose relative paths are relative to `base` (one `input`; a corpus runs
/// through [`corpus::run`]).
pub fn run(spec: &Spec, base: &Path, tick: &(dyn Fn(usize, usize) + Sync)) -> Result<Outcome> {
    if spec.inputs.is_some() {
        return Err(Error::invalid(
            "this experiment names a corpus (`inputs`): run it with experiment::corpus::run",
        ));
    }
    let t = Instant::now();
    let (seq, input) = if spec.input == "builtin" {
        (builtin_sequence()?, keyshape_io::BUILTIN_NAME.to_string())
    } else {
        let p = base.join(&spec.input);
        let opts = ReadOptions {
            format: spec.format,
            dims: spec.dims,
        };
        (read_sequence(&p, &opts)?, p.display().to_string())
    };
    let read = t.elapsed().as_secs_f64();
    analyse(spec, base, seq, input, read, tick)
}

/// Runs a spec's studies on one sequence already read (`read`: the seconds reading took).
pub(crate) fn analyse(
    spec: &Spec,
    base: &Path,
    seq: keyshape_core::sequence::Sequence,
    input: String,
    read: f64,
    tick: &(dyn Fn(usize, usize) + Sync),
) -> Result<Outcome> {
    let mut timings = vec![("read".to_string(), read)];
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
    let raw_rows = if spec.compare_raw {
        let raw = prepare(
            &seq,
            &PrepareOptions {
                points: spec.points.clone(),
                align: false,
            },
        )?;
        let an_raw = Analysis::with_axes(raw.seq.coords.clone(), raw.seq.points, axes)?;
        sweep(
            &an_raw,
            &spec.methods,
            spec.k.0..=spec.k.1,
            &spec.solvers,
            &opts,
            tick,
        )?
    } else {
        Vec::new()
    };
    timings.push(("sweep_raw".to_string(), t.elapsed().as_secs_f64()));
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
            let opts =
                keyshape_actions::modes::RegionOptions::from_user(m.boundary, m.blend_radius)?;
            let regions = keyshape_actions::modes::ModeRegions::builtin(layout)?.weights(
                layout,
                &full.seq.coords,
                full.seq.dims,
                &opts,
            )?;
            let actions = keyshape_actions::modes::Actions::read_for(
                &base.join(&m.actions),
                &full.seq.source,
                &full.seq.frames,
            )?;
            Some(keyshape_actions::modes::orthogonality_study(
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
        Some(st) => Some(keyshape_actions::intensity::study_with_format(
            &base.join(&spec.input),
            spec.format,
            st,
        )?),
        None => None,
    };
    let map = match &spec.map {
        Some(m) => Some(map_study(m, &seq, base, spec.align)?),
        None => None,
    };
    timings.push(("paper002".to_string(), t.elapsed().as_secs_f64()));
    let t = Instant::now();
    let smoothing = match &spec.smooth {
        Some(st) => smoothing::smoothing_study(&seq, &prep, st, &opts)?,
        None => Vec::new(),
    };
    timings.push(("smooth".to_string(), t.elapsed().as_secs_f64()));
    let t = Instant::now();
    let (rig_recovery, (rig_peer, rig_peer_summary)) = match &spec.rig {
        Some(st) => {
            let rig = keyshape_rig::Rig::read_ict(&keyshape_io::shared_data("ict_facekit_face")?)?;
            let rec = keyshape_rig::study::recovery(&rig, st)?;
            let peer = if st.against_input_scores {
                if seq.points != keyshape_rig::LANDMARKS || spec.input == "builtin" {
                    return Err(Error::invalid(
                        "[rig] against_input_scores needs a 68-point py-feat table as input",
                    ));
                }
                let p = base.join(&spec.input);
                let header = keyshape_io::read_text(&p)?;
                let names: Vec<&str> = header
                    .lines()
                    .next()
                    .unwrap_or("")
                    .split(',')
                    .map(str::trim)
                    .filter(|n| {
                        keyshape_rig::livelink::COLUMNS[..52]
                            .iter()
                            .any(|c| c.eq_ignore_ascii_case(n))
                    })
                    .collect();
                if names.is_empty() {
                    return Err(Error::file(
                        &p,
                        "[rig] against_input_scores: no ARKit-named score columns",
                    ));
                }
                let cols = keyshape_io::read_columns(&p, &names)?;
                let scores: Vec<(String, Vec<f64>)> =
                    names.iter().map(|n| n.to_string()).zip(cols).collect();
                keyshape_rig::study::against_peer(
                    &rig,
                    &seq.coords,
                    &scores,
                    seq.segments.as_deref(),
                )?
            } else {
                (Vec::new(), Vec::new())
            };
            (rec, peer)
        }
        None => (Vec::new(), (Vec::new(), Vec::new())),
    };
    timings.push(("rig".to_string(), t.elapsed().as_secs_f64()));
    Ok(Outcome {
        spec: spec.clone(),
        input,
        frames: an.frames(),
        points: an.points,
        failed_frames: seq.failed.len(),
        explained_variance: an.pca.explained_ratio().into_iter().take(6).collect(),
        rows,
        raw_rows,
        timings,
        retarget,
        strip,
        orthogonality,
        intensity,
        map,
        smoothing,
        rig_recovery,
        rig_peer,
        rig_peer_summary,
    })
}
