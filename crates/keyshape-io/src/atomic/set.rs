//! The output set: every file a command writes is staged in one private folder per output
//! folder (`.kslab-staging-XXXXXX`, mode 0700) and renamed into place together, all or
//! nothing, when the command has succeeded.
//!
//! - Before the first rename every target is checked again (still no input of the
//!   command, no folder or special file planted at its name, still writable).
//! - Each file a rename replaces is kept (a hard link in the staging folder) until the last
//!   rename has succeeded; a rename that fails puts every replaced file back and removes
//!   every new one.
//! - A command that fails, or is stopped by SIGINT, SIGTERM or SIGHUP ([`abandon`]), leaves
//!   every output as it was: its staging folders and the folders it made are removed. A
//!   SIGKILL leaves at most one staging folder per output folder, named so a person knows
//!   what it is.
//! - A set belongs to the thread that opened it. Another thread's writes never join it: each
//!   is a set of its own (or of the set that thread opened), so two threads writing at once
//!   (two exports of the lab, two tests) can neither commit nor discard each other's files.
//!   A signal ([`abandon`]) discards the open sets of every thread.

use super::check::{check_not_input, parent_dir, target_of, two_outputs, OutputKey, Target};
use keyshape_core::error::{Error, Result};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::thread::ThreadId;

/// A file written but not yet in place.
struct Staged {
    /// The staged file, inside a staging folder beside its target.
    tmp: PathBuf,
    /// The file it will replace (links followed).
    target: PathBuf,
    /// The path as the user named it.
    shown: PathBuf,
    key: OutputKey,
}

/// The outputs of the open set.
#[derive(Default)]
struct Pending {
    files: Vec<Staged>,
    /// Folders made for outputs, outermost first.
    dirs: Vec<PathBuf>,
    /// (output folder, canonical, its staging folder).
    staging: Vec<(PathBuf, PathBuf)>,
    /// The output that went to standard output, if one did.
    stdout: Option<PathBuf>,
}

impl Pending {
    /// The staging folder for outputs in `dir`, made on first use.
    fn staging_for(&mut self, dir: &Path) -> std::io::Result<PathBuf> {
        let canon = std::fs::canonicalize(dir)?;
        if let Some((_, s)) = self.staging.iter().find(|(d, _)| *d == canon) {
            return Ok(s.clone());
        }
        let s = tempfile::Builder::new()
            .prefix(".kslab-staging-")
            .tempdir_in(&canon)?
            .keep();
        self.staging.push((canon, s.clone()));
        Ok(s)
    }

    /// Removes everything the set made: staging folders (with staged files and kept old
    /// files) and, when empty, the folders made for outputs.
    fn discard(self) {
        for (_, s) in &self.staging {
            let _ = std::fs::remove_dir_all(s);
        }
        for d in self.dirs.iter().rev() {
            let _ = std::fs::remove_dir(d); // only if empty
        }
    }
}

/// The open output sets, one at most per thread.
static SETS: Mutex<Vec<(ThreadId, Pending)>> = Mutex::new(Vec::new());
/// Held while a set's files are renamed into place, so that [`abandon`] (a signal) waits
/// for the renames to finish rather than cutting them in half.
static COMMIT: Mutex<()> = Mutex::new(());
/// Set by [`abandon`]: nothing more is written.
static ABANDONED: AtomicBool = AtomicBool::new(false);

fn all_sets() -> std::sync::MutexGuard<'static, Vec<(ThreadId, Pending)>> {
    match SETS.lock() {
        Ok(g) => g,
        Err(poisoned) => poisoned.into_inner(),
    }
}

/// `f` on this thread's open set (`None` when it has none); what `f` leaves in the slot
/// is this thread's set afterwards.
fn with_set<T>(f: impl FnOnce(&mut Option<Pending>) -> T) -> T {
    let me = std::thread::current().id();
    let mut sets = all_sets();
    let mut slot = sets
        .iter()
        .position(|(t, _)| *t == me)
        .map(|i| sets.swap_remove(i).1);
    let out = f(&mut slot);
    if let Some(p) = slot {
        sets.push((me, p));
    }
    out
}

fn commit_lock() -> std::sync::MutexGuard<'static, ()> {
    match COMMIT.lock() {
        Ok(g) => g,
        Err(p) => p.into_inner(),
    }
}

fn check_not_abandoned(path: &Path) -> Result<()> {
    if ABANDONED.load(Ordering::SeqCst) {
        return Err(Error::file(path, "not written: the command was stopped"));
    }
    Ok(())
}

/// Has [`abandon`] been called (a signal is ending the process)? A command whose write
/// failed for that reason leaves the exit to the signal, so its parent sees the process
/// killed by it rather than a failure of its own.
pub fn abandoned() -> bool {
    ABANDONED.load(Ordering::SeqCst)
}

/// Discards every thread's open set (staged files, staging folders and made folders), and
/// refuses every later write: for a signal handler, before the process ends. Waits for a
/// commit in progress to finish.
pub fn abandon() {
    let _g = commit_lock();
    ABANDONED.store(true, Ordering::SeqCst);
    let sets = std::mem::take(&mut *all_sets());
    for (_, p) in sets {
        p.discard();
    }
}

/// A command's outputs, made visible together: while it is open, [`super::write_atomic`]
/// stages every regular file and [`create_dir_all`] records the directories it makes.
/// [`OutputSet::commit`] renames the staged files into place; dropping the set without
/// committing removes them and the directories, leaving every output as it was.
///
/// One set is open at a time in a thread; [`OutputSet::begin`] while one is open there
/// returns a set that leaves the work to the outer one. Sets of different threads are
/// independent, and a set stays on its thread (it is not `Send`).
#[must_use = "an output set that is dropped discards what was written"]
pub struct OutputSet {
    owner: bool,
    /// Not `Send`: the set is found by the thread that opened it.
    _thread: std::marker::PhantomData<*const ()>,
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
        OutputSet {
            owner,
            _thread: std::marker::PhantomData,
        }
    }

    /// Renames every staged file over its target, all or none, and returns the targets as
    /// named by the caller.
    pub fn commit(self) -> Result<Vec<PathBuf>> {
        self.commit_with(&mut |from, to| std::fs::rename(from, to))
    }

    /// [`OutputSet::commit`] with the final renames done by `rename` (tests fail it at
    /// every position).
    #[doc(hidden)]
    pub fn commit_with(
        mut self,
        rename: &mut dyn FnMut(&Path, &Path) -> std::io::Result<()>,
    ) -> Result<Vec<PathBuf>> {
        if !self.owner {
            return Ok(Vec::new());
        }
        self.owner = false;
        let _g = commit_lock();
        let Some(pending) = with_set(|s| s.take()) else {
            return Err(Error::file(
                "<outputs>",
                "not written: the command was stopped",
            ));
        };
        if let Err(e) = check_targets(&pending.files) {
            pending.discard();
            return Err(e);
        }
        match rename_all(&pending, rename) {
            Ok(()) => {
                let shown = pending.files.iter().map(|f| f.shown.clone()).collect();
                for (_, s) in &pending.staging {
                    let _ = std::fs::remove_dir_all(s);
                }
                Ok(shown)
            }
            Err(e) => {
                pending.discard();
                Err(e)
            }
        }
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        if !self.owner {
            return;
        }
        let _g = commit_lock();
        if let Some(p) = with_set(|s| s.take()) {
            p.discard();
        }
    }
}

/// Every target checked again just before the renames: what the command read since it
/// staged a file, or what appeared at a target's name meanwhile, fails the whole set.
fn check_targets(files: &[Staged]) -> Result<()> {
    for f in files {
        check_not_input(&f.target, &f.shown, &[])?;
        match target_of(&f.target) {
            Ok(Target::File(..)) => {}
            Ok(_) => {
                return Err(Error::file(
                    &f.shown,
                    "is now standard output or a device: not replaced",
                ))
            }
            Err(e) => return Err(e),
        }
        let dir = parent_dir(&f.target);
        if !std::fs::metadata(&dir).is_ok_and(|m| m.is_dir()) {
            return Err(Error::file(
                &f.shown,
                format!("its folder {} is gone", dir.display()),
            ));
        }
    }
    Ok(())
}

/// The renames: each replaced file kept as a hard link in its staging folder until all
/// have succeeded; on a failure everything done is undone.
fn rename_all(
    pending: &Pending,
    rename: &mut dyn FnMut(&Path, &Path) -> std::io::Result<()>,
) -> Result<()> {
    // (target, kept old file or None when the target is new)
    let mut done: Vec<(&Path, Option<PathBuf>)> = Vec::with_capacity(pending.files.len());
    for (i, f) in pending.files.iter().enumerate() {
        let kept = match keep_old(f, i) {
            Ok(k) => k,
            Err(e) => {
                undo(&done);
                return Err(Error::io(&f.shown, e));
            }
        };
        if let Err(e) = rename(&f.tmp, &f.target) {
            if let Some(k) = &kept {
                // The target may have been moved aside (no hard links here): put it back.
                let _ = std::fs::rename(k, &f.target);
            }
            undo(&done);
            return Err(Error::io(&f.shown, e));
        }
        done.push((&f.target, kept));
    }
    Ok(())
}

/// Keeps the file `f` will replace: a hard link beside the staged file, or, where the file
/// system has none, the file itself moved there.
fn keep_old(f: &Staged, i: usize) -> std::io::Result<Option<PathBuf>> {
    if std::fs::symlink_metadata(&f.target).is_err() {
        return Ok(None);
    }
    let kept = parent_dir(&f.tmp).join(format!("old-{i:04}"));
    if std::fs::hard_link(&f.target, &kept).is_err() {
        std::fs::rename(&f.target, &kept)?;
    }
    Ok(Some(kept))
}

/// Puts back every replaced file and removes every new one, last first.
fn undo(done: &[(&Path, Option<PathBuf>)]) {
    for (target, kept) in done.iter().rev() {
        match kept {
            Some(k) => {
                let _ = std::fs::rename(k, target);
            }
            None => {
                let _ = std::fs::remove_file(target);
            }
        }
    }
}

/// `std::fs::create_dir_all` that records, inside an open [`OutputSet`], the directories it
/// made, so that a failed command removes them again.
pub fn create_dir_all(dir: &Path) -> Result<()> {
    check_not_abandoned(dir)?;
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

/// Claims standard output for the output `shown` in the open set: a second output to the
/// same stream is refused.
/// Claims standard output for `shown` in this thread's open set (a path spelling it, or a
/// flag such as `--json` that prints there): a second claim, by a file written to `-` or
/// `/dev/stdout` or by [`check_stdout_free`], is refused — two outputs in one stream. Without
/// an open set there is nothing to claim.
pub fn claim_stdout(shown: &Path) -> Result<()> {
    check_not_abandoned(shown)?;
    with_set(|s| match s {
        Some(p) => match &p.stdout {
            Some(first) => Err(two_outputs(first, shown)),
            None => {
                p.stdout = Some(shown.to_path_buf());
                Ok(())
            }
        },
        None => Ok(()),
    })
}

/// Errors when standard output is claimed already ([`claim_stdout`]): for the checks made
/// before any work, so `--png - --json` fails before the picture is drawn.
pub fn check_stdout_free(shown: &Path) -> Result<()> {
    with_set(|s| match s.as_ref().and_then(|p| p.stdout.as_ref()) {
        Some(first) => Err(two_outputs(first, shown)),
        None => Ok(()),
    })
}

/// Stages `fill`'s bytes for the regular file `target` (`old`: the file it replaces) in the
/// open set, which must exist.
pub(super) fn stage<F>(
    shown: &Path,
    target: PathBuf,
    old: Option<&std::fs::Metadata>,
    fill: F,
) -> Result<()>
where
    F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
{
    check_not_abandoned(shown)?;
    let key = OutputKey::of(&target);
    let dir = parent_dir(&target);
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = with_set(|s| -> Result<PathBuf> {
        let p = s
            .as_mut()
            .ok_or_else(|| Error::file(shown, "no output set is open"))?;
        if let Some(first) = p.files.iter().find(|f| f.key.same(&key)) {
            return Err(two_outputs(&first.shown, shown));
        }
        let staging = p.staging_for(&dir).map_err(|e| Error::io(shown, e))?;
        Ok(staging.join(format!("{:04}-{name}", p.files.len())))
    })?;
    write_new(&tmp, old, fill).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(shown, e)
    })?;
    with_set(|s| match s {
        Some(p) => {
            p.files.push(Staged {
                tmp,
                target,
                shown: shown.to_path_buf(),
                key,
            });
            Ok(())
        }
        None => {
            // Abandoned meanwhile: the staging folder is gone with the file.
            Err(Error::file(shown, "not written: the command was stopped"))
        }
    })
}

/// Writes a new file `path` through `fill` and syncs it. It takes the permission bits of the
/// file it will replace (`old`) less setuid, setgid and sticky, or those a new file gets.
fn write_new<F>(path: &Path, old: Option<&std::fs::Metadata>, fill: F) -> std::io::Result<()>
where
    F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
{
    let mut o = std::fs::OpenOptions::new();
    o.write(true).create_new(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        // A new file: 0666 less the umask, as File::create makes it.
        o.mode(0o666);
    }
    let file = o.open(path)?;
    #[cfg(unix)]
    if let Some(m) = old {
        use std::os::unix::fs::PermissionsExt;
        // The replaced file's bits, which the umask may have narrowed above; never its
        // setuid or setgid bit (a CSV must not become a setuid program).
        let bits = m.permissions().mode() & 0o777;
        file.set_permissions(std::fs::Permissions::from_mode(bits))?;
    }
    #[cfg(not(unix))]
    let _ = old;
    let mut w = BufWriter::new(file);
    fill(&mut w)?;
    let file = w.into_inner().map_err(|e| e.into_error())?;
    file.sync_all()
}
