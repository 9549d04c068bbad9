//! Readers and writers. Every reader returns a validated [`Sequence`]; every error names the
//! file and, for parse errors, the line and column.

pub mod atomic;
mod builtin;
pub mod gltf;
pub mod json;
pub mod obj;
mod pts;
pub mod svg;
mod table;

pub use atomic::write_atomic;
pub use builtin::{builtin_sequence, BUILTIN_NAME};

use crate::error::{Error, Result};
use crate::sequence::{Format, Sequence};
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
        return Err(Error::invalid(format!(
            "--dims must be 2 or 3, got {}",
            opts.dims
        )));
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
    let text = read_text(path)?;
    if text.trim().is_empty() {
        return Err(Error::file(path, "file is empty"));
    }
    let format = match opts.format {
        Some(f) => f,
        None => detect_format(path, &text)?,
    };
    let seq = match format {
        Format::Pts => pts::read_file(path, &text, opts.dims),
        Format::Json => json::read(path, &text, opts.dims),
        f => table::read(path, &text, f, opts.dims),
    }?;
    seq.validate()?;
    Ok(seq)
}

/// Reads a whole file as UTF-8 text, un-gzipping `*.gz` files.
fn read_text(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let bytes = if path.extension().is_some_and(|e| e == "gz") {
        let mut out = Vec::new();
        flate2::read::GzDecoder::new(&bytes[..])
            .read_to_end(&mut out)
            .map_err(|e| Error::file(path, format!("not a valid gzip file: {e}")))?;
        out
    } else {
        bytes
    };
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
            "header has no landmark columns (expected x_0,y_0,… or x0,y0,…); use --format to force one",
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
        .map_err(|e| Error::parse(path, 1, 0, e.to_string()))?
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
    for rec in rdr.records() {
        let rec = rec.map_err(|e| {
            Error::parse(path, e.position().map_or(0, |p| p.line()), 0, e.to_string())
        })?;
        let line = rec.position().map_or(0, |p| p.line());
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
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    serde_json::from_str(&text)
        .map_err(|e| Error::parse(path, e.line() as u64, e.column() as u64, e.to_string()))
}
