//! Output that never loses data.
//!
//! - A regular file is written to a temporary file beside it and renamed over it, so a failed
//!   run never leaves a half-written file and an old file survives a failure.
//! - A symbolic link is followed: the file it names is replaced (atomically, in *that* file's
//!   directory); the link stays a link.
//! - A special file (a device such as `/dev/null`, a FIFO) is written directly, never
//!   replaced; `-` is standard output.
//! - A file this process has read as input is never written: every reader goes through
//!   [`crate::io::read_text`], which records what it read, and [`write_atomic`] refuses a
//!   destination that is the same file (same device and inode, or same canonical path).
//!
//! [`check_output`] and [`check_output_dir`] run the same checks before any work is done,
//! so a command that cannot write one of its outputs fails before writing the others.

use crate::error::{Error, Result};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Identity of a file: (device, inode) on Unix, else its canonical path.
#[derive(Debug, Clone, PartialEq, Eq)]
enum FileId {
    #[cfg(unix)]
    Inode(u64, u64),
    #[cfg(not(unix))]
    Path(PathBuf),
}

fn file_id(path: &Path) -> Option<FileId> {
    let meta = std::fs::metadata(path).ok()?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        let _ = &meta;
        Some(FileId::Inode(meta.dev(), meta.ino()))
    }
    #[cfg(not(unix))]
    {
        let _ = meta;
        std::fs::canonicalize(path).ok().map(FileId::Path)
    }
}

/// Files read as input by this process: (identity, path as given).
static INPUTS: Mutex<Vec<(FileId, PathBuf)>> = Mutex::new(Vec::new());

/// Records `path` as an input: no output of this process may overwrite it.
pub fn register_input(path: &Path) {
    if let Some(id) = file_id(path) {
        if let Ok(mut v) = INPUTS.lock() {
            if !v.iter().any(|(i, _)| *i == id) {
                v.push((id, path.to_path_buf()));
            }
        }
    }
}

/// Errors when `path` (followed through links) is a file registered as input or one of
/// `inputs`.
fn check_not_input(path: &Path, inputs: &[&Path]) -> Result<()> {
    let Some(id) = file_id(path) else {
        return Ok(());
    };
    let registered = INPUTS.lock().map(|v| v.clone()).unwrap_or_default();
    let given = inputs
        .iter()
        .filter_map(|p| file_id(p).map(|i| (i, p.to_path_buf())));
    for (i, input) in registered.into_iter().chain(given) {
        if i == id {
            return Err(Error::file(
                path,
                format!(
                    "refusing to write: this is the input file {} (inputs are never overwritten; choose another output path)",
                    input.display()
                ),
            ));
        }
    }
    Ok(())
}

/// Follows symbolic links to the path they finally name (which may not exist yet).
fn resolve_links(path: &Path) -> Result<PathBuf> {
    let mut p = path.to_path_buf();
    for _ in 0..40 {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let link = std::fs::read_link(&p).map_err(|e| Error::io(&p, e))?;
                p = if link.is_absolute() {
                    link
                } else {
                    parent_dir(&p).join(link)
                };
            }
            _ => return Ok(p),
        }
    }
    Err(Error::file(path, "too many levels of symbolic links"))
}

fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Is `path` standard output (`-`)?
pub fn is_stdout(path: &Path) -> bool {
    path.as_os_str() == "-"
}

/// Can a file be created in `dir`? Tried for real with a probe file, removed at once.
fn check_dir_writable(dir: &Path, what: &Path) -> Result<()> {
    let meta = std::fs::metadata(dir).map_err(|e| {
        Error::file(
            what,
            format!("cannot write: directory {}: {e}", dir.display()),
        )
    })?;
    if !meta.is_dir() {
        return Err(Error::file(
            what,
            format!("cannot write: {} is not a directory", dir.display()),
        ));
    }
    let probe = dir.join(format!(".kslab-probe-{}", std::process::id()));
    match std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
    {
        Ok(_) => {
            let _ = std::fs::remove_file(&probe);
            Ok(())
        }
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(()),
        Err(e) => Err(Error::file(
            what,
            format!("cannot write in directory {}: {e}", dir.display()),
        )),
    }
}

/// Checks, before any work, that `path` can be written as an output file and is none of
/// `inputs` (nor a file already read): its directory exists and takes new files, and it is
/// not a directory.
pub fn check_output(path: &Path, inputs: &[&Path]) -> Result<()> {
    if is_stdout(path) {
        return Ok(());
    }
    let target = resolve_links(path)?;
    check_not_input(&target, inputs)?;
    match std::fs::metadata(&target) {
        Ok(m) if m.is_dir() => Err(Error::file(path, "is a directory; give a file name")),
        Ok(m) if !m.is_file() => Ok(()), // a device or FIFO: written directly
        _ => check_dir_writable(&parent_dir(&target), path),
    }
}

/// Checks, before any work, that `dir` can hold output files: it is a directory that takes
/// new files, or it does not exist yet and its nearest existing ancestor does.
pub fn check_output_dir(dir: &Path) -> Result<()> {
    let mut d = dir.to_path_buf();
    loop {
        match std::fs::metadata(&d) {
            Ok(m) if m.is_dir() => return check_dir_writable(&d, dir),
            Ok(_) => {
                return Err(Error::file(
                    dir,
                    format!("cannot make this directory: {} is a file", d.display()),
                ))
            }
            Err(_) => match d.parent() {
                Some(p) if !p.as_os_str().is_empty() => d = p.to_path_buf(),
                _ => return check_dir_writable(Path::new("."), dir),
            },
        }
    }
}

/// Writes `path` through `fill`; on any error the temporary file is removed and `path` is
/// left as it was. See the module notes for links, special files, `-` and inputs.
pub fn write_atomic<F>(path: &Path, fill: F) -> Result<()>
where
    F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
{
    if is_stdout(path) {
        let mut out = std::io::stdout().lock();
        return fill(&mut out)
            .and_then(|()| out.flush())
            .map_err(|e| Error::io("<standard output>", e));
    }
    let target = resolve_links(path)?;
    check_not_input(&target, &[])?;
    if let Ok(m) = std::fs::metadata(&target) {
        if m.is_dir() {
            return Err(Error::file(path, "is a directory; give a file name"));
        }
        if !m.is_file() {
            // A device or FIFO: write into it, never replace it.
            let file = std::fs::OpenOptions::new()
                .write(true)
                .open(&target)
                .map_err(|e| Error::io(path, e))?;
            let mut w = BufWriter::new(file);
            return fill(&mut w)
                .and_then(|()| w.flush())
                .map_err(|e| Error::io(path, e));
        }
    }
    let dir = parent_dir(&target);
    let name = target
        .file_name()
        .ok_or_else(|| Error::invalid(format!("{}: not a file name", path.display())))?;
    let tmp = dir.join(format!(
        ".{}.tmp-{}",
        name.to_string_lossy(),
        std::process::id()
    ));
    let result = (|| -> std::io::Result<()> {
        let file = std::fs::File::create(&tmp)?;
        let mut w = BufWriter::new(file);
        fill(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        std::fs::rename(&tmp, &target)
    })();
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, e)
    })
}
