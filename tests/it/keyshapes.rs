//! Key-shape heuristics: their defining properties, on random and real shapes.

use keyshape_lab::keyshapes::{greedy_path, Analysis, KeyOptions, Method};
use keyshape_lab::solve::{SolveOptions, Solver};
use nalgebra::DMatrix;
use proptest::prelude::*;

/// Shapes: a base plus a few modes with random amplitudes, some frames repeated.
fn shapes() -> impl Strategy<Value = DMatrix<f64>> {
    (
        6usize..16,
        8usize..40,
        prop::collection::vec(-1.0f64..1.0, 16 * 3 + 40 * 3),
        any::<bool>(),
    )
        .prop_map(|(rows, frames, v, repeat)| {
            let rows = rows * 2;
            let mut q = DMatrix::from_fn(rows, frames, |i, t| {
                let base = (i as f64 * 0.7).sin() * 10.0;
                base + (0..3)
                    .map(|m| v[(i % 16) * 3 + m] * v[48 + (t % 40) * 3 + m] * (3.0 - m as f64))
                    .sum::<f64>()
            });
            if repeat {
                let c = q.column(0).clone_owned();
                q.set_column(frames - 1, &c);
            }
            q
        })
}

/// Full-rank shapes: a base plus independent noise on every coordinate of every frame, so
/// any 6 frames are independent and greedy's LS path is checked at every k.
fn full_rank_shapes() -> impl Strategy<Value = DMatrix<f64>> {
    (
        6usize..12,
        8usize..30,
        prop::collection::vec(-1.0f64..1.0, 24 * 30),
    )
        .prop_map(|(pts, frames, v)| {
            let rows = pts * 2;
            DMatrix::from_fn(rows, frames, |i, t| {
                (i as f64 * 0.7).sin() * 10.0 + v[(i * 30 + t) % v.len()]
            })
        })
}

fn all_methods() -> Vec<Method> {
    Method::ALL.to_vec()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(60))]

    #[test]
    fn no_method_returns_a_duplicate_frame(q in shapes(), k in 1usize..6) {
        let an = Analysis::new(q, 1).unwrap();
        prop_assume!(k <= an.distinct && an.proj.nrows() >= 3);
        for m in all_methods() {
            let sel = m.heuristic(&KeyOptions::default()).select(&an, k).unwrap();
            let mut c = sel.columns.clone();
            c.sort_unstable();
            c.dedup();
            prop_assert_eq!(c.len(), sel.columns.len(), "{} returned a frame twice", m);
            if m != Method::Hull {
                prop_assert_eq!(sel.columns.len(), k);
            }
        }
    }

    #[test]
    fn spread_takes_the_extremes_of_each_axis(q in shapes()) {
        let an = Analysis::new(q, 1).unwrap();
        prop_assume!(an.proj.nrows() >= 2 && an.distinct >= 4);
        let sel = Method::Spread.heuristic(&KeyOptions::default()).select(&an, 4).unwrap();
        for (i, want_max) in [(0, true), (1, false), (2, true), (3, false)] {
            let axis = i / 2;
            let row = an.proj.row(axis);
            let v = row[sel.columns[i]];
            // The pick is the extreme among the frames not already taken.
            let taken = &sel.columns[..i];
            let others = (0..an.frames()).filter(|c| !taken.contains(c)).map(|c| row[c]);
            let ext = if want_max { others.fold(f64::NEG_INFINITY, f64::max) } else { others.fold(f64::INFINITY, f64::min) };
            prop_assert_eq!(v, ext, "axis {} {}", axis, if want_max { "max" } else { "min" });
        }
    }

    #[test]
    fn every_frame_projects_inside_the_hull(q in shapes()) {
        let an = Analysis::new(q, 1).unwrap();
        prop_assume!(an.proj.nrows() >= 2);
        let sel = Method::Hull.heuristic(&KeyOptions::default()).select(&an, 0).unwrap();
        let p = |c: usize| (an.proj[(0, c)], an.proj[(1, c)]);
        let h: Vec<(f64, f64)> = sel.columns.iter().map(|&c| p(c)).collect();
        prop_assert!(h.len() >= 2);
        if h.len() >= 3 {
            let extent = an.proj.rows(0, 2).amax();
            // Hull corners come clockwise: every frame is right of (or on) every edge.
            for t in 0..an.frames() {
                let (x, y) = p(t);
                for i in 0..h.len() {
                    let (a, b) = (h[i], h[(i + 1) % h.len()]);
                    let cross = (b.0 - a.0) * (y - a.1) - (b.1 - a.1) * (x - a.0);
                    prop_assert!(cross <= 1e-9 * extent * extent, "frame {} outside edge {}: {}", t, i, cross);
                }
            }
        }
    }

    #[test]
    fn greedy_error_never_increases_with_k(q in full_rank_shapes(), solver in prop::sample::select(Solver::ALL.to_vec())) {
        let an = Analysis::new(q, 1).unwrap();
        prop_assert_eq!(an.distinct, an.frames());
        let kmax = 6;
        let (keys, errs) = greedy_path(&an, kmax, solver, 8).unwrap();
        prop_assert_eq!(keys.len(), kmax);
        prop_assert_eq!(errs.len(), kmax);
        let mut distinct = keys.clone();
        distinct.sort_unstable();
        distinct.dedup();
        prop_assert_eq!(distinct.len(), kmax, "a frame chosen twice: {:?}", keys);
        for w in errs.windows(2) {
            prop_assert!(w[1] <= w[0] * (1.0 + 1e-9) + 1e-9, "{:?}", errs);
        }
        if solver == Solver::Ls {
            // With independent frames every LS step strictly lowers the error, and each
            // reported error is the error of its keys.
            for w in errs.windows(2) {
                prop_assert!(w[1] < w[0], "{:?}", errs);
            }
        }
        for (j, e) in errs.iter().enumerate() {
            let direct = an.error(&keys[..=j], solver).unwrap();
            prop_assert!((direct - e).abs() <= 1e-9 * e.max(1.0), "k={}: path {} vs direct {}", j + 1, e, direct);
        }
    }

    #[test]
    fn gram_path_error_equals_the_direct_residual(q in shapes(), solver in prop::sample::select(Solver::ALL.to_vec())) {
        let an = Analysis::new(q.clone(), 1).unwrap();
        prop_assume!(an.distinct >= 3);
        let keys = Method::Spread.heuristic(&KeyOptions::default()).select(&an, 3).unwrap().columns;
        let e = an.error(&keys, solver).unwrap();
        let d = keyshape_lab::decompose::decompose(&q, 1, &keys, None, &SolveOptions::new(solver)).unwrap();
        let direct = d.total_sq_error();
        let scale = q.norm_squared();
        prop_assert!((e - direct).abs() <= 1e-8 * scale + 1e-9, "gram {e} vs direct {direct}");
    }
}

#[test]
fn kmeans_heuristics_are_named_as_the_cli_names_them() {
    use keyshape_lab::keyshapes::kmeans::{KMeans, Seeding};
    use keyshape_lab::keyshapes::Heuristic;
    let h = |pcs, mean| KMeans {
        pcs,
        seed: 7,
        mean,
        seeding: Seeding::LAB,
    };
    assert_eq!(h(2, false).name(), "kmeans2");
    assert_eq!(h(3, true).name(), "kmeans3-mean");
    for m in Method::ALL {
        assert_eq!(m.heuristic(&KeyOptions::default()).name(), m.name());
    }
}

#[test]
fn kmeans_is_deterministic_for_a_seed_and_differs_across_seeds() {
    let seq = keyshape_lab::io::builtin_sequence().unwrap();
    let an = Analysis::new(seq.coords, seq.points).unwrap();
    let pick = |seed| {
        Method::KMeans {
            pcs: 3,
            mean: false,
        }
        .heuristic(&KeyOptions {
            seed,
            ..KeyOptions::default()
        })
        .select(&an, 10)
        .unwrap()
    };
    assert_eq!(pick(7), pick(7));
    // Another seed gives other clusters on this sequence (k-means++ starts differ).
    assert!(
        (8..20).any(|seed| pick(seed).columns != pick(7).columns),
        "no seed in 8..20 changes the k-means keys"
    );
    let centres = pick(7).centres.unwrap();
    assert_eq!(centres.shape(), (3, 10));
}

#[test]
fn asking_for_more_keys_than_distinct_shapes_is_a_clear_error() {
    let base = DMatrix::from_fn(6, 4, |i, t| (i * 3 + t * 7) as f64 % 5.0);
    let q = DMatrix::from_fn(6, 12, |i, t| base[(i, t % 4)]);
    let an = Analysis::new(q, 3).unwrap();
    assert_eq!(an.distinct, 4);
    for m in [
        Method::Spread,
        Method::KMeans {
            pcs: 2,
            mean: false,
        },
        Method::Greedy,
        Method::Random,
    ] {
        let e = m
            .heuristic(&KeyOptions::default())
            .select(&an, 5)
            .unwrap_err()
            .to_string();
        assert!(e.contains("only 4 distinct shapes"), "{m}: {e}");
    }
}

#[test]
fn hull_handles_collinear_and_duplicate_projections() {
    // Every frame a multiple of one direction: the projections lie on a line.
    let dir = DMatrix::from_fn(8, 1, |i, _| i as f64 - 3.5);
    let q = DMatrix::from_fn(8, 9, |i, t| {
        100.0 + dir[(i, 0)] * [0.0, 1.0, 2.0, 2.0, 3.0, 1.5, 0.5, 3.0, 1.0][t]
    });
    let an = Analysis::new(q, 4).unwrap();
    let sel = Method::Hull
        .heuristic(&KeyOptions::default())
        .select(&an, 0)
        .unwrap();
    let mut c = sel.columns.clone();
    c.sort_unstable();
    assert_eq!(
        c,
        vec![0, 4],
        "the two ends, lowest index of the duplicates"
    );
}

#[test]
fn fig6_shape_holds_on_real_lips_spread_is_nested_and_decreasing() {
    let seq = keyshape_lab::io::builtin_sequence().unwrap();
    let prep = keyshape_lab::decompose::prepare(
        &seq,
        &keyshape_lab::decompose::PrepareOptions {
            points: Some("lips".into()),
            align: true,
        },
    )
    .unwrap();
    let an = Analysis::new(prep.seq.coords, prep.seq.points).unwrap();
    let mut prev = f64::INFINITY;
    let mut prev_keys: Vec<usize> = Vec::new();
    for k in 2..=16 {
        let keys = Method::Spread
            .heuristic(&KeyOptions::default())
            .select(&an, k)
            .unwrap()
            .columns;
        assert!(
            prev_keys.iter().all(|c| keys.contains(c)),
            "spread sets are nested"
        );
        let e = an.error(&keys, Solver::Nnls).unwrap();
        assert!(e <= prev * (1.0 + 1e-12));
        prev = e;
        prev_keys = keys;
    }
    // Every heuristic beats the random floor at k = 12 on this track.
    let floor = an
        .error(
            &Method::Random
                .heuristic(&KeyOptions::default())
                .select(&an, 12)
                .unwrap()
                .columns,
            Solver::Nnls,
        )
        .unwrap();
    for m in [
        Method::Spread,
        Method::KMeans {
            pcs: 2,
            mean: false,
        },
        Method::KMeans {
            pcs: 3,
            mean: false,
        },
        Method::Greedy,
    ] {
        let e = an
            .error(
                &m.heuristic(&KeyOptions::default())
                    .select(&an, 12)
                    .unwrap()
                    .columns,
                Solver::Nnls,
            )
            .unwrap();
        assert!(e < floor, "{m}: {e} not below random {floor}");
    }
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
    use keyshape_lab::decompose::{prepare, PrepareOptions};
    use keyshape_lab::io::{read_sequence, ReadOptions};
    use keyshape_lab::keyshapes::kmeans::{fit_with, Seeding};
    use linfa::prelude::*;
    use rand::SeedableRng;
    let files = [
        "mediapipe_face_tracks/liveportrait_d6.csv",
        "pyfeat_samples/news_sample_compact.csv",
        "pyfeat_samples/openface_test.csv",
    ];
    let (mut compared, mut exact) = (0, 0);
    for f in files {
        let seq = read_sequence(&crate::common::shared(f), &ReadOptions::default()).unwrap();
        let prep = prepare(
            &seq,
            &PrepareOptions {
                points: None,
                align: true,
            },
        )
        .unwrap();
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

/// Greedy k-means++ against brute force: replaying the same generator, each centre must be,
/// of the candidates drawn for it (with probability proportional to the squared distance
/// to the nearest centre so far, recomputed here from every chosen centre), the one leaving
/// the lowest sum of squared distances to the nearest centre. With one trial it is plain
/// k-means++; with more, the start's potential is lower on average over seeds.
#[test]
fn greedy_kmeans_plusplus_keeps_the_best_of_its_candidates() {
    use keyshape_lab::keyshapes::kmeans::kmeans_plusplus;
    use rand::distributions::{Distribution, WeightedIndex};
    use rand::SeedableRng;
    use rand_xoshiro::Xoshiro256Plus;
    let seq = keyshape_lab::io::builtin_sequence().unwrap();
    let an = Analysis::new(seq.coords, seq.points).unwrap();
    let data = ndarray::Array2::from_shape_fn((an.frames(), 3), |(t, a)| an.proj[(a, t)]);
    let d =
        |i: usize, t: usize| -> f64 { (0..3).map(|a| (data[(i, a)] - data[(t, a)]).powi(2)).sum() };
    let nearest = |chosen: &[usize]| -> Vec<f64> {
        (0..data.nrows())
            .map(|t| {
                chosen
                    .iter()
                    .map(|&c| d(c, t))
                    .fold(f64::INFINITY, f64::min)
            })
            .collect()
    };
    let potential = |chosen: &[usize]| nearest(chosen).iter().sum::<f64>();
    let (mut pot1, mut pot5) = (0.0, 0.0);
    for seed in 0..20 {
        for (k, trials) in [(6, 1), (6, 4), (12, 5)] {
            let got = kmeans_plusplus(&data, k, trials, &mut Xoshiro256Plus::seed_from_u64(seed))
                .unwrap();
            let mut rng = Xoshiro256Plus::seed_from_u64(seed);
            let first = WeightedIndex::new(vec![1.0; data.nrows()])
                .unwrap()
                .sample(&mut rng);
            let mut want = vec![first];
            while want.len() < k {
                let w = WeightedIndex::new(nearest(&want)).unwrap();
                let cands: Vec<usize> = (0..trials).map(|_| w.sample(&mut rng)).collect();
                let score = |c: usize| {
                    let mut v = want.clone();
                    v.push(c);
                    potential(&v)
                };
                // The first candidate with the lowest potential.
                let best = cands
                    .iter()
                    .copied()
                    .fold(None, |b: Option<usize>, c| match b {
                        Some(b) if score(b) <= score(c) => Some(b),
                        _ => Some(c),
                    });
                want.push(best.unwrap());
            }
            assert_eq!(got, want, "seed {seed}, k = {k}, {trials} trials");
            if k == 12 {
                pot5 += potential(&got);
                let plain =
                    kmeans_plusplus(&data, k, 1, &mut Xoshiro256Plus::seed_from_u64(seed)).unwrap();
                pot1 += potential(&plain);
            }
        }
    }
    assert!(
        pot5 < 0.8 * pot1,
        "greedy starts {pot5} against plain {pot1}"
    );
    // Ties: on three points in a line, −1 and +1 leave the same potential once 0 is a
    // centre, so the first drawn must win (as the brute force above takes the first).
    let line = ndarray::Array2::from_shape_vec((3, 1), vec![-1.0, 0.0, 1.0]).unwrap();
    let mut ties = 0;
    for seed in 0..64 {
        let mut rng = Xoshiro256Plus::seed_from_u64(seed);
        let first = WeightedIndex::new(vec![1.0; 3]).unwrap().sample(&mut rng);
        if first != 1 {
            continue;
        }
        let w = WeightedIndex::new(vec![1.0, 0.0, 1.0]).unwrap();
        let cands: Vec<usize> = (0..3).map(|_| w.sample(&mut rng)).collect();
        let got = kmeans_plusplus(&line, 2, 3, &mut Xoshiro256Plus::seed_from_u64(seed)).unwrap();
        assert_eq!(got, vec![1, cands[0]], "seed {seed}: candidates {cands:?}");
        ties += usize::from(cands.iter().any(|&c| c != cands[0]));
    }
    assert!(ties > 3, "only {ties} seeds drew both ends");
}

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
