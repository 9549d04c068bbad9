//! Outputs as one set: a command's files appear together or
//! not at all, two outputs that are one file are refused however spelled, temporaries are
//! never opened through a planted link, a replaced file keeps its permission bits, a closed
//! standard output is an error, and a degenerate frame is refused by every path that fits a
//! shape or a camera.

use crate::common::{kslab, shared};
use std::path::Path;
use std::process::{Command, Stdio};

fn s(p: &Path) -> String {
    p.display().to_string()
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// A 68-point plain CSV of the first 30 frames of the OpenFace sample, frame 5 replaced by
/// `bad(value index)`.
fn track_with_bad_frame(dir: &Path, name: &str, bad: impl Fn(usize) -> String) -> String {
    let text = std::fs::read_to_string(shared("pyfeat_samples/openface_test.csv")).unwrap();
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').map(str::trim).collect();
    let col = |n: &str| head.iter().position(|h| *h == n).unwrap();
    let xy: Vec<(usize, usize)> = (0..68)
        .map(|i| (col(&format!("x_{i}")), col(&format!("y_{i}"))))
        .collect();
    let mut out = String::from("frame");
    for i in 0..68 {
        out += &format!(",x{i},y{i}");
    }
    out.push('\n');
    for (n, line) in lines.take(30).enumerate() {
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        out += &n.to_string();
        for (i, &(x, y)) in xy.iter().enumerate() {
            if n == 5 {
                out += &format!(",{},{}", bad(2 * i), bad(2 * i + 1));
            } else {
                out += &format!(",{},{}", f[x], f[y]);
            }
        }
        out.push('\n');
    }
    let p = dir.join(name);
    std::fs::write(&p, out).unwrap();
    s(&p)
}

/// Runs `script` in bash in `dir` and expects it to succeed.
#[cfg(unix)]
fn bash_ok(dir: &Path, script: &str) {
    let out = Command::new("bash")
        .args(["-c", script])
        .current_dir(dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[cfg(unix)]
#[test]
fn a_link_planted_at_a_guessable_temporary_name_is_never_followed() {
    // The old writer opened `.NAME.tmp-PID` with File::create, which follows a link: with
    // a link planted there, another user could redirect the output onto any file.
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("victim.txt"), "secret\n").unwrap();
    let script = format!(
        "ln -s victim.txt .w2.csv.tmp-$$; exec {} solve --keys 3,50 --out w2.csv",
        env!("CARGO_BIN_EXE_kslab")
    );
    bash_ok(d.path(), &script);
    assert_eq!(
        std::fs::read_to_string(d.path().join("victim.txt")).unwrap(),
        "secret\n"
    );
    let meta = std::fs::symlink_metadata(d.path().join("w2.csv")).unwrap();
    assert!(meta.file_type().is_file(), "w2.csv must be a regular file");
    let w = std::fs::read_to_string(d.path().join("w2.csv")).unwrap();
    assert!(w.starts_with("frame,rms,w_3,w_50\n"), "{w}");
}

#[cfg(unix)]
#[test]
fn a_replaced_file_keeps_its_permission_bits_and_a_new_one_follows_the_umask() {
    use std::os::unix::fs::PermissionsExt;
    let d = tempfile::tempdir().unwrap();
    let old = d.path().join("w.csv");
    std::fs::write(&old, "old").unwrap();
    std::fs::set_permissions(&old, std::fs::Permissions::from_mode(0o600)).unwrap();
    let bin = env!("CARGO_BIN_EXE_kslab");
    let script = format!(
        "umask 022; {bin} solve --keys 3,50 --out w.csv --json > s.json && {bin} solve --keys 3 --out new.csv"
    );
    bash_ok(d.path(), &script);
    let mode = |p: &str| {
        std::fs::metadata(d.path().join(p))
            .unwrap()
            .permissions()
            .mode()
            & 0o7777
    };
    assert_eq!(mode("w.csv"), 0o600, "the replaced file keeps 0600");
    assert_ne!(std::fs::read_to_string(&old).unwrap(), "old");
    assert_eq!(
        mode("new.csv"),
        0o644,
        "a new file is 0666 less the umask 022"
    );
    // Nothing but the outputs is left behind.
    assert_eq!(files_in(d.path()), ["new.csv", "s.json", "w.csv"]);
}

#[test]
fn two_outputs_that_are_one_file_are_refused_however_spelled() {
    let d = tempfile::tempdir().unwrap();
    let p = |n: &str| s(&d.path().join(n));
    let dot = |n: &str| s(&d.path().join(".").join(n));
    std::fs::write(d.path().join("keep.csv"), "keep").unwrap();
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink("keep.csv", d.path().join("link.csv")).unwrap();
        std::fs::hard_link(d.path().join("keep.csv"), d.path().join("hard.csv")).unwrap();
    }
    let mut cases: Vec<Vec<String>> = vec![
        vec![
            "curves".into(),
            "--methods".into(),
            "spread".into(),
            "--k".into(),
            "2..3".into(),
            "--out".into(),
            p("c.csv"),
            "--png".into(),
            dot("c.csv"),
        ],
        vec![
            "rig".into(),
            "--out".into(),
            p("r.csv"),
            "--pose".into(),
            dot("r.csv"),
        ],
        vec![
            "rig".into(),
            "--out".into(),
            p("r.csv"),
            "--livelink".into(),
            dot("r.csv"),
        ],
        vec![
            "retarget".into(),
            "--points".into(),
            "lips".into(),
            "--k".into(),
            "3".into(),
            "--out".into(),
            p("rt.csv"),
            "--png".into(),
            dot("rt.csv"),
        ],
    ];
    #[cfg(unix)]
    {
        cases.push(vec![
            "curves".into(),
            "--methods".into(),
            "spread".into(),
            "--k".into(),
            "2..3".into(),
            "--out".into(),
            p("keep.csv"),
            "--png".into(),
            p("link.csv"),
        ]);
        cases.push(vec![
            "solve".into(),
            "--keys".into(),
            "3".into(),
            "--out".into(),
            p("keep.csv"),
            "--png".into(),
            p("hard.csv"),
        ]);
        cases.push(vec![
            "rig".into(),
            "--out".into(),
            p("hard.csv"),
            "--livelink".into(),
            p("keep.csv"),
        ]);
    }
    for args in &cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let r = kslab(&args);
        assert_eq!(r.code, 1, "{args:?}: {}", r.stderr);
        assert!(
            r.stderr.contains("named as two outputs"),
            "{args:?}: {}",
            r.stderr
        );
        assert_eq!(
            std::fs::read_to_string(d.path().join("keep.csv")).unwrap(),
            "keep"
        );
    }
    let mut left = files_in(d.path());
    left.retain(|f| !["keep.csv", "link.csv", "hard.csv"].contains(&f.as_str()));
    assert!(left.is_empty(), "left behind: {left:?}");
}

#[test]
fn a_failed_command_leaves_every_output_as_it_was() {
    let d = tempfile::tempdir().unwrap();
    let r_csv = d.path().join("r.csv");
    std::fs::write(&r_csv, "old").unwrap();
    // The weights are written first, the Live Link file fails on a full device: the
    // weights must not have replaced the old file, and the frame folder made for
    // --png-dir must be gone again.
    let r = kslab(&[
        "rig",
        "--out",
        &s(&r_csv),
        "--png-dir",
        &s(&d.path().join("new/frames")),
        "--livelink",
        "/dev/full",
    ]);
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(r.stderr.contains("/dev/full"), "{}", r.stderr);
    assert_eq!(std::fs::read_to_string(&r_csv).unwrap(), "old");
    assert_eq!(files_in(d.path()), ["r.csv"]);

    // A spec that is its own report (report.json in --out .) is refused before any of the
    // curves or pictures appear.
    let spec = d.path().join("report.json");
    std::fs::write(
        &spec,
        "title = \"x\"\ninput = \"builtin\"\nmethods = [\"spread\"]\nk = \"2..4\"\n",
    )
    .unwrap();
    let r = kslab(&["run", &s(&spec), "--out", &s(d.path())]);
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(r.stderr.contains("refusing to write"), "{}", r.stderr);
    assert_eq!(files_in(d.path()), ["r.csv", "report.json"]);
}

#[cfg(unix)]
#[test]
fn a_closed_standard_output_is_an_error_and_a_closed_pipe_a_quiet_stop() {
    let bin = env!("CARGO_BIN_EXE_kslab");
    // Closed before the command starts (`>&-`): the weights would vanish.
    let out = Command::new("bash")
        .args(["-c", &format!("exec {bin} solve --keys 3,50 --out - >&-")])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("standard output is closed"), "{err}");
    // A reader that has gone (`| head` after it read enough): no message, not a success.
    let mut child = Command::new(bin)
        .args(["intensity", "--clips"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.is_empty(), "a closed pipe is a quiet stop: {err}");
    assert_ne!(out.status.code(), Some(0));
}

/// Every table written to standard output (through the `csv` crate, which wraps a write
/// error as its own) stops quietly when its reader has gone, as `| head` does.
#[cfg(unix)]
#[test]
fn every_csv_on_standard_output_stops_quietly_on_a_closed_pipe() {
    let bin = env!("CARGO_BIN_EXE_kslab");
    let track = shared("mediapipe_face_tracks/liveportrait_d6.csv");
    let t = track.to_str().unwrap();
    for args in [
        vec!["solve", "--keys", "3,50"],
        vec!["solve", t, "--keys", "0,60,120", "--stream"],
        vec!["rig"],
        vec!["retarget", "--method", "spread", "--k", "6", "--out", "-"],
        vec!["curves", "--methods", "spread", "--k", "2..4"],
    ] {
        let mut child = Command::new(bin)
            .args(&args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.lines().all(|l| !l.starts_with("error")),
            "{args:?}: a closed pipe is a quiet stop: {err}"
        );
    }
}

#[test]
fn a_degenerate_frame_is_refused_by_name_on_every_path_that_fits_it() {
    let d = tempfile::tempdir().unwrap();
    let zero = track_with_bad_frame(d.path(), "zero.csv", |_| "0".into());
    let tiny = track_with_bad_frame(d.path(), "tiny.csv", |i| format!("{}", i as f64 * 1e-300));
    let out = s(&d.path().join("w.csv"));
    for file in [&zero, &tiny] {
        for args in [
            vec!["rig", file.as_str(), "--out", &out],
            vec!["rig", file.as_str(), "--neutral", "0", "--out", &out],
            vec!["solve", file.as_str(), "--keys", "0,3", "--out", &out],
            vec!["keys", file.as_str(), "--method", "spread", "--k", "2"],
            vec!["retarget", file.as_str(), "--k", "3", "--out", &out],
        ] {
            let r = kslab(&args);
            assert_eq!(r.code, 1, "{args:?}: {}{}", r.stdout, r.stderr);
            assert!(
                r.stderr.contains("frame 5: all 68 points coincide"),
                "{args:?}: {}",
                r.stderr
            );
        }
    }
    assert!(!d.path().join("w.csv").exists());
    // The lab's rig view (`kslab tui FILE --rig DIR` at start-up) and the library's rig
    // solve refuse it too, instead of panicking in the camera's SVD.
    let seq = keyshape_io::read_sequence(Path::new(&tiny), &Default::default()).unwrap();
    let rig = keyshape_rig::Rig::read_ict(&shared("ict_facekit_face")).unwrap();
    let source = keyshape_rig::correspondence::RigSource::new(shared("ict_facekit_face"));
    let e = kslab_tui::rig_view(&seq, &source)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("frame 5: all 68 points coincide"), "{e}");
    let e = keyshape_rig::solve_rig(&rig, &seq.coords, &[], &Default::default())
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("frame column 5: all 68 landmarks coincide"),
        "{e}"
    );
    let pts = vec![[1e-300, 2e-300]; 68];
    let e = keyshape_rig::camera::fit_camera(&rig.neutral, &pts);
    assert!(e.is_err());
}

/// One rule for a closed pipe: a command that could not deliver an output commits none of
/// them, whether the weights went to standard output by default or by `--out -` (round
/// three: the default path exited 0 and wrote the PNG).
#[cfg(unix)]
#[test]
fn a_closed_pipe_commits_no_output_whichever_way_standard_output_was_chosen() {
    let d = tempfile::tempdir().unwrap();
    let bin = env!("CARGO_BIN_EXE_kslab");
    let t = shared("mediapipe_face_tracks/liveportrait_d6.csv");
    for out in ["", "--out -"] {
        let script = format!(
            "set -o pipefail; {bin} solve {} --method spread --k 24 --png w.png {out} | head -c 10 >/dev/null; echo ${{PIPESTATUS[0]}}",
            t.display()
        );
        let r = Command::new("bash")
            .args(["-c", &script])
            .current_dir(d.path())
            .output()
            .unwrap();
        let code = String::from_utf8_lossy(&r.stdout).trim().to_string();
        assert_eq!(
            code,
            "141",
            "{out:?}: {}",
            String::from_utf8_lossy(&r.stderr)
        );
        assert_eq!(files_in(d.path()), Vec::<String>::new(), "{out:?}");
    }
}

/// SIGINT, SIGTERM and SIGHUP remove what a command staged and leave every output as it
/// was; SIGKILL, which no process can catch, leaves one staging folder per output folder
/// (round three: SIGINT left `.w.csv.*.tmp`, SIGKILL during `rig --png-dir` 29 files).
#[cfg(unix)]
#[test]
fn a_signal_leaves_every_output_as_it_was_and_a_kill_one_staging_folder_per_folder() {
    let bin = env!("CARGO_BIN_EXE_kslab");
    let t = shared("mediapipe_face_tracks/liveportrait_d6.csv");
    // Every signal whose default ends the process (USR1, USR2 and ALRM left staging folders
    // and a half-made picture folder when only INT, TERM and HUP were covered).
    for sig in [
        "INT", "TERM", "HUP", "USR1", "USR2", "ALRM", "RTMIN", "KILL",
    ] {
        let d = tempfile::tempdir().unwrap();
        std::fs::write(d.path().join("w.csv"), "old").unwrap();
        // Wait until the command has staged at least 10 frames, then signal it.
        let script = format!(
            "{bin} rig {} --out w.csv --pose p.csv --png-dir pd -q & pid=$!\n\
             for i in $(seq 1 600); do n=$(find . -name '*.png' | wc -l); [ $n -ge 10 ] && break; sleep 0.05; done\n\
             kill -{sig} $pid; wait $pid; echo $?",
            t.display()
        );
        let r = Command::new("bash")
            .args(["-c", &script])
            .current_dir(d.path())
            .output()
            .unwrap();
        let code: i32 = String::from_utf8_lossy(&r.stdout).trim().parse().unwrap();
        assert!(code > 128, "{sig}: exit {code}");
        assert_eq!(
            std::fs::read_to_string(d.path().join("w.csv")).unwrap(),
            "old"
        );
        let left = files_in(d.path());
        if sig == "KILL" {
            // w.csv, the folder made for the frames, and one staging folder in each.
            let staging: Vec<&String> = left
                .iter()
                .filter(|n| n.starts_with(".kslab-staging-"))
                .collect();
            assert_eq!(staging.len(), 1, "{left:?}");
            let pd = files_in(&d.path().join("pd"));
            assert_eq!(pd.len(), 1, "{pd:?}");
            assert!(pd[0].starts_with(".kslab-staging-"), "{pd:?}");
        } else {
            assert_eq!(left, ["w.csv"], "{sig}");
        }
    }
}

/// A FIFO, a read-only file and a shard folder named through a link are refused before
/// any work (round three: a FIFO blocked for ever, a 0444 file was replaced silently,
/// `merge --out s0l` wrote into the shard s0).
#[cfg(unix)]
#[test]
fn a_fifo_a_read_only_file_and_a_linked_shard_folder_are_refused() {
    use std::os::unix::fs::PermissionsExt;
    let d = tempfile::tempdir().unwrap();
    bash_ok(d.path(), "mkfifo f.csv && mkdir s0 s1 && ln -s s0 s0l");
    let r = kslab(&["solve", "--keys", "3", "--out", &s(&d.path().join("f.csv"))]);
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(
        r.stderr.contains("f.csv: is a FIFO (named pipe)"),
        "{}",
        r.stderr
    );
    let ro = d.path().join("ro.csv");
    std::fs::write(&ro, "keep").unwrap();
    std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o444)).unwrap();
    let r = kslab(&["solve", "--keys", "3", "--out", &s(&ro)]);
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(
        r.stderr
            .contains("ro.csv: refusing to replace a read-only file (mode 444)"),
        "{}",
        r.stderr
    );
    assert_eq!(std::fs::read_to_string(&ro).unwrap(), "keep");
    let r = kslab(&[
        "merge",
        &s(&d.path().join("s0")),
        &s(&d.path().join("s1")),
        "--out",
        &s(&d.path().join("s0l")),
    ]);
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(
        r.stderr.contains("would overwrite a shard's folder"),
        "{}",
        r.stderr
    );
}

/// Standard output that is an input is refused when the input is read, before anything is
/// written: `solve in.csv >> in.csv` appended the weights to the input, `--out - 1<> in.csv`
/// overwrote its header, `rig in.csv >> in.csv` likewise, all with exit 0.
#[cfg(unix)]
#[test]
fn standard_output_that_is_an_input_is_refused_and_the_input_kept() {
    let d = tempfile::tempdir().unwrap();
    let t = shared("mediapipe_face_tracks/liveportrait_d18.csv");
    std::fs::copy(&t, d.path().join("in.csv")).unwrap();
    let before = std::fs::read(d.path().join("in.csv")).unwrap();
    let bin = env!("CARGO_BIN_EXE_kslab");
    for redirect in [
        "solve in.csv --keys 0,10 >> in.csv",
        "solve in.csv --keys 0,10 --out - 1<> in.csv",
        "solve in.csv --keys 0,10 --stream >> in.csv",
        "rig in.csv -q >> in.csv",
    ] {
        let out = Command::new("bash")
            .args(["-c", &format!("{bin} {redirect}")])
            .current_dir(d.path())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{redirect}: {err}");
        assert!(
            err.contains("in.csv: is also standard output"),
            "{redirect}: {err}"
        );
        assert_eq!(
            std::fs::read(d.path().join("in.csv")).unwrap(),
            before,
            "{redirect}"
        );
    }
    // Standard output to another file is fine.
    bash_ok(d.path(), &format!("{bin} solve in.csv --keys 0,10 > w.csv"));
}

/// A closed standard error loses messages, never the command: `live`, `modes --png` and the
/// error paths of `solve` and `info` panicked (exit 101), and `modes` lost its output.
#[cfg(unix)]
#[test]
fn a_closed_standard_error_never_panics_a_command() {
    let d = tempfile::tempdir().unwrap();
    let bin = env!("CARGO_BIN_EXE_kslab");
    let d6 = shared("mediapipe_face_tracks/liveportrait_d6.csv");
    let d18 = shared("mediapipe_face_tracks/liveportrait_d18.csv");
    let actions =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/actions/actions_liveportrait_d6.json");
    // Standard error into a pipe whose reader has gone (and standard output discarded).
    let cases: [(String, i32); 4] = [
        (
            format!(
                "modes {} --actions {} --png m.png",
                d6.display(),
                actions.display()
            ),
            0,
        ),
        ("solve nope.csv --keys 1".into(), 1),
        ("info nope.csv".into(), 1),
        (
            format!(
                "live --from file:{} --rate 5000 --to stdout --calibrate 5",
                d18.display()
            ),
            0,
        ),
    ];
    for (args, want) in cases {
        let script = format!(
            "{{ {bin} {args} 2>&1 >/dev/null; echo \"exit $?\" >> codes; }} | (exec <&-; sleep 1)"
        );
        let _ = std::fs::remove_file(d.path().join("codes"));
        Command::new("bash")
            .args(["-c", &script])
            .current_dir(d.path())
            .output()
            .unwrap();
        let codes = std::fs::read_to_string(d.path().join("codes")).unwrap();
        assert_eq!(codes.trim(), format!("exit {want}"), "{args}");
    }
    assert!(d.path().join("m.png").exists(), "modes kept its output");
    // Every message goes through the one writer: no `eprintln!` left in the command line.
    for f in walk(&Path::new(env!("CARGO_MANIFEST_DIR")).join("src")) {
        let text = std::fs::read_to_string(&f).unwrap();
        let uses = text
            .lines()
            .filter(|l| {
                (l.contains("eprintln!(") || l.contains("eprint!("))
                    && !l.trim_start().starts_with("//")
            })
            .count();
        assert_eq!(
            uses,
            0,
            "{}: eprintln! panics on a closed standard error; use errln!",
            f.display()
        );
    }
}

fn walk(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
    out
}

/// The protected-symlink rule on every component: in a sticky world-writable folder, a
/// link owned by another user (`nobody`) is not followed on the way to an output or an
/// input, whether it is the folder named or a link points into it (root's `solve --out
/// sticky/dirlink/important.csv` replaced `victim/important.csv`). Needs root (to give the
/// link to `nobody`); elsewhere the rule's owner test is the same and this says so.
#[cfg(unix)]
#[test]
fn a_link_of_another_user_in_a_sticky_folder_is_followed_in_no_component() {
    use std::os::unix::fs::{symlink, PermissionsExt};
    // SAFETY: geteuid has no preconditions.
    #[allow(unsafe_code)]
    let root = unsafe { libc::geteuid() } == 0;
    if !root {
        eprintln!("skipped: giving a link to another user needs root");
        return;
    }
    let d = tempfile::tempdir().unwrap();
    let (sticky, victim) = (d.path().join("sticky"), d.path().join("victim"));
    std::fs::create_dir(&sticky).unwrap();
    std::fs::create_dir(&victim).unwrap();
    std::fs::set_permissions(&sticky, std::fs::Permissions::from_mode(0o1777)).unwrap();
    std::fs::write(victim.join("important.csv"), "keep").unwrap();
    std::fs::write(victim.join("cal.json"), "{}").unwrap();
    let link = sticky.join("dirlink");
    symlink(&victim, &link).unwrap();
    std::os::unix::fs::lchown(&link, Some(65534), Some(65534)).unwrap();
    symlink(&link, d.path().join("rootlink")).unwrap();
    let t = shared("mediapipe_face_tracks/liveportrait_d18.csv");
    let via = |p: &str| s(&d.path().join(p));
    let file = format!("file:{}", t.display());
    let cases: Vec<Vec<String>> = vec![
        vec![
            "solve".into(),
            "--keys".into(),
            "3,40".into(),
            "--out".into(),
            via("sticky/dirlink/important.csv"),
        ],
        vec![
            "solve".into(),
            "--keys".into(),
            "3,40".into(),
            "--out".into(),
            via("rootlink/important.csv"),
        ],
        vec![
            "rig".into(),
            s(&t),
            "--png-dir".into(),
            via("sticky/dirlink"),
            "--out".into(),
            via("w.csv"),
        ],
        vec![
            "live".into(),
            "--from".into(),
            file.clone(),
            "--to".into(),
            "stdout".into(),
            "--stats".into(),
            via("sticky/dirlink/important.csv"),
        ],
        vec![
            "live".into(),
            "--from".into(),
            file.clone(),
            "--to".into(),
            "stdout".into(),
            "--record".into(),
            via("sticky/dirlink/take"),
        ],
        vec![
            "live".into(),
            "--from".into(),
            file,
            "--to".into(),
            "stdout".into(),
            "--neutral-file".into(),
            via("sticky/dirlink/cal.json"),
        ],
    ];
    for args in cases {
        let out = Command::new(env!("CARGO_BIN_EXE_kslab"))
            .args(&args)
            .stdout(Stdio::null())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("refusing to follow this link"),
            "{args:?}: {err}"
        );
    }
    assert_eq!(files_in(&victim), ["cal.json", "important.csv"]);
    assert_eq!(
        std::fs::read_to_string(victim.join("important.csv")).unwrap(),
        "keep"
    );
}
