//! What an output path may be, decided once for every writer: the file it finally names
//! (links followed under the kernel's protected-symlinks rule), standard output however
//! spelled, `/dev/null`, or a refusal naming the path and the reason; and whether it is a
//! file this process reads.

use keyshape_core::error::{Error, Result};
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

fn inputs_registered() -> Vec<(FileId, PathBuf)> {
    match INPUTS.lock() {
        Ok(v) => v.clone(),
        Err(p) => p.into_inner().clone(),
    }
}

/// The files an input path stands for: itself, and when it is a folder (a rig, a morph
/// folder, a folder of `.pts` files) every file directly inside it.
fn input_files(path: &Path) -> Vec<(FileId, PathBuf)> {
    let mut out: Vec<(FileId, PathBuf)> = file_id(path)
        .map(|id| (id, path.to_path_buf()))
        .into_iter()
        .collect();
    if std::fs::metadata(path).is_ok_and(|m| m.is_dir()) {
        if let Ok(rd) = std::fs::read_dir(path) {
            for e in rd.flatten() {
                let p = e.path();
                if let Some(id) = file_id(&p) {
                    out.push((id, p));
                }
            }
        }
    }
    out
}

/// Records `path` as an input: no output of this process may overwrite it. A folder
/// records every file directly inside it too (a command that reads a rig folder must not
/// replace any file of the rig, read or not).
///
/// When standard output is a regular file it is an output too: an input that is that file
/// (`kslab solve in.csv >> in.csv`, `1<> in.csv`) is refused here, when it is read, before
/// anything is written to it.
pub fn register_input(path: &Path) -> Result<()> {
    let files = input_files(path);
    if let Some(out) = stdout_file() {
        if let Some((_, p)) = files.iter().find(|(id, _)| *id == out) {
            return Err(Error::file(
                p,
                "is also standard output (a `>` or `>>` names this input): writing would overwrite it or append to it; send standard output to another file",
            ));
        }
    }
    let mut v = match INPUTS.lock() {
        Ok(v) => v,
        Err(p) => p.into_inner(),
    };
    for (id, p) in files {
        // An entry of this identity whose path names another file now is one a deleted
        // input left (its inode number reused): this file replaces it.
        v.retain(|(i, q)| *i != id || file_id(q).as_ref() == Some(i));
        if !v.iter().any(|(i, _)| *i == id) {
            v.push((id, p));
        }
    }
    Ok(())
}

/// The identity of standard output when it is a regular file (not a terminal, a pipe or
/// `/dev/null`).
fn stdout_file() -> Option<FileId> {
    #[cfg(target_os = "linux")]
    let p = Path::new("/proc/self/fd/1");
    #[cfg(not(target_os = "linux"))]
    let p = Path::new("/dev/stdout");
    std::fs::metadata(p)
        .ok()
        .filter(std::fs::Metadata::is_file)
        .and_then(|_| file_id(p))
}

/// Errors when `target` (a resolved output path) is a file registered as input or one of
/// `inputs` (files or folders); `shown` is the path as the user gave it.
///
/// A registered input counts while its path still names it. An input deleted since (or
/// replaced by a rename) has freed its inode number, which the file system gives to the
/// next new file: in the lab, which runs for hours, an export could otherwise be refused
/// as "the input file" it replaced.
pub(super) fn check_not_input(target: &Path, shown: &Path, inputs: &[&Path]) -> Result<()> {
    let Some(id) = file_id(target) else {
        return Ok(());
    };
    let given = inputs.iter().flat_map(|p| input_files(p));
    for (i, input) in inputs_registered().into_iter().chain(given) {
        if i == id && file_id(&input).as_ref() == Some(&id) {
            return Err(Error::file(
                shown,
                format!(
                    "refusing to write: this is the input file {} (inputs are never overwritten; choose another output path)",
                    input.display()
                ),
            ));
        }
    }
    Ok(())
}

/// The folder a path lies in (`.` for a bare name).
pub(super) fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Refuses to follow the link `link` when the kernel's protected-symlinks rule would: in a
/// sticky, world-writable folder (`/tmp`), a link is followed only when its owner is the
/// user or the folder's owner. The rule is applied here because links are resolved in user
/// space, where the kernel never sees them.
#[cfg(unix)]
fn check_link_owner(link: &Path, meta: &std::fs::Metadata) -> Result<()> {
    use std::os::unix::fs::MetadataExt;
    let dir = parent_dir(link);
    let Ok(dmeta) = std::fs::metadata(&dir) else {
        return Ok(());
    };
    let sticky_shared = dmeta.mode() & 0o1002 == 0o1002;
    // SAFETY: geteuid has no preconditions and cannot fail.
    #[allow(unsafe_code)]
    let me = unsafe { libc::geteuid() };
    if sticky_shared && meta.uid() != me && meta.uid() != dmeta.uid() {
        return Err(Error::file(
            link,
            format!(
                "refusing to follow this link: it belongs to user {} in the shared sticky folder {}, where only links of yours or of the folder's owner are followed",
                meta.uid(),
                dir.display()
            ),
        ));
    }
    Ok(())
}

#[cfg(not(unix))]
fn check_link_owner(_link: &Path, _meta: &std::fs::Metadata) -> Result<()> {
    Ok(())
}

/// Refuses an input reached through a link that the protected-symlinks rule would not
/// follow (the rule every output path is resolved under): a file read is as much at stake as one written (a
/// calibration planted through another user's link).
pub fn check_input_path(path: &Path) -> Result<()> {
    resolve_links(path).map(drop)
}

/// Follows symbolic links to the path they finally name (which may not exist yet): every
/// link on the way, in any component (`sticky/dirlink/out.csv`, a link that points into
/// one), is followed under the kernel's protected-symlinks rule ([`check_link_owner`]) —
/// applied to the last component only, a link planted as a folder in `/tmp` led root's
/// output into another user's folder.
pub(super) fn resolve_links(path: &Path) -> Result<PathBuf> {
    use std::path::Component;
    // The components still to walk, the next first.
    let mut todo: Vec<std::ffi::OsString> = Vec::new();
    let mut done = PathBuf::new();
    let push_all = |todo: &mut Vec<std::ffi::OsString>, p: &Path, done: &mut PathBuf| {
        let mut parts: Vec<std::ffi::OsString> = Vec::new();
        for c in p.components() {
            match c {
                Component::RootDir => {
                    *done = PathBuf::from("/");
                    parts.clear();
                }
                Component::Prefix(pre) => {
                    *done = PathBuf::from(pre.as_os_str());
                    parts.clear();
                }
                Component::CurDir => {}
                Component::ParentDir => parts.push("..".into()),
                Component::Normal(n) => parts.push(n.to_os_string()),
            }
        }
        for part in parts.into_iter().rev() {
            todo.push(part);
        }
    };
    push_all(&mut todo, path, &mut done);
    let mut links = 0;
    while let Some(part) = todo.pop() {
        if part == ".." {
            // `done` holds no links (each was replaced by what it names): its parent is
            // the parent on disk, except above a relative start.
            if done.as_os_str().is_empty() || done.ends_with("..") || !done.pop() {
                done.push("..");
            }
            continue;
        }
        let next = done.join(&part);
        match std::fs::symlink_metadata(&next) {
            Ok(m) if m.file_type().is_symlink() => {
                links += 1;
                if links > 40 {
                    return Err(Error::file(path, "too many levels of symbolic links"));
                }
                check_link_owner(&next, &m).map_err(|e| {
                    if next.as_path() == path {
                        e
                    } else {
                        Error::file(path, format!("on the way to it: {e}"))
                    }
                })?;
                let target = std::fs::read_link(&next).map_err(|e| Error::io(&next, e))?;
                // A relative link is read from its own folder, `done`.
                push_all(&mut todo, &target, &mut done);
            }
            _ => done = next,
        }
    }
    if done.as_os_str().is_empty() {
        done.push(".");
    }
    Ok(done)
}

/// Is `path` standard output: `-`, or a name of the file standard output is (such as
/// `/dev/stdout`)? `/dev/null` is not, even when standard output goes there.
pub fn is_stdout(path: &Path) -> bool {
    if path.as_os_str() == "-" {
        return true;
    }
    let id = file_id(path);
    id.is_some() && id == stdout_id() && id != file_id(Path::new("/dev/null"))
}

/// The identity of the file standard output writes to.
fn stdout_id() -> Option<FileId> {
    #[cfg(target_os = "linux")]
    {
        file_id(Path::new("/proc/self/fd/1"))
    }
    #[cfg(not(target_os = "linux"))]
    {
        file_id(Path::new("/dev/stdout"))
    }
}

/// Where an output path leads.
#[derive(Debug)]
pub(super) enum Target {
    /// Standard output, however spelled.
    Stdout,
    /// `/dev/null`: written and discarded.
    Null,
    /// A regular file to be replaced atomically (or made): the path links lead to, and
    /// the replaced file's metadata.
    File(PathBuf, Option<std::fs::Metadata>),
}

/// Decides where `path` leads, refusing what kslab must never write: a folder, a FIFO, a
/// socket or a device (other than `/dev/null` and standard output), a file with no write
/// bit, a link planted by another user in a shared sticky folder.
pub(super) fn target_of(path: &Path) -> Result<Target> {
    if is_stdout(path) {
        return Ok(Target::Stdout);
    }
    let target = resolve_links(path)?;
    let meta = match std::fs::metadata(&target) {
        Ok(m) => m,
        Err(_) => return Ok(Target::File(target, None)),
    };
    if meta.is_dir() {
        return Err(Error::file(path, "is a directory; give a file name"));
    }
    if !meta.is_file() {
        if file_id(&target) == file_id(Path::new("/dev/null")) {
            return Ok(Target::Null);
        }
        return Err(Error::file(
            path,
            format!(
                "is {}: kslab writes regular files, /dev/null or standard output (-), never into this (it could block or reach hardware)",
                special_kind(&meta)
            ),
        ));
    }
    check_writable(path, &meta)?;
    Ok(Target::File(target, Some(meta)))
}

fn special_kind(meta: &std::fs::Metadata) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let t = meta.file_type();
        if t.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if t.is_socket() {
            return "a socket";
        }
        if t.is_char_device() || t.is_block_device() {
            return "a device";
        }
    }
    let _ = meta;
    "not a regular file"
}

/// Refuses to replace a file that its permissions keep from being written (a 0444 file):
/// replacing it through a rename would ignore what its owner said.
fn check_writable(path: &Path, meta: &std::fs::Metadata) -> Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        let mode = meta.mode();
        // SAFETY: geteuid and getegid have no preconditions and cannot fail.
        #[allow(unsafe_code)]
        let (uid, gid) = unsafe { (libc::geteuid(), libc::getegid()) };
        let writable = if uid == 0 {
            mode & 0o222 != 0
        } else if meta.uid() == uid {
            mode & 0o200 != 0
        } else if meta.gid() == gid {
            mode & 0o020 != 0
        } else {
            mode & 0o002 != 0
        };
        if !writable {
            return Err(Error::file(
                path,
                format!(
                    "refusing to replace a read-only file (mode {:o}): make it writable or choose another output path",
                    mode & 0o7777
                ),
            ));
        }
    }
    #[cfg(not(unix))]
    if meta.permissions().readonly() {
        return Err(Error::file(
            path,
            "refusing to replace a read-only file: make it writable or choose another output path",
        ));
    }
    Ok(())
}

/// Can a file be created in `dir`? Tried for real with a probe file, removed at once.
pub(super) fn check_dir_writable(dir: &Path, what: &Path) -> Result<()> {
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
/// `inputs` (files or folders, nor a file already read): see the module notes for what is
/// refused, and its directory must take new files.
pub fn check_output(path: &Path, inputs: &[&Path]) -> Result<()> {
    match target_of(path)? {
        Target::Stdout | Target::Null => Ok(()),
        Target::File(target, _) => {
            check_not_input(&target, path, inputs)?;
            check_dir_writable(&parent_dir(&target), path)
        }
    }
}

/// Checks, before any work, that `dir` can hold output files: it is a directory that takes
/// new files, or it does not exist yet and its nearest existing ancestor does.
pub fn check_output_dir(dir: &Path) -> Result<()> {
    // Links on the way are followed under the protected-symlinks rule.
    let mut d = resolve_links(dir)?;
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
/// Standard output is one key however it is spelled.
#[derive(Debug, Clone)]
pub(super) struct OutputKey {
    path: PathBuf,
    id: Option<FileId>,
}

impl OutputKey {
    /// The key of a resolved target path.
    pub(super) fn of(target: &Path) -> OutputKey {
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

    /// The key of standard output.
    pub(super) fn stdout() -> OutputKey {
        OutputKey {
            path: PathBuf::from("-"),
            id: None,
        }
    }

    pub(super) fn same(&self, other: &OutputKey) -> bool {
        self.path == other.path || (self.id.is_some() && self.id == other.id)
    }
}

/// Errors when two of `paths` name one file, however spelled (`w.csv` and `./w.csv`, a
/// symbolic or a hard link), or two send their bytes to standard output (`-`,
/// `/dev/stdout`): the two would be concatenated. `/dev/null` may take any number.
pub fn check_distinct(paths: &[&Path]) -> Result<()> {
    let mut seen: Vec<(OutputKey, &Path)> = Vec::new();
    for &p in paths {
        let key = match target_of(p)? {
            Target::Stdout => OutputKey::stdout(),
            Target::Null => continue,
            Target::File(t, _) => OutputKey::of(&t),
        };
        if let Some((_, first)) = seen.iter().find(|(k, _)| k.same(&key)) {
            return Err(two_outputs(first, p));
        }
        seen.push((key, p));
    }
    Ok(())
}

/// The error for two outputs that are one file or one stream.
pub(super) fn two_outputs(first: &Path, second: &Path) -> Error {
    if first.to_string_lossy().starts_with("--") {
        // A flag that prints to standard output (`--json`).
        return Error::file(
            second,
            format!(
                "named as an output on standard output, where {} prints: their bytes would be mixed in one stream (give a file)",
                first.display()
            ),
        );
    }
    if first == second && is_stdout(first) {
        Error::file(
            second,
            "named as two outputs: both would go to standard output, their bytes mixed in one stream",
        )
    } else if is_stdout(first) && is_stdout(second) {
        Error::file(
            second,
            format!(
                "named as two outputs: this is standard output, like {} (their bytes would be mixed in one stream)",
                first.display()
            ),
        )
    } else if first == second {
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

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// An input deleted after it was read may hand its inode number to a new file: that new
    /// file is not the input. (Made deterministic: the registry is given the entry a reused
    /// inode leaves, another file's identity under the input's old path.)
    #[test]
    fn an_input_s_identity_counts_only_while_its_path_still_names_it() {
        let tmp = tempfile::tempdir().unwrap();
        let (input, output) = (tmp.path().join("in.csv"), tmp.path().join("out.csv"));
        std::fs::write(&input, "read").unwrap();
        std::fs::write(&output, "old export").unwrap();
        let reused = file_id(&output).unwrap();
        INPUTS
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .push((reused, input.clone()));
        check_not_input(&output, &output, &[]).unwrap();
        // Read now, the file is an input: the stale entry does not hide it.
        register_input(&output).unwrap();
        let e = check_not_input(&output, &output, &[]).unwrap_err();
        assert!(e.to_string().contains("this is the input file"), "{e}");
    }
}
