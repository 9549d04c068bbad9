//! What a command tells its user: `solve` chooses its own keys as `keys`
//! does, `keys` and `solve` report the same overall RMS for the same keys, and `curves`,
//! `smooth` and `run` end with the line a user wants.

use crate::common::{kslab, shared};

fn ok(args: &[&str]) -> (String, String) {
    let r = kslab(args);
    assert_eq!(r.code, 0, "kslab {args:?}: {}", r.stderr);
    (r.stdout, r.stderr)
}

#[test]
fn solve_chooses_keys_as_keys_does_and_both_report_one_overall_rms() {
    let t = shared("mediapipe_face_tracks/liveportrait_d18.csv");
    let t = t.to_str().unwrap();
    let d = tempfile::tempdir().unwrap();
    let o = |n: &str| d.path().join(n).display().to_string();
    let (keys, _) = ok(&[
        "keys", t, "--points", "lips", "--method", "kmeans2", "--k", "6", "--json",
    ]);
    let kv: serde_json::Value = serde_json::from_str(&keys).unwrap();
    let frames: Vec<String> = kv["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.to_string())
        .collect();
    let (_, said) = ok(&[
        "solve",
        t,
        "--points",
        "lips",
        "--method",
        "kmeans2",
        "--k",
        "6",
        "--out",
        &o("a.csv"),
    ]);
    assert!(
        said.contains(&format!("keys by kmeans2: {}", frames.join(","))),
        "{said}"
    );
    let (sj, _) = ok(&[
        "solve",
        t,
        "--points",
        "lips",
        "--keys",
        &frames.join(","),
        "--json",
        "--out",
        &o("b.csv"),
    ]);
    assert_eq!(
        std::fs::read_to_string(o("a.csv")).unwrap(),
        std::fs::read_to_string(o("b.csv")).unwrap()
    );
    let sv: serde_json::Value = serde_json::from_str(&sj).unwrap();
    let (k_rms, s_rms) = (
        kv["rms"].as_f64().unwrap(),
        sv["overall_rms"].as_f64().unwrap(),
    );
    assert!(
        (k_rms - s_rms).abs() < 1e-9 * k_rms,
        "keys {k_rms} solve {s_rms}"
    );
    let (text, _) = ok(&[
        "keys", t, "--points", "lips", "--method", "kmeans2", "--k", "6",
    ]);
    assert!(text.contains(&format!("overall RMS {k_rms:.4}")), "{text}");
    // Neither keys nor a method: refused, naming both ways.
    let r = kslab(&["solve", t]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr
            .contains("--keys 3,17,42, or --method spread --k 12"),
        "{}",
        r.stderr
    );
}

#[test]
fn curves_smooth_and_run_end_with_their_result() {
    let d = tempfile::tempdir().unwrap();
    let o = |n: &str| d.path().join(n).display().to_string();
    let (out, _) = ok(&[
        "curves",
        "--methods",
        "spread,greedy",
        "--k",
        "2..5",
        "--solver",
        "nnls,ls",
        "--out",
        &o("c.csv"),
    ]);
    let csv = std::fs::read_to_string(o("c.csv")).unwrap();
    // The line names, per solver, the method lowest at the largest k — checked on the CSV.
    for solver in ["nnls", "ls"] {
        let best = csv
            .lines()
            .skip(1)
            .map(|l| l.split(',').collect::<Vec<_>>())
            .filter(|f| f[1] == solver && f[2] == "5")
            .min_by(|a, b| {
                a[3].parse::<f64>()
                    .unwrap()
                    .total_cmp(&b[3].parse::<f64>().unwrap())
            })
            .unwrap()[0]
            .to_string();
        assert!(out.contains(&format!("{solver} {best} (RMS")), "{out}");
    }
    assert!(out.starts_with("at k = 5, lowest error: "), "{out}");
    let (out, _) = ok(&["smooth", "--points", "lips", "--out", &o("sm")]);
    assert!(
        out.contains("lowest error against G(q) at equal jitter — at jitter"),
        "{out}"
    );
    // The line names the winner against G(q), not against the clean reference (whose
    // winner moves with its σ): the first level's lowest target_rms_tracked in the table.
    let table = std::fs::read_to_string(
        std::path::Path::new(&o("sm")).join("smoothing_at_equal_jitter.csv"),
    )
    .unwrap();
    let rows: Vec<Vec<&str>> = table
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    let first = rows[0][0];
    let best = rows
        .iter()
        .filter(|r| r[0] == first && !r[2].is_empty())
        .min_by(|a, b| {
            a[2].parse::<f64>()
                .unwrap()
                .total_cmp(&b[2].parse::<f64>().unwrap())
        })
        .unwrap();
    assert!(
        out.contains(&format!(": {} (target RMS vs G(q)", best[1])),
        "{out}\n{table}"
    );
    let (out, _) = ok(&[
        "run",
        "experiments/smoke_builtin_lips.toml",
        "--out",
        &o("run"),
    ]);
    assert!(out.contains("lowest error: "), "{out}");
}

/// A file of several clips solved with one identity says that `--identity-per clip` exists;
/// asking for either says nothing.
#[test]
fn rig_on_a_file_of_clips_names_the_per_clip_identity() {
    let news = shared("pyfeat_samples/news_sample_compact.csv");
    let n = news.to_str().unwrap();
    let d = tempfile::tempdir().unwrap();
    let o = d.path().join("w.csv").display().to_string();
    let (_, said) = ok(&["rig", n, "--out", &o]);
    assert!(
        said.contains("labels 20 clips") && said.contains("--identity-per clip"),
        "{said}"
    );
    for per in ["track", "clip"] {
        let (_, said) = ok(&["rig", n, "--identity-per", per, "--out", &o]);
        assert!(!said.contains("note:"), "{per}: {said}");
    }
}

/// `info --image-size` says that it scaled the track (round three: it said nothing), and a
/// normalised track without it says it is normalised.
#[test]
fn info_says_whether_it_scaled_a_normalised_track() {
    let d = tempfile::tempdir().unwrap();
    let f = d.path().join("n.csv");
    std::fs::write(
        &f,
        "frame,x0,y0,x1,y1,x2,y2\n0,0.1,0.1,0.2,0.1,0.1,0.2\n1,0.1,0.1,0.3,0.1,0.1,0.2\n",
    )
    .unwrap();
    let t = f.display().to_string();
    let (out, _) = ok(&["info", &t, "--image-size", "512x256"]);
    assert!(
        out.contains("coordinates    pixels: normalised coordinates scaled by --image-size 512x256 (x × 512, y × 256)"),
        "{out}"
    );
    assert!(out.contains("x range        51.200 .. 153.600"), "{out}");
    let (out, _) = ok(&["info", &t]);
    assert!(
        out.contains("coordinates    normalised: every x and y in [0, 1]"),
        "{out}"
    );
}

/// A lips-only template's panels are as low as the lips (round three: square panels left
/// two thirds of each empty); a whole face's stay about square.
#[test]
fn template_panels_fit_the_shapes() {
    let d = tempfile::tempdir().unwrap();
    let size = |points: Option<&str>| -> (f64, f64) {
        let o = d.path().join("t.svg").display().to_string();
        let mut args = vec!["template", "--method", "spread", "--k", "4", "--out", &o];
        if let Some(p) = points {
            args.extend(["--points", p]);
        }
        ok(&args);
        let svg = std::fs::read_to_string(&o).unwrap();
        let attr = |name: &str| -> f64 {
            let key = format!(" {name}=\"");
            let i = svg.find(&key).unwrap() + key.len();
            svg[i..i + svg[i..].find('"').unwrap()].parse().unwrap()
        };
        (attr("width"), attr("height"))
    };
    let (w, h) = size(Some("lips"));
    assert!(h < 0.85 * w, "lips: {w} × {h}");
    let (w, h) = size(None);
    assert!((h / w - 1.0).abs() < 0.35, "face: {w} × {h}");
}
