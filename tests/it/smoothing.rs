//! The smoothing study: the post-filters against hand-computed values, the
//! study's measures (jitter, lag, the clean reference's low-pass) on signals whose answer is
//! known, the equal-jitter table's interpolation, and `kslab smooth` end to end with its
//! refusals.

// One segment is written `&[0..t]`: a slice holding one range, as the API takes.
#![allow(clippy::single_range_in_vec_init)]

use keyshape_core::solve::filters::{gaussian_lowpass, PostFilter};
use keyshape_core::solve::jitter::jitter;
use keyshape_core::solve::Solver;
use keyshape_core::stats::lag;
use keyshape_experiments::experiment::smoothing::{at_equal_jitter, SmoothRow};
use nalgebra::DMatrix;

fn close(a: &[f64], b: &[f64], tol: f64) {
    assert_eq!(a.len(), b.len());
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        assert!((x - y).abs() <= tol, "at {i}: {x} vs {y}\n{a:?}\n{b:?}");
    }
}

#[test]
fn moving_average_is_centred_and_shrinks_at_the_ends() {
    let x = [0.0, 3.0, 6.0, 0.0, 0.0, 9.0, 0.0];
    let y = PostFilter::MovingAverage { window: 3 }.apply_signal(&x);
    // Ends: window 1 (the value itself); inside: the mean of three.
    close(&y, &[0.0, 3.0, 3.0, 2.0, 3.0, 3.0, 0.0], 1e-15);
    let y5 = PostFilter::MovingAverage { window: 5 }.apply_signal(&x);
    close(
        &y5,
        &[0.0, 3.0, 9.0 / 5.0, 18.0 / 5.0, 15.0 / 5.0, 3.0, 0.0],
        1e-15,
    );
}

#[test]
fn exponential_average_by_hand() {
    let y = PostFilter::Exponential { alpha: 0.25 }.apply_signal(&[4.0, 0.0, 8.0]);
    // y0 = x0; y1 = 0.25·0 + 0.75·4 = 3; y2 = 0.25·8 + 0.75·3 = 4.25.
    close(&y, &[4.0, 3.0, 4.25], 1e-15);
}

#[test]
fn one_euro_is_an_ema_at_beta_zero_and_opens_up_with_speed() {
    let rate = 30.0;
    let x: Vec<f64> = (0..50).map(|t| ((t * 7919) % 13) as f64 / 13.0).collect();
    let f = PostFilter::OneEuro {
        min_cutoff: 2.0,
        beta: 0.0,
        d_cutoff: 1.0,
        rate,
    };
    // α = 1 / (1 + τ·rate), τ = 1 / (2π·f_c) (Casiez et al. 2012, Eq. for the low-pass).
    let alpha = 1.0 / (1.0 + rate / (2.0 * std::f64::consts::PI * 2.0));
    close(
        &f.apply_signal(&x),
        &PostFilter::Exponential { alpha }.apply_signal(&x),
        1e-14,
    );
    // By hand, with rate 2π so that α(f_c) = f_c / (f_c + 1): d_cutoff 1 gives α_d = 1/2;
    // min_cutoff 1, beta 1, x = [0, 1, 3].
    let pi = std::f64::consts::PI;
    let y = PostFilter::OneEuro {
        min_cutoff: 1.0,
        beta: 1.0,
        d_cutoff: 1.0,
        rate: 2.0 * pi,
    }
    .apply_signal(&[0.0, 1.0, 3.0]);
    // t = 1: speed 2π, smoothed ½·2π = π, cutoff 1 + π.
    let a1 = (1.0 + pi) / (2.0 + pi);
    let y1 = a1;
    // t = 2: speed (3 − 1)·2π = 4π, smoothed ½·4π + ½·π = 2.5π, cutoff 1 + 2.5π.
    let a2 = (1.0 + 2.5 * pi) / (2.0 + 2.5 * pi);
    let y2 = a2 * 3.0 + (1.0 - a2) * y1;
    close(&y, &[0.0, y1, y2], 1e-14);
    // With beta > 0 a fast ramp is followed more closely than with beta 0.
    let ramp: Vec<f64> = (0..40).map(|t| t as f64 * 0.5).collect();
    let lagged = |beta: f64| {
        let y = PostFilter::OneEuro {
            min_cutoff: 1.0,
            beta,
            d_cutoff: 1.0,
            rate,
        }
        .apply_signal(&ramp);
        ramp[39] - y[39]
    };
    assert!(
        lagged(0.5) < 0.5 * lagged(0.0),
        "{} {}",
        lagged(0.5),
        lagged(0.0)
    );
}

#[test]
fn filters_clamp_to_the_solver_and_keep_segments_apart() {
    // Row 0 jumps from 0 to 1 at a segment boundary; a filter across it would blur it.
    let w = DMatrix::from_row_slice(2, 6, &[0., 0., 0., 1., 1., 1., -1., 2., -1., 2., 2., 2.]);
    let segs = [0..3, 3..6];
    let ma = PostFilter::MovingAverage { window: 3 };
    let out = ma.apply(&w, &segs, Solver::Nnls).unwrap();
    close(
        &out.row(0).iter().copied().collect::<Vec<_>>(),
        &[0., 0., 0., 1., 1., 1.],
        1e-15,
    );
    // Row 1, first segment: [-1, 0, -1] → clamped at 0 for NNLS.
    let r1: Vec<f64> = out.row(1).iter().copied().collect();
    close(&r1, &[0., 0., 0., 2., 2., 2.], 1e-15);
    let b = ma.apply(&w, &segs, Solver::Bounded).unwrap();
    assert!(b.iter().all(|v| (0.0..=1.0).contains(v)), "{b}");
    let ls = ma.apply(&w, &segs, Solver::Ls).unwrap();
    assert_eq!(ls[(1, 0)], -1.0);
    for bad in [
        PostFilter::MovingAverage { window: 4 },
        PostFilter::MovingAverage { window: 0 },
        PostFilter::Exponential { alpha: 0.0 },
        PostFilter::Exponential { alpha: 1.5 },
        PostFilter::OneEuro {
            min_cutoff: f64::NAN,
            beta: 0.0,
            d_cutoff: 1.0,
            rate: 30.0,
        },
        PostFilter::OneEuro {
            min_cutoff: 1.0,
            beta: -1.0,
            d_cutoff: 1.0,
            rate: 30.0,
        },
        // The bounds themselves: a zero cutoff or rate freezes the filter.
        PostFilter::OneEuro {
            min_cutoff: 0.0,
            beta: 0.0,
            d_cutoff: 1.0,
            rate: 30.0,
        },
        PostFilter::OneEuro {
            min_cutoff: 1.0,
            beta: 0.0,
            d_cutoff: 0.0,
            rate: 30.0,
        },
        PostFilter::OneEuro {
            min_cutoff: 1.0,
            beta: 0.0,
            d_cutoff: 1.0,
            rate: 0.0,
        },
    ] {
        let e = bad.apply(&w, &segs, Solver::Nnls).unwrap_err().to_string();
        let family = match bad {
            PostFilter::MovingAverage { .. } => "moving-average",
            PostFilter::Exponential { .. } => "ema",
            PostFilter::OneEuro { .. } => "one-euro",
        };
        assert_eq!(bad.family(), family);
        assert!(
            e.starts_with(&format!("bad {family} filter setting: ")),
            "{e}"
        );
    }
    // The bounds that are allowed: window 1 and alpha 1 leave the weights as they are.
    for ok in [
        PostFilter::MovingAverage { window: 1 },
        PostFilter::Exponential { alpha: 1.0 },
    ] {
        assert_eq!(ok.apply(&w, &segs, Solver::Ls).unwrap(), w, "{ok:?}");
    }
    // beta 0 is allowed (One Euro is then an EMA).
    assert!(PostFilter::OneEuro {
        min_cutoff: 1.0,
        beta: 0.0,
        d_cutoff: 1.0,
        rate: 30.0,
    }
    .check()
    .is_ok());
}

#[test]
fn jitter_of_a_parabola_and_per_segment() {
    // x_t = a t² has second difference 2a everywhere: RMS 2a per value.
    let a = 0.3;
    let x = DMatrix::from_fn(2, 10, |_, t| a * (t * t) as f64);
    assert!((jitter(&x, &[0..10], 2) - 2.0 * a).abs() < 1e-12);
    // Two points per frame counted as one value each: the norm is over both rows.
    assert!((jitter(&x, &[0..10], 1) - 2.0 * a * 2f64.sqrt()).abs() < 1e-12);
    // A jump between segments is not jitter.
    let mut y = DMatrix::zeros(1, 8);
    for t in 4..8 {
        y[(0, t)] = 100.0;
    }
    assert_eq!(jitter(&y, &[0..4, 4..8], 1), 0.0);
    assert!(jitter(&y, &[0..8], 1) > 10.0);
}

#[test]
fn lag_finds_a_known_shift_and_a_centred_filter_has_none() {
    let base: Vec<f64> = (0..120)
        .map(|t| (t as f64 * 0.21).sin() + 0.5 * (t as f64 * 0.047).cos())
        .collect();
    let b = DMatrix::from_row_slice(1, 120, &base);
    for shift in [0i64, 2, 5] {
        let a = DMatrix::from_fn(1, 120, |_, t| base[(t as i64 - shift).max(0) as usize]);
        assert_eq!(lag(&a, &b, &[0..120], 15), shift);
    }
    let centred = PostFilter::MovingAverage { window: 9 }.apply_signal(&base);
    let c = DMatrix::from_row_slice(1, 120, &centred);
    assert_eq!(lag(&c, &b, &[0..120], 15), 0);
    let ema = PostFilter::Exponential { alpha: 0.15 }.apply_signal(&base);
    let e = DMatrix::from_row_slice(1, 120, &ema);
    assert!(lag(&e, &b, &[0..120], 15) >= 3);
}

#[test]
fn gaussian_lowpass_keeps_ramps_and_stays_in_segments() {
    let x = DMatrix::from_fn(1, 40, |_, t| 3.0 + 0.5 * t as f64);
    let y = gaussian_lowpass(&x, &[0..40], 2.0);
    // Symmetric kernel: a ramp is unchanged where the kernel fits (6 frames from the ends),
    // so the low-pass does not shift the reference in time.
    for t in 6..34 {
        assert!((y[(0, t)] - x[(0, t)]).abs() < 1e-12, "frame {t}");
    }
    // A step at a segment boundary stays a step.
    let s = DMatrix::from_fn(1, 20, |_, t| if t < 10 { 0.0 } else { 1.0 });
    let z = gaussian_lowpass(&s, &[0..10, 10..20], 2.0);
    assert_eq!(z, s);
    // Noise is reduced.
    let n = DMatrix::from_fn(1, 200, |_, t| if t % 2 == 0 { 1.0 } else { -1.0 });
    let m = gaussian_lowpass(&n, &[0..200], 2.0);
    assert!(
        m.columns(10, 180).amax() < 1e-3,
        "{}",
        m.columns(10, 180).amax()
    );
}

fn row(approach: &str, jitter: f64, err: f64) -> SmoothRow {
    SmoothRow {
        approach: approach.into(),
        setting: String::new(),
        source_rms: 0.0,
        target_rms_tracked: err,
        target_rms_clean: err + 1.0,
        jitter_target: jitter,
        jitter_weights: 0.0,
        // A lag that names the row, to see which setting the table took it from.
        lag_frames: (jitter * 10.0) as i64,
        kkt: None,
    }
}

#[test]
fn equal_jitter_interpolates_along_each_curve() {
    let rows = vec![
        row("none", 10.0, 1.0),
        row("a", 8.0, 2.0),
        row("a", 4.0, 4.0),
        // b's jitter falls, then rises again: 5 is reached only on its first stretch.
        row("b", 6.0, 3.0),
        row("b", 7.0, 9.0),
        row("b", 2.0, 20.0),
    ];
    let t = at_equal_jitter(&rows, &[0.5, 0.3]);
    let get = |name: &str, level: f64| {
        t.iter()
            .find(|r| r.approach == name && (r.jitter_target - level).abs() < 1e-12)
            .unwrap()
    };
    // a at 5: between (8, 2) and (4, 4): 2 + (3/4)·2 = 3.5.
    assert!((get("a", 5.0).target_rms_tracked.unwrap() - 3.5).abs() < 1e-12);
    assert!((get("a", 5.0).target_rms_clean.unwrap() - 4.5).abs() < 1e-12);
    // a never reaches 3.
    assert!(get("a", 3.0).target_rms_tracked.is_none());
    // b at 5: the stretch (7, 9) → (2, 20), not (6, 3) → (2, 20) by sorting: 9 + (2/5)·11.
    assert!((get("b", 5.0).target_rms_tracked.unwrap() - 13.4).abs() < 1e-12);
    // b at 3: same stretch, 9 + (4/5)·11.
    assert!((get("b", 3.0).target_rms_tracked.unwrap() - 17.8).abs() < 1e-12);
    // The lag is the nearer setting's: a at 5 is 3/4 of the way to (4, 4); b at 5 is 2/5
    // of the way from (7, 9), b at 3 is 4/5 of the way.
    assert_eq!(get("a", 5.0).lag_frames, Some(40));
    assert_eq!(get("b", 5.0).lag_frames, Some(70));
    assert_eq!(get("b", 3.0).lag_frames, Some(20));
    // Exactly half way goes to the stronger setting.
    let half = at_equal_jitter(&[row("none", 10.0, 1.0), row("c", 6.0, 3.0)], &[0.8]);
    assert_eq!(half[0].lag_frames, Some(60));
    assert!((half[0].target_rms_tracked.unwrap() - 2.0).abs() < 1e-12);
    assert!((half[0].jitter_target - 8.0).abs() < 1e-12);
    // Without a `none` row there is nothing to scale by.
    assert!(at_equal_jitter(&[row("c", 6.0, 3.0)], &[0.5]).is_empty());
}

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
