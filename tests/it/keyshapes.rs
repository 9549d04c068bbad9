//! Key-shape heuristics against their peers and through the command line: k-means++ as
//! linfa seeds it, and `kslab bench kmeans` on a real track (the rest is in the core's
//! oracles, `crates/keyshape-core/tests/oracles/keyshapes.rs`).
//! Here: what runs the `kslab` binary; the library's own tests are in `crates/keyshape-core/tests/linfa_kmeans.rs`.

/// `kslab bench kmeans` compares the two seedings on a real track: one row per clustered
/// axis count, an error ratio near 1 and a finite time ratio (its size is not asserted:
/// speed is for benchmarks); it refuses a single seed (no spread between seeds to report).
#[test]
fn bench_kmeans_compares_the_seedings_on_a_real_track() {
    let f = crate::common::shared("mediapipe_face_tracks/liveportrait_d18.csv");
    let f = f.to_str().unwrap();
    let r = crate::common::kslab(&["bench", "kmeans", f, "--seeds", "1,2,3", "--kmax", "8"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let rows: Vec<&str> = r
        .stdout
        .lines()
        .filter(|l| l.starts_with("| liveportrait_d18.csv"))
        .collect();
    assert_eq!(rows.len(), 2, "{}", r.stdout);
    for row in rows {
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        let ratio: f64 = cells[3].parse().unwrap();
        assert!((0.7..1.3).contains(&ratio), "{row}");
        let speed: f64 = cells[9].trim_end_matches('×').parse().unwrap();
        assert!(speed.is_finite() && speed > 0.0, "{row}");
    }
    let r = crate::common::kslab(&["bench", "kmeans", f, "--seeds", "1"]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("at least two seeds"), "{}", r.stderr);
}
