//! Shards written as partials, read back, checked and merged.

use super::aggregate::{aggregate, CorpusOutcome};
use super::{Partial, Unit, PARTIAL_FILE, PARTIAL_FORMAT};

use keyshape_core::error::{Error, Needed, Result};
use std::path::{Path, PathBuf};

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
        return Err(Error::needs_in(
            dir,
            Needed::ShardReports,
            format!("no {PARTIAL_FILE}: not the output of a sharded run"),
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

/// The most frames a partial's sequence may have: a 4 GiB input of 40-byte rows.
const MAX_FRAMES: usize = 100_000_000;
/// The most points a partial's sequence may have.
const MAX_POINTS: usize = 100_000;
/// The range of inter-ocular distances a partial may carry: normalised coordinates of a
/// tiny face to pixels of a huge image. Below it every error divided by it overflows.
const MIN_IOD: f64 = 1e-6;
const MAX_IOD: f64 = 1e7;

/// The most shards of one run.
pub const MAX_SHARDS: usize = keyshape_core::limits::SHARDS.hi as usize;

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
        // What a run can read: the readers' byte limit bounds the frames, a tracker's
        // layout the points (MediaPipe's 478 is the largest known; dense rigs stay far
        // below the bound), a face's eye distance in pixels or normalised coordinates.
        if r.frames > MAX_FRAMES || r.points > MAX_POINTS {
            return Err(format!(
                "sequence {}: {} frames of {} points is beyond what a run reads (at most {MAX_FRAMES} frames of {MAX_POINTS} points)",
                r.unit.name, r.frames, r.points
            ));
        }
        if !(r.iod.is_finite() && (MIN_IOD..=MAX_IOD).contains(&r.iod)) {
            return Err(format!(
                "sequence {}: inter-ocular distance {:?} is not one a face has (give {MIN_IOD:e} to {MAX_IOD:e})",
                r.unit.name, r.iod
            ));
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
    let n = first.shard.count;
    let mut by_index: Vec<Option<usize>> = vec![None; n];
    for (i, (p, d)) in parts.iter().zip(dirs).enumerate() {
        check_same_run(first, first_dir, p, d)?;
        if let Some(j) = by_index[p.shard.index] {
            return Err(Error::invalid(format!(
                "merge: shard {} is given twice: {} and {}",
                p.shard,
                dirs[j].display(),
                d.display()
            )));
        }
        by_index[p.shard.index] = Some(i);
        check_results(p, d)?;
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

/// Refuses a partial `p` (from folder `d`) of another run than the `first` (from
/// `first_dir`): another experiment or version of it, corpus, kslab version or split.
fn check_same_run(first: &Partial, first_dir: &Path, p: &Partial, d: &Path) -> Result<()> {
    let spec_json = |p: &Partial| serde_json::to_string(&p.spec).unwrap_or_default();
    let n = first.shard.count;
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
    Ok(())
}

/// Refuses a partial `p` (from folder `d`) whose results are not those of its shard's part
/// of the corpus, in corpus order.
fn check_results(p: &Partial, d: &Path) -> Result<()> {
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
    Ok(())
}
