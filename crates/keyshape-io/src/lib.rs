//! Readers and writers. Every reader returns a validated [`Sequence`]; every error names the
//! file and, for parse errors, the line and column.
//!
//! **The front door:** [`read_sequence`] with [`ReadOptions`] (any track kslab reads, format
//! detected) and [`builtin_sequence`]; [`write_atomic`] (a file appears whole or not at
//! all) and [`OutputSet`] (several files, all or none); [`csv_out`] for tables. The modules
//! hold the rest: meshes ([`obj`]), morph targets ([`morph`]), GLB ([`gltf`]), JSON tracks,
//! synthetic long tracks for benchmarks, and the solve of a track of any length streamed
//! from its file to its weights ([`stream`]).
//!
//! A whole solve, from the built-in sequence to blend weights:
//!
//! ```
//! use keyshape_core::{decompose, prepare, PrepareOptions, SolveOptions, Solver};
//! use keyshape_io::builtin_sequence;
//!
//! let seq = builtin_sequence()?;
//! let opts = PrepareOptions::group_aligned("lips");
//! let prep = prepare(&seq, &opts)?;
//! let keys: Vec<usize> = [0, 60, 120, 180, 215]
//!     .iter()
//!     .map(|&f| prep.seq.column_of_frame(f))
//!     .collect::<Result<_, _>>()?;
//! let nnls = SolveOptions::new(Solver::Nnls);
//! let d = decompose(&prep, &keys, None, &nnls)?;
//! assert_eq!(d.negative_share(), 0.0);
//! assert!(d.mean_rms() < 5.0); // pixels
//! # Ok::<(), keyshape_core::Error>(())
//! ```

pub mod atomic;
mod builtin;
pub mod csv_error;
pub mod csv_out;
pub mod gltf;
pub mod json;
pub mod morph;
pub mod obj;
mod pts;

pub mod stream;
pub mod synthetic;
pub mod table;

pub use atomic::{check_output, check_output_dir, create_dir_all, write_atomic, OutputSet};
pub use builtin::{builtin_sequence, BUILTIN_NAME};

use keyshape_core::error::{setting, Error, Result};
use keyshape_core::sequence::{Format, Sequence};
use std::io::Read;
use std::path::Path;

/// How to read a sequence.
#[derive(Debug, Clone, Copy)]
pub struct ReadOptions {
    /// Force a format instead of detecting it.
    pub format: Option<Format>,
    /// 2 (x, y) or 3 (x, y, z).
    pub dims: usize,
}

impl Default for ReadOptions {
    fn default() -> Self {
        ReadOptions {
            format: None,
            dims: 2,
        }
    }
}

/// Formats a number for CSV output: shortest round-trip decimal, with an exponent for
/// magnitudes below 1e-4 or from 1e15 on (so 2.5e-12 does not print as 0.0000000000025).
pub fn fmt_num(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 || (1e-4..1e15).contains(&a) || !v.is_finite() {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// Reads a tracked sequence from a file or a directory of `.pts` files.
pub fn read_sequence(path: &Path, opts: &ReadOptions) -> Result<Sequence> {
    if opts.dims != 2 && opts.dims != 3 {
        return Err(Error::bad_setting(
            "dims",
            opts.dims,
            format!("{} must be 2 or 3, got {}", setting("dims"), opts.dims),
        ));
    }
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if meta.is_dir() {
        return match opts.format {
            None | Some(Format::Pts) => pts::read_dir(path, opts.dims),
            Some(f) => Err(Error::file(
                path,
                format!("is a directory; format {f} needs a file"),
            )),
        };
    }
    if let Some(seq) = read_table_streamed(path, &meta, opts)? {
        return Ok(seq);
    }
    let text = read_text(path)?;
    parse_sequence(path, &text, opts)
}

/// Opens a file for reading from the start, un-gzipped when it ends in `.gz`, reading at
/// most [`MAX_INPUT_BYTES`] + 1 bytes (so a caller can tell a file over the limit).
pub fn open_input(path: &Path) -> Result<Box<dyn Read>> {
    let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let r = std::io::BufReader::with_capacity(1 << 16, f);
    Ok(if path.extension().is_some_and(|e| e == "gz") {
        Box::new(std::io::BufReader::new(
            flate2::read::MultiGzDecoder::new(r).take(MAX_INPUT_BYTES + 1),
        ))
    } else {
        Box::new(r.take(MAX_INPUT_BYTES + 1))
    })
}

/// What a check pass over an input found: the checks [`text_from_bytes`] makes on a whole
/// text, made on a stream.
struct Scan {
    /// The first line, with its line end.
    first_line: String,
    /// Line ends.
    newlines: usize,
    /// Bytes of text.
    bytes: u64,
}

/// One pass over `path`: None when the text would fail a check of [`read_text`] (over the
/// size limit, a line over [`MAX_LINE_BYTES`], not UTF-8) or a read fails; the caller then
/// reads the file whole, which reports the problem with its line and column.
fn scan(path: &Path) -> Result<Option<Scan>> {
    let mut r = open_input(path)?;
    let mut buf = vec![0u8; 1 << 16];
    let (mut carry, mut bytes, mut newlines, mut line_len) = (0usize, 0u64, 0usize, 0usize);
    let mut first: Vec<u8> = Vec::new();
    let mut first_done = false;
    loop {
        let n = match r.read(&mut buf[carry..]) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(_) => return Ok(None),
        };
        let fresh = &buf[carry..carry + n];
        bytes += n as u64;
        if bytes > MAX_INPUT_BYTES {
            return Ok(None);
        }
        for &b in fresh {
            if b == b'\n' {
                newlines += 1;
                line_len = 0;
            } else {
                if line_len >= MAX_LINE_BYTES {
                    return Ok(None);
                }
                line_len += 1;
            }
        }
        if !first_done {
            match fresh.iter().position(|&b| b == b'\n') {
                Some(i) => {
                    first.extend_from_slice(&fresh[..=i]);
                    first_done = true;
                }
                None => first.extend_from_slice(fresh),
            }
        }
        let filled = carry + n;
        carry = match std::str::from_utf8(&buf[..filled]) {
            Ok(_) => 0,
            // A sequence cut by the end of the buffer: keep its bytes for the next read.
            Err(e) if e.error_len().is_none() => {
                let from = e.valid_up_to();
                buf.copy_within(from..filled, 0);
                filled - from
            }
            Err(_) => return Ok(None),
        };
    }
    if carry > 0 {
        return Ok(None);
    }
    let Ok(first_line) = String::from_utf8(first) else {
        return Ok(None);
    };
    Ok(Some(Scan {
        first_line,
        newlines,
        bytes,
    }))
}

/// A landmark table (MediaPipe, OpenFace, py-feat, plain CSV) read without holding its
/// text: a check pass ([`scan`]), then the rows parsed straight into the coordinates, so
/// reading holds one copy of them instead of the text and the coordinates. The result is
/// [`parse_sequence`]'s on the same text (the same row reader). None when the file is not
/// such a table or fails a check on the whole text: the caller reads it whole and reports
/// exactly what [`read_text`] and [`parse_sequence`] report.
fn read_table_streamed(
    path: &Path,
    meta: &std::fs::Metadata,
    opts: &ReadOptions,
) -> Result<Option<Sequence>> {
    if !meta.is_file() || meta.len() > MAX_INPUT_BYTES {
        return Ok(None);
    }
    let Some(scan) = scan(path)? else {
        return Ok(None);
    };
    // A blank first line: let the whole-text path decide between "empty" and its header error.
    if scan.first_line.trim().is_empty() {
        return Ok(None);
    }
    let format = match opts.format {
        Some(f) => f,
        None => detect_format(path, &scan.first_line)?,
    };
    if matches!(format, Format::Pts | Format::Json) {
        return Ok(None);
    }
    let reader = open_input(path)?;
    atomic::register_input(path);
    let seq = table::read_rows(
        path,
        reader,
        scan.newlines + 1,
        scan.bytes,
        format,
        opts.dims,
    )?;
    seq.validate()?;
    Ok(Some(seq))
}

/// Parses a sequence from text already read (`path` names it in errors and picks the
/// format by extension). What the fuzz targets call.
pub fn parse_sequence(path: &Path, text: &str, opts: &ReadOptions) -> Result<Sequence> {
    if opts.dims != 2 && opts.dims != 3 {
        return Err(Error::bad_setting(
            "dims",
            opts.dims,
            format!("{} must be 2 or 3, got {}", setting("dims"), opts.dims),
        ));
    }
    if text.trim().is_empty() {
        return Err(Error::file(path, "file is empty"));
    }
    let format = match opts.format {
        Some(f) => f,
        None => detect_format(path, text)?,
    };
    let seq = match format {
        Format::Pts => pts::read_file(path, text, opts.dims),
        Format::Json => json::read(path, text, opts.dims),
        f => table::read(path, text, f, opts.dims),
    }?;
    seq.validate()?;
    Ok(seq)
}

/// A file of the shared data folder (`shared/data/<rel>`, the tracks and meshes beside the
/// repository), found without depending on the current directory: in `$KSLAB_SHARED/data`
/// when that variable is set (it names the folder holding `data/`), else in `../shared/data`
/// beside the repository this binary was built from, else beside the repository the
/// running binary sits in (`<repo>/target/<profile>/kslab`). The error names every path
/// tried.
pub fn shared_data(rel: &str) -> Result<std::path::PathBuf> {
    use std::path::PathBuf;
    let mut tried = Vec::new();
    if let Some(dir) = std::env::var_os("KSLAB_SHARED") {
        let p = PathBuf::from(dir).join("data").join(rel);
        if p.exists() {
            return Ok(p);
        }
        // An explicit setting that does not hold the file is an error, not a fallback.
        return Err(Error::invalid(format!(
            "{} not found (KSLAB_SHARED is set to the folder that should hold data/{rel})",
            p.display()
        )));
    }
    // This crate sits at <repo>/crates/keyshape-io.
    let mut roots: Vec<PathBuf> = Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .nth(2)
        .map(Path::to_path_buf)
        .into_iter()
        .collect();
    if let Some(repo) = std::env::current_exe()
        .ok()
        .and_then(|e| e.ancestors().nth(3).map(Path::to_path_buf))
    {
        roots.push(repo);
    }
    for root in roots {
        let p = root.join("../shared/data").join(rel);
        if p.exists() {
            return Ok(p);
        }
        let shown = p.display().to_string();
        if !tried.contains(&shown) {
            tried.push(shown);
        }
    }
    Err(Error::invalid(format!(
        "shared data file data/{rel} not found: tried {} (set KSLAB_SHARED to the folder holding data/, or give the file explicitly)",
        tried.join(" and ")
    )))
}

/// The largest input file read, and the largest text a gzip file may expand to.
pub const MAX_INPUT_BYTES: u64 = 4 << 30;
/// The longest line an input may have (a 468-point 3-D MediaPipe row is about 25 KB).
pub const MAX_LINE_BYTES: usize = 16 << 20;

/// Reads a whole input file as UTF-8 text, un-gzipping `*.gz` files (every member of a
/// multi-member gzip; trailing bytes that are not gzip are an error). Only regular files are
/// read: a directory, a FIFO or a device (`/dev/zero`) is refused with a message, so nothing
/// blocks or reads without end. Files over [`MAX_INPUT_BYTES`] and lines over
/// [`MAX_LINE_BYTES`] are refused.
pub fn read_text(path: &Path) -> Result<String> {
    let bytes = read_bytes(path)?;
    let gz = path.extension().is_some_and(|e| e == "gz");
    text_from_bytes(path, bytes, gz)
}

/// Reads a whole input file's bytes (a GLB, a binary buffer) with the checks of
/// [`read_text`], recording it as an input that no output may replace.
pub fn read_bytes(path: &Path) -> Result<Vec<u8>> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        let what = if meta.is_dir() {
            "a directory"
        } else {
            "not a regular file (a device, FIFO or socket)"
        };
        return Err(Error::file(path, format!("is {what}; give a file")));
    }
    if meta.len() > MAX_INPUT_BYTES {
        return Err(Error::file(
            path,
            format!(
                "is {} bytes; inputs are limited to {MAX_INPUT_BYTES} bytes",
                meta.len()
            ),
        ));
    }
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    atomic::register_input(path);
    Ok(bytes)
}

/// [`read_text`] on bytes already in memory (`gz`: un-gzip first).
pub fn text_from_bytes(path: &Path, bytes: Vec<u8>, gz: bool) -> Result<String> {
    let bytes = if gz {
        let mut out = Vec::new();
        flate2::read::MultiGzDecoder::new(&bytes[..])
            .take(MAX_INPUT_BYTES + 1)
            .read_to_end(&mut out)
            .map_err(|e| Error::file(path, format!("not a valid gzip file: {e}")))?;
        if out.len() as u64 > MAX_INPUT_BYTES {
            return Err(Error::file(
                path,
                format!("expands to more than {MAX_INPUT_BYTES} bytes"),
            ));
        }
        out
    } else {
        bytes
    };
    // A UTF-8 byte-order mark (Windows editors write one) is not part of the text: every
    // reader takes the file without it, as the CSV reader does.
    let mut bytes = bytes;
    if bytes.starts_with(&[0xEF, 0xBB, 0xBF]) {
        bytes.drain(..3);
    }
    let mut line = 1u64;
    let mut start = 0usize;
    for (i, &b) in bytes.iter().enumerate() {
        if b == b'\n' {
            line += 1;
            start = i + 1;
        } else if i - start >= MAX_LINE_BYTES {
            return Err(Error::parse(
                path,
                line,
                (i - start + 1) as u64,
                format!("line is longer than {MAX_LINE_BYTES} bytes: not a text table"),
            ));
        }
    }
    String::from_utf8(bytes).map_err(|e| {
        let upto = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        let line = upto.iter().filter(|&&b| b == b'\n').count() as u64 + 1;
        let col = upto.iter().rev().take_while(|&&b| b != b'\n').count() as u64 + 1;
        Error::parse(path, line, col, "not UTF-8 text")
    })
}

/// Guesses the format from the file name and the header line.
pub fn detect_format(path: &Path, text: &str) -> Result<Format> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let name = name.trim_end_matches(".gz");
    if name.ends_with(".pts") {
        return Ok(Format::Pts);
    }
    if name.ends_with(".json") || text.trim_start().starts_with('{') {
        return Ok(Format::Json);
    }
    let header = text.lines().next().unwrap_or("");
    let cols: Vec<String> = header.split(',').map(|c| c.trim().to_string()).collect();
    let has = |c: &str| cols.iter().any(|h| h == c);
    if has("x_0") && has("detected") {
        Ok(Format::Mediapipe)
    } else if has("x_0") && has("success") {
        Ok(Format::Openface)
    } else if has("x_0") {
        Ok(Format::Pyfeat)
    } else if has("x0") {
        Ok(Format::Csv)
    } else {
        Err(Error::parse(
            path,
            1,
            1,
            format!("header has no landmark columns (expected x_0,y_0,… or x0,y0,…); use {} to force one", setting("format")),
        ))
    }
}

/// Named numeric columns of a CSV table, one vector per name, over every data row (for side
/// tables such as py-feat's ARKit scores). Errors name file, line and column.
pub fn read_columns(path: &Path, names: &[&str]) -> Result<Vec<Vec<f64>>> {
    let text = read_text(path)?;
    let mut rdr = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let header: Vec<String> = rdr
        .headers()
        .map_err(|e| crate::csv_error::csv_error_in(path, &e, text.as_bytes()))?
        .iter()
        .map(str::to_string)
        .collect();
    let idx: Vec<usize> = names
        .iter()
        .map(|n| {
            header
                .iter()
                .position(|h| h == n)
                .ok_or_else(|| Error::parse(path, 1, 0, format!("no column '{n}'")))
        })
        .collect::<Result<_>>()?;
    let mut out = vec![Vec::new(); names.len()];
    let mut lines = crate::csv_error::LineCounter::new(text.as_bytes());
    for rec in rdr.records() {
        let rec = rec.map_err(|e| crate::csv_error::csv_error_in(path, &e, text.as_bytes()))?;
        let line = rec.position().map_or(0, |p| lines.line_at(p.byte()));
        for (k, &c) in idx.iter().enumerate() {
            let cell = rec.get(c).unwrap_or("");
            let v: f64 = cell.parse().map_err(|_| {
                Error::parse(
                    path,
                    line,
                    c as u64 + 1,
                    format!("not a number: '{cell}' in column '{}'", names[k]),
                )
            })?;
            out[k].push(v);
        }
    }
    Ok(out)
}

/// Reads a JSON file into `T`; errors name the file, line and column.
pub fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T> {
    let text = read_text(path)?;
    serde_json::from_str(&text)
        .map_err(|e| Error::parse(path, e.line() as u64, e.column() as u64, e.to_string()))
}

/// A table built into the binary for a layout family: the text `table` holds for `family`
/// (pairs of family and JSON text), parsed. `what` names the table in the errors: a family
/// with no table, and a table that does not parse (a fault of the build, not of the user).
pub fn builtin_json<T: serde::de::DeserializeOwned>(
    what: &str,
    family: &str,
    table: &[(&str, &str)],
) -> Result<T> {
    let Some((_, text)) = table.iter().find(|(f, _)| *f == family) else {
        return Err(Error::invalid(format!(
            "no built-in {what} for layout {family}"
        )));
    };
    serde_json::from_str(text).map_err(|e| Error::invalid(format!("built-in {what}: {e}")))
}
