//! `kslab retarget`: weights from the source drive a target face; metrics, frames, APNG.

use super::input::InputArgs;
use super::keys::{HeuristicArgs, KeyChoiceArgs};
use anyhow::{Context, Result};
use clap::Args;
use keyshape_core::decompose::Prepared;
use keyshape_core::sequence::Sequence;
use keyshape_core::solve::Solver;
use keyshape_io::csv_out::{pose_cells, write_records, POSE_COLUMNS};
use keyshape_io::{fmt_num, write_atomic};
use keyshape_retarget::regions::{plan, Regions};
use keyshape_retarget::setup::{builtin_target, polylines_for};
use keyshape_retarget::target::TargetSet;
use keyshape_retarget::{retarget, retarget_errors, KeyPlan, Retargeted, Target};
use serde_json::json;

mod pictures;
use pictures::{pictures, write_weights_png};
use std::io::Write;
use std::path::PathBuf;

/// Arguments of `kslab retarget`.
#[derive(Debug, Args)]
pub struct RetargetArgs {
    #[command(flatten)]
    input: InputArgs,
    #[command(flatten)]
    choice: KeyChoiceArgs,
    /// ls, nnls or bounded.
    #[arg(long, default_value = "nnls")]
    solver: Solver,
    /// Target key shapes: a JSON target set or an SVG from `kslab template` [default: the
    /// built-in cartoon face, a smooth warp of the source, which also gives a ground truth].
    #[arg(long)]
    target: Option<PathBuf>,
    /// Built-in target only: hand-tracing noise on each target key shape, as a fraction of
    /// the inter-ocular distance (paper 000's traced lip shapes; 0 = exact warp).
    #[arg(long, default_value_t = 0.0)]
    trace_noise: f64,
    /// Delta mode from this neutral frame: B = N_B + Σ wᵢ (Bᵢ − N_B).
    /// [default: none: absolute key shapes].
    #[arg(long, value_name = "FRAME")]
    neutral: Option<i64>,
    /// Face regions, each with its own key shapes (`builtin`, or a regions JSON file).
    /// [default: none: the whole face as one region].
    #[arg(long)]
    regions: Option<String>,
    #[command(flatten)]
    heuristic: HeuristicArgs,
    /// Write per-frame weights and errors as CSV.
    /// [default: not written].
    #[arg(long, short)]
    out: Option<PathBuf>,
    /// Write one PNG per frame here.
    /// [default: not written].
    #[arg(long)]
    png_dir: Option<PathBuf>,
    /// Draw the weights over time as a PNG here: a row per key shape (per region with
    /// --regions), a column per frame, negative weights red and positive blue.
    /// [default: not drawn].
    #[arg(long, value_name = "FILE")]
    png: Option<PathBuf>,
    /// Write an animated PNG at the sequence's frame rate.
    /// [default: not written].
    #[arg(long)]
    apng: Option<PathBuf>,
    /// Head motion (removed by alignment) in the outputs: `apply` re-applies it to the
    /// pictures (the target follows the source's scaled 2-D translation and rotation; a
    /// target with other points, relative to the first frame about its own centre) and
    /// adds its per-frame pose to `--out` (head_scale, head_angle_deg, head_tx, head_ty);
    /// `none` leaves every output in aligned coordinates. Default `apply`; refused with
    /// --no-align, where no head motion was taken out.
    #[arg(long, value_parser = ["apply", "none"])]
    head_motion: Option<String>,
    /// Print source RMS, target-domain RMS and jitter as JSON.
    #[arg(long)]
    pub(crate) json: bool,
}

/// The target set of `--target` (JSON or an SVG template), if given.
fn read_target(a: &RetargetArgs) -> Result<Option<TargetSet>> {
    let Some(path) = &a.target else {
        return Ok(None);
    };
    Ok(Some(
        if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("svg"))
        {
            keyshape_retarget::svg::read_template(path)?
        } else {
            TargetSet::read_json(path)?
        },
    ))
}

fn target_for(
    a: &RetargetArgs,
    seq: &Sequence,
    prep: &Prepared,
    set: Option<&TargetSet>,
    key_frames: &[i64],
) -> Result<(Target, Vec<Vec<usize>>)> {
    let (Some(path), Some(set)) = (&a.target, set) else {
        let layout_lines = prep
            .layout
            .as_ref()
            .map(|l| polylines_for(l, &prep.point_indices))
            .unwrap_or_default();
        let (g, iod) = builtin_target(seq, prep)?;
        return Ok((
            Target::Warp {
                g,
                trace_noise: a.trace_noise * iod,
            },
            layout_lines,
        ));
    };
    let keys = set
        .for_frames(key_frames)
        .with_context(|| format!("{}", path.display()))?;
    let neutral = set
        .neutral
        .as_ref()
        .map(|n| nalgebra::DVector::from_vec(n.coords.clone()));
    Ok((Target::Shapes { keys, neutral }, set.polylines.clone()))
}

pub fn run(a: &RetargetArgs) -> Result<()> {
    super::check_outputs(
        &[a.out.as_ref(), a.apng.as_ref(), a.png.as_ref()],
        &[a.png_dir.as_ref()],
        &[a.input.file.as_deref(), a.target.as_deref()],
    )?;
    check_options(a)?;
    let progress = super::progress::Progress::new("retarget");
    progress.step("retarget: reading");
    // The raw track is kept only where it is read again: per-frame pictures, and the
    // built-in target of a point subset (it is made from the whole face). Otherwise the
    // track is aligned in place and held once.
    let pictures_asked = a.png_dir.is_some() || a.apng.is_some();
    let (seq, mut prep) = if pictures_asked || a.input.points.is_some() {
        let (seq, prep) = a.input.prepare()?;
        (Some(seq), prep)
    } else {
        (None, a.input.prepare_only()?)
    };
    progress.step("retarget: key shapes and weights");
    let opts = a.heuristic.options(a.solver);
    let neutral = a
        .neutral
        .map(|f| {
            prep.seq
                .column_of_frame(f)
                .with_context(|| format!("--neutral {f}"))
        })
        .transpose()?;
    let set = read_target(a)?;
    let chosen = !a.choice.keys.is_empty() || a.choice.method.is_some();
    check_with_target(a, set.is_some(), chosen)?;
    // The built-in target is made now, so the raw track can go before the key choice:
    // only the per-frame pictures need it after.
    let builtin = match (&a.target, &set) {
        (Some(_), Some(_)) => None,
        _ => Some(target_for(
            a,
            seq.as_ref().unwrap_or(&prep.seq),
            &prep,
            None,
            &[],
        )?),
    };
    let seq = seq.filter(|_| pictures_asked);
    // The global key choice works on the aligned coordinates themselves (no copy).
    let global = match &a.regions {
        None if set.is_none() || chosen => Some(a.choice.columns_in_place(&mut prep.seq, &opts)?),
        _ => None,
    };
    let head = match a.head_motion.as_deref() {
        Some("none") => None,
        _ => prep.head.as_deref(),
    };
    let s = &prep.seq;
    let plan_keys = key_plan(a, &prep, set.as_ref(), chosen, global, &opts)?;
    let (key_frames, columns, keys_json) = key_names(&plan_keys, s);
    if let (Some(set), Some(path)) = (&set, &a.target) {
        check_target_keys(a, set, path, &key_frames)?;
    }
    let (target, target_lines) = match builtin {
        Some(t) => t,
        None => {
            let set = set.as_ref().context("a target set")?;
            target_for(a, &prep.seq, &prep, Some(set), &key_frames)?
        }
    };
    // Per-frame pictures need the reconstructions and the raw track; the CSV and the
    // summary need only the weights and the per-frame errors.
    let r = if pictures_asked {
        retarget(&s.coords, s.dims, &plan_keys, &target, neutral, a.solver)?
    } else {
        retarget_errors(&s.coords, s.dims, &plan_keys, &target, neutral, a.solver)?
    };
    if r.unconverged > 0 {
        errln!(
            "warning: {} did not converge on {} frames (iteration cap); their weights are the last iterate",
            a.solver, r.unconverged
        );
    }
    if let Some(p) = &a.out {
        write_atomic(p, |w| write_csv(w, s, &r, &columns, head))?;
    }
    report(a, s, &r, &plan_keys, keys_json, key_frames.len(), head)?;
    if let Some(png) = &a.png {
        write_weights_png(a, s, &r, &columns, png)?;
    }
    if let Some(seq) = &seq {
        progress.step("retarget: pictures");
        pictures(a, seq, &prep, head, &r, &target_lines, &progress)?;
    }
    Ok(())
}

/// A target file that the request does not fit: `--regions` (each region picks its own
/// key frames) or `--k` without `--method` (the key frames are the target's own).
fn check_with_target(a: &RetargetArgs, has_target: bool, chosen: bool) -> Result<()> {
    if has_target && a.regions.is_some() {
        anyhow::bail!(
            "--regions works with the built-in target only (each region picks its own key frames)"
        );
    }
    if has_target && !chosen && a.choice.k.is_some() {
        anyhow::bail!("--k applies with --method; without it the key frames are the target's own");
    }
    Ok(())
}

/// The target file `path` must hold a key shape for exactly the chosen `key_frames`.
fn check_target_keys(
    a: &RetargetArgs,
    set: &TargetSet,
    path: &std::path::Path,
    key_frames: &[i64],
) -> Result<()> {
    let mut have: Vec<i64> = set.keys.iter().map(|k| k.frame).collect();
    let mut want = key_frames.to_vec();
    have.sort_unstable();
    want.sort_unstable();
    if have != want {
        anyhow::bail!(
            "{} holds key shapes for frames {have:?}, but {} chose frames {want:?}: drop --keys/--method to use the target's own frames",
            path.display(),
            if a.choice.keys.is_empty() { "--method" } else { "--keys" }
        );
    }
    Ok(())
}

/// The summary: as JSON with `--json`, else two lines (the errors and weights, and what
/// became of the head motion).
fn report(
    a: &RetargetArgs,
    s: &Sequence,
    r: &Retargeted,
    plan_keys: &KeyPlan,
    keys_json: serde_json::Value,
    n_keys: usize,
    head: Option<&[keyshape_core::align::Similarity]>,
) -> Result<()> {
    let jitter = keyshape_core::solve::jitter::weight_jitter_all(
        &r.weights,
        &keyshape_core::solve::temporal::segments(&s.frames, s.segments.as_deref()),
    );
    let summary = json!({
        "source": s.source,
        "solver": a.solver.name(),
        "keys": keys_json,
        "regions": match plan_keys { KeyPlan::Regions(p, _) => Some(p.names.clone()), _ => None },
        "frames": s.n_frames(),
        "source_rms": r.source_rms(),
        "target_rms": r.target_rms(),
        "jitter": jitter,
        "negative_share": r.negative_share(),
        "unconverged_frames": r.unconverged,
        "target": a.target.as_ref().map_or("builtin:cartoon".to_string(), |p| p.display().to_string()),
        "head_motion": match (head, r.target_points * s.dims == s.coords.nrows()) {
            (None, _) if a.input.no_align => "kept in the coordinates (--no-align)",
            (None, _) => "none (aligned coordinates)",
            (Some(_), true) => "applied: pictures in image coordinates, per-frame pose columns in --out",
            (Some(_), false) => "applied relative to the first frame (the target has its own points): pictures follow the source head, per-frame pose columns in --out",
        },
    });
    if a.json {
        outln!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        let t = r
            .target_rms()
            .map_or("n/a (no ground truth)".to_string(), |v| format!("{v:.4}"));
        sayln!(
            super::is_stdout(a.out.as_ref()),
            "{} frames, {} keys, {}: source RMS {:.4}, target RMS {t}, jitter {:.3e}, negative weights {:.1}%",
            s.n_frames(),
            n_keys,
            a.solver,
            r.source_rms(),
            jitter,
            100.0 * r.negative_share()
        );
        sayln!(
            super::is_stdout(a.out.as_ref()),
            "head motion: {}",
            summary["head_motion"].as_str().unwrap_or("")
        );
    }
    Ok(())
}

/// The options that cannot go together, refused before anything is read.
fn check_options(a: &RetargetArgs) -> Result<()> {
    super::check_json_stdout(a.json, a.out.as_ref())?;
    a.heuristic.check(&a.choice.methods(), a.solver)?;
    if a.regions.is_some() && a.choice.k.is_some() {
        anyhow::bail!("--regions gives each region its own k (from the regions file): drop --k");
    }
    if a.trace_noise != 0.0 && a.target.is_some() {
        anyhow::bail!("--trace-noise applies to the built-in target only, not to --target");
    }
    if !(a.trace_noise.is_finite() && (0.0..=1.0).contains(&a.trace_noise)) {
        anyhow::bail!(
            "--trace-noise {:?} is not a fraction of the inter-ocular distance in [0, 1]",
            a.trace_noise
        );
    }
    if a.input.no_align && a.head_motion.is_some() {
        anyhow::bail!("--head-motion does not apply with --no-align: no head motion is taken out, so the outputs keep the file's own coordinates");
    }
    Ok(())
}

/// The key frames: the target set's own frames, the global choice, or one choice per region.
fn key_plan(
    a: &RetargetArgs,
    prep: &Prepared,
    set: Option<&TargetSet>,
    chosen: bool,
    global: Option<Vec<usize>>,
    opts: &keyshape_core::keyshapes::KeyOptions,
) -> Result<KeyPlan> {
    let s = &prep.seq;
    Ok(match (&a.regions, set) {
        // A target set stands for the frames it was drawn from: those are the keys, unless
        // --keys or --method asks for others (then the frames must match, said below).
        (None, Some(set)) if !chosen => {
            let path = a.target.as_deref().unwrap_or(std::path::Path::new(""));
            let cols = set
                .keys
                .iter()
                .map(|k| {
                    s.column_of_frame(k.frame).with_context(|| {
                        format!(
                            "{}: key shape for frame {} does not fit this sequence",
                            path.display(),
                            k.frame
                        )
                    })
                })
                .collect::<Result<Vec<_>>>()?;
            KeyPlan::Global(cols)
        }
        (None, _) => KeyPlan::Global(global.context("the global key choice")?),
        (Some(r), _) => {
            let layout = prep
                .layout
                .as_ref()
                .context("--regions needs a known layout (468 or 68 points)")?;
            let regions = if r == "builtin" {
                Regions::builtin(layout)?
            } else {
                Regions::read(std::path::Path::new(r))?
            };
            let mean = s.coords.column_mean();
            let p = plan(
                &regions,
                layout,
                &prep.point_indices,
                mean.as_slice(),
                s.dims,
            )?;
            if !a.choice.keys.is_empty() {
                anyhow::bail!("--regions picks key frames per region: use --method, not --keys");
            }
            let mut keys = Vec::new();
            for (members, &k) in p.members.iter().zip(&p.k) {
                let sub = s.select_points(members)?;
                let choice = KeyChoiceArgs {
                    // hull gives each region the k of its hull.
                    k: (a.choice.method != Some(keyshape_core::keyshapes::Method::Hull))
                        .then_some(k),
                    ..a.choice.clone()
                };
                keys.push(choice.columns(s, sub.coords, sub.points, opts)?);
            }
            KeyPlan::Regions(p, keys)
        }
    })
}

/// The key frames, one weight column name per key (by frame, and by region, which may share
/// frames), and the keys as the JSON summary gives them.
fn key_names(plan_keys: &KeyPlan, s: &Sequence) -> (Vec<i64>, Vec<String>, serde_json::Value) {
    let all_keys: Vec<usize> = match plan_keys {
        KeyPlan::Global(k) => k.clone(),
        KeyPlan::Regions(_, ks) => ks.iter().flatten().copied().collect(),
        KeyPlan::Shapes(_) => Vec::new(),
    };
    let key_frames: Vec<i64> = all_keys.iter().map(|&c| s.frames[c]).collect();
    // One weight column per key, named by frame (and by region, which may share frames).
    let columns: Vec<String> = match plan_keys {
        KeyPlan::Global(k) => k.iter().map(|&c| format!("w_{}", s.frames[c])).collect(),
        KeyPlan::Regions(p, ks) => p
            .names
            .iter()
            .zip(ks)
            .flat_map(|(n, k)| k.iter().map(move |&c| format!("{n}/w_{}", s.frames[c])))
            .collect(),
        KeyPlan::Shapes(m) => (0..m.ncols()).map(|j| format!("w_mean{j}")).collect(),
    };
    let keys_json = match plan_keys {
        KeyPlan::Global(_) | KeyPlan::Shapes(_) => json!(key_frames),
        KeyPlan::Regions(p, ks) => serde_json::Value::Object(
            p.names
                .iter()
                .zip(ks)
                .map(|(n, k)| {
                    (
                        n.clone(),
                        json!(k.iter().map(|&c| s.frames[c]).collect::<Vec<_>>()),
                    )
                })
                .collect(),
        ),
    };
    (key_frames, columns, keys_json)
}

fn write_csv(
    w: &mut dyn Write,
    s: &Sequence,
    r: &Retargeted,
    columns: &[String],
    motion: Option<&[keyshape_core::align::Similarity]>,
) -> std::io::Result<()> {
    let pose: &[&str] = if motion.is_some() { &POSE_COLUMNS } else { &[] };
    let header = ["frame", "source_rms", "target_rms"]
        .into_iter()
        .chain(columns.iter().map(String::as_str))
        .chain(pose.iter().copied());
    let trms = r.target_rms_per_frame();
    let records = s.frames.iter().enumerate().map(|(t, frame)| {
        let src = (r.source_sq[t] / r.points as f64).sqrt();
        let tg = trms.as_ref().map_or(String::new(), |v| fmt_num(v[t]));
        let mut row = vec![frame.to_string(), fmt_num(src), tg];
        for wm in &r.weights {
            row.extend(wm.column(t).iter().map(|v| fmt_num(*v)));
        }
        if let Some(m) = motion {
            row.extend(pose_cells(&m[t]));
        }
        row
    });
    write_records(w, header, records)
}
