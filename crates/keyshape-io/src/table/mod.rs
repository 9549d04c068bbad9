//! CSV landmark tables: MediaPipe tracks, OpenFace 2.x, py-feat tables and the plain CSV.
//! One reader, configured per format by which columns hold what.

use crate::line_index::LineIndex;
use keyshape_core::error::{Error, Result};
use keyshape_core::sequence::{Format, Sequence};
use nalgebra::DMatrix;
use std::collections::HashMap;
use std::path::Path;

mod columns;
use columns::{columns, confidence_columns, coordinate_columns};

/// One data row of a landmark table.
pub struct Row<'a> {
    /// The frame number (the row number for formats without one).
    pub frame: i64,
    /// The row's line in the file (for messages).
    pub line: u64,
    /// False for a frame the tracker marked as failed (its coordinates are not read).
    pub tracked: bool,
    /// The coordinates in shape order (empty for a failed frame).
    pub coords: &'a [f64],
    /// The time stamp, for formats with one.
    pub time: Option<f64>,
    /// The clip label, for formats with one.
    pub segment: Option<&'a str>,
    /// Per point, the tracker's confidence (empty for a file without confidences or a
    /// failed frame).
    pub confidence: &'a [f64],
}

/// Frame numbers seen so far, kept as runs of consecutive frames on consecutive lines: a
/// track's frames take one run (plus one per gap), not one entry each, so a streamed read
/// stays in memory independent of its length and still names a duplicate's first line.
#[derive(Default)]
struct SeenFrames {
    /// Run start → (length, line of its first frame).
    runs: std::collections::BTreeMap<i64, (i64, u64)>,
    /// The run the last frame went into.
    last: Option<i64>,
}

impl SeenFrames {
    /// Records `frame` on `line`; the line it was first seen on when it is a duplicate.
    fn insert(&mut self, frame: i64, line: u64) -> Option<u64> {
        if let Some((&s, &(len, l0))) = self.runs.range(..=frame).next_back() {
            if frame - s < len {
                return Some(l0 + (frame - s) as u64);
            }
        }
        if let Some(run) = self
            .last
            .and_then(|s| self.runs.get_mut(&s).map(|r| (s, r)))
        {
            let (s, (len, l0)) = run;
            if frame == s + *len && line == *l0 + *len as u64 {
                *len += 1;
                return None;
            }
        }
        self.runs.insert(frame, (1, line));
        self.last = Some(frame);
        None
    }
}

/// Is the short row just read the file's last, with no line end — a row cut short by a full
/// disk or a kill while it was written (then [`TableRows`] notes it and leaves it out)? A
/// short row that is not the last stays an error.
fn cut_short<R: std::io::Read>(rdr: &mut csv::Reader<LineIndex<R>>) -> bool {
    if rdr.get_ref().run == 0 {
        return false;
    }
    let mut rest = csv::StringRecord::new();
    matches!(rdr.read_record(&mut rest), Ok(false))
}

/// A landmark table read row by row, from any reader: what [`crate::read_sequence`]
/// collects into a [`Sequence`], and what a streamed solve reads in constant memory.
pub struct TableRows<R: std::io::Read> {
    path: std::path::PathBuf,
    rdr: csv::Reader<LineIndex<R>>,
    header: Vec<String>,
    coord_cols: Vec<usize>,
    valid_col: Option<usize>,
    frame_col: Option<usize>,
    time_col: Option<usize>,
    seg_col: Option<usize>,
    conf_cols: Option<Vec<usize>>,
    record: csv::StringRecord,
    coords: Vec<f64>,
    conf: Vec<f64>,
    row: i64,
    seen: SeenFrames,
    dims: usize,
    /// The line of a last row cut short (see [`TableRows::cut_row`]).
    cut: Option<u64>,
}

impl<R: std::io::Read> TableRows<R> {
    /// Reads the header of a table of `format` from `reader` (`path` names it in errors).
    pub fn new(path: &Path, reader: R, format: Format, dims: usize) -> Result<Self> {
        let cols = columns(format, dims);
        let mut rdr = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .flexible(true)
            .has_headers(true)
            .from_reader(LineIndex::new(reader));
        let header: Vec<String> = rdr
            .headers()
            .map_err(|e| csv_error(path, &e, None))?
            .iter()
            .map(str::to_string)
            .collect();
        let mut index: HashMap<&str, usize> = HashMap::with_capacity(header.len());
        for (i, h) in header.iter().enumerate() {
            if let Some(first) = index.insert(h.as_str(), i) {
                // A column read twice would be read from whichever copy came last: refuse
                // any copy of a column the reader uses.
                let used = [cols.valid, cols.frame, cols.time, cols.segment].contains(&Some(h))
                    || cols.axes[..dims].iter().any(|a| {
                        h.strip_prefix(a)
                            .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
                    });
                if used {
                    return Err(Error::parse(
                        path,
                        1,
                        i as u64 + 1,
                        format!(
                            "column '{h}' appears twice (fields {} and {}): which copy holds the data is ambiguous",
                            first + 1,
                            i + 1
                        ),
                    ));
                }
                index.insert(h.as_str(), first);
            }
        }
        let coord_cols = coordinate_columns(path, &index, &cols, dims, format)?;
        let conf_cols = match cols.confidence {
            Some(prefix) => confidence_columns(path, &index, prefix, coord_cols.len() / dims)?,
            None => None,
        };
        let find = |name: Option<&str>| name.and_then(|n| index.get(n).copied());
        let (valid_col, frame_col) = (find(cols.valid), find(cols.frame));
        let (time_col, seg_col) = (find(cols.time), find(cols.segment));
        Ok(TableRows {
            path: path.to_path_buf(),
            rdr,
            coord_cols,
            valid_col,
            frame_col,
            time_col,
            seg_col,
            conf_cols,
            header,
            record: csv::StringRecord::new(),
            coords: Vec::new(),
            conf: Vec::new(),
            row: 0,
            seen: SeenFrames::default(),
            dims,
            cut: None,
        })
    }

    /// Points per shape.
    pub fn points(&self) -> usize {
        self.coord_cols.len() / self.dims
    }

    /// Values per shape (`dims × points`).
    pub fn values(&self) -> usize {
        self.coord_cols.len()
    }

    /// Whether rows carry a time stamp.
    pub fn has_time(&self) -> bool {
        self.time_col.is_some()
    }

    /// Whether rows carry per-point confidences.
    pub fn has_confidence(&self) -> bool {
        self.conf_cols.is_some()
    }

    /// Whether rows carry a clip label.
    pub fn has_segments(&self) -> bool {
        self.seg_col.is_some()
    }

    /// The line of the file's last row when it was cut short — fewer fields than the
    /// header and no line end, as a full disk or a kill leaves a row being written — and so
    /// left out: the rows before it are read. None for a whole file.
    pub fn cut_row(&self) -> Option<u64> {
        self.cut
    }

    /// The next data row (blank lines skipped), or None at the end.
    pub fn next_row(&mut self) -> Result<Option<Row<'_>>> {
        let path = self.path.as_path();
        loop {
            match self.rdr.read_record(&mut self.record) {
                Ok(true) => {}
                Ok(false) => return Ok(None),
                Err(e) => {
                    let line = e.position().map(|p| self.rdr.get_mut().line_at(p.byte()));
                    return Err(csv_error(path, &e, line));
                }
            }
            let line = match self.record.position() {
                Some(p) => self.rdr.get_mut().line_at(p.byte()),
                None => 0,
            };
            let record = &self.record;
            if record.len() == 1 && record.get(0) == Some("") {
                continue; // blank line
            }
            if record.as_slice().len() > super::MAX_LINE_BYTES {
                return Err(Error::parse(
                    path,
                    line,
                    0,
                    format!(
                        "line is longer than {} bytes: not a text table",
                        super::MAX_LINE_BYTES
                    ),
                ));
            }
            if record.len() < self.header.len() && cut_short(&mut self.rdr) {
                self.cut = Some(line);
                return Ok(None);
            }
            let (record, header) = (&self.record, &self.header);
            if record.len() != header.len() {
                let col = record.len().min(header.len()) as u64 + 1;
                return Err(Error::parse(
                    path,
                    line,
                    col,
                    format!(
                        "ragged row: {} fields, the header has {}",
                        record.len(),
                        header.len()
                    ),
                ));
            }
            let frame = match self.frame_col {
                Some(c) => parse_int(path, line, c, &header[c], &record[c])?,
                None => self.row,
            };
            self.row += 1;
            if let Some(first) = self.seen.insert(frame, line) {
                let c = self.frame_col.map_or(0, |c| c as u64 + 1);
                return Err(Error::parse(
                    path,
                    line,
                    c,
                    format!("frame {frame} appears twice (first on line {first}): frame numbers must be unique"),
                ));
            }
            let tracked = match self.valid_col {
                Some(c) => parse_num(path, line, c, &header[c], &record[c])? != 0.0,
                None => true,
            };
            self.coords.clear();
            self.conf.clear();
            let mut time = None;
            if tracked {
                for &c in &self.coord_cols {
                    self.coords
                        .push(parse_num(path, line, c, &header[c], &record[c])?);
                }
                let cols = self.conf_cols.as_deref().unwrap_or(&[]);
                confidences(path, line, cols, (header, record), &mut self.conf)?;
                if let Some(c) = self.time_col {
                    time = Some(parse_num(path, line, c, &header[c], &record[c])?);
                }
            }
            return Ok(Some(Row {
                frame,
                line,
                tracked,
                coords: &self.coords,
                time,
                segment: self.seg_col.map(|c| &self.record[c]),
                confidence: &self.conf,
            }));
        }
    }
}

/// Reads a landmark table of the given format.
pub(super) fn read(path: &Path, text: &str, format: Format, dims: usize) -> Result<Sequence> {
    let lines = text.bytes().filter(|&b| b == b'\n').count() + 1;
    read_rows(
        path,
        text.as_bytes(),
        lines,
        text.len() as u64,
        format,
        dims,
    )
}

/// Reads a landmark table of the given format from `reader`, which holds `bytes` bytes in
/// `lines` lines (for the room reserved up front; a wrong count costs memory, not results).
pub(super) fn read_rows<R: std::io::Read>(
    path: &Path,
    reader: R,
    lines: usize,
    bytes: u64,
    format: Format,
    dims: usize,
) -> Result<Sequence> {
    let mut rows = TableRows::new(path, reader, format, dims)?;
    let width = rows.values();
    // Room for every line up front: growing by doubling would hold up to twice the
    // coordinates while the last copy is made.
    // (Each value takes at least two bytes with its comma, which bounds a hostile guess.)
    let room = usize::try_from(bytes / 2 + 1).unwrap_or(usize::MAX);
    let mut data = Vec::with_capacity(lines.saturating_mul(width).min(room));
    let (mut frames, mut failed) = (Vec::with_capacity(lines), Vec::new());
    let (mut times, mut segments, mut conf) = (Vec::new(), Vec::new(), Vec::new());
    let (has_time, has_segments) = (rows.has_time(), rows.has_segments());
    let has_confidence = rows.has_confidence();
    while let Some(r) = rows.next_row()? {
        if !r.tracked {
            failed.push(r.frame);
            continue;
        }
        data.extend_from_slice(r.coords);
        frames.push(r.frame);
        if let Some(t) = r.time {
            times.push(t);
        }
        if let Some(s) = r.segment {
            segments.push(s.to_string());
        }
        conf.extend_from_slice(r.confidence);
    }
    let points = rows.points();
    let n = frames.len();
    Ok(Sequence {
        source: path.display().to_string(),
        format,
        dims,
        points,
        coords: DMatrix::from_vec(dims * points, n, data),
        frames,
        times: has_time.then_some(times),
        segments: has_segments.then_some(segments),
        confidence: has_confidence.then(|| DMatrix::from_vec(points, n, conf)),
        failed,
        notes: rows
            .cut_row()
            .map(|line| {
                format!(
                    "{}: line {line}, the last, is cut short (no line end, fewer fields than the header: a take cut by a full disk or a kill); read up to the row before it",
                    path.display()
                )
            })
            .into_iter()
            .collect(),
    })
}

/// The confidences in columns `cols` of `record` (line `line`), each finite and ≥ 0,
/// onto `out`.
fn confidences(
    path: &Path,
    line: u64,
    cols: &[usize],
    (header, record): (&[String], &csv::StringRecord),
    out: &mut Vec<f64>,
) -> Result<()> {
    for &c in cols {
        let v = parse_num(path, line, c, &header[c], &record[c])?;
        if !(v.is_finite() && v >= 0.0) {
            return Err(Error::parse(
                path,
                line,
                c as u64 + 1,
                format!("'{}' is {v}: a confidence is finite and ≥ 0", header[c]),
            ));
        }
        out.push(v);
    }
    Ok(())
}

/// A csv error at `line` (None: the line the csv crate counted).
fn csv_error(path: &Path, e: &csv::Error, line: Option<u64>) -> Error {
    match (crate::csv_error::csv_error(path, e), line) {
        (
            Error::Parse {
                path,
                column,
                message,
                ..
            },
            Some(line),
        ) => Error::parse(path, line, column, message),
        (err, _) => err,
    }
}

fn parse_num(path: &Path, line: u64, col: usize, name: &str, cell: &str) -> Result<f64> {
    let at = |msg: String| Error::parse(path, line, col as u64 + 1, msg);
    if cell.is_empty() {
        return Err(at(format!("empty cell in column '{name}'")));
    }
    let v: f64 = cell
        .parse()
        .map_err(|_| at(format!("not a number: '{cell}' in column '{name}'")))?;
    if !v.is_finite() {
        return Err(at(format!("non-finite value '{cell}' in column '{name}'")));
    }
    if let Some(why) = keyshape_core::sequence::coord_problem(v) {
        return Err(at(format!("{why} in column '{name}'")));
    }
    Ok(v)
}

fn parse_int(path: &Path, line: u64, col: usize, name: &str, cell: &str) -> Result<i64> {
    let v = parse_num(path, line, col, name, cell)?;
    if v.fract() != 0.0 || v.abs() > 1e15 {
        return Err(Error::parse(
            path,
            line,
            col as u64 + 1,
            format!("frame number must be a whole number, got '{cell}' in column '{name}'"),
        ));
    }
    Ok(v as i64)
}
