//! The temporal prior: λ = 0 is the plain solve, the offline solution meets the
//! KKT conditions of its objective (checked here from the objective's gradient written out,
//! not through the library), LS matches a dense solve of the whole system, segments do not
//! couple, causal frames meet their own KKT conditions, and jitter falls with λ on a real
//! track.

// One segment is written `&[0..t]`: a slice holding one range, as the API takes.
#![allow(clippy::single_range_in_vec_init)]

use keyshape_core::solve::temporal::{segments, solve_smooth, SmoothMode, Smoothing};
use keyshape_core::solve::{solve_batch, SolveOptions, Solver};
use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;

fn sm(lambda: f64, order: usize, mode: SmoothMode) -> Smoothing {
    Smoothing {
        lambda,
        order,
        mode,
    }
}

/// The gradient of `E(W) = Σ‖S w_t − q_t‖² + λ Σ‖(D W)_t‖²` written out frame by frame.
fn gradient(
    s: &DMatrix<f64>,
    q: &DMatrix<f64>,
    w: &DMatrix<f64>,
    lambda: f64,
    order: usize,
) -> DMatrix<f64> {
    let t = q.ncols();
    let mut g = (s.transpose() * (s * w - q)) * 2.0;
    if order == 1 {
        for f in 1..t {
            let d = (w.column(f) - w.column(f - 1)) * (2.0 * lambda);
            let mut a = g.column_mut(f);
            a += &d;
            let mut b = g.column_mut(f - 1);
            b -= &d;
        }
    } else {
        for f in 1..t.saturating_sub(1) {
            let d = (w.column(f + 1) - w.column(f) * 2.0 + w.column(f - 1)) * (2.0 * lambda);
            let mut a = g.column_mut(f + 1);
            a += &d;
            let mut b = g.column_mut(f);
            b -= &d * 2.0;
            let mut c = g.column_mut(f - 1);
            c += &d;
        }
    }
    g
}

/// Largest KKT violation relative to the gradient's scale: |g| inside the bounds, the
/// wrong sign at a bound, infeasibility.
fn kkt(g: &DMatrix<f64>, w: &DMatrix<f64>, solver: Solver, scale: f64) -> f64 {
    let upper = if solver == Solver::Bounded {
        1.0
    } else {
        f64::INFINITY
    };
    let mut worst = 0.0f64;
    for (gi, wi) in g.iter().zip(w.iter()) {
        let v = match solver {
            Solver::Ls => gi.abs(),
            _ if *wi < -1e-12 || *wi > upper + 1e-12 => f64::INFINITY,
            _ if *wi <= 1e-12 => (-gi).max(0.0),
            _ if *wi >= upper - 1e-12 => gi.max(0.0),
            _ => gi.abs(),
        };
        worst = worst.max(v);
    }
    worst / scale
}

fn problem(n: usize, k: usize, t: usize, seed: &[f64], dup: bool) -> (DMatrix<f64>, DMatrix<f64>) {
    let at = |i: usize| seed[i % seed.len()];
    let mut s = DMatrix::from_fn(n, k, |i, j| {
        at(i * 7 + j * 3) + if i == j { 1.5 } else { 0.0 }
    });
    if dup && k > 2 {
        let c = s.column(0).clone_owned();
        s.set_column(k - 1, &c); // rank deficient: a duplicate key shape
    }
    let q = DMatrix::from_fn(n, t, |i, f| {
        at(i * 5 + f * 11) * 2.0 + (f as f64 * 0.3).sin()
    });
    (s, q)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn offline_solutions_meet_the_kkt_conditions(
        seed in prop::collection::vec(-1.0f64..1.0, 40),
        k in 2usize..6,
        t in 2usize..40,
        lambda in prop::sample::select(vec![0.01, 0.3, 3.0, 100.0, 1e4, 1e6]),
        order in 1usize..3,
        solver in prop::sample::select(vec![Solver::Ls, Solver::Nnls, Solver::Bounded]),
        dup in any::<bool>(),
    ) {
        let (s, q) = problem(8, k, t, &seed, dup);
        let r = solve_smooth(&s, &q, solver, &sm(lambda, order, SmoothMode::Offline), &[0..t]).unwrap();
        prop_assert_eq!(r.unconverged, 0);
        let g = gradient(&s, &q, &r.weights, lambda, order);
        let scale = 2.0 * ((s.transpose() * &q).amax() + (s.transpose() * &s).amax().max(16.0 * lambda) * r.weights.amax());
        let v = kkt(&g, &r.weights, solver, scale.max(1.0));
        prop_assert!(v < 1e-8, "KKT {v:e} (library says {:e})", r.kkt);
        prop_assert!(r.kkt < 1e-8);
    }

    #[test]
    fn causal_frames_meet_their_own_kkt_conditions(
        seed in prop::collection::vec(-1.0f64..1.0, 40),
        k in 2usize..6,
        lambda in prop::sample::select(vec![0.1, 5.0]),
        order in 1usize..3,
        solver in prop::sample::select(vec![Solver::Ls, Solver::Nnls, Solver::Bounded]),
    ) {
        let t = 12;
        let (s, q) = problem(8, k, t, &seed, false);
        let r = solve_smooth(&s, &q, solver, &sm(lambda, order, SmoothMode::Causal), &[0..t]).unwrap();
        let w = &r.weights;
        for f in 0..t {
            // Frame f minimises ‖S w − q_f‖² + λ‖w − p_f‖², p_f from the frames before it.
            let p: Option<DVector<f64>> = match f {
                0 => None,
                1 => Some(w.column(0).clone_owned()),
                _ if order == 1 => Some(w.column(f - 1).clone_owned()),
                _ => Some(w.column(f - 1) * 2.0 - w.column(f - 2)),
            };
            let wf = w.column(f).clone_owned();
            let mut g = s.transpose() * (&s * &wf - q.column(f)) * 2.0;
            if let Some(p) = &p {
                g += (&wf - p) * (2.0 * lambda);
            }
            let gm = DMatrix::from_column_slice(k, 1, g.as_slice());
            let wm = DMatrix::from_column_slice(k, 1, wf.as_slice());
            let scale = 2.0 * ((s.transpose() * q.column(f)).amax() + ((s.transpose() * &s).amax() + lambda) * wf.amax().max(1.0)) + 2.0 * lambda * p.as_ref().map_or(0.0, |p| p.amax());
            let v = kkt(&gm, &wm, solver, scale);
            prop_assert!(v < 1e-9, "frame {f}: KKT {v:e}");
        }
    }
}

#[test]
fn lambda_zero_is_the_plain_solve_and_bad_settings_are_refused() {
    let seed: Vec<f64> = (0..40)
        .map(|i| ((i * 37) % 17) as f64 / 8.0 - 1.0)
        .collect();
    let (s, q) = problem(8, 4, 30, &seed, false);
    for solver in Solver::ALL {
        let plain = solve_batch(&s, &q, &SolveOptions::new(solver)).unwrap();
        for mode in [SmoothMode::Offline, SmoothMode::Causal] {
            let r = solve_smooth(&s, &q, solver, &sm(0.0, 1, mode), &[0..30]).unwrap();
            assert_eq!(r.weights, plain.weights, "{solver} {mode:?}");
        }
    }
    for bad in [-1.0, f64::NAN, f64::INFINITY] {
        let e = solve_smooth(
            &s,
            &q,
            Solver::Nnls,
            &sm(bad, 1, SmoothMode::Offline),
            &[0..30],
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("λ must be a finite number ≥ 0"), "{e}");
    }
    assert!(solve_smooth(
        &s,
        &q,
        Solver::Nnls,
        &sm(1.0, 3, SmoothMode::Offline),
        &[0..30]
    )
    .is_err());
    assert!(solve_smooth(
        &s,
        &q,
        Solver::Nnls,
        &sm(1.0, 1, SmoothMode::Offline),
        &[0..29]
    )
    .is_err());
}

/// LS offline is the linear system `(I ⊗ SᵀS + λ DᵀD ⊗ I) w = Sᵀq`: solved densely here.
#[test]
fn ls_offline_matches_a_dense_solve_of_the_whole_system() {
    let seed: Vec<f64> = (0..40)
        .map(|i| ((i * 29) % 13) as f64 / 6.0 - 1.0)
        .collect();
    for order in [1, 2] {
        let (k, t, lambda) = (3, 9, 2.5);
        let (s, q) = problem(6, k, t, &seed, false);
        let r = solve_smooth(
            &s,
            &q,
            Solver::Ls,
            &sm(lambda, order, SmoothMode::Offline),
            &[0..t],
        )
        .unwrap();
        let rows = t - order;
        let d = DMatrix::from_fn(rows, t, |r, c| match (order, c as i64 - r as i64) {
            (1, 0) => -1.0,
            (1, 1) => 1.0,
            (2, 0) | (2, 2) => 1.0,
            (2, 1) => -2.0,
            _ => 0.0,
        });
        let dtd = d.transpose() * d;
        let g = s.transpose() * &s;
        let h = DMatrix::from_fn(k * t, k * t, |a, b| {
            let (fa, ia, fb, ib) = (a / k, a % k, b / k, b % k);
            (if fa == fb { g[(ia, ib)] } else { 0.0 })
                + if ia == ib {
                    lambda * dtd[(fa, fb)]
                } else {
                    0.0
                }
        });
        let rhs = DVector::from_column_slice((s.transpose() * &q).as_slice());
        let want = h.lu().solve(&rhs).unwrap();
        let got = DVector::from_column_slice(r.weights.as_slice());
        assert!((got - &want).amax() < 1e-8 * want.amax(), "order {order}");
    }
}

#[test]
fn segments_split_at_clip_changes_and_gaps_and_do_not_couple() {
    let lab = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    assert_eq!(segments(&[0, 1, 2, 5, 6], None), vec![0..3, 3..5]);
    assert_eq!(segments(&[0, 2, 4, 6, 8], None), vec![0..5]);
    assert_eq!(
        segments(&[0, 2, 4, 0, 2], Some(&lab(&["a", "a", "a", "b", "b"]))),
        vec![0..3, 3..5]
    );
    let seed: Vec<f64> = (0..40)
        .map(|i| ((i * 31) % 19) as f64 / 9.0 - 1.0)
        .collect();
    let (s, q) = problem(8, 4, 20, &seed, false);
    for solver in Solver::ALL {
        let both = solve_smooth(
            &s,
            &q,
            solver,
            &sm(4.0, 2, SmoothMode::Offline),
            &[0..8, 8..20],
        )
        .unwrap();
        let a = solve_smooth(
            &s,
            &q.columns(0, 8).clone_owned(),
            solver,
            &sm(4.0, 2, SmoothMode::Offline),
            &[0..8],
        )
        .unwrap();
        let b = solve_smooth(
            &s,
            &q.columns(8, 12).clone_owned(),
            solver,
            &sm(4.0, 2, SmoothMode::Offline),
            &[0..12],
        )
        .unwrap();
        assert!((both.weights.columns(0, 8) - &a.weights).amax() < 1e-12);
        assert!((both.weights.columns(8, 12) - &b.weights).amax() < 1e-12);
    }
}

/// On a real lips track the weights' jitter (mean squared second difference) falls as λ
/// grows, and the fit error rises, for both orders.
#[test]
fn jitter_falls_and_error_rises_with_lambda_on_a_real_track() {
    let prep = d6_lips();
    let q = prep.seq.coords.columns(0, 300).clone_owned();
    let keys = [0usize, 40, 80, 120, 160, 200, 240, 280];
    let s = q.select_columns(&keys);
    let jitter = |w: &DMatrix<f64>| {
        let mut acc = 0.0;
        for f in 1..w.ncols() - 1 {
            acc += (w.column(f + 1) - w.column(f) * 2.0 + w.column(f - 1)).norm_squared();
        }
        acc / (w.ncols() - 2) as f64
    };
    for order in [1, 2] {
        let mut last = (f64::INFINITY, 0.0);
        for lambda in [0.0, 10.0, 100.0, 1000.0] {
            let r = solve_smooth(
                &s,
                &q,
                Solver::Nnls,
                &sm(lambda, order, SmoothMode::Offline),
                &[0..300],
            )
            .unwrap();
            assert!(r.kkt < 1e-8, "λ {lambda}: KKT {}", r.kkt);
            let (j, e) = (jitter(&r.weights), (&s * &r.weights - &q).norm_squared());
            assert!(
                j < last.0 && e >= last.1 - 1e-9,
                "order {order} λ {lambda}: jitter {j} error {e}"
            );
            last = (j, e);
        }
    }
}

/// The case the primal–dual active set cannot finish alone: the second-difference prior at
/// large λ on a real lips track (it cycles; projected Newton takes over). Checked against
/// the gradient written out above, at the library's own stopping tolerance scale.
#[test]
fn second_difference_prior_at_large_lambda_settles_on_a_real_track() {
    let prep = d6_lips();
    let q = &prep.seq.coords;
    let t = q.ncols();
    // The spread heuristic's 12 key frames on this track (`kslab keys --method spread --k 12`).
    let keys = [58usize, 7, 777, 219, 450, 942, 769, 720, 889, 595, 993, 866];
    let s = q.select_columns(&keys);
    for (solver, lambda) in [
        (Solver::Nnls, 1e5),
        (Solver::Nnls, 1e6),
        (Solver::Bounded, 1e7),
    ] {
        let r = solve_smooth(&s, q, solver, &sm(lambda, 2, SmoothMode::Offline), &[0..t]).unwrap();
        assert_eq!(r.unconverged, 0, "{solver:?} λ {lambda}: KKT {:e}", r.kkt);
        let g = gradient(&s, q, &r.weights, lambda, 2);
        let scale = 2.0
            * ((s.transpose() * q).amax()
                + (s.transpose() * &s).amax().max(16.0 * lambda) * r.weights.amax());
        let v = kkt(&g, &r.weights, solver, scale);
        assert!(
            v < 1e-9,
            "{solver:?} λ {lambda}: KKT {v:e} (library {:e})",
            r.kkt
        );
        // The per-frame start is far from it: smoothing did something.
        let plain = solve_batch(&s, q, &SolveOptions::new(solver)).unwrap();
        assert!((&plain.weights - &r.weights).amax() > 0.1);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// The two-ended factorisation (long segments) solves the same system as the one-sweep
    /// one, with any variables fixed, for both orders and separators anywhere. The ridge
    /// is the prior's 1e-12 or a large 0.5: at 1e-12 a separator that dropped the ridge
    /// from its diagonal (or put it off the diagonal) solved the same to 1e-9 (run 28).
    #[test]
    fn two_ended_factorisation_matches_the_one_sweep_solve(
        seed in prop::collection::vec(-1.0f64..1.0, 40),
        k in 1usize..5,
        t in 8usize..40,
        lambda in prop::sample::select(vec![0.05, 2.0, 300.0]),
        order in 1usize..3,
        ridge in prop::sample::select(vec![1e-12, 0.5]),
        fixed_bits in prop::collection::vec(any::<bool>(), 160),
    ) {
        use keyshape_core::solve::temporal::{difference_bands, SegmentSystem};
        let (s, _) = problem(8, k, 2, &seed, false);
        let g = s.transpose() * &s;
        let bands = difference_bands(order, t);
        let fixed: Vec<bool> = (0..t * k).map(|i| fixed_bits[i % fixed_bits.len()] && i % 3 == 0).collect();
        let rhs: Vec<f64> = (0..t * k).map(|i| seed[(i * 7) % seed.len()] * 3.0).collect();
        let mut one = SegmentSystem::factor(&g, lambda, &bands, &fixed, ridge, false).unwrap();
        let mut two = SegmentSystem::factor(&g, lambda, &bands, &fixed, ridge, true).unwrap();
        prop_assert!(matches!(two, SegmentSystem::Split(_)) || t < 4 * order + 4);
        let (mut x1, mut x2) = (rhs.clone(), rhs.clone());
        one.solve(&mut x1);
        two.solve(&mut x2);
        let scale = x1.iter().fold(1.0f64, |m, v| m.max(v.abs()));
        for i in 0..x1.len() {
            prop_assert!((x1[i] - x2[i]).abs() <= 1e-9 * scale, "at {}: {} vs {}", i, x1[i], x2[i]);
            if fixed[i] {
                prop_assert_eq!(x2[i], rhs[i]);
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// The banded factorisation (which stores only packed diagonal blocks and the blocks
    /// inside the band, and applies the outermost one as a triangular solve) solves the
    /// dense system: `H = I ⊗ G + λ·w·DᵀD ⊗ I + δI` (w a weight) with the fixed variables' rows and columns
    /// replaced by the identity, built entry by entry here and solved by nalgebra's LU.
    /// Order 3 (a third difference, bands read off the dense `DᵀD`: `difference_bands`
    /// makes only the prior's orders 1 and 2) is the only order with a stored block
    /// strictly inside the band that a row's update reads (`L_{s,r}` with `1 < s − r < p`);
    /// `BandedSystem::factor` is public and takes any bands.
    #[test]
    fn the_banded_factorisation_solves_the_dense_system(
        seed in prop::collection::vec(-1.0f64..1.0, 40),
        k in 1usize..5,
        t in 1usize..14,
        lambda in prop::sample::select(vec![0.05, 2.0, 300.0]),
        order in 1usize..4,
        weight in prop::sample::select(vec![1.0, 0.5, 3.0]),
        fixed_bits in prop::collection::vec(any::<bool>(), 70),
    ) {
        use keyshape_core::solve::temporal::{difference_bands, SegmentSystem};
        let (s, _) = problem(8, k, 2, &seed, false);
        let g = s.transpose() * &s;
        let ridge = 1e-12;
        let n = t * k;
        let fixed: Vec<bool> = (0..n).map(|i| fixed_bits[i % fixed_bits.len()]).collect();
        // D (rows of the difference operator) and DᵀD, densely.
        let coef: &[f64] = match order {
            1 => &[-1.0, 1.0],
            2 => &[1.0, -2.0, 1.0],
            _ => &[-1.0, 3.0, -3.0, 1.0],
        };
        let mut dtd = DMatrix::<f64>::zeros(t, t);
        for r in 0..t.saturating_sub(order) {
            for (a, ca) in coef.iter().enumerate() {
                for (b, cb) in coef.iter().enumerate() {
                    dtd[(r + a, r + b)] += ca * cb;
                }
            }
        }
        // band[j][i] = DᵀD(i, i − j).
        let read_off: Vec<Vec<f64>> = (0..=order)
            .map(|j| (0..t).map(|i| if i >= j { dtd[(i, i - j)] } else { 0.0 }).collect())
            .collect();
        let bands = if order < 3 {
            let bands = difference_bands(order, t);
            prop_assert_eq!(&bands, &read_off);
            bands
        } else {
            read_off
        };
        // A weighted penalty `weight · DᵀD`: its outermost band is then not ±1, the only
        // value a plain difference gives it (where `λ · band` and `λ / band` agree: run 25).
        let bands: Vec<Vec<f64>> =
            bands.iter().map(|b| b.iter().map(|v| v * weight).collect()).collect();
        let mut h = DMatrix::<f64>::zeros(n, n);
        for u in 0..n {
            for v in 0..n {
                let (su, iu, sv, iv) = (u / k, u % k, v / k, v % k);
                let mut e = if su == sv { g[(iu, iv)] } else { 0.0 };
                if iu == iv {
                    e += lambda * weight * dtd[(su, sv)] + if u == v { ridge } else { 0.0 };
                }
                h[(u, v)] = if fixed[u] || fixed[v] { f64::from(u8::from(u == v)) } else { e };
            }
        }
        let rhs: Vec<f64> = (0..n).map(|i| seed[(i * 7) % seed.len()] * 3.0).collect();
        let want = h.clone().lu().solve(&DVector::from_column_slice(&rhs)).unwrap();
        let mut sys = SegmentSystem::factor(&g, lambda, &bands, &fixed, ridge, false).unwrap();
        let mut got = rhs.clone();
        sys.solve(&mut got);
        let scale = want.iter().fold(1.0f64, |m, v| m.max(v.abs()));
        for i in 0..n {
            prop_assert!((got[i] - want[i]).abs() <= 1e-8 * scale, "at {}: {} vs {}", i, got[i], want[i]);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Refactorising from an earlier factorisation under another mask (the active-set
    /// iterations do) gives bit for bit the factor a fresh factorisation gives, one sweep
    /// or two-ended, whichever frames' masks changed.
    #[test]
    fn reusing_an_earlier_factorisation_is_exact(
        seed in prop::collection::vec(-1.0f64..1.0, 40),
        k in 1usize..5,
        t in 8usize..40,
        lambda in prop::sample::select(vec![0.05, 2.0, 300.0]),
        order in 1usize..3,
        split in any::<bool>(),
        bits_a in prop::collection::vec(any::<bool>(), 160),
        changed in prop::collection::vec(0usize..160, 0..6),
    ) {
        use keyshape_core::solve::temporal::{difference_bands, SegmentSystem};
        let (s, _) = problem(8, k, 2, &seed, false);
        let g = s.transpose() * &s;
        let bands = difference_bands(order, t);
        let first: Vec<bool> = (0..t * k).map(|i| bits_a[i % bits_a.len()] && i % 3 == 0).collect();
        let mut second = first.clone();
        for c in &changed {
            let i = c % second.len();
            second[i] = !second[i];
        }
        let old = SegmentSystem::factor(&g, lambda, &bands, &first, 1e-12, split).unwrap();
        let spare = SegmentSystem::factor(&g, lambda, &bands, &second, 1e-12, split).unwrap();
        let mut fresh = SegmentSystem::factor(&g, lambda, &bands, &second, 1e-12, split).unwrap();
        let mut reused = SegmentSystem::factor_reusing(
            &g, lambda, &bands, &second, 1e-12, split, Some(&old), Some(spare),
        )
        .unwrap();
        let rhs: Vec<f64> = (0..t * k).map(|i| seed[(i * 7) % seed.len()] * 3.0).collect();
        let (mut x1, mut x2) = (rhs.clone(), rhs.clone());
        fresh.solve(&mut x1);
        reused.solve(&mut x2);
        for i in 0..x1.len() {
            prop_assert_eq!(x1[i].to_bits(), x2[i].to_bits(), "at {}: {} vs {}", i, x1[i], x2[i]);
        }
        // The reuse takes effect: the frames before the first changed one, at least, are
        // copied (in the one-sweep factorisation; the two-ended one copies per half).
        prop_assert_eq!(fresh.copied_rows(), 0);
        let changed_frames: Vec<usize> = (0..t)
            .filter(|&f| first[f * k..(f + 1) * k] != second[f * k..(f + 1) * k])
            .collect();
        match changed_frames.first() {
            None => prop_assert_eq!(reused.copied_rows(), t - usize::from(split && t >= 4 * order + 4) * order),
            Some(&f0) if !split => prop_assert!(reused.copied_rows() >= f0, "{} copied, first change at {}", reused.copied_rows(), f0),
            Some(_) => {}
        }
    }
}

/// An earlier factorisation of another segment length or order is not reused (its rows
/// do not line up): the result is the fresh one and nothing is copied.
#[test]
fn an_incompatible_earlier_factorisation_is_not_reused() {
    use keyshape_core::solve::temporal::{difference_bands, SegmentSystem};
    let seed: Vec<f64> = (0..40)
        .map(|i| ((i * 37 % 17) as f64 - 8.0) / 9.0)
        .collect();
    let (s, _) = problem(8, 3, 2, &seed, false);
    let g = s.transpose() * &s;
    let (t, k) = (12, 3);
    let fixed: Vec<bool> = (0..t * k).map(|i| i % 4 == 0).collect();
    let mut fresh =
        SegmentSystem::factor(&g, 5.0, &difference_bands(1, t), &fixed, 1e-12, false).unwrap();
    let rhs: Vec<f64> = (0..t * k).map(|i| seed[i % seed.len()]).collect();
    let mut want = rhs.clone();
    fresh.solve(&mut want);
    for (ot, order) in [(t + 1, 1), (t - 1, 1), (t, 2)] {
        let ofixed: Vec<bool> = (0..ot * k).map(|i| i % 4 == 0).collect();
        let old =
            SegmentSystem::factor(&g, 5.0, &difference_bands(order, ot), &ofixed, 1e-12, false)
                .unwrap();
        let mut re = SegmentSystem::factor_reusing(
            &g,
            5.0,
            &difference_bands(1, t),
            &fixed,
            1e-12,
            false,
            Some(&old),
            None,
        )
        .unwrap();
        assert_eq!(
            re.copied_rows(),
            0,
            "reused rows of a {ot}-frame order-{order} factor"
        );
        let mut got = rhs.clone();
        re.solve(&mut got);
        assert_eq!(got, want);
    }
    // The same segment and order is reused whole when nothing changed.
    let same = SegmentSystem::factor_reusing(
        &g,
        5.0,
        &difference_bands(1, t),
        &fixed,
        1e-12,
        false,
        Some(&fresh),
        None,
    )
    .unwrap();
    assert_eq!(same.copied_rows(), t);
}

/// A change of mask in one frame changes the rows after it only while the recurrence
/// carries it: `L`'s rows contract towards what they were, so a few frames on a recomputed
/// row is the old one bit for bit and copying resumes (the doc of `factor_reusing`), with
/// solves the same as a fresh factor's. Run 25: with the bit-for-bit comparison broken,
/// copying stopped at the change for good, and no test counted the rows after it.
#[test]
fn reuse_resumes_copying_once_a_changed_mask_has_died_out() {
    use keyshape_core::solve::temporal::{difference_bands, SegmentSystem};
    let seed: Vec<f64> = (0..40)
        .map(|i| ((i * 37 % 17) as f64 - 8.0) / 9.0)
        .collect();
    let (s, _) = problem(8, 3, 2, &seed, false);
    let g = s.transpose() * &s;
    let (t, k, lambda) = (200, 3, 0.05);
    for order in [1, 2] {
        let bands = difference_bands(order, t);
        let first: Vec<bool> = (0..t * k).map(|i| i % 5 == 0).collect();
        let mut second = first.clone();
        second[10 * k + 1] = !second[10 * k + 1];
        let old = SegmentSystem::factor(&g, lambda, &bands, &first, 1e-12, false).unwrap();
        let mut re = SegmentSystem::factor_reusing(
            &g,
            lambda,
            &bands,
            &second,
            1e-12,
            false,
            Some(&old),
            None,
        )
        .unwrap();
        let copied = re.copied_rows();
        // Frames 0..10 are copied outright; of the 190 from the change on, all but the
        // few the change reaches before it rounds away (measured: 6 at order 1, 15 at 2).
        assert!(
            copied >= t - 20 && copied < t,
            "order {order}: {copied} of {t} rows copied"
        );
        let mut fresh = SegmentSystem::factor(&g, lambda, &bands, &second, 1e-12, false).unwrap();
        let rhs: Vec<f64> = (0..t * k).map(|i| seed[i % seed.len()]).collect();
        let (mut a, mut b) = (rhs.clone(), rhs);
        re.solve(&mut a);
        fresh.solve(&mut b);
        assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
    }
}

/// The objective `--json` states, per mode and order.
#[test]
fn the_objective_is_named_for_each_mode_and_order() {
    for (mode, order, prior) in [
        (SmoothMode::Offline, 1, "λ Σ_t ‖w_t − w_{t−1}‖²"),
        (SmoothMode::Offline, 2, "λ Σ_t ‖w_{t+1} − 2w_t + w_{t−1}‖²"),
        (SmoothMode::Causal, 1, "λ ‖w_t − w_{t−1}‖² per frame"),
        (
            SmoothMode::Causal,
            2,
            "λ ‖w_t − (2w_{t−1} − w_{t−2})‖² per frame",
        ),
    ] {
        assert_eq!(
            sm(1.0, order, mode).objective(),
            format!("Σ_t ‖S w_t − q_t‖² + {prior}, segments independent")
        );
    }
    assert_eq!(SmoothMode::Offline.name(), "offline");
    assert_eq!(SmoothMode::Causal.name(), "causal");
}

/// The usual step is the smallest positive difference between frame numbers, wherever they
/// start: every 2nd frame from 10, with a gap after 14.
#[test]
fn segments_find_the_step_of_a_track_that_does_not_start_at_zero() {
    assert_eq!(segments(&[10, 12, 14, 20, 22], None), vec![0..3, 3..5]);
    assert_eq!(segments(&[5, 6, 7], None), vec![0..3]);
    assert_eq!(segments(&[7], None), vec![0..1]);
    // A repeated frame number (the readers refuse them; the library need not) breaks the
    // chain there and does not make the step 0.
    assert_eq!(segments(&[0, 1, 1, 2], None), vec![0..2, 2..4]);
    assert!(segments(&[], None).is_empty());
}

/// liveportrait_d6's lips, aligned.
fn d6_lips() -> keyshape_core::decompose::Prepared {
    let seq = keyshape_io::read_sequence(
        &crate::common::shared("mediapipe_face_tracks/liveportrait_d6.csv"),
        &Default::default(),
    )
    .unwrap();
    keyshape_core::decompose::prepare(
        &seq,
        &keyshape_core::decompose::PrepareOptions::group_aligned("lips"),
    )
    .unwrap()
}

/// A system that is not positive definite is refused with the frame it fails at, not
/// factorised into NaNs (the prior's callers never build one; the guard is for the rest).
#[test]
fn an_indefinite_banded_system_is_refused() {
    use keyshape_core::solve::temporal::{difference_bands, SegmentSystem};
    // One variable per frame: frame 0's pivot is −1 + 0.1 < 0.
    let g = -DMatrix::<f64>::identity(1, 1);
    let fixed = vec![false; 5];
    let e = SegmentSystem::factor(&g, 0.1, &difference_bands(1, 5), &fixed, 0.0, false)
        .err()
        .expect("an indefinite system factorised");
    assert!(
        e.to_string().contains("not positive definite at frame 0"),
        "{e}"
    );
    // Positive definite but for one NaN entry: refused too.
    let g = DMatrix::<f64>::from_element(1, 1, f64::NAN);
    let e = SegmentSystem::factor(&g, 0.1, &difference_bands(1, 5), &fixed, 0.0, false)
        .err()
        .expect("a NaN system factorised");
    assert!(e.to_string().contains("at frame 0 (pivot NaN)"), "{e}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    /// A factor kept a window at a time (long segments) solves bit for bit as the whole
    /// factor does — every recomputed row is the row first computed — at lengths on and
    /// around the block boundaries, with any variables fixed, for bands of order 1 to 3; it
    /// holds a window and its checkpoints, not the factor; and it refuses what the whole
    /// one refuses.
    #[test]
    fn a_windowed_factor_solves_bit_for_bit_as_the_whole_one(
        seed in prop::collection::vec(-1.0f64..1.0, 40),
        k in 1usize..5,
        t in prop::sample::select(vec![1usize, 2, 3, 5, 1023, 1024, 1025, 1026, 2048, 2050, 3100]),
        lambda in prop::sample::select(vec![0.05, 2.0, 300.0, 1e5]),
        order in 1usize..4,
        fixed_bits in prop::collection::vec(any::<bool>(), 97),
    ) {
        use keyshape_core::solve::temporal::{difference_bands, BandedSystem, WINDOW_BLOCK};
        let (s, _) = problem(8, k, 2, &seed, false);
        let g = s.transpose() * &s;
        // Order 3 (a third difference, built here: `difference_bands` makes orders 1 and 2)
        // is the only order whose rows read a stored block inside the band, at an offset
        // from the window's base.
        let bands = if order < 3 {
            difference_bands(order, t)
        } else {
            let coef = [-1.0, 3.0, -3.0, 1.0];
            let mut band = vec![vec![0.0; t]; 4];
            for r in 0..t.saturating_sub(3) {
                for a in 0..4 {
                    for b in 0..=a {
                        band[a - b][r + a] += coef[a] * coef[b];
                    }
                }
            }
            band
        };
        let fixed: Vec<bool> = (0..t * k).map(|i| fixed_bits[i % fixed_bits.len()] && i % 3 == 0).collect();
        let rhs: Vec<f64> = (0..t * k).map(|i| seed[(i * 7) % seed.len()] * 3.0).collect();
        let mut whole = BandedSystem::factor(&g, lambda, &bands, &fixed, 1e-12).unwrap();
        let mut win = BandedSystem::factor_windowed(&g, lambda, &bands, &fixed, 1e-12).unwrap();
        prop_assert!(!whole.is_windowed() && win.is_windowed());
        let (mut x1, mut x2) = (rhs.clone(), rhs.clone());
        whole.solve(&mut x1);
        win.solve(&mut x2);
        prop_assert!(x1.iter().zip(&x2).all(|(a, b)| a.to_bits() == b.to_bits()));
        // Again: the second solve starts from the window the first left.
        let mut x3 = rhs.clone();
        win.solve(&mut x3);
        prop_assert!(x2.iter().zip(&x3).all(|(a, b)| a.to_bits() == b.to_bits()));
        // The window (at most a block and 2·order rows) and one checkpoint per block.
        let row = k * (k + 1) / 2 + (order - 1) * k * k;
        let bound = (WINDOW_BLOCK + 2 * order) * row + t.div_ceil(WINDOW_BLOCK) * order * row;
        prop_assert!(win.stored_values() <= bound, "{} > {bound}", win.stored_values());
        if t > 3 * WINDOW_BLOCK {
            prop_assert!(win.stored_values() < whole.stored_values() / 2);
        }
    }
}

/// A windowed factorisation reports a failed pivot at the frame the whole one does.
#[test]
fn a_windowed_factor_refuses_what_the_whole_one_refuses() {
    use keyshape_core::solve::temporal::{difference_bands, BandedSystem};
    // G = 0 and no ridge: H = λ·DᵀD is singular (constant weights are its null space),
    // and the last pivot of a chain is the one that reaches zero.
    let g = DMatrix::<f64>::zeros(1, 1);
    for t in [5, 1500, 2048] {
        let bands = difference_bands(1, t);
        let fixed = vec![false; t];
        let a = BandedSystem::factor(&g, 1.0, &bands, &fixed, 0.0)
            .err()
            .map(|e| e.to_string());
        let b = BandedSystem::factor_windowed(&g, 1.0, &bands, &fixed, 0.0)
            .err()
            .map(|e| e.to_string());
        assert!(a.is_some(), "{t} frames factorised");
        assert_eq!(a, b);
    }
}

/// The whole offline path on a segment long enough to be two-ended with windowed halves
/// (132,000 frames): the solution meets the KKT conditions, written out here frame by
/// frame, as a short segment's does.
#[test]
fn a_segment_long_enough_to_be_windowed_meets_the_kkt_conditions() {
    use keyshape_core::solve::temporal::WINDOW_FRAMES;
    let seed: Vec<f64> = (0..40)
        .map(|i| ((i * 37 % 17) as f64 / 8.5) - 1.0)
        .collect();
    let t = 132_000;
    assert!((t - 2) / 2 >= WINDOW_FRAMES, "the halves must be windowed");
    let (s, q) = problem(8, 3, t, &seed, false);
    for (order, lambda, solver) in [(1, 100.0, Solver::Ls), (2, 1e4, Solver::Nnls)] {
        let r = solve_smooth(
            &s,
            &q,
            solver,
            &sm(lambda, order, SmoothMode::Offline),
            &[0..t],
        )
        .unwrap();
        assert_eq!(r.unconverged, 0);
        let g = gradient(&s, &q, &r.weights, lambda, order);
        let scale = 2.0
            * ((s.transpose() * &q).amax()
                + (s.transpose() * &s).amax().max(16.0 * lambda) * r.weights.amax());
        let v = kkt(&g, &r.weights, solver, scale.max(1.0));
        assert!(
            v < 1e-8,
            "order {order} {solver:?}: KKT {v:e} (library says {:e})",
            r.kkt
        );
    }
}

/// What a windowed factor holds, exactly: after a solve (which ends on the first block),
/// the rows of frames 0..B + p and, per block after the first, a checkpoint of p rows; with
/// nothing fixed every row of frame s ≥ p holds `k(k+1)/2 + (p − 1)k²` values.
#[test]
fn a_windowed_factor_holds_one_window_and_its_checkpoints() {
    use keyshape_core::solve::temporal::{difference_bands, BandedSystem, WINDOW_BLOCK};
    let (k, t) = (3, 3 * WINDOW_BLOCK + 28);
    let g = DMatrix::from_fn(k, k, |i, j| if i == j { 2.0 } else { 0.3 });
    for p in [1usize, 2] {
        let bands = difference_bands(p, t);
        let fixed = vec![false; t * k];
        let mut sys = BandedSystem::factor_windowed(&g, 5.0, &bands, &fixed, 1e-12).unwrap();
        let row = |s: usize| k * (k + 1) / 2 + if s >= 1 && p == 2 { k * k } else { 0 };
        let checkpoints = (t.div_ceil(WINDOW_BLOCK) - 1) * p * row(p);
        // After the factorisation: the last block and the p rows before it.
        let last = (t - 1) / WINDOW_BLOCK * WINDOW_BLOCK;
        let window: usize = (last - p..t).map(row).sum();
        assert_eq!(
            sys.stored_values(),
            window + checkpoints,
            "order {p}, factorised"
        );
        let mut rhs = vec![1.0; t * k];
        sys.solve(&mut rhs);
        let window: usize = (0..WINDOW_BLOCK + p).map(row).sum();
        assert_eq!(
            sys.stored_values(),
            window + checkpoints,
            "order {p}, solved"
        );
    }
}

/// `kkt_residual` is the worst violation of the KKT conditions of `½wᵀHw − bᵀw` over the
/// box, `H = I ⊗ G + λ·DᵀD ⊗ I` built densely here, relative to `max|b| + max(H_ii) ·
/// max|w|` with `max(H_ii)` bounded by `max G_ii + 4λ` (order 1) or `+ 16λ` (order 2). Run
/// 17: returning 0 survived every test, because each solve it checks converges anyway and
/// the tests compute their own KKT conditions; a point off the optimum must be reported.
#[test]
fn the_kkt_residual_is_the_worst_violation_of_a_point_off_the_optimum() {
    use keyshape_core::solve::temporal::kkt_residual;
    let g = DMatrix::from_row_slice(2, 2, &[2.0, 0.5, 0.5, 1.0]);
    let (k, t, lambda) = (2, 4, 0.75);
    let b = [1.0, -2.0, 0.5, 3.0, -1.5, 0.25, 2.0, 1.0];
    for order in [1, 2] {
        // Dense D (rows: differences of `order` consecutive frames) and H.
        let coef: &[f64] = if order == 1 {
            &[-1.0, 1.0]
        } else {
            &[1.0, -2.0, 1.0]
        };
        let mut d = DMatrix::zeros(t - order, t);
        for r in 0..t - order {
            for (a, c) in coef.iter().enumerate() {
                d[(r, r + a)] = *c;
            }
        }
        let h = DMatrix::identity(t, t).kronecker(&g)
            + (d.transpose() * &d * lambda).kronecker(&DMatrix::<f64>::identity(k, k));
        let hmax = 2.0 + lambda * if order == 1 { 4.0 } else { 16.0 };
        for (solver, w) in [
            (Solver::Ls, [0.3, -0.2, 0.1, 0.9, 0.0, 0.4, -0.6, 0.2]),
            // At 0 with the gradient pointing in (no violation) or out; inside; one
            // negative (infeasible: its distance to the box times max H_ii).
            (Solver::Nnls, [0.0, 0.0, 0.5, 1.5, 0.0, 0.2, 0.7, -0.05]),
            // At the upper bound 1 with the gradient pushing up (fine) or down.
            (Solver::Bounded, [1.0, 0.0, 1.0, 0.5, 0.0, 1.0, 0.3, 1.0]),
        ] {
            let wv = DVector::from_row_slice(&w);
            let grad = &h * &wv - DVector::from_row_slice(&b);
            let upper = if solver == Solver::Bounded {
                1.0
            } else {
                f64::INFINITY
            };
            let mut worst = 0.0f64;
            for i in 0..w.len() {
                let v = if solver == Solver::Ls {
                    grad[i].abs()
                } else if w[i] < 0.0 {
                    -w[i] * hmax
                } else if w[i] == 0.0 {
                    (-grad[i]).max(0.0)
                } else if w[i] == upper {
                    grad[i].max(0.0)
                } else {
                    grad[i].abs()
                };
                worst = worst.max(v);
            }
            let wmax = w.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let want = worst / (3.0 + hmax * wmax);
            let got = kkt_residual(&g, lambda, order, &b, &w, solver);
            assert!(
                want > 1e-3,
                "order {order}, {solver}: the point must be off the optimum"
            );
            assert!(
                (got - want).abs() <= 1e-14 * want,
                "order {order}, {solver}: kkt_residual {got}, by hand {want}"
            );
            // Nothing to violate at b = 0, w = 0 (a zero scale is taken as 1, not 0/0).
            let zero = kkt_residual(&g, lambda, order, &[0.0; 8], &[0.0; 8], solver);
            assert_eq!(zero, 0.0, "order {order}, {solver}");
        }
    }
    // A weight within 1e-12 · max(1, max|w|) of 0 counts as at 0: one variable, two frames,
    // H = [[2, −1], [−1, 2]], w = (2, 1e-12), b = (4, −3): the gradient (−1e-12, 1) pushes
    // the second weight onto its bound, which is no violation (measured from its distance
    // 1e-12 as interior, it would be 1 / 14).
    let one = DMatrix::from_element(1, 1, 1.0);
    let near = kkt_residual(&one, 1.0, 1, &[4.0, -3.0], &[2.0, 1e-12], Solver::Nnls);
    assert!(near < 1e-12, "kkt_residual {near}");
    // Outside the box the violation is the distance to it times max H_ii (= 1 + 4λ = 5),
    // whatever the gradient: w = (2, −0.5) has gradient (0.5, 0), so 0.5 · 5 / (4 + 5 · 2);
    // bounded, w = (1.25, 0.5) with b = (4, −0.25) has gradient (−2, 0), so
    // 0.25 · 5 / (4 + 5 · 1.25).
    let out = kkt_residual(&one, 1.0, 1, &[4.0, -3.0], &[2.0, -0.5], Solver::Nnls);
    assert!((out - 2.5 / 14.0).abs() < 1e-15, "kkt_residual {out}");
    let over = kkt_residual(&one, 1.0, 1, &[4.0, -0.25], &[1.25, 0.5], Solver::Bounded);
    assert!((over - 1.25 / 10.25).abs() < 1e-15, "kkt_residual {over}");
}

/// One key shape `s = (1, 0)` (so G = 1) and λ = 0.5 over two frames: the Hessian of
/// `½wᵀHw − bᵀw` is `[[1.5, −0.5], [−0.5, 1.5]]` and each case below is small enough to
/// follow the primal–dual active set by hand from the per-frame solution. In each, the
/// first step's active set is the optimal one, so the solve is one banded solve
/// (`iterations == 1`) and the weights are exact. Projected Newton, the fallback, reaches
/// the same optimum from the same start, so only the iteration count shows whether the
/// active-set step itself works (run 18: every mutant of its gradient, its bound tests and
/// its fixed-value right-hand side survived, masked by the fallback).
fn one_shape_two_frames(b: [f64; 2]) -> (DMatrix<f64>, DMatrix<f64>) {
    let s = DMatrix::from_column_slice(2, 1, &[1.0, 0.0]);
    let q = DMatrix::from_column_slice(2, 2, &[b[0], 0.0, b[1], 0.0]);
    (s, q)
}

#[test]
fn the_active_set_finishes_a_hand_worked_segment_in_one_step() {
    let smooth = sm(0.5, 1, SmoothMode::Offline);
    // (solver, b, optimum). NNLS, b = (1, −1): frame 2 is held at 0 and frame 1 solves
    // 1.5·w₁ = 1. Bounded, b = (3, 0.2): frame 1 at its bound 1, frame 2 free with
    // 1.5·w₂ = 0.2 + 0.5·1. Bounded, b = (3, 3): both at 1 (every fixed value non-zero).
    let cases = [
        (Solver::Nnls, [1.0, -1.0], [2.0 / 3.0, 0.0]),
        (Solver::Bounded, [3.0, 0.2], [1.0, 0.7 / 1.5]),
        (Solver::Bounded, [3.0, 3.0], [1.0, 1.0]),
    ];
    for (solver, b, want) in cases {
        let (s, q) = one_shape_two_frames(b);
        let r = solve_smooth(&s, &q, solver, &smooth, &[0..2]).unwrap();
        // 1e-11: the segment's ridge, 1e-12·(G + 4λ), shifts the free weight by ~1e-12.
        for t in 0..2 {
            assert!(
                (r.weights[(0, t)] - want[t]).abs() < 1e-11,
                "{solver:?} b = {b:?}: w = {}",
                r.weights
            );
        }
        assert_eq!(r.iterations, 1, "{solver:?} b = {b:?}");
        assert_eq!(r.unconverged, 0, "{solver:?} b = {b:?}");
        assert!(r.kkt < 1e-12, "{solver:?} b = {b:?}: kkt {}", r.kkt);
    }
    // Two such segments side by side: nothing couples them, and the counts add up.
    let s = DMatrix::from_column_slice(2, 1, &[1.0, 0.0]);
    let q = DMatrix::from_column_slice(2, 4, &[1.0, 0.0, -1.0, 0.0, 3.0, 0.0, 0.2, 0.0]);
    let r = solve_smooth(&s, &q, Solver::Bounded, &smooth, &[0..2, 2..4]).unwrap();
    let want = [2.0 / 3.0, 0.0, 1.0, 0.7 / 1.5];
    for (t, w) in want.iter().enumerate() {
        assert!((r.weights[(0, t)] - w).abs() < 1e-11, "w = {}", r.weights);
    }
    assert_eq!(r.iterations, 2);
    assert_eq!(r.segments, vec![0..2, 2..4]);
}

/// Causal NNLS counts the active-set iterations of every frame and reports the worst
/// per-frame KKT residual: with one key shape and every frame's target (and so its
/// right-hand side `b_t + λ·prediction`) positive, each frame's solve from w = 0 frees the
/// one weight, one iteration per frame, over both segments; and each frame's weight solves
/// its own problem exactly, so the residual the library reports is rounding. Order 2
/// predicts from two frames (`2w_{t−1} − w_{t−2}`), order 1 from one.
#[test]
fn causal_iterations_are_counted_per_frame_and_the_kkt_is_each_frames() {
    let s = DMatrix::from_column_slice(2, 1, &[1.0, 0.0]);
    let targets = [0.5, 0.6, 0.7, 0.65, 0.55];
    let q = DMatrix::from_fn(2, 5, |i, j| if i == 0 { targets[j] } else { 0.0 });
    for order in [1, 2] {
        for solver in [Solver::Nnls, Solver::Bounded] {
            let smooth = sm(0.5, order, SmoothMode::Causal);
            let r = solve_smooth(&s, &q, solver, &smooth, &[0..3, 3..5]).unwrap();
            assert_eq!(r.iterations, 5, "order {order} {solver:?}");
            assert_eq!(r.unconverged, 0, "order {order} {solver:?}");
            assert!(r.kkt < 1e-12, "order {order} {solver:?}: kkt {}", r.kkt);
            // The same weights, checked by hand: frame t of a segment solves
            // (1 + λ)·w = q_t + λ·prediction (the first frame: w = q_t).
            for seg in [0..3, 3..5] {
                let mut w: Vec<f64> = Vec::new();
                for (i, col) in seg.clone().enumerate() {
                    let x = match i {
                        0 => targets[col],
                        1 => (targets[col] + 0.5 * w[0]) / 1.5,
                        _ if order == 1 => (targets[col] + 0.5 * w[i - 1]) / 1.5,
                        _ => (targets[col] + 0.5 * (2.0 * w[i - 1] - w[i - 2])) / 1.5,
                    };
                    w.push(x);
                    assert!(
                        (r.weights[(0, col)] - x).abs() < 1e-12,
                        "order {order} {solver:?} frame {col}: {} vs {x}",
                        r.weights[(0, col)]
                    );
                }
            }
        }
    }
}

/// Segments must partition the frames in order: too few frames covered is refused even
/// when no segment runs past the end, and so are a gap, an overlap (which covers the right
/// number of frames but solves one twice and another never) and an empty segment.
#[test]
fn segments_that_do_not_cover_the_frames_are_refused() {
    use keyshape_core::solve::temporal::smooth_from;
    let (s, q) = one_shape_two_frames([1.0, 1.0]);
    let q = DMatrix::from_fn(2, 4, |i, j| q[(i, j % 2)]);
    let plain = solve_batch(&s, &q, &SolveOptions::new(Solver::Nnls)).unwrap();
    let smooth = sm(0.5, 1, SmoothMode::Offline);
    // (segments, what the error says). [0..2, 1..3] covers four frames' worth but solves
    // frame 1 twice and frame 3 never.
    let bad: [(&[std::ops::Range<usize>], &str); 6] = [
        (&[0..3], "segments cover 3 of 4 frames"),
        (&[0..2, 2..5], "segments cover 5 of 4 frames"),
        (&[], "segments cover 0 of 4 frames"),
        (&[0..2, 3..4], "3..4 follows frame 2"),
        (&[0..1, 2..5], "2..5 follows frame 1"),
        (&[0..2, 1..3], "1..3 follows frame 2"),
    ];
    for (segs, says) in bad {
        let e = solve_smooth(&s, &q, Solver::Nnls, &smooth, segs).unwrap_err();
        assert!(e.to_string().contains(says), "{segs:?}: {e}");
        let e = smooth_from(&s, &q, &plain, Solver::Nnls, &smooth, segs).unwrap_err();
        assert!(e.to_string().contains(says), "{segs:?}: {e}");
    }
    let e = solve_smooth(&s, &q, Solver::Nnls, &smooth, &[0..2, 2..2, 2..4]).unwrap_err();
    assert!(
        e.to_string().contains("segment 2..2 holds no frames"),
        "{e}"
    );
    assert!(solve_smooth(&s, &q, Solver::Nnls, &smooth, &[0..2, 2..4]).is_ok());
}
