//! Writes a corpus study's report (the same files from a whole run and from `kslab merge`).

use crate::experiment::corpus::{CorpusOutcome, Interval};
use crate::plot::{interval_plot, IntervalCurve, Series, Style};
use crate::render::{render_plot, save_png};
use keyshape_core::error::Result;
use keyshape_io::{fmt_num, write_atomic};
use serde_json::json;
use std::io::Write;
use std::path::{Path, PathBuf};

fn iv(i: &Interval) -> String {
    format!("{},{},{}", fmt_num(i.mean), fmt_num(i.lo), fmt_num(i.hi))
}

/// Writes `corpus_*.csv`, `corpus_<solver>.png`, `corpus_retarget.png` and `report.json`
/// into `dir`; returns the files written.
pub fn write_corpus(o: &CorpusOutcome, dir: &Path) -> Result<Vec<PathBuf>> {
    keyshape_io::create_dir_all(dir)?;
    let mut files = Vec::new();
    let mut put = |name: &str, fill: &dyn Fn(&mut dyn Write) -> std::io::Result<()>| {
        let p = dir.join(name);
        write_atomic(&p, |w| fill(w))?;
        files.push(p);
        Ok::<(), keyshape_core::error::Error>(())
    };
    put("corpus_sequences.csv", &|w| {
        writeln!(w, "sequence,input,clip,frames,points,iod")?;
        for r in &o.results {
            writeln!(
                w,
                "{},{},{},{},{},{}",
                r.unit.name,
                r.unit.input,
                r.unit.clip.as_deref().unwrap_or(""),
                r.frames,
                r.points,
                fmt_num(r.iod)
            )?;
        }
        Ok(())
    })?;
    if !o.summary.is_empty() {
        put("corpus_curves.csv", &|w| {
            writeln!(w, "sequence,method,solver,k,total_sq_error,rms,rms_iod")?;
            for r in &o.results {
                for c in &r.curves {
                    writeln!(
                        w,
                        "{},{},{},{},{},{},{}",
                        r.unit.name,
                        c.method,
                        c.solver,
                        c.k,
                        fmt_num(c.total_sq_error),
                        fmt_num(c.rms),
                        fmt_num(c.rms / r.iod)
                    )?;
                }
            }
            Ok(())
        })?;
        put("corpus_summary.csv", &|w| {
            writeln!(w, "method,solver,k,sequences,mean_rms_iod,lo95,hi95,wins")?;
            for r in &o.summary {
                writeln!(
                    w,
                    "{},{},{},{},{},{}",
                    r.method,
                    r.solver,
                    r.k,
                    r.rms_iod.n,
                    iv(&r.rms_iod),
                    r.wins
                )?;
            }
            Ok(())
        })?;
        put("corpus_paired.csv", &|w| {
            writeln!(
                w,
                "solver,k,method_a,method_b,sequences,mean_diff_iod,lo95,hi95,a_lower,b_lower"
            )?;
            for r in &o.paired {
                writeln!(
                    w,
                    "{},{},{},{},{},{},{},{}",
                    r.solver,
                    r.k,
                    r.a,
                    r.b,
                    r.diff.n,
                    iv(&r.diff),
                    r.a_lower,
                    r.b_lower
                )?;
            }
            Ok(())
        })?;
        put("corpus_wins.csv", &|w| {
            writeln!(w, "method,solver,wins,contests")?;
            for r in &o.wins {
                writeln!(w, "{},{},{},{}", r.method, r.solver, r.wins, r.contests)?;
            }
            Ok(())
        })?;
    }
    if !o.own_k.is_empty() {
        put("corpus_own_k.csv", &|w| {
            writeln!(w, "method,solver,sequences,mean_k,mean_rms_iod,lo95,hi95,compared_with,compared_sequences,mean_diff_iod,diff_lo95,diff_hi95,other_lower")?;
            for r in &o.own_k {
                let mean_k = r.ks.iter().sum::<usize>() as f64 / r.ks.len() as f64;
                let head = format!(
                    "{},{},{},{},{}",
                    r.method,
                    r.solver,
                    r.rms_iod.n,
                    fmt_num(mean_k),
                    iv(&r.rms_iod)
                );
                if r.against.is_empty() {
                    writeln!(w, "{head},,,,,,")?;
                }
                for c in &r.against {
                    writeln!(
                        w,
                        "{head},{},{},{},{}",
                        c.method,
                        c.diff.n,
                        iv(&c.diff),
                        c.lower
                    )?;
                }
            }
            Ok(())
        })?;
    }
    if o.spec.retarget.is_some() {
        put("corpus_retarget.csv", &|w| {
            writeln!(w, "sequence,solver,trace_noise,source_rms,target_rms,source_rms_iod,target_rms_iod,negative_share,max_abs_weight")?;
            for r in &o.results {
                for p in &r.retarget {
                    writeln!(
                        w,
                        "{},{},{},{},{},{},{},{},{}",
                        r.unit.name,
                        p.solver,
                        fmt_num(p.trace_noise),
                        fmt_num(p.source_rms),
                        fmt_num(p.target_rms),
                        fmt_num(p.source_rms / r.iod),
                        fmt_num(p.target_rms / r.iod),
                        fmt_num(p.negative_share),
                        fmt_num(p.max_abs_weight)
                    )?;
                }
            }
            Ok(())
        })?;
        put("corpus_retarget_paired.csv", &|w| {
            writeln!(w, "trace_noise,solver_a,solver_b,sequences,mean_target_diff_iod,lo95,hi95,mean_source_diff_iod,source_lo95,source_hi95,a_lower_target")?;
            for r in &o.retarget_paired {
                writeln!(
                    w,
                    "{},{},{},{},{},{},{}",
                    fmt_num(r.trace_noise),
                    r.a,
                    r.b,
                    r.target_diff.n,
                    iv(&r.target_diff),
                    iv(&r.source_diff),
                    r.a_lower
                )?;
            }
            Ok(())
        })?;
    }
    let mut figures = Vec::new();
    if o.spec.png {
        let n = o.results.len();
        for s in &o.spec.solvers {
            let curves: Vec<IntervalCurve> = o
                .spec
                .methods
                .iter()
                .map(|m| {
                    let m = m.name();
                    let pts = o
                        .summary
                        .iter()
                        .filter(|r| r.solver == s.name() && r.method == m)
                        .map(|r| (r.k as f64, r.rms_iod.mean, r.rms_iod.lo, r.rms_iod.hi))
                        .collect();
                    (m, pts)
                })
                .collect();
            let curves: Vec<IntervalCurve> =
                curves.into_iter().filter(|c| !c.1.is_empty()).collect();
            if curves.is_empty() {
                continue;
            }
            let mut spec = interval_plot(
                &curves,
                &format!("{}: mean over {n} sequences, 95 % interval", o.spec.title),
                "number of key shapes k",
                &format!("RMS error per point (IOD), {}", s.name()),
            );
            for r in o.own_k.iter().filter(|r| r.solver == s.name()) {
                let (color, _) = crate::plot::method_style(&r.method);
                let errors = o.results.iter().zip(&r.ks).filter_map(|(u, &k)| {
                    u.curves
                        .iter()
                        .find(|c| c.method == r.method && c.solver == r.solver && c.k == k)
                        .map(|c| (k as f64, c.rms / u.iod))
                });
                spec.series.push(Series {
                    name: format!("{} (each sequence, at its own k)", r.method),
                    points: errors.collect(),
                    style: Style::Marker,
                    color,
                });
            }
            let name = format!("corpus_{}.png", s.name());
            save_png(&render_plot(&spec, 900, 600)?, &dir.join(&name))?;
            figures.push(name);
        }
        if let Some(plot) = retarget_plot(o) {
            let name = "corpus_retarget.png".to_string();
            save_png(&render_plot(&plot, 900, 600)?, &dir.join(&name))?;
            figures.push(name);
        }
    }
    let report = json!({
        "title": o.spec.title,
        "kind": "corpus",
        "spec": o.spec,
        "sequences": o.results.iter().map(|r| json!({
            "name": r.unit.name,
            "input": r.unit.input,
            "clip": r.unit.clip,
            "frames": r.frames,
            "points": r.points,
            "iod": r.iod,
        })).collect::<Vec<_>>(),
        "summary": o.summary,
        "wins": o.wins,
        "own_k": o.own_k,
        "retarget_paired": o.retarget_paired,
        "files": files.iter().filter_map(|f| f.file_name()).map(|f| f.to_string_lossy().into_owned())
            .chain(figures.iter().cloned()).collect::<Vec<_>>(),
        "timings": {
            "seconds_per_sequence": o.results.iter().map(|r| (r.unit.name.clone(), json!(r.seconds)))
                .collect::<serde_json::Map<String, serde_json::Value>>(),
        },
    });
    let path = dir.join("report.json");
    let text = serde_json::to_string_pretty(&report)
        .map_err(|e| keyshape_core::error::Error::invalid(format!("report.json: {e}")))?;
    write_atomic(&path, |w| writeln!(w, "{text}"))?;
    files.push(path);
    files.extend(figures.iter().map(|f| dir.join(f)));
    Ok(files)
}

/// The first two solvers' target-domain difference per sequence against tracing noise
/// (thin grey lines), with the mean over its 95 % interval.
fn retarget_plot(o: &CorpusOutcome) -> Option<crate::plot::PlotSpec> {
    let rt = o.spec.retarget.as_ref()?;
    let (a, b) = (rt.solvers.first()?.name(), rt.solvers.get(1)?.name());
    let rows: Vec<_> = o
        .retarget_paired
        .iter()
        .filter(|r| r.a == a && r.b == b)
        .collect();
    let mut series: Vec<Series> = o
        .results
        .iter()
        .map(|r| {
            let pts = rt
                .trace_noise
                .iter()
                .filter_map(|&noise| {
                    let get = |s: &str| {
                        r.retarget
                            .iter()
                            .find(|p| p.solver == s && p.trace_noise == noise)
                    };
                    Some((noise, (get(a)?.target_rms - get(b)?.target_rms) / r.iod))
                })
                .collect();
            Series {
                name: String::new(),
                points: pts,
                style: Style::Thin,
                color: [150, 150, 150],
            }
        })
        .collect();
    let mut edge: Vec<(f64, f64)> = rows
        .iter()
        .map(|r| (r.trace_noise, r.target_diff.hi))
        .collect();
    edge.extend(rows.iter().rev().map(|r| (r.trace_noise, r.target_diff.lo)));
    series.push(Series {
        name: "95 %".into(),
        points: edge,
        style: Style::Band,
        color: [200, 30, 30],
    });
    series.push(Series {
        name: format!(
            "mean {a} − {b} over {} sequences (shaded: 95 %; grey: each)",
            o.results.len()
        ),
        points: rows
            .iter()
            .map(|r| (r.trace_noise, r.target_diff.mean))
            .collect(),
        style: Style::Line,
        color: [200, 30, 30],
    });
    series.push(Series {
        name: "no difference".into(),
        points: vec![
            (
                rt.trace_noise.iter().copied().fold(f64::INFINITY, f64::min),
                0.0,
            ),
            (
                rt.trace_noise
                    .iter()
                    .copied()
                    .fold(f64::NEG_INFINITY, f64::max),
                0.0,
            ),
        ],
        style: Style::Dashed,
        color: [20, 20, 20],
    });
    Some(crate::plot::PlotSpec {
        title: format!(
            "{}: target-domain error, {a} − {b}, per sequence",
            o.spec.title
        ),
        x_label: "tracing noise on the target key shapes (IOD)".into(),
        y_label: format!("RMS per point (IOD), {a} − {b}"),
        series,
        y_from_zero: false,
        y_at_least: None,
    })
}
