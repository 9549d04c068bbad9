//! Every landmark the tracker gives. MediaPipe tracks solve through the
//! dense 468 → ICT correspondence (and with 478 points the iris centres); the
//! correspondence is checked on what its derivation did not use, noise-free renders come
//! back exactly, the benchmark's goals hold, and bad correspondences are refused.
//! Here: what runs the `kslab` binary; the library's own tests are in `crates/keyshape-rig/tests/rig_dense.rs`.

use crate::common::{kslab, shared};
use keyshape_rig::correspondence::read_rig;
use keyshape_rig::Rig;

fn dense(layout: usize) -> Rig {
    read_rig(&shared("ict_facekit_face"), layout, None)
        .unwrap()
        .2
}

/// `kslab rig --dims 3` reads a MediaPipe track's z and solves with it (other weights than
/// without), and refuses tracks with no depth.
#[test]
fn kslab_rig_reads_depth_with_dims_3() {
    let d = tempfile::tempdir().unwrap();
    let track = shared("mediapipe_face_tracks/liveportrait_d18.csv");
    let (w2, w3) = (d.path().join("w2.csv"), d.path().join("w3.csv"));
    let r = kslab(&[
        "rig",
        track.to_str().unwrap(),
        "--out",
        w2.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let r = kslab(&[
        "rig",
        track.to_str().unwrap(),
        "--dims",
        "3",
        "--out",
        w3.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let (a, b) = (
        std::fs::read_to_string(&w2).unwrap(),
        std::fs::read_to_string(&w3).unwrap(),
    );
    assert_eq!(a.lines().count(), b.lines().count());
    assert_ne!(a, b);
    let news = shared("pyfeat_samples/news_sample_compact.csv");
    let out = d.path().join("x.csv");
    let r = kslab(&[
        "rig",
        news.to_str().unwrap(),
        "--dims",
        "3",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.contains("--dims 3 needs a column 'z_0'"),
        "{}",
        r.stderr
    );
    let r = kslab(&["rig", "--dims", "3", "--out", out.to_str().unwrap()]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.contains("the built-in sequence has no depth"),
        "{}",
        r.stderr
    );
    assert!(!out.exists());
}

/// Bad correspondences and tracks are refused by name, nothing written: a vertex past the
/// mesh, a point past the track, a point count no layout has.
#[test]
fn bad_correspondences_and_point_counts_are_refused() {
    let d = tempfile::tempdir().unwrap();
    let track = shared("mediapipe_face_tracks/liveportrait_d18.csv");
    let out = d.path().join("w.csv");
    let run = |csv: &str| {
        let p = d.path().join("m.csv");
        std::fs::write(&p, csv).unwrap();
        kslab(&[
            "rig",
            track.to_str().unwrap(),
            "--rig-landmarks",
            p.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
    };
    let r = run("landmark,vertex\n33,100\n263,200\n1,4857\n152,300\n61,99999\n");
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.contains("m.csv:6:2")
            && r.stderr
                .contains("names vertex 99999, but the mesh has 9409 vertices"),
        "{}",
        r.stderr
    );
    let r = run("landmark,vertex\n33,100\n263,200\n1,4857\n152,300\n470,301\n");
    assert_eq!(r.code, 1);
    assert!(
        r.stderr
            .contains("names landmark 470, but the track has 468 points"),
        "{}",
        r.stderr
    );
    // Without the eye corners the magnitude prior has no scale: refused, unless it is off.
    let r = run("landmark,vertex\n1,4857\n152,300\n61,301\n291,302\n");
    assert_eq!(r.code, 1);
    assert!(
        r.stderr
            .contains("outer eye corners (track points 33 and 263)"),
        "{}",
        r.stderr
    );
    assert!(!out.exists());
    // Nor has the live path's default temporal prior (relative to the face): refused with
    // the prior off, and taken in pixels.
    let m = d.path().join("m.csv");
    let live = |extra: &[&str]| {
        let mut args = vec![
            "rig",
            track.to_str().unwrap(),
            "--rig-landmarks",
            m.to_str().unwrap(),
            "--live",
            "--prior",
            "0",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        kslab(&args)
    };
    let r = live(&[]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr
            .contains("a temporal prior relative to the face is scaled by the outer eye corners"),
        "{}",
        r.stderr
    );
    assert!(!out.exists());
    let r = live(&["--smooth", "30"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(out.exists());
    std::fs::remove_file(&out).unwrap();
    // A track of 70 points matches no layout.
    let odd = d.path().join("odd.csv");
    let head: Vec<String> = (0..71).map(|i| format!("x{i},y{i}")).collect();
    let row: Vec<String> = (0..142)
        .map(|i| format!("{}", 100 + (i * 37) % 200))
        .collect();
    std::fs::write(
        &odd,
        format!(
            "frame,{}\n0,{}\n1,{}\n",
            head.join(","),
            row.join(","),
            row.join(",")
        ),
    )
    .unwrap();
    let r = kslab(&["rig", odd.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("this one has 71 points"), "{}", r.stderr);
    // --landmarks dense on an iBUG track, and landmark weights on a dense solve.
    let news = shared("pyfeat_samples/news_sample_compact.csv");
    let r = kslab(&[
        "rig",
        news.to_str().unwrap(),
        "--landmarks",
        "dense",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr
            .contains("--landmarks dense applies to MediaPipe tracks"),
        "{}",
        r.stderr
    );
    let r = kslab(&[
        "rig",
        track.to_str().unwrap(),
        "--landmark-weight",
        "jaw=0.1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("use --landmarks 68"), "{}", r.stderr);
    assert!(!out.exists());
}

/// The automatic neutral takes no frame with parted lips or raised brows: on
/// LivePortrait's d18 (neutral, then "oo", then a scream) it took frame 156, lips parted at
/// 0.038 of the inter-ocular distance against the track's median 0.018; its candidates are
/// now the frames whose lips and brows are at most the candidates' medians (measured: frame
/// 41, gap 0.014).
#[test]
fn the_automatic_neutral_has_closed_lips_and_resting_brows() {
    let d = tempfile::tempdir().unwrap();
    let path = shared("mediapipe_face_tracks/liveportrait_d18.csv");
    let out = d.path().join("w.csv");
    let r = kslab(&[
        "rig",
        path.to_str().unwrap(),
        "--json",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let v: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
    let n = v["neutral_frames"][0].as_u64().unwrap() as usize;
    let seq = keyshape_io::read_sequence(&path, &Default::default()).unwrap();
    let at = |p: usize, f: usize| [seq.coords[(2 * p, f)], seq.coords[(2 * p + 1, f)]];
    let dist = |a: [f64; 2], b: [f64; 2]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
    let iod = |f: usize| dist(at(33, f), at(263, f));
    let gap = |f: usize| dist(at(13, f), at(14, f)) / iod(f);
    let brow =
        |f: usize| (dist(at(105, f), at(159, f)) + dist(at(334, f), at(386, f))) / (2.0 * iod(f));
    let median = |g: &dyn Fn(usize) -> f64| {
        let mut v: Vec<f64> = (0..seq.n_frames()).map(g).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    assert!(
        gap(n) <= median(&gap) * 1.1,
        "frame {n}: lip gap {} against {}",
        gap(n),
        median(&gap)
    );
    assert!(
        brow(n) <= median(&brow) * 1.05,
        "frame {n}: brows {} against {}",
        brow(n),
        median(&brow)
    );
}

/// The layout's contours through a rig's landmarks follow the landmarks, whatever order the
/// correspondence lists them in: the iBUG rig's are the 68 layout's, and a rig read through
/// a shuffled list draws the same contours between the same points.
#[test]
fn a_rigs_contours_follow_its_landmarks_in_any_order() {
    use keyshape_retarget::setup::polylines_for;
    let rig68 = dense(68);
    let all: Vec<usize> = (0..68).collect();
    assert_eq!(
        rig68.polylines(),
        polylines_for(&keyshape_core::sequence::Layout::ibug68(), &all)
    );
    let dir = shared("ict_facekit_face");
    let d = tempfile::tempdir().unwrap();
    let marks = std::fs::read_to_string(dir.join("landmarks_multipie68.csv")).unwrap();
    let mut rows: Vec<&str> = marks.lines().skip(1).collect();
    rows.reverse();
    let csv = d.path().join("rev.csv");
    std::fs::write(&csv, format!("landmark,vertex\n{}\n", rows.join("\n"))).unwrap();
    let rev = read_rig(&dir, 68, Some(&csv)).unwrap().2;
    assert_eq!(rev.points, (0..68).rev().collect::<Vec<_>>());
    let as_points = |r: &Rig| -> Vec<Vec<usize>> {
        r.polylines()
            .iter()
            .map(|l| l.iter().map(|&i| r.points[i]).collect())
            .collect()
    };
    assert_eq!(as_points(&rev), as_points(&rig68));
    assert!(!rig68.polylines().is_empty());
}
