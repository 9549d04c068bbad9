//! `kslab keys`: the key frames a heuristic chooses.

use super::input::InputArgs;
use anyhow::{Context, Result};
use clap::Args;
use keyshape_lab::keyshapes::{Analysis, KeyOptions, Method};
use keyshape_lab::solve::Solver;
use nalgebra::DMatrix;
use serde_json::json;

/// Options every key-shape command shares.
#[derive(Debug, Clone, Args)]
pub struct HeuristicArgs {
    /// Seed for kmeans and random.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// greedy with nnls/bounded: exact solves per step for this many candidates, ranked by
    /// least-squares gain (0 = every frame, exact and slow).
    #[arg(long, default_value_t = 8)]
    pub shortlist: usize,
    /// Principal components k-means clusters (overrides the N of kmeansN).
    #[arg(long)]
    pub pcs: Option<usize>,
}

impl HeuristicArgs {
    /// `method` with `--pcs` applied to k-means.
    pub fn apply(&self, method: Method) -> Method {
        match (method, self.pcs) {
            (Method::KMeans { .. }, Some(pcs)) => Method::KMeans {
                pcs: pcs.clamp(1, 64),
            },
            (m, _) => m,
        }
    }
}

/// Arguments of `kslab keys`.
#[derive(Debug, Args)]
pub struct KeysArgs {
    #[command(flatten)]
    input: InputArgs,
    /// spread, kmeans2, kmeans3, kmeansN (N principal components), hull, greedy or random.
    #[arg(long, value_parser = parse_method)]
    method: Method,
    /// Number of key shapes (hull ignores it: k is whatever the hull gives).
    #[arg(long, required_unless_present_any = ["method"], default_value_t = 0)]
    k: usize,
    /// Solver for the reported error and for greedy's choices.
    #[arg(long, default_value = "nnls", value_parser = super::solve::parse_solver)]
    solver: Solver,
    #[command(flatten)]
    heuristic: HeuristicArgs,
    /// Print JSON (frames, columns, error; k-means centres in PCA coordinates).
    #[arg(long)]
    json: bool,
}

pub fn parse_method(s: &str) -> Result<Method, String> {
    Method::parse(s).map_err(|e| e.to_string())
}

pub fn run(a: &KeysArgs) -> Result<()> {
    if a.k == 0 && a.method != Method::Hull {
        anyhow::bail!("--k is required for --method {}", a.method);
    }
    let (_, prep) = a.input.prepare()?;
    let method = a.heuristic.apply(a.method);
    let axes = keyshape_lab::keyshapes::axes_needed(&[method], a.k);
    let an = Analysis::with_axes(prep.seq.coords.clone(), prep.seq.points, axes)?;
    let opts = KeyOptions {
        solver: a.solver,
        seed: a.heuristic.seed,
        shortlist: a.heuristic.shortlist,
    };
    let sel = method.heuristic(&opts).select(&an, a.k)?;
    let frames: Vec<i64> = sel.columns.iter().map(|&c| prep.seq.frames[c]).collect();
    let e = an.error(&sel.columns, a.solver)?;
    if a.json {
        let centres = sel.centres.as_ref().map(|c| {
            c.column_iter()
                .map(|col| col.iter().copied().collect::<Vec<f64>>())
                .collect::<Vec<_>>()
        });
        let v = json!({
            "source": prep.seq.source,
            "method": method.name(),
            "k": frames.len(),
            "frames": frames,
            "columns": sel.columns,
            "solver": a.solver.name(),
            "total_sq_error": e,
            "rms": an.rms(e),
            "centres_pca": centres,
            "note": sel.centres.as_ref().map(|_| "centres_pca are k-means centres in PCA coordinates; they are not frames, the keys are the nearest frames"),
        });
        outln!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        let list: Vec<String> = frames.iter().map(i64::to_string).collect();
        outln!(
            "{} key frames by {}: {}",
            frames.len(),
            method,
            list.join(",")
        );
        outln!(
            "Eq. 5 error under {}: {e:.6e} (RMS {:.4} per point)",
            a.solver,
            an.rms(e)
        );
    }
    Ok(())
}

/// Key frames given by number, or chosen by a heuristic (shared by `template` and
/// `retarget`).
#[derive(Debug, Clone, Args)]
pub struct KeyChoiceArgs {
    /// Key frames by frame number (or choose them with --method and --k).
    #[arg(long, value_delimiter = ',', conflicts_with = "method")]
    pub keys: Vec<i64>,
    /// Heuristic choosing the key frames (default spread).
    #[arg(long, value_parser = parse_method)]
    pub method: Option<Method>,
    /// Number of key shapes for --method.
    #[arg(long, default_value_t = 12)]
    pub k: usize,
}

impl KeyChoiceArgs {
    /// Key columns of `coords` (a prepared sequence's shapes, `frames` their numbers).
    pub fn columns(
        &self,
        seq: &keyshape_lab::sequence::Sequence,
        coords: DMatrix<f64>,
        points: usize,
        opts: &KeyOptions,
    ) -> Result<Vec<usize>> {
        if !self.keys.is_empty() {
            return self
                .keys
                .iter()
                .map(|&f| {
                    seq.column_of_frame(f)
                        .with_context(|| format!("--keys {f}"))
                })
                .collect();
        }
        let m = self.method.unwrap_or(Method::Spread);
        let an = Analysis::with_axes(
            coords,
            points,
            keyshape_lab::keyshapes::axes_needed(&[m], self.k),
        )?;
        Ok(m.heuristic(opts).select(&an, self.k)?.columns)
    }
}
