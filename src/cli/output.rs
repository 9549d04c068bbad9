//! What `kslab` writes and prints around the commands: outputs checked before any work,
//! standard output as an output, and errors with the library's settings spelled as flags.

use keyshape_core::error::Needed;
use std::path::{Path, PathBuf};

/// Is this output path standard output (`-`)?
pub(crate) fn is_stdout(p: Option<&PathBuf>) -> bool {
    p.is_some_and(|p| keyshape_io::atomic::is_stdout(p))
}

/// Refuses `--json` when `--out -` already sends the data to standard output.
pub(crate) fn check_json_stdout(json: bool, out: Option<&PathBuf>) -> anyhow::Result<()> {
    if json && is_stdout(out) {
        anyhow::bail!("--json and --out - would both write to standard output: give --out a file");
    }
    Ok(())
}

/// Checks every output a command will write before it does any work: each file's directory
/// takes new files, each directory can be made, no output is an input (`inputs`, files or
/// folders whose every file counts, or any file already read) and no two outputs name the
/// same file or stream. A command that cannot write one of
/// its outputs then fails before writing any.
pub(crate) fn check_outputs(
    files: &[Option<&PathBuf>],
    dirs: &[Option<&PathBuf>],
    inputs: &[Option<&Path>],
) -> anyhow::Result<()> {
    let inputs: Vec<&Path> = inputs.iter().flatten().copied().collect();
    // Registered, a folder with every file in it: the final renames check them again.
    for i in &inputs {
        keyshape_io::atomic::register_input(i)?;
    }
    let outputs: Vec<&Path> = files.iter().flatten().map(|f| f.as_path()).collect();
    for f in &outputs {
        keyshape_io::check_output(f, &inputs)?;
        if keyshape_io::atomic::is_stdout(f) {
            // Claimed by `--json` (or another output) already?
            keyshape_io::atomic::check_stdout_free(f)?;
        }
    }
    keyshape_io::atomic::check_distinct(&outputs)?;
    for d in dirs.iter().flatten() {
        keyshape_io::check_output_dir(d)?;
    }
    Ok(())
}

/// What the command says it wrote, held until its output set is committed ([`said_wrote`]):
/// "wrote X" printed before the commit was said of files that a later failure discarded.
static WROTE: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());

/// Notes that the command wrote `what` (said once its outputs are in place).
pub(crate) fn wrote(what: String) {
    WROTE.lock().unwrap_or_else(|p| p.into_inner()).push(what);
}

/// Says what the command wrote: after a successful commit only.
pub(crate) fn said_wrote() {
    for w in std::mem::take(&mut *WROTE.lock().unwrap_or_else(|p| p.into_inner())) {
        errln!("wrote {w}");
    }
}

/// Did this error come from writing into a pipe whose reader has gone?
pub(crate) fn broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
            || matches!(
                c.downcast_ref::<keyshape_core::Error>(),
                Some(keyshape_core::Error::Io { err, .. }) if err.kind() == std::io::ErrorKind::BrokenPipe
            )
    })
}

/// An error chain as `{:#}` prints it (`outer: inner`), each library error's settings
/// ([`keyshape_core::error::setting`]) spelled by `spell`, and what a library error needs
/// ([`keyshape_core::error::Needed`]) followed by the command that makes it.
pub(crate) fn render_error(e: &anyhow::Error, spell: &dyn Fn(&str) -> String) -> String {
    e.chain()
        .map(|c| match c.downcast_ref::<keyshape_core::Error>() {
            Some(k) => match k.needed() {
                Some(n) => format!("{}{}", k.render(spell), how_to_make(n)),
                None => k.render(spell),
            },
            None => c.to_string(),
        })
        .collect::<Vec<_>>()
        .join(": ")
}

/// The command that makes what a library error needs, as the end of its sentence. The
/// library says what is missing; only the front end knows its commands.
fn how_to_make(needed: &Needed) -> String {
    match needed {
        Needed::ActionsFor(track) => {
            format!(" with `kslab actions {} --out FILE`", track.display())
        }
        Needed::Template => "; `kslab template` writes one".to_string(),
        Needed::ShardReports => "; `kslab run EXPERIMENT --shard i/n` writes one".to_string(),
        Needed::ContiguousArray { tasks } => {
            format!(", such as `sbatch --array=0-{}`", tasks.saturating_sub(1))
        }
        // A kind added to the library later: its message says what is missing.
        _ => String::new(),
    }
}

/// A library setting as the command line spells it: `dims` → `--dims`, `smooth_mode` →
/// `--smooth-mode`, `no_align` → `--no-align`.
pub(crate) fn spell_flag(name: &str) -> String {
    format!("--{}", name.replace('_', "-"))
}

/// A library setting as an experiment file spells it: its key (`dims`, `points`, `modes`),
/// `align = false` for `no_align`; `--shard` stays the flag of `kslab run`.
pub(crate) fn spell_experiment_key(name: &str) -> String {
    match name {
        "no_align" => "align = false".to_string(),
        "shard" => spell_flag(name),
        _ => name.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::{render_error, spell_experiment_key, spell_flag};
    use keyshape_core::error::{setting, Error, Needed};

    #[test]
    fn settings_are_spelled_as_flags_or_as_experiment_keys() {
        assert_eq!(spell_flag("dims"), "--dims");
        assert_eq!(spell_flag("smooth_mode"), "--smooth-mode");
        assert_eq!(spell_flag("no_align"), "--no-align");
        assert_eq!(spell_experiment_key("dims"), "dims");
        assert_eq!(spell_experiment_key("no_align"), "align = false");
        assert_eq!(spell_experiment_key("shard"), "--shard");
    }

    #[test]
    fn a_chain_prints_as_its_alternate_display_with_settings_spelled() {
        let inner = Error::invalid(format!("use {} 2", setting("dims")));
        let e = anyhow::Error::from(inner).context("reading t.csv");
        assert_eq!(render_error(&e, &spell_flag), "reading t.csv: use --dims 2");
        assert_eq!(format!("{e:#}"), "reading t.csv: use dims 2");
        let plain = anyhow::anyhow!("no setting here").context("outer");
        assert_eq!(render_error(&plain, &spell_flag), format!("{plain:#}"));
    }

    /// The library names what is missing; the command line adds the command that makes it,
    /// and only there.
    #[test]
    fn what_an_error_needs_is_followed_by_the_command_that_makes_it() {
        let e = Error::needs_in(
            "a.json",
            Needed::ActionsFor("d6.csv".into()),
            "chosen on d9.csv; choose this track's",
        );
        assert!(!e.to_string().contains("kslab"));
        let chain = anyhow::Error::from(e);
        assert_eq!(
            render_error(&chain, &spell_flag),
            "a.json: chosen on d9.csv; choose this track's with `kslab actions d6.csv --out FILE`"
        );
        let e = anyhow::Error::from(Error::needs(Needed::ContiguousArray { tasks: 4 }, "gaps"));
        assert_eq!(
            render_error(&e, &spell_flag),
            "gaps, such as `sbatch --array=0-3`"
        );
        for n in [Needed::Template, Needed::ShardReports] {
            let e = anyhow::Error::from(Error::needs(n, "missing"));
            assert!(render_error(&e, &spell_flag).contains("`kslab "));
        }
    }
}
