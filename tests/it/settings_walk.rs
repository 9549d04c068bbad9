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
        .args([sub, "--help"])
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
        .join("assets/cosker/actions_liveportrait_d6.json")
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
                    let mut args = vec![sub.to_string()];
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
