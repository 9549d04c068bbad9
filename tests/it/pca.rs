//! PCA and the Jacobi SVD against their defining properties.

use keyshape_lab::pca::Pca;
use keyshape_lab::solve::jacobi;
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

    #[test]
    fn jacobi_svd_recomposes_and_is_orthogonal(
        rows in 1usize..14, cols in 1usize..8, vals in prop::collection::vec(-5.0f64..5.0, 112), dup in any::<bool>(),
    ) {
        let mut a = DMatrix::from_fn(rows, cols, |i, j| vals[i * 8 + j]);
        if dup && cols > 1 {
            let c = a.column(0).clone_owned();
            a.set_column(cols - 1, &c);
        }
        let d = jacobi::svd(&a);
        let re = &d.u * DMatrix::from_diagonal(&nalgebra::DVector::from_vec(d.s.clone())) * d.v.transpose();
        prop_assert!((re - &a).amax() < 1e-12 * (1.0 + a.amax()));
        prop_assert!((d.v.transpose() * &d.v - DMatrix::identity(cols, cols)).amax() < 1e-12);
        prop_assert!(d.s.windows(2).all(|w| w[0] >= w[1]));
    }
}

#[test]
fn pca_on_a_real_track_explains_most_variance_in_few_axes() {
    let seq = keyshape_lab::io::builtin_sequence().unwrap();
    let prep = keyshape_lab::decompose::prepare(
        &seq,
        &keyshape_lab::decompose::PrepareOptions {
            points: Some("lips".into()),
            align: true,
        },
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
