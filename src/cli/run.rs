//! `kslab run`: a scripted experiment, headless; `kslab merge`: a sharded corpus' parts
//! combined into its report.

use super::progress::Progress;
use anyhow::{bail, Result};
use clap::Args;
use keyshape_experiments::experiment::corpus::{self, Shard};
use keyshape_experiments::experiment::{run as run_spec, Spec};
use keyshape_experiments::report::corpus::write_corpus;
use keyshape_experiments::report::write_outcome;
use std::path::PathBuf;

/// Arguments of `kslab run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// The experiment file (TOML; see experiments/ and docs/src/keyshapes.md, "Scripted experiments").
    spec: PathBuf,
    /// Output folder (default: `out/<spec name>/`, and `out/<spec name>/shard-I-of-N/` for a
    /// shard).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Run only part I of N of a corpus (`inputs = […]`): its sequences `u` with
    /// `u mod N = I`, written as `partial.json` for `kslab merge`. `auto` (or the flag
    /// alone) takes the part from a Slurm array task (SLURM_ARRAY_TASK_ID, _MIN, _COUNT) or
    /// a Kubernetes Indexed Job pod (JOB_COMPLETION_INDEX and KSLAB_SHARD_COUNT).
    #[arg(long, value_name = "I/N|auto", num_args = 0..=1, default_missing_value = "auto")]
    shard: Option<String>,
}

/// Arguments of `kslab merge`.
#[derive(Debug, Args)]
pub struct MergeArgs {
    /// The shards' output folders (each holding a `partial.json`), in any order.
    #[arg(required = true)]
    shards: Vec<PathBuf>,
    /// Output folder for the combined report: the files an unsharded `kslab run` writes.
    #[arg(long)]
    out: PathBuf,
}

pub fn run(a: &RunArgs) -> Result<()> {
    let (spec, base) = Spec::from_path(&a.spec)?;
    let stem = a
        .spec
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "experiment".into());
    let shard = match a.shard.as_deref() {
        None => None,
        Some("auto") => Some(Shard::from_env(&|k| std::env::var(k).ok())?),
        Some(s) => Some(Shard::parse(s)?),
    };
    if shard.is_some() && spec.inputs.is_none() {
        bail!(
            "{}: --shard splits a corpus' sequences between processes; this experiment has one `input` (name several with `inputs = [...]`)",
            a.spec.display()
        );
    }
    let dir = a.out.clone().unwrap_or_else(|| {
        let d = PathBuf::from("out").join(&stem);
        match shard {
            Some(s) => d.join(format!("shard-{}-of-{}", s.index, s.count)),
            None => d,
        }
    });
    super::check_outputs(&[], &[Some(&dir)], &[Some(&a.spec)])?;
    let progress = Progress::new(&format!("{}: {}", stem, spec.title));
    progress.units(if spec.inputs.is_some() {
        "sequences"
    } else {
        "curves (method × solver)"
    });
    let tick = |d, t| progress.tick(d, t);
    let mut summary = Vec::new();
    let files = match (shard, spec.inputs.is_some()) {
        (Some(s), _) => {
            let p = corpus::run_shard(&spec, &base, &a.spec.display().to_string(), s, &tick)?;
            vec![corpus::write_partial(&p, &dir)?]
        }
        (None, true) => write_corpus(&corpus::run(&spec, &base, &tick)?, &dir)?,
        (None, false) => {
            let o = run_spec(&spec, &base, &tick)?;
            let files = write_outcome(&o, &dir)?;
            summary = o.summary();
            files
        }
    };
    progress.finish();
    for f in files {
        outln!("{}", f.display());
    }
    for line in summary {
        outln!("{line}");
    }
    Ok(())
}

pub fn merge(a: &MergeArgs) -> Result<()> {
    let inputs: Vec<PathBuf> = a
        .shards
        .iter()
        .map(|d| d.join(corpus::PARTIAL_FILE))
        .collect();
    let inputs: Vec<Option<&std::path::Path>> = inputs.iter().map(|p| Some(p.as_path())).collect();
    super::check_outputs(&[], &[Some(&a.out)], &inputs)?;
    if a.shards.iter().any(|s| same_folder(s, &a.out)) {
        bail!(
            "{}: the merged report would overwrite a shard's folder; give another --out",
            a.out.display()
        );
    }
    let o = corpus::merge(&a.shards)?;
    for f in write_corpus(&o, &a.out)? {
        outln!("{}", f.display());
    }
    Ok(())
}

/// Are `a` and `b` one folder, however spelled (`s0`, a link to it, `o1/../s0/`)? By
/// identity when both exist; else by their absolute paths with `.` and `..` resolved
/// lexically, the way `create_dir_all` would walk them.
fn same_folder(a: &std::path::Path, b: &std::path::Path) -> bool {
    let (ia, ib) = (
        keyshape_io::atomic::file_id(a),
        keyshape_io::atomic::file_id(b),
    );
    if ia.is_some() && ib.is_some() {
        return ia == ib;
    }
    let norm = |p: &std::path::Path| -> Option<PathBuf> {
        let abs = std::path::absolute(p).ok()?;
        let mut out = PathBuf::new();
        for c in abs.components() {
            match c {
                std::path::Component::ParentDir => {
                    out.pop();
                }
                std::path::Component::CurDir => {}
                c => out.push(c),
            }
        }
        // A prefix that exists is spelled canonically (links in it followed).
        let mut existing = out.clone();
        let mut rest = Vec::new();
        while std::fs::symlink_metadata(&existing).is_err() {
            rest.push(existing.file_name()?.to_os_string());
            existing = existing.parent()?.to_path_buf();
        }
        let mut canon = std::fs::canonicalize(&existing).ok()?;
        canon.extend(rest.iter().rev());
        Some(canon)
    };
    matches!((norm(a), norm(b)), (Some(x), Some(y)) if x == y)
}
