//! The library's one error type. Every message names what went wrong and where: the file,
//! and for parse errors the 1-based line and column, so a user can open the file and look.

use std::path::PathBuf;

/// Result alias for the library.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong in keyshape-lab's library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be opened, read or written.
    // The OS error is part of the message, not a `source`, so error chains print it once.
    #[error("{}: {err}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        err: std::io::Error,
    },
    /// A file was read but its content is wrong at a known place.
    #[error("{}:{line}:{column}: {message}", path.display())]
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
    #[error("{}: {message}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A setting or argument is invalid (key frame out of range, unknown group …).
    #[error("{0}")]
    Invalid(String),
}

impl Error {
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
