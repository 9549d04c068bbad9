//! NNLS cross-checked against SciPy's independent Lawson–Hanson (`scipy.optimize.nnls`);
//! the numbers come from `tools/nnls_reference.py` and are committed in `tests/data/`.

use crate::common::shared;
use keyshape_core::solve::{solve_batch, SolveOptions, Solver};
use keyshape_io::{read_sequence, ReadOptions};
use nalgebra::DMatrix;
use serde_json::Value;

fn reference() -> Value {
    let text = include_str!("../../../../tests/data/nnls_reference.json");
    serde_json::from_str(text).unwrap()
}

fn matrix(rows: &Value) -> DMatrix<f64> {
    // Stored as a list of columns.
    let cols: Vec<Vec<f64>> = serde_json::from_value(rows.clone()).unwrap();
    DMatrix::from_fn(cols[0].len(), cols.len(), |i, j| cols[j][i])
}

#[test]
fn nnls_matches_scipy_on_random_shape_like_problems() {
    for p in reference()["problems"].as_array().unwrap() {
        let (s, q, want) = (matrix(&p["s"]), matrix(&p["q"]), matrix(&p["w"]));
        let got = solve_batch(&s, &q, &SolveOptions::new(Solver::Nnls))
            .unwrap()
            .weights;
        let residual: Vec<f64> = serde_json::from_value(p["residual"].clone()).unwrap();
        for j in 0..q.ncols() {
            let r = (&s * got.column(j) - q.column(j)).norm();
            assert!(
                (r - residual[j]).abs() <= 1e-9 * (1.0 + residual[j]),
                "{}: residual {r} vs scipy {}",
                p["name"],
                residual[j]
            );
            if !p["name"].as_str().unwrap().contains("duplicate") {
                let d = (got.column(j) - want.column(j)).amax();
                assert!(d < 1e-8, "{}: frame {j} weights differ by {d}", p["name"]);
            }
        }
    }
}

#[test]
fn nnls_matches_scipy_on_real_lip_contours() {
    let r = &reference()["real"];
    let seq = read_sequence(
        &shared(r["file"].as_str().unwrap()),
        &ReadOptions::default(),
    )
    .unwrap();
    let points: Vec<usize> = serde_json::from_value(r["points"].clone()).unwrap();
    let lips = seq.select_points(&points).unwrap();
    let keys: Vec<usize> = serde_json::from_value(r["keys"].clone()).unwrap();
    let frames: Vec<usize> = serde_json::from_value(r["frames"].clone()).unwrap();
    let s = lips.coords.select_columns(&keys);
    let q = lips.coords.select_columns(&frames);
    let got = solve_batch(&s, &q, &SolveOptions::new(Solver::Nnls))
        .unwrap()
        .weights;
    let want = matrix(&r["w"]);
    let d = (&got - &want).amax();
    assert!(d < 1e-6, "weights differ from SciPy by {d}:\n{got}\n{want}");
    // The real problem is not trivial: several weights are exactly zero.
    assert!(got.iter().filter(|&&w| w == 0.0).count() >= 10);
}
