//! Tracked sequences: frames × points × dims, stored as one shape per column.

mod layout;

pub use layout::{mediapipe_to_ibug68, named_polylines_for, polylines_for, Group, Layout};

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
    /// Frame numbers of the frames the tracker failed on (left out of `coords`).
    pub failed: Vec<i64>,
    /// What the reader has to say about the file that is no error, for the user to read
    /// (a take whose last row was cut short, read up to the frame before it).
    pub notes: Vec<String>,
}

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

/// A landmark further from the face's centroid than this many times the median landmark's
/// distance is not on the face: on the shipped tracks (MediaPipe's 468, the 68 iBUG points,
/// OpenFace, py-feat) the ratio stays below 3.
pub const MAX_FACE_SPREAD_RATIO: f64 = 20.0;

/// Below this ratio of the smaller to the larger principal variance, a face's points lie on
/// a line (a face's is about 0.3 to 1).
pub const MIN_FACE_ASPECT: f64 = 1e-4;

/// Why a 2-D frame (`dims` values a point; x and y are read) cannot be a face that a neutral
/// or a calibration is made from, if it cannot: its points coincide
/// ([`degenerate_shape`]), lie on a line, or one lies far off the rest (a landmark at 1e15
/// on one frame became the automatic neutral and moved every other frame's weights by up to
/// 1). Every path that makes a neutral or a calibration from a frame asks this.
pub fn face_problem(shape: &[f64], dims: usize) -> Option<String> {
    let dims = dims.max(1);
    let n = shape.len() / dims;
    if degenerate_shape(shape, dims) {
        return Some(if n == 0 {
            "it has no points".to_string()
        } else {
            let (spread, size) = spread_and_size(shape, dims);
            // (Points that coincide up to rounding spread over a few ulps of their size.)
            if spread >= MIN_SPREAD && spread > 1e-14 * size {
                format!("its {n} points lie beyond what 64-bit numbers resolve from the origin")
            } else {
                format!("all its {n} points coincide")
            }
        });
    }
    if dims < 2 || n < 3 {
        return None;
    }
    let (mut cx, mut cy) = (0.0, 0.0);
    for p in shape.chunks(dims) {
        cx += p[0] / n as f64;
        cy += p[1] / n as f64;
    }
    let mut radii: Vec<f64> = shape
        .chunks(dims)
        .map(|p| (p[0] - cx).hypot(p[1] - cy))
        .collect();
    let (far, far_at) =
        radii
            .iter()
            .enumerate()
            .fold((0.0f64, 0), |b, (i, &r)| if r > b.0 { (r, i) } else { b });
    radii.sort_by(f64::total_cmp);
    let median = radii[n / 2];
    // (Written so that a NaN is refused too.)
    if !matches!(
        far.partial_cmp(&(MAX_FACE_SPREAD_RATIO * median)),
        Some(std::cmp::Ordering::Less | std::cmp::Ordering::Equal)
    ) {
        return Some(format!(
            "landmark {far_at} lies {:.3e} from the face's centre, more than {MAX_FACE_SPREAD_RATIO} times the median landmark's {median:.3e}: it is not on the face",
            far
        ));
    }
    // The principal variances of the points (their ratio is scale-free; coordinates within
    // ±1e30 and spread beyond 1e-100 square without overflow or underflow).
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for p in shape.chunks(dims) {
        let (x, y) = (p[0] - cx, p[1] - cy);
        sxx += x * x;
        syy += y * y;
        sxy += x * y;
    }
    let mean = 0.5 * (sxx + syy);
    let half = (0.25 * (sxx - syy).powi(2) + sxy * sxy).sqrt();
    let (big, small) = (mean + half, (mean - half).max(0.0));
    if !matches!(
        small.partial_cmp(&(MIN_FACE_ASPECT * big)),
        Some(std::cmp::Ordering::Greater | std::cmp::Ordering::Equal)
    ) {
        return Some(format!("its {n} points lie on a line"));
    }
    None
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

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// An ellipse of 68 points: a face's spread.
    fn face() -> Vec<f64> {
        (0..68)
            .flat_map(|i| {
                let a = i as f64 * 0.37;
                [100.0 + 40.0 * a.cos(), 100.0 + 50.0 * a.sin()]
            })
            .collect()
    }

    /// The face check at its thresholds' ends: a landmark just inside the spread ratio
    /// passes and just beyond is named; a thin ellipse passes and a line is refused;
    /// coincident points and a face beyond 64-bit resolution are told apart.
    #[test]
    fn the_face_check_holds_at_its_thresholds() {
        let f = face();
        assert_eq!(face_problem(&f, 2), None);
        // The 3-D layout reads x and y.
        let f3: Vec<f64> = f.chunks(2).flat_map(|p| [p[0], p[1], 7.0]).collect();
        assert_eq!(face_problem(&f3, 3), None);
        let median = {
            let (cx, cy) = (100.0, 100.0);
            let mut r: Vec<f64> = f.chunks(2).map(|p| (p[0] - cx).hypot(p[1] - cy)).collect();
            r.sort_by(f64::total_cmp);
            r[34]
        };
        let mut near = f.clone();
        // Far out along x, the centroid moves too: ratio measured, not assumed.
        near[0] = 100.0 + 15.0 * median;
        assert_eq!(face_problem(&near, 2), None, "ratio 15");
        let mut far = f.clone();
        far[0] = 100.0 + 40.0 * median;
        assert!(face_problem(&far, 2)
            .unwrap()
            .starts_with("landmark 0 lies"));
        // A thin face (aspect 1e-3 in variance) passes; flatter than 1e-4 is a line.
        let thin: Vec<f64> = f
            .chunks(2)
            .flat_map(|p| [p[0], 100.0 + (p[1] - 100.0) * 0.04])
            .collect();
        assert_eq!(face_problem(&thin, 2), None);
        let flat: Vec<f64> = f
            .chunks(2)
            .flat_map(|p| [p[0], 100.0 + (p[1] - 100.0) * 0.005])
            .collect();
        assert!(face_problem(&flat, 2).unwrap().contains("on a line"));
        // A line in any direction (the cross term counts), in 2-D and 3-D, of three points.
        for slope in [0.5, 2.0, -3.0] {
            let line: Vec<f64> = (0..68)
                .flat_map(|i| [i as f64, 1.0 + slope * i as f64])
                .collect();
            assert!(
                face_problem(&line, 2).unwrap().contains("on a line"),
                "{slope}"
            );
            // Nearly a line, across the diagonal: a face this thin still passes.
            let thin: Vec<f64> = line
                .chunks(2)
                .enumerate()
                .flat_map(|(i, p)| {
                    // 3 units across a line 68 long (variance ratio about 1e-2).
                    let w = 3.0 * (i as f64 * 0.37).sin() / (1.0 + slope * slope).sqrt();
                    [p[0] - slope * w, p[1] + w]
                })
                .collect();
            assert_eq!(face_problem(&thin, 2), None, "{slope}");
        }
        let line3: Vec<f64> = (0..68)
            .flat_map(|i| [i as f64, 2.0 * i as f64, 5.0])
            .collect();
        assert!(face_problem(&line3, 3).unwrap().contains("on a line"));
        assert!(face_problem(&[0.0, 0.0, 1.0, 2.0, 2.0, 4.0], 2)
            .unwrap()
            .contains("on a line"));
        assert!(face_problem(&[3.0; 136], 2).unwrap().contains("coincide"));
        // Coincident up to rounding (a few ulps apart, far from the origin) is "coincide";
        // a real spread lost next to the offset is the offset's.
        let ulps: Vec<f64> = (0..136).map(|i| 1e6 + f64::from(i % 3) * 1.2e-10).collect();
        assert!(face_problem(&ulps, 2).unwrap().contains("coincide"));
        let offset: Vec<f64> = f.iter().map(|v| v + 1e15).collect();
        assert!(face_problem(&offset, 2).unwrap().contains("64-bit"));
        assert!(face_problem(&[], 2).unwrap().contains("no points"));
        // Fewer than three points: only coincidence is checked.
        assert_eq!(face_problem(&[0.0, 0.0, 1.0, 5.0], 2), None);
    }
}
