//! MediaPipe Face Landmarker's own output: 478 points (the Face Mesh
//! 468 and two irises of five points) through every subcommand that takes a MediaPipe
//! file, and its default normalised coordinates detected, said, and turned into pixels by
//! `--image-size`.

use crate::common::{kslab, shared};
use std::path::{Path, PathBuf};

/// A 478-point Face Landmarker track made from a real 468-point one: its points as they
/// are, and each iris a centre between the eye's corners with four points at 0.12 of the
/// eye's width around it (right iris 468–472 on eye corners 33/133, left 473–477 on
/// 263/362). With `scale = Some((w, h))` every x is divided by w and y (and z) by h, as
/// MediaPipe normalises.
fn landmarker_track(dir: &Path, name: &str, src: &str, scale: Option<(f64, f64)>) -> PathBuf {
    let text = std::fs::read_to_string(shared(src)).unwrap();
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |n: &str| head.iter().position(|h| *h == n).unwrap();
    let axes: Vec<char> = ['x', 'y', 'z']
        .into_iter()
        .filter(|a| head.contains(&format!("{a}_0").as_str()))
        .collect();
    let mut out = head[..3].join(",");
    for a in &axes {
        for i in 0..478 {
            out += &format!(",{a}_{i}");
        }
    }
    out.push('\n');
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        out += &f[..3].join(",");
        let v = |a: char, i: usize| f[col(&format!("{a}_{i}"))].parse::<f64>().ok();
        for &a in &axes {
            let div = match (scale, a) {
                (Some((w, _)), 'x') => w,
                (Some((_, h)), _) => h,
                (None, _) => 1.0,
            };
            let mut row: Vec<Option<f64>> = (0..468).map(|i| v(a, i)).collect();
            for (p, q) in [(33, 133), (263, 362)] {
                let ctr = |ax: char| Some((v(ax, p)? + v(ax, q)?) / 2.0);
                let r = (|| {
                    let dx = v('x', p)? - v('x', q)?;
                    let dy = v('y', p)? - v('y', q)?;
                    Some(0.12 * (dx * dx + dy * dy).sqrt())
                })();
                for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (0.0, -1.0), (-1.0, 0.0), (0.0, 1.0)] {
                    row.push(match a {
                        'x' => ctr('x').zip(r).map(|(c, r)| c + dx * r),
                        'y' => ctr('y').zip(r).map(|(c, r)| c + dy * r),
                        _ => v('z', p),
                    });
                }
            }
            for x in row {
                out.push(',');
                if let Some(x) = x {
                    out += &format!("{:?}", x / div);
                }
            }
        }
        out.push('\n');
    }
    let p = dir.join(name);
    std::fs::write(&p, out).unwrap();
    p
}

fn ok(args: &[&str]) -> String {
    let r = kslab(args);
    assert_eq!(r.code, 0, "kslab {args:?}: {}", r.stderr);
    assert!(!r.stderr.contains("panicked"), "{}", r.stderr);
    r.stdout + &r.stderr
}

#[test]
fn a_face_landmarker_track_of_478_points_goes_through_every_subcommand() {
    let d = tempfile::tempdir().unwrap();
    let t = landmarker_track(
        d.path(),
        "d18.csv",
        "mediapipe_face_tracks/liveportrait_d18.csv",
        None,
    );
    let t = t.to_str().unwrap();
    let o = |n: &str| d.path().join(n).display().to_string();
    let info = ok(&["info", t]);
    assert!(info.contains("points         478"), "{info}");
    assert!(
        info.contains("layout         mediapipe_face_landmarker_478"),
        "{info}"
    );
    assert!(
        info.contains("left_iris") && info.contains("right_iris"),
        "{info}"
    );
    assert!(!info.contains("normalised"), "{info}");
    // The iris groups select their ten points; every 468 group still works.
    let i = ok(&["info", t, "--points", "irises"]);
    assert!(i.contains("478 (10 selected)"), "{i}");
    ok(&[
        "solve",
        t,
        "--points",
        "left_iris,right_iris",
        "--keys",
        "0,50",
        "--out",
        &o("iris.csv"),
    ]);
    ok(&[
        "solve",
        t,
        "--points",
        "lips",
        "--keys",
        "0,50,100",
        "--out",
        &o("w.csv"),
    ]);
    ok(&[
        "keys", t, "--points", "lips", "--method", "spread", "--k", "5",
    ]);
    ok(&[
        "curves",
        t,
        "--points",
        "lips",
        "--methods",
        "spread",
        "--k",
        "2..4",
        "--out",
        &o("c.csv"),
    ]);
    ok(&[
        "template",
        t,
        "--points",
        "lips",
        "--method",
        "spread",
        "--k",
        "3",
        "--out",
        &o("t.svg"),
    ]);
    ok(&[
        "retarget",
        t,
        "--points",
        "lips",
        "--k",
        "4",
        "--out",
        &o("rt.csv"),
    ]);
    ok(&["retarget", t, "--k", "4", "--out", &o("rt2.csv")]);
    ok(&["smooth", t, "--points", "lips", "--out", &o("sm")]);
    // Through the 68 iBUG points (`--landmarks 68`) the rig reads the 468 → 68
    // correspondence from the first 468 points: the same weights as the 468-point file it
    // was made from. Dense (the default), the 478 file adds the two iris centres.
    ok(&["rig", t, "--landmarks", "68", "--out", &o("r478.csv")]);
    let src = shared("mediapipe_face_tracks/liveportrait_d18.csv");
    ok(&[
        "rig",
        src.to_str().unwrap(),
        "--landmarks",
        "68",
        "--out",
        &o("r468.csv"),
    ]);
    assert_eq!(
        std::fs::read_to_string(o("r478.csv")).unwrap(),
        std::fs::read_to_string(o("r468.csv")).unwrap()
    );
    let dense478 = ok(&["rig", t, "--json", "--out", &o("d478.csv")]);
    let dense468 = ok(&[
        "rig",
        src.to_str().unwrap(),
        "--json",
        "--out",
        &o("d468.csv"),
    ]);
    assert!(
        dense478.contains("\"landmarks\": 464") && dense478.contains("\"irises\": true"),
        "{dense478}"
    );
    assert!(
        dense468.contains("\"landmarks\": 462") && dense468.contains("\"irises\": false"),
        "{dense468}"
    );
    // Transfer onto the MediaPipe canonical face and onto the ICT face (through the rig's
    // 468 → 68 correspondence).
    for mesh in [
        "mediapipe_canonical_face/canonical_face_model.obj",
        "ict_facekit_face/neutral_face.obj",
    ] {
        let m = shared(mesh);
        let s = ok(&["transfer", t, "--mesh", m.to_str().unwrap(), "--json"]);
        assert!(s.contains("\"frames\": 216") || s.contains("216"), "{s}");
    }
    // The lab's rig view takes it too.
    let seq = keyshape_io::read_sequence(Path::new(t), &Default::default()).unwrap();
    let rig = keyshape_rig::correspondence::RigSource::new(shared("ict_facekit_face"));
    kslab_tui::rig_view(&seq, &rig).unwrap();
}

#[test]
fn a_face_landmarker_track_maps_through_action_modes() {
    let d = tempfile::tempdir().unwrap();
    let t = landmarker_track(
        d.path(),
        "d6.csv",
        "mediapipe_face_tracks/liveportrait_d6.csv",
        None,
    );
    let t = t.to_str().unwrap();
    // Its own actions, chosen by `kslab actions`: the shipped d6 file's frames (the
    // irises change no measure); the shipped file itself names another track.
    let actions = d.path().join("actions.json").display().to_string();
    ok(&["actions", t, "--out", &actions]);
    let frames = |p: &str| -> Vec<i64> {
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap();
        v["actions"]
            .as_array()
            .unwrap()
            .iter()
            .map(|a| a["frame"].as_i64().unwrap())
            .collect()
    };
    assert_eq!(
        frames(&actions),
        frames("assets/actions/actions_liveportrait_d6.json")
    );
    ok(&["modes", t, "--actions", &actions]);
    ok(&[
        "map",
        t,
        "--actions",
        &actions,
        "--out",
        &d.path().join("m.csv").display().to_string(),
    ]);
}

#[test]
fn normalised_coordinates_are_detected_said_and_scaled_to_pixels() {
    let d = tempfile::tempdir().unwrap();
    let src = "mediapipe_face_tracks/liveportrait_d18.csv";
    let px = landmarker_track(d.path(), "px.csv", src, None);
    let norm = landmarker_track(d.path(), "norm.csv", src, Some((640.0, 480.0)));
    let (px, norm) = (px.to_str().unwrap(), norm.to_str().unwrap());
    let info = ok(&["info", norm]);
    assert!(
        info.contains("normalised: every x and y in [0, 1]"),
        "{info}"
    );
    // Without --image-size every command says so; with it, the results are the pixel
    // track's (to rounding of the division).
    let o = |n: &str| d.path().join(n).display().to_string();
    let said = ok(&[
        "solve",
        norm,
        "--points",
        "lips",
        "--keys",
        "0,50,100",
        "--out",
        &o("n0.csv"),
    ]);
    assert!(
        said.contains("note: ") && said.contains("--image-size"),
        "{said}"
    );
    let n = ok(&[
        "solve",
        norm,
        "--points",
        "lips",
        "--keys",
        "0,50,100",
        "--image-size",
        "640x480",
        "--json",
        "--out",
        &o("n.csv"),
    ]);
    assert!(!n.contains("note: "), "{n}");
    let p = ok(&[
        "solve",
        px,
        "--points",
        "lips",
        "--keys",
        "0,50,100",
        "--json",
        "--out",
        &o("p.csv"),
    ]);
    let rms = |s: &str| -> f64 {
        let v: serde_json::Value = serde_json::from_str(s.trim()).unwrap();
        v["mean_rms"].as_f64().unwrap()
    };
    assert!(
        (rms(&n) - rms(&p)).abs() < 1e-9 * rms(&p),
        "{n} against {p}"
    );
    let a = std::fs::read_to_string(o("n.csv")).unwrap();
    let b = std::fs::read_to_string(o("p.csv")).unwrap();
    assert_eq!(a.lines().count(), b.lines().count());
    // The rig needs x and y on one scale: with the image size it solves as in pixels.
    ok(&[
        "rig",
        norm,
        "--image-size",
        "640x480",
        "--out",
        &o("rn.csv"),
    ]);
    ok(&["rig", px, "--out", &o("rp.csv")]);
    let w = |f: &str| -> Vec<f64> {
        std::fs::read_to_string(o(f))
            .unwrap()
            .lines()
            .skip(1)
            .flat_map(|l| {
                l.split(',')
                    .skip(1)
                    .map(|v| v.parse::<f64>().unwrap_or(0.0))
                    .collect::<Vec<_>>()
            })
            .collect()
    };
    let (wn, wp) = (w("rn.csv"), w("rp.csv"));
    assert_eq!(wn.len(), wp.len());
    let worst = wn
        .iter()
        .zip(&wp)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    // The rig's iterative solve stops at its tolerance: rounding in the division moves the
    // weights by ~1e-6 (measured 1.3e-6).
    assert!(worst < 1e-4, "rig weights differ by {worst}");
    // An image size for a pixel track, or a malformed one, is refused.
    let r = kslab(&["solve", px, "--keys", "0", "--image-size", "640x480"]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.contains("applies to normalised coordinates"),
        "{}",
        r.stderr
    );
    let r = kslab(&["solve", norm, "--keys", "0", "--image-size", "640"]);
    assert_eq!(r.code, 2);
    assert!(r.stderr.contains("not an image size"), "{}", r.stderr);
}

/// The lab reads normalised tracks too: `--image-size` scales the first
/// one and every normalised one opened with `o`, a pixel track opened later is left as it
/// is, and a track left normalised is said in the status line — only while it is loaded.
#[test]
fn the_lab_scales_normalised_tracks_and_says_when_it_cannot() {
    use kslab_tui::{load, load_sized, normalised_note};
    use kslab_tui::{update, Action, State};
    let d = tempfile::tempdir().unwrap();
    let src = "mediapipe_face_tracks/liveportrait_d18.csv";
    let px = landmarker_track(d.path(), "px.csv", src, None);
    let norm = landmarker_track(d.path(), "norm.csv", src, Some((640.0, 480.0)));
    let (px, norm) = (px.to_str().unwrap(), norm.to_str().unwrap());
    let pixels = load(px).unwrap();
    assert!(normalised_note(&pixels).is_none());
    let left = load_sized(norm, None).unwrap();
    assert!(normalised_note(&left).unwrap().contains("--image-size"));
    let scaled = load_sized(norm, Some((640.0, 480.0))).unwrap();
    assert!(normalised_note(&scaled).is_none());
    let worst = (&scaled.coords - &pixels.coords).amax();
    assert!(worst < 1e-9 * pixels.coords.amax(), "{worst}");
    // A pixel track opened with the size given is read unchanged.
    assert_eq!(
        load_sized(px, Some((640.0, 480.0))).unwrap().coords,
        pixels.coords
    );
    // The notice shows for the sequence loaded, not for a load that was overtaken.
    let mut s = State::new("x", 10, 30.0);
    s.loaded = 3;
    update(&mut s, Action::Notice(2, "old".into()));
    assert_eq!(s.status, "");
    update(&mut s, Action::Notice(3, "normalised".into()));
    assert_eq!(s.status, "normalised");
    // The option needs a file: the built-in sequence is in pixels.
    let r = kslab(&["tui", "--image-size", "640x480"]);
    assert_eq!(r.code, 2, "{}", r.stderr);
}
