//! Choose key shapes from the sequence itself (paper 000 §3): each heuristic picks k
//! frames, and the error of solving every frame on them (NNLS) says how well they span the
//! performance — the paper's Fig. 6 at one k.
//!
//! ```sh
//! cargo run --release --example choose_keys                    # the built-in sequence, k = 8
//! cargo run --release --example choose_keys -- TRACK.csv 12
//! ```

use keyshape_core::keyshapes::axes_needed;
use keyshape_core::{prepare, Analysis, KeyOptions, Method, PrepareOptions, Solver};
use keyshape_io::{builtin_sequence, read_sequence, ReadOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let seq = match args.next() {
        Some(path) => read_sequence(path.as_ref(), &ReadOptions::default())?,
        None => builtin_sequence()?,
    };
    let k: usize = args.next().map_or(Ok(8), |s| s.parse())?;
    let prep = prepare(&seq, &PrepareOptions::group_aligned("lips"))?;
    let methods = ["spread", "kmeans2", "hull", "greedy", "random"]
        .iter()
        .map(|m| m.parse::<Method>())
        .collect::<Result<Vec<_>, _>>()?;
    let an = Analysis::with_axes(
        prep.seq.coords.clone(),
        prep.seq.points,
        axes_needed(&methods, k),
    )?;
    an.check_k(k)?;
    let opts = KeyOptions::default();
    println!("{}: {} frames, k = {k}, NNLS", seq.source, an.frames());
    for m in &methods {
        let sel = m.heuristic(&opts).select(&an, k)?;
        let rms = an.rms(an.selection_error(&sel, Solver::Nnls)?);
        let frames: Vec<i64> = sel.columns.iter().map(|&c| prep.seq.frames[c]).collect();
        // The hull's k is the number of its corners, fixed by the data.
        println!(
            "{:>8}: {} keys, RMS {rms:.3} px, frames {frames:?}",
            m.name(),
            frames.len()
        );
    }
    Ok(())
}
