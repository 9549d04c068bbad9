//! `kslab rig-accuracy`: the rig accuracy benchmark. Performances rendered
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

mod distributions;

use distributions::print_distributions;

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
    /// mouth lower, eyes apart, three bumps), `deep` (that person with a flatter or deeper
    /// face too: depth scaled by 0.8–0.9 or 1.1–1.2, which a turned head shows) or `same`
    /// (the rig's own).
    #[arg(long, default_value = "other", value_parser = ["other", "deep", "same"])]
    person: String,
    /// Head yaw range, ± degrees.
    #[arg(long, default_value_t = 18.0, allow_negative_numbers = true)]
    yaw: f64,
    /// Head pitch range, ± degrees.
    #[arg(long, default_value_t = 9.0, allow_negative_numbers = true)]
    pitch: f64,
    /// A held expression on every frame, the lead-in too, so no frame is neutral: three
    /// seeded shapes of a resting face (a half smile, pressed lips, a squint, a raised inner
    /// brow …) whose weights sum to HOLD, breathing between 70 % and 100 % of it (0: none).
    /// It is part of the truth.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    hold: f64,
    /// Seed of the performance, the person and the noise.
    #[arg(long, default_value_t = 7, conflicts_with = "seeds")]
    seed: u64,
    /// Every seed FIRST..LAST (inclusive, at most 1000 of them), each a performance, a
    /// person and a noise of its own: per kind, each summary measure as a distribution over
    /// the seeds — median, 10th percentile and worst (for errors: median, 90th percentile
    /// and worst) — since one seed says little (on 68 points, 12 of 20 seeds met every
    /// goal). --out gets every seed's rows, --tracks every seed's files
    /// (`<kind>_s<seed>_track.csv`)
    /// [default: one seed, --seed].
    #[arg(long, value_name = "FIRST..LAST")]
    seeds: Option<String>,
    /// The solve's weights: bounded, nnls or ls (as `kslab rig`).
    #[arg(long, default_value = "bounded")]
    solver: Solver,
    /// As `kslab rig --identity`.
    #[arg(long, default_value = "offset")]
    identity: Identity,
    /// The neutral: `auto` (as `kslab rig`), `least-active`, or `lead-in` (the whole
    /// lead-in, where the truth is neutral, averaged: what a user who recorded one names
    /// with `kslab rig --neutral FIRST-LAST`).
    /// [default: auto; lead-in with --live]
    #[arg(long, value_parser = ["auto", "least-active", "lead-in"])]
    neutral: Option<String>,
    /// The live solve, as `kslab live` computes it frame by frame (and `kslab rig --live`
    /// for a file): causal, calibrated on the lead-in (the neutral and the prior's scale),
    /// no zero-phase smoothing, the live path's causal temporal prior. Needs a lead-in.
    #[arg(long)]
    live: bool,
    /// As `kslab rig --min-determination`.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    min_determination: f64,
    /// As `kslab rig --prior` (the magnitude prior, μ = PRIOR × IOD²) [default: 0.0026;
    /// with --live, 0.004].
    #[arg(long, allow_negative_numbers = true)]
    prior: Option<f64>,
    /// The plain ridge μ‖w‖² instead of the tapered prior (the default: each shape's pull
    /// 2μw(1 − w)² fades as it comes on, so peaks are reached; see docs/src/rig_accuracy.md, "Rig accuracy
    /// against ground truth"). Needs a prior.
    #[arg(long)]
    no_prior_taper: bool,
    /// As `kslab rig --robust-landmarks`: landmarks the rig explains much worse than the
    /// median one are down-weighted and the track solved again.
    #[arg(long)]
    robust_landmarks: bool,
    /// Render through a landmark map that is wrong by up to MM millimetres: each track
    /// point on a random vertex of the rig's mesh within MM of the map's (seeded with the
    /// performance), while the solve reads the map as it is — a tracker whose points are not
    /// where the map says. 0: the map itself [default: 0].
    #[arg(
        long,
        value_name = "MM",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    map_noise: f64,
    /// As `kslab rig --refine-landmarks`: solve with the landmark map refined from the track
    /// (landmarks weighed robustly), and measure the refined map against the one the track
    /// was rendered through (how many landmarks sit on its vertex, the median distance).
    #[arg(long)]
    refine_landmarks: bool,
    /// As `kslab rig --refine-radius` (millimetres) [default: 10].
    #[arg(long, value_name = "MM", allow_negative_numbers = true)]
    refine_radius: Option<f64>,
    /// As `kslab rig --zero-phase` (offline Gaussian σ, frames; 0 for the live solve)
    /// [default: 1; with --live, 0].
    #[arg(long, allow_negative_numbers = true)]
    zero_phase: Option<f64>,
    /// As `kslab rig --smooth` (the temporal prior λ, px²) [default: 0; with --live, the
    /// live path's causal prior, 0.0026 × the lead-in's squared inter-ocular distance, as
    /// `kslab live`].
    #[arg(long, allow_negative_numbers = true)]
    smooth: Option<f64>,
    /// As `kslab rig --smooth-mode` [default: offline; with --live, causal].
    #[arg(long, value_parser = ["offline", "causal"])]
    smooth_mode: Option<String>,
    /// Write every shape's measures here (CSV: kind, shape, active, r, mae, rmse,
    /// peak_reach, twin_leakage, idle_activation, jitter, true_jitter, lag, seed)
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
    pub(crate) json: bool,
}

pub fn run(a: &RigAccuracyArgs) -> Result<()> {
    super::check_outputs(&[a.out.as_ref()], &[a.tracks.as_ref()], &[a.rig.as_deref()])?;
    let read = read_rig(a)?;
    let plan = plan_of(a)?;
    let all = render_and_solve(a, &read, &plan)?;
    if let Some(p) = &a.out {
        write_csv(p, &all)?;
    }
    if a.seeds.is_some() {
        return print_distributions(a, &all);
    }
    print_summaries(a, &all)
}

/// The rig the performances are rendered through and solved onto.
struct RigRead {
    mesh: keyshape_io::obj::Mesh,
    morph: keyshape_io::morph::MorphTargets,
    rig: keyshape_rig::Rig,
    /// The track carries depth (`--landmarks 468z`).
    depth: bool,
}

/// What is rendered and how it is solved.
struct Plan {
    opts: RigOptions,
    refinement: Option<keyshape_rig::refine::Refinement>,
    /// Landmark noise, pixels.
    noise: f64,
    kinds: Vec<Kind>,
}

/// One performance's result: its kind, seed, every shape's measures and the summary.
type Run = (Kind, u64, Vec<ShapeAccuracy>, Summary);

/// The rig (`--rig`, the ICT face by default) read for `--landmarks`, and `--map-noise`
/// checked against it.
fn read_rig(a: &RigAccuracyArgs) -> Result<RigRead> {
    let dir = match &a.rig {
        Some(d) => d.clone(),
        None => shared_data("ict_facekit_face")?,
    };
    let depth = a.landmarks.ends_with('z');
    let layout: usize = a.landmarks.trim_end_matches('z').parse()?;
    let (mesh, morph, rig) = keyshape_rig::correspondence::read_rig(&dir, layout, None)?;
    if !(a.map_noise.is_finite() && (0.0..=50.0).contains(&a.map_noise)) {
        anyhow::bail!("--map-noise {}: give 0 to 50 millimetres", a.map_noise);
    }
    if a.map_noise > 0.0 && !dir.is_dir() {
        anyhow::bail!(
            "--map-noise moves landmarks on an ICT FaceKit folder's mesh (in cm); {} is not one",
            dir.display()
        );
    }
    if a.map_noise > 0.0 && layout == 478 {
        anyhow::bail!("--map-noise: the 478-point layout's irises are virtual points, not mesh vertices; use --landmarks 468 or 68");
    }
    Ok(RigRead {
        mesh,
        morph,
        rig,
        depth,
    })
}

/// The solve's options, the refinement, the noise and the kinds, from the flags (each
/// refused where it cannot apply).
fn plan_of(a: &RigAccuracyArgs) -> Result<Plan> {
    let refinement = super::rig::refinement_of(a.refine_landmarks, a.refine_radius)?;
    if refinement.is_some() && a.live {
        anyhow::bail!(
            "--refine-landmarks measures each landmark over the whole track: not with --live"
        );
    }
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
    let neutral_name = match (a.neutral.as_deref(), a.live) {
        (Some(n @ ("auto" | "least-active")), true) => anyhow::bail!(
            "--live calibrates on the lead-in: --neutral {n} searches the whole track"
        ),
        (Some(n), _) => n,
        (None, true) => "lead-in",
        (None, false) => "auto",
    };
    if neutral_name == "lead-in" && a.lead_in == 0 {
        anyhow::bail!("--neutral lead-in (and --live) needs a lead-in (--lead-in is 0)");
    }
    let neutral = match neutral_name {
        "least-active" => Neutral::LeastActive,
        "lead-in" => Neutral::Span(0, a.lead_in),
        _ => Neutral::Auto,
    };
    let t = super::rig::Temporal::of(
        a.live,
        (a.zero_phase, a.smooth, a.smooth_mode.as_deref()),
        a.prior,
        a.no_prior_taper,
    )?;
    let opts = RigOptions {
        neutral,
        solver: a.solver,
        identity: a.identity,
        min_determination: a.min_determination,
        smooth: t.smooth,
        smooth_unit: t.smooth_unit,
        smooth_mode: t.smooth_mode,
        prior: t.prior,
        zero_phase: t.zero_phase,
        taper: !a.no_prior_taper,
        causal: a.live,
        robust: a.robust_landmarks,
        ..Default::default()
    };
    Ok(Plan {
        opts,
        refinement,
        noise,
        kinds,
    })
}

/// Every kind at every seed: rendered (through a map moved by `--map-noise` when asked),
/// solved (through the refined map when asked), its track written with `--tracks`.
fn render_and_solve(a: &RigAccuracyArgs, read: &RigRead, plan: &Plan) -> Result<Vec<Run>> {
    let RigRead {
        mesh,
        morph,
        rig,
        depth,
    } = read;
    let (depth, noise, opts, refinement) = (*depth, plan.noise, &plan.opts, plan.refinement);
    let kinds = &plan.kinds;
    let seeds = seeds_of(a)?;
    let mut all: Vec<Run> = Vec::new();
    let progress = super::progress::Progress::new("rig-accuracy");
    progress.units("performances rendered and solved");
    let runs: Vec<(Kind, u64)> = kinds
        .iter()
        .flat_map(|&k| seeds.iter().map(move |&s| (k, s)))
        .collect();
    let total = runs.len();
    for (i, (kind, seed)) in runs.into_iter().enumerate() {
        progress.tick(i, total);
        let st = Settings {
            kind,
            frames: a.frames,
            lead_in: a.lead_in,
            noise_px: noise,
            iod_px: a.iod,
            other_person: a.person != "same",
            other_depth: a.person == "deep",
            yaw_deg: a.yaw,
            pitch_deg: a.pitch,
            seed,
            depth,
            hold: a.hold,
        };
        // The ICT face is in centimetres.
        let elsewhere = if a.map_noise > 0.0 {
            accuracy::mapped_elsewhere(&mesh.positions, morph, rig, a.map_noise / 10.0, seed)?
        } else {
            rig.clone()
        };
        let (track, _, rows, summary) = match refinement {
            Some(r) => {
                accuracy::run_refined(rig, &elsewhere, (&mesh.positions, morph), r, &st, opts)?
            }
            None => accuracy::run_mapped(rig, &elsewhere, &st, opts)?,
        };
        if let Some(dir) = &a.tracks {
            let name = match &a.seeds {
                Some(_) => format!("{}_s{seed}", kind.name()),
                None => kind.name().to_string(),
            };
            write_track(dir, &name, rig, &track)?;
        }
        all.push((kind, seed, rows, summary));
    }
    progress.finish();
    Ok(all)
}

/// `--out`: every shape's measures, a row per kind, shape and seed.
fn write_csv(p: &std::path::Path, all: &[Run]) -> Result<()> {
    let rows = all.iter().flat_map(|(kind, seed, rows, _)| {
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
            seed: *seed,
        })
    });
    write_atomic(p, |w| write_rows(w, rows))?;
    Ok(())
}

/// One seed's summary per kind, as text or `--json`.
fn print_summaries(a: &RigAccuracyArgs, all: &[Run]) -> Result<()> {
    if a.json {
        let v: Vec<_> = all
            .iter()
            .map(|(k, _, _, s)| json!({"kind": k.name(), "summary": s}))
            .collect();
        outln!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        for (k, _, _, s) in all {
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
            if let Some(m) = &s.map {
                outln!("        {}", map_line(m));
            }
            if let Some(n) = &s.neutral {
                let [y, p, _] = n.view.yaw_pitch_roll;
                outln!(
                    "        neutral frame {} (yaw {y:.0}°, pitch {p:.0}°; first-pass expression {:.2}{}{}): truly holds {:.2} of expression at a head turn of {:.1}°",
                    n.frame,
                    n.view.activity,
                    if n.view.looks_neutral { "" } else { ", does not look neutral" },
                    if n.view.rule == keyshape_rig::NeutralRule::OwnFace {
                        "; the rig's own face: the least active frame"
                    } else {
                        ""
                    },
                    n.true_expression,
                    n.true_turn,
                );
            }
        }
    }
    Ok(())
}

/// A refined map against the render's, in a line.
fn map_line(m: &accuracy::MapTruth) -> String {
    format!(
        "landmark map against the render's: {} of {} landmarks on its vertex (before {}), median off {:.1} mm (before {:.1} mm); moved per round {:?}: {} nearer the render's vertex, {} farther",
        m.right_after,
        m.landmarks,
        m.right_before,
        10.0 * m.median_off_after,
        10.0 * m.median_off_before,
        m.moved,
        m.moved_nearer,
        m.moved_farther,
    )
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
    seed: u64,
}

/// `--seeds FIRST..LAST`, or the one `--seed`.
fn seeds_of(a: &RigAccuracyArgs) -> Result<Vec<u64>> {
    let Some(s) = &a.seeds else {
        return Ok(vec![a.seed]);
    };
    let bad = || {
        anyhow::anyhow!("--seeds '{s}': give FIRST..LAST, two seeds with the first not after the last, at most 1000 seeds")
    };
    let (x, y) = s.split_once("..").ok_or_else(bad)?;
    let (x, y): (u64, u64) = (
        x.trim().parse().map_err(|_| bad())?,
        y.trim().parse().map_err(|_| bad())?,
    );
    if x > y || y - x >= 1000 {
        return Err(bad());
    }
    Ok((x..=y).collect())
}

/// `<kind>_track.csv` and `<kind>_truth.csv` in `dir`.
fn write_track(dir: &std::path::Path, kind: &str, rig: &Rig, t: &accuracy::Track) -> Result<()> {
    keyshape_io::create_dir_all(dir)?;
    let depth = t.points.nrows() == 3 * rig.landmarks();
    let axes: &[&str] = if depth { &["x", "y", "z"] } else { &["x", "y"] };
    let head = std::iter::once("frame".to_string()).chain(
        rig.points
            .iter()
            .flat_map(|i| axes.iter().map(move |a| format!("{a}{i}"))),
    );
    write_atomic(&dir.join(format!("{kind}_track.csv")), |w| {
        write_records(w, head, frame_records(&t.points))
    })?;
    let head = std::iter::once("frame").chain(rig.names.iter().map(String::as_str));
    write_atomic(&dir.join(format!("{kind}_truth.csv")), |w| {
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
