//! Experiment specs, the runner, and the reviewed snapshots of what it writes.
//! (What runs the `kslab` binary is in `tests/it/experiments.rs`.)

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_experiments::experiment::{run, Spec};
use keyshape_experiments::report::write_outcome;
use std::path::{Path, PathBuf};

/// `rel` in the repository.
fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
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
    // The [smooth] study: its settings are checked when the spec is read, with the line.
    let smooth = "title = \"t\"\ninput = \"builtin\"\n[smooth]\nmethod = \"spread\"\nk = 6\n";
    assert!(Spec::from_str(p, smooth).is_ok());
    for (extra, says) in [
        (
            "lambdas = [-1.0]\n",
            "λ must be a finite number ≥ 0, got -1",
        ),
        ("windows = [4]\n", "window 4"),
        ("alphas = [0.0]\n", "alpha 0"),
        (
            "clean_sigma = 0.0\n",
            "clean_sigma 0: give more than 0 and at most 1000 frames",
        ),
        ("lambda = [1.0]\n", "lambda"),
    ] {
        let e = Spec::from_str(p, &format!("{smooth}{extra}"))
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("bad.toml:") && e.contains(says),
            "{extra}: {e}"
        );
    }
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

/// `compare_raw`: the raw curves are exactly a sweep of the unaligned shapes, the aligned
/// ones a sweep of the aligned shapes (computed here through the library), and the report
/// draws them side by side on one y scale.
#[test]
fn compare_raw_sweeps_the_unaligned_shapes_beside_the_aligned_ones() {
    use keyshape_core::decompose::{prepare, PrepareOptions};
    use keyshape_core::keyshapes::{curves::sweep, Analysis, KeyOptions, Method};
    use keyshape_core::solve::Solver;
    let text = "title = \"t\"\ninput = \"builtin\"\npoints = \"lips\"\nmethods = [\"spread\", \"kmeans2-mean\"]\ncompare_raw = true\nk = \"2..5\"\nsolvers = [\"nnls\"]\n";
    let spec = Spec::from_str(Path::new("c.toml"), text).unwrap();
    let o = run(&spec, Path::new("."), &|_, _| {}).unwrap();
    let seq = keyshape_io::builtin_sequence().unwrap();
    let methods = [Method::Spread, Method::KMeans { pcs: 2, mean: true }];
    for (align, rows) in [(true, &o.rows), (false, &o.raw_rows)] {
        let p = prepare(
            &seq,
            &PrepareOptions {
                points: Some("lips".into()),
                align,
            },
        )
        .unwrap();
        let an = Analysis::new(p.seq.coords, p.seq.points).unwrap();
        let want = sweep(
            &an,
            &methods,
            2..=5,
            &[Solver::Nnls],
            &KeyOptions::default(),
            &|_, _| {},
        )
        .unwrap();
        assert_eq!(rows.len(), want.len());
        for (a, b) in rows.iter().zip(&want) {
            assert_eq!(
                (&a.method, a.k, a.keys.clone()),
                (&b.method, b.k, b.keys.clone())
            );
            assert!((a.rms - b.rms).abs() < 1e-12 * b.rms.max(1.0));
        }
    }
    assert!(o.rows.iter().zip(&o.raw_rows).any(|(a, r)| a.rms != r.rms));
    let dir = tempfile::tempdir().unwrap();
    let files = write_outcome(&o, dir.path()).unwrap();
    let png = dir.path().join("curves_nnls_aligned_vs_raw.png");
    assert!(files.contains(&png) && files.contains(&dir.path().join("curves_raw.csv")));
    let img = image_size(&png);
    assert_eq!(img, (1800, 600));
}

fn image_size(p: &Path) -> (u32, u32) {
    let d = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(p).unwrap()));
    let r = d.read_info().unwrap();
    (r.info().width, r.info().height)
}
