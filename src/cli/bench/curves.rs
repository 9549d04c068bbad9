//! `kslab bench curves`: time of the Fig. 6 sweep by stage and by method, against a plain
//! implementation (errors by per-frame textbook NNLS on S, no Gram reuse).

use super::nnls::short;
use anyhow::Result;
use clap::Args;
use keyshape_core::decompose::{prepare, PrepareOptions};
use keyshape_core::keyshapes::curves::{sweep, CurveRow};
use keyshape_core::keyshapes::{Analysis, KeyOptions, Method};
use keyshape_core::solve::{textbook, Solver};
use keyshape_io::{builtin_sequence, read_sequence, ReadOptions};
use rayon::prelude::*;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `kslab bench curves`.
#[derive(Debug, Args)]
pub struct CurvesBenchArgs {
    /// Sequence (default: ../shared/data/mediapipe_face_tracks/liveportrait_d6.csv, 1,008
    /// frames × 468 points, or the built-in sequence when that is missing).
    file: Option<PathBuf>,
    /// Point groups, as for `kslab curves`.
    /// [default: every point].
    #[arg(long)]
    points: Option<String>,
    /// Highest k of the sweep.
    #[arg(long, default_value_t = 24, value_parser = crate::cli::input::count_within(&keyshape_core::limits::BENCH_COUNT))]
    kmax: usize,
}

fn textbook_error(an: &Analysis, keys: &[usize]) -> f64 {
    let s = an.coords.select_columns(keys);
    (0..an.frames())
        .into_par_iter()
        .map(|t| {
            let q = an.coords.column(t).clone_owned();
            let w = textbook::nnls(&s, &q);
            (&s * w - q).norm_squared()
        })
        .sum()
}

pub fn run(a: &CurvesBenchArgs) -> Result<()> {
    let t0 = Instant::now();
    let default = keyshape_io::shared_data("mediapipe_face_tracks/liveportrait_d6.csv")
        .unwrap_or_else(|_| PathBuf::from("builtin"));
    let seq = match (&a.file, default.exists()) {
        (Some(f), _) => read_sequence(f, &ReadOptions::default())?,
        (None, true) => read_sequence(&default, &ReadOptions::default())?,
        (None, false) => builtin_sequence()?,
    };
    let t_read = t0.elapsed().as_secs_f64();
    let t = Instant::now();
    let prep = prepare(
        &seq,
        &PrepareOptions {
            points: a.points.clone(),
            align: true,
        },
    )?;
    let t_align = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let an = Analysis::new(prep.seq.coords.clone(), prep.seq.points)?;
    let t_pca = t.elapsed().as_secs_f64();
    let t = Instant::now();
    an.frame_gram()?;
    let t_gram = t.elapsed().as_secs_f64();
    let opts = KeyOptions::default();
    outln!(
        "kslab bench curves: {} ({} frames × {} points{}), k = 2..{}, nnls, {} threads\n",
        short(&seq.source),
        an.frames(),
        an.points,
        a.points
            .as_deref()
            .map(|p| format!(", {p}"))
            .unwrap_or_default(),
        a.kmax,
        rayon::current_num_threads()
    );
    outln!("| stage | seconds | plain implementation, seconds | ratio |");
    outln!("|---|---|---|---|");
    outln!("| read | {t_read:.3} | | |");
    outln!("| align (Procrustes) | {t_align:.3} | | |");
    outln!("| PCA | {t_pca:.3} | | |");
    outln!("| frames' Gram matrix QᵀQ | {t_gram:.3} | | |");
    let mut total = 0.0;
    let mut total_plain = 0.0;
    for m in frame_methods() {
        let t = Instant::now();
        let rows = sweep(&an, &[m], 2..=a.kmax, &[Solver::Nnls], &opts, &|_, _| {})?;
        let secs = t.elapsed().as_secs_f64();
        total += secs;
        let (plain, note) = plain_seconds(&an, m, &rows, &opts, a.kmax)?;
        total_plain += plain;
        outln!(
            "| sweep: {} | {secs:.3} | {plain:.2}{note} | {:.0}× |",
            m.name(),
            plain / secs
        );
    }
    outln!(
        "| **sweep, all methods** | **{total:.3}** | **{total_plain:.1}** | **{:.0}×** |",
        total_plain / total
    );
    // What `kslab curves` runs: every method in one sweep, the methods and their k in
    // parallel (the rows above time one method at a time, each alone on the cores).
    let methods = frame_methods();
    let mut together = f64::INFINITY;
    for _ in 0..3 {
        let t = Instant::now();
        std::hint::black_box(sweep(
            &an,
            &methods,
            2..=a.kmax,
            &[Solver::Nnls],
            &opts,
            &|_, _| {},
        )?);
        together = together.min(t.elapsed().as_secs_f64());
    }
    outln!(
        "| **sweep, all methods in one call, as `kslab curves` runs it (best of 3)** | **{together:.3}** | | |"
    );
    let all = t_read + t_align + t_pca + t_gram + together;
    outln!("| **everything from reading on** (with the one-call sweep) | **{all:.3}** | | |");
    Ok(())
}

/// The methods that choose frames. The mean-shape k-means variants solve on shapes, not
/// frames: the plain comparison works on frames, so they are left out.
fn frame_methods() -> Vec<Method> {
    Method::ALL
        .into_iter()
        .filter(|m| !matches!(m, Method::KMeans { mean: true, .. }))
        .collect()
}

/// The plain implementation's seconds for method `m`'s sweep `rows`, and a note when the
/// figure is estimated rather than measured (exact greedy).
fn plain_seconds(
    an: &Analysis,
    m: Method,
    rows: &[CurveRow],
    opts: &KeyOptions,
    kmax: usize,
) -> Result<(f64, &'static str)> {
    if m == Method::Greedy {
        return Ok((
            plain_greedy_estimate(an, kmax),
            " (estimated: exact greedy, per-frame textbook NNLS, from measured per-frame times)",
        ));
    }
    // Same selections (k-means included), errors by the textbook solver.
    let t = Instant::now();
    for r in rows {
        let keys = if m == Method::Hull {
            r.keys.clone()
        } else {
            m.heuristic(opts).select(an, r.k)?.columns
        };
        std::hint::black_box(textbook_error(an, &keys));
    }
    Ok((t.elapsed().as_secs_f64(), ""))
}

/// Exact greedy from scratch: for each step k, every remaining frame is tried as the k-th
/// key by solving every frame with the textbook solver. Estimated as Σ_k (T − k + 1) · T ·
/// (per-frame textbook time at k), the per-frame time measured on 100 frames.
fn plain_greedy_estimate(an: &Analysis, kmax: usize) -> f64 {
    let n = an.frames();
    let sample: Vec<usize> = (0..100.min(n)).map(|i| i * n / 100.min(n)).collect();
    let mut est = 0.0;
    for k in 1..=kmax {
        let keys: Vec<usize> = (0..k)
            .map(|i| i * (n - 1) / k.max(2).saturating_sub(1).max(1))
            .collect();
        let s = an.coords.select_columns(&keys);
        let t = Instant::now();
        for &f in &sample {
            std::hint::black_box(textbook::nnls(&s, &an.coords.column(f).clone_owned()));
        }
        let per_frame = t.elapsed().as_secs_f64() / sample.len() as f64;
        est += (n - k + 1) as f64 * n as f64 * per_frame / rayon::current_num_threads() as f64;
    }
    est
}
