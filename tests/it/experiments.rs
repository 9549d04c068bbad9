//! Experiment specs, the runner, and the reviewed snapshots of what it writes.
//! Here: what runs the `kslab` binary; the library's own tests are in `crates/keyshape-experiments/tests/experiments.rs`.

use keyshape_experiments::experiment::{run, Spec};
use keyshape_experiments::report::write_outcome;
use std::path::{Path, PathBuf};

pub fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// `UPDATE_SNAPSHOTS=1` rewrites the snapshots (then review them with `git diff`); any other
/// value is a mistake and fails, so a stray variable cannot turn every snapshot test green.
/// `.ci/run` refuses to run with the variable set at all.
pub fn update() -> bool {
    match std::env::var("UPDATE_SNAPSHOTS") {
        Err(_) => false,
        Ok(v) if v == "1" => true,
        Ok(v) => panic!("UPDATE_SNAPSHOTS={v:?}: set it to 1 to rewrite snapshots, or unset it"),
    }
}

/// Compares a CSV against its golden file: the same number of fields on every line, the
/// same text, numbers within 1e-6 relative.
fn assert_csv_matches(got: &str, golden: &Path) {
    if update() {
        std::fs::write(golden, got).unwrap();
        return;
    }
    let want = std::fs::read_to_string(golden).unwrap_or_else(|_| {
        panic!(
            "missing {}: run with UPDATE_SNAPSHOTS=1 and review",
            golden.display()
        )
    });
    let (g, w): (Vec<&str>, Vec<&str>) = (got.lines().collect(), want.lines().collect());
    assert_eq!(
        g.len(),
        w.len(),
        "row count differs from {}",
        golden.display()
    );
    for (i, (a, b)) in g.iter().zip(&w).enumerate() {
        let (xa, ya): (Vec<&str>, Vec<&str>) = (a.split(',').collect(), b.split(',').collect());
        assert_eq!(
            xa.len(),
            ya.len(),
            "line {}: {} fields, the golden file has {}",
            i + 1,
            xa.len(),
            ya.len()
        );
        for (x, y) in xa.into_iter().zip(ya) {
            match (x.parse::<f64>(), y.parse::<f64>()) {
                (Ok(x), Ok(y)) => assert!(
                    (x - y).abs() <= 1e-6 * y.abs().max(1e-9),
                    "line {}: {x} vs golden {y}",
                    i + 1
                ),
                _ => assert_eq!(x, y, "line {}", i + 1),
            }
        }
    }
}

/// Compares decoded pixels exactly: the pictures are deterministic (tiny-skia, committed
/// fonts), so one changed pixel is a change to review.
pub fn assert_png_matches(got: &Path, golden: &Path) {
    if update() {
        std::fs::copy(got, golden).unwrap();
        return;
    }
    let a = tiny_skia::Pixmap::load_png(got).unwrap();
    let b = tiny_skia::Pixmap::load_png(golden).unwrap_or_else(|_| {
        panic!(
            "missing {}: run with UPDATE_SNAPSHOTS=1 and review",
            golden.display()
        )
    });
    assert_eq!((a.width(), a.height()), (b.width(), b.height()));
    let differ = a
        .pixels()
        .iter()
        .zip(b.pixels())
        .filter(|(p, q)| p != q)
        .count();
    assert!(
        differ == 0,
        "{differ} pixels differ from {} (UPDATE_SNAPSHOTS=1 rewrites it; review the picture)",
        golden.display()
    );
}

#[test]
fn smoke_experiment_matches_its_reviewed_snapshots() {
    let (spec, base) = Spec::from_path(&repo("experiments/smoke_builtin_lips.toml")).unwrap();
    let outcome = run(&spec, &base, &|_, _| {}).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let files = write_outcome(&outcome, dir.path()).unwrap();
    assert_eq!(files.len(), 4);
    let csv = std::fs::read_to_string(dir.path().join("curves.csv")).unwrap();
    assert_csv_matches(&csv, &repo("snapshots/smoke_builtin_lips.csv"));
    assert_png_matches(
        &dir.path().join("curves_nnls.png"),
        &repo("snapshots/smoke_builtin_lips_nnls.png"),
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).unwrap())
            .unwrap();
    assert_eq!(report["frames"], 216);
    assert_eq!(report["settings"]["methods"][1], "kmeans2");
    assert_eq!(report["figures"][0], "curves_nnls.png");

    // What the picture must show, through its specification: titles, one series per
    // method in order with its paper-000 style, and every (k, RMS) of the CSV — so a
    // dropped title, swapped curves or a missing last point fail here as well as in pixels.
    use keyshape_pictures::plot::{curves_plot, Style};
    let title = keyshape_experiments::report::curves_title(&spec.title, "nnls", spec.align);
    let plot = curves_plot(&outcome.rows, "nnls", &title, "px");
    assert_eq!(
        plot.title,
        "Built-in d18, lips, k = 2..8 — nnls, head motion removed"
    );
    // NNLS errors here span 25× (random at k = 2 to greedy at k = 8): a log axis, on which
    // the curves below 1 px stay apart (on the linear one they ran together at the floor).
    assert!(plot.log_y());
    assert_eq!(plot.x_label, "number of key shapes k");
    assert_eq!(plot.y_label, "RMS error per point (px), nnls");
    let names: Vec<&str> = plot.series.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(
        names,
        ["spread", "kmeans2", "kmeans3", "hull", "greedy", "random"]
    );
    let styles: Vec<(Style, [u8; 3])> = plot.series.iter().map(|s| (s.style, s.color)).collect();
    assert_eq!(styles[0], (Style::Line, [31, 90, 200]));
    assert_eq!(styles[1], (Style::Dashed, [30, 150, 60]));
    assert_eq!(styles[2], (Style::Dashed, [190, 40, 190]));
    assert_eq!(styles[3].0, Style::Marker);
    for s in &plot.series {
        let want: Vec<(f64, f64)> = csv
            .lines()
            .skip(1)
            .map(|l| l.split(',').collect::<Vec<_>>())
            .filter(|f| f[0] == s.name && f[1] == "nnls")
            .map(|f| (f[2].parse().unwrap(), f[4].parse().unwrap()))
            .collect();
        assert_eq!(s.points, want, "{}", s.name);
        if s.name != "hull" {
            assert_eq!(s.points.first().map(|p| p.0), Some(2.0), "{}", s.name);
            assert_eq!(s.points.last().map(|p| p.0), Some(8.0), "{}", s.name);
        }
    }
}

/// The y axis turns logarithmic when the data span two decades (LS error curves), with
/// 1-2-5 ticks; `kslab curves --png` names its files by solver whatever the solver count.
#[test]
fn log_axis_for_curves_spanning_decades_and_stable_png_names() {
    use keyshape_pictures::plot::{PlotSpec, Series, Style};
    let spec = |ys: &[f64]| PlotSpec {
        title: String::new(),
        x_label: String::new(),
        y_label: String::new(),
        series: vec![Series {
            name: "a".into(),
            points: ys.iter().enumerate().map(|(i, y)| (i as f64, *y)).collect(),
            style: Style::Line,
            color: [0, 0, 0],
        }],
        y_from_zero: true,
        y_at_least: None,
    };
    assert!(spec(&[20.0, 2.0, 0.2]).log_y());
    // Round three: LS errors spanning 94× stayed on a linear axis, every curve past k = 10
    // flat on zero. A decade is enough.
    assert!(spec(&[20.0, 2.0, 0.5]).log_y(), "40× is more than a decade");
    assert!(spec(&[94.0, 1.0]).log_y());
    assert!(!spec(&[20.0, 2.5]).log_y(), "8× is less than a decade");
    assert!(
        !spec(&[20.0, 0.0]).log_y(),
        "a zero cannot go on a log axis"
    );
    assert_eq!(
        keyshape_pictures::render::log_ticks(0.04, 7.0),
        vec![0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0]
    );
    assert_eq!(
        keyshape_pictures::render::log_ticks(0.001, 50.0),
        vec![0.001, 0.01, 0.1, 1.0, 10.0]
    );
    assert!(keyshape_pictures::render::render_plot(&spec(&[20.0, 2.0, 0.2]), 400, 300).is_ok());

    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("c.png");
    for solvers in ["nnls", "ls,nnls"] {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_kslab"))
            .args([
                "curves",
                "--points",
                "lips",
                "--methods",
                "spread",
                "--k",
                "2..4",
            ])
            .args(["--solver", solvers, "--png", png.to_str().unwrap(), "-q"])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(dir.path().join("c_nnls.png").is_file(), "{solvers}");
        assert!(!png.exists(), "{solvers}: never the bare name");
    }
    assert!(dir.path().join("c_ls.png").is_file());
}

/// A study writes its own table and figure into the report folder, and the figure is
/// listed in `report.json` with the study's keys ([retarget] of Figs. 4–5).
#[test]
fn a_study_writes_its_table_and_figure_and_report_json_lists_them() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("o");
    let r = crate::common::kslab(&[
        "run",
        repo("experiments/chuang_fig4_5_lips_d6.toml")
            .to_str()
            .unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let csv = std::fs::read_to_string(out.join("retarget.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some("solver,trace_noise,source_rms,target_rms,jitter,negative_share,max_abs_weight")
    );
    // Two solvers at four noise levels.
    assert_eq!(lines.count(), 8);
    let png = std::fs::read(out.join("strip.png")).unwrap();
    assert!(png.starts_with(b"\x89PNG"));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["figures"], serde_json::json!(["strip.png"]));
    assert_eq!(report["retarget"].as_array().unwrap().len(), 8);
    assert_eq!(report["strip_frames"].as_array().unwrap().len(), 4);
    // The keys of the studies that did not run are there, empty.
    for k in [
        "intensity",
        "orthogonality_mean",
        "alignment",
        "rig_recovery",
    ] {
        assert!(report[k].is_null(), "{k}: {}", report[k]);
    }
    assert!(
        r.stdout.contains("retarget, exact target: ls target RMS"),
        "{}",
        r.stdout
    );
}
