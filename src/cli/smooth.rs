//! `kslab smooth`: the jitter-against-error study of the temporal prior and post-filters.

use super::input::InputArgs;
use anyhow::Result;
use clap::Args;
use keyshape_core::keyshapes::Method;
use keyshape_core::solve::Solver;
use keyshape_experiments::experiment::smoothing::{smoothing_study_in_place, SmoothStudySettings};
use std::path::PathBuf;

/// Arguments of `kslab smooth`.
#[derive(Debug, Args)]
pub struct SmoothArgs {
    #[command(flatten)]
    input: InputArgs,
    /// Heuristic choosing the key frames (a kmeansN-mean's cluster means work too).
    #[arg(long, default_value = "spread")]
    method: Method,
    /// Number of key shapes [default: 12; not with --method hull, which gives its own].
    #[arg(long)]
    k: Option<usize>,
    /// ls, nnls or bounded.
    #[arg(long, default_value = "nnls")]
    solver: Solver,
    /// λ values of the temporal prior (offline order 1 and 2, causal order 1), in squared
    /// coordinate units (px²) per unit of weight change [default: 10,100,1000,10000,100000;
    /// a track in normalised coordinates needs --image-size or a grid of its own].
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    lambdas: Option<Vec<f64>>,
    /// Post-filter families compared with the prior: moving-average, ema, one-euro.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "moving-average,ema,one-euro"
    )]
    filters: Vec<String>,
    /// Centred moving-average windows, frames (odd) [default: 3,5,9,15,25].
    #[arg(long, value_delimiter = ',')]
    windows: Option<Vec<usize>>,
    /// Exponential moving-average factors α in (0, 1] [default: 0.7,0.5,0.3,0.15,0.08].
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    alphas: Option<Vec<f64>>,
    /// One Euro filter minimum cutoffs, Hz [default: 8,4,2,1,0.5].
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    one_euro_cutoffs: Option<Vec<f64>>,
    /// One Euro filter betas, one curve each (cutoff increase in Hz per unit of weight
    /// speed per second; 0 makes it an exponential moving average) [default: 0.05,0.5].
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    one_euro_betas: Option<Vec<f64>>,
    /// σ (frames) of the zero-phase Gaussian low-pass that makes the clean reference.
    #[arg(long, default_value_t = 2.0, allow_negative_numbers = true)]
    clean_sigma: f64,
    /// Folder for smoothing.csv, smoothing_at_equal_jitter.csv and smoothing.png.
    #[arg(long)]
    out: PathBuf,
}

/// The λ grid in px² when none is given.
const DEFAULT_LAMBDAS: [f64; 5] = [10.0, 100.0, 1000.0, 10000.0, 100000.0];

pub fn run(a: &SmoothArgs) -> Result<()> {
    super::check_outputs(&[], &[Some(&a.out)], &[a.input.file.as_deref()])?;
    let seq = a.input.read()?;
    let lambdas = match &a.lambdas {
        Some(l) => l.clone(),
        // A grid in px² on coordinates that are fractions of the image weighs the prior
        // some 10⁶ times too much: the solves do not settle, or smooth everything away.
        None if seq.is_normalised() => anyhow::bail!(
            "{}: the track is in normalised coordinates (every x and y in [0, 1]) and the default λ grid is in px²: give --image-size WIDTHxHEIGHT (the video's size) to work in pixels, or a grid for this scale with --lambdas (the px² grid divided by the squared image width, e.g. 1e-5,1e-4,1e-3,1e-2,1e-1 for a 1000-px video)",
            seq.source
        ),
        None => DEFAULT_LAMBDAS.to_vec(),
    };
    let st = SmoothStudySettings {
        method: a.method,
        k: a.k,
        solver: a.solver,
        lambdas,
        filters: a.filters.clone(),
        windows: a.windows.clone(),
        alphas: a.alphas.clone(),
        one_euro_cutoffs: a.one_euro_cutoffs.clone(),
        one_euro_betas: a.one_euro_betas.clone(),
        clean_sigma: a.clean_sigma,
    };
    st.check(30.0)?;
    let progress = super::progress::Progress::new("smooth");
    // The raw track only for a point subset (the built-in target is made from the whole
    // face); otherwise it is aligned in place and held once.
    let (raw, mut prep) = if a.input.points.is_some() {
        let prep = a.input.prepare_read(&seq)?;
        (Some(seq), prep)
    } else {
        let mut prep = a.input.prepare_owned_read(seq)?;
        // The removed head motion is not part of the study (five values a frame).
        prep.head = None;
        (None, prep)
    };
    let rows = smoothing_study_in_place(raw.as_ref(), &mut prep, &st, &Default::default())?;
    let seq = raw.as_ref().unwrap_or(&prep.seq);
    keyshape_io::create_dir_all(&a.out)?;
    // The file's name, not its path: a path filled the title and cut what followed.
    let title = format!(
        "{} {} k={} {}",
        super::input::track_label(&seq.source, a.input.points.as_deref()),
        a.method,
        st.key_count(),
        a.solver
    );
    let (files, figures) = keyshape_experiments::experiment::studies::smooth::write_smoothing(
        &rows, &title, &a.out, true,
    )?;
    progress.finish();
    let none = rows.iter().find(|r| r.approach == "none");
    if let Some(n) = none {
        outln!(
            "unsmoothed: source RMS {:.3}, target RMS {:.3} (tracked) / {:.3} (clean), jitter {:.3} px/frame²; {} settings compared",
            n.source_rms,
            n.target_rms_tracked,
            n.target_rms_clean,
            n.jitter_target,
            rows.len() - 1
        );
    }
    let at =
        keyshape_experiments::experiment::smoothing::at_equal_jitter(&rows, &[0.75, 0.5, 0.35]);
    if let Some(line) = keyshape_experiments::experiment::smoothing::summary(&at) {
        outln!("{line}");
    }
    for f in files.iter().chain(
        figures
            .iter()
            .map(|f| a.out.join(f))
            .collect::<Vec<_>>()
            .iter(),
    ) {
        crate::cli::output::wrote(f.display().to_string());
    }
    Ok(())
}
