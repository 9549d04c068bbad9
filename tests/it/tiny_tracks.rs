//! Sizes that come from the data: every subcommand driven with tiny and repeated tracks
//! (one frame, two identical frames, two frames, three frames with two alike), cut from the
//! real MediaPipe and OpenFace tracks. Each run ends with exit 0 or a clear error (exit 1
//! naming distinct shapes, frames or the file), never a panic, and leaves no output behind
//! when it fails. `kslab keys two_identical_frames.csv --method hull` and `kslab map
//! one_frame.csv …` panicked before the one check of "enough distinct frames"
//! (`keyshapes::need_distinct`).

use crate::common::shared;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The header and the first data rows of `src` as a new file: `rows` picks the source rows
/// (0 = first data row), renumbered 0, 1, … in the frame column when `renumber`.
fn cut(src: &Path, rows: &[usize], dst: &Path) {
    let text = std::fs::read_to_string(src).unwrap();
    let mut lines = text.lines();
    let head = lines.next().unwrap();
    let data: Vec<&str> = lines.take(10).collect();
    let mut out = format!("{head}\n");
    let frame_first = head.split(',').next().is_some_and(|h| h.trim() == "frame");
    for (i, &r) in rows.iter().enumerate() {
        let line = data[r];
        if frame_first {
            let rest = line.split_once(',').unwrap().1;
            out += &format!("{i},{rest}\n");
        } else {
            out += line;
            out.push('\n');
        }
    }
    std::fs::write(dst, out).unwrap();
}

fn run(args: &[String], dir: &Path) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_kslab"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn tiny_and_repeated_tracks_never_panic_and_leave_nothing_behind() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    let sources = [
        ("mp", shared("mediapipe_face_tracks/liveportrait_d6.csv")),
        ("of", shared("pyfeat_samples/openface_test.csv")),
    ];
    let shapes: [(&str, &[usize]); 4] = [
        ("one", &[0]),
        ("twin", &[0, 0]),
        ("two", &[0, 5]),
        ("three", &[0, 5, 0]),
    ];
    let ict = shared("ict_facekit_face").display().to_string();
    let mut failures = Vec::new();
    let mut runs = 0;
    for (layout, src) in &sources {
        for (name, rows) in shapes {
            let track = dir.join(format!("{layout}_{name}.csv"));
            cut(src, rows, &track);
            let t = track.display().to_string();
            let actions = dir.join(format!("{layout}_{name}.json"));
            let a = actions.display().to_string();
            // The actions file first (it is an input of modes and map).
            let (code, err) = run(
                &["actions".into(), t.clone(), "--out".into(), a.clone()],
                dir,
            );
            if code != 0 && code != 1 || err.contains("panicked") {
                failures.push(format!("actions {t}: exit {code}: {err}"));
            }
            let out = |f: &str| dir.join(format!("out_{f}")).display().to_string();
            let mut cmds: Vec<Vec<String>> = Vec::new();
            for m in ["spread", "kmeans2", "hull", "greedy", "random"] {
                let mut c = vec!["keys", &t, "--method", m];
                if m != "hull" {
                    c.extend(["--k", "2"]);
                }
                cmds.push(c.into_iter().map(String::from).collect());
                let mut s = vec!["solve", &t, "--method", m];
                if m != "hull" {
                    s.extend(["--k", "1"]);
                }
                let o = out("w.csv");
                s.extend(["--out", &o]);
                cmds.push(s.into_iter().map(String::from).collect());
            }
            let v = |x: &[&str]| x.iter().map(|s| s.to_string()).collect::<Vec<_>>();
            cmds.push(v(&["info", &t]));
            cmds.push(v(&[
                "curves",
                &t,
                "--methods",
                "spread,hull",
                "--k",
                "1..3",
                "--out",
                &out("c.csv"),
                "--png",
                &out("c.png"),
            ]));
            cmds.push(v(&[
                "template",
                &t,
                "--method",
                "hull",
                "--out",
                &out("t.svg"),
            ]));
            cmds.push(v(&[
                "retarget",
                &t,
                "--method",
                "spread",
                "--k",
                "1",
                "--out",
                &out("r.csv"),
            ]));
            cmds.push(v(&["smooth", &t, "--k", "1", "--out", &out("sm")]));
            cmds.push(v(&[
                "rig",
                &t,
                "--out",
                &out("rig.csv"),
                "--pose",
                &out("pose.csv"),
            ]));
            cmds.push(v(&[
                "transfer",
                &t,
                "--mesh",
                &format!("{ict}/neutral_face.obj"),
                "--obj-dir",
                &out("objs"),
            ]));
            if actions.exists() {
                cmds.push(v(&["modes", &t, "--actions", &a, "--png", &out("m.png")]));
                cmds.push(v(&[
                    "map",
                    &t,
                    "--actions",
                    &a,
                    "--morph",
                    &ict,
                    "--out",
                    &out("map.csv"),
                ]));
                cmds.push(v(&[
                    "map",
                    &t,
                    "--actions",
                    &a,
                    "--target-sequence",
                    &t,
                    "--target-actions",
                    &a,
                    "--out",
                    &out("map2.csv"),
                ]));
            }
            for c in cmds {
                runs += 1;
                let before: Vec<PathBuf> = std::fs::read_dir(dir)
                    .unwrap()
                    .flatten()
                    .map(|e| e.path())
                    .collect();
                let (code, err) = run(&c, dir);
                let bad = !(code == 0 || code == 1) || err.contains("panicked");
                if bad {
                    failures.push(format!("{c:?}: exit {code}: {}", err.trim()));
                }
                // A failed run leaves nothing new; a successful one is cleaned for the next.
                let after: Vec<PathBuf> = std::fs::read_dir(dir)
                    .unwrap()
                    .flatten()
                    .map(|e| e.path())
                    .filter(|p| !before.contains(p))
                    .collect();
                if code != 0 && !after.is_empty() {
                    failures.push(format!("{c:?}: failed but left {after:?}"));
                }
                for p in after {
                    if p.is_dir() {
                        std::fs::remove_dir_all(&p).unwrap();
                    } else {
                        std::fs::remove_file(&p).unwrap();
                    }
                }
            }
        }
    }
    assert!(runs > 100, "{runs} runs");
    assert!(
        failures.is_empty(),
        "{} of {runs} runs:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
