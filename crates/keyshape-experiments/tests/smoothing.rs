//! The smoothing study's equal-jitter table: its interpolation along each curve.

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_core::solve::filters::PostFilter;
use keyshape_core::solve::Solver;
use keyshape_experiments::experiment::smoothing::{at_equal_jitter, SmoothRow};
use nalgebra::DMatrix;

fn close(a: &[f64], b: &[f64], tol: f64) {
    assert_eq!(a.len(), b.len());
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        assert!((x - y).abs() <= tol, "at {i}: {x} vs {y}\n{a:?}\n{b:?}");
    }
}

fn row(approach: &str, jitter: f64, err: f64) -> SmoothRow {
    SmoothRow {
        approach: approach.into(),
        setting: String::new(),
        source_rms: 0.0,
        target_rms_tracked: err,
        target_rms_clean: err + 1.0,
        jitter_target: jitter,
        jitter_weights: 0.0,
        // A lag that names the row, to see which setting the table took it from.
        lag_frames: (jitter * 10.0) as i64,
        kkt: None,
    }
}

#[test]
fn filters_clamp_to_the_solver_and_keep_segments_apart() {
    // Row 0 jumps from 0 to 1 at a segment boundary; a filter across it would blur it.
    let w = DMatrix::from_row_slice(2, 6, &[0., 0., 0., 1., 1., 1., -1., 2., -1., 2., 2., 2.]);
    let segs = [0..3, 3..6];
    let ma = PostFilter::MovingAverage { window: 3 };
    let out = ma.apply(&w, &segs, Solver::Nnls).unwrap();
    close(
        &out.row(0).iter().copied().collect::<Vec<_>>(),
        &[0., 0., 0., 1., 1., 1.],
        1e-15,
    );
    // Row 1, first segment: [-1, 0, -1] → clamped at 0 for NNLS.
    let r1: Vec<f64> = out.row(1).iter().copied().collect();
    close(&r1, &[0., 0., 0., 2., 2., 2.], 1e-15);
    let b = ma.apply(&w, &segs, Solver::Bounded).unwrap();
    assert!(b.iter().all(|v| (0.0..=1.0).contains(v)), "{b}");
    let ls = ma.apply(&w, &segs, Solver::Ls).unwrap();
    assert_eq!(ls[(1, 0)], -1.0);
    for bad in [
        PostFilter::MovingAverage { window: 4 },
        PostFilter::MovingAverage { window: 0 },
        PostFilter::Exponential { alpha: 0.0 },
        PostFilter::Exponential { alpha: 1.5 },
        PostFilter::OneEuro {
            min_cutoff: f64::NAN,
            beta: 0.0,
            d_cutoff: 1.0,
            rate: 30.0,
        },
        PostFilter::OneEuro {
            min_cutoff: 1.0,
            beta: -1.0,
            d_cutoff: 1.0,
            rate: 30.0,
        },
        // The bounds themselves: a zero cutoff or rate freezes the filter.
        PostFilter::OneEuro {
            min_cutoff: 0.0,
            beta: 0.0,
            d_cutoff: 1.0,
            rate: 30.0,
        },
        PostFilter::OneEuro {
            min_cutoff: 1.0,
            beta: 0.0,
            d_cutoff: 0.0,
            rate: 30.0,
        },
        PostFilter::OneEuro {
            min_cutoff: 1.0,
            beta: 0.0,
            d_cutoff: 1.0,
            rate: 0.0,
        },
    ] {
        let e = bad.apply(&w, &segs, Solver::Nnls).unwrap_err().to_string();
        let family = match bad {
            PostFilter::MovingAverage { .. } => "moving-average",
            PostFilter::Exponential { .. } => "ema",
            PostFilter::OneEuro { .. } => "one-euro",
        };
        assert_eq!(bad.family(), family);
        assert!(
            e.starts_with(&format!("bad {family} filter setting: ")),
            "{e}"
        );
    }
    // The bounds that are allowed: window 1 and alpha 1 leave the weights as they are.
    for ok in [
        PostFilter::MovingAverage { window: 1 },
        PostFilter::Exponential { alpha: 1.0 },
    ] {
        assert_eq!(ok.apply(&w, &segs, Solver::Ls).unwrap(), w, "{ok:?}");
    }
    // beta 0 is allowed (One Euro is then an EMA).
    assert!(PostFilter::OneEuro {
        min_cutoff: 1.0,
        beta: 0.0,
        d_cutoff: 1.0,
        rate: 30.0,
    }
    .check()
    .is_ok());
}

#[test]
fn equal_jitter_interpolates_along_each_curve() {
    let rows = vec![
        row("none", 10.0, 1.0),
        row("a", 8.0, 2.0),
        row("a", 4.0, 4.0),
        // b's jitter falls, then rises again: 5 is reached only on its first stretch.
        row("b", 6.0, 3.0),
        row("b", 7.0, 9.0),
        row("b", 2.0, 20.0),
    ];
    let t = at_equal_jitter(&rows, &[0.5, 0.3]);
    let get = |name: &str, level: f64| {
        t.iter()
            .find(|r| r.approach == name && (r.jitter_target - level).abs() < 1e-12)
            .unwrap()
    };
    // a at 5: between (8, 2) and (4, 4): 2 + (3/4)·2 = 3.5.
    assert!((get("a", 5.0).target_rms_tracked.unwrap() - 3.5).abs() < 1e-12);
    assert!((get("a", 5.0).target_rms_clean.unwrap() - 4.5).abs() < 1e-12);
    // a never reaches 3.
    assert!(get("a", 3.0).target_rms_tracked.is_none());
    // b at 5: the stretch (7, 9) → (2, 20), not (6, 3) → (2, 20) by sorting: 9 + (2/5)·11.
    assert!((get("b", 5.0).target_rms_tracked.unwrap() - 13.4).abs() < 1e-12);
    // b at 3: same stretch, 9 + (4/5)·11.
    assert!((get("b", 3.0).target_rms_tracked.unwrap() - 17.8).abs() < 1e-12);
    // The lag is the nearer setting's: a at 5 is 3/4 of the way to (4, 4); b at 5 is 2/5
    // of the way from (7, 9), b at 3 is 4/5 of the way.
    assert_eq!(get("a", 5.0).lag_frames, Some(40));
    assert_eq!(get("b", 5.0).lag_frames, Some(70));
    assert_eq!(get("b", 3.0).lag_frames, Some(20));
    // Exactly half way goes to the stronger setting.
    let half = at_equal_jitter(&[row("none", 10.0, 1.0), row("c", 6.0, 3.0)], &[0.8]);
    assert_eq!(half[0].lag_frames, Some(60));
    assert!((half[0].target_rms_tracked.unwrap() - 2.0).abs() < 1e-12);
    assert!((half[0].jitter_target - 8.0).abs() < 1e-12);
    // Without a `none` row there is nothing to scale by.
    assert!(at_equal_jitter(&[row("c", 6.0, 3.0)], &[0.5]).is_empty());
}
