//! `kslab curves`: paper 000 Fig. 6 — reconstruction error against k for each method.

use super::input::InputArgs;
use super::keys::HeuristicArgs;
use super::progress::Progress;
use anyhow::Result;
use clap::Args;
use keyshape_core::keyshapes::curves::sweep;
use keyshape_core::keyshapes::{Analysis, Method};
use keyshape_core::solve::Solver;
use keyshape_experiments::report::write_curves_csv;
use std::path::PathBuf;

/// Arguments of `kslab curves`.
#[derive(Debug, Args)]
pub struct CurvesArgs {
    #[command(flatten)]
    input: InputArgs,
    /// Comma-separated methods.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "spread,kmeans2,kmeans3,hull,greedy,random"
    )]
    methods: Vec<Method>,
    /// k range, `A..B` (inclusive) or a single k.
    #[arg(long, default_value = "2..24", value_parser = parse_range)]
    k: (usize, usize),
    /// Solvers, comma-separated (ls, nnls, bounded).
    #[arg(long = "solver", value_delimiter = ',', default_value = "nnls")]
    solvers: Vec<Solver>,
    #[command(flatten)]
    heuristic: HeuristicArgs,
    /// Write the curves as CSV (method,solver,k,total_sq_error,rms).
    /// [default: not written].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write the plot as PNG, one file per solver named `NAME_<solver>.png` (`--png c.png
    /// --solver nnls` writes `c_nnls.png`), whatever other options are given.
    /// [default: not drawn].
    #[arg(long)]
    png: Option<PathBuf>,
}

pub fn parse_range(s: &str) -> Result<(usize, usize), String> {
    let bad = || format!("'{s}' is not a k range (write A..B, e.g. 2..24, or one number)");
    let parts: Vec<&str> = s.split("..").collect();
    let num = |t: &str| {
        t.trim()
            .trim_start_matches('=')
            .parse::<usize>()
            .map_err(|_| bad())
    };
    match parts.as_slice() {
        [one] => num(one).map(|k| (k, k)),
        [a, b] => Ok((num(a)?, num(b)?)),
        _ => Err(bad()),
    }
}

pub fn run(a: &CurvesArgs) -> Result<()> {
    if let Some(p) = a.png.as_ref().filter(|p| keyshape_io::atomic::is_stdout(p)) {
        anyhow::bail!(
            "--png {}: names one file per solver (NAME_<solver>.png), so it takes a file name, not standard output",
            p.display()
        );
    }
    super::check_outputs(
        &[a.out.as_ref(), a.png.as_ref()],
        &[],
        &[a.input.file.as_deref()],
    )?;
    // The files actually written: one per solver.
    let pngs: Vec<PathBuf> = a
        .png
        .iter()
        .flat_map(|p| a.solvers.iter().map(move |s| suffixed(p, s.name())))
        .collect();
    super::check_outputs(
        &std::iter::once(a.out.as_ref())
            .chain(pngs.iter().map(Some))
            .collect::<Vec<_>>(),
        &[],
        &[a.input.file.as_deref()],
    )?;
    // --shortlist counts if any solver of the sweep uses it.
    let constrained = a.solvers.iter().copied().find(|s| *s != Solver::Ls);
    a.heuristic
        .check(&a.methods, constrained.unwrap_or(a.solvers[0]))?;
    let progress = Progress::new("curves: reading");
    let mut prep = a.input.prepare_only()?;
    progress.step("curves: principal axes");
    let methods: Vec<Method> = a.methods.iter().map(|m| a.heuristic.apply(*m)).collect();
    let axes = keyshape_core::keyshapes::axes_needed(&methods, a.k.1);
    // The analysis takes the coordinates; only the frame numbers and source are used after.
    let coords = std::mem::replace(&mut prep.seq.coords, nalgebra::DMatrix::zeros(0, 0));
    let an = Analysis::with_axes(coords, prep.seq.points, axes)?;
    let opts = a.heuristic.options(a.solvers[0]);
    progress.step(&format!("curves: k = {}..{}", a.k.0, a.k.1));
    progress.units("curves (method × solver)");
    let rows = sweep(&an, &methods, a.k.0..=a.k.1, &a.solvers, &opts, &|d, t| {
        progress.tick(d, t)
    })?;
    progress.finish();
    match &a.out {
        Some(p) => keyshape_io::write_atomic(p, |w| write_curves_csv(w, &rows))?,
        None => write_curves_csv(&mut std::io::stdout().lock(), &rows)?,
    }
    if let Some(png) = &a.png {
        for s in &a.solvers {
            // What was measured: track, points, solver, aligned or raw.
            let title = format!(
                "{} — {}, {}, {}",
                short(&prep.seq.source),
                a.input.points.as_deref().unwrap_or("whole face"),
                s.name(),
                if a.input.no_align {
                    "raw coordinates"
                } else {
                    "head motion removed"
                }
            );
            // One name per solver whatever else is asked: NAME_<solver>.png.
            let path = suffixed(png, s.name());
            keyshape_experiments::report::write_curves_png(&rows, s.name(), &title, &path)?;
            crate::cli::output::wrote(path.display().to_string());
        }
    }
    if let Some(line) = keyshape_core::keyshapes::curves::summary(&rows) {
        // On standard error when standard output carries the table.
        sayln!(
            a.out.is_none() || super::is_stdout(a.out.as_ref()),
            "{line}"
        );
    }
    Ok(())
}

pub fn short(source: &str) -> &str {
    source.rsplit('/').next().unwrap_or(source)
}

/// `dir/name.png` → `dir/name_<tag>.png`.
pub fn suffixed(path: &std::path::Path, tag: &str) -> PathBuf {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let ext = path
        .extension()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "png".into());
    path.with_file_name(format!("{stem}_{tag}.{ext}"))
}
