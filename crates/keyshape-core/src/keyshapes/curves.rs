//! Error curves (paper 000 Fig. 6): Eq. (5) against k for each method and solver.

use super::{greedy_path, Analysis, KeyOptions, Method, GRAM_LIMIT};
use crate::error::{Error, Result};
use crate::solve::Solver;
use rayon::prelude::*;

/// One point of an error curve.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CurveRow {
    /// Method name (`spread`, `kmeans2`, …).
    pub method: String,
    /// Solver name.
    pub solver: String,
    /// Number of key shapes.
    pub k: usize,
    /// Eq. (5): Σ_t ‖Q_t − S w_t‖².
    pub total_sq_error: f64,
    /// `sqrt(total_sq_error / (frames · points))`, in input units.
    pub rms: f64,
    /// The key frames (columns); for `random`, those of the first draw; for `kmeansN-mean`
    /// (whose key shapes are cluster means), the frame nearest each centre.
    pub keys: Vec<usize>,
}

/// Draws averaged for the `random` curve (seeds seed, seed + 1, …).
pub const RANDOM_DRAWS: u64 = 5;

/// Sweeps k over `ks` for every method and solver. `hull` gives one row at its own k.
/// `random` reports the mean error of [`RANDOM_DRAWS`] seeded draws. `tick` is called once
/// per finished (method, solver) curve with (done, total).
pub fn sweep(
    an: &Analysis,
    methods: &[Method],
    ks: std::ops::RangeInclusive<usize>,
    solvers: &[Solver],
    opts: &KeyOptions,
    tick: &(dyn Fn(usize, usize) + Sync),
) -> Result<Vec<CurveRow>> {
    let (lo, hi) = (*ks.start(), *ks.end());
    if lo == 0 || lo > hi {
        return Err(Error::bad_setting(
            "k",
            format!("{lo}..{hi}"),
            format!("k range {lo}..{hi} is empty or starts at 0"),
        ));
    }
    an.check_k(hi)?;
    let total = methods.len() * solvers.len();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let jobs: Vec<(Method, Solver)> = solvers
        .iter()
        .flat_map(|&s| methods.iter().map(move |&m| (m, s)))
        .collect();
    let run = |&(m, s): &(Method, Solver)| {
        let rows = curve(an, m, lo, hi, s, opts);
        tick(
            done.fetch_add(1, std::sync::atomic::Ordering::SeqCst) + 1,
            total,
        );
        rows
    };
    // Past the Gram limit greedy holds its subsample's Gram matrix (up to 288 MB) while it
    // runs: it runs first, alone (it is parallel inside), so that memory never adds to the
    // other methods'. Shorter tracks run every curve at once. The rows are the same either
    // way, in the same order.
    let alone = |m: &Method| an.frames() > GRAM_LIMIT && matches!(m, Method::Greedy);
    let mut parts: Vec<Option<Result<Vec<CurveRow>>>> = jobs.iter().map(|_| None).collect();
    for (i, j) in jobs.iter().enumerate() {
        if alone(&j.0) {
            parts[i] = Some(run(j));
        }
    }
    let rest: Vec<(usize, Result<Vec<CurveRow>>)> = jobs
        .par_iter()
        .enumerate()
        .filter(|(_, j)| !alone(&j.0))
        .map(|(i, j)| (i, run(j)))
        .collect();
    for (i, r) in rest {
        parts[i] = Some(r);
    }
    let parts: Vec<Result<Vec<CurveRow>>> = parts.into_iter().flatten().collect();
    let mut rows = Vec::new();
    for p in parts {
        rows.extend(p?);
    }
    Ok(rows)
}

fn row(an: &Analysis, m: Method, s: Solver, k: usize, e: f64, keys: Vec<usize>) -> CurveRow {
    CurveRow {
        method: m.name(),
        solver: s.name().into(),
        k,
        total_sq_error: e,
        rms: an.rms(e),
        keys,
    }
}

/// One method's curve under one solver.
fn curve(
    an: &Analysis,
    m: Method,
    lo: usize,
    hi: usize,
    s: Solver,
    opts: &KeyOptions,
) -> Result<Vec<CurveRow>> {
    let opts = KeyOptions { solver: s, ..*opts };
    match m {
        Method::Greedy => {
            let (keys, errs) = greedy_path(an, hi, s, opts.shortlist)?;
            Ok((lo..=hi)
                .map(|k| row(an, m, s, k, errs[k - 1], keys[..k].to_vec()))
                .collect())
        }
        Method::Hull => {
            let sel = m.heuristic(&opts).select(an, 0)?;
            let e = an.error(&sel.columns, s)?;
            Ok(vec![row(an, m, s, sel.columns.len(), e, sel.columns)])
        }
        Method::Random => (lo..=hi)
            .into_par_iter()
            .map(|k| {
                let mut sum = 0.0;
                let mut first = Vec::new();
                for d in 0..RANDOM_DRAWS {
                    let o = KeyOptions {
                        seed: opts.seed.wrapping_add(d),
                        ..opts
                    };
                    let sel = m.heuristic(&o).select(an, k)?;
                    sum += an.error(&sel.columns, s)?;
                    if d == 0 {
                        first = sel.columns;
                    }
                }
                Ok(row(an, m, s, k, sum / RANDOM_DRAWS as f64, first))
            })
            .collect(),
        _ => (lo..=hi)
            .into_par_iter()
            .map(|k| {
                let sel = m.heuristic(&opts).select(an, k)?;
                let e = an.selection_error(&sel, s)?;
                Ok(row(an, m, s, k, e, sel.columns))
            })
            .collect(),
    }
}

/// The one line a user wants from a sweep: per solver (in the order met), the method with
/// the lowest error at the largest k swept, e.g. `at k = 12, lowest error: nnls greedy (RMS
/// 0.71), ls greedy (RMS 0.12)`. None for no rows.
pub fn summary(rows: &[CurveRow]) -> Option<String> {
    let kmax = rows.iter().map(|r| r.k).max()?;
    let mut solvers: Vec<&str> = Vec::new();
    for r in rows {
        if !solvers.contains(&r.solver.as_str()) {
            solvers.push(&r.solver);
        }
    }
    let parts: Vec<String> = solvers
        .iter()
        .filter_map(|s| {
            rows.iter()
                .filter(|r| r.solver == *s && r.k == kmax)
                .min_by(|a, b| a.total_sq_error.total_cmp(&b.total_sq_error))
                .map(|r| format!("{s} {} (RMS {:.4})", r.method, r.rms))
        })
        .collect();
    Some(format!("at k = {kmax}, lowest error: {}", parts.join(", ")))
}
