//! The experiment file's sections and their defaults.

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

/// What an experiment file's `[intensity]` leaves out is the paper's set-up, the study's
/// `Default` (K = 10, degree 5, threshold 0.4, clip-mean centring, the 1–14 split); a key
/// given is taken, and a key the section does not have is refused.
#[test]
fn study_settings_left_out_of_a_file_are_the_defaults() {
    use keyshape_actions::intensity::{Centring, Evaluation, StudySettings};
    use keyshape_experiments::experiment::spec::IntensitySpec;
    let read = |text: &str| serde_json::from_str::<IntensitySpec>(text).map(|s| s.settings());
    let d = StudySettings::default();
    assert_eq!(read("{}").unwrap(), d);
    assert_eq!((d.k, d.degree, d.threshold), (10, 5, 0.4));
    assert_eq!(
        (d.centring, d.evaluation),
        (Centring::ClipMean, Evaluation::Split)
    );
    assert_eq!((d.train_clips, d.neutral_frames), (None, None));
    assert_eq!(d.train_range(), (1, 14));
    let half = read(r#"{"threshold": 0.5, "evaluation": "leave-one-clip-out"}"#).unwrap();
    assert_eq!(
        half,
        StudySettings {
            threshold: 0.5,
            evaluation: Evaluation::LeaveOneClipOut,
            ..d.clone()
        }
    );
    let e = read(r#"{"kk": 3}"#).unwrap_err().to_string();
    assert!(e.contains("unknown field `kk`"), "{e}");
}
