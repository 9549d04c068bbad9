//! Long tracks: greedy beyond the frames' Gram matrix (without it, subsampled, blocked
//! errors) chooses and reports what the exact path does.
//! (What runs the `kslab` binary is in `tests/it/scale.rs`.)

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_core::decompose::{prepare, PrepareOptions};
use keyshape_core::keyshapes::{greedy_gram, greedy_ls_feature_space, greedy_subsampled, Analysis};
use keyshape_core::solve::Solver;
use keyshape_io::{read_sequence, ReadOptions};

/// `../shared/data/<rel>` beside the repository.
fn shared(rel: &str) -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data")
        .join(rel)
}
fn analysis(file: &str, points: Option<&str>) -> Analysis {
    let seq = read_sequence(&shared(file), &ReadOptions::default()).unwrap();
    let prep = prepare(
        &seq,
        &PrepareOptions {
            points: points.map(String::from),
            align: true,
        },
    )
    .unwrap();
    Analysis::new(prep.seq.coords.clone(), prep.seq.points).unwrap()
}

const TRACKS: [(&str, Option<&str>); 5] = [
    ("mediapipe_face_tracks/liveportrait_d6.csv", Some("lips")),
    ("mediapipe_face_tracks/liveportrait_d6.csv", None),
    ("mediapipe_face_tracks/liveportrait_d9.csv", Some("lips")),
    (
        "mediapipe_face_tracks/pyfeat_wolfganglanger_pexels.csv",
        None,
    ),
    ("pyfeat_samples/news_sample_compact.csv", None),
];

#[test]
fn least_squares_greedy_without_the_gram_matrix_chooses_exactly_what_the_gram_path_does() {
    for (file, points) in TRACKS {
        let an = analysis(file, points);
        let (k1, e1) = greedy_gram(&an, 16, Solver::Ls, 8).unwrap();
        let (k2, e2) = greedy_ls_feature_space(&an, 16).unwrap();
        eprintln!("{file} {points:?}: {k1:?} {k2:?}");
        assert_eq!(k1, k2, "{file} {points:?}");
        for (a, b) in e1.iter().zip(&e2) {
            assert!((a - b).abs() <= 1e-9 * a.abs().max(1e-300), "{a} {b}");
        }
    }
}

#[test]
fn subsampled_greedy_reports_exact_errors_and_stays_near_the_exact_greedy() {
    for (file, points) in TRACKS {
        let an = analysis(file, points);
        for solver in [Solver::Nnls, Solver::Bounded] {
            let (_, exact) = greedy_gram(&an, 12, solver, 8).unwrap();
            let limit = an.frames() / 4;
            let (keys, sub) = greedy_subsampled(&an, 12, solver, 8, limit).unwrap();
            // Its errors are the exact errors of its keys on every frame.
            for k in 1..=12 {
                let e = an.weights_and_error(&keys[..k], solver).unwrap().1;
                assert_eq!(e, sub[k - 1]);
            }
            let ratio: Vec<f64> = exact.iter().zip(&sub).map(|(a, b)| b / a).collect();
            eprintln!(
                "{file} {points:?} {solver:?} 1/4 subsample / exact: {:.3?}",
                ratio
            );
        }
    }
}

/// Past the Gram matrix's limit, errors are summed block by block (never a keys × frames
/// matrix): the same value, bit for bit, as solving every frame at once, for every solver,
/// for key frames and for k-means' mean shapes.
#[test]
fn blocked_errors_on_long_tracks_equal_the_one_pass_errors() {
    use keyshape_core::keyshapes::{Heuristic, KMeans, GRAM_LIMIT};
    let mut text = Vec::new();
    keyshape_io::synthetic::write_long_track(&mut text, GRAM_LIMIT + 1500, 68, 3).unwrap();
    let seq = keyshape_io::parse_sequence(
        std::path::Path::new("long.csv"),
        std::str::from_utf8(&text).unwrap(),
        &ReadOptions::default(),
    )
    .unwrap();
    let prep = prepare(&seq, &PrepareOptions::all_aligned()).unwrap();
    let an = Analysis::new(prep.seq.coords.clone(), prep.seq.points).unwrap();
    assert!(an.frames() > GRAM_LIMIT);
    let keys: Vec<usize> = (0..9).map(|i| i * (an.frames() - 1) / 8).collect();
    for solver in [Solver::Ls, Solver::Nnls, Solver::Bounded] {
        let one = an.weights_and_error(&keys, solver).unwrap().1;
        let blocked = an.error(&keys, solver).unwrap();
        assert_eq!(
            one.to_bits(),
            blocked.to_bits(),
            "{solver:?}: {one} vs {blocked}"
        );
        let sel = KMeans {
            pcs: 2,
            seed: 1,
            mean: true,
            seeding: keyshape_core::keyshapes::kmeans::Seeding::LAB,
        }
        .select(&an, 6)
        .unwrap();
        let one = an.selection_weights_and_error(&sel, solver).unwrap().1;
        let blocked = an.selection_error(&sel, solver).unwrap();
        assert_eq!(
            one.to_bits(),
            blocked.to_bits(),
            "{solver:?} mean shapes: {one} vs {blocked}"
        );
    }
    // An out-of-range key is refused, not read past the end.
    assert!(an.error(&[0, an.frames()], Solver::Nnls).is_err());
}
