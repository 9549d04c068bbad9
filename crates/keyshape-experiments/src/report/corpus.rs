//! Writes a corpus study's report (the same files from a whole run and from `kslab merge`).

use crate::experiment::corpus::CorpusOutcome;
use keyshape_core::error::Result;
use keyshape_io::csv_out::{write_rows, Num};
use keyshape_io::write_atomic;
use keyshape_pictures::plot::{interval_plot, IntervalCurve, Series, Style};
use keyshape_pictures::render::{render_plot, save_png};
use serde::Serialize;
use serde_json::json;
use std::io::Write;
use std::path::{Path, PathBuf};

/// A row of `corpus_sequences.csv`.
#[derive(Serialize, Default)]
struct SequenceCsv<'a> {
    sequence: &'a str,
    input: &'a str,
    clip: Option<&'a str>,
    frames: usize,
    points: usize,
    iod: Num,
}

/// A row of `corpus_curves.csv`.
#[derive(Serialize, Default)]
struct CurveCsv<'a> {
    sequence: &'a str,
    method: &'a str,
    solver: &'a str,
    k: usize,
    total_sq_error: Num,
    rms: Num,
    rms_iod: Num,
}

/// A row of `corpus_summary.csv`.
#[derive(Serialize, Default)]
struct SummaryCsv<'a> {
    method: &'a str,
    solver: &'a str,
    k: usize,
    sequences: usize,
    mean_rms_iod: Num,
    lo95: Num,
    hi95: Num,
    wins: usize,
}

/// A row of `corpus_paired.csv`.
#[derive(Serialize, Default)]
struct PairedCsv<'a> {
    solver: &'a str,
    k: usize,
    method_a: &'a str,
    method_b: &'a str,
    sequences: usize,
    mean_diff_iod: Num,
    lo95: Num,
    hi95: Num,
    a_lower: usize,
    b_lower: usize,
}

/// A row of `corpus_wins.csv`.
#[derive(Serialize, Default)]
struct WinCsv<'a> {
    method: &'a str,
    solver: &'a str,
    wins: usize,
    contests: usize,
}

/// A row of `corpus_own_k.csv`: an own-k method against one other method at its k (the
/// comparison's columns empty when there is none).
#[derive(Serialize, Default, Clone)]
struct OwnKCsv<'a> {
    method: &'a str,
    solver: &'a str,
    sequences: usize,
    mean_k: Num,
    mean_rms_iod: Num,
    lo95: Num,
    hi95: Num,
    compared_with: Option<&'a str>,
    compared_sequences: Option<usize>,
    mean_diff_iod: Option<Num>,
    diff_lo95: Option<Num>,
    diff_hi95: Option<Num>,
    other_lower: Option<usize>,
}

/// A row of `corpus_retarget.csv`.
#[derive(Serialize, Default)]
struct RetargetCsv<'a> {
    sequence: &'a str,
    solver: &'a str,
    trace_noise: Num,
    source_rms: Num,
    target_rms: Num,
    source_rms_iod: Num,
    target_rms_iod: Num,
    negative_share: Num,
    max_abs_weight: Num,
}

/// A row of `corpus_retarget_paired.csv`.
#[derive(Serialize, Default)]
struct RetargetPairedCsv<'a> {
    trace_noise: Num,
    solver_a: &'a str,
    solver_b: &'a str,
    sequences: usize,
    mean_target_diff_iod: Num,
    lo95: Num,
    hi95: Num,
    mean_source_diff_iod: Num,
    source_lo95: Num,
    source_hi95: Num,
    a_lower_target: usize,
}

/// Writes `corpus_*.csv`, `corpus_<solver>.png`, `corpus_retarget.png` and `report.json`
/// into `dir`; returns the files written.
pub fn write_corpus(o: &CorpusOutcome, dir: &Path) -> Result<Vec<PathBuf>> {
    keyshape_io::create_dir_all(dir)?;
    let mut files = Files {
        dir,
        written: Vec::new(),
    };
    files.put("corpus_sequences.csv", &|w| {
        write_rows(
            w,
            o.results.iter().map(|r| SequenceCsv {
                sequence: &r.unit.name,
                input: &r.unit.input,
                clip: r.unit.clip.as_deref(),
                frames: r.frames,
                points: r.points,
                iod: Num(r.iod),
            }),
        )
    })?;
    if !o.summary.is_empty() {
        write_curve_tables(o, &mut files)?;
    }
    if !o.own_k.is_empty() {
        write_own_k(o, &mut files)?;
    }
    if o.spec.retarget.is_some() {
        write_retarget_tables(o, &mut files)?;
    }
    let figures = if o.spec.png {
        write_figures(o, dir)?
    } else {
        Vec::new()
    };
    let mut files = files.written;
    let report = corpus_report(o, &files, &figures);
    let path = dir.join("report.json");
    let text = serde_json::to_string_pretty(&report)
        .map_err(|e| keyshape_core::error::Error::invalid(format!("report.json: {e}")))?;
    write_atomic(&path, |w| writeln!(w, "{text}"))?;
    files.push(path);
    files.extend(figures.iter().map(|f| dir.join(f)));
    Ok(files)
}

/// The files a corpus report writes into its folder, in the order written.
struct Files<'a> {
    dir: &'a Path,
    written: Vec<PathBuf>,
}

impl Files<'_> {
    /// Writes `name` in the folder through `fill`, whole or not at all.
    fn put(
        &mut self,
        name: &str,
        fill: &dyn Fn(&mut dyn Write) -> std::io::Result<()>,
    ) -> Result<()> {
        let p = self.dir.join(name);
        write_atomic(&p, |w| fill(w))?;
        self.written.push(p);
        Ok(())
    }
}

/// `corpus_curves.csv`, `corpus_summary.csv`, `corpus_paired.csv`, `corpus_wins.csv`.
fn write_curve_tables(o: &CorpusOutcome, files: &mut Files) -> Result<()> {
    files.put("corpus_curves.csv", &|w| {
        let rows = o.results.iter().flat_map(|r| {
            r.curves.iter().map(move |c| CurveCsv {
                sequence: &r.unit.name,
                method: &c.method,
                solver: &c.solver,
                k: c.k,
                total_sq_error: Num(c.total_sq_error),
                rms: Num(c.rms),
                rms_iod: Num(c.rms / r.iod),
            })
        });
        write_rows(w, rows)
    })?;
    files.put("corpus_summary.csv", &|w| {
        write_rows(
            w,
            o.summary.iter().map(|r| SummaryCsv {
                method: &r.method,
                solver: &r.solver,
                k: r.k,
                sequences: r.rms_iod.n,
                mean_rms_iod: Num(r.rms_iod.mean),
                lo95: Num(r.rms_iod.lo),
                hi95: Num(r.rms_iod.hi),
                wins: r.wins,
            }),
        )
    })?;
    files.put("corpus_paired.csv", &|w| {
        write_rows(
            w,
            o.paired.iter().map(|r| PairedCsv {
                solver: &r.solver,
                k: r.k,
                method_a: &r.a,
                method_b: &r.b,
                sequences: r.diff.n,
                mean_diff_iod: Num(r.diff.mean),
                lo95: Num(r.diff.lo),
                hi95: Num(r.diff.hi),
                a_lower: r.a_lower,
                b_lower: r.b_lower,
            }),
        )
    })?;
    files.put("corpus_wins.csv", &|w| {
        write_rows(
            w,
            o.wins.iter().map(|r| WinCsv {
                method: &r.method,
                solver: &r.solver,
                wins: r.wins,
                contests: r.contests,
            }),
        )
    })?;
    Ok(())
}

/// `corpus_own_k.csv`: each method at each sequence's own k, and against the others.
fn write_own_k(o: &CorpusOutcome, files: &mut Files) -> Result<()> {
    files.put("corpus_own_k.csv", &|w| {
        let rows = o.own_k.iter().flat_map(|r| {
            let own = OwnKCsv {
                method: &r.method,
                solver: &r.solver,
                sequences: r.rms_iod.n,
                mean_k: Num(r.ks.iter().sum::<usize>() as f64 / r.ks.len() as f64),
                mean_rms_iod: Num(r.rms_iod.mean),
                lo95: Num(r.rms_iod.lo),
                hi95: Num(r.rms_iod.hi),
                ..Default::default()
            };
            let alone = r.against.is_empty().then(|| own.clone());
            let against = r.against.iter().map(move |c| OwnKCsv {
                compared_with: Some(&c.method),
                compared_sequences: Some(c.diff.n),
                mean_diff_iod: Some(Num(c.diff.mean)),
                diff_lo95: Some(Num(c.diff.lo)),
                diff_hi95: Some(Num(c.diff.hi)),
                other_lower: Some(c.lower),
                ..own.clone()
            });
            alone.into_iter().chain(against)
        });
        write_rows(w, rows)
    })?;
    Ok(())
}

/// `corpus_retarget.csv` and `corpus_retarget_paired.csv`.
fn write_retarget_tables(o: &CorpusOutcome, files: &mut Files) -> Result<()> {
    files.put("corpus_retarget.csv", &|w| {
        let rows = o.results.iter().flat_map(|r| {
            r.retarget.iter().map(move |p| RetargetCsv {
                sequence: &r.unit.name,
                solver: &p.solver,
                trace_noise: Num(p.trace_noise),
                source_rms: Num(p.source_rms),
                target_rms: Num(p.target_rms),
                source_rms_iod: Num(p.source_rms / r.iod),
                target_rms_iod: Num(p.target_rms / r.iod),
                negative_share: Num(p.negative_share),
                max_abs_weight: Num(p.max_abs_weight),
            })
        });
        write_rows(w, rows)
    })?;
    files.put("corpus_retarget_paired.csv", &|w| {
        write_rows(
            w,
            o.retarget_paired.iter().map(|r| RetargetPairedCsv {
                trace_noise: Num(r.trace_noise),
                solver_a: &r.a,
                solver_b: &r.b,
                sequences: r.target_diff.n,
                mean_target_diff_iod: Num(r.target_diff.mean),
                lo95: Num(r.target_diff.lo),
                hi95: Num(r.target_diff.hi),
                mean_source_diff_iod: Num(r.source_diff.mean),
                source_lo95: Num(r.source_diff.lo),
                source_hi95: Num(r.source_diff.hi),
                a_lower_target: r.a_lower,
            }),
        )
    })?;
    Ok(())
}

/// The corpus's pictures: each solver's mean curves over their 95 % intervals (with each
/// sequence at its own k), and the retargeting picture; their file names.
fn write_figures(o: &CorpusOutcome, dir: &Path) -> Result<Vec<String>> {
    let mut figures = Vec::new();
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
        let curves: Vec<IntervalCurve> = curves.into_iter().filter(|c| !c.1.is_empty()).collect();
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
            let (color, _) = keyshape_pictures::plot::named_style(&r.method);
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
    Ok(figures)
}

/// `report.json` of a corpus.
fn corpus_report(o: &CorpusOutcome, files: &[PathBuf], figures: &[String]) -> serde_json::Value {
    json!({
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
    })
}

/// The first two solvers' target-domain difference per sequence against tracing noise
/// (thin grey lines), with the mean over its 95 % interval.
fn retarget_plot(o: &CorpusOutcome) -> Option<keyshape_pictures::plot::PlotSpec> {
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
    Some(keyshape_pictures::plot::PlotSpec {
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
