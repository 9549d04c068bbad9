//! Oracles for numbers the other tests did not pin down: each test
//! here fails on a plausible one-line bug that the suite used to let through.

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_actions::intensity::median3;
use nalgebra::DMatrix;

/// `../shared/data/<rel>` beside the repository.
fn shared(rel: &str) -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data")
        .join(rel)
}

/// Training labels by brute force from a py-feat table's own scores: a frame's strongest
/// study action (mean of its columns; the first in `STUDY_ACTIONS` order on a tie) when
/// that score is strictly above the threshold.
fn brute_force_labels(path: &std::path::Path, threshold: f64) -> [usize; 3] {
    use keyshape_actions::intensity::STUDY_ACTIONS;
    let mut rd = csv::Reader::from_path(path).unwrap();
    let header = rd.headers().unwrap().clone();
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let mut counts = [0usize; 3];
    for rec in rd.records() {
        let rec = rec.unwrap();
        let score: Vec<f64> = STUDY_ACTIONS
            .iter()
            .map(|(_, cs)| {
                cs.iter()
                    .map(|c| rec[col(c)].parse::<f64>().unwrap())
                    .sum::<f64>()
                    / cs.len() as f64
            })
            .collect();
        let (best, v) = (0..3).fold((0, f64::MIN), |m, k| {
            if score[k] > m.1 {
                (k, score[k])
            } else {
                m
            }
        });
        if v > threshold {
            counts[best] += 1;
        }
    }
    counts
}

/// The news sample rewritten into `dir/name`: `edit` gets each record (as strings) and the
/// column lookup, changes it in place and says whether to keep it.
fn edited_news(
    dir: &std::path::Path,
    name: &str,
    edit: impl Fn(&dyn Fn(&str) -> usize, &mut Vec<String>) -> bool,
) -> std::path::PathBuf {
    let path = shared("pyfeat_samples/news_sample_compact.csv");
    let mut rd = csv::Reader::from_path(&path).unwrap();
    let header = rd.headers().unwrap().clone();
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let out = dir.join(name);
    let mut w = csv::Writer::from_path(&out).unwrap();
    w.write_record(&header).unwrap();
    for rec in rd.records() {
        let mut r: Vec<String> = rec.unwrap().iter().map(str::to_string).collect();
        if edit(&col, &mut r) {
            w.write_record(&r).unwrap();
        }
    }
    w.flush().unwrap();
    out
}
/// Median of three keeps a two-sample pulse (a median of five would remove it) and removes
/// a one-sample spike; the ends are kept.
#[test]
fn median3_keeps_a_two_sample_pulse_and_removes_a_spike() {
    assert_eq!(
        median3(&[0.0, 0.0, 9.0, 9.0, 0.0, 0.0, 0.0]),
        [0.0, 0.0, 9.0, 9.0, 0.0, 0.0, 0.0]
    );
    assert_eq!(
        median3(&[0.0, 0.0, 9.0, 0.0, 0.0]),
        [0.0, 0.0, 0.0, 0.0, 0.0]
    );
    assert_eq!(
        median3(&[5.0, 1.0, 2.0, 3.0, 7.0]),
        [5.0, 2.0, 2.0, 3.0, 7.0]
    );
}

/// soft KNN refuses mismatched inputs (labels or query rows) instead of reading past them.
#[test]
fn soft_knn_refuses_mismatched_inputs() {
    use keyshape_actions::intensity::soft_knn;
    let train = DMatrix::from_column_slice(2, 3, &[0.0, 0.0, 1.0, 0.0, 0.0, 1.0]);
    let query = DMatrix::from_column_slice(2, 1, &[0.1, 0.1]);
    assert!(soft_knn(&train, &[0, 1, 1], 2, &query, 2).is_ok());
    let e = soft_knn(&train, &[0, 1], 2, &query, 2)
        .unwrap_err()
        .to_string();
    assert!(e.contains("do not match"), "{e}");
    let q3 = DMatrix::from_column_slice(3, 1, &[0.1, 0.1, 0.0]);
    let e = soft_knn(&train, &[0, 1, 1], 2, &q3, 2)
        .unwrap_err()
        .to_string();
    assert!(e.contains("do not match"), "{e}");
}

/// The polynomial fit returns one value per sample and is the least-squares polynomial:
/// a line through noisy points equals the closed-form regression line; one sample is kept.
/// Correlation of two points is ±1; K may equal the training count.
#[test]
fn polyfit_is_least_squares_and_correlation_handles_two_points() {
    use keyshape_actions::intensity::{polyfit_smooth, soft_knn};
    use keyshape_core::stats::correlation;
    let x = [1.0, 3.0, 2.0, 5.0, 4.0, 7.0, 5.5];
    let fit = polyfit_smooth(&x, 1);
    assert_eq!(fit.len(), x.len());
    let n = x.len() as f64;
    let (mt, mx) = (3.0, x.iter().sum::<f64>() / n);
    let slope = (0..x.len())
        .map(|i| (i as f64 - mt) * (x[i] - mx))
        .sum::<f64>()
        / (0..x.len()).map(|i| (i as f64 - mt).powi(2)).sum::<f64>();
    for (i, f) in fit.iter().enumerate() {
        let want = mx + slope * (i as f64 - mt);
        assert!(
            (f - want).abs() < 1e-12,
            "fit[{i}] = {f}, regression line {want}"
        );
    }
    assert_eq!(polyfit_smooth(&[4.0], 3), [4.0]);
    // An empty signal stays empty (a fit of no samples would be a non-square solve).
    assert!(polyfit_smooth(&[], 3).is_empty());
    assert!((correlation(&[1.0, 2.0], &[5.0, 9.0]) - 1.0).abs() < 1e-15);
    assert_eq!(correlation(&[1.0, 2.0, 3.0], &[5.0, 5.0, 5.0]), 0.0);
    assert_eq!(correlation(&[5.0, 5.0, 5.0], &[1.0, 2.0, 3.0]), 0.0);
    let train = DMatrix::from_column_slice(1, 3, &[0.0, 1.0, 2.0]);
    let p = soft_knn(
        &train,
        &[0, 1, 1],
        2,
        &DMatrix::from_column_slice(1, 1, &[0.1]),
        3,
    )
    .unwrap();
    assert!((p[(1, 0)] - 2.0 / 3.0).abs() < 1e-12, "{p}");
}

/// Paper 002's polynomial smoothing caps the degree at `n − 1`: three samples with degree
/// 5 are interpolated exactly by the quadratic through them.
#[test]
fn polyfit_caps_the_degree_at_the_clip_length() {
    use keyshape_actions::intensity::polyfit_smooth;
    let x = [1.0, 5.0, 2.0];
    let y = polyfit_smooth(&x, 5);
    for (a, b) in x.iter().zip(&y) {
        assert!((a - b).abs() < 1e-12, "{y:?}");
    }
    // Degree 1 on the same three samples is the least-squares line: mean 8/3, slope 0.5.
    let y = polyfit_smooth(&x, 1);
    let want = [8.0 / 3.0 - 0.5, 8.0 / 3.0, 8.0 / 3.0 + 0.5];
    for (a, b) in want.iter().zip(&y) {
        assert!((a - b).abs() < 1e-12, "{y:?}");
    }
}

/// The intensity study's settings: the threshold must lie strictly inside (0, 1), each
/// bound refused on its own side; a train range must leave both training and test clips.
#[test]
fn intensity_study_refuses_thresholds_outside_the_open_unit_interval_and_empty_splits() {
    use keyshape_actions::intensity::{study, Evaluation, StudySettings};
    for bad in [0.0, -0.5, 1.0, 1.5, f64::NAN, f64::INFINITY] {
        let st = StudySettings {
            threshold: bad,
            ..Default::default()
        };
        let e = st.check().unwrap_err().to_string();
        assert!(e.contains("must lie in (0, 1)"), "{bad}: {e}");
    }
    for good in [1e-9, 0.5, 0.999] {
        let st = StudySettings {
            threshold: good,
            ..Default::default()
        };
        assert!(st.check().is_ok(), "{good}");
    }
    let path = shared("pyfeat_samples/news_sample_compact.csv");
    for range in [(1, 20), (30, 40)] {
        let st = StudySettings {
            evaluation: Evaluation::Split,
            train_clips: Some(range),
            ..Default::default()
        };
        let e = study(&path, &st).unwrap_err().to_string();
        assert!(
            e.contains("leave no training or no test frames"),
            "{range:?}: {e}"
        );
    }
}

/// The training labels counted per action are, by brute force from the CSV's own scores,
/// the frames whose strongest study action (mean of its columns) exceeds the threshold;
/// leave-one-clip-out trains on every frame 19 times (20 clips).
#[test]
fn intensity_study_counts_the_labelled_training_frames() {
    use keyshape_actions::intensity::{study, Evaluation, StudySettings, STUDY_ACTIONS};
    let path = shared("pyfeat_samples/news_sample_compact.csv");
    let st = StudySettings {
        evaluation: Evaluation::LeaveOneClipOut,
        ..Default::default()
    };
    let r = study(&path, &st).unwrap();
    let counts = brute_force_labels(&path, st.threshold);
    assert!(counts.iter().all(|&c| c > 0), "{counts:?}");
    for (k, (name, _)) in STUDY_ACTIONS.iter().enumerate() {
        let row = r.actions.iter().find(|a| a.action == *name).unwrap();
        assert_eq!(row.training_frames_labelled, 19 * counts[k], "{name}");
    }
}

/// The study's edge cases on an edited news sample: a tie between two actions goes to the
/// first (smile before brow raise), a score exactly at the threshold is not labelled, a clip
/// whose ground truth does not vary and a clip of two frames have no correlation (NaN, left
/// out of the spread), and leave-one-clip-out runs on two clips and refuses one.
#[test]
fn intensity_study_ties_thresholds_and_undefined_clips() {
    use keyshape_actions::intensity::{study, Evaluation, StudySettings, STUDY_ACTIONS};
    let dir = tempfile::tempdir().unwrap();
    let set = |col: &dyn Fn(&str) -> usize, r: &mut Vec<String>, name: &str, v: &str| {
        r[col(name)] = v.to_string();
    };
    let kept_of_7 = std::cell::Cell::new(0);
    let path = edited_news(dir.path(), "edited.csv", |col, r| {
        let clip: usize = r[col("clip")].parse::<f64>().unwrap() as usize;
        let frame: usize = r[col("frame")].parse::<f64>().unwrap() as usize;
        match clip {
            // Two frames only.
            7 => {
                kept_of_7.set(kept_of_7.get() + 1);
                kept_of_7.get() <= 2
            }
            // Blink held constant.
            13 => {
                set(col, r, "eyeBlinkLeft", "0.1");
                set(col, r, "eyeBlinkRight", "0.1");
                true
            }
            // Ties (smile = brow raise = 0.7) on frames 0, 4, 8, …, brow raise exactly at
            // the threshold (0.4) on frames 2, 6, 10, … (the sample keeps every other frame).
            2 => {
                let (smile, brow) = if frame % 4 == 0 {
                    ("0.7", "0.7")
                } else {
                    ("0", "0.4")
                };
                for c in ["mouthSmileLeft", "mouthSmileRight"] {
                    set(col, r, c, smile);
                }
                set(col, r, "browInnerUp", brow);
                for c in ["eyeBlinkLeft", "eyeBlinkRight"] {
                    set(col, r, c, "0");
                }
                true
            }
            _ => true,
        }
    });
    let st = StudySettings {
        evaluation: Evaluation::LeaveOneClipOut,
        ..Default::default()
    };
    let r = study(&path, &st).unwrap();
    let counts = brute_force_labels(&path, st.threshold);
    for (k, (name, _)) in STUDY_ACTIONS.iter().enumerate() {
        let row = r.actions.iter().find(|a| a.action == *name).unwrap();
        assert_eq!(row.training_frames_labelled, 19 * counts[k], "{name}");
    }
    let row = |action: &str, clip: usize| {
        r.clips
            .iter()
            .find(|c| c.action == action && c.clip == clip)
            .unwrap()
    };
    for (name, _) in STUDY_ACTIONS {
        let c7 = row(name, 7);
        assert_eq!(c7.frames, 2);
        assert!(
            c7.raw.is_nan() && c7.median3.is_nan() && c7.smoothed.is_nan(),
            "{c7:?}"
        );
    }
    let blink13 = row("blink", 13);
    assert!(
        blink13.raw.is_nan() && blink13.smoothed.is_nan(),
        "{blink13:?}"
    );
    let smile13 = row("smile", 13);
    assert!(
        smile13.raw.is_finite() && smile13.smoothed.is_finite(),
        "{smile13:?}"
    );
    // Undefined clips are left out of the spread: 20 clips, clip 7 never defined, clip 13's
    // blink neither.
    let blink = r.actions.iter().find(|a| a.action == "blink").unwrap();
    let defined = r
        .clips
        .iter()
        .filter(|c| c.action == "blink" && c.raw.is_finite())
        .count();
    assert_eq!(blink.clips_raw.clips, defined);
    assert!(defined <= 18, "{defined}");

    // Leave-one-clip-out on two clips runs (each held out once); on one it is refused.
    let two = edited_news(dir.path(), "two.csv", |col, r| {
        matches!(r[col("clip")].as_str(), "1" | "2" | "1.0" | "2.0")
    });
    let r2 = study(&two, &st).unwrap();
    assert_eq!(r2.test_clips, [1, 2]);
    let one = edited_news(dir.path(), "one.csv", |col, r| {
        matches!(r[col("clip")].as_str(), "1" | "1.0")
    });
    let e = study(&one, &st).unwrap_err().to_string();
    assert!(e.contains("needs at least two clips"), "{e}");
}
