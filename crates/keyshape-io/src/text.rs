//! A file's text and bytes as every reader takes them: size limits, gzip, a byte-order
//! mark; named columns of a CSV; a JSON file.

use keyshape_core::error::{Error, Result};
use std::io::Read;
use std::path::Path;

/// The largest input file read, and the largest text a gzip file may expand to.
pub const MAX_INPUT_BYTES: u64 = 4 << 30;
/// The longest line an input may have (a 468-point 3-D MediaPipe row is about 25 KB).
pub const MAX_LINE_BYTES: usize = 16 << 20;

/// One line of a stream, read with its length bounded before it is stored.
#[derive(Debug, PartialEq, Eq)]
pub enum Line {
    /// The line's bytes (with its `\n`, when it had one) are in the buffer.
    Read(usize),
    /// The stream has ended.
    End,
    /// The line was longer than the cap: its first bytes were dropped and the rest read
    /// past, so the next call reads the next line.
    TooLong,
}

/// Reads one line (up to and including `\n`) into `buf` (cleared first), storing at most
/// `cap` bytes: a longer line is read past and reported, never held whole. Every reader of
/// lines from a stream (a live source, a streamed table) goes through this, so one line of
/// a gigabyte costs no gigabyte.
pub fn read_line_capped(
    r: &mut dyn std::io::BufRead,
    buf: &mut Vec<u8>,
    cap: usize,
) -> std::io::Result<Line> {
    buf.clear();
    let mut too_long = false;
    let mut any = false;
    loop {
        let avail = match r.fill_buf() {
            Ok(a) => a,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        if avail.is_empty() {
            break;
        }
        any = true;
        let (take, done) = match avail.iter().position(|&b| b == b'\n') {
            Some(i) => (i + 1, true),
            None => (avail.len(), false),
        };
        if !too_long {
            if buf.len() + take > cap {
                too_long = true;
                buf.clear();
            } else {
                buf.extend_from_slice(&avail[..take]);
            }
        }
        r.consume(take);
        if done {
            break;
        }
    }
    Ok(if too_long {
        Line::TooLong
    } else if any {
        Line::Read(buf.len())
    } else {
        Line::End
    })
}

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
    crate::atomic::check_input_path(path)?;
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
    crate::atomic::register_input(path)?;
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

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// Lines come back whole up to the cap, a longer one is read past (never stored) and
    /// the next line is read as it is; the last line may lack its `\n`.
    #[test]
    fn a_line_is_stored_up_to_its_cap_and_a_longer_one_read_past() {
        let text = b"ab\n12345\nxyz\n\nlast";
        // A reader of 2-byte reads, so lines cross the buffer's edges.
        let mut r = std::io::BufReader::with_capacity(2, &text[..]);
        let mut buf = Vec::new();
        let mut got = Vec::new();
        loop {
            match read_line_capped(&mut r, &mut buf, 4).unwrap() {
                Line::End => break,
                Line::TooLong => got.push("<too long>".to_string()),
                Line::Read(n) => {
                    assert_eq!(n, buf.len());
                    got.push(String::from_utf8(buf.clone()).unwrap());
                }
            }
        }
        assert_eq!(got, ["ab\n", "<too long>", "xyz\n", "\n", "last"]);
        assert!(buf.is_empty(), "an ended stream leaves the buffer empty");
        // A line of exactly the cap is whole.
        let mut r = &b"abc\n"[..];
        assert_eq!(
            read_line_capped(&mut r, &mut buf, 4).unwrap(),
            Line::Read(4)
        );
        let mut r = &b"abcd\n"[..];
        assert_eq!(
            read_line_capped(&mut r, &mut buf, 4).unwrap(),
            Line::TooLong
        );
        assert_eq!(read_line_capped(&mut r, &mut buf, 4).unwrap(), Line::End);
    }

    /// A read interrupted by a signal is retried; any other error is the caller's.
    #[test]
    fn an_interrupted_read_is_retried_and_another_error_returned() {
        struct Flaky<'a> {
            fails: Vec<std::io::ErrorKind>,
            data: &'a [u8],
        }
        impl std::io::Read for Flaky<'_> {
            fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
                if let Some(k) = self.fails.pop() {
                    return Err(k.into());
                }
                let n = out.len().min(self.data.len());
                out[..n].copy_from_slice(&self.data[..n]);
                self.data = &self.data[n..];
                Ok(n)
            }
        }
        let mut buf = Vec::new();
        let mut r = std::io::BufReader::new(Flaky {
            fails: vec![std::io::ErrorKind::Interrupted],
            data: b"ok\n",
        });
        assert_eq!(
            read_line_capped(&mut r, &mut buf, 16).unwrap(),
            Line::Read(3)
        );
        let mut r = std::io::BufReader::new(Flaky {
            fails: vec![std::io::ErrorKind::InvalidData],
            data: b"ok\n",
        });
        let e = read_line_capped(&mut r, &mut buf, 16).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::InvalidData);
    }
}
