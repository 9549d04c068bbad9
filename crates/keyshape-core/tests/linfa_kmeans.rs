//! k-means with linfa's seeding is linfa's own ten-run fit (the other heuristics' oracles
//! are in `crates/keyshape-core/tests/oracles/keyshapes.rs`).
//! (What runs the `kslab` binary is in `tests/it/keyshapes.rs`.)

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_core::keyshapes::Analysis;

/// `../shared/data/<rel>` beside the repository.
fn shared(rel: &str) -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data")
        .join(rel)
}

/// `kmeans::fit_with(…, Seeding::LINFA)` draws the k-means++ starts itself (k passes over
/// the frames) and runs the restarts in parallel; it must give linfa's own 10-run fit on
/// real tracks, for several
/// axes, k and seeds: the same frame nearest each centre, the same cluster for every frame,
/// and centres bit for bit, except where two restarts ended in the same clusters with
/// inertias that differ in the last bits (linfa compares the sums, `fit` can only read them
/// divided by the frame count) — there the centres agree to 1e-9.
#[test]
fn kmeans_with_linfas_seeding_is_linfas_own_ten_run_fit() {
    use keyshape_core::decompose::{prepare, PrepareOptions};
    use keyshape_core::keyshapes::kmeans::{fit_with, Seeding};
    use keyshape_io::{read_sequence, ReadOptions};
    use linfa::prelude::*;
    use rand::SeedableRng;
    let files = [
        "mediapipe_face_tracks/liveportrait_d6.csv",
        "pyfeat_samples/news_sample_compact.csv",
        "pyfeat_samples/openface_test.csv",
    ];
    let (mut compared, mut exact) = (0, 0);
    for f in files {
        let seq = read_sequence(&shared(f), &ReadOptions::default()).unwrap();
        let prep = prepare(&seq, &PrepareOptions::all_aligned()).unwrap();
        let an = Analysis::new(prep.seq.coords.clone(), prep.seq.points).unwrap();
        for pcs in [1, 2, 3, 5] {
            let data = ndarray::Array2::from_shape_fn((an.frames(), pcs), |(t, a)| an.proj[(a, t)]);
            for (k, seed) in [(2, 7), (3, 0), (7, 7), (12, 123), (16, 7), (24, 9)] {
                let ours = fit_with(&data, k, seed, Seeding::LINFA).unwrap();
                let linfa = linfa_clustering::KMeans::params_with_rng(
                    k,
                    rand_xoshiro::Xoshiro256Plus::seed_from_u64(seed),
                )
                .n_runs(10)
                .max_n_iterations(300)
                .tolerance(1e-6)
                .fit(&DatasetBase::from(data.clone()))
                .unwrap();
                let theirs = linfa.centroids();
                let what = format!("{f}: {pcs} axes, k = {k}, seed {seed}");
                let dist = |c: &ndarray::Array2<f64>, i: usize, t: usize| -> f64 {
                    (0..pcs).map(|a| (c[(i, a)] - data[(t, a)]).powi(2)).sum()
                };
                let argmin = |n: usize, d: &dyn Fn(usize) -> f64| {
                    (0..n)
                        .min_by(|&i, &j| d(i).total_cmp(&d(j)).then(i.cmp(&j)))
                        .unwrap()
                };
                for c in 0..k {
                    assert_eq!(
                        argmin(an.frames(), &|t| dist(&ours, c, t)),
                        argmin(an.frames(), &|t| dist(theirs, c, t)),
                        "{what}: frame nearest centre {c}"
                    );
                }
                for t in 0..an.frames() {
                    assert_eq!(
                        argmin(k, &|c| dist(&ours, c, t)),
                        argmin(k, &|c| dist(theirs, c, t)),
                        "{what}: cluster of frame {t}"
                    );
                }
                let scale = data.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                let gap = (&ours - theirs).iter().fold(0.0f64, |m, x| m.max(x.abs()));
                assert!(gap <= 1e-9 * scale, "{what}: centres differ by {gap}");
                compared += 1;
                exact += usize::from(ours == theirs);
            }
        }
    }
    assert_eq!(compared, 3 * 4 * 6);
    eprintln!("k-means: {exact} of {compared} fits bit for bit linfa's");
    assert!(
        exact * 4 >= compared * 3,
        "only {exact} of {compared} fits bit for bit"
    );
}
