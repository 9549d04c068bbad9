//! Output that never loses data.
//!
//! - A regular file is written into a private staging folder beside it and renamed over it,
//!   so a failed run never leaves a half-written file and an old file survives a failure.
//!   The replaced file's permission bits carry over to the new one, less setuid and setgid.
//! - Inside an [`OutputSet`] (the command line opens one per command) every file is staged
//!   and nothing is renamed until [`OutputSet::commit`], which renames all or none: a
//!   command that fails anywhere, or is stopped by a signal ([`abandon`]), leaves every
//!   output as it was before it started, and directories it made are removed again. Two
//!   outputs of one set that are one file (however spelled: `./w.csv`, a symbolic or a
//!   hard link) or one stream (`-`, `/dev/stdout`) are refused.
//! - A symbolic link is followed: the file it names is replaced (atomically, in *that*
//!   file's directory); the link stays a link. In a shared sticky folder (`/tmp`) a link is
//!   followed only when it belongs to the user or the folder's owner, as the kernel's
//!   protected-symlinks rule says.
//! - `-` and any other name of standard output write to standard output, refused when it
//!   was closed; `/dev/null` takes what it is given. Every other special file (a FIFO, a
//!   socket, a device) is refused before any work, and so is a file with no write bit.
//! - A file this process reads as input is never written: every reader goes through
//!   [`crate::read_text`] or [`register_input`] (a folder registers every file in it), and
//!   an output that is an input is refused when staged and again just before the renames.
//!
//! [`check_output`] and [`check_output_dir`] run the same checks before any work is done,
//! so a command that cannot write one of its outputs fails before writing the others.

mod check;
mod set;

pub use check::{
    check_distinct, check_input_path, check_output, check_output_dir, file_id, is_stdout,
    register_input, FileId,
};
pub use set::{abandon, abandoned, check_stdout_free, claim_stdout, create_dir_all, OutputSet};

use check::{check_not_input, target_of, Target};
use keyshape_core::error::{Error, Result};
use std::io::{BufWriter, Write};
use std::path::Path;

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

/// Writes `path` through `fill`; on any error nothing is left behind and `path` is as it
/// was. Inside an open [`OutputSet`] the file is only staged. See the module notes for
/// links, special files, standard output and inputs.
pub fn write_atomic<F>(path: &Path, fill: F) -> Result<()>
where
    F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
{
    match target_of(path)? {
        Target::Stdout => {
            if stdout_closed() {
                return Err(Error::file(
                    "<standard output>",
                    "standard output is closed: the data would be lost (give a file)",
                ));
            }
            set::claim_stdout(path)?;
            let mut out = std::io::stdout().lock();
            fill(&mut out)
                .and_then(|()| out.flush())
                .map_err(|e| Error::io("writing to standard output", e))
        }
        Target::Null => {
            let file = std::fs::OpenOptions::new()
                .write(true)
                .open("/dev/null")
                .map_err(|e| Error::io(path, e))?;
            let mut w = BufWriter::new(file);
            fill(&mut w)
                .and_then(|()| w.flush())
                .map_err(|e| Error::io(path, e))
        }
        Target::File(target, old) => {
            check_not_input(&target, path, &[])?;
            // A write outside a set is a set of one.
            let own = OutputSet::begin();
            set::stage(path, target, old.as_ref(), fill)?;
            own.commit().map(drop)
        }
    }
}
