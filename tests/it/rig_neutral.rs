//! The person's neutral frame against ground truth: the pose `kslab rig` reports for it, the
//! warning when it cannot look neutral (a turned head, parted lips), and the benchmark's
//! renders that have no neutral frame (`--hold`) or a face whose depth differs (`--person
//! deep`).
//! Here: what runs the `kslab` binary; the library's own tests are in `crates/keyshape-rig/tests/rig_neutral.rs`.

use crate::common::{kslab, shared};
use keyshape_rig::camera::Camera;
use keyshape_rig::Rig;
use nalgebra::DMatrix;
use std::path::Path;

fn ict() -> Rig {
    Rig::read_ict(&shared("ict_facekit_face")).unwrap()
}

/// Writes a 68-point track as `kslab rig-accuracy --tracks` does (frame, x0, y0 … x67, y67).
fn write_track(path: &Path, rig: &Rig, points: &DMatrix<f64>) {
    let mut s = String::from("frame");
    for i in &rig.points {
        s += &format!(",x{i},y{i}");
    }
    s.push('\n');
    for f in 0..points.ncols() {
        s += &f.to_string();
        for v in points.column(f).iter() {
            s += &format!(",{v}");
        }
        s.push('\n');
    }
    std::fs::write(path, s).unwrap();
}

/// `rig`'s neutral landmarks rendered at `frames` frames of one head pose, holding
/// `weights` (name, weight) on every frame, with a small seeded wobble of the jaw so the
/// frames differ.
fn held_pose_track(
    rig: &Rig,
    frames: usize,
    yaw: f64,
    pitch: f64,
    weights: &[(&str, f64)],
) -> DMatrix<f64> {
    let mut truth = DMatrix::zeros(rig.k(), frames);
    let jaw = rig.names.iter().position(|n| n == "jawOpen").unwrap();
    for f in 0..frames {
        truth[(jaw, f)] = 0.05 * (f as f64 / 3.0).sin().abs();
        for (name, w) in weights {
            let s = rig.names.iter().position(|n| n == name).unwrap();
            truth[(s, f)] = *w;
        }
    }
    let cams: Vec<Camera> = (0..frames)
        .map(|_| {
            Camera::from_angles(
                300.0,
                yaw.to_radians(),
                pitch.to_radians(),
                0.0,
                [320.0, -240.0],
            )
        })
        .collect();
    rig.render(&truth, &cams)
}

/// A take whose every frame is turned 30° (or holds the mouth open) has no neutral-looking
/// frame: `kslab rig` still solves it, reports the chosen frame's pose in its summary and
/// JSON (the true 30° within 3°), and warns on stderr, saying what it saw and to record a
/// lead-in. A frontal, relaxed take gets no warning.
#[test]
fn a_take_with_no_neutral_looking_frame_is_warned_about() {
    let rig = ict();
    let d = tempfile::tempdir().unwrap();
    /// (name, yaw, held weights, the warning expected)
    type Case<'a> = (&'a str, f64, &'a [(&'a str, f64)], Option<&'a str>);
    let cases: [Case; 3] = [
        ("turned", 30.0, &[], Some("the head is turned")),
        (
            "open",
            0.0,
            &[("jawOpen", 0.7)],
            Some("the lips are parted"),
        ),
        ("relaxed", 0.0, &[], None),
    ];
    for (name, yaw, held, warning) in cases {
        let path = d.path().join(format!("{name}.csv"));
        write_track(&path, &rig, &held_pose_track(&rig, 40, yaw, 0.0, held));
        let out = d.path().join(format!("{name}_w.csv"));
        let r = kslab(&[
            "rig",
            path.to_str().unwrap(),
            "--json",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(r.code, 0, "{name}: {}", r.stderr);
        let v: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
        let view = &v["neutral_views"][0];
        assert!(
            (view["yaw"].as_f64().unwrap() - yaw).abs() < 3.0,
            "{name}: {view}"
        );
        match warning {
            Some(w) => {
                assert!(r.stderr.contains(w), "{name}: {}", r.stderr);
                assert!(
                    r.stderr.contains("--neutral FIRST-LAST"),
                    "{name}: {}",
                    r.stderr
                );
                assert_eq!(view["looks_neutral"], false, "{name}: {view}");
            }
            None => {
                assert!(!r.stderr.contains("warning"), "{name}: {}", r.stderr);
                assert_eq!(view["looks_neutral"], true, "{name}: {view}");
            }
        }
    }
    // The human summary names the frame's pose.
    let r = kslab(&[
        "rig",
        d.path().join("turned.csv").to_str().unwrap(),
        "--out",
        d.path().join("t2.csv").to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let yaw: f64 = r
        .stdout
        .split("(yaw ")
        .nth(1)
        .and_then(|s| s.split('°').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no pose in {}", r.stdout));
    assert!((yaw - 30.0).abs() <= 3.0, "{}", r.stdout);
}

/// `--hold` renders a take with no neutral frame: every frame's true weights sum to at least
/// 0.7 × HOLD (the held expression breathes between 70 % and 100 %); `--person deep` changes
/// the rendered landmarks of `other`; out-of-range holds are refused naming the value.
#[test]
fn held_expressions_and_deeper_faces_take_effect() {
    let d = tempfile::tempdir().unwrap();
    let run = |extra: &[&str], dir: &str| {
        let t = d.path().join(dir);
        let mut args = vec![
            "rig-accuracy",
            "--kind",
            "speech",
            "--frames",
            "60",
            "--lead-in",
            "10",
            "--tracks",
            t.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let r = kslab(&args);
        assert_eq!(r.code, 0, "{}", r.stderr);
        (t, r.stdout)
    };
    let read = |p: &Path| -> Vec<Vec<f64>> {
        std::fs::read_to_string(p)
            .unwrap()
            .lines()
            .skip(1)
            .map(|l| l.split(',').skip(1).map(|v| v.parse().unwrap()).collect())
            .collect()
    };
    let (held, out) = run(&["--hold", "1.2"], "held");
    let sums: Vec<f64> = read(&held.join("speech_truth.csv"))
        .iter()
        .map(|r| r.iter().sum())
        .collect();
    assert!(sums.iter().all(|&s| s >= 0.7 * 1.2 - 1e-9), "{sums:?}");
    assert!(out.contains("truly holds"), "{out}");
    let (plain, _) = run(&[], "plain");
    let lead: f64 = read(&plain.join("speech_truth.csv"))[..10]
        .iter()
        .flatten()
        .sum();
    assert_eq!(lead, 0.0);
    let (deep, _) = run(&["--person", "deep"], "deep");
    assert_ne!(
        read(&deep.join("speech_track.csv")),
        read(&plain.join("speech_track.csv"))
    );
    for bad in ["-1", "3.5", "NaN"] {
        let r = kslab(&["rig-accuracy", "--hold", bad, "--frames", "20"]);
        assert_eq!(r.code, 1, "{bad}: {}", r.stderr);
        assert!(
            r.stderr.contains("held expression") && r.stderr.contains("[0, 3]"),
            "{bad}: {}",
            r.stderr
        );
    }
}

/// `kslab rig` says which rule chose the neutral: on a render of the rig's own face holding
/// an expression throughout (`rig-accuracy --person same --hold 1.2 --tracks`), the least
/// active frame, "the rig reads as the performer's own face", in the summary and as
/// `"rule": "own-face"` in the JSON; on another person's face the error score's
/// `"best-explaining"`; a named frame is `"given"`.
#[test]
fn the_summary_names_the_rule_that_chose_the_neutral() {
    let d = tempfile::tempdir().unwrap();
    let rule = |person: &str, extra: &[&str]| {
        let t = d.path().join(person);
        let r = kslab(&[
            "rig-accuracy",
            "--kind",
            "speech",
            "--frames",
            "60",
            "--person",
            person,
            "--hold",
            "1.2",
            "--tracks",
            t.to_str().unwrap(),
        ]);
        assert_eq!(r.code, 0, "{}", r.stderr);
        let track = t.join("speech_track.csv");
        let out = d.path().join(format!("{person}_w.csv"));
        let mut args = vec![
            "rig",
            track.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let text = kslab(&args);
        assert_eq!(text.code, 0, "{}", text.stderr);
        args.push("--json");
        let json = kslab(&args);
        let v: serde_json::Value = serde_json::from_str(&json.stdout).unwrap();
        (v["neutral_views"][0]["rule"].clone(), text.stdout)
    };
    let (own, text) = rule("same", &[]);
    assert_eq!(own, "own-face");
    assert!(
        text.contains("the least active frame: the rig reads as the performer's own face"),
        "{text}"
    );
    let (other, text) = rule("other", &[]);
    assert_eq!(other, "best-explaining");
    assert!(!text.contains("own face"), "{text}");
    assert_eq!(rule("same", &["--neutral", "5"]).0, "given");
}
