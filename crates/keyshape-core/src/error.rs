//! The library's one error type. Every message names what went wrong and where: the file,
//! and for parse errors the 1-based line and column, so a user can open the file and look.

use std::path::PathBuf;

/// Result alias for the library.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong in keyshape-lab's library.
#[derive(Debug)]
pub enum Error {
    /// A file could not be opened, read or written. (The OS error is part of the message,
    /// not a `source`, so error chains print it once.)
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        err: std::io::Error,
    },
    /// A file was read but its content is wrong at a known place.
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line (0 when unknown).
        line: u64,
        /// 1-based column (0 when unknown). For CSV files this is the field number.
        column: u64,
        /// What is wrong there.
        message: String,
    },
    /// A file is wrong as a whole (empty, no landmark columns, every frame failed …).
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A setting or argument is invalid (key frame out of range, unknown group …).
    Invalid(String),
}

impl std::fmt::Display for Error {
    /// The message with each [`setting`] by its library name (`dims 3 …`).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.render(&|name| name.to_string()))
    }
}

impl std::error::Error for Error {}

/// Marks a setting's name in a message: the library's name for something its caller chose
/// (`dims`, `points`, `modes` …). [`Error`]'s `Display` shows the name as it is; a front end
/// shows it as its users spell it ([`Error::render`]): the command line as a flag
/// (`--dims`), an experiment file as its key.
pub fn setting(name: &str) -> String {
    format!("{MARK_OPEN}{name}{MARK_CLOSE}")
}

const MARK_OPEN: char = '\u{2}';
const MARK_CLOSE: char = '\u{3}';

/// `text` with every [`setting`] mark replaced by `spell(name)`.
pub fn spell_settings(text: &str, spell: &dyn Fn(&str) -> String) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(i) = rest.find(MARK_OPEN) {
        out.push_str(&rest[..i]);
        let after = &rest[i + MARK_OPEN.len_utf8()..];
        match after.find(MARK_CLOSE) {
            Some(j) => {
                out.push_str(&spell(&after[..j]));
                rest = &after[j + MARK_CLOSE.len_utf8()..];
            }
            None => {
                rest = after;
            }
        }
    }
    out.push_str(rest);
    out
}

impl Error {
    /// The message, each [`setting`] spelled by `spell`: `|n| format!("--{n}")` for a
    /// command line. `Display` is `render` with the names as they are.
    pub fn render(&self, spell: &dyn Fn(&str) -> String) -> String {
        let text = match self {
            Error::Io { path, err } => format!("{}: {err}", path.display()),
            Error::Parse {
                path,
                line,
                column,
                message,
            } => format!("{}{}: {message}", path.display(), place(*line, *column)),
            Error::File { path, message } => format!("{}: {message}", path.display()),
            Error::Invalid(message) => message.clone(),
        };
        spell_settings(&text, spell)
    }

    /// An [`Error::Invalid`] from anything printable.
    pub fn invalid(msg: impl Into<String>) -> Self {
        Error::Invalid(msg.into())
    }

    /// An [`Error::File`] for `path`.
    pub fn file(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::File {
            path: path.into(),
            message: msg.into(),
        }
    }

    /// An [`Error::Io`] for `path`.
    pub fn io(path: impl Into<PathBuf>, err: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            err,
        }
    }

    /// An error from the `csv` crate while reading `path`, at the line and 1-based field the
    /// crate reports (a record of the wrong length names the first field missing or extra).
    ///
    /// The crate does not count blank lines; give the `text` that was read so the line is
    /// counted from the byte offset instead ([`Error::csv_in`]).
    pub fn csv(path: impl Into<PathBuf>, err: &csv::Error) -> Self {
        Error::csv_line(path, err, err.position().map_or(0, |p| p.line()))
    }

    /// [`Error::csv`] for a reader over `text`: the line counted from the byte offset.
    pub fn csv_in(path: impl Into<PathBuf>, err: &csv::Error, text: &[u8]) -> Self {
        let line = err.position().map_or(0, |p| line_at(text, p.byte()));
        Error::csv_line(path, err, line)
    }

    fn csv_line(path: impl Into<PathBuf>, err: &csv::Error, line: u64) -> Self {
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

    /// An [`Error::Parse`] at `line:column` of `path`.
    pub fn parse(path: impl Into<PathBuf>, line: u64, column: u64, msg: impl Into<String>) -> Self {
        Error::Parse {
            path: path.into(),
            line,
            column,
            message: msg.into(),
        }
    }
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

/// `:line:column`, leaving out what is unknown (0), so no message points at a column 0 that
/// does not exist.
fn place(line: u64, column: u64) -> String {
    match (line, column) {
        (0, _) => String::new(),
        (l, 0) => format!(":{l}"),
        (l, c) => format!(":{l}:{c}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_setting_is_named_as_each_front_end_spells_it() {
        let e = Error::parse(
            "t.csv",
            1,
            13,
            format!("{d} 3 needs a column 'z_0'; use {d} 2", d = setting("dims")),
        );
        assert_eq!(
            e.to_string(),
            "t.csv:1:13: dims 3 needs a column 'z_0'; use dims 2"
        );
        let flag = e.render(&|n| format!("--{n}"));
        assert_eq!(
            flag,
            "t.csv:1:13: --dims 3 needs a column 'z_0'; use --dims 2"
        );
        // No marks left in either, and text without marks is left as it is.
        assert!(!flag.contains(MARK_OPEN) && !flag.contains(MARK_CLOSE));
        assert_eq!(spell_settings("a, b", &|_| "x".into()), "a, b");
        // A mark cut short (a message truncated by its caller) loses its mark only.
        let cut = format!("use {}", setting("dims"));
        let cut = &cut[..cut.len() - 1];
        assert_eq!(spell_settings(cut, &|n| format!("--{n}")), "use dims");
    }

    /// Columns are 1-based: an unknown one is left out, never printed as 0.
    #[test]
    fn unknown_places_are_left_out() {
        assert_eq!(Error::parse("a.csv", 3, 2, "m").to_string(), "a.csv:3:2: m");
        assert_eq!(Error::parse("a.csv", 3, 0, "m").to_string(), "a.csv:3: m");
        assert_eq!(Error::parse("a.csv", 0, 0, "m").to_string(), "a.csv: m");
    }

    /// A csv-crate error names the line and the first field missing or extra.
    #[test]
    fn csv_errors_name_line_and_field() {
        let read = |text: &str| {
            let mut rdr = csv::Reader::from_reader(text.as_bytes());
            let e = rdr.records().find_map(|r| r.err()).unwrap();
            Error::csv_in("t.csv", &e, text.as_bytes()).to_string()
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
