//! The front door of every track reader: options, format detection, the whole file or
//! a stream of rows, and the checks every sequence passes.

use crate::{atomic, json, pts, read_text, table, MAX_INPUT_BYTES, MAX_LINE_BYTES};
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
    atomic::register_input(path)?;
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
    atomic::register_input(path)?;
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
