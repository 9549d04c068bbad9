//! Long tracks: greedy beyond the frames' Gram matrix, generated tracks, and
//! peak memory through the real binary.
//! Here: what runs the `kslab` binary; the library's own tests are in `crates/keyshape-core/tests/scale.rs`.

use keyshape_io::{read_sequence, ReadOptions};

/// Solve, k-means, greedy, template, retarget, transfer and modes on generated long tracks
/// through the real binary, with peak
/// memory from `kslab bench scale` (wait4's rusage): all finish, and memory grows linearly
/// in frames. The slope between 10,000 and 40,000 frames is the memory per frame
/// without the fixed costs. Measured on 2026-12-01 (eighth session, after the reader
/// stopped holding the file's text): solve 1.4 kB, kmeans2 1.3 kB, greedy 3.6 kB per frame
/// of 68 points (one copy of the coordinates is 1.1 kB; greedy's includes its subsample's
/// Gram matrix, 5,000 frames at 10k and 5,715 at 40k: 2.0 kB per frame of the slope);
/// template, retarget, transfer and modes (after they stopped copying the track) 1.0, 1.1,
/// 0.5 and 1.0 kB. The bounds below are those plus a margin: a copy of the coordinates more
/// would break them.
/// The frames × frames Gram matrix would be 12.8 GB at 40,000 frames.
#[test]
fn long_generated_tracks_run_in_memory_linear_in_frames() {
    let d = tempfile::tempdir().unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_kslab"))
        .args([
            "bench",
            "scale",
            "--frames",
            "10000,40000",
            "--steps",
            "solve,kmeans2,greedy,template,retarget,transfer,modes",
            "--json",
            "--dir",
        ])
        .arg(d.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rows: Vec<serde_json::Value> = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(rows.len(), 14);
    for r in &rows {
        assert_eq!(r["ok"], true, "{r}");
    }
    let peak = |step: &str, frames: u64| {
        rows.iter()
            .find(|r| r["step"] == step && r["frames"] == frames)
            .and_then(|r| r["peak_mb"].as_f64())
    };
    for (step, bound) in [
        ("solve", 2_300.0),
        ("kmeans2", 2_300.0),
        ("greedy", 4_500.0),
        ("template", 2_000.0),
        ("retarget", 2_000.0),
        ("transfer", 2_000.0),
        ("modes", 2_000.0),
    ] {
        if let (Some(a), Some(b)) = (peak(step, 10000), peak(step, 40000)) {
            let slope = (b - a) * 1e6 / 30000.0;
            assert!(
                slope < bound,
                "{step}: {a} MB at 10k, {b} MB at 40k: {slope:.0} B/frame"
            );
        }
    }
    // The generated track is the size asked for.
    let track = d.path().join("track_40000x68.csv");
    let seq = read_sequence(&track, &ReadOptions::default()).unwrap();
    assert_eq!((seq.n_frames(), seq.points), (40000, 68));
}

#[test]
fn bench_scale_refuses_what_it_cannot_run_and_generates_one_track_on_request() {
    let d = tempfile::tempdir().unwrap();
    let k = |args: &[&str]| crate::common::kslab(args);
    let r = k(&["bench", "scale", "--steps", "greedy,sort"]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("unknown step 'sort'"), "{}", r.stderr);
    let r = k(&["bench", "scale", "--frames", "0"]);
    assert_eq!(r.code, 2, "a usage error: {}", r.stderr);
    assert!(
        r.stderr.contains("0: give 1 to 1000000 frames"),
        "{}",
        r.stderr
    );
    let two = d.path().join("two.csv");
    let r = k(&[
        "bench",
        "scale",
        "--frames",
        "10,20",
        "--generate",
        two.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("one --frames value"), "{}", r.stderr);
    assert!(!two.exists());
    let r = k(&[
        "bench",
        "scale",
        "--points",
        "100",
        "--frames",
        "10",
        "--generate",
        two.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.contains("68 or 468 points, not 100"),
        "{}",
        r.stderr
    );
    assert!(!two.exists(), "a refused generate left a file");
    for points in [68usize, 468] {
        let p = d.path().join(format!("g{points}.csv"));
        let r = k(&[
            "bench",
            "scale",
            "--frames",
            "500",
            "--points",
            &points.to_string(),
            "--generate",
            p.to_str().unwrap(),
        ]);
        assert_eq!(r.code, 0, "{}", r.stderr);
        let seq = read_sequence(&p, &ReadOptions::default()).unwrap();
        assert_eq!((seq.n_frames(), seq.points), (500, points));
        // Real shapes under drift and noise: the face moves, but stays a face-sized thing.
        let (x, y) = (seq.ranges()[0], seq.ranges()[1]);
        assert!(x.1 - x.0 > 50.0 && x.1 - x.0 < 1000.0, "{x:?}");
        assert!(y.1 - y.0 > 50.0 && y.1 - y.0 < 1000.0, "{y:?}");
        // Seeded: the same track twice.
        let p2 = d.path().join(format!("h{points}.csv"));
        k(&[
            "bench",
            "scale",
            "--frames",
            "500",
            "--points",
            &points.to_string(),
            "--generate",
            p2.to_str().unwrap(),
        ]);
        assert_eq!(std::fs::read(&p).unwrap(), std::fs::read(&p2).unwrap());
    }
}
