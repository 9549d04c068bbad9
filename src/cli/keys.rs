//! `kslab keys`: the key frames a heuristic chooses.

use super::input::InputArgs;
use anyhow::{Context, Result};
use clap::Args;
use keyshape_core::keyshapes::{Analysis, KeyOptions, Method};
use keyshape_core::solve::Solver;
use nalgebra::DMatrix;
use serde_json::json;

/// Options every key-shape command shares.
#[derive(Debug, Clone, Args)]
pub struct HeuristicArgs {
    /// Seed for kmeans and random [default: 7].
    #[arg(long)]
    pub seed: Option<u64>,
    /// greedy with nnls/bounded: exact solves per step for this many candidates, ranked by
    /// least-squares gain (0 = every frame, exact and slow) [default: 8].
    #[arg(long)]
    pub shortlist: Option<usize>,
    /// Principal components k-means clusters (overrides the N of kmeansN; 1–64).
    /// [default: the N of kmeansN].
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=64))]
    pub pcs: Option<u64>,
}

impl HeuristicArgs {
    /// `method` with `--pcs` applied to k-means.
    pub fn apply(&self, method: Method) -> Method {
        match (method, self.pcs) {
            (Method::KMeans { mean, .. }, Some(pcs)) => Method::KMeans {
                pcs: pcs as usize,
                mean,
            },
            (m, _) => m,
        }
    }

    /// Errors when an option was given that none of `methods` uses (with `solver`), so no
    /// option is silently ignored.
    pub fn check(&self, methods: &[Method], solver: Solver) -> Result<()> {
        let names = || {
            methods
                .iter()
                .map(|m| m.name())
                .collect::<Vec<_>>()
                .join(", ")
        };
        if methods.is_empty() {
            if self.pcs.is_some() || self.seed.is_some() || self.shortlist.is_some() {
                anyhow::bail!("--pcs, --seed and --shortlist apply when --method chooses the keys, not with --keys");
            }
            return Ok(());
        }
        let any = |f: fn(&Method) -> bool| methods.iter().any(f);
        if self.pcs.is_some() && !any(|m| matches!(m, Method::KMeans { .. })) {
            anyhow::bail!("--pcs applies to k-means only, not to {}", names());
        }
        if self.seed.is_some() && !any(|m| matches!(m, Method::KMeans { .. } | Method::Random)) {
            anyhow::bail!(
                "--seed applies to kmeans and random only, not to {}",
                names()
            );
        }
        if self.shortlist.is_some() && (!any(|m| *m == Method::Greedy) || solver == Solver::Ls) {
            anyhow::bail!(
                "--shortlist applies to greedy with the nnls or bounded solver only (here: {} with {solver})",
                names()
            );
        }
        Ok(())
    }

    /// The key options these arguments set.
    pub fn options(&self, solver: Solver) -> KeyOptions {
        KeyOptions {
            solver,
            seed: self.seed.unwrap_or(7),
            shortlist: self.shortlist.unwrap_or(8),
        }
    }
}

/// Arguments of `kslab keys`.
#[derive(Debug, Args)]
pub struct KeysArgs {
    #[command(flatten)]
    input: InputArgs,
    /// spread, kmeans2, kmeans3, kmeansN (N principal components), kmeansN-mean (the
    /// clusters' mean shapes, the paper's "center of mass", which are not frames), hull,
    /// greedy or random.
    #[arg(long)]
    method: Method,
    /// Number of key shapes [default: none: required, except with hull, which gives its own k].
    #[arg(long)]
    k: Option<usize>,
    /// Solver for the reported error and for greedy's choices.
    #[arg(long, default_value = "nnls")]
    solver: Solver,
    #[command(flatten)]
    heuristic: HeuristicArgs,
    /// Print JSON: key frame numbers, their positions in the sequence (`columns`, from 0),
    /// the error, and k-means centres in PCA coordinates.
    #[arg(long)]
    pub(crate) json: bool,
}

pub fn run(a: &KeysArgs) -> Result<()> {
    let k = k_for(a.method, a.k)?;
    a.heuristic.check(&[a.method], a.solver)?;
    let progress = super::progress::Progress::new("keys");
    let mut prep = a.input.prepare_only()?;
    let method = a.heuristic.apply(a.method);
    let axes = keyshape_core::keyshapes::axes_needed(&[method], k);
    // The analysis takes the coordinates; only the frame numbers and source are used after.
    let coords = std::mem::replace(&mut prep.seq.coords, nalgebra::DMatrix::zeros(0, 0));
    let an = Analysis::with_axes(coords, prep.seq.points, axes)?;
    let opts = a.heuristic.options(a.solver);
    let sel = method.heuristic(&opts).select(&an, k)?;
    let frames: Vec<i64> = sel.columns.iter().map(|&c| prep.seq.frames[c]).collect();
    let e = an.selection_error(&sel, a.solver)?;
    progress.finish();
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
            "cluster_sizes": sel.sizes,
            "key_shapes": sel.shapes.as_ref().map(|s| {
                s.column_iter()
                    .map(|col| col.iter().copied().collect::<Vec<f64>>())
                    .collect::<Vec<_>>()
            }),
            "note": sel.centres.as_ref().map(|_| if sel.shapes.is_some() {
                "the key shapes are the clusters' mean shapes (key_shapes, aligned coordinates), not frames; frames are the frames nearest each centre, for reference; centres_pca are the centres in PCA coordinates"
            } else {
                "centres_pca are k-means centres in PCA coordinates; they are not frames, the keys are the nearest frames"
            }),
        });
        outln!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        let list: Vec<String> = frames.iter().map(i64::to_string).collect();
        match &sel.sizes {
            None => outln!(
                "{} key frames by {}: {}",
                frames.len(),
                method,
                list.join(",")
            ),
            Some(sizes) => {
                let sizes: Vec<String> = sizes.iter().map(usize::to_string).collect();
                outln!(
                    "{} key shapes by {}: the clusters' mean shapes (not frames; --json gives them), of {} frames; frames nearest the centres: {}",
                    frames.len(),
                    method,
                    sizes.join(", "),
                    list.join(",")
                );
            }
        }
        outln!(
            "Eq. 5 error under {}: {e:.6e} (overall RMS {:.4} = √(E / (frames·points)), as `kslab solve` reports it beside its mean per-frame RMS)",
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
    /// Key frames by frame number [default: chosen by --method and --k].
    #[arg(
        long,
        value_delimiter = ',',
        conflicts_with = "method",
        allow_negative_numbers = true
    )]
    pub keys: Vec<i64>,
    /// Heuristic choosing the key frames [default: spread].
    #[arg(long)]
    pub method: Option<Method>,
    /// Number of key shapes for --method [default: 12; hull gives its own k].
    #[arg(long, conflicts_with = "keys")]
    pub k: Option<usize>,
}

impl KeyChoiceArgs {
    /// The heuristic that will choose the keys (none with `--keys`).
    pub fn methods(&self) -> Vec<Method> {
        if self.keys.is_empty() {
            vec![self.method.unwrap_or(Method::Spread)]
        } else {
            Vec::new()
        }
    }
}

/// Columns of the key frames `--keys` names by frame number; a frame listed twice, failed
/// or out of range is an error naming the frame.
pub fn frame_columns(
    seq: &keyshape_core::sequence::Sequence,
    frames: &[i64],
) -> Result<Vec<usize>> {
    let mut seen = std::collections::HashSet::new();
    frames
        .iter()
        .map(|&f| {
            if !seen.insert(f) {
                anyhow::bail!("--keys: frame {f} is listed twice");
            }
            seq.column_of_frame(f)
                .with_context(|| format!("--keys {f}"))
        })
        .collect()
}

/// The k a method runs with: `k` as given (required unless hull); hull refuses one.
pub fn k_for(method: Method, k: Option<usize>) -> Result<usize> {
    match (method, k) {
        (Method::Hull, Some(_)) => anyhow::bail!(
            "--method hull chooses its own k (the frames on the hull of the first two principal components): drop --k"
        ),
        (Method::Hull, None) => Ok(0),
        (_, Some(k)) => Ok(k),
        (m, None) => anyhow::bail!("--k is required for --method {m}"),
    }
}

impl KeyChoiceArgs {
    /// Key columns of `coords` (a prepared sequence's shapes, `frames` their numbers).
    pub fn columns(
        &self,
        seq: &keyshape_core::sequence::Sequence,
        coords: DMatrix<f64>,
        points: usize,
        opts: &KeyOptions,
    ) -> Result<Vec<usize>> {
        if !self.keys.is_empty() {
            return frame_columns(seq, &self.keys);
        }
        self.choose(coords, points, opts).0
    }

    /// As [`KeyChoiceArgs::columns`] on `seq`'s own coordinates, without a copy: the
    /// analysis holds them while it chooses and hands them back.
    pub fn columns_in_place(
        &self,
        seq: &mut keyshape_core::sequence::Sequence,
        opts: &KeyOptions,
    ) -> Result<Vec<usize>> {
        if !self.keys.is_empty() {
            return frame_columns(seq, &self.keys);
        }
        let coords = std::mem::replace(&mut seq.coords, DMatrix::zeros(0, 0));
        let (cols, coords) = self.choose(coords, seq.points, opts);
        seq.coords = coords;
        cols
    }

    /// The heuristic's key columns of `coords`, and `coords` back (empty if the analysis
    /// could not be built, which is then the error).
    fn choose(
        &self,
        coords: DMatrix<f64>,
        points: usize,
        opts: &KeyOptions,
    ) -> (Result<Vec<usize>>, DMatrix<f64>) {
        let m = self.method.unwrap_or(Method::Spread);
        let k = match (m, self.k) {
            (Method::Hull, _) => match k_for(m, self.k) {
                Ok(k) => k,
                Err(e) => return (Err(e), coords),
            },
            (_, k) => k.unwrap_or(12),
        };
        let an = match Analysis::with_axes(
            coords,
            points,
            keyshape_core::keyshapes::axes_needed(&[m], k),
        ) {
            Ok(an) => an,
            Err(e) => return (Err(e.into()), DMatrix::zeros(0, 0)),
        };
        let cols = m
            .heuristic(opts)
            .select(&an, k)
            .map_err(anyhow::Error::from)
            .and_then(|sel| Ok(sel.key_frames(&m, "retargeting")?.to_vec()));
        (cols, an.coords)
    }
}
