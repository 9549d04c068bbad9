//! `[smooth]`: the jitter-against-error study of the temporal prior and the post-filters
//! ([`crate::experiment::smoothing`] runs it). Writes `smoothing.csv`,
//! `smoothing_at_equal_jitter.csv` and `smoothing.png`.

use super::{Context, Finding, Output, Study};
use crate::experiment::smoothing::{at_equal_jitter, smoothing_study, summary, SmoothRow};
use keyshape_core::error::{Error, Result};
use keyshape_io::csv_out::{opt, write_rows, Num};
use keyshape_io::write_atomic;
use keyshape_pictures::render::{render_plot, save_png};
use serde::Serialize;
use serde_json::{Map, Value};
use std::any::Any;
use std::path::{Path, PathBuf};

/// The jitter levels, as fractions of the least-squares jitter, at which the approaches are
/// compared (`smoothing_at_equal_jitter.csv`, the run's summary).
pub const EQUAL_JITTER: [f64; 3] = [0.75, 0.5, 0.35];

/// The `[smooth]` study.
pub struct SmoothStudy;

impl Study for SmoothStudy {
    fn stage(&self) -> &'static str {
        "smooth"
    }

    fn run(&self, cx: &Context) -> Result<Option<Box<dyn Finding>>> {
        let Some(st) = &cx.spec.smooth else {
            return Ok(None);
        };
        let rows = smoothing_study(cx.seq, cx.prep, st, cx.opts)?;
        Ok(Some(Box::new(SmoothFinding(rows))))
    }

    fn absent(&self, _report: &mut Map<String, Value>) {}
}

/// What `[smooth]` found: a row per approach and setting.
#[derive(Debug, Clone)]
pub struct SmoothFinding(pub Vec<SmoothRow>);

impl Finding for SmoothFinding {
    fn write(&self, out: &mut Output) -> Result<()> {
        if self.0.is_empty() {
            return Ok(());
        }
        let (files, figures) = write_smoothing(&self.0, &out.spec.title, out.dir, out.spec.png)?;
        out.files.extend(files);
        out.figures.extend(figures);
        Ok(())
    }

    fn report(&self, _report: &mut Map<String, Value>) {}

    fn summary(&self) -> Vec<String> {
        summary(&at_equal_jitter(&self.0, &EQUAL_JITTER))
            .into_iter()
            .collect()
    }

    fn as_any(&self) -> &dyn Any {
        self
    }
}

/// A row of `smoothing.csv`.
#[derive(Serialize, Default)]
struct SmoothCsv<'a> {
    approach: &'a str,
    setting: &'a str,
    source_rms: Num,
    target_rms_tracked: Num,
    target_rms_clean: Num,
    jitter_target: Num,
    jitter_weights: Num,
    lag_frames: i64,
    kkt: Option<Num>,
}

/// A row of `smoothing_at_equal_jitter.csv`.
#[derive(Serialize, Default)]
struct AtJitterCsv<'a> {
    jitter_target: Num,
    approach: &'a str,
    target_rms_tracked: Option<Num>,
    target_rms_clean: Option<Num>,
    lag_frames: Option<i64>,
}

/// Writes the smoothing study: `smoothing.csv`, `smoothing_at_equal_jitter.csv` and (with
/// `png`) `smoothing.png`; returns (files, figure names).
pub fn write_smoothing(
    rows: &[SmoothRow],
    title: &str,
    dir: &Path,
    png: bool,
) -> Result<(Vec<PathBuf>, Vec<String>)> {
    let mut files = Vec::new();
    let mut figures = Vec::new();
    let csv = dir.join("smoothing.csv");
    write_atomic(&csv, |w| {
        write_rows(
            w,
            rows.iter().map(|r| SmoothCsv {
                approach: &r.approach,
                setting: &r.setting,
                source_rms: Num(r.source_rms),
                target_rms_tracked: Num(r.target_rms_tracked),
                target_rms_clean: Num(r.target_rms_clean),
                jitter_target: Num(r.jitter_target),
                jitter_weights: Num(r.jitter_weights),
                lag_frames: r.lag_frames,
                kkt: opt(r.kkt),
            }),
        )
    })?;
    files.push(csv);
    let eq = dir.join("smoothing_at_equal_jitter.csv");
    let at = at_equal_jitter(rows, &EQUAL_JITTER);
    write_atomic(&eq, |w| {
        write_rows(
            w,
            at.iter().map(|r| AtJitterCsv {
                jitter_target: Num(r.jitter_target),
                approach: &r.approach,
                target_rms_tracked: opt(r.target_rms_tracked),
                target_rms_clean: opt(r.target_rms_clean),
                lag_frames: r.lag_frames,
            }),
        )
    })?;
    files.push(eq);
    if png {
        // Both scorings side by side on one y scale: against G(q), which carries the
        // tracker's jitter, and against the clean reference.
        let mut a = crate::experiment::smoothing_plot::smoothing_plot(
            rows,
            &format!("{title}: vs tracked (lower left is better)"),
            false,
        );
        let mut c = crate::experiment::smoothing_plot::smoothing_plot(
            rows,
            &format!("{title}: vs clean (lower left is better)"),
            true,
        );
        let top = |p: &keyshape_pictures::plot::PlotSpec| p.bounds().map_or(0.0, |b| b.1 .1);
        let y = top(&a).max(top(&c));
        a.y_at_least = Some(y);
        c.y_at_least = Some(y);
        let (pa, pc) = (render_plot(&a, 900, 620)?, render_plot(&c, 900, 620)?);
        let mut out = tiny_skia::Pixmap::new(1800, 620)
            .ok_or_else(|| Error::invalid("cannot allocate the smoothing picture"))?;
        let paint = tiny_skia::PixmapPaint::default();
        for (x, p) in [(0, &pa), (900, &pc)] {
            out.draw_pixmap(
                x,
                0,
                p.as_ref(),
                &paint,
                tiny_skia::Transform::identity(),
                None,
            );
        }
        save_png(&out, &dir.join("smoothing.png"))?;
        figures.push("smoothing.png".to_string());
    }
    Ok((files, figures))
}
