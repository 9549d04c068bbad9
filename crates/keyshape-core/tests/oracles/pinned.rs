//! Oracles for numbers the other tests did not pin down, the core's
//! share (the rest, on paper 002's intensities, is in the root's `tests/it/oracles.rs`): each
//! test here fails on a plausible one-line bug that the suite used to let through.

use keyshape_core::decompose::decompose_coords;
use keyshape_core::keyshapes::{Analysis, KeyOptions, Method};
use keyshape_core::rbf::Rbf;
use keyshape_core::solve::{SolveOptions, Solver};
use keyshape_core::ErrorKind;
use nalgebra::{DMatrix, DVector};

/// A frame whose weights are finite but whose squared error overflows is refused, not
/// reported with an infinite error: key (1, 0, 0, 0), frame 1e160 · (1, 0, 0, 1) — weight
/// 1e160 (1 for bounded) but a residual of 1e160 on the last coordinate, squared past
/// f64's range. Run 29: reading the check's `||` as `&&` (both non-finite) survived,
/// because every test's overflow came from non-finite weights.
#[test]
fn an_error_that_overflows_with_finite_weights_is_refused() {
    let q = DMatrix::from_column_slice(4, 2, &[1.0, 0.0, 0.0, 0.0, 1e160, 0.0, 0.0, 1e160]);
    for solver in Solver::ALL {
        let e = decompose_coords(&q, 2, &[0], None, &SolveOptions::new(solver))
            .err()
            .unwrap_or_else(|| panic!("{solver}: an infinite error was accepted"))
            .to_string();
        assert!(
            e.contains("non-finite weights or error at frame column 1"),
            "{solver}: {e}"
        );
    }
}

/// Per-frame RMS is `sqrt(‖q − q̂‖² / points)` on a residual made by hand: two 2-D points,
/// one key shape (1, 0, 0, 0); frame 1 is the key plus 3 on the last coordinate, so its
/// residual is (0, 0, 0, 3) under every solver: RMS = sqrt(9 / 2) (not sqrt(9 / 4)).
#[test]
fn per_frame_rms_divides_by_the_point_count() {
    let q = DMatrix::from_column_slice(
        4,
        3,
        &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 3.0, 2.0, 0.0, 0.0, 4.0],
    );
    for solver in Solver::ALL {
        let d = decompose_coords(&q, 2, &[0], None, &SolveOptions::new(solver)).unwrap();
        let rms = d.rms();
        assert_eq!(rms[0], 0.0, "{solver}");
        assert!(
            (rms[1] - 4.5f64.sqrt()).abs() < 1e-15,
            "{solver}: {}",
            rms[1]
        );
        // frame 2 = 2 × key + 4 on the last coordinate: weight 2 (1 for bounded), residual 4.
        let want2 = if solver == Solver::Bounded {
            ((1.0 + 16.0) / 2.0f64).sqrt()
        } else {
            8.0f64.sqrt()
        };
        assert!((rms[2] - want2).abs() < 1e-15, "{solver}: {}", rms[2]);
        let mean = (0.0 + 4.5f64.sqrt() + want2) / 3.0;
        assert!((d.mean_rms() - mean).abs() < 1e-15, "{solver}");
        let total = 9.0 + 2.0 * want2 * want2;
        assert!((d.total_sq_error() - total).abs() < 1e-12, "{solver}");
        assert!(
            (d.overall_rms() - (total / 6.0).sqrt()).abs() < 1e-15,
            "{solver}"
        );
    }
}

/// The RBF away from its centres equals the multiquadric computed here from scratch
/// (own H, LU solve, own kernel): `F(x) = Σ wᵢ sqrt(‖x − sᵢ‖² + scᵢ²)`, `scᵢ` the distance
/// from sᵢ to its nearest other centre. A kernel swapped for another still interpolates
/// the centres, so only points between them can tell.
#[test]
fn the_rbf_between_its_centres_is_the_paper_multiquadric() {
    let src = [0.0, 0.0, 3.0, 0.5, 1.0, 4.0, -2.0, 2.5, 2.0, 2.0];
    let dst = [0.5, 0.1, 3.2, 1.0, 1.1, 5.0, -2.5, 2.0, 2.4, 2.6];
    let n = 5;
    let rbf = Rbf::fit(&src, &dst, 2).unwrap();
    let c = |i: usize| [src[2 * i], src[2 * i + 1]];
    let d2 = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2);
    let sc2: Vec<f64> = (0..n)
        .map(|i| {
            (0..n)
                .filter(|&j| j != i)
                .map(|j| d2(c(i), c(j)))
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    let h = DMatrix::from_fn(n, n, |j, i| (d2(c(j), c(i)) + sc2[i]).sqrt());
    let lu = h.lu();
    let w: Vec<DVector<f64>> = (0..2)
        .map(|d| {
            let t = DVector::from_fn(n, |j, _| dst[2 * j + d]);
            lu.solve(&t).unwrap()
        })
        .collect();
    for x in [[1.5, 1.0], [0.3, 2.9], [-1.0, 0.0], [4.0, 4.0], [2.5, 0.2]] {
        let mut got = [0.0; 2];
        rbf.apply_point(&x, &mut got);
        for d in 0..2 {
            let want: f64 = (0..n)
                .map(|i| w[d][i] * (d2(x, c(i)) + sc2[i]).sqrt())
                .sum();
            assert!(
                (got[d] - want).abs() < 1e-10 * (1.0 + want.abs()),
                "F({x:?})[{d}] = {}, the multiquadric gives {want}",
                got[d]
            );
        }
    }
    // and it interpolates the centres
    for i in 0..n {
        let mut got = [0.0; 2];
        rbf.apply_point(&c(i), &mut got);
        assert!((got[0] - dst[2 * i]).abs() < 1e-10 && (got[1] - dst[2 * i + 1]).abs() < 1e-10);
    }
}

/// k-means' key frames are, centre by centre, the unused frame nearest the centre over
/// *every* clustered axis: checked by brute force on the built-in sequence for kmeans2,
/// kmeans3 and kmeans5.
#[test]
fn kmeans_keys_are_the_frames_nearest_the_centres_over_all_axes() {
    let seq = keyshape_io::builtin_sequence().unwrap();
    let an = Analysis::with_axes(seq.coords, seq.points, 8).unwrap();
    for pcs in [2usize, 3, 5] {
        let sel = Method::KMeans { pcs, mean: false }
            .heuristic(&KeyOptions::default())
            .select(&an, 9)
            .unwrap();
        let centres = sel.centres.unwrap();
        assert_eq!(centres.nrows(), pcs);
        let mut taken = vec![false; an.frames()];
        for (c, &got) in sel.columns.iter().enumerate() {
            let mut best = (f64::INFINITY, usize::MAX);
            for t in 0..an.frames() {
                if taken[t] {
                    continue;
                }
                let d: f64 = (0..pcs)
                    .map(|a| (an.proj[(a, t)] - centres[(a, c)]).powi(2))
                    .sum();
                if d < best.0 {
                    best = (d, t);
                }
            }
            assert_eq!(got, best.1, "kmeans{pcs}: centre {c}");
            taken[best.1] = true;
        }
    }
}

/// Paper 000 §4.2's k-means variant: the key shapes are the clusters' centres of mass — the
/// mean, in full coordinates, of the frames nearest each centre on the clustered axes —
/// checked by brute force, with Eq. 5 checked against the textbook NNLS frame by frame.
#[test]
fn kmeans_mean_keys_are_the_clusters_mean_shapes() {
    use keyshape_core::solve::textbook;
    let seq = keyshape_io::builtin_sequence().unwrap();
    let an = Analysis::with_axes(seq.coords.clone(), seq.points, 8).unwrap();
    for pcs in [2usize, 3] {
        let m = Method::KMeans { pcs, mean: true };
        let sel = m.heuristic(&KeyOptions::default()).select(&an, 6).unwrap();
        // Same clustering as kmeansN: same centres and nearest frames.
        let plain = Method::KMeans { pcs, mean: false }
            .heuristic(&KeyOptions::default())
            .select(&an, 6)
            .unwrap();
        assert_eq!(sel.centres, plain.centres);
        assert_eq!(sel.columns, plain.columns);
        let centres = sel.centres.clone().unwrap();
        let shapes = sel.shapes.clone().unwrap();
        assert_eq!(shapes.shape(), (an.coords.nrows(), 6));
        let mut sums = DMatrix::<f64>::zeros(an.coords.nrows(), 6);
        let mut sizes = [0usize; 6];
        for t in 0..an.frames() {
            let d = |c: usize| -> f64 {
                (0..pcs)
                    .map(|a| (an.proj[(a, t)] - centres[(a, c)]).powi(2))
                    .sum()
            };
            let mut best = 0;
            for c in 1..6 {
                if d(c) < d(best) {
                    best = c;
                }
            }
            for i in 0..an.coords.nrows() {
                sums[(i, best)] += an.coords[(i, t)];
            }
            sizes[best] += 1;
        }
        assert_eq!(sel.sizes.as_deref(), Some(&sizes[..]));
        assert_eq!(sizes.iter().sum::<usize>(), an.frames());
        for c in 0..6 {
            for i in 0..an.coords.nrows() {
                let want = sums[(i, c)] / sizes[c] as f64;
                assert!((shapes[(i, c)] - want).abs() < 1e-9 * want.abs().max(1.0));
            }
        }
        // Eq. 5 on the mean shapes, from inner products, against direct residuals.
        let e = an.selection_error(&sel, Solver::Nnls).unwrap();
        let mut direct = 0.0;
        for t in 0..an.frames() {
            let q = an.coords.column(t).clone_owned();
            let w = textbook::nnls(&shapes, &q);
            direct += (&shapes * &w - &q).norm_squared();
        }
        assert!((e - direct).abs() < 1e-6 * direct, "{e} vs {direct}");
        // The frame variant's error is on the frames, not on the means.
        let ef = an.selection_error(&plain, Solver::Nnls).unwrap();
        assert_eq!(ef, an.error(&plain.columns, Solver::Nnls).unwrap());
        assert_ne!(e, ef);
        // Where frames are needed, the mean variant is refused with a pointer to kmeansN.
        let msg = sel
            .key_frames(&m, "retargeting")
            .unwrap_err()
            .kind_is(ErrorKind::Invalid);
        assert!(msg.contains(&format!("use kmeans{pcs} ")), "{msg}");
        assert_eq!(plain.key_frames(&m, "x").unwrap(), &plain.columns[..]);
        // Names round-trip.
        assert_eq!(Method::parse(&m.name()).unwrap(), m);
        assert_eq!(m.name(), format!("kmeans{pcs}-mean"));
    }
    for bad in [
        "spread-mean",
        "hull-mean",
        "greedy-mean",
        "random-mean",
        "kmeans0-mean",
        "kmeans-means",
    ] {
        assert!(Method::parse(bad).is_err(), "{bad}");
    }
    assert_eq!(
        Method::parse("kmeans-mean").unwrap(),
        Method::KMeans { pcs: 2, mean: true }
    );
}

/// Survivors of the first mutation run (mutants/README.md), each killed here.
#[test]
fn negative_share_tolerance_scales_with_the_largest_weight() {
    use keyshape_core::decompose::Decomposition;
    let d = |w: Vec<f64>| Decomposition {
        key_columns: vec![0, 1],
        neutral: None,
        solver: Solver::Ls,
        weights: DMatrix::from_vec(2, 2, w),
        sq_error: vec![0.0, 0.0],
        points: 1,
        rank: 2,
        condition: 1.0,
        unconverged: 0,
    };
    // tolerance 1e-9 × 1000 = 1e-6: −1e-7 is rounding, −2e-6 is a negative weight
    let a = d(vec![1000.0, -1e-7, 0.5, -2e-6]);
    assert_eq!(a.max_abs_weight(), 1000.0);
    assert_eq!(a.negative_share(), 0.25);
    // exactly at −tolerance is not negative
    assert_eq!(d(vec![1.0, -1e-9, 0.5, 0.5]).negative_share(), 0.0);
    // an LS weight of −3e-14 is rounding, not "−0.0 %"; −0.25 counts
    assert_eq!(d(vec![1.0, -3e-14, 0.5, 0.5]).negative_share(), 0.0);
    assert_eq!(d(vec![1.0, -0.25, 0.5, 0.5]).negative_share(), 0.25);
}

/// As many key shapes as frames is allowed (every frame reconstructs itself); one more is
/// an error. Delta mode (`neutral`) reconstructs `base + Σ wᵢ (keyᵢ − base)` exactly.
#[test]
fn decompose_takes_every_frame_as_a_key_and_solves_deltas_exactly() {
    let q = DMatrix::from_column_slice(
        4,
        3,
        &[1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0],
    );
    let d = decompose_coords(&q, 2, &[0, 1, 2], None, &SolveOptions::new(Solver::Nnls)).unwrap();
    assert_eq!(d.total_sq_error(), 0.0);
    // delta mode: neutral n, keys a and b; frames n + 0.25 (a − n) + 0.5 (b − n)
    let n = [1.0, 1.0, 3.0, 1.0];
    let a = [2.0, 1.0, 3.0, 2.0];
    let b = [1.0, 3.0, 4.0, 1.0];
    let mix: Vec<f64> = (0..4)
        .map(|i| n[i] + 0.25 * (a[i] - n[i]) + 0.5 * (b[i] - n[i]))
        .collect();
    let cols: Vec<f64> = [n, a, b].iter().flatten().copied().chain(mix).collect();
    let q = DMatrix::from_column_slice(4, 4, &cols);
    for solver in Solver::ALL {
        let d = decompose_coords(&q, 2, &[1, 2], Some(0), &SolveOptions::new(solver)).unwrap();
        assert!(
            (d.weights[(0, 3)] - 0.25).abs() < 1e-12,
            "{solver}: {}",
            d.weights
        );
        assert!(
            (d.weights[(1, 3)] - 0.5).abs() < 1e-12,
            "{solver}: {}",
            d.weights
        );
        assert!(d.sq_error[3] < 1e-20, "{solver}: {}", d.sq_error[3]);
        assert_eq!(
            d.weights[(0, 0)],
            0.0,
            "{solver}: the neutral frame has no delta"
        );
    }
}

/// Survivors of mutation run 2 (mutants/README.md): the batch solvers over several chunks
/// of frames, a bad frame named exactly, and the method table's edges.
#[test]
fn batch_solves_over_many_chunks_match_frame_by_frame_solves() {
    use keyshape_core::solve::{solve_batch, textbook, CHUNK};
    // 3 key shapes of 5 values, 3 chunks and a bit of frames.
    let s = DMatrix::from_fn(5, 3, |i, j| {
        ((i * 7 + j * 3) % 5) as f64 + if i == j { 2.0 } else { 0.5 }
    });
    let frames = 3 * CHUNK + 7;
    let q = DMatrix::from_fn(5, frames, |i, t| ((i * 13 + t * 7) % 11) as f64 * 0.3 - 1.0);
    let ls = solve_batch(&s, &q, &SolveOptions::new(Solver::Ls)).unwrap();
    let want = s.clone().pseudo_inverse(1e-12).unwrap() * &q;
    assert!((&ls.weights - &want).amax() < 1e-9);
    let nn = solve_batch(&s, &q, &SolveOptions::new(Solver::Nnls)).unwrap();
    for t in [0, CHUNK - 1, CHUNK, 2 * CHUNK + 3, frames - 1] {
        let w = textbook::nnls(&s, &q.column(t).clone_owned());
        assert!((nn.weights.column(t) - w).amax() < 1e-9, "frame {t}");
    }
    // A frame holding NaN is named by its own column, whatever its place in a chunk.
    let mut bad = q.clone();
    bad[(2, CHUNK + 5)] = f64::NAN;
    for solver in [Solver::Ls, Solver::Nnls] {
        let e = solve_batch(&s, &bad, &SolveOptions::new(solver))
            .unwrap_err()
            .kind_is(ErrorKind::Unfit);
        assert!(
            e.contains(&format!("frame column {}:", CHUNK + 5)),
            "{solver}: {e}"
        );
    }
    // Solver names as the command line writes them.
    let names: Vec<&str> = Solver::ALL.iter().map(|s| s.name()).collect();
    assert_eq!(names, ["ls", "nnls", "bounded"]);
}

#[test]
fn the_method_table_and_its_edges() {
    use keyshape_core::keyshapes::axes_needed;
    assert_eq!(
        Method::parse("kmeans").unwrap(),
        Method::KMeans {
            pcs: 2,
            mean: false
        }
    );
    assert_eq!(
        Method::parse("kmeans64").unwrap(),
        Method::KMeans {
            pcs: 64,
            mean: false
        }
    );
    for bad in ["kmeans0", "kmeans65", "kmeansx"] {
        assert!(Method::parse(bad).is_err(), "{bad}");
    }
    // k-means needs its own number of axes; spread ⌈k/2⌉; never fewer than 24.
    assert_eq!(
        axes_needed(
            &[Method::KMeans {
                pcs: 30,
                mean: true
            }],
            2
        ),
        30
    );
    assert_eq!(axes_needed(&[Method::Spread], 60), 30);
    assert_eq!(axes_needed(&[Method::Hull], 2), 24);
    // As many key shapes as distinct shapes is allowed, one more is not.
    let coords = DMatrix::from_fn(4, 9, |i, t| ((t % 5) * (i + 1)) as f64 + (i * t % 5) as f64);
    let an = Analysis::new(coords, 2).unwrap();
    assert_eq!(an.distinct, 5);
    an.check_k(5).unwrap();
    assert!(an.check_k(6).is_err());
    // A method that needs more principal axes than the data has is refused, not run.
    let flat = DMatrix::from_fn(2, 12, |i, t| (t as f64) * if i == 0 { 1.0 } else { 0.5 });
    let an = Analysis::new(flat, 1).unwrap();
    let e = Method::KMeans {
        pcs: 3,
        mean: false,
    }
    .heuristic(&KeyOptions::default())
    .select(&an, 2)
    .unwrap_err()
    .kind_is(ErrorKind::Unfit);
    assert!(e.contains("needs 3 principal axes"), "{e}");
}

/// Past the Gram limit the key-set products come from the shapes directly: the Eq. 5 error
/// there equals the residual computed frame by frame, and the frames' Gram matrix is refused.
#[test]
fn long_sequences_evaluate_errors_without_the_frames_gram_matrix() {
    use keyshape_core::keyshapes::GRAM_LIMIT;
    use keyshape_core::solve::textbook;
    let frames = GRAM_LIMIT + 1;
    let coords = DMatrix::from_fn(6, frames, |i, t| {
        ((t * (i + 3)) % 17) as f64 * 0.1 + i as f64
    });
    let an = Analysis::new(coords.clone(), 3).unwrap();
    assert!(an.frame_gram().is_err());
    let keys = [0usize, 5, 11, 400];
    let s = coords.select_columns(&keys);
    for solver in [Solver::Ls, Solver::Nnls] {
        let e = an.error(&keys, solver).unwrap();
        let mut direct = 0.0;
        for t in 0..frames {
            let q = coords.column(t).clone_owned();
            let w = match solver {
                Solver::Ls => s.clone().pseudo_inverse(1e-12).unwrap() * &q,
                _ => textbook::nnls(&s, &q),
            };
            direct += (&s * w - q).norm_squared();
        }
        assert!(
            (e - direct).abs() < 1e-8 * direct.max(1.0),
            "{solver}: {e} vs {direct}"
        );
    }
}

/// The frames' Gram matrix is formed up to the limit inclusive (run 16: `>` → `>=` in
/// `frame_gram` refused it at exactly `GRAM_LIMIT` frames, where `error` still asks for it).
#[test]
fn the_frames_gram_matrix_is_formed_at_exactly_the_limit() {
    use keyshape_core::keyshapes::GRAM_LIMIT;
    let coords = DMatrix::from_fn(4, GRAM_LIMIT, |i, t| ((t * (i + 2)) % 13) as f64 + i as f64);
    let an = Analysis::new(coords.clone(), 2).unwrap();
    let g = an.frame_gram().unwrap();
    assert_eq!(g.shape(), (GRAM_LIMIT, GRAM_LIMIT));
    assert_eq!(g[(7, 11)], coords.column(7).dot(&coords.column(11)));
    let e = an.error(&[0, 1, 2], Solver::Nnls).unwrap();
    assert!(e.is_finite() && e > 0.0);
}

/// Frames an nnls/bounded solve stops at its iteration cap make the Eq. 5 error an error
/// naming how many, on every path: key frames from the frames' Gram matrix, key frames past
/// the Gram limit (block by block), and cluster mean shapes on both sides of the limit.
/// Every frame here is a positive vector and every key shape too, so from w = 0 each frame
/// needs at least one step: a cap of 0 stops them all; least squares has no cap; the
/// default cap converges (run 16: the counts `bad += n` → `*=`/`-=`, `bad > 0` → `<` and
/// `unconverged > 0` → `<` all survived, since no test could reach the cap).
#[test]
fn an_iteration_cap_makes_the_error_an_error_that_counts_the_stopped_frames() {
    use keyshape_core::keyshapes::{Selection, GRAM_LIMIT};
    for frames in [40, GRAM_LIMIT + 5] {
        let coords = DMatrix::from_fn(6, frames, |i, t| {
            1.0 + ((t * (i + 3)) % 17) as f64 * 0.1 + i as f64
        });
        let mut an = Analysis::new(coords.clone(), 3).unwrap();
        let keys = [0usize, 5, 11];
        let means = Selection {
            columns: keys.to_vec(),
            centres: None,
            shapes: Some(coords.select_columns(&[1, 2])),
            sizes: Some(vec![frames / 2, frames - frames / 2]),
        };
        let free = an.error(&keys, Solver::Nnls).unwrap();
        an.max_iterations = Some(0);
        for solver in [Solver::Nnls, Solver::Bounded] {
            let msg = an
                .error(&keys, solver)
                .unwrap_err()
                .kind_is(ErrorKind::Unfit);
            let want = format!("{solver} did not converge on {frames} frames (iteration cap) for key columns [0, 5, 11]");
            assert!(msg.contains(&want), "{frames} frames: {msg}");
            let msg = an
                .selection_error(&means, solver)
                .unwrap_err()
                .kind_is(ErrorKind::Unfit);
            let want = format!("{solver} did not converge on {frames} frames (iteration cap) for the cluster mean shapes");
            assert!(msg.contains(&want), "{frames} frames: {msg}");
            if frames <= GRAM_LIMIT {
                assert!(an.weights_and_error(&keys, solver).is_err());
            }
        }
        assert!(an.error(&keys, Solver::Ls).is_ok());
        an.max_iterations = Some(20);
        assert_eq!(an.error(&keys, Solver::Nnls).unwrap(), free);
    }
}

/// Cluster mean shapes with the wrong number of values are refused on both sides of the
/// Gram limit, never multiplied (run 16: the guard of the block-wise path, widened by
/// `&&` → `||`, `==` → `!=` or `true`, sent them into a dimension mismatch).
#[test]
fn mean_shapes_of_the_wrong_size_are_refused_on_every_path() {
    use keyshape_core::keyshapes::{Selection, GRAM_LIMIT};
    for frames in [40, GRAM_LIMIT + 5] {
        let coords = DMatrix::from_fn(6, frames, |i, t| {
            ((t * (i + 3)) % 17) as f64 * 0.1 + i as f64
        });
        let an = Analysis::new(coords, 3).unwrap();
        let sel = Selection {
            columns: vec![0, 1],
            centres: None,
            shapes: Some(DMatrix::from_element(4, 2, 1.0)),
            sizes: Some(vec![1, frames - 1]),
        };
        for solver in Solver::ALL {
            let msg = an
                .selection_error(&sel, solver)
                .unwrap_err()
                .kind_is(ErrorKind::Invalid);
            assert!(
                msg.contains("key shapes have 4 values, the frames 6"),
                "{msg}"
            );
            assert!(an.selection_weights_and_error(&sel, solver).is_err());
        }
    }
}

/// Run 1's open survivors (mutants/README.md), each pinned by a case that only the
/// correct code passes.
///
/// `Rbf::fit` refuses each malformed input on its own (no points; source and target of
/// different lengths; a length that is not a multiple of `dims`) and nearly coincident
/// points by the condition number of H (distinct points 1e-9 apart: not singular, but the
/// weights would be noise).
#[test]
fn rbf_refuses_each_malformed_input_and_nearly_coincident_points() {
    let src = [0.0, 0.0, 1.0, 0.0, 0.0, 1.0];
    let cases: [(&[f64], &[f64], &str); 3] = [
        (&[], &[], "differ in count"),
        (&src, &src[..4], "differ in count"),
        (&src[..5], &src[..5], "differ in count"),
    ];
    for (s, d, want) in cases {
        let e = Rbf::fit(s, d, 2).unwrap_err().kind_is(ErrorKind::Invalid);
        assert!(e.contains(want), "{} points: {e}", s.len());
    }
    let close = [0.0, 0.0, 1e-13, 0.0, 1.0, 1.0];
    let e = Rbf::fit(&close, &close, 2)
        .unwrap_err()
        .kind_is(ErrorKind::Unfit);
    assert!(e.contains("too close together"), "{e}");
    // Well separated points train, and 1e-3 apart still do (condition well below 1e12).
    assert!(Rbf::fit(&src, &src, 2).is_ok());
    let near = [0.0, 0.0, 1e-3, 0.0, 1.0, 1.0];
    assert!(Rbf::fit(&near, &near, 2).is_ok());
}

/// The Gram form's column norms are those of S's columns (the diagonal of SᵀS), and the
/// stopping tolerance is `1000 ε k max‖Sᵢ‖ max(‖q‖, max‖Sᵢ‖)` with ‖q‖ estimated as
/// `maxᵢ |bᵢ| / ‖Sᵢ‖`: columns (3, 4) and (0, 1), norms 5 and 1.
#[test]
fn gram_norms_are_the_column_norms_and_the_tolerance_follows_them() {
    use keyshape_core::solve::active_set::Gram;
    let s = DMatrix::from_column_slice(2, 2, &[3.0, 4.0, 0.0, 1.0]);
    let g = Gram::new(&s, f64::INFINITY);
    assert_eq!(g.norms, vec![5.0, 1.0]);
    assert_eq!(g.max_norm, 5.0);
    // b = Sᵀq for q = (0, 20): (80, 20); ‖q‖ estimated max(80 / 5, 20 / 1) = 20.
    let tol = g.tolerance(&[80.0, 20.0]);
    let want = 1e3 * f64::EPSILON * 2.0 * 5.0 * 20.0;
    assert!((tol - want).abs() <= 1e-15 * want, "{tol} vs {want}");
}

/// The batch solve's iteration and unconverged counts are the per-frame reports summed: the
/// same frames solved one by one with `solve_frame` (one chunk, warm-started in order, as
/// the batch does within a chunk) give the same weights and the same totals.
#[test]
fn batch_iteration_counts_are_the_per_frame_reports_summed() {
    use keyshape_core::solve::active_set::{solve_frame, Bound, Gram, Workspace};
    use keyshape_core::solve::{solve_batch, SolveOptions, Solver};
    let seq = keyshape_io::builtin_sequence().unwrap();
    let prep = keyshape_core::decompose::prepare(
        &seq,
        &keyshape_core::decompose::PrepareOptions::group_aligned("lips"),
    )
    .unwrap();
    let q = &prep.seq.coords;
    let s = q.select_columns(&[0, 30, 60, 90, 120, 150, 180, 210]);
    for (solver, upper) in [(Solver::Nnls, f64::INFINITY), (Solver::Bounded, 1.0)] {
        let sol = solve_batch(&s, q, &SolveOptions::new(solver)).unwrap();
        let gram = Gram::new(&s, upper);
        let (mut ws, mut state, mut w) = (Workspace::new(8), vec![Bound::Lower; 8], vec![0.0; 8]);
        let (mut iters, mut bad) = (0u64, 0usize);
        // Sᵀq as the batch forms it (one product), so every tolerance test sees the same bits.
        let b_all = &s.transpose() * q;
        for f in 0..q.ncols() {
            let b = b_all.column(f).into_owned();
            let rep = solve_frame(&gram, b.as_slice(), &mut w, &mut state, &mut ws);
            iters += u64::from(rep.iterations);
            bad += usize::from(!rep.converged);
            for k in 0..8 {
                assert!(
                    (w[k] - sol.weights[(k, f)]).abs() < 1e-9,
                    "{solver} frame {f}"
                );
            }
        }
        assert!(iters > 0);
        assert_eq!(sol.iterations, iters, "{solver}");
        assert_eq!(sol.unconverged, bad, "{solver}");
    }
}

/// The active-set iteration cap, forced: with S = I and q = (1, 2, 3) Lawson–Hanson frees
/// the largest gradient first, one variable a step, so the frame needs exactly 3 steps;
/// (5, 0, 0) needs 1 and (−1, −1, −1) none. Over 600 frames (three parallel chunks) a
/// cap below 3 leaves every (1, 2, 3) frame unconverged, with the feasible partial answer
/// of its first steps, and the batch counts them; a cap of exactly 3 converges.
#[test]
fn the_iteration_cap_stops_frames_feasibly_and_the_batch_counts_them() {
    use keyshape_core::solve::solve_batch;
    let s = DMatrix::<f64>::identity(3, 3);
    let kinds = [[1.0, 2.0, 3.0], [5.0, 0.0, 0.0], [-1.0, -1.0, -1.0]];
    let q = DMatrix::from_fn(3, 600, |i, j| kinds[j % 3][i]);
    let solve = |cap: Option<u32>, warm: bool| {
        let mut o = SolveOptions::new(Solver::Nnls);
        o.max_iterations = cap;
        o.warm_start = warm;
        solve_batch(&s, &q, &o).unwrap()
    };
    let partial = [[0.0, 0.0, 3.0], [0.0, 2.0, 3.0], [1.0, 2.0, 3.0]];
    for (cap, unconverged, iterations, w0) in [
        (Some(0), 400, 0, [0.0, 0.0, 0.0]),
        (Some(1), 200, 400, partial[0]),
        (Some(2), 200, 600, partial[1]),
        (Some(3), 0, 800, partial[2]),
        (None, 0, 800, partial[2]),
    ] {
        let sol = solve(cap, false);
        assert_eq!(sol.unconverged, unconverged, "cap {cap:?}");
        assert_eq!(sol.iterations, iterations, "cap {cap:?}");
        for f in 0..600 {
            let want = match f % 3 {
                0 => w0,
                1 if cap == Some(0) => [0.0; 3],
                1 => [5.0, 0.0, 0.0],
                _ => [0.0; 3],
            };
            let got: Vec<f64> = sol.weights.column(f).iter().copied().collect();
            assert_eq!(got, want, "cap {cap:?} frame {f}");
        }
    }
}

/// `residuals` over more frames than one parallel chunk (600 > 256) equals each frame's
/// ‖q − S w‖² computed column by column.
#[test]
fn residuals_past_the_first_chunk_are_each_frames_own() {
    let s = DMatrix::from_fn(10, 3, |i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0);
    let w = DMatrix::from_fn(3, 600, |i, f| ((i + f) % 5) as f64 * 0.25);
    let q = DMatrix::from_fn(10, 600, |i, f| ((i * 13 + f * 17) % 23) as f64 * 0.1);
    let got = keyshape_core::solve::residuals(&s, &w, &q);
    assert_eq!(got.len(), 600);
    for f in 0..600 {
        let want = (q.column(f) - &s * w.column(f)).norm_squared();
        assert!((got[f] - want).abs() <= 1e-12 * want.max(1.0), "frame {f}");
    }
}

/// `apply_all` maps every column as `apply` does, and an empty matrix (no points, or no
/// frames) maps to an empty one of the same shape.
#[test]
fn rbf_apply_all_is_apply_per_column_and_takes_empty_matrices() {
    use keyshape_core::rbf::Rbf;
    let src = [0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 1.0];
    let dst = [0.0, 0.0, 2.0, 0.1, 0.1, 2.0, 2.2, 2.1];
    let f = Rbf::fit(&src, &dst, 2).unwrap();
    let shapes = nalgebra::DMatrix::from_fn(6, 3, |i, c| (i as f64 * 0.3 + c as f64) % 1.3);
    let all = f.apply_all(&shapes);
    for c in 0..3 {
        let one = f.apply(shapes.column(c).as_slice());
        assert_eq!(all.column(c).as_slice(), &one[..]);
    }
    for (rows, cols) in [(0, 4), (6, 0), (0, 0)] {
        let e = f.apply_all(&nalgebra::DMatrix::zeros(rows, cols));
        assert_eq!(e.shape(), (rows, cols));
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
