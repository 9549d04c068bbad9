//! Corpus studies: many sequences in one experiment, aggregated; shards and
//! their merge give exactly the unsharded report; the scheduler set-ups (Slurm for real,
//! the Kubernetes manifest against its schemas).
//! Here: what runs the `kslab` binary; the library's own tests are in `crates/keyshape-experiments/tests/corpus.rs`.

use crate::common::{kslab, shared};
use keyshape_experiments::experiment::corpus::Shard;
use keyshape_experiments::experiment::Spec;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// A small corpus over the four real MediaPipe tracks (lips; three methods, the hull
/// among them; both solvers; a [retarget] study), written into `dir`.
fn small_corpus(dir: &Path, seed: u64) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let spec = dir.join("corpus.toml");
    let glob = shared("mediapipe_face_tracks").join("*.csv");
    std::fs::write(
        &spec,
        format!(
            r#"title = "corpus test"
inputs = ["{}"]
points = "lips"
methods = ["spread", "kmeans2", "hull"]
k = "2..6"
solvers = ["nnls", "ls"]
seed = {seed}
bootstrap = 500

[retarget]
method = "spread"
k = 10
solvers = ["ls", "nnls"]
trace_noise = [0.0, 0.01]
strip = 0
"#,
            glob.display()
        ),
    )
    .unwrap();
    spec
}

/// A scratch directory, removed when the returned guard drops (also when the test fails).
fn tmp(name: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::Builder::new()
        .prefix(&format!("kslab-corpus-{name}-"))
        .tempdir()
        .unwrap();
    let d = dir.path().to_path_buf();
    (dir, d)
}

fn run_ok(args: &[&str]) {
    let r = kslab(args);
    assert_eq!(r.code, 0, "kslab {args:?}: {}", r.stderr);
}

/// The report.json without its timings.
fn json_without_timings(p: &Path) -> serde_json::Value {
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap();
    v.as_object_mut()
        .unwrap()
        .remove("timings")
        .expect("report.json has timings");
    v
}

/// Every file of `a` is in `b`, byte for byte (CSV and PNG), report.json equal but for its
/// timings; and `b` has no other file.
fn assert_same_report(a: &Path, b: &Path) {
    let names = |d: &Path| {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    };
    assert_eq!(
        names(a),
        names(b),
        "{} against {}",
        a.display(),
        b.display()
    );
    for f in names(a) {
        if f == "report.json" {
            assert_eq!(
                json_without_timings(&a.join(&f)),
                json_without_timings(&b.join(&f))
            );
        } else {
            assert!(
                std::fs::read(a.join(&f)).unwrap() == std::fs::read(b.join(&f)).unwrap(),
                "{f} differs between {} and {}",
                a.display(),
                b.display()
            );
        }
    }
}

#[test]
fn shards_merged_in_any_order_give_exactly_the_unsharded_report() {
    let (_scratch, d) = tmp("merge");
    let spec = small_corpus(&d, 7);
    let s = spec.to_str().unwrap();
    let full = d.join("full");
    run_ok(&["run", s, "--out", full.to_str().unwrap()]);
    for f in [
        "corpus_sequences.csv",
        "corpus_curves.csv",
        "corpus_summary.csv",
        "corpus_paired.csv",
        "corpus_wins.csv",
        "corpus_own_k.csv",
        "corpus_retarget.csv",
        "corpus_retarget_paired.csv",
        "corpus_nnls.png",
        "corpus_ls.png",
        "corpus_retarget.png",
        "report.json",
    ] {
        assert!(full.join(f).exists(), "{f} missing");
    }
    // Three shards of four sequences: one shard has two, two have one.
    let shard_dirs: Vec<PathBuf> = (0..3).map(|i| d.join(format!("s{i}"))).collect();
    for (i, sd) in shard_dirs.iter().enumerate() {
        run_ok(&[
            "run",
            s,
            "--shard",
            &format!("{i}/3"),
            "--out",
            sd.to_str().unwrap(),
        ]);
        assert!(sd.join("partial.json").exists());
    }
    let orders = [
        [0, 1, 2],
        [2, 1, 0],
        [1, 0, 2],
        [1, 2, 0],
        [0, 2, 1],
        [2, 0, 1],
    ];
    for (j, o) in orders.iter().enumerate() {
        let out = d.join(format!("merged{j}"));
        let mut args = vec!["merge".to_string()];
        args.extend(o.iter().map(|&i| shard_dirs[i].display().to_string()));
        args.extend(["--out".into(), out.display().to_string()]);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        run_ok(&args);
        assert_same_report(&full, &out);
    }
    // More shards than sequences: the empty shards merge as well.
    let many: Vec<PathBuf> = (0..6).map(|i| d.join(format!("m{i}"))).collect();
    for (i, sd) in many.iter().enumerate() {
        run_ok(&[
            "run",
            s,
            "--shard",
            &format!("{i}/6"),
            "--out",
            sd.to_str().unwrap(),
        ]);
    }
    let out = d.join("merged_many");
    let mut args = vec!["merge".to_string()];
    args.extend(many.iter().map(|p| p.display().to_string()));
    args.extend(["--out".into(), out.display().to_string()]);
    run_ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert_same_report(&full, &out);
}

#[test]
fn merge_refuses_a_missing_or_repeated_shard_and_shards_of_other_experiments() {
    let (_scratch, d) = tmp("refuse");
    let spec = small_corpus(&d, 7);
    let other = small_corpus(&d.join("other"), 8);
    let p = |x: &Path| x.display().to_string();
    for i in 0..3 {
        run_ok(&[
            "run",
            &p(&spec),
            "--shard",
            &format!("{i}/3"),
            "--out",
            &p(&d.join(format!("s{i}"))),
        ]);
    }
    run_ok(&[
        "run",
        &p(&other),
        "--shard",
        "1/3",
        "--out",
        &p(&d.join("o1")),
    ]);
    run_ok(&[
        "run",
        &p(&spec),
        "--shard",
        "1/2",
        "--out",
        &p(&d.join("h1")),
    ]);
    let s = |i: usize| p(&d.join(format!("s{i}")));
    let out = p(&d.join("out"));
    let cases: Vec<(Vec<String>, &str)> = vec![
        (vec![s(0), s(2)], "shard 1/3 of"),
        (vec![s(0), s(1), s(2), s(1)], "shard 1/3 is given twice"),
        (vec![s(0), p(&d.join("o1")), s(2)], "different experiments"),
        (vec![s(0), p(&d.join("h1")), s(2)], "different splits"),
        (vec![s(0), p(&d.join("nothing")), s(2)], "no partial.json"),
    ];
    for (dirs, want) in cases {
        let mut args = vec!["merge".to_string()];
        args.extend(dirs);
        args.extend(["--out".to_string(), out.clone()]);
        let r = kslab(&args.iter().map(String::as_str).collect::<Vec<_>>());
        assert_eq!(r.code, 1, "{args:?}");
        assert!(r.stderr.contains(want), "{args:?}: {}", r.stderr);
        assert!(!Path::new(&out).exists(), "a refused merge wrote {out}");
    }
    // A partial edited to a shard outside its split is refused, not indexed.
    let text = std::fs::read_to_string(d.join("s2/partial.json")).unwrap();
    let bad = text.replacen("\"index\": 2", "\"index\": 7", 1);
    assert_ne!(bad, text);
    std::fs::write(d.join("s2/partial.json"), bad).unwrap();
    let r = kslab(&["merge", &s(0), &s(1), &s(2), "--out", &out]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.contains("shard 7/3 is not a part of a split"),
        "{}",
        r.stderr
    );
    // A damaged partial names its file and position.
    std::fs::write(d.join("s2/partial.json"), "{\"format\": 1, \"kslab\": ").unwrap();
    let r = kslab(&["merge", &s(0), &s(1), &s(2), "--out", &out]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("s2/partial.json:1:"), "{}", r.stderr);
}

#[test]
fn the_aggregates_match_a_brute_force_count_over_the_per_sequence_curves() {
    let (_scratch, d) = tmp("oracle");
    let spec = small_corpus(&d, 7);
    let full = d.join("full");
    run_ok(&[
        "run",
        spec.to_str().unwrap(),
        "--out",
        full.to_str().unwrap(),
    ]);
    let read = |f: &str| {
        let text = std::fs::read_to_string(full.join(f)).unwrap();
        let mut lines = text.lines();
        let head: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
        lines
            .map(|l| {
                head.iter()
                    .cloned()
                    .zip(l.split(',').map(String::from))
                    .collect::<HashMap<String, String>>()
            })
            .collect::<Vec<_>>()
    };
    let seqs = read("corpus_sequences.csv");
    assert_eq!(seqs.len(), 4);
    let iod: HashMap<String, f64> = seqs
        .iter()
        .map(|r| (r["sequence"].clone(), r["iod"].parse().unwrap()))
        .collect();
    let curves = read("corpus_curves.csv");
    // rms_iod is rms / iod of its sequence.
    for c in &curves {
        let (rms, ri): (f64, f64) = (c["rms"].parse().unwrap(), c["rms_iod"].parse().unwrap());
        assert!((rms / iod[&c["sequence"]] - ri).abs() <= 1e-15 * ri.abs().max(1.0));
    }
    let summary = read("corpus_summary.csv");
    // The hull picks its own k: it is not on the k rows, but in corpus_own_k.csv.
    assert!(summary.iter().all(|r| r["method"] != "hull"));
    assert_eq!(summary.len(), 2 * 2 * 5);
    for r in &summary {
        let at = |m: &str, seq: &str| -> f64 {
            curves
                .iter()
                .find(|c| {
                    c["method"] == m
                        && c["solver"] == r["solver"]
                        && c["k"] == r["k"]
                        && c["sequence"] == seq
                })
                .unwrap()["rms_iod"]
                .parse()
                .unwrap()
        };
        let vals: Vec<f64> = seqs
            .iter()
            .map(|s| at(&r["method"], &s["sequence"]))
            .collect();
        let mean: f64 = r["mean_rms_iod"].parse().unwrap();
        assert!((mean - vals.iter().sum::<f64>() / 4.0).abs() < 1e-15);
        let (lo, hi): (f64, f64) = (r["lo95"].parse().unwrap(), r["hi95"].parse().unwrap());
        let (min, max) = vals
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(*v), b.max(*v))
            });
        assert!(min <= lo && lo <= mean && mean <= hi && hi <= max, "{r:?}");
        // Wins: sequences where this method is the lowest of spread and kmeans2.
        let wins = seqs
            .iter()
            .filter(|s| {
                let mine = at(&r["method"], &s["sequence"]);
                ["spread", "kmeans2"]
                    .iter()
                    .all(|m| at(m, &s["sequence"]) >= mine)
            })
            .count();
        assert_eq!(r["wins"], wins.to_string(), "{r:?}");
    }
    // Paired: spread − kmeans2 per sequence, averaged.
    for r in read("corpus_paired.csv") {
        let diff = |seq: &str| {
            let at = |m: &str| -> f64 {
                curves
                    .iter()
                    .find(|c| {
                        c["method"] == m
                            && c["solver"] == r["solver"]
                            && c["k"] == r["k"]
                            && c["sequence"] == seq
                    })
                    .unwrap()["rms_iod"]
                    .parse()
                    .unwrap()
            };
            at(&r["method_a"]) - at(&r["method_b"])
        };
        let d: Vec<f64> = seqs.iter().map(|s| diff(&s["sequence"])).collect();
        let mean: f64 = r["mean_diff_iod"].parse().unwrap();
        assert!((mean - d.iter().sum::<f64>() / 4.0).abs() < 1e-15);
        assert_eq!(
            r["a_lower"],
            d.iter().filter(|x| **x < 0.0).count().to_string()
        );
    }
    // The retarget difference per sequence is ls − nnls of corpus_retarget.csv.
    let rt = read("corpus_retarget.csv");
    for r in read("corpus_retarget_paired.csv") {
        let d: Vec<f64> = seqs
            .iter()
            .map(|s| {
                let get = |solver: &str| -> f64 {
                    rt.iter()
                        .find(|x| {
                            x["sequence"] == s["sequence"]
                                && x["solver"] == solver
                                && x["trace_noise"] == r["trace_noise"]
                        })
                        .unwrap()["target_rms_iod"]
                        .parse()
                        .unwrap()
                };
                get("ls") - get("nnls")
            })
            .collect();
        let mean: f64 = r["mean_target_diff_iod"].parse().unwrap();
        assert!((mean - d.iter().sum::<f64>() / 4.0).abs() < 1e-12, "{r:?}");
    }
    // The lips' hull has about 15 vertices here, beyond k = 6: no method to compare at its k.
    let own = read("corpus_own_k.csv");
    assert_eq!(own.len(), 2, "{own:?}");
    for r in &own {
        assert_eq!(r["method"], "hull");
        assert!(r["mean_k"].parse::<f64>().unwrap() > 6.0, "{r:?}");
        assert_eq!(r["compared_with"], "");
    }
}

#[test]
fn shard_options_are_checked_and_read_from_the_schedulers() {
    assert_eq!(Shard::parse("2/5").unwrap(), Shard { index: 2, count: 5 });
    for bad in ["5/5", "0/0", "1", "a/3", "-1/3"] {
        assert!(Shard::parse(bad).is_err(), "{bad}");
    }
    let env = |pairs: &'static [(&'static str, &'static str)]| {
        move |k: &str| pairs.iter().find(|p| p.0 == k).map(|p| p.1.to_string())
    };
    // Slurm: a 1-based array 1-4 is shards 0..3 of 4.
    let s = Shard::from_env(&env(&[
        ("SLURM_ARRAY_TASK_ID", "3"),
        ("SLURM_ARRAY_TASK_MIN", "1"),
        ("SLURM_ARRAY_TASK_MAX", "4"),
        ("SLURM_ARRAY_TASK_COUNT", "4"),
    ]))
    .unwrap();
    assert_eq!(s, Shard { index: 2, count: 4 });
    // An array with a step (0-6:2, four tasks) would leave parts unrun: refused.
    let e = Shard::from_env(&env(&[
        ("SLURM_ARRAY_TASK_ID", "2"),
        ("SLURM_ARRAY_TASK_MIN", "0"),
        ("SLURM_ARRAY_TASK_MAX", "6"),
        ("SLURM_ARRAY_TASK_COUNT", "4"),
    ]))
    .unwrap_err();
    assert!(e.to_string().contains("gaps or a step"), "{e}");
    // A step without a maximum, and a task id outside the array, picked a
    // wrong shard.
    let e = Shard::from_env(&env(&[
        ("SLURM_ARRAY_TASK_ID", "2"),
        ("SLURM_ARRAY_TASK_MIN", "0"),
        ("SLURM_ARRAY_TASK_STEP", "2"),
        ("SLURM_ARRAY_TASK_COUNT", "4"),
    ]))
    .unwrap_err();
    assert!(e.to_string().contains("gaps or a step"), "{e}");
    let e = Shard::from_env(&env(&[
        ("SLURM_ARRAY_TASK_ID", "0"),
        ("SLURM_ARRAY_TASK_MIN", "1"),
        ("SLURM_ARRAY_TASK_COUNT", "4"),
    ]))
    .unwrap_err();
    assert!(
        e.to_string()
            .contains("SLURM_ARRAY_TASK_ID 0 lies outside the array (1-?)"),
        "{e}"
    );
    let s = Shard::from_env(&env(&[
        ("SLURM_ARRAY_TASK_ID", "4"),
        ("SLURM_ARRAY_TASK_MIN", "1"),
        ("SLURM_ARRAY_TASK_STEP", "1"),
        ("SLURM_ARRAY_TASK_COUNT", "4"),
    ]))
    .unwrap();
    assert_eq!(s, Shard { index: 3, count: 4 });
    let s = Shard::from_env(&env(&[
        ("JOB_COMPLETION_INDEX", "1"),
        ("KSLAB_SHARD_COUNT", "3"),
    ]))
    .unwrap();
    assert_eq!(s, Shard { index: 1, count: 3 });
    assert!(Shard::from_env(&env(&[("JOB_COMPLETION_INDEX", "1")]))
        .unwrap_err()
        .to_string()
        .contains("KSLAB_SHARD_COUNT"));
    assert!(Shard::from_env(&env(&[
        ("JOB_COMPLETION_INDEX", "3"),
        ("KSLAB_SHARD_COUNT", "3")
    ]))
    .is_err());
    assert!(
        crate::common::as_cli(&Shard::from_env(&env(&[])).unwrap_err())
            .contains("give --shard i/n")
    );

    // Through the binary: --shard on one input, and --shard auto without a scheduler.
    let (_scratch, d) = tmp("shardcli");
    let one = d.join("one.toml");
    std::fs::write(
        &one,
        "title = \"t\"\ninput = \"builtin\"\nmethods = [\"spread\"]\nk = 2\n",
    )
    .unwrap();
    let r = kslab(&[
        "run",
        one.to_str().unwrap(),
        "--shard",
        "0/2",
        "--out",
        d.join("o").to_str().unwrap(),
    ]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("has one `input`"), "{}", r.stderr);
    let spec = small_corpus(&d, 7);
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_kslab"))
        .args([
            "run",
            spec.to_str().unwrap(),
            "--shard",
            "--out",
            d.join("o").to_str().unwrap(),
        ])
        .env_remove("SLURM_ARRAY_TASK_ID")
        .env_remove("JOB_COMPLETION_INDEX")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no scheduler variables"));
    assert!(!d.join("o").exists());
}

/// Needs a running Slurm: `bash deploy/slurm/local_cluster.sh` (root; `.ci/run` does it and
/// runs the ignored tests).
#[test]
#[ignore = "needs Slurm: bash deploy/slurm/local_cluster.sh, then cargo test --release -- --ignored corpus::"]
fn a_study_run_as_a_real_slurm_array_merges_into_the_unsharded_report() {
    let status = std::process::Command::new("sinfo").arg("-h").output();
    assert!(
        status.as_ref().is_ok_and(|o| o.status.success()),
        "Slurm is not up: run `bash deploy/slurm/local_cluster.sh`"
    );
    let (_scratch, d) = tmp("slurm");
    let spec = small_corpus(&d, 7);
    let full = d.join("full");
    run_ok(&[
        "run",
        spec.to_str().unwrap(),
        "--out",
        full.to_str().unwrap(),
    ]);
    let study = d.join("study");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("deploy/slurm/run_study.sh");
    let out = std::process::Command::new("bash")
        .arg(&script)
        .arg(&spec)
        .arg("3")
        .arg(&study)
        .env("KSLAB", env!("CARGO_BIN_EXE_kslab"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{} {}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    // Each array task ran its own shard.
    for i in 0..3 {
        let p: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(study.join(format!("shard-{i}/partial.json"))).unwrap(),
        )
        .unwrap();
        assert_eq!(p["shard"]["index"], i);
        assert_eq!(p["shard"]["count"], 3);
    }
    assert_same_report(&full, &study.join("merged"));
}

/// Needs `kubernetes-validate` (PyPI; `.ci/run` installs it and runs the ignored tests).
#[test]
#[ignore = "needs kubernetes-validate (pip install kubernetes-validate), then cargo test --release -- --ignored corpus::"]
fn the_kubernetes_manifests_validate_and_run_an_indexed_job_reading_its_shard() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("deploy/k8s");
    let files = [dir.join("corpus-study.yaml"), dir.join("corpus-merge.yaml")];
    let out = std::process::Command::new("kubernetes-validate")
        .arg("--strict")
        .args(&files)
        .output()
        .expect("kubernetes-validate is not installed: pip install kubernetes-validate");
    assert!(
        out.status.success(),
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    // The study is an Indexed Job whose pods run `kslab run … --shard auto` with the
    // shard count equal to its completions, each writing its own folder.
    let check = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/check_k8s_job.py");
    let out = std::process::Command::new("python3")
        .arg(&check)
        .arg(&files[0])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    // And the experiment it names exists and is a corpus.
    let text = std::fs::read_to_string(&files[0]).unwrap();
    let exp = text
        .lines()
        .find_map(|l| l.trim().strip_prefix("- \"experiments/"))
        .map(|r| format!("experiments/{}", r.trim_end_matches('"')))
        .unwrap();
    let (spec, _) = Spec::from_path(&Path::new(env!("CARGO_MANIFEST_DIR")).join(&exp)).unwrap();
    assert!(spec.inputs.is_some(), "{exp} is not a corpus");
}

/// A partial report is validated as an input: a damaged value, an
/// impossible count or a repeated curve point is refused by name, nothing is written.
#[test]
fn merge_refuses_a_partial_with_values_no_run_gives() {
    let (_scratch, d) = tmp("values");
    let spec = d.join("c.toml");
    std::fs::write(
        &spec,
        format!(
            "title = \"t\"\ninputs = [\"{}\"]\npoints = \"lips\"\nmethods = [\"spread\"]\nk = \"2..3\"\nbootstrap = 50\n",
            shared("mediapipe_face_tracks/liveportrait_d6.csv").display()
        ),
    )
    .unwrap();
    let p = |x: &Path| x.display().to_string();
    run_ok(&[
        "run",
        &p(&spec),
        "--shard",
        "0/1",
        "--out",
        &p(&d.join("s0")),
    ]);
    let good = std::fs::read_to_string(d.join("s0/partial.json")).unwrap();
    let out = d.join("merged");
    // The untouched partial merges.
    run_ok(&["merge", &p(&d.join("s0")), "--out", &p(&out)]);
    std::fs::remove_dir_all(&out).unwrap();
    // The first `"name": "…"` of the partial with another value.
    let field = |name: &str, v: &str| {
        let key = format!("\"{name}\": \"");
        let i = good.find(&key).unwrap() + key.len();
        let j = i + good[i..].find('"').unwrap();
        format!("{}{v}{}", &good[..i], &good[j..])
    };
    let second_k = good.replacen("\"k\": 3,", "\"k\": 2,", 1);
    let cases: Vec<(String, &str)> = vec![
        (field("rms", "NaN"), "rms NaN is not a value a run gives"),
        (field("rms", "inf"), "rms inf is not a value a run gives"),
        (field("rms", "1e999"), "rms inf is not a value a run gives"),
        (field("rms", "-1"), "rms -1.0 is not a value a run gives"),
        (
            field("iod", "0"),
            "inter-ocular distance 0.0 is not one a face has",
        ),
        // Round three: 1e-320 was accepted and made mean_rms_iod = inf in the summary.
        (
            field("iod", "1e-320"),
            "inter-ocular distance 1e-320 is not one a face has",
        ),
        (
            field("iod", "1e308"),
            "inter-ocular distance 1e308 is not one a face has",
        ),
        (
            good.replacen("\"frames\": 1008", "\"frames\": 1000000000000", 1),
            "1000000000000 frames of 40 points is beyond what a run reads",
        ),
        (
            good.replacen("\"points\": 40", "\"points\": 1000000000", 1),
            "1008 frames of 1000000000 points is beyond what a run reads",
        ),
        (
            good.replacen(
                "\"frames\": 1008",
                "\"frames\": 1008, \"colour\": \"red\"",
                1,
            ),
            "unknown field `colour`",
        ),
        (
            good.replacen("\"frames\": 1008", "\"frames\": 0", 1),
            "0 frames of 40 points",
        ),
        (second_k, "the curve point spread nnls k = 2 appears twice"),
        (
            good.replacen("\"count\": 1", "\"count\": 1152921504606846976", 1),
            "shard count 1152921504606846976 is beyond",
        ),
        (
            good.replacen("\"bootstrap\": 50", "\"bootstrap\": 2305843009213693952", 1),
            "the experiment it carries: bootstrap: 2305843009213693952 resamples",
        ),
    ];
    for (text, want) in cases {
        assert_ne!(text, good, "the edit for '{want}' changed nothing");
        std::fs::write(d.join("s0/partial.json"), &text).unwrap();
        let r = kslab(&["merge", &p(&d.join("s0")), "--out", &p(&out)]);
        assert_eq!(r.code, 1, "{want}: {}", r.stderr);
        assert!(
            r.stderr.contains(want),
            "expected '{want}' in: {}",
            r.stderr
        );
        assert!(r.stderr.contains("partial.json"), "{}", r.stderr);
        assert!(!out.exists(), "a refused merge wrote {}", out.display());
    }
}
