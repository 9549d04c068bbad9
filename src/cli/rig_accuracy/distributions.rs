//! `kslab rig-accuracy --seeds`: each kind's measures as distributions over the seeds
//! (median, 10th or 90th percentile, worst), printed or as `--json`.

use super::{RigAccuracyArgs, Run};
use anyhow::Result;
use keyshape_rig::accuracy::{self, Kind, Summary};
use serde_json::json;

/// The `q`-quantile of `v` (nearest rank; `v` not empty).
fn quantile(v: &[f64], q: f64) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let i = ((q * s.len() as f64).ceil() as usize).clamp(1, s.len()) - 1;
    s[i]
}

/// A measure over the seeds where more is better (r): median, 10th percentile, worst.
fn higher(v: &[f64]) -> serde_json::Value {
    let min = v.iter().copied().fold(f64::INFINITY, f64::min);
    json!({"median": quantile(v, 0.5), "p10": quantile(v, 0.1), "worst": min})
}

/// A measure over the seeds where less is better (errors): median, 90th percentile, worst.
fn lower(v: &[f64]) -> serde_json::Value {
    let max = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    json!({"median": quantile(v, 0.5), "p90": quantile(v, 0.9), "worst": max})
}

/// Per kind, each summary measure as a distribution over the seeds.
pub(super) fn print_distributions(a: &RigAccuracyArgs, all: &[Run]) -> Result<()> {
    let mut kinds: Vec<Kind> = all.iter().map(|x| x.0).collect();
    kinds.dedup();
    let out: Vec<serde_json::Value> = kinds
        .into_iter()
        .map(|k| {
            let runs: Vec<(u64, &Summary)> = all
                .iter()
                .filter(|x| x.0 == k)
                .map(|x| (x.1, &x.3))
                .collect();
            distribution(k, &runs)
        })
        .collect();
    if a.json {
        outln!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    for v in &out {
        let f = |m: &str, k: &str| v[m][k].as_f64().unwrap_or(f64::NAN);
        outln!(
            "{:<7} {} seeds · mean r median {:.3} p10 {:.3} worst {:.3} · worst r median {:.3} p10 {:.3} worst {:.3} (seed {}, {}) · RMSE median {:.3} p90 {:.3} worst {:.3} · idle max median {:.2} p90 {:.2} worst {:.2}",
            v["kind"].as_str().unwrap_or(""),
            v["seeds"].as_array().map_or(0, Vec::len),
            f("mean_r", "median"),
            f("mean_r", "p10"),
            f("mean_r", "worst"),
            f("worst_r", "median"),
            f("worst_r", "p10"),
            f("worst_r", "worst"),
            v["lowest_worst_r"]["seed"],
            v["lowest_worst_r"]["shape"].as_str().unwrap_or(""),
            f("rmse", "median"),
            f("rmse", "p90"),
            f("rmse", "worst"),
            f("max_idle", "median"),
            f("max_idle", "p90"),
            f("max_idle", "worst"),
        );
        if v["map"].is_object() {
            let m = |m: &str, k: &str| v["map"][m][k].as_f64().unwrap_or(f64::NAN);
            outln!(
                "        landmark map against the render's: on its vertex median {:.0} % (before {:.0} %), p10 {:.0} % · median landmark off, median {:.1} mm (before {:.1} mm), p90 {:.1} mm · moved, over the seeds: {} nearer the render's vertex, {} farther",
                100.0 * m("right_after", "median"),
                100.0 * m("right_before", "median"),
                100.0 * m("right_after", "p10"),
                m("median_off_mm_after", "median"),
                m("median_off_mm_before", "median"),
                m("median_off_mm_after", "p90"),
                v["map"]["moved_nearer"],
                v["map"]["moved_farther"],
            );
        }
        if v["neutral"].is_object() {
            let n = |m: &str, k: &str| v["neutral"][m][k].as_f64().unwrap_or(f64::NAN);
            outln!(
                "        neutral frame: true expression (weights summed) median {:.2} p90 {:.2} worst {:.2} · true head turn median {:.1}° p90 {:.1}° worst {:.1}° · no candidate looked neutral on {} seeds",
                n("true_expression", "median"),
                n("true_expression", "p90"),
                n("true_expression", "worst"),
                n("true_turn", "median"),
                n("true_turn", "p90"),
                n("true_turn", "worst"),
                v["neutral"]["warned"],
            );
        }
    }
    Ok(())
}

/// One kind's measures over its seeds (`runs`: seed and summary), as the `--json` object
/// the text is printed from.
fn distribution(k: Kind, runs: &[(u64, &Summary)]) -> serde_json::Value {
    let col = |f: &dyn Fn(&Summary) -> f64| runs.iter().map(|(_, s)| f(s)).collect::<Vec<f64>>();
    let (mean_r, worst_r, rmse, idle) = (
        col(&|s| s.mean_r),
        col(&|s| s.worst_r),
        col(&|s| s.rmse),
        col(&|s| s.max_idle),
    );
    // The shape that is worst on the most seeds.
    let mut counts: Vec<(&str, usize)> = Vec::new();
    for (_, s) in runs {
        match counts.iter_mut().find(|c| c.0 == s.worst_shape) {
            Some(c) => c.1 += 1,
            None => counts.push((&s.worst_shape, 1)),
        }
    }
    counts.sort_by(|x, y| y.1.cmp(&x.1).then(x.0.cmp(y.0)));
    let worst_seed = runs
        .iter()
        .min_by(|x, y| x.1.worst_r.total_cmp(&y.1.worst_r))
        .map(|(seed, s)| (*seed, s.worst_shape.clone()));
    json!({
        "kind": k.name(),
        "neutral": neutral_distribution(runs),
        "map": map_distribution(runs),
                        "seeds": runs.iter().map(|(s, _)| *s).collect::<Vec<_>>(),
        "mean_r": higher(&mean_r),
        "worst_r": higher(&worst_r),
        "rmse": lower(&rmse),
        "max_idle": lower(&idle),
        "most_often_worst": counts.first().map(|c| json!({"shape": c.0, "seeds": c.1})),
        "lowest_worst_r": worst_seed.map(|(seed, shape)| json!({"seed": seed, "shape": shape})),
        "per_seed": runs.iter().map(|(seed, s)| json!({"seed": seed, "summary": s})).collect::<Vec<_>>(),
    })
}

/// The chosen neutral frames' truth over the seeds (None without an identity).
fn neutral_distribution(runs: &[(u64, &Summary)]) -> Option<serde_json::Value> {
    let neutral: Vec<&accuracy::NeutralTruth> = runs
        .iter()
        .filter_map(|(_, s)| s.neutral.as_ref())
        .collect();
    (!neutral.is_empty()).then(|| {
        let expr: Vec<f64> = neutral.iter().map(|n| n.true_expression).collect();
        let turn: Vec<f64> = neutral.iter().map(|n| n.true_turn).collect();
        json!({
            "true_expression": lower(&expr),
            "true_turn": lower(&turn),
            "warned": neutral.iter().filter(|n| !n.view.looks_neutral).count(),
        })
    })
}

/// The refined map against the render's over the seeds (None without `--map-noise`).
fn map_distribution(runs: &[(u64, &Summary)]) -> Option<serde_json::Value> {
    let maps: Vec<&accuracy::MapTruth> = runs.iter().filter_map(|(_, s)| s.map.as_ref()).collect();
    (!maps.is_empty()).then(|| {
        let share = |f: &dyn Fn(&accuracy::MapTruth) -> usize| -> Vec<f64> {
            maps.iter()
                .map(|m| f(m) as f64 / m.landmarks.max(1) as f64)
                .collect()
        };
        let mm = |f: &dyn Fn(&accuracy::MapTruth) -> f64| -> Vec<f64> {
            maps.iter().map(|m| 10.0 * f(m)).collect()
        };
        json!({
            "right_before": higher(&share(&|m| m.right_before)),
            "right_after": higher(&share(&|m| m.right_after)),
            "median_off_mm_before": lower(&mm(&|m| m.median_off_before)),
            "median_off_mm_after": lower(&mm(&|m| m.median_off_after)),
            "moved_nearer": maps.iter().map(|m| m.moved_nearer).sum::<usize>(),
            "moved_farther": maps.iter().map(|m| m.moved_farther).sum::<usize>(),
        })
    })
}
