//! `kslab solve`.

use super::input::InputArgs;
use anyhow::{Context, Result};
use clap::Args;
use keyshape_lab::decompose::{decompose, Decomposition};
use keyshape_lab::io::{fmt_num, write_atomic};
use keyshape_lab::sequence::Sequence;
use keyshape_lab::solve::{SolveOptions, Solver};
use serde_json::json;
use std::io::Write;
use std::path::PathBuf;

/// Arguments of `kslab solve`.
#[derive(Debug, Args)]
pub struct SolveArgs {
    #[command(flatten)]
    input: InputArgs,
    /// Key frames, by the frame numbers the file uses, e.g. `3,17,42`.
    #[arg(
        long,
        value_delimiter = ',',
        required = true,
        num_args = 1..,
        allow_negative_numbers = true
    )]
    keys: Vec<i64>,
    /// ls (Eq. 3), nnls (Eq. 4, w ≥ 0) or bounded (0 ≤ w ≤ 1).
    #[arg(long, default_value = "nnls", value_parser = parse_solver)]
    solver: Solver,
    /// Solve deltas from this neutral frame: q − N = Σ wᵢ (Sᵢ − N).
    #[arg(long, value_name = "FRAME")]
    neutral: Option<i64>,
    /// LS singular-value cutoff relative to the largest (default max(n,k)·ε).
    #[arg(long)]
    rcond: Option<f64>,
    /// Write the weights CSV here (written atomically); without it the CSV goes to stdout.
    #[arg(long, short)]
    out: Option<PathBuf>,
    /// Print a JSON summary (mean RMS, share of negative weights, max |w|, …).
    #[arg(long)]
    json: bool,
}

pub fn parse_solver(s: &str) -> Result<Solver, String> {
    Solver::parse(s).map_err(|e| e.to_string())
}

pub fn run(a: &SolveArgs) -> Result<()> {
    super::check_outputs(&[a.out.as_ref()], &[], &[a.input.file.as_deref()])?;
    super::check_json_stdout(a.json, a.out.as_ref())?;
    let progress = super::progress::Progress::new("solve");
    let (_, prep) = a.input.prepare()?;
    let seq = &prep.seq;
    let cols = super::keys::frame_columns(seq, &a.keys)?;
    let neutral = match a.neutral {
        Some(f) => Some(
            seq.column_of_frame(f)
                .with_context(|| format!("--neutral {f}"))?,
        ),
        None => None,
    };
    let mut opts = SolveOptions::new(a.solver);
    opts.rcond = a.rcond;
    let d = decompose(&seq.coords, seq.points, &cols, neutral, &opts)?;
    progress.finish();
    warn(&d);
    match &a.out {
        Some(path) => write_atomic(path, |w| write_csv(w, seq, &a.keys, &d))?,
        None if a.json => {}
        None => {
            let stdout = std::io::stdout();
            match write_csv(&mut stdout.lock(), seq, &a.keys, &d) {
                // `kslab solve … | head` closes the pipe early: not an error.
                Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {}
                r => r?,
            }
        }
    }
    if a.json {
        let v = json!({
            "source": seq.source,
            "solver": d.solver.name(),
            "keys": a.keys,
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
            "out": a.out,
        });
        outln!("{}", serde_json::to_string_pretty(&v)?);
    } else if let Some(p) = &a.out {
        sayln!(
            super::is_stdout(a.out.as_ref()),
            "{} frames, {} keys, {}: mean RMS {:.4}, negative weights {:.1}%, max |w| {:.3} → {}",
            seq.n_frames(),
            d.key_columns.len(),
            d.solver,
            d.mean_rms(),
            100.0 * d.negative_share(),
            d.max_abs_weight(),
            p.display()
        );
    }
    Ok(())
}

fn warn(d: &Decomposition) {
    let k = d.key_columns.len();
    if d.rank < k {
        eprintln!(
            "warning: the {k} key shapes span only {} dimensions (duplicate or dependent shapes); \
             LS returns the minimum-norm weights",
            d.rank
        );
    } else if d.condition > 1e8 {
        eprintln!(
            "warning: key shapes are nearly dependent (condition number {:.2e})",
            d.condition
        );
    }
    if d.unconverged > 0 {
        eprintln!(
            "warning: {} frames hit the active-set iteration cap",
            d.unconverged
        );
    }
}

fn write_csv(
    w: &mut dyn Write,
    seq: &Sequence,
    keys: &[i64],
    d: &Decomposition,
) -> std::io::Result<()> {
    let mut header = String::from("frame,rms");
    for k in keys {
        header.push_str(&format!(",w_{k}"));
    }
    writeln!(w, "{header}")?;
    let rms = d.rms();
    for (c, frame) in seq.frames.iter().enumerate() {
        write!(w, "{frame},{}", fmt_num(rms[c]))?;
        for v in d.weights.column(c).iter() {
            write!(w, ",{}", fmt_num(*v))?;
        }
        writeln!(w)?;
    }
    Ok(())
}
