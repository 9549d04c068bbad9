//! Writes an experiment's outcome: `curves.csv`, `report.json` and one PNG per solver.

pub mod corpus;

use crate::experiment::{Outcome, Strip};
use crate::plot::curves_plot;
use crate::render::{render_plot, save_png};
use keyshape_core::error::{Error, Result};
use keyshape_core::keyshapes::curves::CurveRow;
use keyshape_io::{fmt_num, write_atomic};
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
    let top = |p: &crate::plot::PlotSpec| p.bounds().map_or(0.0, |b| b.1 .1);
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

/// Writes the smoothing study: `smoothing.csv`, `smoothing_at_equal_jitter.csv` and (with
/// `png`) `smoothing.png`; returns (files, figure names).
pub fn write_smoothing(
    rows: &[crate::experiment::smoothing::SmoothRow],
    title: &str,
    dir: &Path,
    png: bool,
) -> Result<(Vec<PathBuf>, Vec<String>)> {
    let mut files = Vec::new();
    let mut figures = Vec::new();
    let csv = dir.join("smoothing.csv");
    write_atomic(&csv, |w| {
        writeln!(w, "approach,setting,source_rms,target_rms_tracked,target_rms_clean,jitter_target,jitter_weights,lag_frames,kkt")?;
        for r in rows {
            writeln!(
                w,
                "{},{},{},{},{},{},{},{},{}",
                r.approach,
                r.setting,
                fmt_num(r.source_rms),
                fmt_num(r.target_rms_tracked),
                fmt_num(r.target_rms_clean),
                fmt_num(r.jitter_target),
                fmt_num(r.jitter_weights),
                r.lag_frames,
                r.kkt.map_or(String::new(), fmt_num)
            )?;
        }
        Ok(())
    })?;
    files.push(csv);
    let eq = dir.join("smoothing_at_equal_jitter.csv");
    let opt = |v: Option<f64>| v.map_or(String::new(), fmt_num);
    write_atomic(&eq, |w| {
        writeln!(
            w,
            "jitter_target,approach,target_rms_tracked,target_rms_clean,lag_frames"
        )?;
        for r in crate::experiment::smoothing::at_equal_jitter(rows, &[0.75, 0.5, 0.35]) {
            writeln!(
                w,
                "{},{},{},{},{}",
                fmt_num(r.jitter_target),
                r.approach,
                opt(r.target_rms_tracked),
                opt(r.target_rms_clean),
                r.lag_frames.map_or(String::new(), |l| l.to_string())
            )?;
        }
        Ok(())
    })?;
    files.push(eq);
    if png {
        // Both scorings side by side on one y scale: against G(q), which carries the
        // tracker's jitter, and against the clean reference.
        let mut a = crate::plot::smoothing_plot(
            rows,
            &format!("{title}: vs tracked (lower left is better)"),
            false,
        );
        let mut c = crate::plot::smoothing_plot(
            rows,
            &format!("{title}: vs clean (lower left is better)"),
            true,
        );
        let top = |p: &crate::plot::PlotSpec| p.bounds().map_or(0.0, |b| b.1 .1);
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

/// Writes everything into `dir` (created if missing); returns the files written.
pub fn write_outcome(o: &Outcome, dir: &Path) -> Result<Vec<PathBuf>> {
    keyshape_io::create_dir_all(dir)?;
    let mut files = Vec::new();
    let mut figures = Vec::new();
    if !o.rows.is_empty() {
        let csv = dir.join("curves.csv");
        write_atomic(&csv, |w| write_curves_csv(w, &o.rows))?;
        files.push(csv);
    }
    if !o.raw_rows.is_empty() {
        let csv = dir.join("curves_raw.csv");
        write_atomic(&csv, |w| write_curves_csv(w, &o.raw_rows))?;
        files.push(csv);
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
                figures.push(name);
            }
        }
    }
    if !o.retarget.is_empty() {
        let csv = dir.join("retarget.csv");
        write_atomic(&csv, |w| {
            writeln!(
                w,
                "solver,trace_noise,source_rms,target_rms,jitter,negative_share,max_abs_weight"
            )?;
            for r in &o.retarget {
                writeln!(
                    w,
                    "{},{},{},{},{},{},{}",
                    r.solver,
                    fmt_num(r.trace_noise),
                    fmt_num(r.source_rms),
                    fmt_num(r.target_rms),
                    fmt_num(r.jitter),
                    fmt_num(r.negative_share),
                    fmt_num(r.max_abs_weight)
                )?;
            }
            Ok(())
        })?;
        files.push(csv);
    }
    if let (Some(strip), true) = (&o.strip, o.spec.png) {
        save_png(&render_strip(strip)?, &dir.join("strip.png"))?;
        figures.push("strip.png".to_string());
    }
    if let Some(st) = &o.orthogonality {
        let csv = dir.join("orthogonality.csv");
        write_atomic(&csv, |w| {
            writeln!(w, "model,action_i,action_j,eq9")?;
            for (model, m) in [
                ("action_specific", &st.action_model),
                ("plain_pca", &st.plain),
            ] {
                for i in 0..st.names.len() {
                    for j in i + 1..st.names.len() {
                        writeln!(
                            w,
                            "{model},{},{},{}",
                            st.names[i],
                            st.names[j],
                            fmt_num(m[(i, j)])
                        )?;
                    }
                }
            }
            Ok(())
        })?;
        files.push(csv);
        if o.spec.png {
            let pm = crate::render::heat::heat_maps(
                &[
                    ("action-specific model", &st.action_model),
                    ("plain PCA", &st.plain),
                ],
                &st.names,
                44,
            )?;
            save_png(&pm, &dir.join("orthogonality.png"))?;
            figures.push("orthogonality.png".to_string());
        }
    }
    if let Some(st) = &o.intensity {
        let csv = dir.join("intensity.csv");
        write_atomic(&csv, |w| {
            writeln!(w, "action,training_frames_labelled,correlation_raw,correlation_median3,correlation_smoothed,clips,clip_median_raw,clip_median_median3,clip_median_smoothed,clip_q1_smoothed,clip_q3_smoothed")?;
            for r in &st.actions {
                writeln!(
                    w,
                    "{},{},{},{},{},{},{},{},{},{},{}",
                    r.action,
                    r.training_frames_labelled,
                    fmt_num(r.correlation_raw),
                    fmt_num(r.correlation_median3),
                    fmt_num(r.correlation_smoothed),
                    r.clips_smoothed.clips,
                    fmt_num(r.clips_raw.median),
                    fmt_num(r.clips_median3.median),
                    fmt_num(r.clips_smoothed.median),
                    fmt_num(r.clips_smoothed.q1),
                    fmt_num(r.clips_smoothed.q3)
                )?;
            }
            Ok(())
        })?;
        files.push(csv);
        let csv = dir.join("intensity_clips.csv");
        write_atomic(&csv, |w| {
            writeln!(
                w,
                "action,clip,frames,correlation_raw,correlation_median3,correlation_smoothed"
            )?;
            for r in &st.clips {
                writeln!(
                    w,
                    "{},{},{},{},{},{}",
                    r.action,
                    r.clip,
                    r.frames,
                    fmt_num(r.raw),
                    fmt_num(r.median3),
                    fmt_num(r.smoothed)
                )?;
            }
            Ok(())
        })?;
        files.push(csv);
    }
    if let Some(m) = &o.map {
        let csv = dir.join("trajectories.csv");
        write_atomic(&csv, |w| {
            writeln!(w, "frame,{}", m.actions.join(","))?;
            for (t, f) in m.frames.iter().enumerate() {
                let v: Vec<String> = (0..m.actions.len())
                    .map(|i| fmt_num(m.trajectories[(i, t)]))
                    .collect();
                writeln!(w, "{f},{}", v.join(","))?;
            }
            Ok(())
        })?;
        files.push(csv);
        let ex = dir.join("normalisation.csv");
        write_atomic(&ex, |w| {
            writeln!(w, "action,source_mode,target_mode,side,source_extreme,target_extreme,two_sided,one_sided,ratio")?;
            for r in &m.extremes {
                writeln!(
                    w,
                    "{},{},{},{},{},{},{},{},{}",
                    r.action,
                    r.source_mode,
                    r.target_mode,
                    r.side,
                    fmt_num(r.source_extreme),
                    fmt_num(r.target_extreme),
                    fmt_num(r.two_sided),
                    fmt_num(r.one_sided),
                    fmt_num(r.ratio)
                )?;
            }
            Ok(())
        })?;
        files.push(ex);
        let al = dir.join("alignment.json");
        let text = serde_json::to_string_pretty(&m.alignment)
            .map_err(|e| Error::invalid(e.to_string()))?;
        write_atomic(&al, |w| w.write_all(text.as_bytes()))?;
        files.push(al);
        if let Some(f) = &m.morph {
            let glb = dir.join("morph.glb");
            write_atomic(&glb, |w| {
                keyshape_io::gltf::write_morph_glb(
                    w, &f.neutral, &f.faces, &f.targets, &f.weights, m.fps,
                )
            })?;
            files.push(glb);
        }
    }
    if !o.smoothing.is_empty() {
        let (f, fig) = write_smoothing(&o.smoothing, &o.spec.title, dir, o.spec.png)?;
        files.extend(f);
        figures.extend(fig);
    }
    if !o.rig_recovery.is_empty() {
        let csv = dir.join("rig_recovery.csv");
        write_atomic(&csv, |w| {
            writeln!(w, "solver,noise_px,shape,r,rmse,frozen")?;
            for r in &o.rig_recovery {
                writeln!(
                    w,
                    "{},{},{},{},{},{}",
                    r.solver,
                    fmt_num(r.noise_px),
                    r.shape,
                    fmt_num(r.r),
                    fmt_num(r.rmse),
                    r.frozen
                )?;
            }
            Ok(())
        })?;
        files.push(csv);
    }
    if !o.rig_peer.is_empty() {
        let csv = dir.join("rig_vs_input_scores.csv");
        write_atomic(&csv, |w| {
            writeln!(w, "identity,neutral,clip,shape,r")?;
            for r in &o.rig_peer {
                writeln!(
                    w,
                    "{},{},{},{},{}",
                    r.identity,
                    r.neutral,
                    r.clip,
                    r.shape,
                    r.r.map_or(String::new(), fmt_num)
                )?;
            }
            Ok(())
        })?;
        files.push(csv);
    }
    if !o.rig_peer_summary.is_empty() {
        let csv = dir.join("rig_vs_input_summary.csv");
        write_atomic(&csv, |w| {
            writeln!(w, "setting,shapes,mean_r,median_r,clip_median_mean_r,rms")?;
            for r in &o.rig_peer_summary {
                writeln!(
                    w,
                    "\"{}\",{},{},{},{},{}",
                    r.setting,
                    r.shapes,
                    fmt_num(r.mean_r),
                    fmt_num(r.median_r),
                    r.clip_mean_r.map_or(String::new(), fmt_num),
                    r.rms.map_or(String::new(), fmt_num)
                )?;
            }
            Ok(())
        })?;
        files.push(csv);
    }
    if o.spec.png && !o.rows.is_empty() {
        for s in &o.spec.solvers {
            let name = format!("curves_{}.png", s.name());
            let title = curves_title(&o.spec.title, s.name(), o.spec.align);
            write_curves_png(&o.rows, s.name(), &title, &dir.join(&name))?;
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
        "raw_rows": (!o.raw_rows.is_empty()).then_some(&o.raw_rows),
        "retarget": o.retarget,
        "strip_frames": o.strip.as_ref().map(|s| s.frames.clone()),
        "intensity": o.intensity,
        "orthogonality_mean": o.orthogonality.as_ref().map(|st| json!({
            "action_specific": keyshape_actions::modes::OrthogonalityStudy::mean_upper(&st.action_model),
            "plain_pca": keyshape_actions::modes::OrthogonalityStudy::mean_upper(&st.plain),
        })),
        "alignment": o.map.as_ref().map(|m| m.alignment.clone()),
        "rig_recovery": (!o.rig_recovery.is_empty()).then_some(&o.rig_recovery),
        "rig_vs_input_scores": (!o.rig_peer.is_empty()).then_some(&o.rig_peer),
        "rig_vs_input_summary": (!o.rig_peer_summary.is_empty()).then_some(&o.rig_peer_summary),
        "normalisation_extremes": o.map.as_ref().map(|m| m.extremes.clone()),
        "paper002_features": (o.orthogonality.is_some() || o.map.is_some())
            .then_some("shape only: landmark tracks, no texture (the paper's appearance models had both)"),
    });
    let path = dir.join("report.json");
    let text = serde_json::to_string_pretty(&report).map_err(|e| Error::invalid(e.to_string()))?;
    write_atomic(&path, |w| w.write_all(text.as_bytes()))?;
    files.push(path);
    files.extend(figures.iter().map(|f| dir.join(f)));
    Ok(files)
}

/// One row per strip frame: the source with the first solver's reconstruction, then per
/// solver the target-domain truth with that solver's retargeted shape.
pub fn render_strip(s: &Strip) -> Result<tiny_skia::Pixmap> {
    use crate::render::face::{bounds_of, col, render_panels, Layer, Panel};
    let mut all = vec![&s.truth];
    all.extend(s.solvers.iter().map(|x| &x.target));
    let tb = bounds_of(&all, s.dims);
    let mut src = vec![&s.tracked];
    src.extend(s.solvers.iter().map(|x| &x.source));
    let sb = bounds_of(&src, s.dims);
    let colours = [[200, 30, 30], [31, 90, 200], [30, 150, 60]];
    let mut rows = Vec::new();
    for (i, frame) in s.frames.iter().enumerate() {
        let (name0, rec0) = (&s.solvers[0].name, &s.solvers[0].source);
        let mut panels = vec![Panel {
            title: "source".into(),
            layers: vec![
                Layer {
                    name: "tracked",
                    shape: col(&s.tracked, i),
                    dims: s.dims,
                    polylines: &s.polylines,
                    color: [20, 20, 20],
                    dashed: false,
                },
                Layer {
                    name: name0,
                    shape: col(rec0, i),
                    dims: s.dims,
                    polylines: &s.polylines,
                    color: [31, 90, 200],
                    dashed: true,
                },
            ],
            bounds: sb,
            mesh: None,
        }];
        for (j, sv) in s.solvers.iter().enumerate() {
            let (name, tgt, rms) = (&sv.name, &sv.target, &sv.target_rms);
            panels.push(Panel {
                title: format!("target, {name}: RMS {:.2}", rms[i]),
                layers: vec![
                    Layer {
                        name: "ground truth G(q)",
                        shape: col(&s.truth, i),
                        dims: s.dims,
                        polylines: &s.polylines,
                        color: [150, 150, 150],
                        dashed: true,
                    },
                    Layer {
                        name,
                        shape: col(tgt, i),
                        dims: s.dims,
                        polylines: &s.polylines,
                        color: colours[j % 3],
                        dashed: false,
                    },
                ],
                bounds: tb,
                mesh: None,
            });
        }
        let caption = format!("frame {frame}   (tracing noise {} IOD)", s.trace_noise);
        rows.push(render_panels(&panels, &caption, 300)?);
    }
    crate::render::face::stack(&rows)
}
