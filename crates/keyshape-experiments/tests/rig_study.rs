//! The `[rig]` study's own numbers: the calibrated reference's regression.

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::DMatrix;

/// The calibrated reference's regression: on outputs that are exactly affine in the
/// features, a whisper of ridge predicts every held-out group exactly; a huge ridge
/// predicts the other groups' mean.
#[test]
fn leave_one_group_out_ridge_predicts_affine_outputs_exactly() {
    use keyshape_experiments::experiment::rig_study::leave_one_group_out_ridge;
    let n = 60;
    let x = DMatrix::from_fn(n, 3, |f, j| ((f * (j + 2)) as f64 * 0.37).sin() + j as f64);
    let x = x.insert_column(3, 5.0); // a constant feature is dropped, not divided by 0
    let y = DMatrix::from_fn(n, 2, |f, k| {
        1.5 * x[(f, 0)] - 2.0 * x[(f, 1)] + (k as f64 + 0.5) * x[(f, 2)] + 3.0 - k as f64
    });
    let groups: Vec<Vec<usize>> = (0..4).map(|g| (g * 15..(g + 1) * 15).collect()).collect();
    let p = leave_one_group_out_ridge(&x, &y, &groups, 1e-10);
    let err = (&p - &y).amax();
    assert!(err < 1e-6, "off by {err}");
    let p = leave_one_group_out_ridge(&x, &y, &groups, 1e15);
    for (g, held) in groups.iter().enumerate() {
        for k in 0..2 {
            let others: Vec<f64> = (0..n)
                .filter(|f| !held.contains(f))
                .map(|f| y[(f, k)])
                .collect();
            let mean = others.iter().sum::<f64>() / others.len() as f64;
            for &f in held {
                assert!((p[(f, k)] - mean).abs() < 1e-9, "group {g}");
            }
        }
    }
}
