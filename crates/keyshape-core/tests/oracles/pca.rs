//! PCA against its defining properties (the Jacobi SVD under it is tested in its module).

use keyshape_core::pca::Pca;
use nalgebra::DMatrix;
use proptest::prelude::*;

fn cov_residual(x: &DMatrix<f64>, pca: &Pca) -> f64 {
    let mean = x.column_mean();
    let mut c = x.clone();
    for mut col in c.column_iter_mut() {
        col -= &mean;
    }
    let cov = &c * c.transpose() / (x.ncols() - 1) as f64;
    let mut worst = 0.0f64;
    for (j, v) in pca.variances.iter().enumerate() {
        let a = pca.components.column(j);
        worst = worst.max((&cov * a - a * *v).amax() / pca.variances[0]);
    }
    worst
}

proptest! {
    #[test]
    fn pca_axes_are_orthonormal_eigenvectors_of_the_covariance(
        rows in 2usize..12, cols in 2usize..12, vals in prop::collection::vec(-5.0f64..5.0, 144),
    ) {
        let x = DMatrix::from_fn(rows, cols, |i, j| vals[i * 12 + j] + 3.0 * (i as f64));
        let pca = Pca::fit(&x).unwrap();
        let r = pca.components.ncols();
        prop_assert!((pca.components.transpose() * &pca.components - DMatrix::identity(r, r)).amax() < 1e-10);
        prop_assert!(cov_residual(&x, &pca) < 1e-10);
        let explained: f64 = pca.explained_ratio().iter().sum();
        prop_assert!((explained - 1.0).abs() < 1e-9, "explained {explained}");
        prop_assert!(pca.variances.windows(2).all(|w| w[0] >= w[1]));
    }
}

#[test]
fn pca_on_a_real_track_explains_most_variance_in_few_axes() {
    let seq = keyshape_io::builtin_sequence().unwrap();
    let prep = keyshape_core::decompose::prepare(
        &seq,
        &keyshape_core::decompose::PrepareOptions::group_aligned("lips"),
    )
    .unwrap();
    let pca = Pca::fit(&prep.seq.coords).unwrap();
    assert!(cov_residual(&prep.seq.coords, &pca) < 1e-9);
    let ratio = pca.explained_ratio();
    // d18 opens the mouth: the first axis carries most of the lip motion.
    assert!(ratio[0] > 0.5, "{ratio:?}");
    let proj = pca.project(&prep.seq.coords, 2);
    assert_eq!(proj.shape(), (2, 216));
}

#[test]
fn leading_axes_by_subspace_iteration_match_the_full_decomposition() {
    for rel in [
        "mediapipe_face_tracks/liveportrait_d6.csv",
        "mediapipe_face_tracks/pyfeat_wolfganglanger_pexels.csv",
    ] {
        let seq =
            keyshape_io::read_sequence(&crate::common::shared(rel), &Default::default()).unwrap();
        let prep = keyshape_core::decompose::prepare(
            &seq,
            &keyshape_core::decompose::PrepareOptions::all_aligned(),
        )
        .unwrap();
        let full = Pca::fit(&prep.seq.coords).unwrap();
        let fast = Pca::fit_leading(&prep.seq.coords, 24).unwrap();
        assert_eq!(fast.components.ncols(), 24);
        assert!((fast.total_variance - full.total_variance).abs() < 1e-9 * full.total_variance);
        for j in 0..24 {
            let rel_var = (fast.variances[j] - full.variances[j]).abs() / full.variances[0];
            assert!(
                rel_var < 1e-10,
                "{rel} axis {j}: variance differs by {rel_var:e}"
            );
            let dot = fast
                .components
                .column(j)
                .dot(&full.components.column(j))
                .abs();
            // Axes with a clear gap to their neighbours must agree as directions.
            let gap = (full.variances[j] - full.variances[j + 1]).min(if j > 0 {
                full.variances[j - 1] - full.variances[j]
            } else {
                f64::INFINITY
            });
            if gap > 1e-3 * full.variances[0] {
                assert!(dot > 1.0 - 1e-8, "{rel} axis {j}: |cos| = {dot}");
            }
        }
    }
}

/// The sign convention that makes axes (and so spread's and the lab's projections)
/// deterministic: every axis's largest-magnitude coordinate is positive, and the axes
/// are unit vectors, for the full fit from either side (more frames than values and
/// fewer) and for the block-wise fit.
#[test]
fn every_axis_is_a_unit_vector_with_a_positive_largest_coordinate() {
    let seq = keyshape_io::read_sequence(
        &crate::common::shared("pyfeat_samples/news_sample_compact.csv"),
        &Default::default(),
    )
    .unwrap();
    let q = seq.coords; // 136 values, 477 frames
    let wide = q.columns(0, 40).clone_owned(); // 136 values, 40 frames
    let blocks =
        Pca::fit_blocks(q.nrows(), q.ncols(), &|s, w| q.columns(s, w).clone_owned()).unwrap();
    for (what, p) in [
        ("tall", Pca::fit(&q).unwrap()),
        ("wide", Pca::fit(&wide).unwrap()),
        ("blocks", blocks),
    ] {
        assert!(p.components.ncols() >= 10, "{what}");
        for (c, axis) in p.components.column_iter().enumerate() {
            assert!(
                (axis.norm() - 1.0).abs() < 1e-12,
                "{what} axis {c}: norm {}",
                axis.norm()
            );
            let imax = axis.iamax();
            assert!(
                axis[imax] > 0.0,
                "{what} axis {c}: largest coordinate {}",
                axis[imax]
            );
        }
    }
}

/// The rank cutoff: an axis whose variance is below 1e-13 · max(values, frames) of the
/// largest is numerically zero and dropped; one well above is kept.
#[test]
fn axes_below_the_rank_cutoff_are_dropped() {
    // 3 values × 40 frames, variances along the coordinate axes 1 : 0.25 : s.
    let data = |s: f64| {
        DMatrix::from_fn(3, 40, |i, t| {
            let u = ((t * 37 + 11) % 40) as f64 / 20.0 - 0.975;
            let v = ((t * 13 + 5) % 40) as f64 / 20.0 - 0.975;
            let w = ((t * 29 + 3) % 40) as f64 / 20.0 - 0.975;
            [u, 0.5 * v, s.sqrt() * w][i]
        })
    };
    // 1e-13 · 40 · top is the cutoff: 1e-14 of the top variance is below it, 1e-9 above.
    assert_eq!(Pca::fit(&data(1e-14)).unwrap().components.ncols(), 2);
    assert_eq!(Pca::fit(&data(1e-9)).unwrap().components.ncols(), 3);
}
