//! `kslab template`: the chosen key shapes as an SVG for an artist to redraw.

use super::input::InputArgs;
use super::keys::{parse_method, HeuristicArgs};
use anyhow::{Context, Result};
use clap::Args;
use keyshape_lab::io::{svg::write_template, write_atomic};
use keyshape_lab::keyshapes::{axes_needed, Analysis, KeyOptions, Method};
use keyshape_lab::retarget::setup::polylines_for;
use keyshape_lab::solve::Solver;
use std::path::PathBuf;

/// Arguments of `kslab template`.
#[derive(Debug, Args)]
pub struct TemplateArgs {
    #[command(flatten)]
    input: InputArgs,
    /// Key frames by frame number (or choose them with --method and --k).
    #[arg(long, value_delimiter = ',', conflicts_with = "method")]
    keys: Vec<i64>,
    /// Heuristic choosing the key frames.
    #[arg(long, value_parser = parse_method)]
    method: Option<Method>,
    /// Number of key shapes for --method.
    #[arg(long, default_value_t = 12)]
    k: usize,
    #[command(flatten)]
    heuristic: HeuristicArgs,
    /// The SVG to write.
    #[arg(long, short)]
    out: PathBuf,
}

pub fn run(a: &TemplateArgs) -> Result<()> {
    let (_, prep) = a.input.prepare()?;
    let s = &prep.seq;
    if s.dims != 2 {
        anyhow::bail!("SVG templates are 2-D: use --dims 2");
    }
    let cols: Vec<usize> = if a.keys.is_empty() {
        let m = a.method.unwrap_or(Method::Spread);
        let an = Analysis::with_axes(s.coords.clone(), s.points, axes_needed(&[m], a.k))?;
        let opts = KeyOptions {
            solver: Solver::Nnls,
            seed: a.heuristic.seed,
            shortlist: a.heuristic.shortlist,
        };
        m.heuristic(&opts).select(&an, a.k)?.columns
    } else {
        a.keys
            .iter()
            .map(|&f| s.column_of_frame(f).with_context(|| format!("--keys {f}")))
            .collect::<Result<_>>()?
    };
    let keys: Vec<(i64, Vec<f64>)> = cols
        .iter()
        .map(|&c| (s.frames[c], s.coords.column(c).iter().copied().collect()))
        .collect();
    let lines = prep
        .layout
        .as_ref()
        .map(|l| polylines_for(l, &prep.point_indices))
        .unwrap_or_default();
    write_atomic(&a.out, |w| write_template(w, &keys, s.points, &lines))?;
    let frames: Vec<String> = keys.iter().map(|k| k.0.to_string()).collect();
    println!(
        "{} key shapes (frames {}) → {}",
        keys.len(),
        frames.join(","),
        a.out.display()
    );
    Ok(())
}
