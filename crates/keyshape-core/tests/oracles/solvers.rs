//! Solver properties: KKT optimality, brute-force agreement, LS = normal equations,
//! invariance under frame permutation, finite weights on duplicate key shapes.

use crate::common::{brute_force, kkt_violation, objective};
use keyshape_core::solve::{lstsq, solve_batch, textbook, SolveOptions, Solver};
use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;

/// Key shapes like real ones: a shared base shape plus small per-key offsets, sometimes
/// with a column duplicated (rank deficient), and frames near their span.
fn problem(max_k: usize) -> impl Strategy<Value = (DMatrix<f64>, DMatrix<f64>)> {
    (1..=max_k, 0usize..3, 1usize..6).prop_flat_map(move |(k, dup, frames)| {
        let n = 2 * (k + 2);
        (
            prop::collection::vec(-1.0f64..1.0, n),
            prop::collection::vec(-1.0f64..1.0, n * k),
            prop::collection::vec(-1.0f64..1.0, n * frames),
            prop::collection::vec(-0.5f64..1.5, k * frames),
            0.0f64..1.0,
        )
            .prop_map(move |(base, off, noise, mix, spread)| {
                let mut s = DMatrix::from_fn(n, k, |i, j| {
                    10.0 * base[i] + (0.1 + spread) * off[i * k + j]
                });
                if dup == 1 && k >= 2 {
                    let c = s.column(0).clone_owned();
                    s.set_column(k - 1, &c);
                }
                let w = DMatrix::from_vec(k, frames, mix);
                let q = &s * w + DMatrix::from_vec(n, frames, noise) * 0.05;
                // Frames equal to a key shape (exact zeros in the sub-solves) are common:
                // every key frame of a sequence is one.
                let q = if dup == 2 {
                    DMatrix::from_columns(&[
                        q.column(0).clone_owned(),
                        s.column(k - 1).clone_owned(),
                    ])
                } else {
                    q
                };
                (s, q)
            })
    })
}

fn column(q: &DMatrix<f64>, j: usize) -> DVector<f64> {
    q.column(j).clone_owned()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn nnls_satisfies_kkt_including_rank_deficient_bases((s, q) in problem(10), warm in any::<bool>()) {
        let mut opts = SolveOptions::new(Solver::Nnls);
        opts.warm_start = warm;
        let sol = solve_batch(&s, &q, &opts).unwrap();
        prop_assert_eq!(sol.unconverged, 0);
        for j in 0..q.ncols() {
            let v = kkt_violation(&s, &column(&q, j), &column(&sol.weights, j), f64::INFINITY);
            prop_assert!(v < 1e-12, "KKT violated by {v:e} at frame {j}");
        }
    }

    #[test]
    fn bounded_satisfies_kkt_in_the_unit_box((s, q) in problem(10)) {
        let sol = solve_batch(&s, &q, &SolveOptions::new(Solver::Bounded)).unwrap();
        for j in 0..q.ncols() {
            let v = kkt_violation(&s, &column(&q, j), &column(&sol.weights, j), 1.0);
            prop_assert!(v < 1e-12, "KKT violated by {v:e} at frame {j}");
        }
    }

    #[test]
    fn nnls_and_bounded_match_brute_force_active_set_enumeration((s, q) in problem(6)) {
        for (solver, upper) in [(Solver::Nnls, f64::INFINITY), (Solver::Bounded, 1.0)] {
            let sol = solve_batch(&s, &q, &SolveOptions::new(solver)).unwrap();
            for j in 0..q.ncols() {
                let qj = column(&q, j);
                let ours = objective(&s, &qj, &column(&sol.weights, j));
                let best = brute_force(&s, &qj, upper);
                let scale = qj.norm_squared().max(1.0);
                prop_assert!(ours <= best + 1e-9 * scale, "{solver}: {ours} > brute force {best}");
            }
        }
    }

    #[test]
    fn nnls_matches_the_textbook_per_frame_solver((s, q) in problem(8)) {
        let sol = solve_batch(&s, &q, &SolveOptions::new(Solver::Nnls)).unwrap();
        for j in 0..q.ncols() {
            let qj = column(&q, j);
            let ours = objective(&s, &qj, &column(&sol.weights, j));
            let theirs = objective(&s, &qj, &textbook::nnls(&s, &qj));
            prop_assert!((ours - theirs).abs() <= 1e-9 * qj.norm_squared().max(1.0), "{ours} vs {theirs}");
        }
    }

    #[test]
    fn ls_equals_normal_equations_when_well_conditioned(
        k in 1usize..8, frames in 1usize..5,
        vals in prop::collection::vec(-1.0f64..1.0, 40 * 8 + 40 * 5),
    ) {
        let n = 40;
        let s = DMatrix::from_fn(n, k, |i, j| vals[i * 8 + j] + if i % k == j { 2.0 } else { 0.0 });
        let q = DMatrix::from_fn(n, frames, |i, j| vals[n * 8 + i * 5 + j]);
        let ls = solve_batch(&s, &q, &SolveOptions::new(Solver::Ls)).unwrap();
        let ne = lstsq::normal_equations(&s, &q).unwrap();
        prop_assert!(ls.condition < 1e3);
        prop_assert!((ls.weights - ne).amax() < 1e-9);
    }

    #[test]
    fn weights_do_not_depend_on_frame_order(
        (s, q) in problem(8), seed in any::<u64>(), solver in prop::sample::select(Solver::ALL.to_vec()),
    ) {
        let n = q.ncols();
        let mut perm: Vec<usize> = (0..n).collect();
        let mut x = seed;
        for i in (1..n).rev() {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            perm.swap(i, (x >> 33) as usize % (i + 1));
        }
        let opts = SolveOptions::new(solver);
        let a = solve_batch(&s, &q, &opts).unwrap();
        let b = solve_batch(&s, &q.select_columns(&perm), &opts).unwrap();
        for (pj, &j) in perm.iter().enumerate() {
            // Compare reconstructions: with duplicate key shapes the weights are not unique.
            let ra = &s * column(&a.weights, j);
            let rb = &s * column(&b.weights, pj);
            prop_assert!((ra - rb).amax() < 1e-7 * (1.0 + q.amax()));
        }
    }
}

#[test]
fn ls_on_duplicate_key_shapes_gives_finite_split_weights() {
    let base = DVector::from_vec(vec![1.0, 2.0, 3.0, 4.0, 5.0, 7.0]);
    let other = DVector::from_vec(vec![0.0, 1.0, 0.0, 1.0, 0.0, 1.0]);
    let s = DMatrix::from_columns(&[base.clone(), other.clone(), base.clone()]);
    let q = DMatrix::from_columns(&[&base * 2.0 + &other]);
    let sol = solve_batch(&s, &q, &SolveOptions::new(Solver::Ls)).unwrap();
    assert_eq!(sol.rank, 2);
    assert!(sol.condition.is_infinite() || sol.condition > 1e12);
    // Minimum-norm: the duplicate pair shares the weight 2 equally.
    assert!((sol.weights[(0, 0)] - 1.0).abs() < 1e-10, "{}", sol.weights);
    assert!((sol.weights[(2, 0)] - 1.0).abs() < 1e-10);
    assert!((sol.weights[(1, 0)] - 1.0).abs() < 1e-10);
}

/// With a key shape repeated, nnls and bounded put its weight on the earlier copy: of equal
/// gradients the first is freed, and the copy's gradient is then zero (run 16: the pick's
/// `v > best` → `>=` freed the later copy instead: the same fit, other weights).
#[test]
fn a_repeated_key_shape_takes_its_weight_on_the_earlier_copy() {
    let base = DVector::from_vec(vec![1.0, 2.0, 3.0, 4.0, 5.0, 7.0]);
    let other = DVector::from_vec(vec![0.0, 1.0, 0.0, 1.0, 0.0, 1.0]);
    let s = DMatrix::from_columns(&[base.clone(), other.clone(), base.clone()]);
    let q = DMatrix::from_columns(&[&base * 0.5 + &other * 0.3]);
    for solver in [Solver::Nnls, Solver::Bounded] {
        for warm in [false, true] {
            let mut opts = SolveOptions::new(solver);
            opts.warm_start = warm;
            let w = solve_batch(&s, &q, &opts).unwrap().weights;
            assert!((w[(0, 0)] - 0.5).abs() < 1e-12, "{solver}: {w}");
            assert!((w[(1, 0)] - 0.3).abs() < 1e-12, "{solver}: {w}");
            assert_eq!(w[(2, 0)], 0.0, "{solver}: {w}");
        }
    }
}

#[test]
fn near_duplicate_key_shapes_keep_nnls_weights_bounded() {
    let base = DVector::from_fn(20, |i, _| (i as f64 * 0.7).sin() + 3.0);
    let bump = DVector::from_fn(20, |i, _| if i == 3 { 1e-9 } else { 0.0 });
    let other = DVector::from_fn(20, |i, _| (i as f64 * 1.3).cos());
    let s = DMatrix::from_columns(&[base.clone(), &base + bump, other.clone()]);
    let q = DMatrix::from_columns(&[&base * 0.7 + &other * 0.2]);
    let sol = solve_batch(&s, &q, &SolveOptions::new(Solver::Nnls)).unwrap();
    assert!(sol.weights.amax() < 2.0, "{}", sol.weights);
    let r = &s * sol.weights.column(0) - q.column(0);
    assert!(r.norm() < 1e-6);
}

#[test]
fn nan_in_frames_is_an_error_not_nan_weights() {
    let s = DMatrix::from_element(4, 2, 1.0);
    let mut q = DMatrix::from_element(4, 1, 1.0);
    q[(2, 0)] = f64::NAN;
    assert!(solve_batch(&s, &q, &SolveOptions::new(Solver::Nnls)).is_err());
}

#[test]
fn nnls_meets_kkt_on_every_frame_of_a_real_track_including_key_frames() {
    let seq = keyshape_io::builtin_sequence().unwrap();
    let prep = keyshape_core::decompose::prepare(
        &seq,
        &keyshape_core::decompose::PrepareOptions::all_aligned(),
    )
    .unwrap();
    let q = &prep.seq.coords;
    let t = q.ncols();
    for k in [8usize, 16, 32] {
        let keys: Vec<usize> = (0..k).map(|i| i * (t - 1) / (k - 1)).collect();
        let s = q.select_columns(&keys);
        for warm in [false, true] {
            let mut opts = SolveOptions::new(Solver::Nnls);
            opts.warm_start = warm;
            let sol = solve_batch(&s, q, &opts).unwrap();
            assert_eq!(sol.unconverged, 0, "k={k}");
            for j in 0..t {
                let v = kkt_violation(&s, &column(q, j), &column(&sol.weights, j), f64::INFINITY);
                assert!(v < 1e-12, "k={k} frame {j}: KKT violated by {v:e}");
            }
            for (i, &c) in keys.iter().enumerate() {
                assert!(
                    (sol.weights[(i, c)] - 1.0).abs() < 1e-9,
                    "key frame {c} does not reconstruct itself"
                );
            }
        }
    }
}

proptest! {
    #[test]
    fn ls_residual_is_orthogonal_to_the_key_shapes((s, q) in problem(10)) {
        let sol = solve_batch(&s, &q, &SolveOptions::new(Solver::Ls)).unwrap();
        let r = &q - &s * &sol.weights;
        let g = s.transpose() * &r;
        let scale = s.amax() * q.amax() * (s.nrows() as f64);
        prop_assert!(g.amax() < 1e-9 * scale, "Sᵀr = {}", g.amax());
    }
}

/// A weight whose gradient is 22× the solver's own stopping tolerance must be freed:
/// `S = [e₁ e₂]`, `q = e₁ + 1e-11·e₂` has the exact NNLS (and bounded) solution (1, 1e-11).
/// A solver that stopped 100× later (tolerance 4.4e-11 here) would leave w₂ at 0 — which
/// the KKT bound of the proptests (relative 1e-8) cannot see.
#[test]
fn a_gradient_above_the_stopping_tolerance_frees_its_weight() {
    let s = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 0.0, 1.0, 0.0, 0.0]);
    let q = DMatrix::from_column_slice(3, 1, &[1.0, 1e-11, 0.0]);
    for solver in [Solver::Nnls, Solver::Bounded] {
        for warm in [false, true] {
            let mut opts = SolveOptions::new(solver);
            opts.warm_start = warm;
            let sol = solve_batch(&s, &q, &opts).unwrap();
            assert_eq!(sol.unconverged, 0);
            assert_eq!(sol.weights[(0, 0)], 1.0, "{solver}");
            assert!(
                (sol.weights[(1, 0)] - 1e-11).abs() < 1e-24,
                "{solver}: w₂ = {:e}, expected 1e-11",
                sol.weights[(1, 0)]
            );
        }
    }
}

/// A problem that forces Lawson–Hanson's step back: the largest gradient frees s₁ first,
/// freeing s₃ then drives w₁ negative, so the step stops where w₁ reaches 0 and s₁ leaves.
/// The optimum (brute force over active sets, exact in fractions) is (0, 9/7, 19/7);
/// taking the full step and clipping gives (0, 2, 13/3) instead.
#[test]
fn the_lawson_hanson_step_back_reaches_the_exact_optimum() {
    let s = DMatrix::from_row_slice(3, 3, &[-1.0, -3.0, 1.0, -2.0, 1.0, -1.0, 2.0, 0.0, 1.0]);
    let q = DMatrix::from_column_slice(3, 1, &[-1.0, -1.0, 3.0]);
    let want = [0.0, 9.0 / 7.0, 19.0 / 7.0];
    for warm in [false, true] {
        let mut opts = SolveOptions::new(Solver::Nnls);
        opts.warm_start = warm;
        let sol = solve_batch(&s, &q, &opts).unwrap();
        assert_eq!(sol.unconverged, 0);
        for (i, w) in want.iter().enumerate() {
            assert!(
                (sol.weights[(i, 0)] - w).abs() < 1e-13,
                "w{i} = {}, expected {w}",
                sol.weights[(i, 0)]
            );
        }
        let best = brute_force(&s, &q.column(0).clone_owned(), f64::INFINITY);
        let ours = objective(
            &s,
            &q.column(0).clone_owned(),
            &sol.weights.column(0).clone_owned(),
        );
        assert!(
            (ours - best).abs() < 1e-12,
            "objective {ours} vs brute force {best}"
        );
    }
    // Two weights go negative in one full step; the step back removes only the first to
    // reach 0 and keeps the other. Optimum on {s₁, s₂, s₄}: (81/238, 440/357, 0, 664/357).
    let s = DMatrix::from_row_slice(
        4,
        4,
        &[
            3.0, 3.0, 2.0, -2.0, 0.0, 1.0, -1.0, 1.0, -2.0, 0.0, -3.0, 1.0, -1.0, 3.0, -3.0, -2.0,
        ],
    );
    let q4 = DMatrix::from_column_slice(4, 1, &[2.0, 2.0, 3.0, -1.0]);
    let want4 = [81.0 / 238.0, 440.0 / 357.0, 0.0, 664.0 / 357.0];
    for warm in [false, true] {
        let mut opts = SolveOptions::new(Solver::Nnls);
        opts.warm_start = warm;
        let sol = solve_batch(&s, &q4, &opts).unwrap();
        assert_eq!(sol.unconverged, 0);
        for (i, w) in want4.iter().enumerate() {
            assert!(
                (sol.weights[(i, 0)] - w).abs() < 1e-13,
                "4-key problem: w{i} = {}, expected {w}",
                sol.weights[(i, 0)]
            );
        }
    }
    let s = DMatrix::from_row_slice(3, 3, &[-1.0, -3.0, 1.0, -2.0, 1.0, -1.0, 2.0, 0.0, 1.0]);
    // The textbook solver agrees.
    let t = textbook::nnls(&s, &q.column(0).clone_owned());
    for (i, w) in want.iter().enumerate() {
        assert!((t[i] - w).abs() < 1e-12, "textbook w{i} = {}", t[i]);
    }
}

/// The LS pseudo-inverse's rank, condition number and null directions, against values
/// known by construction: S = U diag(σ) Vᵀ with chosen σ, one of them far below the
/// cutoff; the Gram route (`gram_pseudo_inverse`) gives the same `S⁺S⁺ᵀ`; an all-zero
/// matrix has rank 0 and an infinite (not NaN) condition number.
#[test]
fn pseudo_inverses_know_rank_condition_and_null_directions() {
    // Orthonormal U (5 × 3) and V (3 × 3) from QR of fixed matrices.
    let u = DMatrix::from_row_slice(
        5,
        3,
        &[
            1.0, 2.0, 0.5, -1.0, 0.3, 2.0, 0.7, -0.4, 1.1, 0.2, 1.5, -0.9, -0.6, 0.8, 0.4,
        ],
    )
    .qr()
    .q();
    let v = DMatrix::from_row_slice(3, 3, &[0.3, -1.2, 0.8, 1.1, 0.4, -0.5, -0.2, 0.9, 1.3])
        .qr()
        .q();
    let build =
        |s: [f64; 3]| &u * DMatrix::from_diagonal(&DVector::from_row_slice(&s)) * v.transpose();
    let full = build([4.0, 2.0, 0.5]);
    let p = lstsq::pseudo_inverse(&full, None).unwrap();
    assert_eq!(p.rank, 3);
    assert!(
        (p.condition - 8.0).abs() < 1e-9,
        "condition {}",
        p.condition
    );
    assert!((&p.pinv * &full - DMatrix::identity(3, 3)).amax() < 1e-12);
    // σ₃ = 1e-20: far below the cutoff, but positive: it must not be inverted.
    let thin = build([4.0, 2.0, 1e-20]);
    let p = lstsq::pseudo_inverse(&thin, None).unwrap();
    assert_eq!(p.rank, 2);
    let want = v.columns(0, 2)
        * DMatrix::from_diagonal(&DVector::from_row_slice(&[0.25, 0.5]))
        * u.columns(0, 2).transpose();
    assert!(
        (&p.pinv - &want).amax() < 1e-12,
        "pinv off by {}",
        (&p.pinv - &want).amax()
    );
    // Through the Gram matrix: G⁺ = S⁺ S⁺ᵀ, with the same null direction dropped.
    for s in [&full, &thin] {
        let g = s.transpose() * s;
        let p = lstsq::pseudo_inverse(s, None).unwrap().pinv;
        let want = &p * p.transpose();
        let got = lstsq::gram_pseudo_inverse(&g, None);
        assert!(
            (&got - &want).amax() < 1e-9 * want.amax(),
            "G⁺ off by {}",
            (&got - &want).amax()
        );
    }
    // A Gram matrix with an eigenvalue 1e-30 (positive, below the cutoff) and one 1e-3 λmax
    // (above it): exactly the one is dropped.
    let g =
        &v * DMatrix::from_diagonal(&DVector::from_row_slice(&[1.0, 1e-3, 1e-30])) * v.transpose();
    let got = lstsq::gram_pseudo_inverse(&g, None);
    let want = v.columns(0, 2)
        * DMatrix::from_diagonal(&DVector::from_row_slice(&[1.0, 1e3]))
        * v.columns(0, 2).transpose();
    assert!(
        (&got - &want).amax() < 1e-6,
        "G⁺ off by {}",
        (&got - &want).amax()
    );
    let z = lstsq::pseudo_inverse(&DMatrix::zeros(4, 2), None).unwrap();
    assert_eq!(z.rank, 0);
    assert_eq!(z.condition, f64::INFINITY);
    assert_eq!(z.pinv, DMatrix::zeros(2, 4));
}

/// The chunked parallel normal-equation solve equals the one-matrix solve, for frame
/// counts below, on and across the chunk size (the last chunk partial).
#[test]
fn the_batch_normal_equations_equal_the_whole_matrix_solve() {
    use keyshape_core::solve::CHUNK;
    let s = DMatrix::from_fn(9, 4, |i, j| {
        ((i * 5 + j * 3) % 7) as f64 - 3.0 + if i == j { 4.0 } else { 0.0 }
    });
    for t in [1, CHUNK - 1, CHUNK, CHUNK + 1, 3 * CHUNK + 17] {
        let q = DMatrix::from_fn(9, t, |i, f| ((i * 11 + f * 7) % 13) as f64 * 0.5 - 3.0);
        let a = lstsq::normal_equations(&s, &q).unwrap();
        let b = lstsq::normal_equations_batch(&s, &q).unwrap();
        assert_eq!(a.shape(), b.shape());
        assert!(
            (&a - &b).amax() < 1e-12,
            "{t} frames: off by {}",
            (&a - &b).amax()
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]
    /// The textbook NNLS is itself an NNLS solver, checked on its own (the tests that use it
    /// as an oracle only ask that the batch solver be no worse): every frame meets the KKT
    /// conditions to its own stopping tolerance, and its objective is the brute-force
    /// optimum over all active sets.
    #[test]
    fn the_textbook_nnls_meets_kkt_and_the_brute_force_optimum((s, q) in problem(6)) {
        for j in 0..q.ncols() {
            let qj = column(&q, j);
            let w = textbook::nnls(&s, &qj);
            let v = kkt_violation(&s, &qj, &w, f64::INFINITY);
            prop_assert!(v < 1e-10, "frame {j}: KKT violation {v:e}");
            let best = brute_force(&s, &qj, f64::INFINITY);
            let ours = objective(&s, &qj, &w);
            prop_assert!((ours - best).abs() <= 1e-10 * qj.norm_squared().max(1.0), "frame {j}: {ours} vs brute force {best}");
        }
    }
}

/// The textbook NNLS on the two hand-made problems whose Lawson–Hanson path must step back
/// (one weight, then two going negative in a full step): exact optima in fractions.
#[test]
fn the_textbook_nnls_steps_back_to_the_exact_optima() {
    let s = DMatrix::from_row_slice(3, 3, &[-1.0, -3.0, 1.0, -2.0, 1.0, -1.0, 2.0, 0.0, 1.0]);
    let q = DVector::from_column_slice(&[-1.0, -1.0, 3.0]);
    let s4 = DMatrix::from_row_slice(
        4,
        4,
        &[
            3.0, 3.0, 2.0, -2.0, 0.0, 1.0, -1.0, 1.0, -2.0, 0.0, -3.0, 1.0, -1.0, 3.0, -3.0, -2.0,
        ],
    );
    let q4 = DVector::from_column_slice(&[2.0, 2.0, 3.0, -1.0]);
    for (s, q, want) in [
        (&s, &q, vec![0.0, 9.0 / 7.0, 19.0 / 7.0]),
        (
            &s4,
            &q4,
            vec![81.0 / 238.0, 440.0 / 357.0, 0.0, 664.0 / 357.0],
        ),
    ] {
        let w = textbook::nnls(s, q);
        for (i, x) in want.iter().enumerate() {
            assert!((w[i] - x).abs() < 1e-13, "w{i} = {}, expected {x}", w[i]);
        }
    }
}

/// `gram_pseudo_inverse`'s cutoff is relative to the largest eigenvalue: on a diagonal Gram
/// matrix (exact eigenvalues) far from unit scale, an eigenvalue 1e-18 of the largest is
/// dropped and one 1e-6 of it kept, whatever the scale.
#[test]
fn the_gram_pseudo_inverse_cutoff_is_relative_to_the_largest_eigenvalue() {
    for scale in [1e-6, 1.0, 1e6] {
        let g = DMatrix::from_diagonal(&DVector::from_row_slice(&[
            scale,
            1e-6 * scale,
            1e-18 * scale,
        ]));
        let got = lstsq::gram_pseudo_inverse(&g, None);
        let want =
            DMatrix::from_diagonal(&DVector::from_row_slice(&[1.0 / scale, 1e6 / scale, 0.0]));
        assert!(
            (&got - &want).amax() <= 1e-9 * want.amax(),
            "scale {scale}: {got}"
        );
    }
}

/// `gram_pseudo_inverse` with a caller's `rcond` cuts at `rcond²·λmax` (the Gram matrix
/// squares the condition number), and a zero Gram matrix has a zero pseudo-inverse.
#[test]
fn the_gram_pseudo_inverse_takes_rcond_squared_and_maps_zero_to_zero() {
    let g = DMatrix::from_diagonal(&DVector::from_row_slice(&[1.0, 1e-5, 1e-7]));
    // rcond 1e-3: cut 1e-6, so 1e-5 is kept and 1e-7 dropped.
    let got = lstsq::gram_pseudo_inverse(&g, Some(1e-3));
    let want = DMatrix::from_diagonal(&DVector::from_row_slice(&[1.0, 1e5, 0.0]));
    assert!((&got - &want).amax() <= 1e-9 * want.amax(), "{got}");
    assert_eq!(
        lstsq::gram_pseudo_inverse(&DMatrix::zeros(3, 3), None),
        DMatrix::zeros(3, 3)
    );
}

/// The active-set solver's box is `0 ≤ w ≤ u` for any `u` the caller gives `Gram` (the
/// binary uses 1 and ∞ only). With `u` = 2.5 and 0.4 the weights at the upper bound enter
/// the free variables' right-hand side as `G_FU · u` (run 17: `· u` → `/ u` survived every
/// test, because at `u = 1` the two are the same); each frame must reach the brute-force
/// optimum and the KKT conditions, with some weight at `u`.
#[test]
fn the_active_set_solves_a_box_other_than_the_unit_box() {
    use keyshape_core::solve::active_set::{solve_frame, Bound, Gram, Workspace};
    let s = DMatrix::from_fn(7, 4, |r, c| {
        ((r * 5 + c * 3) as f64 * 0.9).sin() + 0.2 * c as f64
    });
    for upper in [2.5, 0.4] {
        let gram = Gram::new(&s, upper);
        let mut at_upper = 0;
        for (f, target) in [
            [3.0, -1.0, 1.0, 0.5],
            [1.5, 2.0, -0.5, 4.0],
            [-2.0, 5.0, 0.3, 0.2],
            [0.1, 0.2, 0.3, 9.0],
        ]
        .iter()
        .enumerate()
        {
            let wt = DVector::from_iterator(4, target.iter().map(|v| v * upper));
            let q = &s * wt + DVector::from_fn(7, |r, _| 0.05 * (r as f64 - 3.0));
            let b = s.tr_mul(&q);
            let (mut ws, mut state, mut w) =
                (Workspace::new(4), vec![Bound::Lower; 4], vec![0.0; 4]);
            let rep = solve_frame(&gram, b.as_slice(), &mut w, &mut state, &mut ws);
            assert!(rep.converged, "u = {upper}, frame {f}");
            let w = DVector::from_vec(w);
            at_upper += w.iter().filter(|&&v| v == upper).count();
            let best = brute_force(&s, &q, upper);
            let ours = objective(&s, &q, &w);
            assert!(
                (ours - best).abs() <= 1e-10 * best.max(1.0),
                "u = {upper}, frame {f}: objective {ours} vs brute force {best}, w = {w}"
            );
            assert!(kkt_violation(&s, &q, &w, upper) < 1e-12, "u = {upper}: {w}");
        }
        assert!(
            at_upper >= 3,
            "u = {upper}: only {at_upper} weights at the bound"
        );
    }
}

/// A free set whose Gram block is singular (a key shape repeated, both copies free from the
/// caller's warm start) goes to the ridge fallback of the sub-solve: `G_FF + 1e-12·max(diag)`
/// solved densely, which fits exactly and splits the repeated shape's weight between its
/// copies (about equally: the minimum-norm optimum, up to rounding). Three free variables, so the dense system is 3 × 3 (run 17:
/// every mutant of the fallback's assembly survived, because no test reached it).
#[test]
fn a_singular_free_set_is_solved_through_the_ridge() {
    use keyshape_core::solve::active_set::{solve_frame, Bound, Gram, Workspace};
    let a = DVector::from_vec(vec![1.0, 2.0, 3.0, 4.0, 5.0, 7.0, 2.5]);
    let c = DVector::from_vec(vec![0.5, -1.0, 0.0, 2.0, 1.0, -0.5, 3.0]);
    let s = DMatrix::from_columns(&[a.clone(), a.clone(), c.clone()]);
    let q = &a * 2.0 + &c * 3.0;
    let b = s.tr_mul(&q);
    for upper in [f64::INFINITY, 10.0] {
        let gram = Gram::new(&s, upper);
        let mut ws = Workspace::new(3);
        let mut state = vec![Bound::Free; 3];
        let mut w = vec![0.1, 0.2, 0.3];
        let rep = solve_frame(&gram, b.as_slice(), &mut w, &mut state, &mut ws);
        assert!(rep.converged, "u = {upper}");
        assert_eq!(state, vec![Bound::Free; 3], "u = {upper}: {w:?}");
        // The fit is exact and the copies share the weight 2; how it splits is left to
        // rounding in the null direction (the ridge's condition number is about 1e12, so
        // about 1e-4), but neither copy takes it all.
        assert!((w[0] + w[1] - 2.0).abs() < 1e-9, "u = {upper}: w = {w:?}");
        assert!((w[2] - 3.0).abs() < 1e-9, "u = {upper}: w = {w:?}");
        assert!((w[0] - 1.0).abs() < 1e-3, "u = {upper}: w = {w:?}");
        let fit = objective(&s, &q, &DVector::from_vec(w.clone()));
        assert!(
            fit < 1e-16 * q.norm_squared(),
            "u = {upper}: residual² {fit}"
        );
    }
}

/// The ridge goes on every diagonal of the free block, including the last ones: here the
/// repeated shape is the third and fourth of four free variables, so the block's null
/// direction is (0, 0, 1, −1) and only a ridge on diagonals 2 and 3 makes it definite.
/// Without it every ridge's Cholesky fails, the sub-solve returns zero, and Lawson–Hanson
/// restarts from w = 0, where it frees one copy and leaves the other at its bound (run 17's
/// `392:24`, the ridge's index `r·p + r` → `r·p − r`, which lands on diagonal 0 only
/// when p = 4).
#[test]
fn the_ridge_reaches_the_last_diagonals_of_a_singular_free_set() {
    use keyshape_core::solve::active_set::{solve_frame, Bound, Gram, Workspace};
    let a = DVector::from_vec(vec![1.0, 2.0, 3.0, 4.0, 5.0, 7.0, 2.5, -1.0]);
    let c = DVector::from_vec(vec![0.5, -1.0, 0.0, 2.0, 1.0, -0.5, 3.0, 0.0]);
    let d = DVector::from_vec(vec![0.0, 1.0, -2.0, 0.5, 0.0, 1.5, 1.0, 2.0]);
    let s = DMatrix::from_columns(&[c.clone(), d.clone(), a.clone(), a.clone()]);
    let q = &c * 1.5 + &d * 0.5 + &a * 2.0;
    let b = s.tr_mul(&q);
    for upper in [f64::INFINITY, 10.0] {
        let gram = Gram::new(&s, upper);
        let mut ws = Workspace::new(4);
        let mut state = vec![Bound::Free; 4];
        let mut w = vec![0.1, 0.2, 0.3, 0.4];
        let rep = solve_frame(&gram, b.as_slice(), &mut w, &mut state, &mut ws);
        assert!(rep.converged, "u = {upper}");
        assert_eq!(state, vec![Bound::Free; 4], "u = {upper}: {w:?}");
        assert!((w[0] - 1.5).abs() < 1e-9, "u = {upper}: w = {w:?}");
        assert!((w[1] - 0.5).abs() < 1e-9, "u = {upper}: w = {w:?}");
        assert!((w[2] + w[3] - 2.0).abs() < 1e-9, "u = {upper}: w = {w:?}");
        assert!((w[2] - 1.0).abs() < 1e-3, "u = {upper}: w = {w:?}");
    }
}
