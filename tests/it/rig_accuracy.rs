//! The rig's weights measured against ground truth. Tracks rendered through the
//! ICT rig from known weights are solved back; the default solve (magnitude prior, no
//! freezing, zero-phase smoothing) must meet the goals, its per-frame optimum must
//! meet its KKT conditions, and a noise-free render must come back exactly.
//! Here: what runs the `kslab` binary; the library's own tests are in `crates/keyshape-rig/tests/rig_accuracy.rs`.

use crate::common::{kslab, shared};
use keyshape_rig::Rig;

fn ict() -> Rig {
    Rig::read_ict(&shared("ict_facekit_face")).unwrap()
}

/// Bad settings are refused with the value named, and nothing is written.
#[test]
fn bad_priors_and_settings_are_refused() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("w.csv");
    let o = out.display().to_string();
    for (args, needle) in [
        (
            vec!["rig", "--prior", "-1", "--out", &o],
            "magnitude prior must be a number ≥ 0, not -1",
        ),
        (vec!["rig", "--prior", "NaN", "--out", &o], "not NaN"),
        (
            vec!["rig", "--zero-phase", "-2", "--out", &o],
            "zero-phase σ must be a number of frames in [0, 1000], not -2",
        ),
        (
            vec!["rig", "--live", "--zero-phase", "2", "--out", &o],
            "--live is causal",
        ),
        (
            vec!["rig-accuracy", "--noise", "-1", "--out", &o],
            "--noise -1: give 0 to 1000 pixels",
        ),
        (
            vec!["rig-accuracy", "--frames", "1", "--out", &o],
            "frames 1 is not allowed",
        ),
        (
            vec!["rig", "--prior", "0", "--no-prior-taper", "--out", &o],
            "--no-prior-taper: there is no prior to taper (--prior 0)",
        ),
        (
            vec![
                "rig-accuracy",
                "--prior",
                "0",
                "--no-prior-taper",
                "--out",
                &o,
            ],
            "--no-prior-taper: there is no prior to taper (--prior 0)",
        ),
    ] {
        let r = kslab(&args);
        assert_eq!(r.code, 1, "{args:?}: {}", r.stderr);
        assert!(r.stderr.contains(needle), "{args:?}: {}", r.stderr);
        assert!(!out.exists(), "{args:?} wrote its output");
    }
}

/// `kslab rig-accuracy` prints a summary per kind and writes every shape's measures.
#[test]
fn the_benchmark_command_writes_per_shape_measures() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("acc.csv");
    let r = kslab(&[
        "rig-accuracy",
        "--kind",
        "winks",
        "--frames",
        "120",
        "--out",
        &out.display().to_string(),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(r.stdout.starts_with("winks   mean r "), "{}", r.stdout);
    let text = std::fs::read_to_string(&out).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "kind,shape,active,r,mae,rmse,peak_reach,twin_leakage,idle_activation,jitter,true_jitter,lag,seed");
    assert_eq!(lines.len(), 1 + ict().k());
    let blink = lines
        .iter()
        .find(|l| l.starts_with("winks,eyeBlink_L,true,"))
        .unwrap();
    let f: Vec<&str> = blink.split(',').collect();
    assert!(f[3].parse::<f64>().unwrap() > 0.9, "{blink}");
    assert!(
        !f[6].is_empty() && !f[7].is_empty(),
        "peak reach and twin leakage: {blink}"
    );
}

/// `--no-prior-taper` takes effect: the JSON says which prior solved, and the weights
/// differ (the taper lifts the largest weights).
#[test]
fn no_prior_taper_takes_effect() {
    let d = tempfile::tempdir().unwrap();
    let mut largest = Vec::new();
    for (flag, taper) in [(None, true), (Some("--no-prior-taper"), false)] {
        let out = d.path().join(format!("w{taper}.csv"));
        let o = out.display().to_string();
        let mut args = vec!["rig", "--json", "--out", &o];
        args.extend(flag);
        let r = kslab(&args);
        assert_eq!(r.code, 0, "{}", r.stderr);
        let v: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
        assert_eq!(v["prior_taper"], serde_json::json!(taper), "{}", r.stdout);
        let text = std::fs::read_to_string(&out).unwrap();
        let max = text
            .lines()
            .skip(1)
            .flat_map(|l| {
                l.split(',')
                    .skip(1)
                    .filter_map(|x| x.parse::<f64>().ok())
                    .collect::<Vec<_>>()
            })
            .fold(0.0f64, f64::max);
        largest.push(max);
    }
    assert!(largest[0] > largest[1], "{largest:?}");
}

/// `kslab rig --neutral FIRST-LAST` names a recorded lead-in by frame numbers (inclusive);
/// the JSON reports it, and a reversed or unreadable stretch is refused by value with
/// nothing written.
#[test]
fn the_rig_command_takes_a_neutral_stretch() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("w.csv");
    let o = out.display().to_string();
    let r = kslab(&["rig", "--neutral", "0-9", "--json", "--out", &o]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let v: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
    assert_eq!(v["neutral"], serde_json::json!("0-9"), "{}", r.stdout);
    assert_eq!(v["neutral_frames"], serde_json::json!([5]), "{}", r.stdout);
    std::fs::remove_file(&out).unwrap();
    for (arg, needle) in [
        ("9-0", "--neutral 9-0: frame 9 comes after frame 0"),
        (
            "a-9",
            "'a-9' is neither auto, least-active, a frame number nor a stretch",
        ),
        ("0-99999", "99999"),
    ] {
        let r = kslab(&["rig", "--neutral", arg, "--out", &o]);
        assert_eq!(r.code, 1, "{arg}: {}", r.stderr);
        assert!(r.stderr.contains(needle), "{arg}: {}", r.stderr);
        assert!(!out.exists(), "{arg} wrote its output");
    }
}

/// `--seeds`: each summary measure as a distribution over the seeds; the median and the
/// worst are those of the per-seed summaries it lists, --out holds every seed's rows.
#[test]
fn seeds_give_distributions_of_the_per_seed_summaries() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("per_shape.csv");
    let r = kslab(&[
        "rig-accuracy",
        "--kind",
        "winks",
        "--frames",
        "60",
        "--seeds",
        "1..3",
        "--json",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let v: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
    let k = &v[0];
    assert_eq!(k["kind"], "winks");
    let mut means: Vec<f64> = k["per_seed"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["summary"]["mean_r"].as_f64().unwrap())
        .collect();
    assert_eq!(means.len(), 3);
    means.sort_by(f64::total_cmp);
    assert_eq!(k["mean_r"]["median"].as_f64().unwrap(), means[1]);
    assert_eq!(k["mean_r"]["worst"].as_f64().unwrap(), means[0]);
    let rmse: Vec<f64> = k["per_seed"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["summary"]["rmse"].as_f64().unwrap())
        .collect();
    assert_eq!(
        k["rmse"]["worst"].as_f64().unwrap(),
        rmse.iter().copied().fold(0.0, f64::max)
    );
    let text = std::fs::read_to_string(&out).unwrap();
    for seed in 1..=3 {
        let rows = text
            .lines()
            .filter(|l| l.ends_with(&format!(",{seed}")))
            .count();
        assert_eq!(rows, ict().k(), "seed {seed}'s rows");
    }
    let plain = kslab(&[
        "rig-accuracy",
        "--kind",
        "winks",
        "--frames",
        "60",
        "--seeds",
        "1..3",
    ]);
    assert!(
        plain.stdout.starts_with("winks   3 seeds · mean r median "),
        "{}",
        plain.stdout
    );
    for (args, code, needle) in [
        (vec!["--seeds", "5..2"], 1, "--seeds '5..2'"),
        (vec!["--seeds", "1..2000"], 1, "at most 1000 seeds"),
        (vec!["--seeds", "1-3"], 1, "FIRST..LAST"),
        (
            vec!["--seeds", "1..3", "--seed", "4"],
            2,
            "cannot be used with",
        ),
    ] {
        let mut all = vec!["rig-accuracy", "--kind", "winks", "--frames", "30"];
        all.extend(args);
        let r = kslab(&all);
        assert_eq!(r.code, code, "{all:?}: {}", r.stderr);
        assert!(r.stderr.contains(needle), "{all:?}: {}", r.stderr);
    }
}

/// `--live` measures the live path: the same weights `kslab rig --live` gives the rendered
/// track (calibrated on its lead-in), each scored against the truth it was rendered from.
#[test]
fn live_accuracy_is_the_causal_solves_score_against_the_truth() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("per_shape.csv");
    let r = kslab(&[
        "rig-accuracy",
        "--kind",
        "smooth",
        "--frames",
        "120",
        "--seed",
        "3",
        "--live",
        "--tracks",
        d.path().to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let w = d.path().join("w.csv");
    let rig = kslab(&[
        "rig",
        d.path().join("smooth_track.csv").to_str().unwrap(),
        "--live",
        "--neutral",
        "0-19",
        "--out",
        w.to_str().unwrap(),
    ]);
    assert_eq!(rig.code, 0, "{}", rig.stderr);
    let read = |p: &std::path::Path| -> Vec<Vec<f64>> {
        std::fs::read_to_string(p)
            .unwrap()
            .lines()
            .skip(1)
            .map(|l| l.split(',').skip(1).map(|v| v.parse().unwrap()).collect())
            .collect()
    };
    let (truth, got) = (read(&d.path().join("smooth_truth.csv")), read(&w));
    let jaw = ict().names.iter().position(|n| n == "jawOpen").unwrap();
    let col = |m: &[Vec<f64>]| m.iter().map(|row| row[jaw]).collect::<Vec<f64>>();
    let (t, g) = (col(&truth), col(&got));
    let n = t.len() as f64;
    let (mt, mg) = (t.iter().sum::<f64>() / n, g.iter().sum::<f64>() / n);
    let cov: f64 = t.iter().zip(&g).map(|(a, b)| (a - mt) * (b - mg)).sum();
    let r_jaw = cov
        / (t.iter().map(|a| (a - mt).powi(2)).sum::<f64>()
            * g.iter().map(|b| (b - mg).powi(2)).sum::<f64>())
        .sqrt();
    let text = std::fs::read_to_string(&out).unwrap();
    let row = text
        .lines()
        .find(|l| l.starts_with("smooth,jawOpen,"))
        .unwrap();
    let reported: f64 = row.split(',').nth(3).unwrap().parse().unwrap();
    assert!(
        (reported - r_jaw).abs() < 1e-9,
        "{reported} against {r_jaw}"
    );
    assert!(r_jaw > 0.95, "{r_jaw}");
    for (args, needle) in [
        (vec!["--live", "--zero-phase", "1"], "--live is causal"),
        (
            vec!["--live", "--neutral", "auto"],
            "calibrates on the lead-in",
        ),
        (vec!["--live", "--lead-in", "0"], "needs a lead-in"),
        (
            vec!["--live", "--smooth", "10", "--smooth-mode", "offline"],
            "--live is causal",
        ),
    ] {
        let mut all = vec!["rig-accuracy", "--kind", "winks", "--frames", "30"];
        all.extend(args);
        let r = kslab(&all);
        assert_eq!(r.code, 1, "{all:?}: {}", r.stderr);
        assert!(r.stderr.contains(needle), "{all:?}: {}", r.stderr);
    }
}
