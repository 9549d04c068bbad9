//! Cosker et al. (paper 002) on landmark shapes: the artificial training set, Eq. 9, the
//! orthogonality study on a real track, trajectories mapped between people and onto morph
//! targets, and the soft-KNN intensities, against hand-worked values and real tracks.

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_actions::modes::{
    action_vectors, artificial_set, orthogonality, orthogonality_study, region_weights, shape_size,
    Actions, Boundary, ModeRegions, RegionOptions, DEFAULT_BLEND_RADIUS,
};
use keyshape_actions::trajectory::Normalisation;
use keyshape_core::sequence::Layout;
use keyshape_core::ErrorKind;
use nalgebra::DVector;
use proptest::prelude::*;
use std::path::PathBuf;

/// `../shared/data/<rel>` beside the repository.
fn shared(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data")
        .join(rel)
}

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

fn d6_prepared() -> keyshape_core::decompose::Prepared {
    let seq = keyshape_io::read_sequence(
        &shared("mediapipe_face_tracks/liveportrait_d6.csv"),
        &Default::default(),
    )
    .unwrap();
    keyshape_core::decompose::prepare(
        &seq,
        &keyshape_core::decompose::PrepareOptions::all_aligned(),
    )
    .unwrap()
}

fn opts(boundary: Boundary, blend_radius: f64) -> RegionOptions {
    RegionOptions {
        boundary,
        blend_radius,
    }
}

#[test]
fn the_averaging_filter_ramps_across_a_boundary_on_a_line_of_points() {
    // Ten points on a line, the first five in the region; the RMS distance from the centroid
    // is sqrt(8.25), so this radius takes each point's two neighbours (distance 1).
    let mean: Vec<f64> = (0..10).flat_map(|i| [i as f64, 0.0]).collect();
    let r = 1.0001 / 8.25f64.sqrt();
    let w = region_weights(&mean, 2, &[0, 1, 2, 3, 4], &opts(Boundary::Blended, r)).unwrap();
    let want = [1.0, 1.0, 1.0, 1.0, 2.0 / 3.0, 1.0 / 3.0, 0.0, 0.0, 0.0, 0.0];
    for (a, b) in w.iter().zip(want) {
        assert!((a - b).abs() < 1e-15, "{w:?}");
    }
    // Disjoint, and blended with radius 0, are the indicator itself.
    let ind = [1.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let d = region_weights(&mean, 2, &[0, 1, 2, 3, 4], &opts(Boundary::Disjoint, r)).unwrap();
    assert_eq!(d, ind);
    let z = region_weights(&mean, 2, &[0, 1, 2, 3, 4], &opts(Boundary::Blended, 0.0)).unwrap();
    assert_eq!(z, ind);
    // A radius wider than the line averages everything: 5 of 10 points inside.
    let all = region_weights(&mean, 2, &[0, 1, 2, 3, 4], &opts(Boundary::Blended, 10.0)).unwrap();
    assert!(all.iter().all(|&v| v == 0.5), "{all:?}");
    // Bad radii and a radius with disjoint boundaries are refused.
    assert!(region_weights(&mean, 2, &[0], &opts(Boundary::Blended, f64::NAN)).is_err());
    assert!(region_weights(&mean, 2, &[0], &opts(Boundary::Blended, -0.1)).is_err());
    assert!(RegionOptions::from_user(Boundary::Disjoint, Some(0.1)).is_err());
    assert_eq!(
        RegionOptions::from_user(Boundary::Blended, None).unwrap(),
        opts(Boundary::Blended, DEFAULT_BLEND_RADIUS)
    );
}

#[test]
fn the_artificial_set_adds_each_regions_weighted_offsets_to_the_mean() {
    let seq = keyshape_io::builtin_sequence().unwrap();
    let layout = Layout::mediapipe468();
    let q = seq.coords.columns(0, 30).clone_owned();
    let mean = q.column_mean();
    let defs = ModeRegions::builtin(&layout).unwrap();
    let named = defs.points(&layout).unwrap();
    // Disjoint weights are the indicator of each region after `cover` hands every point no
    // group names to the forehead or the lower face, whichever has the nearest named point.
    let hard = defs
        .weights(&layout, &q, 2, &opts(Boundary::Disjoint, 0.0))
        .unwrap();
    let d2 = |a: usize, b: usize| {
        (mean[2 * a] - mean[2 * b]).powi(2) + (mean[2 * a + 1] - mean[2 * b + 1]).powi(2)
    };
    let cover = ["forehead", "lower_face"].map(|c| named.iter().position(|r| r.0 == c).unwrap());
    for p in 0..468 {
        let inside: Vec<bool> = hard.iter().map(|r| r.weights[p] == 1.0).collect();
        assert!(hard
            .iter()
            .all(|r| r.weights[p] == 0.0 || r.weights[p] == 1.0));
        if named.iter().any(|r| r.1.contains(&p)) {
            for (r, region) in named.iter().enumerate() {
                assert_eq!(inside[r], region.1.contains(&p));
            }
        } else {
            let nearest = |r: usize| {
                named[r]
                    .1
                    .iter()
                    .map(|&x| d2(p, x))
                    .fold(f64::MAX, f64::min)
            };
            let want = if nearest(cover[0]) <= nearest(cover[1]) {
                cover[0]
            } else {
                cover[1]
            };
            assert!(inside[want], "point {p}");
            assert_eq!(inside.iter().filter(|&&b| b).count(), 1, "point {p}");
        }
        assert!(
            inside[cover[0]] || inside[cover[1]],
            "R1 and R2 tile the face"
        );
    }
    for o in [opts(Boundary::Disjoint, 0.0), RegionOptions::default()] {
        let regions = defs.weights(&layout, &q, 2, &o).unwrap();
        let art = artificial_set(&q, &regions, 2);
        assert_eq!(art.ncols(), 30 * regions.len());
        for (r, region) in regions.iter().enumerate() {
            // Brute force: the averaging filter computed here from its definition.
            let size = shape_size(mean.as_slice(), 2);
            for p in 0..468 {
                let want = if o.boundary == Boundary::Disjoint {
                    hard[r].weights[p]
                } else {
                    let near: Vec<usize> = (0..468)
                        .filter(|&x| d2(p, x).sqrt() <= o.blend_radius * size)
                        .collect();
                    near.iter().map(|&x| hard[r].weights[x]).sum::<f64>() / near.len() as f64
                };
                assert!(
                    (region.weights[p] - want).abs() < 1e-12,
                    "{} {p}",
                    region.name
                );
            }
            for i in [0, 17, 29] {
                let col = art.column(r * 30 + i);
                for k in 0..2 * 468 {
                    let want = mean[k] + region.weights[k / 2] * (q[(k, i)] - mean[k]);
                    assert!((col[k] - want).abs() < 1e-9);
                }
            }
        }
        // Blended, the forehead and the lower face overlap across their boundary.
        if o.boundary == Boundary::Blended {
            let (f, l) = (&regions[cover[0]].weights, &regions[cover[1]].weights);
            assert!(f.iter().zip(l).any(|(a, b)| *a > 0.0 && *b > 0.0));
            assert!(f.iter().any(|&w| w > 0.0 && w < 1.0));
        }
    }
}

/// Properties Table 2 has on any data: symmetric, 1 on the diagonal, every value in [0, 1],
/// and each entry Eq. 9 of the two actions' projections.
fn check_table(m: &nalgebra::DMatrix<f64>) {
    for i in 0..m.nrows() {
        assert!((m[(i, i)] - 1.0).abs() < 1e-12, "diagonal {}", m[(i, i)]);
        for j in 0..m.ncols() {
            assert_eq!(m[(i, j)], m[(j, i)]);
            assert!((0.0..=1.0 + 1e-12).contains(&m[(i, j)]));
        }
    }
}

#[test]
fn table_2_on_d6_is_a_measurement_with_blended_regions() {
    let prep = d6_prepared();
    let layout = Layout::mediapipe468();
    let defs = ModeRegions::builtin(&layout).unwrap();
    let actions = Actions::read(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../assets/actions/actions_liveportrait_d6.json"
    )))
    .unwrap();
    let study = |o: &RegionOptions| {
        let regions = defs.weights(&layout, &prep.seq.coords, 2, o).unwrap();
        let st = orthogonality_study(
            &prep.seq.coords,
            &prep.seq.frames,
            2,
            &regions,
            &actions,
            10,
        )
        .unwrap();
        (st, regions)
    };
    let (blended, regions) = study(&RegionOptions::default());
    check_table(&blended.action_model);
    check_table(&blended.plain);
    // Each entry is Eq. 9 of the actions' projections on the leading modes, computed here.
    let vecs = action_vectors(&prep.seq.coords, &prep.seq.frames, 2, &regions, &actions).unwrap();
    // The study fits the set block by block, never holding it (`artificial_pca`): that is
    // the full decomposition of the set's matrix, bit for bit; fit_leading's subspace
    // iteration on the matrix agrees with it to its 1e-10 convergence tolerance.
    let art = artificial_set(&prep.seq.coords, &regions, 2);
    let mut model = keyshape_core::pca::Pca::fit(&art).unwrap();
    model.truncate(10);
    let blocks =
        keyshape_actions::modes::artificial_pca(&prep.seq.coords, &regions, 2, 10).unwrap();
    assert_eq!(blocks.components, model.components);
    assert_eq!(blocks.variances, model.variances);
    assert_eq!(blocks.mean, model.mean);
    let iterated = keyshape_core::pca::Pca::fit_leading(&art, 10).unwrap();
    for (a, b) in iterated.variances.iter().zip(&model.variances) {
        assert!((a - b).abs() <= 1e-9 * model.variances[0], "{a} vs {b}");
    }
    for c in 0..10 {
        let cos = iterated
            .components
            .column(c)
            .dot(&model.components.column(c))
            .abs();
        assert!(cos > 1.0 - 1e-8, "axis {c}: |cos| {cos}");
    }
    let proj: Vec<DVector<f64>> = vecs
        .iter()
        .map(|v| model.components.tr_mul(&(v - &model.mean)))
        .collect();
    for i in 0..9 {
        for j in 0..9 {
            let (a, b) = (&proj[i], &proj[j]);
            let want = a.dot(b).powi(2) / (a.dot(a) * b.dot(b));
            assert!((blended.action_model[(i, j)] - want).abs() < 1e-12);
        }
    }
    // Disjoint regions make the covariance block-diagonal between groups of regions that
    // share no point (directly or through a third region: the brows share points with the
    // forehead, not with each other), so entries across groups are 0 by construction (the
    // reason it is not the default).
    let (disjoint, dregions) = study(&opts(Boundary::Disjoint, 0.0));
    check_table(&disjoint.action_model);
    let shares = |a: usize, b: usize| {
        dregions[a]
            .weights
            .iter()
            .zip(&dregions[b].weights)
            .any(|(x, y)| x * y > 0.0)
    };
    let mut group: Vec<usize> = (0..dregions.len()).collect();
    for _ in 0..dregions.len() {
        for a in 0..dregions.len() {
            for b in 0..dregions.len() {
                if shares(a, b) {
                    let g = group[a].min(group[b]);
                    group[a] = g;
                    group[b] = g;
                }
            }
        }
    }
    let group_of = |i: usize| {
        let r = &actions.actions[i].region;
        group[dregions.iter().position(|x| &x.name == r).unwrap()]
    };
    let overlap = |i: usize, j: usize| group_of(i) == group_of(j);
    let mut cross = 0;
    for i in 0..9 {
        for j in 0..9 {
            if !overlap(i, j) {
                cross += 1;
                assert!(disjoint.action_model[(i, j)] < 1e-12);
            }
        }
    }
    assert!(cross > 0);
    // Two actions are a table (the 9-action table's corner); one is refused, as are 0 modes.
    let mut two = actions.clone();
    two.actions.truncate(2);
    let st2 =
        orthogonality_study(&prep.seq.coords, &prep.seq.frames, 2, &regions, &two, 10).unwrap();
    assert_eq!(st2.action_model.shape(), (2, 2));
    assert_eq!(st2.action_model, blended.action_model.view((0, 0), (2, 2)));
    assert_eq!(st2.plain, blended.plain.view((0, 0), (2, 2)));
    let mut one = two.clone();
    one.actions.truncate(1);
    let e = orthogonality_study(&prep.seq.coords, &prep.seq.frames, 2, &regions, &one, 10)
        .unwrap_err()
        .kind_is(ErrorKind::Invalid);
    assert!(e.contains("needs at least two actions"), "{e}");
    let e = orthogonality_study(&prep.seq.coords, &prep.seq.frames, 2, &regions, &two, 0)
        .unwrap_err()
        .kind_is(ErrorKind::Setting);
    assert!(e.contains("at least 1 mode"), "{e}");
    // The summary the report gives: the mean of the 36 pairs above the diagonal.
    let mut upper = Vec::new();
    for i in 0..9 {
        for j in i + 1..9 {
            upper.push(blended.action_model[(i, j)]);
        }
    }
    let want = upper.iter().sum::<f64>() / 36.0;
    let got = keyshape_actions::modes::OrthogonalityStudy::mean_upper(&blended.action_model);
    assert!((got - want).abs() < 1e-15, "{got} vs {want}");
    // Bad labels are explained.
    let mut bad = actions.clone();
    bad.actions[0].region = "cheeks".into();
    let e = orthogonality_study(&prep.seq.coords, &prep.seq.frames, 2, &regions, &bad, 10)
        .unwrap_err()
        .kind_is(ErrorKind::Invalid);
    assert!(e.contains("names region 'cheeks'"), "{e}");
    let mut bad = actions;
    bad.actions[1].frame = 5000;
    let e = orthogonality_study(&prep.seq.coords, &prep.seq.frames, 2, &regions, &bad, 10)
        .unwrap_err()
        .kind_is(ErrorKind::Invalid);
    assert!(
        e.contains("frame 5000, which is not a tracked frame"),
        "{e}"
    );
}

#[test]
fn median_polynomial_and_correlation_on_known_signals() {
    use keyshape_actions::intensity::{median3, polyfit_smooth, soft_knn};
    use keyshape_core::stats::correlation;
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
fn intensity_centring_and_spread_follow_their_definitions() {
    use keyshape_actions::intensity::{centre, spread, Centring, Evaluation, StudySettings};
    // One feature, clip 1 = [1, 2, 6], clip 2 = [10, 20].
    let x0 = nalgebra::DMatrix::from_row_slice(1, 5, &[1.0, 2.0, 6.0, 10.0, 20.0]);
    let clips = [1, 1, 1, 2, 2];
    let run = |c: Centring, n: Option<usize>| {
        let mut x = x0.clone();
        let st = StudySettings {
            centring: c,
            neutral_frames: n,
            ..Default::default()
        };
        centre(&mut x, &clips, &st).map(|_| x.iter().copied().collect::<Vec<f64>>())
    };
    assert_eq!(
        run(Centring::ClipMean, None).unwrap(),
        [-2.0, -1.0, 3.0, -5.0, 5.0]
    );
    // Causal: each frame minus the mean of its clip's frames so far.
    assert_eq!(
        run(Centring::Causal, None).unwrap(),
        [0.0, 0.5, 3.0, 0.0, 5.0]
    );
    // Neutral: minus the mean of the first n frames of the clip.
    assert_eq!(
        run(Centring::Neutral, Some(2)).unwrap(),
        [-0.5, 0.5, 4.5, -5.0, 5.0]
    );
    let e = run(Centring::Neutral, Some(3))
        .unwrap_err()
        .kind_is(ErrorKind::Invalid);
    assert!(e.contains("clip 2 has 2 frames"), "{e}");
    // Options that cannot apply are refused.
    let bad = [
        StudySettings {
            centring: Centring::Neutral,
            ..Default::default()
        },
        StudySettings {
            neutral_frames: Some(3),
            ..Default::default()
        },
        StudySettings {
            evaluation: Evaluation::LeaveOneClipOut,
            train_clips: Some((1, 3)),
            ..Default::default()
        },
        StudySettings {
            threshold: 1.0,
            ..Default::default()
        },
    ];
    for st in bad {
        assert!(st.check().is_err(), "{st:?}");
    }
    // Median and quartiles by linear interpolation; undefined correlations are left out.
    let sp = spread(&[4.0, f64::NAN, 1.0, 3.0, 2.0]);
    assert_eq!((sp.median, sp.q1, sp.q3, sp.clips), (2.5, 1.75, 3.25, 4));
    assert!(spread(&[f64::NAN]).median.is_nan());
    // One defined clip: every quartile is that clip (no neighbour to interpolate toward).
    let one = spread(&[f64::NAN, 0.3]);
    assert_eq!((one.median, one.q1, one.q3, one.clips), (0.3, 0.3, 0.3, 1));
}

#[test]
fn leave_one_clip_out_holds_out_every_person_once() {
    use keyshape_actions::intensity::{study, Evaluation, StudySettings};
    use keyshape_core::stats::correlation;
    let st = StudySettings {
        evaluation: Evaluation::LeaveOneClipOut,
        ..Default::default()
    };
    let r = study(&shared("pyfeat_samples/news_sample_compact.csv"), &st).unwrap();
    assert_eq!(r.test_clips, (1..=20).collect::<Vec<_>>());
    assert_eq!(r.test_frames, 477);
    assert_eq!(r.train_frames, 477 * 19);
    // Each clip row is Eq. 10 on that clip alone; the summary's median is the median of them.
    for row in &r.actions {
        let per: Vec<f64> = r
            .clips
            .iter()
            .filter(|c| c.action == row.action)
            .map(|c| c.smoothed)
            .collect();
        assert_eq!(per.len(), 20);
        let mut v: Vec<f64> = per.iter().copied().filter(|x| x.is_finite()).collect();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let med = if n % 2 == 1 {
            v[n / 2]
        } else {
            (v[n / 2 - 1] + v[n / 2]) / 2.0
        };
        assert!((row.clips_smoothed.median - med).abs() < 1e-15);
    }
    // numpy.corrcoef([1, 2, 3], [2, 4, 6.5]).
    assert!((correlation(&[1.0, 2.0, 3.0], &[2.0, 4.0, 6.5]) - 0.9979487157886733).abs() < 1e-12);
}

fn person(
    rel: &str,
    actions: &str,
    normalisation: Normalisation,
) -> (keyshape_actions::trajectory::PersonModel, DMatrixF) {
    let seq = keyshape_io::read_sequence(&shared(rel), &Default::default()).unwrap();
    let prep = keyshape_core::decompose::prepare(
        &seq,
        &keyshape_core::decompose::PrepareOptions::all_aligned(),
    )
    .unwrap();
    let layout = Layout::mediapipe468();
    let regions = ModeRegions::builtin(&layout)
        .unwrap()
        .weights(&layout, &prep.seq.coords, 2, &RegionOptions::default())
        .unwrap();
    let acts = Actions::read(std::path::Path::new(&format!(
        "{}/../../assets/actions/{actions}",
        env!("CARGO_MANIFEST_DIR")
    )))
    .unwrap();
    let m = keyshape_actions::trajectory::person_model(
        &prep.seq.coords,
        &prep.seq.frames,
        2,
        &regions,
        &acts,
        10,
        normalisation,
    )
    .unwrap();
    // Each action sits on the mode its region-only offset from the mean projects onto most,
    // with that projection's sign (brute force over the modes).
    let vs = action_vectors(&prep.seq.coords, &prep.seq.frames, 2, &regions, &acts).unwrap();
    for ((name, mode, sign), v) in m.actions.iter().zip(&vs) {
        let c = m.pca.components.tr_mul(&(v - &m.pca.mean));
        let best = (0..c.len())
            .max_by(|&a, &b| c[a].abs().total_cmp(&c[b].abs()))
            .unwrap();
        assert_eq!((*mode, *sign), (best, c[best].signum()), "{rel}: {name}");
    }
    // Both extremes of every mode straddle 0 (lower < 0 < upper), as the scale needs.
    assert!(m.lower.iter().all(|v| *v < 0.0) && m.upper.iter().all(|v| *v > 0.0));
    (m, prep.seq.coords)
}

type DMatrixF = nalgebra::DMatrix<f64>;

#[test]
fn trajectories_are_normalised_and_map_between_people() {
    use keyshape_actions::trajectory::{
        extremes, synthesise, trajectories, ModeAlignment, ModePair,
    };
    let d6 = "mediapipe_face_tracks/liveportrait_d6.csv";
    let d9 = "mediapipe_face_tracks/liveportrait_d9.csv";
    let (src, q) = person(d6, "actions_liveportrait_d6.json", Normalisation::TwoSided);
    let (one, _) = person(d6, "actions_liveportrait_d6.json", Normalisation::OneSided);
    let traj = trajectories(&src, &q);
    let traj1 = trajectories(&one, &q);
    let b = src.pca.project(&q, 10);
    for k in 0..traj.nrows() {
        // Two-sided (§3.2): both observed extremes map to ±1 exactly; every value keeps its
        // sign and is divided by its own side's extreme.
        let row = traj.row(k);
        assert_eq!(row.max(), 1.0, "mode {k}");
        assert_eq!(row.min(), -1.0, "mode {k}");
        let (hi, lo) = (b.row(k).max(), b.row(k).min());
        assert_eq!((src.upper[k], src.lower[k]), (hi, lo));
        for t in [0, 100, 500] {
            let v = b[(k, t)];
            let want = if v >= 0.0 { v / hi } else { v / -lo };
            assert!((traj[(k, t)] - want).abs() < 1e-15);
            // One-sided: both sides over the largest magnitude.
            assert!((traj1[(k, t)] - v / hi.max(-lo)).abs() < 1e-15);
        }
        let row1 = traj1.row(k);
        assert!((row1.amax() - 1.0).abs() < 1e-15);
        assert!((row1.max().min(-row1.min()) - hi.min(-lo) / hi.max(-lo)).abs() < 1e-12);
    }
    // Identity alignment on the same person reproduces the projection on the model's modes,
    // under either normalisation (each scales back by what it divided by).
    let id = ModeAlignment {
        pairs: (0..10)
            .map(|m| ModePair {
                source_mode: m,
                target_mode: m,
                flip: false,
                action: String::new(),
            })
            .collect(),
    };
    let u = &src.pca.components;
    let c = u * u.tr_mul(&(q.column(100) - &src.pca.mean));
    for (model, tr) in [(&src, &traj), (&one, &traj1)] {
        let x = synthesise(model, &id, tr);
        assert!((x.column(100) - (&src.pca.mean + &c)).amax() < 1e-9);
    }
    // By action labels onto d9: every pair names modes that exist, a source mode once.
    let (tgt, _) = person(d9, "actions_liveportrait_d9.json", Normalisation::TwoSided);
    let al = ModeAlignment::by_actions(&src, &tgt);
    al.check(&src, &tgt).unwrap();
    let mut s: Vec<usize> = al.pairs.iter().map(|p| p.source_mode).collect();
    s.sort_unstable();
    s.dedup();
    assert_eq!(s.len(), al.pairs.len());
    // By hand: the source's actions in order, each source mode by its first action, paired
    // with the target's action of that name, flipped where the two signs differ.
    let mut want: Vec<(usize, usize, bool, String)> = Vec::new();
    for (name, sm, ss) in &src.actions {
        if want.iter().any(|w| w.0 == *sm) {
            continue;
        }
        if let Some((_, tm, ts)) = tgt.actions.iter().find(|a| &a.0 == name) {
            want.push((*sm, *tm, ss != ts, name.clone()));
        }
    }
    let got: Vec<(usize, usize, bool, String)> = al
        .pairs
        .iter()
        .map(|p| (p.source_mode, p.target_mode, p.flip, p.action.clone()))
        .collect();
    assert_eq!(got, want);
    assert!(got.len() >= 3, "{got:?}");
    // A flipped pair drives the target as the unflipped one driven by the negated trajectory.
    let flip = |f: bool| ModeAlignment {
        pairs: vec![ModePair {
            source_mode: 0,
            target_mode: 1,
            flip: f,
            action: String::new(),
        }],
    };
    let neg = -traj.clone();
    let (a, b) = (
        synthesise(&tgt, &flip(true), &traj),
        synthesise(&tgt, &flip(false), &neg),
    );
    assert!((&a - &b).amax() < 1e-12);
    assert!((&a - synthesise(&tgt, &flip(false), &traj)).amax() > 1e-3);
    // Where a source extreme lands: two-sided on the target's own extreme of that side;
    // one-sided by the closed form (s / max|s|) · max|t|.
    let ex = extremes(&src, &tgt, &al);
    assert_eq!(ex.len(), 2 * al.pairs.len());
    for r in &ex {
        let p = al
            .pairs
            .iter()
            .find(|p| p.source_mode == r.source_mode)
            .unwrap();
        let sign = if p.flip { -1.0 } else { 1.0 };
        let (shi, slo) = (src.upper[r.source_mode], src.lower[r.source_mode]);
        let (thi, tlo) = (tgt.upper[r.target_mode], tgt.lower[r.target_mode]);
        let s = if r.side == "+" { shi } else { slo };
        let t = if sign * s > 0.0 { thi } else { tlo };
        assert_eq!(r.two_sided, t);
        assert_eq!((r.source_extreme, r.target_extreme), (s, t));
        let one = sign * s / shi.max(-slo) * thi.max(-tlo);
        assert!((r.one_sided - one).abs() < 1e-12 * one.abs());
        assert!((r.ratio - one / t).abs() < 1e-12 * (one / t).abs());
    }
    let bad = ModeAlignment {
        pairs: vec![ModePair {
            source_mode: 0,
            target_mode: 99,
            flip: false,
            action: String::new(),
        }],
    };
    assert!(bad.check(&src, &tgt).is_err());
}

#[test]
fn eq8_with_one_hot_weights_reproduces_each_morph_target() {
    use keyshape_actions::morph::MorphMapping;
    use keyshape_io::morph::MorphTargets;
    let mesh = keyshape_io::obj::read_obj(&shared("ict_facekit_face/neutral_face.obj")).unwrap();
    let t = MorphTargets::read(
        &shared("ict_facekit_face/expressions.csv"),
        &shared("ict_facekit_face/expression_deltas.csv"),
        mesh.positions.len(),
    )
    .unwrap();
    assert_eq!(
        t.names.len(),
        55,
        "the README of ict_facekit_face lists 55 shapes"
    );
    let mut out = mesh.positions.clone();
    for s in [0, 28, 54] {
        let mut w = vec![0.0; t.names.len()];
        w[s] = 1.0;
        t.blend(&mesh.positions, &w, &mut out);
        let mut want = mesh.positions.clone();
        for &(v, d) in &t.deltas[s] {
            for k in 0..3 {
                want[v][k] += d[k];
            }
        }
        assert_eq!(out, want, "shape {}", t.names[s]);
    }
    // The built-in mapping names only shapes and actions that exist; others are errors.
    let names: Vec<String> = [
        "jaw_drop",
        "smile",
        "pucker",
        "brow_raise_left",
        "brow_lower_left",
        "brow_raise_right",
        "brow_lower_right",
        "eyes_wide",
        "blink",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let traj = DMatrixF::from_element(names.len(), 3, 0.5);
    let w = MorphMapping::builtin()
        .unwrap()
        .weights(&t, &names, &traj)
        .unwrap();
    assert!(w.iter().all(|v| (0.0..=1.0).contains(v)));
    let bad: MorphMapping =
        serde_json::from_str(r#"{"actions": {"smile": [["mouthGrin", 1.0]]}}"#).unwrap();
    let e = bad
        .weights(&t, &names, &traj)
        .unwrap_err()
        .kind_is(ErrorKind::Invalid);
    assert!(e.contains("shape 'mouthGrin'"), "{e}");
    let bad: MorphMapping =
        serde_json::from_str(r#"{"actions": {"wink": [["jawOpen", 1.0]]}}"#).unwrap();
    assert!(bad
        .weights(&t, &names, &traj)
        .unwrap_err()
        .kind_is(ErrorKind::Invalid)
        .contains("action 'wink'"));
}

/// `cover` gives each point no region names to the cover region of its nearest named
/// cover point (brute force on the news sample's mean shape), and leaves the points another
/// region names alone; a region naming a point past the shape is an error, not a panic.
#[test]
fn cover_fills_only_the_unnamed_points_with_their_nearest_cover_region() {
    use keyshape_io::{read_sequence, ReadOptions};
    let seq = read_sequence(
        &shared("pyfeat_samples/news_sample_compact.csv"),
        &ReadOptions::default(),
    )
    .unwrap();
    let layout = Layout::ibug68();
    let r: ModeRegions = serde_json::from_str(
        r#"{"layout": "ibug68",
            "regions": {"upper": ["left_eyebrow", "right_eyebrow"], "lower": ["jaw"],
                        "mouth": ["lips"]},
            "cover": ["upper", "lower"]}"#,
    )
    .unwrap();
    let w = r
        .weights(&layout, &seq.coords, 2, &opts(Boundary::Disjoint, 0.0))
        .unwrap();
    let by = |name: &str| &w.iter().find(|g| g.name == name).unwrap().weights;
    let mean = seq.coords.column_mean();
    let d2 = |a: usize, b: usize| {
        (mean[2 * a] - mean[2 * b]).powi(2) + (mean[2 * a + 1] - mean[2 * b + 1]).powi(2)
    };
    let (brows, jaw, lips) = (17..=26, 0..=16, 48..=67);
    let mut joined = [0usize; 2];
    for p in 0..68 {
        let (up, low, mouth) = (by("upper")[p], by("lower")[p], by("mouth")[p]);
        if lips.contains(&p) {
            assert_eq!((up, low, mouth), (0.0, 0.0, 1.0), "lip point {p}");
        } else if brows.contains(&p) {
            assert_eq!((up, low), (1.0, 0.0), "brow point {p}");
        } else if jaw.contains(&p) {
            assert_eq!((up, low), (0.0, 1.0), "jaw point {p}");
        } else {
            // Nose and eyes: the region of the nearest brow or jaw point.
            let nearest = (0..=26)
                .min_by(|&a, &b| d2(p, a).total_cmp(&d2(p, b)))
                .unwrap();
            let want = if brows.contains(&nearest) {
                (1.0, 0.0)
            } else {
                (0.0, 1.0)
            };
            assert_eq!((up, low), want, "point {p}, nearest cover point {nearest}");
            joined[usize::from(low == 1.0)] += 1;
        }
    }
    assert!(joined[0] > 0 && joined[1] > 0, "{joined:?}");
    // 67 points against the 68-point layout: point 67 (a lip) lies past the shape.
    let short = seq.coords.rows(0, 134).into_owned();
    let all: ModeRegions = serde_json::from_str(
        r#"{"layout": "ibug68", "regions": {"face": ["lips"], "brows": ["left_eyebrow"]},
            "cover": ["face", "brows"]}"#,
    )
    .unwrap();
    let e = all
        .weights(&layout, &short, 2, &RegionOptions::default())
        .unwrap_err()
        .kind_is(ErrorKind::Invalid);
    assert!(
        e.contains("region point 67 is beyond the shape's 67 points"),
        "{e}"
    );
}

/// The blend radius's unit: the RMS distance of a shape's points from their centroid, by
/// hand in 2-D and 3-D, unchanged by a translation, 0 for no points.
#[test]
fn shape_size_is_the_rms_distance_from_the_centroid() {
    let square = [0.0, 0.0, 2.0, 0.0, 0.0, 2.0, 2.0, 2.0];
    assert!((shape_size(&square, 2) - 2f64.sqrt()).abs() < 1e-15);
    // Centroid (1, 0, 2); squared distances 5, 8, 17: RMS sqrt(30 / 3).
    let tri = [0.0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 0.0, 6.0];
    assert!((shape_size(&tri, 3) - 10f64.sqrt()).abs() < 1e-15);
    let moved: Vec<f64> = tri
        .iter()
        .enumerate()
        .map(|(i, v)| v + [7.0, -3.0, 0.5][i % 3])
        .collect();
    assert!((shape_size(&moved, 3) - 10f64.sqrt()).abs() < 1e-14);
    assert_eq!(shape_size(&[], 2), 0.0);
}

/// The mean of a table's upper triangle by hand (diagonal and lower triangle ignored), 0
/// without pairs; Eq. (9) is 0 when either vector is zero (not 0/0).
#[test]
fn mean_upper_and_eq9_of_a_zero_vector_by_hand() {
    use keyshape_actions::modes::OrthogonalityStudy;
    let m =
        nalgebra::DMatrix::from_row_slice(3, 3, &[9.0, 0.2, 0.4, -7.0, 9.0, 0.9, 5.0, 3.0, 9.0]);
    assert!((OrthogonalityStudy::mean_upper(&m) - 0.5).abs() < 1e-15);
    assert_eq!(
        OrthogonalityStudy::mean_upper(&nalgebra::DMatrix::from_element(1, 1, 4.0)),
        0.0
    );
    assert_eq!(
        OrthogonalityStudy::mean_upper(&nalgebra::DMatrix::zeros(0, 0)),
        0.0
    );
    let z = DVector::zeros(3);
    let v = DVector::from_vec(vec![1.0, 2.0, 3.0]);
    assert_eq!(orthogonality(&z, &v), 0.0);
    assert_eq!(orthogonality(&v, &z), 0.0);
    assert_eq!(orthogonality(&z, &z), 0.0);
}

#[test]
fn empty_or_unknown_regions_are_explained() {
    let layout = Layout::mediapipe468();
    let r: ModeRegions =
        serde_json::from_str(r#"{"layout": "mediapipe_face_mesh_468", "regions": {"mouth": []}}"#)
            .unwrap();
    assert!(r
        .points(&layout)
        .unwrap_err()
        .kind_is(ErrorKind::Invalid)
        .contains("region 'mouth' names no groups"));
    let r: ModeRegions = serde_json::from_str(
        r#"{"layout": "mediapipe_face_mesh_468", "regions": {"mouth": ["lipz"]}}"#,
    )
    .unwrap();
    assert!(r
        .points(&layout)
        .unwrap_err()
        .kind_is(ErrorKind::Invalid)
        .contains("region 'mouth': unknown point group 'lipz'"));
    let r: ModeRegions =
        serde_json::from_str(r#"{"layout": "ibug68", "regions": {"mouth": ["lips"]}}"#).unwrap();
    assert!(r
        .points(&layout)
        .unwrap_err()
        .kind_is(ErrorKind::Invalid)
        .contains("regions are for layout ibug68"));
}

/// With 68 points (136 values per shape) `Pca::fit_leading` takes the full decomposition,
/// so the block-wise action model must be fit_leading's on the materialised set, bit for
/// bit (a generated 3,000-frame track, iBUG regions: several blocks of 4,096 shapes).
#[test]
fn the_block_wise_action_model_is_fit_leadings_on_68_points() {
    let mut text = Vec::new();
    keyshape_io::synthetic::write_long_track(&mut text, 3000, 68, 5).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("long.csv");
    std::fs::write(&path, &text).unwrap();
    let seq = keyshape_io::read_sequence(&path, &Default::default()).unwrap();
    let prep = keyshape_core::decompose::prepare(
        &seq,
        &keyshape_core::decompose::PrepareOptions::all_aligned(),
    )
    .unwrap();
    let layout = Layout::ibug68();
    let regions = ModeRegions::builtin(&layout)
        .unwrap()
        .weights(&layout, &prep.seq.coords, 2, &RegionOptions::default())
        .unwrap();
    let q = &prep.seq.coords;
    assert!(q.ncols() * regions.len() > 4096, "more than one block");
    let whole = keyshape_core::pca::Pca::fit_leading(&artificial_set(q, &regions, 2), 10).unwrap();
    let blocks = keyshape_actions::modes::artificial_pca(q, &regions, 2, 10).unwrap();
    assert_eq!(blocks.components, whole.components);
    assert_eq!(blocks.variances, whole.variances);
    assert_eq!(blocks.mean, whole.mean);
    assert_eq!(
        blocks.total_variance.to_bits(),
        whole.total_variance.to_bits()
    );
}

/// `Pca::fit_blocks` at its edges: one column and more values than columns are refused
/// with a message; two columns, and as many columns as values, are fitted exactly as
/// `Pca::fit` fits the same matrix.
#[test]
fn block_wise_pca_refuses_what_it_cannot_fit_and_fits_its_edges() {
    use keyshape_core::pca::Pca;
    let m = nalgebra::DMatrix::from_fn(3, 5, |i, j| {
        ((i * 7 + j * 3) % 5) as f64 + 0.1 * (i * j) as f64
    });
    let fit = |rows: usize, n: usize| {
        let part = m.view((0, 0), (rows, n)).clone_owned();
        let blocks = Pca::fit_blocks(rows, n, &|s, w| part.columns(s, w).clone_owned());
        (blocks, part)
    };
    let e = fit(2, 1).0.unwrap_err().kind_is(ErrorKind::Unfit);
    assert!(e.contains("at least 2 frames"), "{e}");
    let e = fit(3, 2).0.unwrap_err().kind_is(ErrorKind::Invalid);
    assert!(e.contains("at least as many columns"), "{e}");
    for (rows, n) in [(2, 2), (3, 3), (3, 5)] {
        let (blocks, part) = fit(rows, n);
        let blocks = blocks.unwrap();
        let whole = Pca::fit(&part).unwrap();
        assert_eq!(blocks.components, whole.components, "{rows} × {n}");
        assert_eq!(blocks.variances, whole.variances);
        assert_eq!(blocks.mean, whole.mean);
    }
}

/// A glTF export carries only the shapes the performance uses: a shape whose weights are
/// all 0 is left out (and so is one only ever negative, which blends as 0), and each used
/// shape's sparse offsets land on their vertices, zero elsewhere.
#[test]
fn used_dense_keeps_the_shapes_with_a_positive_weight() {
    use keyshape_io::morph::MorphTargets;
    let t = MorphTargets {
        names: vec!["a".into(), "b".into(), "c".into(), "d".into()],
        deltas: vec![
            vec![(0, [1.0, 0.0, 0.0])],
            vec![(2, [0.0, 2.0, 0.0]), (4, [0.0, 0.0, 3.0])],
            vec![(1, [5.0, 5.0, 5.0])],
            vec![(3, [1.0, 1.0, 1.0])],
        ],
    };
    let w = nalgebra::DMatrix::from_row_slice(
        4,
        3,
        &[0.0, 0.0, 0.0, 0.0, 0.5, 0.0, -0.2, -1.0, 0.0, 0.0, 0.0, 1.0],
    );
    let (dense, used) = t.used_dense(&w, 5);
    let names: Vec<&str> = dense.iter().map(|d| d.0.as_str()).collect();
    assert_eq!(names, ["b", "d"]);
    assert_eq!(used.nrows(), 2);
    assert_eq!(
        used.row(0).iter().copied().collect::<Vec<_>>(),
        [0.0, 0.5, 0.0]
    );
    assert_eq!(
        used.row(1).iter().copied().collect::<Vec<_>>(),
        [0.0, 0.0, 1.0]
    );
    assert_eq!(
        dense[0].1,
        vec![
            [0.0; 3],
            [0.0; 3],
            [0.0, 2.0, 0.0],
            [0.0; 3],
            [0.0, 0.0, 3.0]
        ]
    );
    assert_eq!(dense[1].1[3], [1.0, 1.0, 1.0]);
}

/// Eq. 8's weights from action trajectories: `clamp(Σ gain · max(0, a(t)), 0, 1)`, by hand
/// on gains that are not 1 and two actions sharing a shape; an unknown name is an error.
#[test]
fn morph_mapping_weights_are_clamped_gain_sums_of_the_positive_trajectory() {
    use keyshape_actions::morph::MorphMapping;
    use keyshape_io::morph::MorphTargets;
    let t = MorphTargets {
        names: vec!["a".into(), "b".into()],
        deltas: vec![Vec::new(), Vec::new()],
    };
    let mapping: MorphMapping = serde_json::from_str(
        r#"{"actions": {"up": [["a", 0.5], ["b", 2.0]], "down": [["b", 0.25]]}}"#,
    )
    .unwrap();
    let names = vec!["up".to_string(), "down".to_string()];
    let traj = nalgebra::DMatrix::from_row_slice(2, 4, &[-0.5, 0.3, 0.8, 0.1, 0.4, 0.4, -1.0, 0.8]);
    let w = mapping.weights(&t, &names, &traj).unwrap();
    let want = [
        [0.0, 0.15, 0.4, 0.05],
        [0.1, (2.0 * 0.3 + 0.25 * 0.4f64).min(1.0), 1.0, 0.2 + 0.2],
    ];
    for s in 0..2 {
        for f in 0..4 {
            assert!(
                (w[(s, f)] - want[s][f]).abs() < 1e-12,
                "shape {s} frame {f}: {}",
                w[(s, f)]
            );
        }
    }
    let bad: MorphMapping = serde_json::from_str(r#"{"actions": {"up": [["zz", 1.0]]}}"#).unwrap();
    let e = bad
        .weights(&t, &names, &traj)
        .unwrap_err()
        .kind_is(ErrorKind::Invalid);
    assert!(e.contains("'zz'"), "{e}");
    let bad: MorphMapping =
        serde_json::from_str(r#"{"actions": {"sideways": [["a", 1.0]]}}"#).unwrap();
    let e = bad
        .weights(&t, &names, &traj)
        .unwrap_err()
        .kind_is(ErrorKind::Invalid);
    assert!(e.contains("'sideways'") && e.contains("up, down"), "{e}");
}

/// The normalisation's name is the one its option and the experiment files spell.
#[test]
fn normalisation_names_are_the_spelling_the_options_read() {
    use keyshape_actions::trajectory::Normalisation;
    for n in [Normalisation::TwoSided, Normalisation::OneSided] {
        let spelled = serde_json::to_string(&n).unwrap();
        assert_eq!(spelled, format!("\"{}\"", n.name()));
        let back: Normalisation = serde_json::from_str(&spelled).unwrap();
        assert_eq!(back, n);
    }
    assert_eq!(Normalisation::TwoSided.name(), "two-sided");
    assert_eq!(Normalisation::OneSided.name(), "one-sided");
    // Region boundaries (reported by `kslab modes --json`) and the study's centrings.
    for b in [Boundary::Blended, Boundary::Disjoint] {
        assert_eq!(
            serde_json::to_string(&b).unwrap(),
            format!("\"{}\"", b.name())
        );
    }
    assert_eq!(Boundary::Blended.name(), "blended");
    assert_eq!(Boundary::Disjoint.name(), "disjoint");
    use keyshape_actions::intensity::Centring;
    for c in [Centring::ClipMean, Centring::Causal, Centring::Neutral] {
        assert_eq!(
            serde_json::to_string(&c).unwrap(),
            format!("\"{}\"", c.name())
        );
    }
}

/// A library error's kind checked before its words are read: a test acts on the kind, as a
/// caller would, and reads the message only for what it must name.
trait KindIs {
    fn kind_is(self, kind: keyshape_core::ErrorKind) -> String;
}

impl KindIs for keyshape_core::Error {
    #[track_caller]
    fn kind_is(self, kind: keyshape_core::ErrorKind) -> String {
        assert_eq!(self.kind(), kind, "{self}");
        self.to_string()
    }
}
