//! Errors of the `csv` crate as the library's [`Error`]: the file, the line counted the way
//! an editor counts it (blank lines included) and the field. It lives here, with the
//! readers, so the numeric core does not depend on a CSV crate to build its messages.

use keyshape_core::error::Error;
use std::path::PathBuf;

/// An error from the `csv` crate while reading `path`, at the line and 1-based field the
/// crate reports (a record of the wrong length names the first field missing or extra).
///
/// The crate does not count blank lines; give the `text` that was read so the line is
/// counted from the byte offset instead ([`csv_error_in`]).
pub fn csv_error(path: impl Into<PathBuf>, err: &csv::Error) -> Error {
    csv_error_at(path, err, err.position().map_or(0, |p| p.line()))
}

/// [`csv_error`] for a reader over `text`: the line counted from the byte offset.
pub fn csv_error_in(path: impl Into<PathBuf>, err: &csv::Error, text: &[u8]) -> Error {
    let line = err.position().map_or(0, |p| line_at(text, p.byte()));
    csv_error_at(path, err, line)
}

fn csv_error_at(path: impl Into<PathBuf>, err: &csv::Error, line: u64) -> Error {
    let (column, message) = match err.kind() {
        csv::ErrorKind::UnequalLengths {
            expected_len, len, ..
        } => {
            let (expected, len) = (*expected_len, *len);
            let plural = |n: u64| if n == 1 { "field" } else { "fields" };
            (
                expected.min(len) + 1,
                format!(
                    "this row has {len} {} where the first row has {expected}",
                    plural(len)
                ),
            )
        }
        _ => (0, format!("CSV error: {err}")),
    };
    Error::parse(path, line, column, message)
}

/// The 1-based line of the first content at or after byte `byte` of `text`: the `csv` crate
/// places a record at the blank lines before it, and does not count them in its own line.
pub fn line_at(text: &[u8], byte: u64) -> u64 {
    let mut end = (byte as usize).min(text.len());
    while end < text.len() && matches!(text[end], b'\n' | b'\r') {
        end += 1;
    }
    1 + text[..end].iter().filter(|&&b| b == b'\n').count() as u64
}

/// [`line_at`] for records met in order: counts forward from the last call, so reading a
/// file costs one pass (calling [`line_at`] per record would be quadratic in its length).
pub struct LineCounter<'a> {
    text: &'a [u8],
    at: usize,
    line: u64,
}

impl<'a> LineCounter<'a> {
    /// A counter at the start of `text`.
    pub fn new(text: &'a [u8]) -> Self {
        LineCounter {
            text,
            at: 0,
            line: 1,
        }
    }

    /// The line of the first content at or after byte `byte`; `byte` must not go backwards.
    pub fn line_at(&mut self, byte: u64) -> u64 {
        let mut end = (byte as usize).clamp(self.at, self.text.len());
        while end < self.text.len() && matches!(self.text[end], b'\n' | b'\r') {
            end += 1;
        }
        self.line += self.text[self.at..end]
            .iter()
            .filter(|&&b| b == b'\n')
            .count() as u64;
        self.at = end;
        self.line
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A csv-crate error names the line and the first field missing or extra.
    #[test]
    fn csv_errors_name_line_and_field() {
        let read = |text: &str| {
            let mut rdr = csv::Reader::from_reader(text.as_bytes());
            let e = rdr.records().find_map(|r| r.err()).unwrap();
            csv_error_in("t.csv", &e, text.as_bytes()).to_string()
        };
        assert_eq!(
            read("a,b,c\n1,2,3\n\n4\n"),
            "t.csv:4:2: this row has 1 field where the first row has 3"
        );
        let text = b"a\n1\n\n\r\n2\n3";
        let mut lines = LineCounter::new(text);
        let starts = [2u64, 4, 8, 10];
        let counted: Vec<u64> = starts.iter().map(|&b| lines.line_at(b)).collect();
        let direct: Vec<u64> = starts.iter().map(|&b| line_at(text, b)).collect();
        assert_eq!(counted, vec![2, 5, 6, 6]);
        assert_eq!(counted, direct);
        assert_eq!(
            read("a,b\n1,2,3,4\n"),
            "t.csv:2:3: this row has 4 fields where the first row has 2"
        );
    }
}
