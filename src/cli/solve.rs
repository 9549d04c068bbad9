//! `kslab solve`.

use super::input::InputArgs;
use anyhow::{Context, Result};
use clap::Args;
use keyshape_core::decompose::{decompose_smoothed, Decomposition};
use keyshape_core::sequence::Sequence;
use keyshape_core::solve::temporal::{segments, SmoothMode, Smoothing};
use keyshape_core::solve::{SolveOptions, Solver};
use keyshape_io::csv_out::write_records;
use keyshape_io::{fmt_num, write_atomic};
use serde_json::json;
use std::io::Write;
use std::path::PathBuf;

/// Arguments of `kslab solve`.
#[derive(Debug, Args)]
pub struct SolveArgs {
    #[command(flatten)]
    input: InputArgs,
    /// The key frames: `--keys 3,17,42` by the file's frame numbers, or chosen by
    /// `--method NAME --k K` as `kslab keys` chooses them (one of the two is required).
    #[command(flatten)]
    choice: super::keys::KeyChoiceArgs,
    #[command(flatten)]
    heuristic: super::keys::HeuristicArgs,
    /// ls (Eq. 3), nnls (Eq. 4, w ≥ 0) or bounded (0 ≤ w ≤ 1).
    #[arg(long, default_value = "nnls")]
    solver: Solver,
    /// Solve deltas from this neutral frame: q − N = Σ wᵢ (Sᵢ − N).
    /// [default: none: absolute shapes].
    #[arg(long, value_name = "FRAME")]
    neutral: Option<i64>,
    /// LS singular-value cutoff, relative to the largest singular value [default:
    /// max(n, k)·ε].
    #[arg(long)]
    rcond: Option<f64>,
    /// Write the weights CSV here (written atomically) [default: stdout].
    #[arg(long, short)]
    out: Option<PathBuf>,
    /// Print a JSON summary (mean RMS, share of negative weights, max |w|, …).
    #[arg(long)]
    pub(crate) json: bool,
    /// Draw the weights over time as a PNG here: a row per key frame, a column per frame,
    /// negative weights red and positive blue.
    /// [default: not drawn].
    #[arg(long, value_name = "FILE")]
    png: Option<PathBuf>,
    /// Temporal prior λ (≥ 0; 0 = today's per-frame weights): minimise
    /// Σ‖S w_t − q_t‖² + λ Σ‖w_t − w_{t−1}‖² (order 1) in the coordinates the solve uses
    /// (aligned; the file's with --no-align; deltas with --neutral), under the solver's
    /// constraints. λ is in squared coordinate units (px²) per unit of weight change; clips
    /// and gaps left by failed frames are not smoothed across.
    /// [default: off, the same as 0].
    #[arg(long, value_name = "LAMBDA", allow_negative_numbers = true)]
    smooth: Option<f64>,
    /// `offline` (the whole sequence at once) or `causal` (each frame from the past only,
    /// for live use). Needs --smooth [default: offline].
    #[arg(long, requires = "smooth")]
    smooth_mode: Option<SmoothMode>,
    /// 1 (first difference, penalises motion) or 2 (second difference, penalises
    /// acceleration: lags less). Needs --smooth [default: 1].
    #[arg(long, requires = "smooth")]
    smooth_order: Option<usize>,
    /// Stream: read FILE (a CSV table, gzipped or not) in passes and write each chunk of
    /// weights as soon as it is solved, in memory independent of the track's length (for
    /// hour-long tracks). The weights are exactly those of the in-memory solve; alignment
    /// costs one pass over the file per Procrustes round. Needs FILE; refuses --png,
    /// --json and the offline temporal prior (--smooth-mode causal streams).
    #[arg(long, conflicts_with_all = ["png", "json"])]
    stream: bool,
}

pub fn run(a: &SolveArgs) -> Result<()> {
    let smoothing = checked_smoothing(a)?;
    // Without --out (and --json) the weights go to standard output, as with `--out -`.
    let stdout = std::path::PathBuf::from("-");
    let out = a.out.as_ref().or((!a.json).then_some(&stdout));
    super::check_outputs(&[out, a.png.as_ref()], &[], &[a.input.file.as_deref()])?;
    super::check_json_stdout(a.json, a.out.as_ref())?;
    check_args(a)?;
    if a.stream {
        return run_stream(a, smoothing);
    }
    let progress = super::progress::Progress::new("solve");
    let mut prep = a.input.prepare_only()?;
    let cols = a
        .choice
        .columns_in_place(&mut prep.seq, &a.heuristic.options(a.solver))?;
    let seq = &prep.seq;
    let keys: Vec<i64> = cols.iter().map(|&c| seq.frames[c]).collect();
    if a.choice.keys.is_empty() {
        errln!(
            "keys by {}: {}",
            a.choice
                .method
                .unwrap_or(keyshape_core::keyshapes::Method::Spread),
            keys.iter()
                .map(i64::to_string)
                .collect::<Vec<_>>()
                .join(",")
        );
    }
    let neutral = match a.neutral {
        Some(f) => Some(
            seq.column_of_frame(f)
                .with_context(|| format!("--neutral {f}"))?,
        ),
        None => None,
    };
    let mut opts = SolveOptions::new(a.solver);
    opts.rcond = a.rcond;
    let segs = segments(&seq.frames, seq.segments.as_deref());
    let (d, smoothed) = decompose_smoothed(
        &prep,
        &cols,
        neutral,
        &opts,
        smoothing.as_ref().map(|s| (s, segs.as_slice())),
    )?;
    progress.finish();
    if let Some(r) = &smoothed {
        if r.unconverged > 0 {
            let (what, of) = match smoothing.map(|s| s.mode) {
                Some(SmoothMode::Causal) => ("frames", seq.frames.len()),
                _ => ("segments", r.segments.len()),
            };
            errln!(
                "warning: the smoothed solve did not settle on {} of {of} {what} (KKT residual {:.1e})",
                r.unconverged, r.kkt
            );
        }
    }
    warn(&d);
    if let Some(png) = &a.png {
        write_png(a, seq, &keys, &d, smoothing, png)?;
    }
    match &a.out {
        Some(path) => write_atomic(path, |w| write_csv(w, seq, &keys, &d))?,
        None if a.json => {}
        // Standard output as `--out -` is: a reader that goes away (`kslab solve … | head`)
        // ends the command quietly with none of its other outputs committed.
        None => write_atomic(std::path::Path::new("-"), |w| write_csv(w, seq, &keys, &d))?,
    }
    report(a, seq, &keys, &d, smoothing, smoothed.as_ref(), &segs)
}

/// `--smooth λ` with its order and mode, checked.
fn checked_smoothing(a: &SolveArgs) -> Result<Option<Smoothing>> {
    Ok(a.smooth
        .map(|lambda| {
            let s = Smoothing {
                lambda,
                order: a.smooth_order.unwrap_or(1),
                mode: a.smooth_mode.unwrap_or(SmoothMode::Offline),
            };
            s.check().map(|_| s)
        })
        .transpose()?)
}

/// The options that must hold together: key frames named or chosen, `--stream` with
/// `--keys`, `--rcond` for least squares only and in range.
fn check_args(a: &SolveArgs) -> Result<()> {
    // `--k` alone chooses by the default method (spread), as the help says.
    if a.choice.keys.is_empty() && a.choice.method.is_none() && a.choice.k.is_none() {
        anyhow::bail!("name the key frames: --keys 3,17,42, or --method spread --k 12 (as `kslab keys` chooses them)");
    }
    a.heuristic.check(&a.choice.methods(), a.solver)?;
    if a.stream && a.choice.keys.is_empty() {
        anyhow::bail!("--stream needs the key frames by number (--keys): choosing them needs the whole track in memory; run `kslab keys` first");
    }
    if let Some(r) = a.rcond {
        if a.solver != Solver::Ls {
            anyhow::bail!(
                "--rcond is the least-squares cutoff: it does not apply to --solver {}",
                a.solver
            );
        }
        if !(r.is_finite() && (0.0..1.0).contains(&r)) {
            anyhow::bail!(
                "--rcond {r}: give a cutoff in [0, 1) relative to the largest singular value"
            );
        }
    }
    Ok(())
}

/// The weights-over-time picture (`--png`), the key frames marked.
fn write_png(
    a: &SolveArgs,
    seq: &keyshape_core::Sequence,
    keys: &[i64],
    d: &keyshape_core::Decomposition,
    smoothing: Option<Smoothing>,
    png: &std::path::Path,
) -> Result<()> {
    let labels: Vec<String> = keys.iter().map(|k| format!("w_{k}")).collect();
    let title = format!(
        "{}: weights over time, {} keys, {}{}",
        super::input::track_label(&seq.source, a.input.points.as_deref()),
        keys.len(),
        a.solver,
        smoothing.map_or(String::new(), |s| format!(
            " (λ {} {} order {})",
            s.lambda,
            s.mode.name(),
            s.order
        ))
    );
    let pm = keyshape_pictures::render::weights::weights_picture_marked(
        &d.weights,
        &labels,
        &seq.frames,
        &title,
        keys,
    )?;
    keyshape_pictures::render::save_png(&pm, png)?;
    Ok(())
}

/// What was solved: `--json`, or one line when the weights went to a file.
fn report(
    a: &SolveArgs,
    seq: &keyshape_core::Sequence,
    keys: &[i64],
    d: &keyshape_core::Decomposition,
    smoothing: Option<Smoothing>,
    smoothed: Option<&keyshape_core::solve::temporal::Smoothed>,
    segs: &[std::ops::Range<usize>],
) -> Result<()> {
    if a.json {
        let v = json!({
            "source": seq.source,
            "solver": d.solver.name(),
            "keys": keys,
            "neutral": a.neutral,
            "frames": seq.n_frames(),
            "points": seq.points,
            "mean_rms": d.mean_rms(),
            "overall_rms": d.overall_rms(),
            "total_sq_error": d.total_sq_error(),
            "negative_share": d.negative_share(),
            "max_abs_weight": d.max_abs_weight(),
            "rank": d.rank,
            "condition": d.condition,
            "unconverged_frames": d.unconverged,
            "jitter": weight_jitter(&d.weights, segs),
            "smoothing": smoothing.map(|s| json!({
                "objective": s.objective(),
                "lambda": s.lambda,
                "order": s.order,
                "mode": s.mode.name(),
                "segments": segs.len(),
                "iterations": smoothed.as_ref().map_or(0, |r| r.iterations),
                "kkt_residual": smoothed.as_ref().map_or(0.0, |r| r.kkt),
                "unconverged_segments": smoothed.as_ref().map_or(0, |r| r.unconverged),
            })),
            "out": a.out,
        });
        outln!("{}", serde_json::to_string_pretty(&v)?);
    } else if let Some(p) = &a.out {
        sayln!(
            super::is_stdout(a.out.as_ref()),
            "{} frames, {} keys, {}{}: mean RMS {:.4} per frame (overall {:.4}), negative weights {:.1}%, max |w| {:.3} → {}",
            seq.n_frames(),
            d.key_columns.len(),
            d.solver,
            smoothing.map_or(String::new(), |s| format!(
                " with the {} order-{} temporal prior λ = {} (weight jitter {:.2e})",
                s.mode.name(),
                s.order,
                s.lambda,
                weight_jitter(&d.weights, segs)
            )),
            d.mean_rms(),
            d.overall_rms(),
            100.0 * d.negative_share(),
            d.max_abs_weight(),
            p.display()
        );
    }
    Ok(())
}

/// `--stream`'s input file and options; refuses the built-in sequence and the offline
/// prior (it solves the whole sequence at once).
fn stream_options(
    a: &SolveArgs,
    smoothing: Option<Smoothing>,
) -> Result<(&std::path::Path, keyshape_io::stream::StreamOptions)> {
    use keyshape_io::stream::StreamOptions;
    let Some(path) = a.input.file.as_deref() else {
        anyhow::bail!("--stream reads a FILE in several passes: give one (the built-in sequence is 216 frames: drop --stream)");
    };
    if let Some(sm) = &smoothing {
        if sm.mode == SmoothMode::Offline {
            anyhow::bail!(
                "--stream with --smooth: the offline prior solves the whole sequence at once; add --smooth-mode causal (each frame from the past only), or drop --stream"
            );
        }
    }
    let mut opts = SolveOptions::new(a.solver);
    opts.rcond = a.rcond;
    Ok((
        path,
        StreamOptions {
            format: a.input.format,
            dims: usize::from(a.input.dims),
            points: a.input.points.clone(),
            align: !a.input.no_align,
            keys: a.choice.keys.clone(),
            neutral: a.neutral,
            solve: opts,
            smoothing,
        },
    ))
}

/// `kslab solve --stream`: [`keyshape_io::stream::stream_solve`] into the CSV as it goes.
fn run_stream(a: &SolveArgs, smoothing: Option<Smoothing>) -> Result<()> {
    use keyshape_io::stream::stream_solve;
    let (path, so) = stream_options(a, smoothing)?;
    let header: Vec<String> = ["frame".to_string(), "rms".to_string()]
        .into_iter()
        .chain(a.choice.keys.iter().map(|k| format!("w_{k}")))
        .collect();
    // The stream's own error, kept while the writer sees only that it stopped.
    let mut failure: Option<keyshape_core::error::Error> = None;
    let mut summary = None;
    let mut fill = |w: &mut dyn Write| -> std::io::Result<()> {
        let mut out = keyshape_io::csv_out::record_writer(w);
        let mut io_err: Option<std::io::Error> = None;
        let mut first = true;
        let r = stream_solve(path, &so, &mut |f| {
            // The header goes out with the first frame: an error found while the passes
            // before the solve check the input leaves standard output empty.
            let header = first.then_some(&header).into_iter().map(|h| h.to_vec());
            first = false;
            let row = [f.frame.to_string(), fmt_num(f.rms)]
                .into_iter()
                .chain(f.weights.iter().map(|v| fmt_num(*v)))
                .collect::<Vec<_>>();
            header
                .chain(std::iter::once(row))
                .try_for_each(|r| out.write_record(r))
                .map_err(|e| {
                    let e = keyshape_io::csv_out::io_error(e);
                    let msg = e.to_string();
                    io_err = Some(e);
                    keyshape_core::error::Error::invalid(msg)
                })
        });
        let r = r.and_then(|s| {
            out.flush().map_err(|e| {
                let msg = e.to_string();
                io_err = Some(e);
                keyshape_core::error::Error::invalid(msg)
            })?;
            Ok(s)
        });
        match r {
            Ok(s) => {
                summary = Some(s);
                Ok(())
            }
            Err(e) => {
                if let Some(ioe) = io_err.take() {
                    return Err(ioe);
                }
                failure = Some(e);
                Err(std::io::Error::other("the streamed solve failed"))
            }
        }
    };
    let written = match &a.out {
        Some(p) => write_atomic(p, &mut fill).map_err(anyhow::Error::from),
        None => write_atomic(std::path::Path::new("-"), |w| {
            let mut w = std::io::BufWriter::new(w);
            fill(&mut w).and_then(|()| w.flush())
        })
        .map_err(anyhow::Error::from),
    };
    if let Some(e) = failure {
        return Err(e.into());
    }
    written?;
    let Some(s) = summary else {
        anyhow::bail!("the streamed solve stopped without a result");
    };
    warn_solve(a.choice.keys.len(), s.rank, s.condition, s.unconverged);
    if let Some(p) = &a.out {
        sayln!(
            super::is_stdout(a.out.as_ref()),
            "{} frames ({} failed, skipped), {} keys, {}, streamed in {} passes ({} Procrustes rounds): mean RMS {:.4}, max |w| {:.3} → {}",
            s.frames,
            s.failed,
            a.choice.keys.len(),
            a.solver,
            s.passes,
            s.align_rounds,
            s.mean_rms,
            s.max_abs_weight,
            p.display()
        );
    }
    Ok(())
}

pub use keyshape_core::solve::jitter::weight_jitter;

fn warn(d: &Decomposition) {
    warn_solve(d.key_columns.len(), d.rank, d.condition, d.unconverged);
}

/// The warnings of a solve on `k` keys: dependent shapes, iteration caps.
fn warn_solve(k: usize, rank: usize, condition: f64, unconverged: usize) {
    if rank < k {
        errln!(
            "warning: the {k} key shapes span only {rank} dimensions (duplicate or dependent shapes); \
             LS returns the minimum-norm weights"
        );
    } else if condition > 1e8 {
        errln!("warning: key shapes are nearly dependent (condition number {condition:.2e})");
    }
    if unconverged > 0 {
        errln!("warning: {unconverged} frames hit the active-set iteration cap");
    }
}

fn write_csv(
    w: &mut dyn Write,
    seq: &Sequence,
    keys: &[i64],
    d: &Decomposition,
) -> std::io::Result<()> {
    let header = ["frame".to_string(), "rms".to_string()]
        .into_iter()
        .chain(keys.iter().map(|k| format!("w_{k}")));
    let rms = d.rms();
    let records = seq.frames.iter().enumerate().map(|(c, frame)| {
        [frame.to_string(), fmt_num(rms[c])]
            .into_iter()
            .chain(d.weights.column(c).iter().map(|v| fmt_num(*v)))
            .collect::<Vec<_>>()
    });
    write_records(w, header, records)
}
