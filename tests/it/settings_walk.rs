//! Every setting of every subcommand walked with the values a fuzzer tries first — 0, −1,
//! NaN, 1e300 and 2⁶¹ — on a command line that is otherwise valid, so the value is what the
//! command meets. Each run ends (within two minutes) with exit 0, a refusal (1) or a usage
//! error (2), never a panic or a hang. Round three found `smooth --clean-sigma 1e300`
//! (capacity overflow) and `[rig] noise_px = [1e154]` (minutes); the options are read from
//! `--help`, so a new option is walked without a change here.

use crate::common::shared;
use std::path::Path;
use std::process::Command;

const VALUES: [&str; 5] = ["0", "-1", "NaN", "1e300", "2305843009213693952"];

/// Options of `kslab SUB --help` that take a value.
fn options(sub: &str) -> Vec<String> {
    let out = Command::new(env!("CARGO_BIN_EXE_kslab"))
        .args(sub.split(' '))
        .arg("--help")
        .output()
        .unwrap();
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| {
            let l = l.trim_start();
            let l = l.strip_prefix("-q, ").unwrap_or(l);
            let (flag, rest) = l.split_once(' ')?;
            (flag.starts_with("--") && rest.trim_start().starts_with('<')).then(|| flag.to_string())
        })
        .collect()
}

/// `base` with `--flag=value` replacing the flag (and its value) if `base` has it.
fn with(base: &[String], flag: &str, value: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut skip = false;
    for a in base {
        if skip {
            skip = false;
            continue;
        }
        if a == flag {
            skip = true;
            continue;
        }
        out.push(a.clone());
    }
    out.push(format!("{flag}={value}"));
    out
}

fn run_bounded(args: &[String], dir: &Path) -> (Option<i32>, String) {
    let out = Command::new("timeout")
        .arg("120")
        .arg(env!("CARGO_BIN_EXE_kslab"))
        .args(args)
        .arg("-q")
        .current_dir(dir)
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn every_setting_of_every_subcommand_refuses_or_takes_zero_minus_one_nan_1e300_and_2_61() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    let o = |f: &str| dir.join(f).display().to_string();
    let d6 = shared("mediapipe_face_tracks/liveportrait_d6.csv")
        .display()
        .to_string();
    let actions = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets/actions/actions_liveportrait_d6.json")
        .display()
        .to_string();
    let ict = shared("ict_facekit_face").display().to_string();
    let v = |x: &[&str]| x.iter().map(|s| s.to_string()).collect::<Vec<String>>();
    let subs: Vec<(&str, Vec<String>)> = vec![
        ("info", v(&[])),
        ("keys", v(&["--method", "spread", "--k", "3"])),
        ("solve", v(&["--keys", "3,50", "--out", &o("w.csv")])),
        (
            "curves",
            v(&["--methods", "spread", "--k", "2..3", "--out", &o("c.csv")]),
        ),
        (
            "template",
            v(&["--method", "spread", "--k", "3", "--out", &o("t.svg")]),
        ),
        (
            "retarget",
            v(&["--method", "spread", "--k", "3", "--out", &o("r.csv")]),
        ),
        ("rig", v(&["--out", &o("rig.csv")])),
        (
            "live",
            v(&[
                "--from",
                &format!("file:{d6}"),
                "--rate",
                "5000",
                "--landmarks",
                "68",
                "--to",
                "stdout",
            ]),
        ),
        ("rig-accuracy", v(&["--frames", "40", "--lead-in", "5"])),
        (
            "transfer",
            v(&[
                "--mesh",
                &format!("{ict}/neutral_face.obj"),
                "--every",
                "100",
                "--obj-dir",
                &o("objs"),
            ]),
        ),
        ("actions", v(&["--out", &o("a.json")])),
        ("modes", v(&[&d6, "--actions", &actions])),
        (
            "map",
            v(&[&d6, "--actions", &actions, "--out", &o("m.csv")]),
        ),
        ("intensity", v(&[])),
        ("smooth", v(&["--k", "3", "--out", &o("sm")])),
        // The benchmarks too (`bench nnls --frames 2⁶¹` overflowed a capacity, `bench
        // scale --frames` had no bound), on sizes that run in a second.
        (
            "bench nnls",
            v(&["--frames", "200", "--baseline-frames", "20", "--k", "4"]),
        ),
        ("bench rig", v(&["--frames", "20", "--repeats", "1"])),
        ("bench transfer", v(&["--frames", "5"])),
        ("bench smooth", v(&["--frames", "300", "--k", "4"])),
        (
            "bench scale",
            v(&["--frames", "300", "--steps", "info", "--dir", &o("scale")]),
        ),
        ("bench curves", v(&["--kmax", "3"])),
        ("bench kmeans", v(&["--kmax", "3", "--seeds", "1,2"])),
        ("bench live", v(&["--seconds", "0.5", "--fps", "30"])),
    ];
    // Two workers (CI has two cores), each a share of the subcommands.
    let walk = |share: usize| {
        let mut failures = Vec::new();
        let mut runs = 0;
        for (sub, base) in subs.iter().skip(share).step_by(2) {
            let opts = options(sub);
            assert!(!opts.is_empty(), "{sub}: no options read from --help");
            for flag in &opts {
                for value in VALUES {
                    let mut args: Vec<String> = sub.split(' ').map(String::from).collect();
                    args.extend(with(base, flag, value));
                    runs += 1;
                    let (code, err) = run_bounded(&args, dir);
                    match code {
                        Some(0..=2) if !err.contains("panicked") => {}
                        Some(124) => failures.push(format!("{args:?}: still running after 120 s")),
                        c => failures.push(format!("{args:?}: exit {c:?}: {}", err.trim())),
                    }
                }
            }
        }
        (runs, failures)
    };
    let (a, b) = std::thread::scope(|s| {
        let a = s.spawn(|| walk(0));
        let b = s.spawn(|| walk(1));
        (a.join().unwrap(), b.join().unwrap())
    });
    let runs = a.0 + b.0;
    let failures: Vec<String> = a.1.into_iter().chain(b.1).collect();
    assert!(runs > 400, "{runs} runs");
    assert!(
        failures.is_empty(),
        "{} of {runs} runs:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// The same values in every numeric key of every table of an experiment file, on a spec
/// that otherwise runs: `[retarget] strip = 2⁶¹` overflowed a capacity, `[smooth]
/// clean_sigma = 1e300` a kernel, `[rig] noise_px = [1e154]` ran for minutes. Each run
/// ends within two minutes with exit 0 or 1 and no panic.
#[test]
fn every_numeric_key_of_every_experiment_table_refuses_or_takes_the_same_values() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let data = |rel: &str| shared(rel).display().to_string();
    let asset = |rel: &str| root.join("assets").join(rel).display().to_string();
    let d6 = data("mediapipe_face_tracks/liveportrait_d6.csv");
    let one = format!("title = \"w\"\ninput = \"{d6}\"\npoints = \"lips\"\n");
    // (the spec before the key, the key, whether it takes a list)
    let tables: Vec<(String, &str, bool)> = vec![
        (format!("{one}methods = [\"kmeans2\"]\nk = \"2..3\"\n"), "seed", false),
        (format!("{one}methods = [\"greedy\"]\nk = \"2..3\"\n"), "shortlist", false),
        (format!("{one}methods = [\"spread\"]\nk = \"2..3\"\n"), "dims", false),
        (format!("title = \"w\"\ninputs = [\"{d6}\"]\npoints = \"lips\"\nmethods = [\"spread\"]\nk = \"2..3\"\n"), "bootstrap", false),
        (format!("{one}[retarget]\nmethod = \"spread\"\nsolvers = [\"nnls\"]\n"), "k", false),
        (format!("{one}[retarget]\nmethod = \"spread\"\nk = 3\nsolvers = [\"nnls\"]\n"), "strip", false),
        (format!("{one}[retarget]\nmethod = \"spread\"\nk = 3\nsolvers = [\"nnls\"]\n"), "trace_noise", true),
        (format!("title = \"w\"\ninput = \"{d6}\"\n[modes]\nactions = \"{}\"\n", asset("cosker/actions_liveportrait_d6.json")), "modes", false),
        (format!("title = \"w\"\ninput = \"{d6}\"\n[modes]\nactions = \"{}\"\n", asset("cosker/actions_liveportrait_d6.json")), "blend_radius", false),
        (format!("title = \"w\"\ninput = \"{d6}\"\n[map]\nactions = \"{}\"\n", asset("cosker/actions_liveportrait_d6.json")), "modes", false),
        (format!("title = \"w\"\ninput = \"{d6}\"\n[map]\nactions = \"{}\"\n", asset("cosker/actions_liveportrait_d6.json")), "blend_radius", false),
        (format!("title = \"w\"\ninput = \"{}\"\n[intensity]\nevaluation = \"split\"\ntrain_clips = [1, 14]\n", data("pyfeat_samples/news_sample_compact.csv")), "k", false),
        (format!("title = \"w\"\ninput = \"{}\"\n[intensity]\nevaluation = \"split\"\ntrain_clips = [1, 14]\n", data("pyfeat_samples/news_sample_compact.csv")), "degree", false),
        (format!("title = \"w\"\ninput = \"{}\"\n[intensity]\nevaluation = \"split\"\ntrain_clips = [1, 14]\n", data("pyfeat_samples/news_sample_compact.csv")), "threshold", false),
        (format!("title = \"w\"\ninput = \"{}\"\n[intensity]\nevaluation = \"split\"\ntrain_clips = [1, 14]\ncentring = \"neutral\"\n", data("pyfeat_samples/news_sample_compact.csv")), "neutral_frames", false),
        (format!("{one}[smooth]\nmethod = \"spread\"\n"), "k", false),
        (format!("{one}[smooth]\nmethod = \"spread\"\nk = 3\n"), "lambdas", true),
        (format!("{one}[smooth]\nmethod = \"spread\"\nk = 3\n"), "clean_sigma", false),
        (format!("{one}[smooth]\nmethod = \"spread\"\nk = 3\n"), "windows", true),
        (format!("{one}[smooth]\nmethod = \"spread\"\nk = 3\n"), "alphas", true),
        (format!("{one}[smooth]\nmethod = \"spread\"\nk = 3\n"), "one_euro_cutoffs", true),
        (format!("{one}[smooth]\nmethod = \"spread\"\nk = 3\n"), "one_euro_betas", true),
        ("title = \"w\"\ninput = \"builtin\"\n[rig]\nframes = 40\n".to_string(), "noise_px", true),
        ("title = \"w\"\ninput = \"builtin\"\n[rig]\nframes = 40\n".to_string(), "smooth", true),
        ("title = \"w\"\ninput = \"builtin\"\n[rig]\nframes = 40\n".to_string(), "seed", false),
        ("title = \"w\"\ninput = \"builtin\"\n[rig]\n".to_string(), "frames", false),
    ];
    let toml_values = ["0", "-1", "nan", "1e300", "2305843009213693952"];
    let walk = |share: usize| {
        let mut failures = Vec::new();
        let mut runs = 0;
        for (i, (base, key, list)) in tables.iter().enumerate().skip(share).step_by(2) {
            for (j, v) in toml_values.iter().enumerate() {
                let value = if *list {
                    format!("[{v}]")
                } else {
                    v.to_string()
                };
                let spec = dir.join(format!("s{i}_{j}.toml"));
                std::fs::write(&spec, format!("{base}{key} = {value}\n")).unwrap();
                let out = dir.join(format!("o{i}_{j}"));
                let args = vec![
                    "run".to_string(),
                    spec.display().to_string(),
                    "--out".to_string(),
                    out.display().to_string(),
                ];
                runs += 1;
                let (code, err) = run_bounded(&args, dir);
                match code {
                    Some(0 | 1) if !err.contains("panicked") => {}
                    Some(124) => failures.push(format!(
                        "{key} = {value}: still running after 120 s\n{base}"
                    )),
                    c => failures.push(format!(
                        "{key} = {value}: exit {c:?}: {}\n{base}",
                        err.trim()
                    )),
                }
            }
        }
        (runs, failures)
    };
    let (a, b) = std::thread::scope(|s| {
        let a = s.spawn(|| walk(0));
        let b = s.spawn(|| walk(1));
        (a.join().unwrap(), b.join().unwrap())
    });
    let runs = a.0 + b.0;
    let failures: Vec<String> = a.1.into_iter().chain(b.1).collect();
    assert_eq!(runs, tables.len() * toml_values.len());
    assert!(
        failures.is_empty(),
        "{} of {runs} runs:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
