//! `kslab run`: a scripted experiment, headless.

use super::progress::Progress;
use anyhow::Result;
use clap::Args;
use keyshape_lab::experiment::{run as run_spec, Spec};
use keyshape_lab::report::write_outcome;
use std::path::PathBuf;

/// Arguments of `kslab run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// The experiment file (TOML; see experiments/ and the README).
    spec: PathBuf,
    /// Output folder (default: `out/<spec name>/`).
    #[arg(long)]
    out: Option<PathBuf>,
}

pub fn run(a: &RunArgs) -> Result<()> {
    let (spec, base) = Spec::from_path(&a.spec)?;
    let dir = a.out.clone().unwrap_or_else(|| {
        let stem = a
            .spec
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "experiment".into());
        PathBuf::from("out").join(stem)
    });
    super::check_outputs(&[], &[Some(&dir)], &[Some(&a.spec)])?;
    let progress = Progress::new(&spec.title);
    let outcome = run_spec(&spec, &base, &|d, t| progress.tick(d, t))?;
    progress.finish();
    for f in write_outcome(&outcome, &dir)? {
        outln!("{}", f.display());
    }
    Ok(())
}
