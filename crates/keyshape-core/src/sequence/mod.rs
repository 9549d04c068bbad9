//! Tracked sequences: frames × points × dims, stored as one shape per column.

mod face;
mod layout;

pub use face::{face_problem, MAX_FACE_SPREAD_RATIO, MIN_FACE_ASPECT};
pub use layout::{
    mediapipe_to_ibug68, named_polylines_for, polylines_for, Group, Layout, OPENSEEFACE_TO_IBUG70,
    OPENSEEFACE_UNTRACKED,
};

use crate::error::{Error, Result};
use nalgebra::DMatrix;

/// The file formats keyshape-lab reads (docs/src/formats.md gives each one's columns).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// MediaPipe track CSV: `frame,time_s,detected,x_*,y_*,z_*`.
    Mediapipe,
    /// OpenFace 2.x CSV: `frame, timestamp, confidence, success, …, x_0.., y_0.., X_0..`.
    Openface,
    /// py-feat style table: `x_0..x_67,y_0..y_67` amid other columns, `clip` as segment.
    Pyfeat,
    /// iBUG `.pts` file, or a directory of them (one per frame, natural order).
    Pts,
    /// The lab's own JSON sequence (see `keyshape_io::json`).
    Json,
    /// Plain CSV: `frame,x0,y0,x1,y1,…` (optional `time_s`, optional `z*`).
    Csv,
}

impl std::str::FromStr for Format {
    type Err = crate::error::Error;

    /// As [`Format::parse`].
    fn from_str(s: &str) -> crate::error::Result<Format> {
        Format::parse(s)
    }
}

impl Format {
    /// All formats, in the order `--format` lists them.
    pub const ALL: [Format; 6] = [
        Format::Mediapipe,
        Format::Openface,
        Format::Pyfeat,
        Format::Pts,
        Format::Json,
        Format::Csv,
    ];

    /// The name used on the command line and in JSON.
    pub fn name(self) -> &'static str {
        match self {
            Format::Mediapipe => "mediapipe",
            Format::Openface => "openface",
            Format::Pyfeat => "pyfeat",
            Format::Pts => "pts",
            Format::Json => "json",
            Format::Csv => "csv",
        }
    }

    /// Parses a format name as [`Format::name`] writes it.
    pub fn parse(name: &str) -> Result<Format> {
        Format::ALL
            .into_iter()
            .find(|f| f.name().eq_ignore_ascii_case(name.trim()))
            .ok_or_else(|| {
                let names: Vec<_> = Format::ALL.iter().map(|f| f.name()).collect();
                Error::bad_setting(
                    "format",
                    name,
                    format!(
                        "unknown format '{name}' (expected one of: {})",
                        names.join(", ")
                    ),
                )
            })
    }
}

impl std::fmt::Display for Format {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A tracked performance: the valid frames' shapes plus what the file said about the rest.
///
/// `coords` has one column per valid frame; a column is the flat shape
/// `[x1, y1, x2, y2, …]` (or `[x1, y1, z1, …]` when `dims` = 3), so key shapes are columns
/// of the same matrix (paper 000, §4.1).
#[derive(Debug, Clone)]
pub struct Sequence {
    /// Where it came from (a path, or `builtin:…`).
    pub source: String,
    /// The format it was read as.
    pub format: Format,
    /// 2 or 3.
    pub dims: usize,
    /// Number of feature points per frame.
    pub points: usize,
    /// (dims · points) × valid frames.
    pub coords: DMatrix<f64>,
    /// Frame number (as the file names it) of each column of `coords`.
    pub frames: Vec<i64>,
    /// Time in seconds of each valid frame, when the file has it.
    pub times: Option<Vec<f64>>,
    /// Segment id of each valid frame (py-feat `clip`), when the file has one.
    pub segments: Option<Vec<String>>,
    /// The tracker's confidence in each point of each valid frame (points × frames), when
    /// the file has it (a `kslab live` take from OpenSeeFace: columns `c0, c1, …`). A
    /// confidence is finite and ≥ 0; below [`MIN_CONFIDENCE`] the point is not seen.
    pub confidence: Option<DMatrix<f64>>,
    /// Frame numbers of the frames the tracker failed on (left out of `coords`).
    pub failed: Vec<i64>,
    /// What the reader has to say about the file that is no error, for the user to read
    /// (a take whose last row was cut short, read up to the frame before it).
    pub notes: Vec<String>,
}

/// The confidence below which a tracker's point is not seen: left out of the solve (its
/// weight 0) rather than weighed. OpenSeeFace's own receivers draw a point from 0.20 on
/// (`facetracker.py`'s pupil rule, the Unity `OpenSeeShowPoints` default).
pub const MIN_CONFIDENCE: f64 = 0.2;

/// The message for a degenerate frame, the same from every path (see [`degenerate_shape`]):
/// points that coincide, or points whose spread is lost next to their distance from the
/// origin (a face offset by 1e15), which is the file's offset, not the face.
pub fn degenerate_message(frame: i64, shape: &[f64], dims: usize) -> String {
    let points = shape.len() / dims.max(1);
    let (spread, size) = spread_and_size(shape, dims);
    if spread >= MIN_SPREAD {
        format!(
            "frame {frame}: the {points} points spread over {spread:.3e} but lie {size:.3e} from the origin, beyond what 64-bit numbers resolve (a spread of at least 1e-12 of it): subtract the offset from the coordinates"
        )
    } else {
        format!(
            "frame {frame}: all {points} points coincide, so no shape or camera can be fitted to it (drop the frame, or mark it untracked)"
        )
    }
}

/// (The largest distance of a coordinate from its centroid, the largest |centroid|.)
fn spread_and_size(shape: &[f64], dims: usize) -> (f64, f64) {
    let n = shape.len() / dims.max(1);
    if n == 0 {
        return (0.0, 0.0);
    }
    let mut c = [0.0f64; 3];
    for p in shape.chunks(dims) {
        for (ci, v) in c.iter_mut().zip(p) {
            *ci += v / n as f64;
        }
    }
    let (mut spread, mut size) = (0.0f64, 0.0f64);
    for p in shape.chunks(dims) {
        for (ci, v) in c.iter().zip(p) {
            spread = spread.max((v - ci).abs());
            size = size.max(ci.abs());
        }
    }
    (spread, size)
}

/// The most coordinates one frame may hold (dims × points): far above any tracker's
/// 468 × 3, low enough that sizes computed from it cannot overflow.
pub const MAX_SHAPE_VALUES: usize = 1 << 24;

/// The largest coordinate magnitude read. Pixels, millimetres and normalised coordinates
/// are nowhere near it. Results are scale-free up to about 1e60 (a real track scaled by
/// 10^e gives the same condition number and relative errors to 12 digits for e ≤ 60) and
/// break by 1e76 (the PCA's covariance overflows: condition 144 read as 1.001); 1e30 keeps
/// thirty orders of margin (`tests/it/readers.rs`).
pub const MAX_COORD: f64 = 1e30;

/// Why `v` cannot be a coordinate, if it cannot (non-finite, or beyond [`MAX_COORD`]).
pub fn coord_problem(v: f64) -> Option<String> {
    if !v.is_finite() {
        Some("non-finite value".into())
    } else if v.abs() > MAX_COORD {
        Some(format!(
            "coordinate {v:e} is beyond ±{MAX_COORD:e} (results would not stay right); rescale the data"
        ))
    } else {
        None
    }
}

/// Below this spread (the largest distance of a coordinate from its centroid) a shape has
/// no size: squared distances underflow and no similarity or camera can be fitted to it.
/// Real tracks (pixels, millimetres, normalised 0–1) spread over 1e-3 and more.
pub const MIN_SPREAD: f64 = 1e-100;

/// Is this flat shape (`dims` values per point) degenerate: all points at one place, up to
/// rounding (a spread of at most 1e-12 of its distance from the origin) or absolutely (a
/// spread below [`MIN_SPREAD`])? Such a frame is refused by every path that fits a shape or
/// a camera to it (alignment, the rig's camera), through [`Sequence::check_geometry`].
pub fn degenerate_shape(shape: &[f64], dims: usize) -> bool {
    if shape.len() / dims.max(1) == 0 {
        return true;
    }
    let (spread, size) = spread_and_size(shape, dims);
    !(spread >= MIN_SPREAD && spread > 1e-12 * size)
}

impl Sequence {
    /// The geometry check: refuses a sequence with a frame whose points all coincide (see
    /// [`degenerate_shape`]), naming the file and the frame. Every path that fits a shape or
    /// a camera to each frame (`keys`, `solve`, `retarget`, `rig`, `map`, the lab …) runs it,
    /// so a degenerate frame gets the same answer everywhere.
    pub fn check_geometry(&self) -> Result<()> {
        for (c, col) in self.coords.column_iter().enumerate() {
            if degenerate_shape(col.as_slice(), self.dims) {
                return Err(Error::file(
                    &self.source,
                    degenerate_message(self.frames[c], col.as_slice(), self.dims),
                ));
            }
        }
        Ok(())
    }

    /// Are these MediaPipe's normalised image coordinates (its default output): every x
    /// and y within [0, 1]? (A pixel track of a face spans tens of pixels at least.)
    pub fn is_normalised(&self) -> bool {
        self.coords.ncols() > 0
            && self.coords.column_iter().all(|c| {
                c.as_slice()
                    .chunks(self.dims)
                    .all(|p| p[..2].iter().all(|v| (0.0..=1.0).contains(v)))
            })
    }

    /// Turns normalised coordinates into pixels of a `width` × `height` image: x × width,
    /// y × height and z × width (MediaPipe's z is relative depth on x's scale). Errors when
    /// the coordinates are not normalised or a size is not a positive finite number.
    pub fn scale_to_image(&mut self, width: f64, height: f64) -> Result<()> {
        if !(width.is_finite() && width > 0.0 && height.is_finite() && height > 0.0) {
            return Err(Error::bad_setting(
                "image_size",
                format!("{width} × {height}"),
                format!("image size {width} × {height}: give positive sizes in pixels"),
            ));
        }
        if !self.is_normalised() {
            let (lo, hi) = self.ranges()[0];
            return Err(Error::file(
                &self.source,
                format!(
                    "an image size applies to normalised coordinates (every x and y in [0, 1]); here x runs {lo} .. {hi}"
                ),
            ));
        }
        let scale = [width, height, width];
        for mut c in self.coords.column_iter_mut() {
            for p in c.as_mut_slice().chunks_mut(self.dims) {
                for (v, s) in p.iter_mut().zip(scale) {
                    *v *= s;
                }
            }
        }
        Ok(())
    }

    /// Checks the invariants every reader promises: at least one valid frame, finite values,
    /// one frame number per column, side tables of matching length.
    pub fn validate(&self) -> Result<()> {
        let src = &self.source;
        if self.dims != 2 && self.dims != 3 {
            return Err(Error::invalid(format!(
                "{src}: dims must be 2 or 3, got {}",
                self.dims
            )));
        }
        if self.coords.nrows() != self.dims * self.points {
            return Err(Error::invalid(format!(
                "{src}: shape rows {} != dims {} × points {}",
                self.coords.nrows(),
                self.dims,
                self.points
            )));
        }
        if self.points == 0 {
            return Err(Error::file(src, "no feature points"));
        }
        if self.coords.ncols() == 0 {
            let why = if self.failed.is_empty() {
                "no frames".to_string()
            } else {
                format!(
                    "every frame failed ({} frames, none tracked)",
                    self.failed.len()
                )
            };
            return Err(Error::file(src, why));
        }
        if self.frames.len() != self.coords.ncols() {
            return Err(Error::invalid(format!(
                "{src}: frame numbers do not match frames"
            )));
        }
        let mut seen = std::collections::HashSet::new();
        if let Some(f) = self
            .frames
            .iter()
            .chain(&self.failed)
            .find(|&&f| !seen.insert(f))
        {
            return Err(Error::file(
                src,
                format!("frame {f} appears twice: frame numbers must be unique"),
            ));
        }
        let n = self.coords.ncols();
        if self.times.as_ref().is_some_and(|t| t.len() != n)
            || self.segments.as_ref().is_some_and(|s| s.len() != n)
        {
            return Err(Error::invalid(format!(
                "{src}: side tables do not match frames"
            )));
        }
        if let Some(c) = &self.confidence {
            if c.nrows() != self.points || c.ncols() != n {
                return Err(Error::invalid(format!(
                    "{src}: the confidences are {} × {}, not points × frames {} × {n}",
                    c.nrows(),
                    c.ncols(),
                    self.points
                )));
            }
            if let Some((i, v)) = c
                .iter()
                .enumerate()
                .find(|(_, v)| !(v.is_finite() && **v >= 0.0))
            {
                return Err(Error::file(
                    src,
                    format!(
                        "confidence {v} at frame {} point {}: a confidence is finite and ≥ 0",
                        self.frames[i / self.points],
                        i % self.points
                    ),
                ));
            }
        }
        if let Some((i, v)) = self
            .coords
            .iter()
            .enumerate()
            .find(|(_, v)| coord_problem(**v).is_some())
        {
            let (row, col) = (i % self.coords.nrows(), i / self.coords.nrows());
            return Err(Error::file(
                src,
                format!(
                    "{} at frame {} point {} axis {}",
                    coord_problem(*v).unwrap_or_default(),
                    self.frames[col],
                    row / self.dims,
                    row % self.dims
                ),
            ));
        }
        Ok(())
    }

    /// The same sequence with other coordinates of the same shape (frame for frame), without
    /// copying the old ones.
    pub fn with_coords(&self, coords: DMatrix<f64>) -> Sequence {
        Sequence {
            source: self.source.clone(),
            format: self.format,
            dims: self.dims,
            points: self.points,
            coords,
            frames: self.frames.clone(),
            times: self.times.clone(),
            segments: self.segments.clone(),
            confidence: self.confidence.clone(),
            failed: self.failed.clone(),
            notes: self.notes.clone(),
        }
    }

    /// Number of valid frames.
    pub fn n_frames(&self) -> usize {
        self.coords.ncols()
    }

    /// Column index of the frame the file numbers `frame`; an error names why not.
    pub fn column_of_frame(&self, frame: i64) -> Result<usize> {
        if let Some(c) = self.frames.iter().position(|&f| f == frame) {
            return Ok(c);
        }
        if self.failed.contains(&frame) {
            return Err(Error::invalid(format!(
                "frame {frame} is a failed frame (the tracker found no face there); pick a tracked frame"
            )));
        }
        let (lo, hi) = (self.frames.iter().min(), self.frames.iter().max());
        Err(Error::invalid(match (lo, hi) {
            (Some(lo), Some(hi)) if (*lo..=*hi).contains(&frame) => {
                // Inside the range: a number the file skips.
                let before = self.frames.iter().filter(|&&f| f < frame).max();
                let after = self.frames.iter().filter(|&&f| f > frame).min();
                format!(
                    "frame {frame} is not in the file: its frame numbers skip from {} to {} (frames run {lo}..={hi} with gaps)",
                    before.map_or("the start".into(), i64::to_string),
                    after.map_or("the end".into(), i64::to_string)
                )
            }
            (Some(lo), Some(hi)) => {
                format!("frame {frame} is out of range: frames run {lo}..={hi}")
            }
            _ => format!("frame {frame} is out of range: the sequence is empty"),
        }))
    }

    /// The same sequence restricted to the given point indices (in that order).
    pub fn select_points(&self, indices: &[usize]) -> Result<Sequence> {
        if indices.is_empty() {
            return Err(Error::invalid("point selection is empty"));
        }
        if let Some(&bad) = indices.iter().find(|&&i| i >= self.points) {
            return Err(Error::invalid(format!(
                "point {bad} is out of range: the sequence has {} points",
                self.points
            )));
        }
        let rows: Vec<usize> = indices
            .iter()
            .flat_map(|&p| (0..self.dims).map(move |d| p * self.dims + d))
            .collect();
        // Field by field: `..self.clone()` would copy every coordinate only to drop them.
        Ok(Sequence {
            source: self.source.clone(),
            format: self.format,
            dims: self.dims,
            points: indices.len(),
            coords: self.coords.select_rows(&rows),
            frames: self.frames.clone(),
            times: self.times.clone(),
            segments: self.segments.clone(),
            confidence: self.confidence.as_ref().map(|c| c.select_rows(indices)),
            failed: self.failed.clone(),
            notes: self.notes.clone(),
        })
    }

    /// Per-axis (min, max) over all valid frames.
    pub fn ranges(&self) -> Vec<(f64, f64)> {
        (0..self.dims)
            .map(|d| {
                let mut lo = f64::INFINITY;
                let mut hi = f64::NEG_INFINITY;
                for col in self.coords.column_iter() {
                    for v in col.iter().skip(d).step_by(self.dims) {
                        lo = lo.min(*v);
                        hi = hi.max(*v);
                    }
                }
                (lo, hi)
            })
            .collect()
    }

    /// Frames per second from the time column: frame-number span over time span (robust
    /// to rounded time stamps), if the file has times.
    pub fn fps(&self) -> Option<f64> {
        let t = self.times.as_ref()?;
        let (t0, t1) = (*t.first()?, *t.last()?);
        let (f0, f1) = (*self.frames.first()?, *self.frames.last()?);
        (t1 > t0 && f1 > f0).then(|| (f1 - f0) as f64 / (t1 - t0))
    }
}
