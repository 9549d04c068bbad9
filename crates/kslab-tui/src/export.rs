//! `e` in the lab: the current weights as CSV, the current view as PNG, and an experiment
//! TOML that reproduces the settings with `kslab run`. Head motion follows
//! `kslab tui --head-motion` (default `apply`): per-frame pose columns in the CSV and the
//! picture in image coordinates, as `kslab retarget` writes them; `none` keeps both aligned.

use super::request::{Computed, SolverView};
use super::state::State;
use anyhow::{Context, Result};
use keyshape_core::keyshapes::Method;
use keyshape_io::csv_out::{pose_cells, write_records, POSE_COLUMNS};
use keyshape_io::{fmt_num, write_atomic};
use keyshape_pictures::render::face::{bounds_of, col, render_frame, FrameShapes};
use keyshape_pictures::render::save_png;
use std::path::{Path, PathBuf};

/// The folder for the next export in `base`: `kslab-export`, then `kslab-export-2`, `-3` …,
/// the first that does not exist, so an export never replaces an earlier one.
pub fn next_dir(base: &Path) -> PathBuf {
    let first = base.join("kslab-export");
    if std::fs::symlink_metadata(&first).is_err() {
        return first;
    }
    (2u64..)
        .map(|n| base.join(format!("kslab-export-{n}")))
        .find(|d| std::fs::symlink_metadata(d).is_err())
        .unwrap_or(first)
}

/// The footer's line after an export: `exported to kslab-export-2/: weights.csv, view.png,
/// experiment.toml` (the folder once, then the names).
pub fn status_line(dir: &Path, files: &[String]) -> String {
    let names: Vec<String> = files
        .iter()
        .map(|f| {
            Path::new(f)
                .file_name()
                .map_or(f.clone(), |n| n.to_string_lossy().into_owned())
        })
        .collect();
    let d = dir.strip_prefix(".").unwrap_or(dir);
    format!("exported to {}/: {}", d.display(), names.join(", "))
}

/// Writes `weights.csv`, `view.png` and `experiment.toml` into `dir`, all or none;
/// returns their paths.
pub fn export(s: &State, seq_path: &str, dir: &Path) -> Result<Vec<String>> {
    let set = keyshape_io::OutputSet::begin();
    let files = export_files(s, seq_path, dir)?;
    set.commit()?;
    Ok(files)
}

fn export_files(s: &State, seq_path: &str, dir: &Path) -> Result<Vec<String>> {
    // The rig view exports what it shows: the rig's weights, not the key-shape solve's.
    if let (true, Some(r)) = (s.show_rig, s.rig.as_deref()) {
        if r.preview.is_some() {
            anyhow::bail!(
                "the rig is still solving the take (the view shows one frame alone): export once it is done"
            );
        }
        return export_rig(s, r, dir);
    }
    let c = s.computed.as_ref().context("nothing computed yet")?;
    let v = c.views.first().context("no solver view")?;
    keyshape_io::create_dir_all(dir)?;
    let mean_keys = matches!(c.settings.method, Method::KMeans { mean: true, .. });
    // Head motion as `kslab retarget --head-motion` handles it: re-applied (pose columns in
    // the CSV, the picture in image coordinates) or not at all.
    let head = if s.export_head_motion {
        c.head.as_deref()
    } else {
        None
    };
    let csv = dir.join("weights.csv");
    write_weights(&csv, c, v, head, mean_keys)?;
    let png = dir.join("view.png");
    write_view(s, c, v, head, &png)?;
    let toml = dir.join("experiment.toml");
    let text = experiment_text(c, seq_path, &toml, mean_keys);
    write_atomic(&toml, |w| w.write_all(text.as_bytes()))?;
    Ok(vec![
        csv.display().to_string(),
        png.display().to_string(),
        toml.display().to_string(),
    ])
}

/// `weights.csv`: a row per frame, its errors, the key-shape weights (`w_<frame>`, or
/// `w_mean<j>` for cluster means) and with `head` the pose columns.
fn write_weights(
    csv: &Path,
    c: &Computed,
    v: &SolverView,
    head: Option<&[keyshape_core::align::Similarity]>,
    mean_keys: bool,
) -> Result<()> {
    // kmeansN-mean: the key shapes are cluster means, not frames.
    let keys = c.keys.iter().enumerate().map(|(j, &k)| {
        if mean_keys {
            format!("w_mean{j}")
        } else {
            format!("w_{}", c.frames[k])
        }
    });
    let pose: &[&str] = if head.is_some() { &POSE_COLUMNS } else { &[] };
    let header = ["frame", "source_rms", "target_rms"]
        .into_iter()
        .map(String::from)
        .chain(keys)
        .chain(pose.iter().map(|p| p.to_string()));
    let records = c.frames.iter().enumerate().map(|(t, f)| {
        let mut row = vec![
            f.to_string(),
            fmt_num(v.frame_rms[t]),
            fmt_num(v.frame_target_rms[t]),
        ];
        row.extend(v.weights.column(t).iter().map(|x| fmt_num(*x)));
        if let Some(h) = head {
            row.extend(pose_cells(&h[t]));
        }
        row
    });
    write_atomic(csv, |w| write_records(w, header, records))?;
    Ok(())
}

/// `view.png`: the current frame as the lab shows it, its errors in the title.
fn write_view(
    s: &State,
    c: &Computed,
    v: &SolverView,
    head: Option<&[keyshape_core::align::Similarity]>,
    png: &Path,
) -> Result<()> {
    let image = |m: &nalgebra::DMatrix<f64>| -> Result<nalgebra::DMatrix<f64>> {
        Ok(match head {
            Some(h) => keyshape_retarget::with_head_motion(m, h, c.dims)?,
            None => m.clone(),
        })
    };
    let t = s.frame.min(c.frames.len().saturating_sub(1));
    let (tracked, recon, truth, target) = (
        image(&c.tracked)?,
        image(&v.recon)?,
        image(&c.truth)?,
        image(&v.target)?,
    );
    let sb = bounds_of(&[&tracked], c.dims);
    let tb = bounds_of(&[&truth, &target], c.dims);
    let shapes = FrameShapes {
        dims: c.dims,
        tracked: col(&tracked, t),
        recon: col(&recon, t),
        truth: Some(col(&truth, t)),
        target: col(&target, t),
        source_lines: &c.polylines,
        target_lines: &c.polylines,
        source_bounds: sb,
        target_bounds: tb,
    };
    // The frame's errors in the title, as on screen (the export had none).
    let unit = if s.normalised {
        " (0–1 units)"
    } else {
        " px"
    };
    let caption = format!(
        "frame {}   {} {} k={}   {}{}   RMS {} · target {}{unit}",
        c.frames[t],
        c.settings.points,
        c.settings.method,
        c.keys.len(),
        c.settings.solver,
        if c.settings.smooth > 0.0 {
            format!(" λ={}", c.settings.smooth)
        } else {
            String::new()
        },
        keyshape_core::stats::sig(v.frame_rms[t], 3),
        keyshape_core::stats::sig(v.frame_target_rms[t], 3),
    );
    save_png(&render_frame(&shapes, &caption, 360)?, png)?;
    Ok(())
}

/// `experiment.toml`'s text (written at `toml`): the experiment that reproduces the
/// current settings, with the retargeting study unless the keys are cluster means and the
/// smoothing study at the lab's λ.
fn experiment_text(c: &Computed, seq_path: &str, toml: &Path, mean_keys: bool) -> String {
    let input = if seq_path == "builtin" {
        "builtin".to_string()
    } else {
        std::fs::canonicalize(seq_path).map_or(seq_path.to_string(), |p| p.display().to_string())
    };
    let st = &c.settings;
    let points = if st.points == "all" {
        "# points: whole face".to_string()
    } else {
        format!("points = \"{}\"", st.points)
    };
    let k = if st.method == Method::Hull {
        c.keys.len()
    } else {
        st.k
    };
    let methods: Vec<String> = Method::ALL.iter().map(|m| format!("\"{m}\"")).collect();
    let retarget = if mean_keys {
        format!("# [retarget] is left out: {} key shapes are cluster means, not frames, and the\n# retargeting study draws its target on key frames.\n", st.method)
    } else {
        format!("[retarget]\nmethod = \"{}\"\nk = {k}\nsolvers = [\"ls\", \"nnls\"]\ntrace_noise = [0.0, 0.01]\nstrip = 4\n", st.method)
    };
    // The temporal prior: the smoothing study at this λ has the exported weights' row.
    let smooth = if st.smooth > 0.0 {
        let k_line = if st.method == Method::Hull {
            String::new()
        } else {
            format!("k = {k}\n")
        };
        format!("\n# The weights were solved with the offline first-difference temporal prior at λ = {l}:\n# the [smooth] study's `prior offline order 1, λ {l}` row is that solve.\n[smooth]\nmethod = \"{}\"\n{k_line}solver = \"{}\"\nlambdas = [{l:?}]\n", st.method, st.solver, l = st.smooth)
    } else {
        String::new()
    };
    format!(
        "# Exported from the kslab lab: reproduces the current settings. Run: kslab run {}\ntitle = \"{} {} k={} {}\"\ninput = \"{input}\"\n{points}\nalign = true\nmethods = [{}]\nk = \"2..24\"\nsolvers = [\"{}\"]\n\n{retarget}{smooth}",
        toml.display(),
        st.points,
        st.method,
        k,
        st.solver,
        methods.join(", "),
        st.solver,
    )
}

/// The rig view's export: `rig_weights.csv` (a row per frame, a column per shape, as
/// `kslab rig --out` writes them, with the frame's landmark RMS) and `view.png` (the track
/// and the fitted rig on the current frame).
fn export_rig(s: &State, r: &super::rig::RigView, dir: &Path) -> Result<Vec<String>> {
    keyshape_io::create_dir_all(dir)?;
    let frames: Vec<i64> = match &s.computed {
        Some(c) if c.frames.len() == r.weights.len() => c.frames.clone(),
        _ => (0..r.weights.len() as i64).collect(),
    };
    let csv = dir.join("rig_weights.csv");
    let header = ["frame", "rms"]
        .into_iter()
        .map(String::from)
        .chain(r.names.iter().cloned());
    let records = frames.iter().enumerate().map(|(t, f)| {
        let mut row = vec![f.to_string(), fmt_num(r.rms[t])];
        row.extend(r.weights[t].iter().map(|x| fmt_num(*x)));
        row
    });
    write_atomic(&csv, |w| write_records(w, header, records))?;
    let t = s.frame.min(r.weights.len().saturating_sub(1));
    // y up in the view, down in the picture.
    let flat = |pts: &[[f64; 2]]| -> Vec<f64> { pts.iter().flat_map(|p| [p[0], -p[1]]).collect() };
    let (tracked, fitted) = (flat(&r.tracked[t]), flat(&r.fitted[t]));
    let ((x0, x1), (y0, y1)) = (
        (r.bounds.0[0], r.bounds.0[1]),
        (r.bounds.1[0], r.bounds.1[1]),
    );
    let panel = keyshape_pictures::render::face::Panel {
        title: format!(
            "frame {} · landmark RMS {}",
            frames[t],
            keyshape_core::stats::sig(r.rms[t], 3)
        ),
        layers: vec![
            keyshape_pictures::render::face::Layer {
                name: "tracked",
                shape: &tracked,
                dims: 2,
                polylines: &r.polylines,
                color: [20, 20, 20],
                dashed: false,
            },
            keyshape_pictures::render::face::Layer {
                name: "fitted rig, posed by the weights, head pose",
                shape: &fitted,
                dims: 2,
                polylines: &r.polylines,
                color: [30, 90, 200],
                dashed: true,
            },
        ],
        bounds: ((x0, -y1), (x1, -y0)),
        mesh: None,
    };
    let top = keyshape_rig::largest_weights(&r.names, &r.weights[t], 2);
    let png = dir.join("view.png");
    save_png(
        &keyshape_pictures::render::face::render_panels(&[panel], &format!("rig: {top}"), 480)?,
        &png,
    )?;
    Ok(vec![csv.display().to_string(), png.display().to_string()])
}

#[cfg(test)]
mod tests {
    use super::next_dir;

    #[test]
    fn the_export_line_fits_an_eighty_column_footer() {
        let dir = std::path::Path::new("./kslab-export-12");
        let files: Vec<String> = ["weights.csv", "view.png", "experiment.toml"]
            .iter()
            .map(|f| dir.join(f).display().to_string())
            .collect();
        let line = super::status_line(dir, &files);
        assert_eq!(
            line,
            "exported to kslab-export-12/: weights.csv, view.png, experiment.toml"
        );
        assert!(line.chars().count() < 79);
    }

    #[test]
    fn exports_are_numbered_and_never_replace_an_earlier_one() {
        let d = tempfile::tempdir().unwrap();
        assert_eq!(next_dir(d.path()), d.path().join("kslab-export"));
        std::fs::create_dir(d.path().join("kslab-export")).unwrap();
        assert_eq!(next_dir(d.path()), d.path().join("kslab-export-2"));
        std::fs::create_dir(d.path().join("kslab-export-2")).unwrap();
        // A file of that name counts as taken too.
        std::fs::write(d.path().join("kslab-export-3"), "x").unwrap();
        assert_eq!(next_dir(d.path()), d.path().join("kslab-export-4"));
    }
}
