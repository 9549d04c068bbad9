//! A tracker whose points are not where the landmark map says: renders through a map that
//! is wrong by millimetres (`rig-accuracy --map-noise`), solved with the map as it is, with
//! and without robust landmark weights (`--robust-landmarks`), against the truth.
//! Here: what runs the `kslab` binary; the library's own tests are in `crates/keyshape-rig/tests/rig_map.rs`.

use crate::common::{assert_refused, kslab, shared};

/// The options reach the commands, and what cannot work is refused with the reason.
#[test]
fn map_noise_and_robust_landmarks_are_checked() {
    assert_refused(&[
        (
            vec!["rig-accuracy", "--map-noise", "-1"],
            "--map-noise -1: give 0 to 50 millimetres",
        ),
        (
            vec!["rig-accuracy", "--map-noise", "NaN"],
            "--map-noise NaN",
        ),
        (
            vec!["rig-accuracy", "--map-noise", "3", "--landmarks", "478"],
            "irises are virtual points",
        ),
        (
            vec!["rig-accuracy", "--live", "--robust-landmarks"],
            "cannot weigh landmarks robustly",
        ),
        (
            vec!["rig", "--live", "--robust-landmarks"],
            "cannot weigh landmarks robustly",
        ),
    ]);
    // Taken: the same seed through a 3 mm map error scores lower without the robust
    // weights than with them (speech, 468 points).
    let score = |extra: &[&str]| {
        let mut args = vec![
            "rig-accuracy",
            "--landmarks",
            "468",
            "--kind",
            "speech",
            "--frames",
            "150",
            "--seed",
            "2",
            "--map-noise",
            "3",
            "--json",
        ];
        args.extend_from_slice(extra);
        let r = kslab(&args);
        assert_eq!(r.code, 0, "{}", r.stderr);
        let v: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
        v[0]["summary"]["mean_r"].as_f64().unwrap()
    };
    let (plain, robust) = (score(&[]), score(&["--robust-landmarks"]));
    assert!(robust > plain, "{plain} → {robust}");
}

/// `kslab rig --refine-landmarks --save-landmarks F` writes the refined map, and solving
/// the take again through it (`--rig-landmarks F`, robust weights as the refinement's
/// last solve had) gives the same weights, byte for byte.
#[test]
fn a_saved_refined_map_solves_the_take_again() {
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("map.csv");
    let (w1, w2) = (dir.path().join("w1.csv"), dir.path().join("w2.csv"));
    let track = shared("mediapipe_face_tracks/liveportrait_d18.csv");
    let (track, map_s) = (track.to_str().unwrap(), map.to_str().unwrap());
    let r = kslab(&[
        "rig",
        track,
        "--refine-landmarks",
        "--save-landmarks",
        map_s,
        "--out",
        w1.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(
        r.stdout.contains("landmark map refined from the track:")
            && r.stdout.contains("of 462 landmarks on another vertex"),
        "{}",
        r.stdout
    );
    let text = std::fs::read_to_string(&map).unwrap();
    let rows: Vec<&str> = text.lines().collect();
    assert_eq!(rows[0], "landmark,vertex");
    assert_eq!(rows.len(), 463);
    // The built-in map, for comparison: the saved one differs in a few rows only.
    let builtin = include_str!("../../assets/features/mediapipe468_to_ict.csv");
    let changed = rows
        .iter()
        .filter(|r| !builtin.lines().any(|b| b == **r))
        .count();
    assert!((1..60).contains(&changed), "{changed} rows changed");
    let r = kslab(&[
        "rig",
        track,
        "--rig-landmarks",
        map_s,
        "--robust-landmarks",
        "--out",
        w2.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert_eq!(
        std::fs::read(&w1).unwrap(),
        std::fs::read(&w2).unwrap(),
        "the saved map gives other weights"
    );
}

/// Every refinement option takes effect or is refused with the reason.
#[test]
fn refinement_options_are_checked() {
    assert_refused(&[
        (
            vec!["rig", "--save-landmarks", "/tmp/never.csv"],
            "--save-landmarks writes the refined landmark map: give --refine-landmarks",
        ),
        (
            vec!["rig", "--refine-radius", "5"],
            "--refine-radius applies to --refine-landmarks",
        ),
        (
            vec!["rig", "--refine-landmarks", "--refine-radius", "0"],
            "--refine-radius 0: give a distance in (0, 30] millimetres",
        ),
        (
            vec!["rig", "--refine-landmarks", "--refine-radius", "NaN"],
            "--refine-radius NaN",
        ),
        (
            vec!["rig", "--refine-landmarks", "--live"],
            "--refine-landmarks measures each landmark over the whole track: not with --live",
        ),
        (
            vec!["rig-accuracy", "--refine-landmarks", "--live"],
            "not with --live",
        ),
        (
            vec!["rig-accuracy", "--refine-radius", "4"],
            "--refine-radius applies to --refine-landmarks",
        ),
    ]);
    assert!(!std::path::Path::new("/tmp/never.csv").exists());
    // The radius takes effect: a radius too small to reach another vertex moves nothing.
    let moved = |radius: &str| {
        let r = kslab(&[
            "rig",
            "--refine-landmarks",
            "--refine-radius",
            radius,
            "--json",
        ]);
        assert_eq!(r.code, 0, "{}", r.stderr);
        let v: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
        v["refined_map"]["moved"].as_u64().unwrap()
    };
    assert_eq!(moved("0.01"), 0);
    assert!(moved("10") > 0);
}
