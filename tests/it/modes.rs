//! Cosker et al. (paper 002) on landmark shapes: the artificial training set, Eq. 9, and
//! the orthogonality study on a real track.

use crate::common::shared;
use keyshape_lab::modes::{
    artificial_set, orthogonality, orthogonality_study, Actions, ModeRegions,
};
use keyshape_lab::sequence::Layout;
use nalgebra::DVector;
use proptest::prelude::*;

proptest! {
    #[test]
    fn eq9_is_symmetric_one_for_parallel_and_zero_for_orthogonal(a in prop::collection::vec(-5.0f64..5.0, 6), s in 0.1f64..10.0) {
        let u = DVector::from_vec(a.clone());
        prop_assume!(u.norm() > 1e-3);
        let v = &u * -s;
        prop_assert!((orthogonality(&u, &v) - 1.0).abs() < 1e-12);
        let w = DVector::from_vec(vec![1.0, 2.0, 0.5, -1.0, 0.3, 2.0]);
        prop_assert!((orthogonality(&u, &w) - orthogonality(&w, &u)).abs() < 1e-15);
        let (p, q) = (DVector::from_vec(vec![1.0, 0.0, 0.0]), DVector::from_vec(vec![0.0, a[0], a[1]]));
        prop_assert_eq!(orthogonality(&p, &q), 0.0);
    }
}

#[test]
fn the_artificial_set_changes_nothing_outside_its_region() {
    let seq = keyshape_lab::io::builtin_sequence().unwrap();
    let layout = Layout::mediapipe468();
    let regions = ModeRegions::builtin(&layout)
        .unwrap()
        .points(&layout)
        .unwrap();
    let q = seq.coords.columns(0, 30).clone_owned();
    let art = artificial_set(&q, &regions, 2);
    assert_eq!(art.ncols(), 30 * regions.len());
    let mean = q.column_mean();
    for (r, (_, pts)) in regions.iter().enumerate() {
        for i in [0, 17, 29] {
            let col = art.column(r * 30 + i);
            for p in 0..468 {
                for d in 0..2 {
                    let want = if pts.contains(&p) {
                        q[(2 * p + d, i)]
                    } else {
                        mean[2 * p + d]
                    };
                    assert_eq!(col[2 * p + d], want);
                }
            }
        }
    }
}

#[test]
fn action_specific_modes_separate_regions_better_than_plain_pca_on_d6() {
    let seq = keyshape_lab::io::read_sequence(
        &shared("mediapipe_face_tracks/liveportrait_d6.csv"),
        &Default::default(),
    )
    .unwrap();
    let prep = keyshape_lab::decompose::prepare(
        &seq,
        &keyshape_lab::decompose::PrepareOptions {
            points: None,
            align: true,
        },
    )
    .unwrap();
    let layout = Layout::mediapipe468();
    let regions = ModeRegions::builtin(&layout)
        .unwrap()
        .points(&layout)
        .unwrap();
    let actions = Actions::read(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/cosker/actions_liveportrait_d6.json"
    )))
    .unwrap();
    let st = orthogonality_study(
        &prep.seq.coords,
        &prep.seq.frames,
        2,
        &regions,
        &actions,
        10,
    )
    .unwrap();
    // Actions in different regions: orthogonal in the action model, not always in plain PCA.
    let region_of: Vec<&str> = actions.actions.iter().map(|a| a.region.as_str()).collect();
    let mut worst_cross = (0.0f64, 0.0f64);
    for i in 0..st.names.len() {
        for j in i + 1..st.names.len() {
            if region_of[i] != region_of[j] {
                worst_cross = (
                    worst_cross.0.max(st.action_model[(i, j)]),
                    worst_cross.1.max(st.plain[(i, j)]),
                );
            }
            assert!((st.action_model[(i, j)] - st.action_model[(j, i)]).abs() < 1e-12);
        }
    }
    assert!(
        worst_cross.0 < 0.01,
        "action model cross-region score {}",
        worst_cross.0
    );
    assert!(
        worst_cross.1 > 0.1,
        "plain PCA mixes regions: {}",
        worst_cross.1
    );
    // Bad labels are explained.
    let mut bad = actions.clone();
    bad.actions[0].region = "forehead".into();
    let e = orthogonality_study(&prep.seq.coords, &prep.seq.frames, 2, &regions, &bad, 10)
        .unwrap_err()
        .to_string();
    assert!(e.contains("names region 'forehead'"), "{e}");
    let mut bad = actions;
    bad.actions[1].frame = 5000;
    let e = orthogonality_study(&prep.seq.coords, &prep.seq.frames, 2, &regions, &bad, 10)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("frame 5000, which is not a tracked frame"),
        "{e}"
    );
}

#[test]
fn median_polynomial_and_correlation_on_known_signals() {
    use keyshape_lab::intensity::{correlation, median3, polyfit_smooth, soft_knn};
    assert_eq!(
        median3(&[0.0, 0.0, 9.0, 0.0, 1.0, 1.0]),
        vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0]
    );
    let cubic: Vec<f64> = (0..20)
        .map(|t| 1.0 + 0.5 * t as f64 - 0.03 * (t as f64).powi(3))
        .collect();
    let fit = polyfit_smooth(&cubic, 3);
    assert!(fit.iter().zip(&cubic).all(|(a, b)| (a - b).abs() < 1e-9));
    let s: Vec<f64> = (0..50).map(|t| (t as f64 * 0.3).sin()).collect();
    assert!((correlation(&s, &s) - 1.0).abs() < 1e-12);
    let neg: Vec<f64> = s.iter().map(|v| -2.0 * v + 3.0).collect();
    assert!((correlation(&s, &neg) + 1.0).abs() < 1e-12);
    // Soft KNN: 3 of the 4 nearest training points are class 1.
    let train = nalgebra::DMatrix::from_row_slice(1, 6, &[0.0, 0.1, 0.2, 0.3, 5.0, 5.1]);
    let p = soft_knn(
        &train,
        &[1, 1, 1, 0, 2, 2],
        3,
        &nalgebra::DMatrix::from_row_slice(1, 1, &[0.05]),
        4,
    )
    .unwrap();
    assert_eq!((p[(0, 0)], p[(1, 0)], p[(2, 0)]), (0.25, 0.75, 0.0));
    assert!(soft_knn(&train, &[1, 1, 1, 0, 2, 2], 3, &train, 7).is_err());
}

#[test]
fn intensity_study_on_the_news_sample_finds_smiles() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_kslab"))
        .args([
            "intensity",
            &shared("pyfeat_samples/news_sample_compact.csv")
                .display()
                .to_string(),
            "--json",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let smile = v["actions"]
        .as_array()
        .unwrap()
        .iter()
        .find(|a| a["action"] == "smile")
        .unwrap();
    assert!(
        smile["correlation_median3"].as_f64().unwrap() > 0.6,
        "{smile}"
    );
    assert_eq!(
        v["test_frames"].as_u64().unwrap() + v["train_frames"].as_u64().unwrap(),
        477
    );
}
