//! Aggregation across sequences: means with bootstrap intervals, wins, paired differences.

use super::{CurvePoint, RetargetPoint, UnitResult};
use crate::experiment::spec::RetargetSpec;
use crate::experiment::Spec;

use keyshape_core::error::{Error, Result};
use rand::{Rng, SeedableRng};
use serde::Serialize;

/// A mean across sequences and its bootstrap 95 % interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Interval {
    /// Sequences.
    pub n: usize,
    /// Mean.
    pub mean: f64,
    /// 2.5 % percentile of the resampled means.
    pub lo: f64,
    /// 97.5 % percentile of the resampled means.
    pub hi: f64,
}

/// Per method, solver and k: the error across sequences (IOD).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SummaryRow {
    /// Method.
    pub method: String,
    /// Solver.
    pub solver: String,
    /// Key shapes.
    pub k: usize,
    /// RMS per point in IOD, across sequences.
    pub rms_iod: Interval,
    /// Sequences on which this method has the lowest error at this k (ties count for each).
    pub wins: usize,
}

/// Per solver and k, two methods on the same sequences: `a − b` in IOD.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PairedRow {
    /// Solver.
    pub solver: String,
    /// Key shapes.
    pub k: usize,
    /// First method.
    pub a: String,
    /// Second method.
    pub b: String,
    /// Mean of rms_iod(a) − rms_iod(b) over sequences, with its interval.
    pub diff: Interval,
    /// Sequences on which `a`'s error is below `b`'s.
    pub a_lower: usize,
    /// Sequences on which `b`'s error is below `a`'s (the rest are ties).
    pub b_lower: usize,
}

/// Per method and solver: wins over every (sequence, k).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WinRow {
    /// Method.
    pub method: String,
    /// Solver.
    pub solver: String,
    /// (sequence, k) pairs won.
    pub wins: usize,
    /// (sequence, k) pairs contested.
    pub contests: usize,
}

/// A method that chooses its own k per sequence (the hull), and how the other methods do
/// at that k on the same sequence.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OwnKRow {
    /// Method.
    pub method: String,
    /// Solver.
    pub solver: String,
    /// Its k on each sequence, in corpus order.
    pub ks: Vec<usize>,
    /// Its error across sequences (IOD).
    pub rms_iod: Interval,
    /// Each other method at the same k on the same sequences (those whose k is in range).
    pub against: Vec<OwnKComparison>,
}

/// Another method at an own-k method's k: `other − own` in IOD.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OwnKComparison {
    /// The other method.
    pub method: String,
    /// Mean of rms_iod(other) − rms_iod(own), with its interval.
    pub diff: Interval,
    /// Sequences on which the other method's error is lower.
    pub lower: usize,
}

/// Per tracing-noise level, two solvers of `[retarget]` on the same sequences.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RetargetPairedRow {
    /// Tracing noise, IOD.
    pub trace_noise: f64,
    /// First solver.
    pub a: String,
    /// Second solver.
    pub b: String,
    /// Mean target-domain rms_iod(a) − rms_iod(b), with its interval.
    pub target_diff: Interval,
    /// The same for the source error.
    pub source_diff: Interval,
    /// Sequences on which `a`'s target error is below `b`'s.
    pub a_lower: usize,
}

/// A corpus study's result.
#[derive(Debug, Clone)]
pub struct CorpusOutcome {
    /// The spec as run.
    pub spec: Spec,
    /// Every sequence's result, in corpus order.
    pub results: Vec<UnitResult>,
    /// The curves across sequences.
    pub summary: Vec<SummaryRow>,
    /// Method against method on the same sequences.
    pub paired: Vec<PairedRow>,
    /// Wins over all k.
    pub wins: Vec<WinRow>,
    /// Methods that choose their own k (the hull), against the others at that k.
    pub own_k: Vec<OwnKRow>,
    /// Solver against solver through the target, on the same sequences.
    pub retarget_paired: Vec<RetargetPairedRow>,
}

/// Bootstrap resamples: `b` draws of `n` sequence indices with replacement, seeded.
fn resamples(n: usize, b: usize, seed: u64) -> Vec<Vec<usize>> {
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
    (0..b)
        .map(|_| (0..n).map(|_| rng.gen_range(0..n)).collect())
        .collect()
}

/// The mean of `v` and the 2.5–97.5 % percentiles (linear interpolation between order
/// statistics) of its means over `draws`.
pub fn interval(v: &[f64], draws: &[Vec<usize>]) -> Interval {
    let n = v.len();
    let mean = v.iter().sum::<f64>() / n as f64;
    let mut means: Vec<f64> = draws
        .iter()
        .map(|d| d.iter().map(|&i| v[i]).sum::<f64>() / n as f64)
        .collect();
    means.sort_by(f64::total_cmp);
    let q = |p: f64| {
        let x = p * (means.len() - 1) as f64;
        let (i, f) = (x.floor() as usize, x - x.floor());
        let j = (i + 1).min(means.len() - 1);
        means[i] + f * (means[j] - means[i])
    };
    Interval {
        n,
        mean,
        lo: q(0.025),
        hi: q(0.975),
    }
}

/// Aggregates the sequences' results (all of them, in corpus order).
pub fn aggregate(spec: &Spec, results: Vec<UnitResult>) -> Result<CorpusOutcome> {
    let n = results.len();
    if n == 0 {
        return Err(Error::invalid("the corpus has no sequence"));
    }
    let draws = resamples(n, spec.bootstrap.unwrap_or(2000), spec.seed);
    let solvers: Vec<&str> = spec.solvers.iter().map(|s| s.name()).collect();
    // Methods with an error at every k of the range on every sequence; the others (the
    // hull) choose their own k per sequence and are compared at it.
    let has_all = |m: &str| {
        results.iter().all(|r| {
            solvers.iter().all(|s| {
                (spec.k.0..=spec.k.1).all(|k| {
                    r.curves
                        .iter()
                        .any(|c| c.method == m && c.solver == *s && c.k == k)
                })
            })
        })
    };
    let (methods, own): (Vec<String>, Vec<String>) = spec
        .methods
        .iter()
        .map(|m| m.name())
        .partition(|m| has_all(m));
    let (summary, paired, wins) = compare_methods(spec, &results, &methods, &solvers, &draws)?;
    let own_k = own_k_rows(spec, &results, &own, &methods, &solvers, &draws)?;
    let retarget_paired = match &spec.retarget {
        Some(rt) => retarget_pairs(rt, &results, &draws)?,
        None => Vec::new(),
    };
    Ok(CorpusOutcome {
        spec: spec.clone(),
        results,
        summary,
        paired,
        wins,
        own_k,
        retarget_paired,
    })
}

/// The error over the inter-ocular distance of one (method, solver, k) on every sequence.
fn curve(results: &[UnitResult], m: &str, s: &str, k: usize) -> Result<Vec<f64>> {
    results
        .iter()
        .map(|r| {
            r.curves
                .iter()
                .find(|c| c.method == m && c.solver == s && c.k == k)
                .map(|c| c.rms / r.iod)
                .ok_or_else(|| {
                    Error::invalid(format!(
                        "sequence {} has no {m}/{s} error at k = {k}",
                        r.unit.name
                    ))
                })
        })
        .collect()
}

/// The methods that have every k, compared at each k: each one's interval and wins, each
/// pair's paired difference, and each one's wins over the range.
fn compare_methods(
    spec: &Spec,
    results: &[UnitResult],
    methods: &[String],
    solvers: &[&str],
    draws: &[Vec<usize>],
) -> Result<(Vec<SummaryRow>, Vec<PairedRow>, Vec<WinRow>)> {
    let n = results.len();
    let mut summary = Vec::new();
    let mut paired = Vec::new();
    let mut wins: Vec<WinRow> = Vec::new();
    if !methods.is_empty() {
        for s in solvers {
            let mut total = vec![0usize; methods.len()];
            let mut contests = 0;
            for k in spec.k.0..=spec.k.1 {
                let vals: Vec<Vec<f64>> = methods
                    .iter()
                    .map(|m| curve(results, m, s, k))
                    .collect::<Result<_>>()?;
                let mut won = vec![0usize; methods.len()];
                for u in 0..n {
                    let best = vals.iter().map(|v| v[u]).fold(f64::INFINITY, f64::min);
                    for (mi, v) in vals.iter().enumerate() {
                        if v[u] == best {
                            won[mi] += 1;
                        }
                    }
                }
                contests += n;
                for (mi, m) in methods.iter().enumerate() {
                    total[mi] += won[mi];
                    summary.push(SummaryRow {
                        method: m.clone(),
                        solver: s.to_string(),
                        k,
                        rms_iod: interval(&vals[mi], draws),
                        wins: won[mi],
                    });
                }
                for a in 0..methods.len() {
                    for b in a + 1..methods.len() {
                        let d: Vec<f64> = (0..n).map(|u| vals[a][u] - vals[b][u]).collect();
                        paired.push(PairedRow {
                            solver: s.to_string(),
                            k,
                            a: methods[a].clone(),
                            b: methods[b].clone(),
                            diff: interval(&d, draws),
                            a_lower: d.iter().filter(|x| **x < 0.0).count(),
                            b_lower: d.iter().filter(|x| **x > 0.0).count(),
                        });
                    }
                }
            }
            for (mi, m) in methods.iter().enumerate() {
                wins.push(WinRow {
                    method: m.clone(),
                    solver: s.to_string(),
                    wins: total[mi],
                    contests,
                });
            }
        }
    }
    Ok((summary, paired, wins))
}

/// The methods that choose their own k (the hull): per sequence its k and error, and the
/// other methods compared with it at that k.
fn own_k_rows(
    spec: &Spec,
    results: &[UnitResult],
    own: &[String],
    methods: &[String],
    solvers: &[&str],
    draws: &[Vec<usize>],
) -> Result<Vec<OwnKRow>> {
    let n = results.len();
    let mut own_k = Vec::new();
    for m in own {
        for s in solvers {
            // Per sequence: the method's own k and error.
            let mut at: Vec<(usize, f64)> = Vec::with_capacity(n);
            for r in results {
                let mine: Vec<&CurvePoint> = r
                    .curves
                    .iter()
                    .filter(|c| c.method == *m && c.solver == *s)
                    .collect();
                match mine.as_slice() {
                    [c] => at.push((c.k, c.rms / r.iod)),
                    _ => {
                        return Err(Error::invalid(format!(
                            "sequence {}: {m}/{s} has {} error points; a method is either on every k of the range or at one k of its own",
                            r.unit.name,
                            mine.len()
                        )))
                    }
                }
            }
            let own_errors: Vec<f64> = at.iter().map(|a| a.1).collect();
            let mut against = Vec::new();
            for c in methods {
                let mut d = Vec::new();
                for (r, &(k, e)) in results.iter().zip(&at) {
                    if let Some(p) = r
                        .curves
                        .iter()
                        .find(|p| p.method == *c && p.solver == *s && p.k == k)
                    {
                        d.push(p.rms / r.iod - e);
                    }
                }
                if d.is_empty() {
                    continue;
                }
                // Resamples of the sequences that have the comparison.
                let sub = resamples(d.len(), draws.len(), spec.seed);
                against.push(OwnKComparison {
                    method: c.clone(),
                    diff: interval(&d, &sub),
                    lower: d.iter().filter(|x| **x < 0.0).count(),
                });
            }
            own_k.push(OwnKRow {
                method: m.clone(),
                solver: s.to_string(),
                ks: at.iter().map(|a| a.0).collect(),
                rms_iod: interval(&own_errors, draws),
                against,
            });
        }
    }
    Ok(own_k)
}

/// `[retarget]`'s solvers compared pairwise at each trace noise, over the sequences.
fn retarget_pairs(
    rt: &RetargetSpec,
    results: &[UnitResult],
    draws: &[Vec<usize>],
) -> Result<Vec<RetargetPairedRow>> {
    let n = results.len();
    let mut retarget_paired = Vec::new();
    let get = |r: &UnitResult, s: &str, noise: f64| -> Result<RetargetPoint> {
        r.retarget
            .iter()
            .find(|p| p.solver == s && p.trace_noise == noise)
            .cloned()
            .ok_or_else(|| {
                Error::invalid(format!(
                    "sequence {} has no [retarget] row for {s} at trace noise {noise}",
                    r.unit.name
                ))
            })
    };
    for &noise in &rt.trace_noise {
        for a in 0..rt.solvers.len() {
            for b in a + 1..rt.solvers.len() {
                let (sa, sb) = (rt.solvers[a].name(), rt.solvers[b].name());
                let mut td = Vec::with_capacity(n);
                let mut sd = Vec::with_capacity(n);
                for r in results {
                    let (pa, pb) = (get(r, sa, noise)?, get(r, sb, noise)?);
                    td.push((pa.target_rms - pb.target_rms) / r.iod);
                    sd.push((pa.source_rms - pb.source_rms) / r.iod);
                }
                retarget_paired.push(RetargetPairedRow {
                    trace_noise: noise,
                    a: sa.to_string(),
                    b: sb.to_string(),
                    target_diff: interval(&td, draws),
                    source_diff: interval(&sd, draws),
                    a_lower: td.iter().filter(|x| **x < 0.0).count(),
                });
            }
        }
    }
    Ok(retarget_paired)
}
