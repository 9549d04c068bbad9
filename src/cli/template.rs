//! `kslab template`: the chosen key shapes as an SVG for an artist to redraw.

use super::input::InputArgs;
use super::keys::{HeuristicArgs, KeyChoiceArgs};
use anyhow::Result;
use clap::Args;
use keyshape_core::solve::Solver;
use keyshape_io::write_atomic;
use keyshape_retarget::setup::named_polylines_for;
use keyshape_retarget::svg::write_template;
use std::path::PathBuf;

/// Arguments of `kslab template`.
#[derive(Debug, Args)]
pub struct TemplateArgs {
    #[command(flatten)]
    input: InputArgs,
    #[command(flatten)]
    choice: KeyChoiceArgs,
    #[command(flatten)]
    heuristic: HeuristicArgs,
    /// The SVG to write.
    #[arg(long, short)]
    out: PathBuf,
}

pub fn run(a: &TemplateArgs) -> Result<()> {
    super::check_outputs(&[Some(&a.out)], &[], &[a.input.file.as_deref()])?;
    a.heuristic.check(&a.choice.methods(), Solver::Nnls)?;
    let progress = super::progress::Progress::new("template");
    let mut prep = a.input.prepare_only()?;
    if prep.seq.dims != 2 {
        anyhow::bail!("SVG templates are 2-D: use --dims 2");
    }
    let opts = a.heuristic.options(Solver::Nnls);
    let cols = a.choice.columns_in_place(&mut prep.seq, &opts)?;
    let s = &prep.seq;
    let keys: Vec<(i64, Vec<f64>)> = cols
        .iter()
        .map(|&c| (s.frames[c], s.coords.column(c).iter().copied().collect()))
        .collect();
    let lines = prep
        .layout
        .as_ref()
        .map(|l| named_polylines_for(l, &prep.point_indices))
        .unwrap_or_default();
    progress.finish();
    write_atomic(&a.out, |w| write_template(w, &keys, s.points, &lines))?;
    let frames: Vec<String> = keys.iter().map(|k| k.0.to_string()).collect();
    sayln!(
        super::is_stdout(Some(&a.out)),
        "{} key shapes (frames {}) → {}",
        keys.len(),
        frames.join(","),
        a.out.display()
    );
    Ok(())
}
