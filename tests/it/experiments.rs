//! Experiment specs, the runner, and the reviewed snapshots of what it writes.

use keyshape_lab::experiment::{run, Spec};
use keyshape_lab::report::write_outcome;
use std::path::{Path, PathBuf};

pub fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn update() -> bool {
    std::env::var_os("UPDATE_SNAPSHOTS").is_some()
}

#[test]
fn invalid_specs_name_the_key_and_line() {
    let p = Path::new("bad.toml");
    let base = "title = \"t\"\ninput = \"builtin\"\nmethods = [\"spread\"]\nk = \"2..4\"\nsolvers = [\"nnls\"]\n";
    let e = Spec::from_str(
        p,
        &base.replace(
            "methods = [\"spread\"]",
            "methods = [\"spread\", \"sprad\"]",
        ),
    )
    .unwrap_err()
    .to_string();
    assert!(e.starts_with("bad.toml:3:") && e.contains("sprad"), "{e}");
    let e = Spec::from_str(p, &format!("{base}metods = 1\n"))
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("bad.toml:6:") && e.contains("metods"), "{e}");
    let e = Spec::from_str(p, &base.replace("\"2..4\"", "\"4..2\""))
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("bad.toml:4:1: k:"), "{e}");
    let e = Spec::from_str(p, &base.replace("[\"nnls\"]", "[\"lasso\"]"))
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("bad.toml:5:") && e.contains("lasso"), "{e}");
    let e = Spec::from_str(p, &base.replace("title = \"t\"\n", ""))
        .unwrap_err()
        .to_string();
    assert!(e.contains("title"), "{e}");
}

#[test]
fn every_experiment_in_the_repository_parses() {
    for entry in std::fs::read_dir(repo("experiments")).unwrap() {
        let p = entry.unwrap().path();
        if p.extension().is_some_and(|e| e == "toml") {
            Spec::from_path(&p).unwrap_or_else(|e| panic!("{e}"));
        }
    }
}

/// Compares a CSV against its golden file: same text columns, numbers within 1e-6 relative.
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
        for (x, y) in a.split(',').zip(b.split(',')) {
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

/// Compares decoded pixels: at most 0.5 % of pixels may differ by more than 16 in a channel.
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
        .filter(|(p, q)| {
            let d = |x: u8, y: u8| x.abs_diff(y) > 16;
            d(p.red(), q.red()) || d(p.green(), q.green()) || d(p.blue(), q.blue())
        })
        .count();
    let share = differ as f64 / a.pixels().len() as f64;
    assert!(
        share <= 0.005,
        "{:.2}% of pixels differ from {}",
        share * 100.0,
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
}
