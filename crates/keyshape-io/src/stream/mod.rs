//! A streamed solve: the weights of a landmark table of any length, written
//! while it is read, in memory independent of its length.
//!
//! The whole-sequence steps are done in passes over the file instead of in memory: one pass
//! finds the key frames' columns and the segment step; with alignment, the generalised
//! Procrustes mean takes one pass for the shapes' sizes and one per round
//! ([`keyshape_core::align::procrustes_mean`]); one pass collects the aligned key shapes (and the
//! neutral); the last pass aligns, solves and hands each frame's weights to the caller. The
//! frames are solved in chunks of [`keyshape_core::solve::CHUNK`] counted from the first frame,
//! exactly as the in-memory solve chunks them, and every step is the in-memory code, so the
//! weights are bit for bit the ones `kslab solve` writes without `--stream` (tested).
//!
//! Memory: one chunk of frames, the key shapes, and the Procrustes mean. Reads CSV landmark
//! tables (MediaPipe, OpenFace, py-feat, plain CSV), gzipped or not. The offline temporal
//! prior needs the whole sequence and is refused; the causal one streams.

use crate::detect_format;
use crate::table::TableRows;
use keyshape_core::align::{align_to, centre, procrustes_mean};
use keyshape_core::error::{setting, Error, Result};
use keyshape_core::sequence::{Format, Layout};
use keyshape_core::solve::temporal::{CausalShared, SmoothMode, Smoothing};
use keyshape_core::solve::{lstsq, SolveOptions, CHUNK};
use nalgebra::DMatrix;
use std::io::{BufReader, Read};
use std::path::Path;

mod chunks;

use chunks::Chunks;

/// What to solve.
#[derive(Debug, Clone)]
pub struct StreamOptions {
    /// The table's format (None: detected from the name and header, as the readers do).
    pub format: Option<Format>,
    /// 2 or 3 values per point.
    pub dims: usize,
    /// A point-group selection (`lips`, `eyes,brows`), applied after alignment.
    pub points: Option<String>,
    /// Remove 2-D head motion (generalised Procrustes over the whole track).
    pub align: bool,
    /// Key frames, by frame number.
    pub keys: Vec<i64>,
    /// Solve deltas from this frame.
    pub neutral: Option<i64>,
    /// The solver and its options.
    pub solve: SolveOptions,
    /// A causal temporal prior (the offline one is refused).
    pub smoothing: Option<Smoothing>,
}

/// What a streamed solve did.
#[derive(Debug, Clone, serde::Serialize)]
pub struct StreamSummary {
    /// Tracked frames solved.
    pub frames: usize,
    /// Frames the tracker marked as failed (skipped).
    pub failed: usize,
    /// Points per shape solved.
    pub points: usize,
    /// Passes over the file.
    pub passes: usize,
    /// Procrustes rounds (0 without alignment).
    pub align_rounds: usize,
    /// Numerical rank of the key-shape matrix.
    pub rank: usize,
    /// Its condition number.
    pub condition: f64,
    /// Frames the active-set solver stopped early on.
    pub unconverged: usize,
    /// Total squared error (paper 000 Eq. 5).
    pub total_sq_error: f64,
    /// Mean of the per-frame RMS (as [`keyshape_core::decompose::Decomposition::mean_rms`]).
    pub mean_rms: f64,
    /// Largest |w|.
    pub max_abs_weight: f64,
}

/// One frame's result, handed to the caller in frame order.
pub struct FrameWeights<'a> {
    /// The frame number.
    pub frame: i64,
    /// Its RMS error per point.
    pub rms: f64,
    /// Its weights, one per key.
    pub weights: &'a [f64],
}

/// Opens `path` for one pass: a regular file, un-gzipped when it ends in `.gz`.
fn open(path: &Path) -> Result<Box<dyn Read>> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(Error::file(
            path,
            format!(
                "is not a regular file; {} reads a file (several times)",
                setting("stream")
            ),
        ));
    }
    crate::open_input(path)
}

/// The format: as given, or detected from the name and the first line.
fn format_of(path: &Path, given: Option<Format>) -> Result<Format> {
    let format = match given {
        Some(f) => f,
        None => {
            let mut bytes = Vec::new();
            let read = crate::read_line_capped(
                &mut BufReader::new(open(path)?),
                &mut bytes,
                crate::MAX_LINE_BYTES,
            )
            .map_err(|e| Error::file(path, format!("cannot read the first line: {e}")))?;
            if read == crate::Line::TooLong {
                return Err(Error::parse(
                    path,
                    1,
                    0,
                    format!(
                        "line is longer than {} bytes: not a text table",
                        crate::MAX_LINE_BYTES
                    ),
                ));
            }
            let first = String::from_utf8(bytes)
                .map_err(|_| Error::parse(path, 1, 0, "the first line is not UTF-8 text"))?;
            if first.trim().is_empty() {
                return Err(Error::file(path, "file is empty"));
            }
            detect_format(path, &first)?
        }
    };
    if matches!(format, Format::Json | Format::Pts) {
        return Err(Error::file(
            path,
            format!("{stream} reads CSV landmark tables (MediaPipe, OpenFace, py-feat, plain CSV); a {format} file is read whole: drop {stream}", stream = setting("stream")),
        ));
    }
    Ok(format)
}

/// Every tracked row of one pass, in order: `f(column, frame, segment label, coords)`.
/// The file must still hold the `n` tracked frames, with the same width, that the first
/// pass found: a file changed between passes is an error, not a mix of two tracks.
fn pass<F>(
    path: &Path,
    format: Format,
    dims: usize,
    n: usize,
    values: usize,
    mut f: F,
) -> Result<()>
where
    F: FnMut(usize, i64, Option<&str>, &[f64]) -> Result<()>,
{
    let changed = || {
        Error::file(
            path,
            format!("changed while it was read: {} reads the file several times; let the tracker finish writing it first", setting("stream")),
        )
    };
    let mut rows = TableRows::new(path, open(path)?, format, dims)?;
    if rows.values() != values {
        return Err(changed());
    }
    let mut col = 0;
    while let Some(r) = rows.next_row()? {
        if r.tracked {
            if col == n {
                return Err(changed());
            }
            f(col, r.frame, r.segment, r.coords)?;
            col += 1;
        }
    }
    if col != n {
        return Err(changed());
    }
    Ok(())
}

/// Solves every frame of the table at `path`, calling `sink` with each frame's weights in
/// order as soon as its chunk is solved. See the module's description.
pub fn stream_solve(
    path: &Path,
    opts: &StreamOptions,
    sink: &mut dyn FnMut(FrameWeights<'_>) -> Result<()>,
) -> Result<StreamSummary> {
    check_options(opts)?;
    let format = format_of(path, opts.format)?;
    let dims = opts.dims;
    let src = path.display().to_string();
    let table = Table { path, format, dims };
    // Pass 1: columns of the key frames and the neutral, the segment step, the checks the
    // in-memory path makes when it reads and prepares.
    let mut passes = 1;
    let found = first_pass(&table, opts)?;
    let (n, values) = (found.n, found.values);
    let (cols, neutral) = key_columns(&found, opts)?;
    let selected = selected_points(values / dims, opts)?;
    let select = |v: &[f64]| -> Vec<f64> {
        selected
            .iter()
            .flat_map(|&p| v[p * dims..(p + 1) * dims].iter().copied())
            .collect()
    };

    // The Procrustes mean: one pass for the sizes, one per round.
    let (mean, rounds) = if opts.align {
        let (mean, rounds) = procrustes_passes(&table, (n, values), &mut passes)?;
        (Some(mean), rounds)
    } else {
        (None, 0)
    };
    // A frame as the solve sees it: aligned (when asked), points selected.
    let prepare = |c: usize, v: &[f64], buf: &mut Vec<f64>| -> Result<Vec<f64>> {
        buf.clear();
        buf.extend_from_slice(v);
        if let Some(m) = &mean {
            let cen = centre(buf, dims);
            align_to(buf, m, dims, cen, c).map_err(|e| Error::file(&src, e.to_string()))?;
        }
        Ok(select(buf))
    };

    // The key shapes (and the neutral).
    passes += 1;
    let rows = selected.len() * dims;
    let mut buf = Vec::with_capacity(values);
    let (s, base) = key_shapes(&table, (n, values), rows, (&cols, neutral), |c, v| {
        prepare(c, v, &mut buf)
    })?;
    let pinv = lstsq::pseudo_inverse(&s, opts.solve.rcond)?;
    let causal = match &opts.smoothing {
        Some(sm) if sm.lambda > 0.0 => {
            Some(CausalShared::new(&s.tr_mul(&s), opts.solve.solver, sm)?)
        }
        _ => None,
    };

    // The solve, chunk by chunk.
    passes += 1;
    let mut chunks = Chunks::new(&s, opts, causal.as_ref(), found.step, selected.len());
    let mut chunk = DMatrix::zeros(rows, CHUNK);
    let mut frames: Vec<i64> = Vec::with_capacity(CHUNK);
    let mut labels: Vec<Option<String>> = Vec::with_capacity(CHUNK);
    pass(path, format, dims, n, values, |c, frame, label, v| {
        let mut shape = prepare(c, v, &mut buf)?;
        if let Some(b) = &base {
            for (x, y) in shape.iter_mut().zip(b) {
                *x -= y;
            }
        }
        chunk.column_mut(frames.len()).copy_from_slice(&shape);
        frames.push(frame);
        labels.push(label.map(str::to_string));
        if frames.len() == CHUNK {
            chunks.flush(&chunk, &frames, &labels, sink)?;
            frames.clear();
            labels.clear();
        }
        Ok(())
    })?;
    if !frames.is_empty() {
        chunks.flush(&chunk, &frames, &labels, sink)?;
    }
    Ok(StreamSummary {
        frames: n,
        failed: found.failed,
        points: selected.len(),
        passes,
        align_rounds: rounds,
        rank: pinv.rank,
        condition: pinv.condition,
        unconverged: chunks.unconverged,
        total_sq_error: chunks.total,
        mean_rms: chunks.rms_sum / n as f64,
        max_abs_weight: chunks.wmax,
    })
}

/// The generalised Procrustes mean of the table's centred shapes: one pass for the sizes,
/// one per round (each counted in `passes`); the mean and the rounds it took.
fn procrustes_passes(
    t: &Table,
    (n, values): (usize, usize),
    passes: &mut usize,
) -> Result<(Vec<f64>, usize)> {
    let mut buf = vec![0.0; values];
    procrustes_mean(n, t.dims, |f| {
        *passes += 1;
        pass(t.path, t.format, t.dims, n, values, |c, _, _, v| {
            buf.copy_from_slice(v);
            centre(&mut buf, t.dims);
            f(c, &buf)
        })
    })
    .map_err(|e| Error::file(t.path, e.to_string()))
}

/// The table being streamed: where, in which format, with how many coordinates a point.
struct Table<'a> {
    path: &'a Path,
    format: Format,
    dims: usize,
}

/// What the first pass found.
struct FirstPass {
    /// Tracked frames.
    n: usize,
    /// Failed frames (the tracker found no face).
    failed: usize,
    /// Each key frame's column, when the file has it tracked.
    key_cols: Vec<Option<usize>>,
    neutral_col: Option<usize>,
    /// The smallest step between consecutive frame numbers.
    step: Option<i64>,
    /// The first and last frame numbers.
    lo: i64,
    hi: i64,
    /// Key or neutral frames the tracker failed on.
    failed_keys: Vec<i64>,
    /// Values per row.
    values: usize,
}

/// The offline prior cannot stream; key shapes are needed.
fn check_options(opts: &StreamOptions) -> Result<()> {
    if let Some(sm) = &opts.smoothing {
        sm.check()?;
        if sm.mode == SmoothMode::Offline && sm.lambda > 0.0 {
            return Err(Error::bad_setting("smooth_mode", "offline", format!(
                "the offline temporal prior solves the whole sequence at once and cannot stream: use {} causal, or drop {}",
                setting("smooth_mode"),
                setting("stream")
            )));
        }
    }
    if opts.keys.is_empty() {
        return Err(Error::invalid("no key shapes given"));
    }
    Ok(())
}

/// Pass 1: the key frames' and the neutral's columns, the segment step, the frame range;
/// a degenerate frame (with alignment) or a file without a tracked frame is an error.
fn first_pass(t: &Table, opts: &StreamOptions) -> Result<FirstPass> {
    let (path, format, dims) = (t.path, t.format, t.dims);
    let src = path.display().to_string();
    let (mut n, mut failed) = (0usize, 0usize);
    let mut key_cols: Vec<Option<usize>> = vec![None; opts.keys.len()];
    let mut neutral_col = None;
    let mut step: Option<i64> = None;
    let (mut lo, mut hi) = (i64::MAX, i64::MIN);
    let mut failed_keys = Vec::new();
    let values;
    {
        let mut rows = TableRows::new(path, open(path)?, format, dims)?;
        values = rows.values();
        let mut last: Option<i64> = None;
        while let Some(r) = rows.next_row()? {
            let wanted = opts.keys.contains(&r.frame) || opts.neutral == Some(r.frame);
            if !r.tracked {
                failed += 1;
                if wanted {
                    failed_keys.push(r.frame);
                }
                continue;
            }
            if opts.align && keyshape_core::sequence::degenerate_shape(r.coords, dims) {
                return Err(Error::file(
                    &src,
                    keyshape_core::sequence::degenerate_message(r.frame, r.coords, dims),
                ));
            }
            for (slot, k) in key_cols.iter_mut().zip(&opts.keys) {
                if *k == r.frame {
                    *slot = Some(n);
                }
            }
            if opts.neutral == Some(r.frame) {
                neutral_col = Some(n);
            }
            if let Some(p) = last {
                let d = r.frame - p;
                if d > 0 {
                    step = Some(step.map_or(d, |s| s.min(d)));
                }
            }
            last = Some(r.frame);
            lo = lo.min(r.frame);
            hi = hi.max(r.frame);
            n += 1;
        }
    }
    if n == 0 {
        return Err(Error::file(
            &src,
            if failed == 0 {
                "no frames".to_string()
            } else {
                format!("every frame failed ({failed} frames, none tracked)")
            },
        ));
    }
    Ok(FirstPass {
        n,
        failed,
        key_cols,
        neutral_col,
        step,
        lo,
        hi,
        failed_keys,
        values,
    })
}

/// The key frames' columns and the neutral's, each named when the file does not have it
/// tracked (failed, in a gap, or out of range), listed twice, or both neutral and key.
fn key_columns(found: &FirstPass, opts: &StreamOptions) -> Result<(Vec<usize>, Option<usize>)> {
    let (n, lo, hi) = (found.n, found.lo, found.hi);
    let failed_keys = &found.failed_keys;
    let missing = |f: i64, what: &str| -> Error {
        if failed_keys.contains(&f) {
            Error::invalid(format!(
                "{what} {f}: frame {f} is a failed frame (the tracker found no face there); pick a tracked frame"
            ))
        } else if (lo..=hi).contains(&f) {
            Error::invalid(format!(
                "{what} {f}: frame {f} is not in the file (frames run {lo}..={hi} with gaps)"
            ))
        } else {
            Error::invalid(format!(
                "{what} {f}: frame {f} is out of range: frames run {lo}..={hi}"
            ))
        }
    };
    let mut seen = std::collections::HashSet::new();
    let mut cols = Vec::with_capacity(opts.keys.len());
    for (c, &k) in found.key_cols.iter().zip(&opts.keys) {
        if !seen.insert(k) {
            return Err(Error::bad_setting(
                "keys",
                k,
                format!("{}: frame {k} is listed twice", setting("keys")),
            ));
        }
        cols.push(c.ok_or_else(|| missing(k, &setting("keys")))?);
    }
    let neutral = match opts.neutral {
        Some(f) => Some(
            found
                .neutral_col
                .ok_or_else(|| missing(f, &setting("neutral")))?,
        ),
        None => None,
    };
    if cols.len() > n {
        return Err(Error::invalid(format!(
            "{} key shapes asked for, but the sequence has only {n} valid frames",
            cols.len()
        )));
    }
    if let Some(nc) = neutral {
        if cols.contains(&nc) {
            return Err(Error::invalid(
                "the neutral frame cannot also be a key shape (its delta is zero)",
            ));
        }
    }
    Ok((cols, neutral))
}

/// The points solved for: all, or the layout's groups `opts.points` names.
fn selected_points(points: usize, opts: &StreamOptions) -> Result<Vec<usize>> {
    let layout = Layout::for_points(points);
    Ok(match (&opts.points, &layout) {
        (None, _) => (0..points).collect(),
        (Some(spec), Some(l)) => l.select(spec)?,
        (Some(spec), None) => {
            return Err(Error::bad_setting(
                "points",
                spec,
                format!(
                "{} {spec}: no built-in layout has {points} points (MediaPipe has 468, iBUG 68)",
                setting("points")
            ),
            ))
        }
    })
}

/// The key-shape pass: each key frame as the solve sees it (`prepare`), less the neutral
/// when there is one; and the neutral.
#[allow(clippy::type_complexity)]
fn key_shapes(
    t: &Table,
    (n, values): (usize, usize),
    rows: usize,
    (cols, neutral): (&[usize], Option<usize>),
    mut prepare: impl FnMut(usize, &[f64]) -> Result<Vec<f64>>,
) -> Result<(DMatrix<f64>, Option<Vec<f64>>)> {
    let mut s = DMatrix::zeros(rows, cols.len());
    let mut base: Option<Vec<f64>> = None;
    pass(t.path, t.format, t.dims, n, values, |c, _, _, v| {
        let is_key = cols.contains(&c);
        if is_key || neutral == Some(c) {
            let shape = prepare(c, v)?;
            for (j, _) in cols.iter().enumerate().filter(|(_, &k)| k == c) {
                s.column_mut(j).copy_from_slice(&shape);
            }
            if neutral == Some(c) {
                base = Some(shape);
            }
        }
        Ok(())
    })?;
    if let Some(b) = &base {
        for mut col in s.column_iter_mut() {
            for (x, y) in col.iter_mut().zip(b) {
                *x -= y;
            }
        }
    }
    if s.iter().any(|v| !v.is_finite()) {
        return Err(Error::invalid("key shapes contain NaN or infinity"));
    }
    Ok((s, base))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pass that finds another number of tracked frames, or another width, than the first
    /// pass is refused: the file changed between passes.
    #[test]
    fn a_file_changed_between_passes_is_refused() {
        let d = std::env::temp_dir().join(format!("kslab-stream-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let p = d.join("t.csv");
        std::fs::write(&p, "frame,x0,y0,x1,y1\n0,0,0,1,0\n1,0,0,1,1\n2,0,0,2,1\n").unwrap();
        let ok = pass(&p, Format::Csv, 2, 3, 4, |_, _, _, _| Ok(()));
        assert!(ok.is_ok());
        for (n, values) in [(2, 4), (4, 4), (3, 6)] {
            let e = pass(&p, Format::Csv, 2, n, values, |_, _, _, _| Ok(())).unwrap_err();
            assert!(e.to_string().contains("changed while it was read"), "{e}");
        }
        let _ = std::fs::remove_dir_all(&d);
    }
}
