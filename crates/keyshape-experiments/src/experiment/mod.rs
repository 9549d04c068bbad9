//! Scripted experiments: a TOML spec (input, points, alignment, methods, k range, solvers,
//! outputs) run headless. [`spec`] parses and checks the file, [`run`] runs it, [`studies`]
//! holds the studies beside the curves (one file each, each writing its own files);
//! [`crate::report`] writes the curves and `report.json`.
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
pub mod rig_study;
pub mod smoothing;
pub mod smoothing_plot;
pub mod spec;
pub mod studies;

pub use spec::{MapSpec, ModesSpec, RetargetSpec, Spec};
pub use studies::{
    Context, Finding, MapOutcome, MorphFace, Output, RetargetRow, Strip, StripSolver, Study,
    STUDIES,
};

use keyshape_core::decompose::{prepare, PrepareOptions};
use keyshape_core::error::{Error, Result};
use keyshape_core::keyshapes::curves::{sweep, CurveRow};
use keyshape_core::keyshapes::{axes_needed, Analysis, KeyOptions};
use keyshape_io::{builtin_sequence, read_sequence, ReadOptions};
use std::path::Path;
use std::time::Instant;

/// What a run produced, in memory.
#[derive(Debug)]
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
    /// Seconds per stage: read, prepare, pca, sweep, sweep_raw, then each study's stage.
    pub timings: Vec<(String, f64)>,
    /// What each study the spec asked for found, in [`STUDIES`] order.
    pub findings: Vec<Box<dyn Finding>>,
}

impl Outcome {
    /// The finding of the study whose finding type is `T`, if it ran.
    pub fn finding<T: 'static>(&self) -> Option<&T> {
        self.findings
            .iter()
            .find_map(|f| f.as_any().downcast_ref::<T>())
    }

    /// The lines a user wants after a run: the lowest curve, then each study's.
    pub fn summary(&self) -> Vec<String> {
        let mut out: Vec<String> = keyshape_core::keyshapes::curves::summary(&self.rows)
            .into_iter()
            .collect();
        out.extend(self.findings.iter().flat_map(|f| f.summary()));
        out
    }
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
    let cx = Context {
        spec,
        base,
        seq: &seq,
        prep: &prep,
        an: &an,
        opts: &opts,
    };
    let mut findings = Vec::new();
    for study in STUDIES {
        let t = Instant::now();
        findings.extend(study.run(&cx)?);
        add_timing(&mut timings, study.stage(), t.elapsed().as_secs_f64());
    }
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
        findings,
    })
}

/// Adds `secs` to the timings: to the last stage when it is `stage` (paper 002's three
/// studies share one), else as a new stage.
fn add_timing(timings: &mut Vec<(String, f64)>, stage: &str, secs: f64) {
    match timings.last_mut() {
        Some((last, s)) if last == stage => *s += secs,
        _ => timings.push((stage.to_string(), secs)),
    }
}

#[cfg(test)]
mod tests {
    use super::{add_timing, STUDIES};

    #[test]
    fn studies_of_one_stage_share_its_timing() {
        let mut t = vec![("sweep".to_string(), 1.0)];
        for (stage, secs) in [("retarget", 2.0), ("paper002", 0.5), ("paper002", 0.25)] {
            add_timing(&mut t, stage, secs);
        }
        add_timing(&mut t, "smooth", 4.0);
        let want = [
            ("sweep", 1.0),
            ("retarget", 2.0),
            ("paper002", 0.75),
            ("smooth", 4.0),
        ];
        assert_eq!(t.len(), want.len());
        for ((k, v), (wk, wv)) in t.iter().zip(want) {
            assert_eq!((k.as_str(), *v), (wk, wv));
        }
        // The registry's stages, in order, as report.json has always listed them.
        let mut stages: Vec<&str> = STUDIES.iter().map(|s| s.stage()).collect();
        stages.dedup();
        assert_eq!(stages, ["retarget", "paper002", "smooth", "rig"]);
    }
}
