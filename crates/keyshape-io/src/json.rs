//! The lab's own JSON sequence format.
//!
//! ```json
//! { "kslab_sequence": 1, "dims": 2, "points": 3,
//!   "frames": [ { "frame": 0, "time": 0.0, "coords": [x0, y0, x1, y1, x2, y2] },
//!               { "frame": 1, "valid": false } ] }
//! ```
//! `coords` is the flat shape (dims × points values); `time` is optional; a frame with
//! `"valid": false` is a failed frame and needs no coords.

use keyshape_core::error::{setting, Error, Result};
use keyshape_core::sequence::{Format, Sequence};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The file as serde sees it.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SequenceFile {
    /// Format version, 1.
    pub kslab_sequence: u32,
    /// 2 or 3.
    pub dims: usize,
    /// Points per frame.
    pub points: usize,
    /// The frames in order.
    pub frames: Vec<FrameRecord>,
}

/// One frame of a [`SequenceFile`].
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameRecord {
    /// Frame number.
    pub frame: i64,
    /// Time in seconds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time: Option<f64>,
    /// False for a failed frame.
    #[serde(default = "valid_unless_said")]
    pub valid: bool,
    /// Segment id (e.g. a clip).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub segment: Option<String>,
    /// The flat shape.
    #[serde(default)]
    pub coords: Vec<f64>,
}

/// A frame without `valid` is a tracked frame.
fn valid_unless_said() -> bool {
    true
}

/// Converts a sequence to the JSON file form.
pub fn to_file(seq: &Sequence) -> SequenceFile {
    let mut frames: Vec<FrameRecord> = (0..seq.n_frames())
        .map(|c| FrameRecord {
            frame: seq.frames[c],
            time: seq.times.as_ref().map(|t| t[c]),
            valid: true,
            segment: seq.segments.as_ref().map(|s| s[c].clone()),
            coords: seq.coords.column(c).iter().copied().collect(),
        })
        .collect();
    frames.extend(seq.failed.iter().map(|&f| FrameRecord {
        frame: f,
        time: None,
        valid: false,
        segment: None,
        coords: Vec::new(),
    }));
    frames.sort_by_key(|f| f.frame);
    SequenceFile {
        kslab_sequence: 1,
        dims: seq.dims,
        points: seq.points,
        frames,
    }
}

pub(super) fn read(path: &Path, text: &str, dims: usize) -> Result<Sequence> {
    let file: SequenceFile = serde_json::from_str(text)
        .map_err(|e| Error::parse(path, e.line() as u64, e.column() as u64, e.to_string()))?;
    let want = check_header(path, &file, dims)?;
    let (mut data, mut frames, mut failed) = (Vec::new(), Vec::new(), Vec::new());
    let (mut times, mut segments) = (Vec::new(), Vec::new());
    for (i, f) in file.frames.iter().enumerate() {
        if !f.valid {
            failed.push(f.frame);
            continue;
        }
        check_coords(path, &file, i, want)?;
        for p in f.coords.chunks(file.dims) {
            data.extend_from_slice(&p[..dims]);
        }
        frames.push(f.frame);
        times.push(f.time);
        segments.push(f.segment.clone());
    }
    let n = frames.len();
    let all_some = |v: &[Option<f64>]| !v.is_empty() && v.iter().all(Option::is_some);
    Ok(Sequence {
        source: path.display().to_string(),
        format: Format::Json,
        dims,
        points: file.points,
        coords: DMatrix::from_vec(dims * file.points, n, data),
        frames,
        times: all_some(&times).then(|| times.iter().flatten().copied().collect()),
        segments: (!segments.is_empty() && segments.iter().all(Option::is_some))
            .then(|| segments.into_iter().flatten().collect()),
        confidence: None,
        failed,
        notes: Vec::new(),
    })
}

/// The file's version, dims (2 or 3, at least the `dims` asked), size and unique frame
/// numbers; returns the number of values a frame holds.
fn check_header(path: &Path, file: &SequenceFile, dims: usize) -> Result<usize> {
    if file.kslab_sequence != 1 {
        return Err(Error::file(
            path,
            format!("unsupported kslab_sequence version {}", file.kslab_sequence),
        ));
    }
    if file.dims != 2 && file.dims != 3 {
        return Err(Error::file(
            path,
            format!("dims must be 2 or 3, got {}", file.dims),
        ));
    }
    if dims > file.dims {
        return Err(Error::file(
            path,
            format!(
                "{} {dims} asked, but the file has {}-D points",
                setting("dims"),
                file.dims
            ),
        ));
    }
    let want = file
        .dims
        .checked_mul(file.points)
        .filter(|&w| w <= keyshape_core::sequence::MAX_SHAPE_VALUES)
        .ok_or_else(|| {
            Error::file(
                path,
                format!(
                    "points {} is too large (at most {} values per frame)",
                    file.points,
                    keyshape_core::sequence::MAX_SHAPE_VALUES
                ),
            )
        })?;
    let mut seen = std::collections::HashMap::new();
    for (i, f) in file.frames.iter().enumerate() {
        if let Some(first) = seen.insert(f.frame, i) {
            return Err(Error::file(
                path,
                format!(
                    "frames[{i}] repeats frame number {} (first at frames[{first}]): frame numbers must be unique",
                    f.frame
                ),
            ));
        }
    }
    Ok(want)
}

/// Frame `i`'s coordinates: `want` of them, each one every reader accepts.
fn check_coords(path: &Path, file: &SequenceFile, i: usize, want: usize) -> Result<()> {
    let f = &file.frames[i];
    if f.coords.len() != want {
        return Err(Error::file(
            path,
            format!(
                "frames[{i}] (frame {}) has {} coords; dims {} × points {} = {want}",
                f.frame,
                f.coords.len(),
                file.dims,
                file.points
            ),
        ));
    }
    if let Some((j, why)) = f
        .coords
        .iter()
        .enumerate()
        .find_map(|(j, v)| keyshape_core::sequence::coord_problem(*v).map(|w| (j, w)))
    {
        return Err(Error::file(
            path,
            format!("frames[{i}] (frame {}) coords[{j}]: {why}", f.frame),
        ));
    }
    Ok(())
}
