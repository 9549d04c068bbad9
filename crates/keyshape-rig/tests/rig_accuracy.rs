//! The rig's weights measured against ground truth. Tracks rendered through the
//! ICT rig from known weights are solved back; the default solve (magnitude prior, no
//! freezing, zero-phase smoothing) must meet the goals, its per-frame optimum must
//! meet its KKT conditions, and a noise-free render must come back exactly.
//! (What runs the `kslab` binary is in `tests/it/rig_accuracy.rs`.)

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_core::solve::temporal::SmoothMode;
use keyshape_rig::accuracy::{self, Kind, Settings};
use keyshape_rig::{
    is_gaze, solve_rig, track_iod, zero_phase, Identity, Neutral, Rig, RigOptions, EXCLUSIVE,
    GAZE_DAMPING,
};
use nalgebra::DMatrix;

/// `../shared/data/<rel>` beside the repository.
fn shared(rel: &str) -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data")
        .join(rel)
}
fn ict() -> Rig {
    Rig::read_ict(&shared("ict_facekit_face")).unwrap()
}

/// The worst KKT violation of a rig solve's weights (relative to the largest curvature of
/// one weight), with each frame's camera fixed: the gradient of landmark error + μ‖w‖²
/// (gaze 100 μ) + the exclusive pairs' γ w_a w_b — plus, with the offline temporal prior,
/// λ Σ_t ‖w_t − w_{t−1}‖² — must be ≥ 0 at 0, ≤ 0 at 1 and 0 between. With `taper_from`
/// (per-frame weights), each frame's ridge of a non-gaze shape is the tapered `μ (1 − w)²`
/// of those weights instead of μ.
fn worst_kkt(
    rig: &Rig,
    points: &DMatrix<f64>,
    r: &keyshape_rig::RigSolve,
    opts: &RigOptions,
    taper_from: Option<&DMatrix<f64>>,
) -> f64 {
    let k = rig.k();
    let mu = opts.prior * track_iod(points, [36, 45]).powi(2);
    let ridge: Vec<f64> = (0..k)
        .map(|s| {
            if is_gaze(&rig.names[s]) {
                GAZE_DAMPING * mu
            } else {
                mu
            }
        })
        .collect();
    let at = |n: &str| rig.names.iter().position(|m| m == n).unwrap();
    let mut worst = 0.0f64;
    for f in 0..points.ncols() {
        let cam = &r.cameras[f];
        let w: Vec<f64> = r.weights.column(f).iter().copied().collect();
        let posed = rig.posed(&w);
        // Residual e = model − observation (y up), and A's columns d(model)/dw_s.
        let mut grad = vec![0.0; k];
        let mut scale = 0.0f64;
        for (i, p) in posed.iter().enumerate() {
            let x = cam.project(p);
            let e = [x[0] - points[(2 * i, f)], x[1] + points[(2 * i + 1, f)]];
            for (s, g) in grad.iter_mut().enumerate() {
                let d = rig.deltas[s][i];
                for row in 0..2 {
                    let a = cam.s
                        * (cam.r[(row, 0)] * d[0]
                            + cam.r[(row, 1)] * d[1]
                            + cam.r[(row, 2)] * d[2]);
                    *g += 2.0 * a * e[row];
                    scale = scale.max((2.0 * a * a).abs());
                }
            }
        }
        for (s, g) in grad.iter_mut().enumerate() {
            let mu = match taper_from {
                Some(w0) if !is_gaze(&rig.names[s]) => {
                    ridge[s] * (1.0 - w0[(s, f)].clamp(0.0, 1.0)).powi(2)
                }
                _ => ridge[s],
            };
            *g += 2.0 * mu * w[s];
        }
        if opts.smooth > 0.0 && opts.smooth_mode == SmoothMode::Offline {
            let frames = points.ncols();
            for (s, g) in grad.iter_mut().enumerate() {
                for nb in [f.wrapping_sub(1), f + 1] {
                    if nb < frames {
                        *g += 2.0 * opts.smooth * (w[s] - r.weights[(s, nb)]);
                    }
                }
            }
        }
        for (a, b, share) in EXCLUSIVE {
            let (a, b) = (at(a), at(b));
            let gamma = share * 2.0 * (ridge[a] * ridge[b]).sqrt();
            grad[a] += gamma * w[b];
            grad[b] += gamma * w[a];
        }
        for s in 0..k {
            let v = if w[s] <= 1e-9 {
                (-grad[s]).max(0.0)
            } else if w[s] >= 1.0 - 1e-9 {
                grad[s].max(0.0)
            } else {
                grad[s].abs()
            };
            worst = worst.max(v / scale);
        }
    }
    worst
}

/// The offline prior's KKT tests' case: 60 frames of the rig's own face at 1 px, and the
/// options (no identity, nothing frozen, prior 0.0026, offline λ 300), tapered or not.
fn offline_case(rig: &Rig, taper: bool) -> (accuracy::Track, RigOptions) {
    let st = Settings {
        frames: 60,
        lead_in: 0,
        other_person: false,
        noise_px: 1.0,
        ..Settings::default()
    };
    let opts = RigOptions {
        identity: Identity::None,
        min_determination: 0.0,
        prior: 0.0026,
        taper,
        smooth: 300.0,
        smooth_mode: SmoothMode::Offline,
        max_steps: 200,
        ..RigOptions::default()
    };
    (accuracy::render(rig, &st).unwrap(), opts)
}

/// The goals for 68 points, another person with a lead-in, 0.5 px, default
/// settings: mean r ≥ 0.96, worst ≥ 0.90, RMSE ≤ 0.08, no unused shape above 0.5 (measured
/// 0.976 / 0.912 / 0.059 / 0.34; 0.974 / 0.907 / 0.071 / 0.24 with the plain ridge). The
/// plain solve of before misses them (0.745 / 0.000 / 0.156 / 1.00), so the test fails on
/// the old default. At 1 px: mean ≥ 0.88, worst ≥ 0.5, RMSE ≤ 0.09 (measured 0.952 / 0.848
/// / 0.079; the plain ridge and the uncentred neutral search left 0.092).
#[test]
fn the_default_solve_meets_the_goals_on_a_smooth_performance() {
    let rig = ict();
    let (_, _, _, s) =
        accuracy::run(&rig, &Settings::default(), &RigOptions::recommended()).unwrap();
    assert!(s.mean_r >= 0.96, "{s:?}");
    assert!(s.worst_r >= 0.90, "{s:?}");
    assert!(s.rmse <= 0.08, "{s:?}");
    assert!(s.max_idle < 0.5, "{s:?}");
    let (_, _, _, old) = accuracy::run(&rig, &Settings::default(), &RigOptions::default()).unwrap();
    assert!(old.worst_r < 0.5 && old.max_idle > 0.9, "{old:?}");
    let noisy = Settings {
        noise_px: 1.0,
        ..Settings::default()
    };
    let (_, _, _, s) = accuracy::run(&rig, &noisy, &RigOptions::recommended()).unwrap();
    assert!(
        s.mean_r >= 0.88 && s.worst_r >= 0.5 && s.rmse <= 0.09,
        "{s:?}"
    );
}

/// The hardest shape over 20 seeds (68 points, 0.5 px, the lead-in as the neutral, no
/// smoothing: the settings `tools/rig_reference.py` was run at). The worst shape's 10th
/// percentile over the seeds is at least the ridge reference's 0.636 on the smooth
/// performance, whose smiles and frowns are on together at random (measured 0.679; 0.564
/// with the full smile / frown term of the exclusive pairs), and its median is at least the
/// 0.805 it was (measured 0.851). The same seeds with the smile / frown pairs at the full
/// term give the old figure, so the test fails on it.
#[test]
fn the_hardest_shape_over_seeds_is_at_least_the_references() {
    let rig = ict();
    let opts = RigOptions {
        neutral: Neutral::Span(0, Settings::default().lead_in),
        zero_phase: 0.0,
        ..RigOptions::recommended()
    };
    let worst: Vec<(f64, String)> = (1..=20)
        .map(|seed| {
            let st = Settings {
                seed,
                ..Settings::default()
            };
            let s = accuracy::run(&rig, &st, &opts).unwrap().3;
            (s.worst_r, s.worst_shape)
        })
        .collect();
    let mut r: Vec<f64> = worst.iter().map(|w| w.0).collect();
    r.sort_by(f64::total_cmp);
    // Nearest rank over 20: the 10th percentile is the 2nd lowest, the median the 10th.
    let (p10, median) = (r[1], r[9]);
    assert!(p10 >= 0.636, "p10 {p10:.3}: {worst:?}");
    assert!(median >= 0.805, "median {median:.3}: {worst:?}");
}

/// Winks, the goal at 68 points: every one-sided shape comes through (r ≥ 0.95) and
/// reaches ≥ 0.85 at its peaks, its twin stays < 0.15 and every other shape < 0.4
/// (measured: lowest peak 0.86, browDown_L; twins ≤ 0.06; others ≤ 0.20). The plain ridge
/// shrank the peaks to 0.68: the tapered prior is what reaches them.
#[test]
fn winks_come_through_one_sided() {
    let rig = ict();
    let st = Settings {
        kind: Kind::Winks,
        ..Settings::default()
    };
    let (_, _, rows, s) = accuracy::run(&rig, &st, &RigOptions::recommended()).unwrap();
    for name in accuracy::WINK_SHAPES {
        let r = rows.iter().find(|r| r.shape == name).unwrap();
        assert!(r.r >= 0.95, "{name}: {r:?}");
        assert!(r.twin_leakage.unwrap() < 0.15, "{name}: {r:?}");
        assert!(r.peak_reach.unwrap() >= 0.85, "{name}: {r:?}");
    }
    assert!(s.max_idle < 0.4, "{s:?}");
    let plain = RigOptions {
        taper: false,
        ..RigOptions::recommended()
    };
    let (_, _, _, p) = accuracy::run(&rig, &st, &plain).unwrap();
    assert!(p.min_peak_reach.unwrap() < 0.75, "{p:?}");
}

/// Blinks under a held smile, with a neutral lead-in: the automatic neutral finds the
/// lead-in, not a frame inside the smile (measured mean r 0.978 against 0.980 with the
/// lead-in named; the uncentred search took frame 204, inside the smile: 0.903).
#[test]
fn the_automatic_neutral_finds_the_lead_in_under_a_held_smile() {
    let rig = ict();
    let st = Settings {
        kind: Kind::Blinks,
        ..Settings::default()
    };
    let (_, _, _, auto) = accuracy::run(&rig, &st, &RigOptions::recommended()).unwrap();
    let named = RigOptions {
        neutral: keyshape_rig::Neutral::Column(st.lead_in / 2),
        ..RigOptions::recommended()
    };
    let (_, _, _, lead) = accuracy::run(&rig, &st, &named).unwrap();
    assert!(auto.mean_r >= 0.97 && auto.worst_r >= 0.95, "{auto:?}");
    assert!(auto.mean_r >= lead.mean_r - 0.01, "{auto:?} {lead:?}");
}

/// A noise-free render of the rig itself (no identity to find, the priors off, every shape
/// free) is fitted exactly: the landmarks come back to rounding, and the shapes the
/// performance drives come back to 1e-6.
#[test]
fn a_noise_free_render_comes_back_exactly_with_the_priors_off() {
    let rig = ict();
    let st = Settings {
        noise_px: 0.0,
        other_person: false,
        lead_in: 0,
        frames: 60,
        ..Settings::default()
    };
    let track = accuracy::render(&rig, &st).unwrap();
    let opts = RigOptions {
        identity: Identity::None,
        min_determination: 0.0,
        ..RigOptions::default()
    };
    let r = solve_rig(&rig, &track.points, &[], &opts).unwrap();
    let worst_rms = r.rms.iter().copied().fold(0.0, f64::max);
    assert!(worst_rms < 1e-6, "landmark RMS {worst_rms}");
    let driven: Vec<usize> = accuracy::SMOOTH_SHAPES
        .iter()
        .map(|n| rig.names.iter().position(|m| m == n).unwrap())
        .collect();
    let worst_w = driven
        .iter()
        .flat_map(|&s| (0..60).map(move |f| (s, f)))
        .map(|(s, f)| (r.weights[(s, f)] - track.truth[(s, f)]).abs())
        .fold(0.0, f64::max);
    assert!(worst_w < 1e-6, "worst driven weight error {worst_w}");
    // With the magnitude prior on, the fit is no longer exact but stays close.
    let on = solve_rig(
        &rig,
        &track.points,
        &[],
        &RigOptions {
            prior: 0.0026,
            ..opts
        },
    )
    .unwrap();
    let mean_rms = on.rms.iter().sum::<f64>() / on.rms.len() as f64;
    assert!(mean_rms > 1e-6 && mean_rms < 1.0, "{mean_rms}");
}

/// The prior's optimum meets its KKT conditions on every frame: with the frame's camera
/// fixed, the model is linear in the weights, and the gradient of landmark error + μ‖w‖²
/// (gaze 100 μ) + the exclusive pairs' γ w_a w_b is ≥ 0 at 0, ≤ 0 at 1 and 0 between.
#[test]
fn the_prior_optimum_meets_its_kkt_conditions() {
    let rig = ict();
    let st = Settings {
        frames: 40,
        lead_in: 0,
        other_person: false,
        ..Settings::default()
    };
    let track = accuracy::render(&rig, &st).unwrap();
    let opts = RigOptions {
        identity: Identity::None,
        min_determination: 0.0,
        prior: 0.0026,
        max_steps: 200,
        ..RigOptions::default()
    };
    let r = solve_rig(&rig, &track.points, &[], &opts).unwrap();
    let worst = worst_kkt(&rig, &track.points, &r, &opts, None);
    // Relative to the largest curvature of one weight: measured 2e-6 (the solve stops at
    // a relative objective change of 1e-12).
    assert!(worst < 1e-3, "worst KKT violation {worst}");
}

/// The zero-phase smoothing keeps constants and bounds, and moves no peak (no lag).
#[test]
fn zero_phase_smoothing_has_no_lag_and_keeps_bounds() {
    let n = 41;
    let mut w = DMatrix::from_fn(2, n, |i, t| {
        if i == 0 {
            0.7
        } else {
            (-((t as f64 - 20.0) / 4.0).powi(2)).exp()
        }
    });
    zero_phase(&mut w, 0..n, 2.0);
    assert!(w.row(0).iter().all(|v| (v - 0.7).abs() < 1e-12));
    let peak = (0..n)
        .max_by(|&a, &b| w[(1, a)].total_cmp(&w[(1, b)]))
        .unwrap();
    assert_eq!(peak, 20);
    assert!(w.iter().all(|v| (0.0..=1.0).contains(v)));
    // Symmetric about the peak.
    for d in 1..10 {
        assert!((w[(1, 20 - d)] - w[(1, 20 + d)]).abs() < 1e-12);
    }
}

/// The offline temporal prior's optimum (the whole clip at once, with the magnitude prior)
/// meets the KKT conditions of the whole-clip problem, is smoother than the per-frame solve,
/// and lags no shape it recovers.
#[test]
fn the_offline_temporal_prior_meets_its_kkt_conditions() {
    let rig = ict();
    let (track, opts) = offline_case(&rig, false);
    let r = solve_rig(&rig, &track.points, &[], &opts).unwrap();
    assert!(
        r.sweeps > 1 && r.sweeps_unconverged == 0,
        "{} sweeps",
        r.sweeps
    );
    let worst = worst_kkt(&rig, &track.points, &r, &opts, None);
    // Measured 1.2e-7 after 67 sweeps (they stop when no weight moves by more than 1e-6).
    assert!(worst < 1e-3, "worst KKT violation {worst}");
    // Smoother than the per-frame solve, and no lag on the performance's shapes.
    let plain = solve_rig(
        &rig,
        &track.points,
        &[],
        &RigOptions {
            smooth: 0.0,
            ..opts
        },
    )
    .unwrap();
    let jit = |w: &DMatrix<f64>| {
        keyshape_core::solve::jitter::weight_jitter(w, std::slice::from_ref(&(0..60)))
    };
    assert!(jit(&r.weights) < 0.8 * jit(&plain.weights));
    let (rows, _) = accuracy::measure(&rig.names, &track.truth, &r.weights);
    // (On shapes it recovers: 60 frames of a bump are too few for every shape.)
    let recovered: Vec<_> = rows.iter().filter(|r| r.active && r.r >= 0.8).collect();
    assert!(recovered.len() >= 8, "{rows:?}");
    for row in recovered {
        assert!(row.lag.unwrap().abs() <= 1, "{row:?}");
    }
}

/// With the tapered prior, the offline temporal prior holds each frame's ridge where the
/// per-frame solve left it, `μ (1 − w_t)²`, and its optimum meets the KKT conditions of
/// that clip-wide problem.
#[test]
fn the_offline_prior_with_the_taper_meets_its_kkt_conditions() {
    let rig = ict();
    let (track, opts) = offline_case(&rig, true);
    let per_frame = solve_rig(
        &rig,
        &track.points,
        &[],
        &RigOptions {
            smooth: 0.0,
            ..opts
        },
    )
    .unwrap();
    let r = solve_rig(&rig, &track.points, &[], &opts).unwrap();
    assert!(r.sweeps > 1 && r.sweeps_unconverged == 0, "{}", r.sweeps);
    let worst = worst_kkt(&rig, &track.points, &r, &opts, Some(&per_frame.weights));
    assert!(worst < 1e-3, "worst KKT violation {worst}");
    // And not of the plain ridge's problem: the taper changed the weights.
    let plain = worst_kkt(&rig, &track.points, &r, &opts, None);
    assert!(plain > 10.0 * worst.max(1e-9), "{plain} against {worst}");
}

/// A recorded lead-in named as a stretch (`--neutral FIRST-LAST`) is averaged into one
/// identity, so no single frame's landmark noise becomes the person's face: at 1 px the
/// weights come back closer than from the lead-in's middle frame alone (measured RMSE 0.059
/// against 0.081), and with no noise the stretch and one of its frames agree (every
/// lead-in frame is the same face, up to the 2-D identity's missing depth as the head
/// turns).
#[test]
fn a_lead_in_named_as_a_stretch_is_averaged_into_the_identity() {
    let rig = ict();
    let noisy = Settings {
        noise_px: 1.0,
        ..Settings::default()
    };
    let with = |st: &Settings, neutral| {
        let opts = RigOptions {
            neutral,
            ..RigOptions::recommended()
        };
        accuracy::run(&rig, st, &opts).unwrap().3
    };
    let span = with(&noisy, Neutral::Span(0, noisy.lead_in));
    let one = with(&noisy, Neutral::Column(noisy.lead_in / 2));
    eprintln!("span {span:?}\none {one:?}");
    assert!(
        span.rmse < 0.85 * one.rmse,
        "{} against {}",
        span.rmse,
        one.rmse
    );
    let clean = Settings {
        noise_px: 0.0,
        ..Settings::default()
    };
    let (a, b) = (
        with(&clean, Neutral::Span(0, clean.lead_in)),
        with(&clean, Neutral::Column(clean.lead_in / 2)),
    );
    assert!((a.rmse - b.rmse).abs() < 0.01, "{a:?} {b:?}");
    // A stretch that is empty or runs past the track is refused by value.
    let track = accuracy::render(&rig, &clean).unwrap();
    for (x, y) in [(5, 5), (6, 2), (0, track.points.ncols() + 1)] {
        let opts = RigOptions {
            neutral: Neutral::Span(x, y),
            ..RigOptions::recommended()
        };
        let e = solve_rig(&rig, &track.points, &[], &opts)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&format!("neutral frame columns {x}..{y}")),
            "{e}"
        );
    }
}
