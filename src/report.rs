//! Writes an experiment's outcome: `curves.csv`, `report.json` and one PNG per solver.

use crate::error::{Error, Result};
use crate::experiment::Outcome;
use crate::io::{fmt_num, write_atomic};
use crate::keyshapes::curves::CurveRow;
use crate::plot::curves_plot;
use crate::render::{render_plot, save_png};
use serde_json::json;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Writes the curve rows as CSV: `method,solver,k,total_sq_error,rms`.
pub fn write_curves_csv(w: &mut dyn Write, rows: &[CurveRow]) -> std::io::Result<()> {
    writeln!(w, "method,solver,k,total_sq_error,rms")?;
    for r in rows {
        writeln!(
            w,
            "{},{},{},{},{}",
            r.method,
            r.solver,
            r.k,
            fmt_num(r.total_sq_error),
            fmt_num(r.rms)
        )?;
    }
    Ok(())
}

/// Renders one solver's curves to a 900 × 600 PNG at `path`.
pub fn write_curves_png(rows: &[CurveRow], solver: &str, title: &str, path: &Path) -> Result<()> {
    let spec = curves_plot(rows, solver, title, "px");
    let pm = render_plot(&spec, 900, 600)?;
    save_png(&pm, path)
}

/// Writes everything into `dir` (created if missing); returns the files written.
pub fn write_outcome(o: &Outcome, dir: &Path) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let mut files = Vec::new();
    let csv = dir.join("curves.csv");
    write_atomic(&csv, |w| write_curves_csv(w, &o.rows))?;
    files.push(csv);
    let mut figures = Vec::new();
    if o.spec.png {
        for s in &o.spec.solvers {
            let name = format!("curves_{}.png", s.name());
            write_curves_png(&o.rows, s.name(), &o.spec.title, &dir.join(&name))?;
            figures.push(name);
        }
    }
    let report = json!({
        "kslab_version": env!("CARGO_PKG_VERSION"),
        "settings": o.spec,
        "input": o.input,
        "frames": o.frames,
        "points": o.points,
        "failed_frames": o.failed_frames,
        "explained_variance": o.explained_variance,
        "timings_s": o.timings.iter().map(|(k, v)| (k.clone(), json!(v))).collect::<serde_json::Map<_, _>>(),
        "figures": figures,
        "rows": o.rows,
    });
    let path = dir.join("report.json");
    let text = serde_json::to_string_pretty(&report).map_err(|e| Error::invalid(e.to_string()))?;
    write_atomic(&path, |w| w.write_all(text.as_bytes()))?;
    files.push(path);
    files.extend(figures.iter().map(|f| dir.join(f)));
    Ok(files)
}
