//! The library's one error type. Every message names what went wrong and where: the file,
//! and for parse errors the 1-based line and column, so a user can open the file and look.
//!
//! A caller acts on the kind ([`Error::kind`]), never on the words: a reader's place in a
//! file ([`Error::Parse`]), a setting with its value ([`Error::Setting`]), data that cannot
//! be fitted as asked ([`Error::Unfit`]), something another step makes first
//! ([`Error::Needs`], which the front end turns into the command that makes it), I/O.
//!
//! `Display` is written by hand rather than derived (`thiserror`): a setting's name is
//! marked in the message ([`setting`]) and each front end spells it its own way
//! ([`Error::render`]), which a derived format string cannot do.

use std::path::PathBuf;

/// Result alias for the library.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong in keyshape-lab's library.
#[derive(Debug)]
#[non_exhaustive]
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
    /// A setting the caller chose is unknown, malformed or out of its range.
    Setting {
        /// The library's name of the setting (`dims`, `k`, `smooth_lambda` …), as marked in
        /// the message.
        name: String,
        /// The value given, as text.
        value: String,
        /// The whole message: the setting, its value and what it takes.
        message: String,
    },
    /// The data cannot be fitted as asked: too few distinct shapes, coincident points, a
    /// system that is not positive definite, a solve that gave non-finite numbers.
    Unfit(String),
    /// This step needs something another step makes (actions chosen on this track, a
    /// template with its record of the keys, a sharded run's partial reports). The message
    /// says what is missing; a front end says how its users make it ([`Needed`]).
    Needs {
        /// The file found wanting, if one was.
        path: Option<PathBuf>,
        /// What makes the missing piece.
        needed: Needed,
        /// What is missing, and why.
        message: String,
    },
    /// A request that does not fit the data or the other arguments (a frame or point out of
    /// range, a key listed twice, shapes of different sizes), or a built-in table that is
    /// malformed.
    Invalid(String),
}

/// What another step makes, for [`Error::Needs`].
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum Needed {
    /// Actions (paper 002's example frames) chosen on this track.
    ActionsFor(PathBuf),
    /// A target template written by this program.
    Template,
    /// The partial reports of a sharded corpus run.
    ShardReports,
    /// A Slurm array whose task ids run from 0 without gaps, `tasks` of them.
    ContiguousArray {
        /// How many tasks the array has.
        tasks: usize,
    },
}

/// The kind of an [`Error`], for a caller (or a test) that acts on what went wrong rather
/// than on its words.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum ErrorKind {
    /// [`Error::Io`].
    Io,
    /// [`Error::Parse`].
    Parse,
    /// [`Error::File`].
    File,
    /// [`Error::Setting`].
    Setting,
    /// [`Error::Unfit`].
    Unfit,
    /// [`Error::Needs`].
    Needs,
    /// [`Error::Invalid`].
    Invalid,
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
            Error::Needs {
                path: Some(path),
                message,
                ..
            } => format!("{}: {message}", path.display()),
            Error::Setting { message, .. }
            | Error::Unfit(message)
            | Error::Needs { message, .. }
            | Error::Invalid(message) => message.clone(),
        };
        spell_settings(&text, spell)
    }

    /// What went wrong, as a kind.
    pub fn kind(&self) -> ErrorKind {
        match self {
            Error::Io { .. } => ErrorKind::Io,
            Error::Parse { .. } => ErrorKind::Parse,
            Error::File { .. } => ErrorKind::File,
            Error::Setting { .. } => ErrorKind::Setting,
            Error::Unfit(_) => ErrorKind::Unfit,
            Error::Needs { .. } => ErrorKind::Needs,
            Error::Invalid(_) => ErrorKind::Invalid,
        }
    }

    /// The setting an [`Error::Setting`] names, with the value given.
    pub fn setting(&self) -> Option<(&str, &str)> {
        match self {
            Error::Setting { name, value, .. } => Some((name, value)),
            _ => None,
        }
    }

    /// The file an error names, if it names one.
    pub fn path(&self) -> Option<&std::path::Path> {
        match self {
            Error::Io { path, .. } | Error::Parse { path, .. } | Error::File { path, .. } => {
                Some(path)
            }
            Error::Needs { path, .. } => path.as_deref(),
            _ => None,
        }
    }

    /// An [`Error::Invalid`] from anything printable.
    pub fn invalid(msg: impl Into<String>) -> Self {
        Error::Invalid(msg.into())
    }

    /// An [`Error::Setting`]: the setting `name` given `value`; `message` says it all,
    /// naming the setting with [`setting`] where it appears.
    pub fn bad_setting(
        name: &str,
        value: impl std::fmt::Display,
        message: impl Into<String>,
    ) -> Self {
        Error::Setting {
            name: name.to_string(),
            value: value.to_string(),
            message: message.into(),
        }
    }

    /// An [`Error::Unfit`] from anything printable.
    pub fn unfit(msg: impl Into<String>) -> Self {
        Error::Unfit(msg.into())
    }

    /// An [`Error::Needs`]: `message` says what is missing, `needed` what makes it.
    pub fn needs(needed: Needed, message: impl Into<String>) -> Self {
        Error::Needs {
            path: None,
            needed,
            message: message.into(),
        }
    }

    /// [`Error::needs`] for a file found wanting: the message is placed after its path.
    pub fn needs_in(path: impl Into<PathBuf>, needed: Needed, message: impl Into<String>) -> Self {
        Error::Needs {
            path: Some(path.into()),
            needed,
            message: message.into(),
        }
    }

    /// What makes the missing piece of an [`Error::Needs`].
    pub fn needed(&self) -> Option<&Needed> {
        match self {
            Error::Needs { needed, .. } => Some(needed),
            _ => None,
        }
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

    /// Each constructor gives its kind; a setting error names its setting and value; a
    /// file's errors name the file; what an error needs is given back; and the words are
    /// the message's, a path before them when there is one.
    #[test]
    fn each_error_has_the_kind_a_caller_acts_on() {
        let cases = [
            (Error::io("a", std::io::Error::other("gone")), ErrorKind::Io),
            (Error::parse("a", 1, 2, "m"), ErrorKind::Parse),
            (Error::file("a", "m"), ErrorKind::File),
            (
                Error::bad_setting("k", 0, "k 0: give 1 to 64"),
                ErrorKind::Setting,
            ),
            (Error::unfit("m"), ErrorKind::Unfit),
            (Error::needs(Needed::Template, "m"), ErrorKind::Needs),
            (Error::invalid("m"), ErrorKind::Invalid),
        ];
        for (e, kind) in &cases {
            assert_eq!(e.kind(), *kind, "{e}");
            let named = matches!(kind, ErrorKind::Io | ErrorKind::Parse | ErrorKind::File);
            assert_eq!(e.path().is_some(), named, "{e}");
        }
        let e = Error::bad_setting("k", 0, format!("{} 0: give 1 to 64", setting("k")));
        assert_eq!(e.setting(), Some(("k", "0")));
        assert_eq!(e.render(&|n| format!("--{n}")), "--k 0: give 1 to 64");
        assert_eq!(Error::unfit("m").setting(), None);
        let e = Error::needs_in("t.svg", Needed::Template, "not a template");
        assert_eq!(e.needed(), Some(&Needed::Template));
        assert_eq!(e.path(), Some(std::path::Path::new("t.svg")));
        assert_eq!(e.to_string(), "t.svg: not a template");
        assert_eq!(Error::needs(Needed::ShardReports, "m").to_string(), "m");
        assert_eq!(Error::invalid("m").needed(), None);
    }
}
