//! `kslab rig-accuracy`: the rig accuracy benchmark (issue 39). Performances rendered
//! through the rig from known weights are solved back with `kslab rig`'s solve, and every
//! shape is measured against the truth.

use anyhow::Result;
use clap::Args;
use keyshape_core::solve::Solver;
use keyshape_io::csv_out::{opt, write_records, write_rows, Num};
use keyshape_io::{fmt_num, shared_data, write_atomic};
use keyshape_rig::accuracy::{self, Kind, Settings, ShapeAccuracy, Summary};
use keyshape_rig::{Identity, Neutral, Rig, RigOptions};
use serde::Serialize;
use serde_json::json;
use std::path::PathBuf;

/// Arguments of `kslab rig-accuracy`.
#[derive(Debug, Args)]
pub struct RigAccuracyArgs {
    /// The rig (ICT FaceKit folder layout) [default: ../shared/data/ict_facekit_face].
    #[arg(long, value_name = "DIR")]
    rig: Option<PathBuf>,
    /// The tracker's landmark set the performance is rendered at and solved from: 68 (iBUG),
    /// 468 (MediaPipe Face Mesh, through the rig's dense correspondence) or 478 (Face
    /// Landmarker: the 468 and the iris centres, which see eye gaze); `468z` and `478z`
    /// with MediaPipe's relative depth, solved as `kslab rig --dims 3` does.
    #[arg(long, default_value = "68", value_parser = ["68", "468", "478", "468z", "478z"])]
    landmarks: String,
    /// The performance: smooth (a dozen shapes as overlapping smooth bumps), winks
    /// (one-sided shapes alone to 1.0 in turn), blinks (both eyes to 1.0, often), speech
    /// (fast jaw motion), or all four.
    #[arg(long, default_value = "all", value_parser = ["smooth", "winks", "blinks", "speech", "all"])]
    kind: String,
    /// Frames of performance.
    #[arg(long, default_value_t = 300, allow_negative_numbers = true)]
    frames: usize,
    /// Neutral frames before the performance (0: none).
    #[arg(long, default_value_t = 20, allow_negative_numbers = true)]
    lead_in: usize,
    /// Landmark noise σ, pixels (at --iod).
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    noise: f64,
    /// Landmark noise σ as a percentage of the inter-ocular distance, instead of --noise
    /// (0.5 px at 107 px is 0.47 %) [default: --noise].
    #[arg(
        long,
        value_name = "PERCENT",
        allow_negative_numbers = true,
        conflicts_with = "noise"
    )]
    noise_iod: Option<f64>,
    /// The inter-ocular distance the face is drawn at, pixels.
    #[arg(long, default_value_t = 107.0, allow_negative_numbers = true)]
    iod: f64,
    /// Whose neutral face is rendered: `other` (a seeded deformation of the rig's: wider,
    /// mouth lower, eyes apart, three bumps) or `same` (the rig's own).
    #[arg(long, default_value = "other", value_parser = ["other", "same"])]
    person: String,
    /// Head yaw range, ± degrees.
    #[arg(long, default_value_t = 18.0, allow_negative_numbers = true)]
    yaw: f64,
    /// Head pitch range, ± degrees.
    #[arg(long, default_value_t = 9.0, allow_negative_numbers = true)]
    pitch: f64,
    /// Seed of the performance, the person and the noise.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// The solve's weights: bounded, nnls or ls (as `kslab rig`).
    #[arg(long, default_value = "bounded")]
    solver: Solver,
    /// As `kslab rig --identity`.
    #[arg(long, default_value = "offset")]
    identity: Identity,
    /// The neutral: `auto` (as `kslab rig`), `least-active`, or `lead-in` (the whole
    /// lead-in, where the truth is neutral, averaged: what a user who recorded one names
    /// with `kslab rig --neutral FIRST-LAST`).
    #[arg(long, default_value = "auto", value_parser = ["auto", "least-active", "lead-in"])]
    neutral: String,
    /// As `kslab rig --min-determination`.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    min_determination: f64,
    /// As `kslab rig --prior` (the magnitude prior, μ = PRIOR × IOD²).
    #[arg(long, default_value_t = keyshape_rig::RECOMMENDED_PRIOR, allow_negative_numbers = true)]
    prior: f64,
    /// The plain ridge μ‖w‖² instead of the tapered prior (the default: each shape's pull
    /// 2μw(1 − w)² fades as it comes on, so peaks are reached; see docs/src/rig_accuracy.md, "Rig accuracy
    /// against ground truth"). Needs a prior.
    #[arg(long)]
    no_prior_taper: bool,
    /// As `kslab rig --zero-phase` (offline Gaussian σ, frames; 0 for the live solve).
    #[arg(long, default_value_t = keyshape_rig::RECOMMENDED_ZERO_PHASE, allow_negative_numbers = true)]
    zero_phase: f64,
    /// As `kslab rig --smooth` (the temporal prior λ).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    smooth: f64,
    /// As `kslab rig --smooth-mode`.
    #[arg(long, default_value = "offline", value_parser = ["offline", "causal"])]
    smooth_mode: String,
    /// Write every shape's measures here (CSV: kind, shape, active, r, mae, rmse,
    /// peak_reach, twin_leakage, idle_activation, jitter, true_jitter, lag)
    /// [default: not written].
    #[arg(long, short)]
    out: Option<PathBuf>,
    /// Also write each kind's rendered track and truth here, for another solver to be
    /// measured on the same tracks (`tools/rig_reference.py`): `<kind>_track.csv` (frame,
    /// then x and y of each landmark, named by its track point: x0, y0 … x67, y67 for 68
    /// points; image axes, y down) and `<kind>_truth.csv` (frame, one column per
    /// rig shape) [default: not written].
    #[arg(long, value_name = "DIR")]
    tracks: Option<PathBuf>,
    /// Print the summaries as JSON.
    #[arg(long)]
    json: bool,
}

pub fn run(a: &RigAccuracyArgs) -> Result<()> {
    super::check_outputs(&[a.out.as_ref()], &[a.tracks.as_ref()], &[a.rig.as_deref()])?;
    let dir = match &a.rig {
        Some(d) => d.clone(),
        None => shared_data("ict_facekit_face")?,
    };
    let depth = a.landmarks.ends_with('z');
    let layout: usize = a.landmarks.trim_end_matches('z').parse()?;
    let (_, _, rig) = keyshape_rig::correspondence::read_rig(&dir, layout, None)?;
    let noise = match a.noise_iod {
        Some(p) if !(p.is_finite() && (0.0..=100.0).contains(&p)) => {
            anyhow::bail!("--noise-iod {p}: give a percentage in [0, 100]")
        }
        Some(p) => p / 100.0 * a.iod,
        None => a.noise,
    };
    let kinds: Vec<Kind> = if a.kind == "all" {
        Kind::ALL.to_vec()
    } else {
        vec![Kind::parse(&a.kind)?]
    };
    if a.neutral == "lead-in" && a.lead_in == 0 {
        anyhow::bail!("--neutral lead-in needs a lead-in (--lead-in is 0)");
    }
    let neutral = match a.neutral.as_str() {
        "least-active" => Neutral::LeastActive,
        "lead-in" => Neutral::Span(0, a.lead_in),
        _ => Neutral::Auto,
    };
    if a.no_prior_taper && a.prior == 0.0 {
        anyhow::bail!("--no-prior-taper: there is no prior to taper (--prior 0)");
    }
    let opts = RigOptions {
        neutral,
        solver: a.solver,
        identity: a.identity,
        min_determination: a.min_determination,
        smooth: a.smooth,
        smooth_mode: if a.smooth_mode == "causal" {
            keyshape_core::solve::temporal::SmoothMode::Causal
        } else {
            keyshape_core::solve::temporal::SmoothMode::Offline
        },
        prior: a.prior,
        zero_phase: a.zero_phase,
        taper: !a.no_prior_taper,
        ..Default::default()
    };
    let mut all: Vec<(Kind, Vec<ShapeAccuracy>, Summary)> = Vec::new();
    let progress = super::progress::Progress::new("rig-accuracy");
    progress.units("performances rendered and solved");
    let total = kinds.len();
    for (i, kind) in kinds.into_iter().enumerate() {
        progress.tick(i, total);
        let st = Settings {
            kind,
            frames: a.frames,
            lead_in: a.lead_in,
            noise_px: noise,
            iod_px: a.iod,
            other_person: a.person == "other",
            yaw_deg: a.yaw,
            pitch_deg: a.pitch,
            seed: a.seed,
            depth,
        };
        let (track, _, rows, summary) = accuracy::run(&rig, &st, &opts)?;
        if let Some(dir) = &a.tracks {
            write_track(dir, kind, &rig, &track)?;
        }
        all.push((kind, rows, summary));
    }
    if let Some(p) = &a.out {
        let rows = all.iter().flat_map(|(kind, rows, _)| {
            rows.iter().map(move |r| AccuracyCsv {
                kind: kind.name(),
                shape: &r.shape,
                active: r.active,
                r: (!r.r.is_nan()).then_some(Num(r.r)),
                mae: Num(r.mae),
                rmse: Num(r.rmse),
                peak_reach: opt(r.peak_reach),
                twin_leakage: opt(r.twin_leakage),
                idle_activation: opt(r.idle_activation),
                jitter: Num(r.jitter),
                true_jitter: Num(r.true_jitter),
                lag: r.lag,
            })
        });
        write_atomic(p, |w| write_rows(w, rows))?;
    }
    if a.json {
        let v: Vec<_> = all
            .iter()
            .map(|(k, _, s)| json!({"kind": k.name(), "summary": s}))
            .collect();
        outln!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        for (k, _, s) in &all {
            outln!(
                "{:<7} mean r {:.3}  worst r {:.3} ({})  weight RMSE {:.3}  idle max {:.2} ({})  twin leakage max {:.2}  peak reach min {}  lag max {}",
                k.name(),
                s.mean_r,
                s.worst_r,
                s.worst_shape,
                s.rmse,
                s.max_idle,
                s.max_idle_shape,
                s.max_twin_leakage,
                s.min_peak_reach.map_or("—".into(), |v| format!("{v:.2}")),
                s.max_abs_lag,
            );
        }
    }
    Ok(())
}

/// A row of `--out`: one shape of one kind of track.
#[derive(Serialize, Default)]
struct AccuracyCsv<'a> {
    kind: &'a str,
    shape: &'a str,
    active: bool,
    r: Option<Num>,
    mae: Num,
    rmse: Num,
    peak_reach: Option<Num>,
    twin_leakage: Option<Num>,
    idle_activation: Option<Num>,
    jitter: Num,
    true_jitter: Num,
    lag: Option<i64>,
}

/// `<kind>_track.csv` and `<kind>_truth.csv` in `dir`.
fn write_track(dir: &std::path::Path, kind: Kind, rig: &Rig, t: &accuracy::Track) -> Result<()> {
    keyshape_io::create_dir_all(dir)?;
    let depth = t.points.nrows() == 3 * rig.landmarks();
    let axes: &[&str] = if depth { &["x", "y", "z"] } else { &["x", "y"] };
    let head = std::iter::once("frame".to_string()).chain(
        rig.points
            .iter()
            .flat_map(|i| axes.iter().map(move |a| format!("{a}{i}"))),
    );
    write_atomic(&dir.join(format!("{}_track.csv", kind.name())), |w| {
        write_records(w, head, frame_records(&t.points))
    })?;
    let head = std::iter::once("frame").chain(rig.names.iter().map(String::as_str));
    write_atomic(&dir.join(format!("{}_truth.csv", kind.name())), |w| {
        write_records(w, head, frame_records(&t.truth))
    })?;
    Ok(())
}

/// One record per column of `m`: its index, then its values.
fn frame_records(m: &nalgebra::DMatrix<f64>) -> impl Iterator<Item = Vec<String>> + '_ {
    (0..m.ncols()).map(|f| {
        std::iter::once(f.to_string())
            .chain(m.column(f).iter().map(|v| fmt_num(*v)))
            .collect()
    })
}
