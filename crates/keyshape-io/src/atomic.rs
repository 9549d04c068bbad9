//! Output that never loses data.
//!
//! - A regular file is written to a temporary file beside it and renamed over it, so a failed
//!   run never leaves a half-written file and an old file survives a failure. The temporary
//!   is created exclusively under an unpredictable name (`O_EXCL`, never through a link a
//!   third party planted), and the replaced file's permission bits carry over to the new one.
//! - Inside an [`OutputSet`] (the command line opens one per command) every file is staged
//!   and nothing is renamed until [`OutputSet::commit`]: a command that fails anywhere leaves
//!   every output as it was before it started, and directories it made are removed again.
//!   Two outputs of one set that are one file (however spelled: `./w.csv`, a symbolic or a
//!   hard link) are refused.
//! - A symbolic link is followed: the file it names is replaced (atomically, in *that* file's
//!   directory); the link stays a link.
//! - A special file (a device such as `/dev/null`, a FIFO) is written directly, never
//!   replaced; `-` is standard output, refused when standard output was closed.
//! - A file this process has read as input is never written: every reader goes through
//!   [`crate::read_text`], which records what it read, and [`write_atomic`] refuses a
//!   destination that is the same file (same device and inode, or same canonical path).
//!
//! [`check_output`] and [`check_output_dir`] run the same checks before any work is done,
//! so a command that cannot write one of its outputs fails before writing the others.

use keyshape_core::error::{Error, Result};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Identity of a file: (device, inode) on Unix, else its canonical path. Two names of one
/// file (`p.csv` and `./p.csv`, a symbolic or a hard link) have the same identity.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum FileId {
    /// Device and inode.
    #[cfg(unix)]
    Inode(u64, u64),
    /// Canonical path.
    #[cfg(not(unix))]
    Path(PathBuf),
}

/// The identity of the file `path` names (links followed), if it exists.
pub fn file_id(path: &Path) -> Option<FileId> {
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

/// What identifies an output: the file it finally names (links followed, the directory
/// canonicalised) and, when it exists, its device and inode (which also catch hard links).
#[derive(Debug, Clone)]
struct OutputKey {
    path: PathBuf,
    id: Option<FileId>,
}

impl OutputKey {
    fn of(target: &Path) -> OutputKey {
        let dir = parent_dir(target);
        let dir = std::fs::canonicalize(&dir).unwrap_or(dir);
        let path = match target.file_name() {
            Some(n) => dir.join(n),
            None => target.to_path_buf(),
        };
        OutputKey {
            path,
            id: file_id(target),
        }
    }

    fn same(&self, other: &OutputKey) -> bool {
        self.path == other.path || (self.id.is_some() && self.id == other.id)
    }
}

/// Errors when two of `paths` name one file, however spelled (`w.csv` and `./w.csv`, a
/// symbolic or a hard link). `-` (standard output) is left to the caller.
pub fn check_distinct(paths: &[&Path]) -> Result<()> {
    let mut seen: Vec<(OutputKey, &Path)> = Vec::new();
    for &p in paths {
        if is_stdout(p) {
            continue;
        }
        let key = OutputKey::of(&resolve_links(p)?);
        if let Some((_, first)) = seen.iter().find(|(k, _)| k.same(&key)) {
            return Err(two_outputs(first, p));
        }
        seen.push((key, p));
    }
    Ok(())
}

fn two_outputs(first: &Path, second: &Path) -> Error {
    if first == second {
        Error::file(second, "named as two outputs")
    } else {
        Error::file(
            second,
            format!(
                "named as two outputs: this is the same file as {} (one output would overwrite the other)",
                first.display()
            ),
        )
    }
}

/// A file written but not yet in place.
struct Staged {
    tmp: tempfile::TempPath,
    target: PathBuf,
    shown: PathBuf,
    key: OutputKey,
}

/// The outputs of the open set: staged files, and directories made for them.
#[derive(Default)]
struct Pending {
    files: Vec<Staged>,
    dirs: Vec<PathBuf>,
}

/// The open output set, if any.
static SET: Mutex<Option<Pending>> = Mutex::new(None);

fn with_set<T>(f: impl FnOnce(&mut Option<Pending>) -> T) -> T {
    match SET.lock() {
        Ok(mut g) => f(&mut g),
        Err(poisoned) => f(&mut poisoned.into_inner()),
    }
}

/// A command's outputs, made visible together: while it is open, [`write_atomic`] stages
/// every regular file and [`create_dir_all`] records the directories it makes.
/// [`OutputSet::commit`] renames the staged files into place; dropping the set without
/// committing removes them and the directories, leaving every output as it was.
///
/// One set is open at a time; [`OutputSet::begin`] while one is open returns a set that
/// leaves the work to the outer one.
#[must_use = "an output set that is dropped discards what was written"]
pub struct OutputSet {
    owner: bool,
}

impl OutputSet {
    /// Opens the set.
    pub fn begin() -> OutputSet {
        let owner = with_set(|s| {
            if s.is_some() {
                false
            } else {
                *s = Some(Pending::default());
                true
            }
        });
        OutputSet { owner }
    }

    /// Renames every staged file over its target and returns the targets as named by the
    /// caller. On an error the files not yet renamed are removed.
    pub fn commit(mut self) -> Result<Vec<PathBuf>> {
        if !self.owner {
            return Ok(Vec::new());
        }
        self.owner = false;
        let pending = with_set(|s| s.take()).unwrap_or_default();
        let mut done = Vec::with_capacity(pending.files.len());
        for f in pending.files {
            f.tmp
                .persist(&f.target)
                .map_err(|e| Error::io(&f.shown, e.error))?;
            done.push(f.shown);
        }
        Ok(done)
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        if !self.owner {
            return;
        }
        if let Some(p) = with_set(|s| s.take()) {
            drop(p.files); // each TempPath removes its file
            for d in p.dirs.iter().rev() {
                let _ = std::fs::remove_dir(d); // only if empty
            }
        }
    }
}

/// `std::fs::create_dir_all` that records, inside an open [`OutputSet`], the directories it
/// made, so that a failed command removes them again.
pub fn create_dir_all(dir: &Path) -> Result<()> {
    let mut missing = Vec::new();
    let mut d = dir;
    while !d.as_os_str().is_empty() && std::fs::symlink_metadata(d).is_err() {
        missing.push(d.to_path_buf());
        match d.parent() {
            Some(p) => d = p,
            None => break,
        }
    }
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    missing.reverse(); // outermost first
    with_set(|s| {
        if let Some(p) = s {
            p.dirs.extend(missing);
        }
    });
    Ok(())
}

/// Is standard output usable? A process started with it closed (`>&-`) has it reopened on
/// `/dev/null` read-write by the Rust runtime, where every write would vanish; a shell's
/// `> /dev/null` opens it write-only.
fn stdout_closed() -> bool {
    #[cfg(target_os = "linux")]
    {
        let null = std::fs::read_link("/proc/self/fd/1")
            .map(|l| l == Path::new("/dev/null"))
            .unwrap_or(false);
        // SAFETY: fcntl(F_GETFL) on a descriptor only reads its flags; an invalid one
        // returns -1.
        #[allow(unsafe_code)]
        let flags = unsafe { libc::fcntl(1, libc::F_GETFL) };
        flags == -1 || (null && flags & libc::O_ACCMODE == libc::O_RDWR)
    }
    #[cfg(not(target_os = "linux"))]
    {
        false
    }
}

/// Writes `path` through `fill`; on any error the temporary file is removed and `path` is
/// left as it was. Inside an open [`OutputSet`] the file is only staged. See the module
/// notes for links, special files, `-` and inputs.
pub fn write_atomic<F>(path: &Path, fill: F) -> Result<()>
where
    F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
{
    if is_stdout(path) {
        if stdout_closed() {
            return Err(Error::file(
                "<standard output>",
                "standard output is closed: the data would be lost (give a file)",
            ));
        }
        let mut out = std::io::stdout().lock();
        return fill(&mut out)
            .and_then(|()| out.flush())
            .map_err(|e| Error::io("<standard output>", e));
    }
    let target = resolve_links(path)?;
    check_not_input(&target, &[])?;
    let old = std::fs::metadata(&target).ok();
    if let Some(m) = &old {
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
    let key = OutputKey::of(&target);
    let clash = with_set(|s| {
        s.as_ref().and_then(|p| {
            p.files
                .iter()
                .find(|f| f.key.same(&key))
                .map(|f| f.shown.clone())
        })
    });
    if let Some(first) = clash {
        return Err(two_outputs(&first, path));
    }
    let tmp = stage(&target, old.as_ref(), fill).map_err(|e| Error::io(path, e))?;
    let staged = Staged {
        tmp,
        target,
        shown: path.to_path_buf(),
        key,
    };
    let leftover = with_set(|s| match s {
        Some(p) => {
            p.files.push(staged);
            None
        }
        None => Some(staged),
    });
    if let Some(f) = leftover {
        f.tmp
            .persist(&f.target)
            .map_err(|e| Error::io(path, e.error))?;
    }
    Ok(())
}

/// Writes a new temporary file beside `target` through `fill` and syncs it. It takes the
/// permission bits of the file it will replace (`old`), or those a new file would get.
fn stage<F>(
    target: &Path,
    old: Option<&std::fs::Metadata>,
    fill: F,
) -> std::io::Result<tempfile::TempPath>
where
    F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
{
    let dir = parent_dir(target);
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let prefix = format!(".{name}.");
    let mut b = tempfile::Builder::new();
    b.prefix(&prefix).suffix(".tmp");
    #[cfg(unix)]
    let perm = {
        use std::os::unix::fs::PermissionsExt;
        // A new file: 0666 less the umask, as File::create makes it.
        old.map(|m| m.permissions())
            .unwrap_or_else(|| std::fs::Permissions::from_mode(0o666))
    };
    #[cfg(unix)]
    b.permissions(perm.clone());
    let file = b.tempfile_in(&dir)?;
    #[cfg(unix)]
    if old.is_some() {
        // The exact bits of the replaced file, which the umask may have narrowed above.
        file.as_file().set_permissions(perm)?;
    }
    #[cfg(not(unix))]
    let _ = old;
    let (file, tmp) = file.into_parts();
    let mut w = BufWriter::new(file);
    fill(&mut w)?;
    let file = w.into_inner().map_err(|e| e.into_error())?;
    file.sync_all()?;
    Ok(tmp)
}
