//! `kslab retarget`'s pictures: the weights over time, and each frame's source and target.

use super::RetargetArgs;
use anyhow::Result;
use keyshape_core::decompose::Prepared;
use keyshape_core::sequence::Sequence;
use keyshape_core::stats::sig;
use keyshape_pictures::render::face::{bounds_of, col, render_frame, FrameShapes};
use keyshape_pictures::render::{apng::write_apng, save_png};
use keyshape_retarget::setup::polylines_for;
use keyshape_retarget::{with_head_motion, Retargeted};
use nalgebra::DMatrix;

/// Every region's weights over time, one under the other, named as the CSV names them.
pub(super) fn write_weights_png(
    a: &RetargetArgs,
    s: &Sequence,
    r: &Retargeted,
    columns: &[String],
    png: &std::path::Path,
) -> Result<()> {
    let frames = r.weights.first().map_or(0, |w| w.ncols());
    let rows: usize = r.weights.iter().map(|w| w.nrows()).sum();
    let mut all = nalgebra::DMatrix::zeros(rows, frames);
    let mut at = 0;
    for w in &r.weights {
        all.rows_mut(at, w.nrows()).copy_from(w);
        at += w.nrows();
    }
    let title = format!(
        "{}: weights over time, {} keys, {}",
        crate::cli::input::track_label(&s.source, a.input.points.as_deref()),
        rows,
        a.solver
    );
    // The key frames marked on the time axis, as `kslab solve --png` marks them (cluster
    // means are no frames and get no mark).
    let mut keys: Vec<i64> = r
        .keys
        .iter()
        .flatten()
        .filter_map(|&c| s.frames.get(c).copied())
        .collect();
    keys.sort_unstable();
    keys.dedup();
    let pm = keyshape_pictures::render::weights::weights_picture_marked(
        &all, columns, &s.frames, &title, &keys,
    )?;
    save_png(&pm, png)?;
    Ok(())
}

/// Image-space shapes (head motion re-applied when asked for).
fn image_space(
    m: &DMatrix<f64>,
    head: Option<&[keyshape_core::align::Similarity]>,
    dims: usize,
) -> Result<DMatrix<f64>> {
    Ok(match head {
        Some(h) => with_head_motion(m, h, dims)?,
        None => m.clone(),
    })
}

/// Root-mean-square distance of the points from their centroid, averaged over frames.
fn mean_size(m: &DMatrix<f64>, dims: usize) -> f64 {
    let n = m.ncols().max(1) as f64;
    m.column_iter()
        .map(|c| {
            let pts = (c.len() / dims).max(1) as f64;
            let mut centre = [0.0; 3];
            for p in c.as_slice().chunks(dims) {
                for d in 0..dims {
                    centre[d] += p[d] / pts;
                }
            }
            let ss: f64 = c
                .as_slice()
                .chunks(dims)
                .map(|p| (0..dims).map(|d| (p[d] - centre[d]).powi(2)).sum::<f64>())
                .sum();
            (ss / pts).sqrt()
        })
        .sum::<f64>()
        / n
}

pub(super) fn pictures(
    a: &RetargetArgs,
    seq: &Sequence,
    prep: &Prepared,
    head: Option<&[keyshape_core::align::Similarity]>,
    r: &Retargeted,
    target_lines: &[Vec<usize>],
    progress: &crate::cli::progress::Progress,
) -> Result<()> {
    let s = &prep.seq;
    let dims = s.dims;
    // Errors of a normalised track are fractions of the image, not pixels: say so.
    let unit = if seq.is_normalised() {
        "   (0–1 units)"
    } else {
        "   (px)"
    };
    // The tracked points as the recon is drawn: in the file's coordinates with head
    // motion, else aligned.
    let tracked = match (head, &prep.head) {
        (None, Some(_)) => s.coords.clone(),
        _ => seq.select_points(&prep.point_indices)?.coords,
    };
    let recon = image_space(&r.source, head, dims)?;
    let same_points = r.target.nrows() == s.coords.nrows();
    let target = match (head, same_points) {
        (Some(_), true) => image_space(&r.target, head, dims)?,
        (Some(h), false) => {
            let ratio = mean_size(&r.target, dims) / mean_size(&s.coords, dims).max(1e-300);
            keyshape_retarget::with_relative_head_motion(&r.target, h, dims, ratio)?
        }
        (None, _) => r.target.clone(),
    };
    let truth = match (&r.truth, same_points) {
        (Some(t), true) => Some(image_space(t, head, dims)?),
        _ => None,
    };
    let src_lines = prep
        .layout
        .as_ref()
        .map(|l| polylines_for(l, &prep.point_indices))
        .unwrap_or_default();
    let sb = bounds_of(&[&tracked], dims);
    let mut all_t = vec![&target];
    all_t.extend(truth.iter());
    let tb = bounds_of(&all_t, dims);
    let frame = |t: usize| -> keyshape_core::Result<tiny_skia::Pixmap> {
        let shapes = FrameShapes {
            dims,
            tracked: col(&tracked, t),
            recon: col(&recon, t),
            truth: truth.as_ref().map(|m| col(m, t)),
            target: col(&target, t),
            source_lines: &src_lines,
            target_lines,
            source_bounds: sb,
            target_bounds: tb,
        };
        // Frame, solver, and both errors of this frame (the target's against its ground
        // truth, when there is one).
        let target_err = r.target_sq.as_ref().map_or(String::new(), |e| {
            format!(
                "   target RMS {}",
                sig((e[t] / r.target_points.max(1) as f64).sqrt(), 3)
            )
        });
        let caption = format!(
            "frame {}   {}   source RMS {}{target_err}{unit}",
            s.frames[t],
            a.solver,
            sig((r.source_sq[t] / r.points as f64).sqrt(), 3)
        );
        render_frame(&shapes, &caption, 360)
    };
    if let Some(dir) = &a.png_dir {
        keyshape_io::create_dir_all(dir)?;
        progress.step("retarget: PNG frames");
        progress.units("frames");
        for t in 0..s.n_frames() {
            progress.tick(t, s.n_frames());
            save_png(
                &frame(t)?,
                &dir.join(format!("frame_{:06}.png", s.frames[t])),
            )?;
        }
        crate::cli::output::wrote(format!("{} frames to {}", s.n_frames(), dir.display()));
    }
    if let Some(p) = &a.apng {
        let fps = s.fps().unwrap_or(30.0);
        progress.step("retarget: animated PNG");
        progress.units("frames");
        let n = s.n_frames();
        write_apng(p, n, fps, &|t| {
            progress.tick(t, n);
            frame(t)
        })?;
        crate::cli::output::wrote(p.display().to_string());
    }
    Ok(())
}
