//! Writes an experiment's outcome: `curves.csv`, `report.json` and one PNG per solver.

pub mod corpus;

use crate::experiment::{Outcome, Output, STUDIES};
use keyshape_core::error::{Error, Result};
use keyshape_core::keyshapes::curves::CurveRow;
use keyshape_io::csv_out::{write_rows, Num};
use keyshape_pictures::plot::curves_plot;
use keyshape_pictures::render::{render_plot, save_png};
use serde::Serialize;
use serde_json::json;
use std::io::Write;
use std::path::{Path, PathBuf};

/// A row of `curves.csv`.
#[derive(Serialize, Default)]
struct CurveCsv<'a> {
    method: &'a str,
    solver: &'a str,
    k: usize,
    total_sq_error: Num,
    rms: Num,
}

/// Writes the curve rows as CSV: `method,solver,k,total_sq_error,rms`.
pub fn write_curves_csv(w: &mut dyn Write, rows: &[CurveRow]) -> std::io::Result<()> {
    write_rows(
        w,
        rows.iter().map(|r| CurveCsv {
            method: &r.method,
            solver: &r.solver,
            k: r.k,
            total_sq_error: Num(r.total_sq_error),
            rms: Num(r.rms),
        }),
    )
}

/// An experiment's curves title: its own title, then what was measured (solver, aligned
/// or raw).
pub fn curves_title(title: &str, solver: &str, aligned: bool) -> String {
    format!(
        "{title} — {solver}, {}",
        if aligned {
            "head motion removed"
        } else {
            "raw coordinates"
        }
    )
}

/// Renders one solver's curves to a 900 × 600 PNG at `path`.
pub fn write_curves_png(rows: &[CurveRow], solver: &str, title: &str, path: &Path) -> Result<()> {
    let spec = curves_plot(rows, solver, title, "px");
    let pm = render_plot(&spec, 900, 600)?;
    save_png(&pm, path)
}

/// Aligned (left) and raw (right) curves of one solver side by side, on one y scale.
pub fn write_aligned_vs_raw_png(
    aligned: &[CurveRow],
    raw: &[CurveRow],
    solver: &str,
    title: &str,
    path: &Path,
) -> Result<()> {
    let mut a = curves_plot(
        aligned,
        solver,
        &format!("{title}: head motion removed"),
        "px",
    );
    let mut r = curves_plot(raw, solver, &format!("{title}: raw coordinates"), "px");
    let top = |p: &keyshape_pictures::plot::PlotSpec| p.bounds().map_or(0.0, |b| b.1 .1);
    let y = top(&a).max(top(&r));
    a.y_at_least = Some(y);
    r.y_at_least = Some(y);
    let (pa, pr) = (render_plot(&a, 900, 600)?, render_plot(&r, 900, 600)?);
    let mut out = tiny_skia::Pixmap::new(1800, 600)
        .ok_or_else(|| Error::invalid("cannot allocate the side-by-side picture"))?;
    let paint = tiny_skia::PixmapPaint::default();
    out.draw_pixmap(
        0,
        0,
        pa.as_ref(),
        &paint,
        tiny_skia::Transform::identity(),
        None,
    );
    out.draw_pixmap(
        900,
        0,
        pr.as_ref(),
        &paint,
        tiny_skia::Transform::identity(),
        None,
    );
    save_png(&out, path)
}

/// Writes everything into `dir` (created if missing): the curves, each study's files
/// ([`Finding::write`](crate::experiment::Finding::write)), the curves' pictures and `report.json`; returns the files written.
pub fn write_outcome(o: &Outcome, dir: &Path) -> Result<Vec<PathBuf>> {
    keyshape_io::create_dir_all(dir)?;
    let mut out = Output {
        spec: &o.spec,
        dir,
        files: Vec::new(),
        figures: Vec::new(),
    };
    if !o.rows.is_empty() {
        out.file("curves.csv", |w| write_curves_csv(w, &o.rows))?;
    }
    if !o.raw_rows.is_empty() {
        out.file("curves_raw.csv", |w| write_curves_csv(w, &o.raw_rows))?;
        if o.spec.png {
            for s in &o.spec.solvers {
                let name = format!("curves_{}_aligned_vs_raw.png", s.name());
                write_aligned_vs_raw_png(
                    &o.rows,
                    &o.raw_rows,
                    s.name(),
                    &o.spec.title,
                    &dir.join(&name),
                )?;
                out.figures.push(name);
            }
        }
    }
    for f in &o.findings {
        f.write(&mut out)?;
    }
    if o.spec.png && !o.rows.is_empty() {
        for s in &o.spec.solvers {
            let name = format!("curves_{}.png", s.name());
            let title = curves_title(&o.spec.title, s.name(), o.spec.align);
            write_curves_png(&o.rows, s.name(), &title, &dir.join(&name))?;
            out.figures.push(name);
        }
    }
    let mut report = serde_json::Map::new();
    for s in STUDIES {
        s.absent(&mut report);
    }
    for f in &o.findings {
        f.report(&mut report);
    }
    let base = json!({
        "kslab_version": env!("CARGO_PKG_VERSION"),
        "settings": o.spec,
        "input": o.input,
        "frames": o.frames,
        "points": o.points,
        "failed_frames": o.failed_frames,
        "explained_variance": o.explained_variance,
        "timings_s": o.timings.iter().map(|(k, v)| (k.clone(), json!(v))).collect::<serde_json::Map<_, _>>(),
        "figures": out.figures,
        "rows": o.rows,
        "raw_rows": (!o.raw_rows.is_empty()).then_some(&o.raw_rows),
    });
    if let serde_json::Value::Object(m) = base {
        report.extend(m);
    }
    out.json("report.json", &report)?;
    let Output {
        mut files, figures, ..
    } = out;
    files.extend(figures.iter().map(|f| dir.join(f)));
    Ok(files)
}
