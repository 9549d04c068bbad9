//! Key-shape heuristics: their defining properties, on random and real shapes.

use keyshape_core::keyshapes::{greedy_path, Analysis, KeyOptions, Method};
use keyshape_core::solve::{SolveOptions, Solver};
use keyshape_core::ErrorKind;
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
        let d = keyshape_core::decompose::decompose_coords(&q, 1, &keys, None, &SolveOptions::new(solver)).unwrap();
        let direct = d.total_sq_error();
        let scale = q.norm_squared();
        prop_assert!((e - direct).abs() <= 1e-8 * scale + 1e-9, "gram {e} vs direct {direct}");
    }
}

#[test]
fn kmeans_heuristics_are_named_as_the_cli_names_them() {
    use keyshape_core::keyshapes::kmeans::{KMeans, Seeding};
    use keyshape_core::keyshapes::Heuristic;
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
    let seq = keyshape_io::builtin_sequence().unwrap();
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
            .kind_is(ErrorKind::Setting);
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
    let seq = keyshape_io::builtin_sequence().unwrap();
    let prep = keyshape_core::decompose::prepare(
        &seq,
        &keyshape_core::decompose::PrepareOptions::group_aligned("lips"),
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

/// Greedy k-means++ against brute force: replaying the same generator, each centre must be,
/// of the candidates drawn for it (with probability proportional to the squared distance
/// to the nearest centre so far, recomputed here from every chosen centre), the one leaving
/// the lowest sum of squared distances to the nearest centre. With one trial it is plain
/// k-means++; with more, the start's potential is lower on average over seeds.
#[test]
fn greedy_kmeans_plusplus_keeps_the_best_of_its_candidates() {
    use keyshape_core::keyshapes::kmeans::kmeans_plusplus;
    use rand::distributions::{Distribution, WeightedIndex};
    use rand::SeedableRng;
    use rand_xoshiro::Xoshiro256Plus;
    let seq = keyshape_io::builtin_sequence().unwrap();
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

/// An analysis whose first two principal coordinates are set by hand to `pts` (the hull
/// reads only the projection), so the hull's cases can be built exactly.
fn with_projection(pts: &[(f64, f64)]) -> Analysis {
    let n = pts.len();
    let q = DMatrix::from_fn(6, n, |i, t| ((i * 7 + t * 3) % 11) as f64 + t as f64);
    let mut an = Analysis::new(q, 3).unwrap();
    an.proj = DMatrix::from_fn(2, n, |r, t| if r == 0 { pts[t].0 } else { pts[t].1 });
    an
}

fn hull_of(pts: &[(f64, f64)]) -> keyshape_core::error::Result<Vec<usize>> {
    Method::Hull
        .heuristic(&KeyOptions::default())
        .select(&with_projection(pts), 0)
        .map(|s| s.columns)
}

fn sorted(mut v: Vec<usize>) -> Vec<usize> {
    v.sort_unstable();
    v
}

#[test]
fn hull_keeps_strict_corners_only_of_an_axis_aligned_rectangle() {
    // Corners 0–3; 4 and 5 on edges, 6 inside. Axis-aligned neighbours differ on one
    // coordinate only, so a distance that multiplies the two differences would merge them.
    let pts = [
        (-10.0, -1.0),
        (10.0, -1.0),
        (10.0, 1.0),
        (-10.0, 1.0),
        (0.0, -1.0),
        (10.0, 0.5),
        (1.0, 0.0),
    ];
    assert_eq!(sorted(hull_of(&pts).unwrap()), vec![0, 1, 2, 3]);
    // The same transposed: the long side on the other axis.
    let t: Vec<(f64, f64)> = pts.iter().map(|&(x, y)| (y, x)).collect();
    assert_eq!(sorted(hull_of(&t).unwrap()), vec![0, 1, 2, 3]);
    // A triangle is its three corners.
    assert_eq!(
        sorted(hull_of(&[(0.0, 0.0), (4.0, 0.0), (1.0, 3.0)]).unwrap()),
        vec![0, 1, 2]
    );
}

#[test]
fn hull_merges_corners_closer_than_1e_9_of_the_extent_and_no_others() {
    // A 20 × 2 rectangle (extent 20, so corners closer than 2e-8 count once) with corner c
    // doubled by a point just outside it, diagonally: both are corners of the exact hull.
    // The extent is the larger side, whichever axis it lies on; the doubled corner is
    // tried at each of the four corners (so once where the hull's ring starts and ends).
    let rect: [(f64, f64); 4] = [(-10.0, -1.0), (10.0, -1.0), (10.0, 1.0), (-10.0, 1.0)];
    for transpose in [false, true] {
        for c in 0..4 {
            for (delta, merged) in [(0.7e-8, true), (2e-8, false)] {
                let (sx, sy) = (rect[c].0.signum(), rect[c].1.signum());
                // Out along x, in along y: a corner of its own, 1.41 δ from corner c.
                let extra = (rect[c].0 + sx * delta, rect[c].1 - sy * delta);
                let mut pts: Vec<(f64, f64)> = rect.to_vec();
                pts.push(extra);
                if transpose {
                    pts = pts.iter().map(|&(x, y)| (y, x)).collect();
                }
                let got = sorted(hull_of(&pts).unwrap());
                let at = format!("δ = {delta}, corner {c}, transposed {transpose}: {got:?}");
                if merged {
                    // One of the pair, whichever the ring meets first, and the other three.
                    assert_eq!(got.len(), 4, "{at}");
                    assert!((0..4).filter(|&i| i != c).all(|i| got.contains(&i)), "{at}");
                } else {
                    assert_eq!(got, vec![0, 1, 2, 3, 4], "{at}");
                }
            }
        }
    }
}

/// Exactly at the tolerance the corners merge: a square of side 5·10⁹ (tolerance
/// 1e-9 · 5e9 = 5.0 exactly in f64; large enough sides that both corners of the pair are
/// strict) with a second corner (−3, −4) — 5.0 exactly — from corner 1.
#[test]
fn hull_merges_corners_exactly_at_the_tolerance() {
    let side = 5e9;
    let pts = [
        (0.0, 0.0),
        (side, 0.0),
        (side, side - 4.0),
        (0.0, side - 4.0),
        (side - 3.0, -4.0),
    ];
    let got = sorted(hull_of(&pts).unwrap());
    assert_eq!(got.len(), 4, "{got:?}");
    assert!([0, 2, 3].iter().all(|i| got.contains(i)), "{got:?}");
    // Twice as far (10 apart; the extent grows by 4, the tolerance to 5.000000004): both.
    let mut far = pts;
    far[4] = (side - 6.0, -8.0);
    assert_eq!(sorted(hull_of(&far).unwrap()), vec![0, 1, 2, 3, 4]);
}

/// A square turned 45° with a frame on the middle of each edge and one inside: the four
/// corners only. Tilted edges matter: on an axis-aligned hull one of the cross product's
/// two terms is always zero, so a sign slip between them goes unseen.
#[test]
fn hull_of_a_tilted_square_drops_the_frames_on_its_edges() {
    let pts = [
        (0.0, -10.0),
        (10.0, 0.0),
        (0.0, 10.0),
        (-10.0, 0.0),
        (5.0, -5.0),
        (5.0, 5.0),
        (-5.0, 5.0),
        (-5.0, -5.0),
        (0.0, 0.0),
    ];
    assert_eq!(sorted(hull_of(&pts).unwrap()), vec![0, 1, 2, 3]);
}

/// A turn exactly at the collinearity tolerance is not a corner: extent 10⁶ (tolerance
/// 1e-12 · 1e6 · 1e6 = 1.0 exactly) and frame 1 turning the hull by a cross product of
/// exactly 1 between its ring neighbours 0 and 2 (2 lies on the bottom edge).
#[test]
fn hull_drops_a_turn_exactly_at_the_collinearity_tolerance() {
    let m = 1e6;
    let pts = [
        (0.0, 0.0),
        (1.0, -1.0),
        (2.0, -1.0),
        (m, -1.0),
        (m, m - 1.0),
        (0.0, m - 1.0),
    ];
    assert_eq!(sorted(hull_of(&pts).unwrap()), vec![0, 3, 4, 5]);
    // Twice the turn (frame 1 at (2, −2), the bottom edge at y = −2): a corner.
    let pts = [
        (0.0, 0.0),
        (2.0, -2.0),
        (4.0, -2.0),
        (m, -2.0),
        (m, m - 2.0),
        (0.0, m - 2.0),
    ];
    assert_eq!(sorted(hull_of(&pts).unwrap()), vec![0, 1, 3, 4, 5]);
}

#[test]
fn hull_of_a_thin_triangle_within_tolerance_of_a_line_is_the_lines_two_ends() {
    // The apex is 1e-13 of the extent off the base: within the collinearity tolerance, so
    // no corner is strict. The hull is then the two ends of the line, as for an exact line.
    let pts = [(0.0, 0.0), (3.0, 1e-12), (10.0, 0.0), (6.0, 0.0)];
    assert_eq!(sorted(hull_of(&pts).unwrap()), vec![0, 2]);
    // Corners merged down to two (the apex within 1e-9 of the extent of a base end).
    let pts = [(0.0, 0.0), (10.0, 0.0), (10.0 - 1e-9, 1e-9)];
    assert_eq!(sorted(hull_of(&pts).unwrap()), vec![0, 1]);
}

#[test]
fn hull_of_an_exact_line_reports_the_end_near_frame_0_then_the_far_end() {
    // Exactly collinear on a tilted line y = 3 − 2x (small integers: spade's exact
    // predicates see a line). Frame 0 (x = −1) is inside the segment; frame 1 (x = 5) is
    // farther from it than frame 3 (x = −4), so the ends come as [3, 1]: the end farther
    // from frame 0 last, and of its duplicates (frames 1 and 5) the lowest.
    let line = |x: f64| (x, 3.0 - 2.0 * x);
    let pts = [
        line(-1.0),
        line(5.0),
        line(2.0),
        line(-4.0),
        line(0.0),
        line(5.0),
    ];
    assert_eq!(hull_of(&pts).unwrap(), vec![3, 1]);
    // Frame 0 at an end: it is reported first, the far end (the lowest of its duplicates) second.
    let pts = [line(-4.0), line(5.0), line(2.0), line(-1.0), line(5.0)];
    assert_eq!(hull_of(&pts).unwrap(), vec![0, 1]);
    // Mirrored (x → −x): frame 1 (x = −5) is the far end again.
    let pts = [line(1.0), line(-5.0), line(-2.0), line(4.0), line(0.0)];
    assert_eq!(hull_of(&pts).unwrap(), vec![3, 1]);
    // Two frames only.
    assert_eq!(hull_of(&[line(2.0), line(-3.0)]).unwrap(), vec![0, 1]);
}

/// Lines parallel to an axis, away from the origin, with the far end on the negative side
/// of frame 0: the ends are ordered by the direction from frame 0 to the far end (a sum
/// where a difference belongs flips it, since both coordinates are positive; a vertical line
/// has no x-extent, so a quotient by it is 0/0), and the far end comes second.
#[test]
fn hull_of_an_axis_parallel_line_orders_its_ends_by_the_direction_to_the_far_end() {
    let at = [10.0, 9.5, 8.0, 10.5, 9.0];
    let horizontal: Vec<(f64, f64)> = at.iter().map(|&x| (x, 4.0)).collect();
    assert_eq!(hull_of(&horizontal).unwrap(), vec![3, 2]);
    let vertical: Vec<(f64, f64)> = at.iter().map(|&y| (4.0, y)).collect();
    assert_eq!(hull_of(&vertical).unwrap(), vec![3, 2]);
    // On the axes themselves (no offset) and far end on the positive side.
    let up: Vec<(f64, f64)> = at.iter().map(|&y| (0.0, 20.0 - y)).collect();
    assert_eq!(hull_of(&up).unwrap(), vec![3, 2]);
}

#[test]
fn hull_refuses_a_sequence_whose_frames_project_to_one_point() {
    for p in [(0.0, 0.0), (2.5, -1.0)] {
        let e = hull_of(&[p, p, p]).unwrap_err().kind_is(ErrorKind::Unfit);
        assert!(e.contains("every frame projects to the same point"), "{e}");
    }
}

/// The builtin sequence's lips, aligned: the analysis the error-curve tests sweep.
fn builtin_lips() -> Analysis {
    let seq = keyshape_io::builtin_sequence().unwrap();
    let prep = keyshape_core::decompose::prepare(
        &seq,
        &keyshape_core::decompose::PrepareOptions::group_aligned("lips"),
    )
    .unwrap();
    Analysis::new(prep.seq.coords, prep.seq.points).unwrap()
}

#[test]
fn sweep_refuses_an_empty_k_range_and_sweeps_a_single_k() {
    use keyshape_core::keyshapes::curves::sweep;
    let an = builtin_lips();
    let opts = KeyOptions::default();
    let run = |ks| sweep(&an, &[Method::Spread], ks, &[Solver::Ls], &opts, &|_, _| {});
    // `RangeInclusive::new(4, 3)`: an empty range, spelled so clippy lets it be.
    for (lo, hi) in [(0, 3), (4, 3), (0, 0)] {
        let e = run(std::ops::RangeInclusive::new(lo, hi))
            .unwrap_err()
            .kind_is(ErrorKind::Setting);
        assert!(
            e.contains(&format!("k range {lo}..{hi} is empty or starts at 0")),
            "{e}"
        );
    }
    let rows = run(3..=3).unwrap();
    assert_eq!(rows.len(), 1);
    assert_eq!((rows[0].method.as_str(), rows[0].k), ("spread", 3));
    let direct = an.error(&rows[0].keys, Solver::Ls).unwrap();
    assert_eq!(rows[0].total_sq_error, direct);
}

#[test]
fn sweep_ticks_once_per_curve_with_the_count_of_curves() {
    use keyshape_core::keyshapes::curves::sweep;
    let an = builtin_lips();
    let ticks = std::sync::Mutex::new(Vec::new());
    let methods = [Method::Spread, Method::Hull, Method::Greedy];
    let solvers = [Solver::Ls, Solver::Nnls];
    let rows = sweep(
        &an,
        &methods,
        2..=4,
        &solvers,
        &KeyOptions::default(),
        &|done, total| ticks.lock().unwrap().push((done, total)),
    )
    .unwrap();
    let mut t = ticks.into_inner().unwrap();
    t.sort_unstable();
    let want: Vec<(usize, usize)> = (1..=6).map(|d| (d, 6)).collect();
    assert_eq!(t, want);
    // Rows by solver, then method, k ascending; hull one row at its own k.
    let got: Vec<(String, String, usize)> = rows
        .iter()
        .map(|r| (r.solver.clone(), r.method.clone(), r.k))
        .collect();
    let hull_k = Method::Hull
        .heuristic(&KeyOptions::default())
        .select(&an, 0)
        .unwrap()
        .columns
        .len();
    let mut want = Vec::new();
    for s in ["ls", "nnls"] {
        for (m, ks) in [
            ("spread", 2..=4),
            ("hull", hull_k..=hull_k),
            ("greedy", 2..=4),
        ] {
            want.extend(ks.map(|k| (s.to_string(), m.to_string(), k)));
        }
    }
    assert_eq!(got, want);
}

#[test]
fn sweep_random_averages_its_seeded_draws_and_reports_the_first_draws_keys() {
    use keyshape_core::keyshapes::curves::{sweep, RANDOM_DRAWS};
    let an = builtin_lips();
    let opts = KeyOptions {
        seed: 11,
        ..KeyOptions::default()
    };
    let rows = sweep(
        &an,
        &[Method::Random],
        3..=5,
        &[Solver::Nnls],
        &opts,
        &|_, _| {},
    )
    .unwrap();
    assert_eq!(rows.len(), 3);
    for r in &rows {
        let draw = |d: u64| {
            let o = KeyOptions {
                seed: 11 + d,
                ..opts
            };
            Method::Random
                .heuristic(&o)
                .select(&an, r.k)
                .unwrap()
                .columns
        };
        assert_eq!(r.keys, draw(0), "k = {}", r.k);
        assert_ne!(draw(0), draw(RANDOM_DRAWS - 1), "k = {}", r.k);
        let mean = (0..RANDOM_DRAWS)
            .map(|d| an.error(&draw(d), Solver::Nnls).unwrap())
            .sum::<f64>()
            / RANDOM_DRAWS as f64;
        assert!(
            (r.total_sq_error - mean).abs() <= 1e-12 * mean,
            "k = {}",
            r.k
        );
        assert!((r.rms - an.rms(mean)).abs() <= 1e-12 * r.rms, "k = {}", r.k);
    }
}

#[test]
fn eq5_refuses_no_keys_and_keys_out_of_range_on_both_paths() {
    use keyshape_core::keyshapes::{Selection, GRAM_LIMIT};
    // Short (the frames' Gram matrix) and long (block-wise products) tracks.
    for frames in [40, GRAM_LIMIT + 1] {
        let q = DMatrix::from_fn(8, frames, |i, t| ((i * 13 + t * 7) % 17) as f64 + i as f64);
        let an = Analysis::new(q, 4).unwrap();
        for s in Solver::ALL {
            let e = an.error(&[], s).unwrap_err().kind_is(ErrorKind::Invalid);
            assert!(e.contains("no key shapes"), "{frames} frames, {s}: {e}");
            let e = an
                .weights_and_error(&[], s)
                .unwrap_err()
                .kind_is(ErrorKind::Invalid);
            assert!(e.contains("no key shapes"), "{e}");
            let e = an
                .selection_error(&Selection::frames(vec![]), s)
                .unwrap_err()
                .kind_is(ErrorKind::Invalid);
            assert!(e.contains("no key shapes"), "{e}");
            let want = format!("key column {frames} out of range (0..{frames})");
            for keys in [vec![frames], vec![0, frames, 1]] {
                let e = an.error(&keys, s).unwrap_err().kind_is(ErrorKind::Invalid);
                assert!(e.contains(&want), "{frames} frames, {s}: {e}");
                let e = an
                    .weights_and_error(&keys, s)
                    .unwrap_err()
                    .kind_is(ErrorKind::Invalid);
                assert!(e.contains(&want), "{e}");
            }
            // The last frame is in range.
            assert!(an.error(&[frames - 1], s).unwrap() > 0.0);
        }
    }
}

/// Greedy against brute force on 30 real frames (the built-in lips, every fifth frame):
/// at each step every remaining frame is tried as the next key and Eq. (5) computed
/// directly. Least squares and the constrained solvers with `shortlist = 0` must take the
/// best of all; with a shortlist of 3 the constrained greedy must take the best of the 3
/// frames whose one-variable gain — `Σ_t max_{a ∈ [0, u]} 2a⟨r_t, q_c⟩ − a²‖q_c‖²` with
/// `r_t` the frame's residual under the keys so far, computed here from the coordinates —
/// is largest.
#[test]
fn greedy_takes_the_brute_force_best_frame_at_each_step_and_ranks_its_shortlist_by_the_bound() {
    use keyshape_core::keyshapes::greedy_gram;
    let full = builtin_lips();
    let cols: Vec<usize> = (0..full.frames()).step_by(5).take(30).collect();
    // And the same frames scaled by 1–4, so weights above 1 matter: bounded's bound clips
    // the one-variable gain where nnls's does not.
    let mut scaled = full.coords.select_columns(&cols);
    for (t, mut c) in scaled.column_iter_mut().enumerate() {
        c *= 1.0 + (t % 4) as f64;
    }
    for q in [full.coords.select_columns(&cols), scaled] {
        let an = Analysis::new(q, full.points).unwrap();
        let q = &an.coords;
        let n = an.frames();
        for solver in Solver::ALL {
            for shortlist in [0usize, 1, 3] {
                if solver == Solver::Ls && shortlist > 0 {
                    continue; // LS ranks by its exact gain: no shortlist.
                }
                let (keys, errs) = greedy_gram(&an, 5, solver, shortlist).unwrap();
                for j in 0..5 {
                    let before = &keys[..j];
                    let trial = |c: usize| {
                        let mut k = before.to_vec();
                        k.push(c);
                        an.error(&k, solver).unwrap()
                    };
                    let mut pool: Vec<usize> = (0..n).filter(|c| !before.contains(c)).collect();
                    if shortlist > 0 {
                        let upper = if solver == Solver::Bounded {
                            1.0
                        } else {
                            f64::INFINITY
                        };
                        // Residuals under the keys so far (the frames themselves before any).
                        let r = if j == 0 {
                            q.clone()
                        } else {
                            let (w, _) = an.weights_and_error(before, solver).unwrap();
                            q - q.select_columns(before) * &w
                        };
                        let bound = |c: usize| {
                            let qc = q.column(c);
                            let qq = qc.norm_squared();
                            (0..n)
                                .map(|t| {
                                    let rc = qc.dot(&r.column(t));
                                    let a = (rc / qq).clamp(0.0, upper);
                                    2.0 * a * rc - a * a * qq
                                })
                                .sum::<f64>()
                        };
                        pool.sort_by(|&a, &b| bound(b).total_cmp(&bound(a)).then(a.cmp(&b)));
                        pool.truncate(shortlist);
                    }
                    let best = pool.iter().map(|&c| trial(c)).fold(f64::INFINITY, f64::min);
                    let got = trial(keys[j]);
                    assert!(
                        pool.contains(&keys[j]),
                        "{solver} shortlist {shortlist} step {j}: {} not in {pool:?}",
                        keys[j]
                    );
                    assert!(
                        got <= best * (1.0 + 1e-9),
                        "{solver} shortlist {shortlist} step {j}: took {} ({got}), best {best}",
                        keys[j]
                    );
                    assert!((errs[j] - got).abs() <= 1e-9 * got, "{solver} step {j}");
                }
            }
        }
    }
}

/// Five distinct frames spanning three dimensions (frames 3 and 4 are sums of the first
/// three): least-squares greedy, on each path, takes three keys and then refuses a fourth by
/// name rather than add a frame the keys already span. Under nnls and bounded weights a
/// dependent frame is a real key (f0 = f3 − f1 needs a negative weight), so they go on to
/// five keys, the error never rising — and for nnls falling at the fourth.
#[test]
fn greedy_least_squares_refuses_more_keys_than_the_frames_span() {
    use keyshape_core::keyshapes::{greedy_gram, greedy_ls_feature_space, greedy_subsampled};
    let base = DMatrix::from_fn(8, 3, |i, j| ((i * 5 + j * 3) % 7) as f64 - 2.5 + j as f64);
    let mut q = DMatrix::zeros(8, 5);
    for j in 0..3 {
        q.set_column(j, &base.column(j));
    }
    q.set_column(3, &(base.column(0) + base.column(1)));
    q.set_column(4, &(base.column(1) + base.column(2) * 2.0));
    let an = Analysis::new(q, 4).unwrap();
    assert_eq!(an.distinct, 5);
    let want = "greedy: only 3 linearly independent shapes, 4 asked for";
    let check = |r: keyshape_core::error::Result<(Vec<usize>, Vec<f64>)>, what: &str| {
        let e = r.unwrap_err().kind_is(ErrorKind::Unfit);
        assert!(e.contains(want), "{what}: {e}");
    };
    let (keys, errs) = greedy_gram(&an, 3, Solver::Ls, 0).unwrap();
    assert_eq!(keys.len(), 3);
    assert!(errs[2] <= 1e-9 * errs[0], "{errs:?}");
    check(greedy_gram(&an, 4, Solver::Ls, 0), "gram");
    check(greedy_subsampled(&an, 4, Solver::Ls, 0, 5), "subsampled");
    let (keys, errs) = greedy_ls_feature_space(&an, 3).unwrap();
    assert_eq!(keys.len(), 3);
    assert!(errs[2] <= 1e-9 * errs[0], "{errs:?}");
    check(greedy_ls_feature_space(&an, 4), "feature space");
    for solver in [Solver::Nnls, Solver::Bounded] {
        let (keys, errs) = greedy_gram(&an, 5, solver, 0).unwrap();
        assert_eq!(sorted(keys), vec![0, 1, 2, 3, 4], "{solver}");
        assert!(
            errs.windows(2).all(|w| w[1] <= w[0] * (1.0 + 1e-12)),
            "{solver}: {errs:?}"
        );
        if solver == Solver::Nnls {
            assert!(errs[3] < 0.5 * errs[2], "{errs:?}");
        }
    }
}

/// Identical frames tie exactly (the same bits in, the same gain and error out): greedy
/// takes the earliest. The built-in lips' 30 frames with a copy of greedy's first choice
/// appended, and a copy placed before it, under every solver.
#[test]
fn greedy_takes_the_earliest_of_identical_frames() {
    use keyshape_core::keyshapes::greedy_gram;
    let full = builtin_lips();
    let cols: Vec<usize> = (0..full.frames()).step_by(5).take(30).collect();
    let q = full.coords.select_columns(&cols);
    for solver in Solver::ALL {
        let an = Analysis::new(q.clone(), full.points).unwrap();
        let first = greedy_gram(&an, 1, solver, 0).unwrap().0[0];
        // A copy after it: still `first`.
        let mut after = q.clone().insert_column(30, 0.0);
        after.set_column(30, &q.column(first));
        let an = Analysis::new(after, full.points).unwrap();
        assert_eq!(
            greedy_gram(&an, 1, solver, 0).unwrap().0,
            vec![first],
            "{solver}"
        );
        // A copy in front of everything: the copy, frame 0.
        let mut before = q.clone().insert_column(0, 0.0);
        before.set_column(0, &q.column(first));
        let an = Analysis::new(before, full.points).unwrap();
        assert_eq!(
            greedy_gram(&an, 1, solver, 0).unwrap().0,
            vec![0],
            "{solver}"
        );
    }
}

/// Once the keys reconstruct every frame, each further key ties at zero error; the
/// constrained greedy must still add a frame it has not taken. Frames (10, 0), (30, 0),
/// (0, 10), (10, 0.1) (two points, second at the origin): nnls takes (10, 0) and (0, 10),
/// bounded (weights ≤ 1) (30, 0) and (0, 10); either pair spans every frame within its
/// bounds, and then it must add one of the other two.
#[test]
fn constrained_greedy_never_takes_a_key_twice_when_every_step_ties() {
    use keyshape_core::keyshapes::greedy_gram;
    let f = [(10.0, 0.0), (30.0, 0.0), (0.0, 10.0), (10.0, 0.1)];
    let q = DMatrix::from_fn(4, 4, |i, t| match i {
        0 => f[t].0,
        1 => f[t].1,
        _ => 0.0,
    });
    let an = Analysis::new(q, 2).unwrap();
    for solver in [Solver::Nnls, Solver::Bounded] {
        for shortlist in [0, 2, 8] {
            for kmax in [3, 4] {
                let (keys, errs) = greedy_gram(&an, kmax, solver, shortlist).unwrap();
                let first = if solver == Solver::Nnls { 0 } else { 1 };
                let at = format!("{solver} {shortlist}: {keys:?} {errs:?}");
                assert_eq!(&keys[..2], &[first, 2], "{at}");
                assert_eq!(errs[1], 0.0, "{at}");
                let mut d = keys.clone();
                d.sort_unstable();
                d.dedup();
                assert_eq!(d.len(), kmax, "{solver} {shortlist}: {keys:?} {errs:?}");
            }
        }
    }
}

/// A frame 10⁻⁷ the size of the others (`‖q‖² ≤ 1e-12 · max ‖q‖²`) counts as zero: every
/// solver's greedy takes the two real frames and refuses a third.
#[test]
fn greedy_treats_a_numerically_zero_frame_as_no_shape() {
    use keyshape_core::keyshapes::greedy_gram;
    let q = DMatrix::from_row_slice(3, 3, &[10.0, 0.0, 0.0, 0.0, 10.0, 0.0, 0.0, 0.0, 1e-6]);
    let an = Analysis::new(q, 1).unwrap();
    assert_eq!(an.distinct, 3);
    for solver in Solver::ALL {
        let (keys, _) = greedy_gram(&an, 2, solver, 0).unwrap();
        assert_eq!(sorted(keys), vec![0, 1], "{solver}");
        let e = greedy_gram(&an, 3, solver, 0)
            .unwrap_err()
            .kind_is(ErrorKind::Unfit);
        assert!(
            e.contains("greedy: only 2 linearly independent shapes, 3 asked for"),
            "{solver}: {e}"
        );
    }
    // The feature-space path (long tracks' least squares) draws the same line.
    use keyshape_core::keyshapes::greedy_ls_feature_space;
    let (keys, _) = greedy_ls_feature_space(&an, 2).unwrap();
    assert_eq!(sorted(keys), vec![0, 1]);
    let e = greedy_ls_feature_space(&an, 3)
        .unwrap_err()
        .kind_is(ErrorKind::Unfit);
    assert!(
        e.contains("only 2 linearly independent shapes, 3 asked for"),
        "{e}"
    );
}

/// Past the Gram limit `greedy_path` takes least squares to the feature-space greedy and
/// nnls/bounded to the subsample (at the limit's size); up to it, the Gram-matrix greedy.
#[test]
fn greedy_path_dispatches_on_the_gram_limit_and_the_solver() {
    use keyshape_core::keyshapes::{
        greedy_gram, greedy_ls_feature_space, greedy_subsampled, GRAM_LIMIT,
    };
    let q = |n: usize| {
        DMatrix::from_fn(6, n, |i, t| {
            let a = (t as f64 * 0.01).sin();
            let b = (t as f64 * 0.037).cos();
            [1.0, a, 1.0 + b, 0.5 * a * b, 2.0 - a, b][i] + 0.1 * i as f64
        })
    };
    let long = Analysis::new(q(GRAM_LIMIT + 1), 3).unwrap();
    let short = Analysis::new(q(300), 3).unwrap();
    for solver in Solver::ALL {
        let got = greedy_path(&long, 4, solver, 8).unwrap();
        let want = if solver == Solver::Ls {
            greedy_ls_feature_space(&long, 4).unwrap()
        } else {
            greedy_subsampled(&long, 4, solver, 8, GRAM_LIMIT).unwrap()
        };
        assert_eq!(got, want, "{solver}");
        assert_eq!(
            greedy_path(&short, 4, solver, 8).unwrap(),
            greedy_gram(&short, 4, solver, 8).unwrap(),
            "{solver}"
        );
    }
}

/// The shortlist's one-variable bound clips the weight to the solver's bound. Frames
/// (1, 0), (10, 0.5), (10, −0.5): with a shortlist of one, nnls (no upper bound) ranks the
/// small frame on the frames' mean direction first, and it is the best nnls key; bounded
/// (weights ≤ 1) cannot scale it up to the large frames and ranks a large frame first —
/// again the best key under its bound.
#[test]
fn the_shortlist_bound_clips_to_each_solvers_bound() {
    use keyshape_core::keyshapes::greedy_gram;
    let f = [(1.0, 0.0), (10.0, 0.5), (10.0, -0.5)];
    let q = DMatrix::from_fn(3, 3, |i, t| match i {
        0 => f[t].0,
        1 => f[t].1,
        _ => 0.0,
    });
    let an = Analysis::new(q, 1).unwrap();
    for (solver, want) in [(Solver::Nnls, 0), (Solver::Bounded, 1)] {
        let (keys, _) = greedy_gram(&an, 1, solver, 1).unwrap();
        assert_eq!(keys, vec![want], "{solver}");
        // The brute-force best single key agrees.
        let e: Vec<f64> = (0..3).map(|c| an.error(&[c], solver).unwrap()).collect();
        assert!(e.iter().all(|&x| e[want] <= x), "{solver}: {e:?}");
    }
}

/// A library error's kind checked before its words are read: a test acts on the kind, as a
/// caller would, and reads the message only for what it must name.
trait KindIs {
    fn kind_is(self, kind: keyshape_core::ErrorKind) -> String;
}

impl KindIs for keyshape_core::Error {
    #[track_caller]
    fn kind_is(self, kind: keyshape_core::ErrorKind) -> String {
        assert_eq!(self.kind(), kind, "{self}");
        self.to_string()
    }
}
