//! The post-filters against hand-computed values, and the smoothing study's measures
//! (jitter, lag, the clean reference's low-pass) on signals whose answer is known.

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
// One segment is written `&[0..t]`: a slice holding one range, as the API takes.
#![allow(clippy::single_range_in_vec_init)]

use keyshape_core::solve::filters::{gaussian_lowpass, PostFilter};
use keyshape_core::solve::jitter::jitter;
use keyshape_core::stats::lag;
use nalgebra::DMatrix;

fn close(a: &[f64], b: &[f64], tol: f64) {
    assert_eq!(a.len(), b.len());
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        assert!((x - y).abs() <= tol, "at {i}: {x} vs {y}\n{a:?}\n{b:?}");
    }
}

#[test]
fn moving_average_is_centred_and_shrinks_at_the_ends() {
    let x = [0.0, 3.0, 6.0, 0.0, 0.0, 9.0, 0.0];
    let y = PostFilter::MovingAverage { window: 3 }.apply_signal(&x);
    // Ends: window 1 (the value itself); inside: the mean of three.
    close(&y, &[0.0, 3.0, 3.0, 2.0, 3.0, 3.0, 0.0], 1e-15);
    let y5 = PostFilter::MovingAverage { window: 5 }.apply_signal(&x);
    close(
        &y5,
        &[0.0, 3.0, 9.0 / 5.0, 18.0 / 5.0, 15.0 / 5.0, 3.0, 0.0],
        1e-15,
    );
}

#[test]
fn exponential_average_by_hand() {
    let y = PostFilter::Exponential { alpha: 0.25 }.apply_signal(&[4.0, 0.0, 8.0]);
    // y0 = x0; y1 = 0.25·0 + 0.75·4 = 3; y2 = 0.25·8 + 0.75·3 = 4.25.
    close(&y, &[4.0, 3.0, 4.25], 1e-15);
}

#[test]
fn one_euro_is_an_ema_at_beta_zero_and_opens_up_with_speed() {
    let rate = 30.0;
    let x: Vec<f64> = (0..50).map(|t| ((t * 7919) % 13) as f64 / 13.0).collect();
    let f = PostFilter::OneEuro {
        min_cutoff: 2.0,
        beta: 0.0,
        d_cutoff: 1.0,
        rate,
    };
    // α = 1 / (1 + τ·rate), τ = 1 / (2π·f_c) (Casiez et al. 2012, Eq. for the low-pass).
    let alpha = 1.0 / (1.0 + rate / (2.0 * std::f64::consts::PI * 2.0));
    close(
        &f.apply_signal(&x),
        &PostFilter::Exponential { alpha }.apply_signal(&x),
        1e-14,
    );
    // By hand, with rate 2π so that α(f_c) = f_c / (f_c + 1): d_cutoff 1 gives α_d = 1/2;
    // min_cutoff 1, beta 1, x = [0, 1, 3].
    let pi = std::f64::consts::PI;
    let y = PostFilter::OneEuro {
        min_cutoff: 1.0,
        beta: 1.0,
        d_cutoff: 1.0,
        rate: 2.0 * pi,
    }
    .apply_signal(&[0.0, 1.0, 3.0]);
    // t = 1: speed 2π, smoothed ½·2π = π, cutoff 1 + π.
    let a1 = (1.0 + pi) / (2.0 + pi);
    let y1 = a1;
    // t = 2: speed (3 − 1)·2π = 4π, smoothed ½·4π + ½·π = 2.5π, cutoff 1 + 2.5π.
    let a2 = (1.0 + 2.5 * pi) / (2.0 + 2.5 * pi);
    let y2 = a2 * 3.0 + (1.0 - a2) * y1;
    close(&y, &[0.0, y1, y2], 1e-14);
    // With beta > 0 a fast ramp is followed more closely than with beta 0.
    let ramp: Vec<f64> = (0..40).map(|t| t as f64 * 0.5).collect();
    let lagged = |beta: f64| {
        let y = PostFilter::OneEuro {
            min_cutoff: 1.0,
            beta,
            d_cutoff: 1.0,
            rate,
        }
        .apply_signal(&ramp);
        ramp[39] - y[39]
    };
    assert!(
        lagged(0.5) < 0.5 * lagged(0.0),
        "{} {}",
        lagged(0.5),
        lagged(0.0)
    );
}

#[test]
fn jitter_of_a_parabola_and_per_segment() {
    // x_t = a t² has second difference 2a everywhere: RMS 2a per value.
    let a = 0.3;
    let x = DMatrix::from_fn(2, 10, |_, t| a * (t * t) as f64);
    assert!((jitter(&x, &[0..10], 2) - 2.0 * a).abs() < 1e-12);
    // Two points per frame counted as one value each: the norm is over both rows.
    assert!((jitter(&x, &[0..10], 1) - 2.0 * a * 2f64.sqrt()).abs() < 1e-12);
    // A jump between segments is not jitter.
    let mut y = DMatrix::zeros(1, 8);
    for t in 4..8 {
        y[(0, t)] = 100.0;
    }
    assert_eq!(jitter(&y, &[0..4, 4..8], 1), 0.0);
    assert!(jitter(&y, &[0..8], 1) > 10.0);
}

#[test]
fn lag_finds_a_known_shift_and_a_centred_filter_has_none() {
    let base: Vec<f64> = (0..120)
        .map(|t| (t as f64 * 0.21).sin() + 0.5 * (t as f64 * 0.047).cos())
        .collect();
    let b = DMatrix::from_row_slice(1, 120, &base);
    for shift in [0i64, 2, 5] {
        let a = DMatrix::from_fn(1, 120, |_, t| base[(t as i64 - shift).max(0) as usize]);
        assert_eq!(lag(&a, &b, &[0..120], 15), shift);
    }
    let centred = PostFilter::MovingAverage { window: 9 }.apply_signal(&base);
    let c = DMatrix::from_row_slice(1, 120, &centred);
    assert_eq!(lag(&c, &b, &[0..120], 15), 0);
    let ema = PostFilter::Exponential { alpha: 0.15 }.apply_signal(&base);
    let e = DMatrix::from_row_slice(1, 120, &ema);
    assert!(lag(&e, &b, &[0..120], 15) >= 3);
}

#[test]
fn gaussian_lowpass_keeps_ramps_and_stays_in_segments() {
    let x = DMatrix::from_fn(1, 40, |_, t| 3.0 + 0.5 * t as f64);
    let y = gaussian_lowpass(&x, &[0..40], 2.0);
    // Symmetric kernel: a ramp is unchanged where the kernel fits (6 frames from the ends),
    // so the low-pass does not shift the reference in time.
    for t in 6..34 {
        assert!((y[(0, t)] - x[(0, t)]).abs() < 1e-12, "frame {t}");
    }
    // A step at a segment boundary stays a step.
    let s = DMatrix::from_fn(1, 20, |_, t| if t < 10 { 0.0 } else { 1.0 });
    let z = gaussian_lowpass(&s, &[0..10, 10..20], 2.0);
    assert_eq!(z, s);
    // Noise is reduced.
    let n = DMatrix::from_fn(1, 200, |_, t| if t % 2 == 0 { 1.0 } else { -1.0 });
    let m = gaussian_lowpass(&n, &[0..200], 2.0);
    assert!(
        m.columns(10, 180).amax() < 1e-3,
        "{}",
        m.columns(10, 180).amax()
    );
}
