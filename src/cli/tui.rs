//! `kslab tui` (and `kslab` alone): the interactive lab.

use anyhow::Result;
use clap::Args;
use keyshape_lab::retarget::target::TargetSet;
use std::io::IsTerminal;
use std::path::PathBuf;

/// Arguments of `kslab tui`.
#[derive(Debug, Default, Args)]
pub struct TuiArgs {
    /// Tracked sequence (omit for the built-in one).
    file: Option<PathBuf>,
    /// Target key shapes (JSON target set or SVG template): its frames become the key frames.
    #[arg(long)]
    target: Option<PathBuf>,
}

pub fn run(a: &TuiArgs) -> Result<()> {
    if !std::io::stdout().is_terminal() {
        anyhow::bail!("the lab needs a terminal (stdout is not one); see `kslab --help` for the headless commands");
    }
    let path = a
        .file
        .as_ref()
        .map_or("builtin".to_string(), |p| p.display().to_string());
    let seq = keyshape_lab::tui::compute::load(&path)?;
    let target = match &a.target {
        None => None,
        Some(p) if p.extension().is_some_and(|e| e.eq_ignore_ascii_case("svg")) => {
            Some(keyshape_lab::io::svg::read_template(p)?)
        }
        Some(p) => Some(TargetSet::read_json(p)?),
    };
    keyshape_lab::tui::run(seq, &path, target)
}
