//! Solve blend weights from a CSV track (paper 000 §4): read the track, keep the lips and
//! remove head motion, take five frames as key shapes, and solve every frame's weights by
//! least squares and by non-negative least squares.
//!
//! ```sh
//! cargo run --release --example solve_weights                  # the built-in sequence
//! cargo run --release --example solve_weights -- TRACK.csv     # any track kslab reads
//! ```

use keyshape_core::{decompose, prepare, PrepareOptions, SolveOptions, Solver};
use keyshape_io::{builtin_sequence, read_sequence, ReadOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let seq = match std::env::args().nth(1) {
        Some(path) => read_sequence(path.as_ref(), &ReadOptions::default())?,
        None => builtin_sequence()?,
    };
    let prep = prepare(&seq, &PrepareOptions::group_aligned("lips"))?;
    // Five evenly spaced frames as the key shapes. Least squares fits every frame closer,
    // with large weights of both signs that distort a retargeted face (paper 000 Fig. 5);
    // NNLS keeps every weight ≥ 0. `choose_keys` picks better frames.
    let n = prep.seq.n_frames();
    let keys: Vec<usize> = (0..5).map(|i| i * (n - 1) / 4).collect();
    println!(
        "{}: {n} frames, {} lip points, key frames {:?}",
        seq.source,
        prep.seq.points,
        keys.iter().map(|&c| prep.seq.frames[c]).collect::<Vec<_>>()
    );
    for solver in [Solver::Ls, Solver::Nnls] {
        let d = decompose(&prep, &keys, None, &SolveOptions::new(solver))?;
        let first: Vec<String> = d
            .weights
            .column(n / 3)
            .iter()
            .map(|w| format!("{w:.3}"))
            .collect();
        println!(
            "{:>4}: mean RMS {:.3} px, negative weights {:.1} %, frame {}'s weights [{}]",
            solver.name(),
            d.mean_rms(),
            100.0 * d.negative_share(),
            prep.seq.frames[n / 3],
            first.join(", ")
        );
    }
    Ok(())
}
