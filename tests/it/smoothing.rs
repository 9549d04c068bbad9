//! `kslab smooth` end to end with its refusals, and the smoothed solve on the command
//! line. The filters' and the study's own tests are in their crates
//! (`crates/keyshape-core/tests/filters.rs`, `crates/keyshape-experiments/tests/smoothing.rs`).

// One segment is written `&[0..t]`: a slice holding one range, as the API takes.
#![allow(clippy::single_range_in_vec_init)]

/// `kslab smooth` on the built-in sequence: every approach and setting in the CSV, the
/// λ = 0 row equal to the plain solve's error, a PNG; and its refusals.
#[test]
fn smooth_command_end_to_end_and_refusals() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("study");
    let run = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_kslab"))
            .args(args)
            .output()
            .unwrap()
    };
    let o = run(&[
        "smooth",
        "--points",
        "lips",
        "--k",
        "6",
        "--lambdas",
        "10,1000",
        "--windows",
        "3,9",
        "--alphas",
        "0.5",
        "--one-euro-cutoffs",
        "4,1",
        "--one-euro-betas",
        "0,0.5",
        "--out",
        out.to_str().unwrap(),
        "-q",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_to_string(out.join("smoothing.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    // Header, none, 3 prior curves × 2 λ, 2 windows, 1 alpha, 2 betas × 2 cutoffs.
    assert_eq!(lines.len(), 1 + 1 + 6 + 2 + 1 + 4, "{csv}");
    for name in [
        "none,",
        "prior offline order 1,λ 10,",
        "prior offline order 2,λ 1000,",
        "prior causal order 1,λ 1000,",
        "moving-average,window 9,",
        "ema,alpha 0.5,",
        "one-euro beta 0,min_cutoff 4 Hz beta 0,",
        "one-euro beta 0.5,min_cutoff 1 Hz beta 0.5,",
    ] {
        assert!(
            lines.iter().any(|l| l.starts_with(name)),
            "{name} missing:\n{csv}"
        );
    }
    assert!(out.join("smoothing.png").is_file());
    assert!(out.join("smoothing_at_equal_jitter.csv").is_file());
    // Jitter falls with λ for the offline prior, error rises.
    let field = |l: &str, i: usize| l.split(',').nth(i).unwrap().parse::<f64>().unwrap();
    let find = |p: &str| *lines.iter().find(|l| l.starts_with(p)).unwrap();
    let (none, weak, strong) = (
        find("none,"),
        find("prior offline order 1,λ 10,"),
        find("prior offline order 1,λ 1000,"),
    );
    assert!(field(none, 5) > field(weak, 5) && field(weak, 5) > field(strong, 5));
    assert!(field(none, 2) <= field(weak, 2) && field(weak, 2) <= field(strong, 2));

    let before: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    for (args, says) in [
        (
            vec!["--lambdas", "-1"],
            "λ must be a finite number ≥ 0, got -1",
        ),
        (vec!["--lambdas", "NaN"], "got NaN"),
        (vec!["--windows", "4"], "window 4"),
        (vec!["--alphas", "0"], "alpha 0"),
        (vec!["--one-euro-betas", "-0.5"], "beta -0.5"),
        (
            vec!["--clean-sigma", "0"],
            "--clean-sigma 0: give more than 0 and at most 1000 frames",
        ),
        (
            vec!["--clean-sigma", "-2"],
            "--clean-sigma -2: give more than 0 and at most 1000 frames",
        ),
        (vec!["--k", "0"], "k ≥ 1"),
        (
            vec!["--method", "hull", "--k", "5"],
            "k does not apply to the hull",
        ),
        (vec!["--filters", "kalman"], "unknown filter 'kalman'"),
        (
            vec!["--filters", "ema", "--windows", "3"],
            "windows set, but the moving-average filter is not among the filters compared (ema)",
        ),
        (
            vec!["--filters", "moving-average", "--one-euro-betas", "0"],
            "one-euro betas set, but the one-euro filter",
        ),
    ] {
        let bad = dir.path().join("bad");
        let mut a = vec!["smooth", "--points", "lips", "--out", bad.to_str().unwrap()];
        a.extend(args.iter());
        let o = run(&a);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert!(!bad.exists(), "{args:?} left {bad:?}");
    }
    let after: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(before.len(), after.len());
}

/// `--filters` picks the families compared: the others' rows are not there; `--method hull`
/// runs with its own k.
#[test]
fn smooth_filters_choose_the_families_and_hull_takes_its_own_k() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_kslab"))
        .args([
            "smooth",
            "--points",
            "lips",
            "--method",
            "hull",
            "--lambdas",
            "100",
        ])
        .args([
            "--filters",
            "ema",
            "--alphas",
            "0.5,0.2",
            "--out",
            out.to_str().unwrap(),
            "-q",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_to_string(out.join("smoothing.csv")).unwrap();
    let approaches: Vec<&str> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap())
        .collect();
    assert_eq!(
        approaches,
        [
            "none",
            "prior offline order 1",
            "prior offline order 2",
            "prior causal order 1",
            "ema",
            "ema"
        ]
    );
}

/// The CLI on the news sample (20 clips): one segment per clip, the KKT residual reported,
/// and λ = 0 writing exactly the unsmoothed weights.
#[test]
fn solve_smooth_on_the_command_line_respects_clips() {
    let dir = tempfile::tempdir().unwrap();
    let run = |extra: &[&str], out: &str| {
        let file = crate::common::shared("pyfeat_samples/news_sample_compact.csv");
        let mut args = vec![
            "solve".to_string(),
            file.display().to_string(),
            "--keys".into(),
            "0,40,120".into(),
            "--out".into(),
            dir.path().join(out).display().to_string(),
        ];
        args.extend(extra.iter().map(|s| s.to_string()));
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_kslab"))
            .args(&args)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        o.stdout
    };
    let v: serde_json::Value =
        serde_json::from_slice(&run(&["--smooth", "50", "--json"], "s.csv")).unwrap();
    let sm = &v["smoothing"];
    assert_eq!(sm["segments"], 20);
    assert!(sm["kkt_residual"].as_f64().unwrap() < 1e-8, "{sm}");
    assert_eq!(sm["mode"], "offline");
    run(&[], "plain.csv");
    run(&["--smooth", "0"], "zero.csv");
    let read = |f: &str| std::fs::read(dir.path().join(f)).unwrap();
    assert_eq!(read("plain.csv"), read("zero.csv"));
    assert_ne!(read("plain.csv"), read("s.csv"));
}
