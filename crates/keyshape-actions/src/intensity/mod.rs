//! Automatic action intensities (Cosker et al., paper 002 §4.1): a soft K-nearest-neighbour
//! classifier gives each frame a proportion per action class; each track is median-filtered
//! (window 3) and smoothed by a least-squares polynomial; quality is the correlation
//! coefficient with a ground truth (Eq. 10).

mod signal;

pub use signal::{median3, polyfit_smooth, soft_knn};

use keyshape_core::error::{Error, Result};
use nalgebra::{DMatrix, DVector};

use keyshape_core::stats::correlation;

/// Actions scored in the study, each the mean of its ARKit-style columns.
pub const STUDY_ACTIONS: [(&str, &[&str]); 3] = [
    ("smile", &["mouthSmileLeft", "mouthSmileRight"]),
    ("brow_raise", &["browInnerUp"]),
    ("blink", &["eyeBlinkLeft", "eyeBlinkRight"]),
];

/// How each frame's features are centred: the study subtracts a per-clip reference shape
/// from every aligned shape (the clips are different people; without it KNN matches identity,
/// not expression). The reference comes from:
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Centring {
    /// the mean of all the clip's frames, future ones included (offline, as before);
    #[default]
    ClipMean,
    /// the mean of the clip's frames up to and including this one (causal: a live system
    /// can do it);
    Causal,
    /// the mean of the clip's first `neutral_frames` frames (a neutral segment at the start,
    /// also causal).
    Neutral,
}

impl std::str::FromStr for Centring {
    type Err = keyshape_core::error::Error;

    /// The option's spelling on the command line and in experiment files.
    fn from_str(s: &str) -> keyshape_core::error::Result<Centring> {
        match s {
            "clip-mean" => Ok(Centring::ClipMean),
            "causal" => Ok(Centring::Causal),
            "neutral" => Ok(Centring::Neutral),
            _ => Err(keyshape_core::error::Error::bad_setting(
                "centring",
                s,
                format!("'{s}': choose clip-mean, causal or neutral"),
            )),
        }
    }
}

impl Centring {
    /// The name used in files and options.
    pub fn name(self) -> &'static str {
        match self {
            Centring::ClipMean => "clip-mean",
            Centring::Causal => "causal",
            Centring::Neutral => "neutral",
        }
    }
}

/// Which clips train and which are tested.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Evaluation {
    /// Train on `train_clips`, test on the others (one split).
    #[default]
    Split,
    /// Each clip in turn is tested by a model trained on all the other clips: every person
    /// is held out once.
    LeaveOneClipOut,
}

impl std::str::FromStr for Evaluation {
    type Err = keyshape_core::error::Error;

    /// The option's spelling on the command line and in experiment files.
    fn from_str(s: &str) -> keyshape_core::error::Result<Evaluation> {
        match s {
            "split" => Ok(Evaluation::Split),
            "leave-one-clip-out" => Ok(Evaluation::LeaveOneClipOut),
            _ => Err(keyshape_core::error::Error::bad_setting(
                "evaluation",
                s,
                format!("'{s}': choose split or leave-one-clip-out"),
            )),
        }
    }
}

/// Settings of the intensity study: plain parameters (an experiment file's `[intensity]`
/// section is read into them by keyshape-experiments; `kslab intensity` fills them from
/// its flags). Serialised as the reports print them.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct StudySettings {
    /// Training clips, inclusive range (split evaluation only; default 1..14).
    pub train_clips: Option<(usize, usize)>,
    /// K of the soft KNN.
    pub k: usize,
    /// Polynomial degree.
    pub degree: usize,
    /// Labelling threshold on the scores.
    pub threshold: f64,
    /// Reference shape subtracted per clip.
    pub centring: Centring,
    /// Frames of the neutral segment (`centring = "neutral"` only).
    pub neutral_frames: Option<usize>,
    /// Split or leave-one-clip-out.
    pub evaluation: Evaluation,
}

/// The default training clips of the split evaluation.
pub const DEFAULT_TRAIN_CLIPS: (usize, usize) = (1, 14);

impl Default for StudySettings {
    fn default() -> Self {
        StudySettings {
            train_clips: None,
            // Paper 002 §4's K, and its smoothing polynomial's degree.
            k: 10,
            degree: 5,
            threshold: 0.4,
            centring: Centring::ClipMean,
            neutral_frames: None,
            evaluation: Evaluation::Split,
        }
    }
}

impl StudySettings {
    /// Checks the settings; an option that cannot apply is an error, not ignored.
    pub fn check(&self) -> Result<()> {
        keyshape_core::limits::POLY_DEGREE.check_count("degree", self.degree as u64)?;
        if !(self.threshold.is_finite() && self.threshold > 0.0 && self.threshold < 1.0) {
            return Err(Error::bad_setting(
                "threshold",
                self.threshold,
                format!(
                    "threshold {:?} must lie in (0, 1): it is an ARKit-style score",
                    self.threshold
                ),
            ));
        }
        if self.evaluation == Evaluation::LeaveOneClipOut && self.train_clips.is_some() {
            return Err(Error::bad_setting(
                "train_clips",
                format!("{:?}", self.train_clips),
                "train clips apply to the split evaluation; leave-one-clip-out trains on every other clip",
            ));
        }
        match (self.centring, self.neutral_frames) {
            (Centring::Neutral, None | Some(0)) => Err(Error::bad_setting(
                "neutral_frames",
                self.neutral_frames.unwrap_or(0),
                "neutral centring needs the number of neutral frames at the start of each clip (≥ 1)",
            )),
            (Centring::ClipMean | Centring::Causal, Some(n)) => Err(Error::bad_setting(
                "neutral_frames",
                n,
                format!(
                    "neutral frames apply only to neutral centring, not to {}",
                    self.centring.name()
                ),
            )),
            _ => Ok(()),
        }
    }

    /// The training clips of the split evaluation.
    pub fn train_range(&self) -> (usize, usize) {
        self.train_clips.unwrap_or(DEFAULT_TRAIN_CLIPS)
    }
}

/// Eq. (10) of one test clip.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ClipRow {
    /// Action.
    pub action: String,
    /// Clip id.
    pub clip: usize,
    /// Frames in the clip.
    pub frames: usize,
    /// Raw proportions (NaN when the clip's score does not vary: no correlation exists).
    pub raw: f64,
    /// After the median filter.
    pub median3: f64,
    /// After the polynomial fit.
    pub smoothed: f64,
}

/// The median, lower and upper quartile and count of the defined per-clip correlations.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct Spread {
    /// Median.
    pub median: f64,
    /// Lower quartile.
    pub q1: f64,
    /// Upper quartile.
    pub q3: f64,
    /// Clips with a defined correlation.
    pub clips: usize,
}

/// Median and quartiles (linear interpolation) of the finite values.
pub fn spread(values: &[f64]) -> Spread {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    let q = |f: f64| {
        if v.is_empty() {
            return f64::NAN;
        }
        let x = f * (v.len() - 1) as f64;
        let (i, t) = (x.floor() as usize, x - x.floor());
        if i + 1 < v.len() {
            v[i] * (1.0 - t) + v[i + 1] * t
        } else {
            v[i]
        }
    };
    Spread {
        median: q(0.5),
        q1: q(0.25),
        q3: q(0.75),
        clips: v.len(),
    }
}

/// One action's result.
#[derive(Debug, Clone, serde::Serialize)]
pub struct StudyRow {
    /// Action.
    pub action: String,
    /// Training frames labelled with it (summed over folds).
    pub training_frames_labelled: usize,
    /// Eq. (10) of the raw proportions, all test frames pooled.
    pub correlation_raw: f64,
    /// After the median filter.
    pub correlation_median3: f64,
    /// After the polynomial fit.
    pub correlation_smoothed: f64,
    /// Per-clip correlations of the raw proportions: median and quartiles.
    pub clips_raw: Spread,
    /// … after the median filter.
    pub clips_median3: Spread,
    /// … after the polynomial fit.
    pub clips_smoothed: Spread,
}

/// The study's result.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Study {
    /// Training frames (summed over folds).
    pub train_frames: usize,
    /// Test frames.
    pub test_frames: usize,
    /// Test clips (held-out people).
    pub test_clips: Vec<usize>,
    /// What the features are, in words.
    pub features: String,
    /// Per action.
    pub actions: Vec<StudyRow>,
    /// Per action and test clip.
    pub clips: Vec<ClipRow>,
}

/// Each column of `x` minus its clip's reference shape (`clips[t]` names column t's clip;
/// a clip's columns are in time order).
pub fn centre(x: &mut DMatrix<f64>, clips: &[usize], st: &StudySettings) -> Result<()> {
    let ids: std::collections::BTreeSet<usize> = clips.iter().copied().collect();
    for &c in &ids {
        let members: Vec<usize> = (0..clips.len()).filter(|&t| clips[t] == c).collect();
        match st.centring {
            Centring::ClipMean => {
                let mean = x.select_columns(&members).column_mean();
                for &t in &members {
                    let mut col = x.column_mut(t);
                    col -= &mean;
                }
            }
            Centring::Neutral => {
                let n = st.neutral_frames.unwrap_or(1);
                if members.len() < n {
                    return Err(Error::invalid(format!(
                        "clip {c} has {} frames, fewer than the {n} neutral frames asked for",
                        members.len()
                    )));
                }
                let mean = x.select_columns(&members[..n]).column_mean();
                for &t in &members {
                    let mut col = x.column_mut(t);
                    col -= &mean;
                }
            }
            Centring::Causal => {
                let mut sum = DVector::zeros(x.nrows());
                for (i, &t) in members.iter().enumerate() {
                    sum += x.column(t);
                    let mean = &sum / (i + 1) as f64;
                    let mut col = x.column_mut(t);
                    col -= &mean;
                }
            }
        }
    }
    Ok(())
}

/// Soft-KNN intensities on a py-feat table (landmarks, `clip`, ARKit-style scores), tested on
/// clips (people) the model was not trained on. Features: the 68 landmarks aligned by
/// generalised Procrustes over the whole table (a similarity per frame, which removes head
/// position, roll and scale), minus the clip's reference shape ([`Centring`]). Training
/// labels: a frame's strongest study action when its score exceeds the threshold, else
/// neutral. Each test clip's proportions go through median-3 and a polynomial separately.
pub fn study(path: &std::path::Path, st: &StudySettings) -> Result<Study> {
    study_with_format(path, None, st)
}

/// [`study`] with the reader forced to `format` (None: detected from the file).
pub fn study_with_format(
    path: &std::path::Path,
    format: Option<keyshape_core::sequence::Format>,
    st: &StudySettings,
) -> Result<Study> {
    use keyshape_core::decompose::{prepare, PrepareOptions};
    use keyshape_io::{read_sequence, ReadOptions};
    st.check()?;
    let seq = read_sequence(path, &ReadOptions { format, dims: 2 })?;
    let clips = clip_ids(path, &seq)?;
    let truth = action_truth(path, &seq)?;
    let prep = prepare(&seq, &PrepareOptions::all_aligned())?;
    let mut x = prep.seq.coords.clone();
    centre(&mut x, &clips, st)?;
    let ids: Vec<usize> = clips
        .iter()
        .copied()
        .collect::<std::collections::BTreeSet<usize>>()
        .into_iter()
        .collect();
    let folds = folds(&ids, st)?;
    let n_act = STUDY_ACTIONS.len();
    let mut pooled: Vec<[Vec<f64>; 4]> = (0..n_act).map(|_| Default::default()).collect();
    let mut labelled = vec![0usize; n_act];
    let mut clip_rows = Vec::new();
    let (mut train_frames, mut test_frames) = (0, 0);
    let mut test_clips = Vec::new();
    for (tr, te) in &folds {
        let train: Vec<usize> = (0..clips.len())
            .filter(|&t| tr.contains(&clips[t]))
            .collect();
        let test: Vec<usize> = (0..clips.len())
            .filter(|&t| te.contains(&clips[t]))
            .collect();
        train_frames += train.len();
        test_frames += test.len();
        let labels: Vec<usize> = train
            .iter()
            .map(|&t| {
                let (best, v) = (0..n_act)
                    .map(|k| (k, truth[k][t]))
                    .fold((0, f64::MIN), |m, x| if x.1 > m.1 { x } else { m });
                if v > st.threshold {
                    best + 1
                } else {
                    0
                }
            })
            .collect();
        for k in 0..n_act {
            labelled[k] += labels.iter().filter(|&&l| l == k + 1).count();
        }
        let p = soft_knn(
            &x.select_columns(&train),
            &labels,
            n_act + 1,
            &x.select_columns(&test),
            st.k,
        )?;
        for &c in te {
            test_clips.push(c);
            let idx: Vec<usize> = (0..test.len()).filter(|&i| clips[test[i]] == c).collect();
            for (k, (name, _)) in STUDY_ACTIONS.iter().enumerate() {
                let r: Vec<f64> = idx.iter().map(|&i| p[(k + 1, i)]).collect();
                let m = median3(&r);
                let sm = polyfit_smooth(&m, st.degree);
                let gt: Vec<f64> = idx.iter().map(|&i| truth[k][test[i]]).collect();
                let varies = gt.iter().any(|&v| v != gt[0]);
                let c_of = |a: &[f64]| {
                    if varies && a.len() > 2 {
                        correlation(a, &gt)
                    } else {
                        f64::NAN
                    }
                };
                clip_rows.push(ClipRow {
                    action: name.to_string(),
                    clip: c,
                    frames: idx.len(),
                    raw: c_of(&r),
                    median3: c_of(&m),
                    smoothed: c_of(&sm),
                });
                pooled[k][0].extend(r);
                pooled[k][1].extend(m);
                pooled[k][2].extend(sm);
                pooled[k][3].extend(gt);
            }
        }
    }
    let rows = study_rows(&clip_rows, &pooled, &labelled);
    Ok(Study {
        train_frames,
        test_frames,
        test_clips,
        features: features_text(st),
        actions: rows,
        clips: clip_rows,
    })
}

/// Each frame's clip (person) as a number: the study tests on clips it did not train on.
fn clip_ids(path: &std::path::Path, seq: &keyshape_core::Sequence) -> Result<Vec<usize>> {
    seq
        .segments
        .as_ref()
        .ok_or_else(|| {
            Error::file(
                path,
                format!(
                    "read with the {} reader, which keeps no `clip` column (only the py-feat reader does): the study needs clips (people) to test on; force the py-feat reader if the file is one",
                    seq.format
                ),
            )
        })?
        .iter()
        .map(|c| {
            c.parse::<f64>()
                .map(|v| v as usize)
                .map_err(|_| Error::file(path, format!("clip id '{c}' is not a number")))
        })
        .collect::<Result<_>>()
}

/// Each study action's score per frame: the mean of its ARKit-style columns in the table.
fn action_truth(path: &std::path::Path, seq: &keyshape_core::Sequence) -> Result<Vec<Vec<f64>>> {
    let names: Vec<&str> = STUDY_ACTIONS
        .iter()
        .flat_map(|(_, c)| c.iter().copied())
        .collect();
    let cols = keyshape_io::read_columns(path, &names)?;
    let mut truth = Vec::new();
    let mut at = 0;
    for (_, c) in STUDY_ACTIONS {
        let n = c.len();
        truth.push(
            (0..seq.n_frames())
                .map(|t| (at..at + n).map(|k| cols[k][t]).sum::<f64>() / n as f64)
                .collect::<Vec<f64>>(),
        );
        at += n;
    }
    Ok(truth)
}

/// The folds, as (training clips, test clips): one split, or each clip left out in turn.
fn folds(ids: &[usize], st: &StudySettings) -> Result<Vec<(Vec<usize>, Vec<usize>)>> {
    Ok(match st.evaluation {
        Evaluation::Split => {
            let (a, b) = st.train_range();
            let (tr, te): (Vec<usize>, Vec<usize>) = ids.iter().partition(|&&c| c >= a && c <= b);
            if tr.is_empty() || te.is_empty() {
                return Err(Error::invalid(format!(
                    "train clips {a}..{b} leave no training or no test frames"
                )));
            }
            vec![(tr, te)]
        }
        Evaluation::LeaveOneClipOut => {
            if ids.len() < 2 {
                return Err(Error::invalid(
                    "leave-one-clip-out needs at least two clips",
                ));
            }
            ids.iter()
                .map(|&c| (ids.iter().copied().filter(|&o| o != c).collect(), vec![c]))
                .collect()
        }
    })
}

/// One row per action: its correlations pooled over the test clips and their spread
/// clip by clip.
fn study_rows(
    clip_rows: &[ClipRow],
    pooled: &[[Vec<f64>; 4]],
    labelled: &[usize],
) -> Vec<StudyRow> {
    STUDY_ACTIONS
        .iter()
        .enumerate()
        .map(|(k, (name, _))| {
            let per = |f: fn(&ClipRow) -> f64| {
                let v: Vec<f64> = clip_rows
                    .iter()
                    .filter(|r| r.action == *name)
                    .map(f)
                    .collect();
                spread(&v)
            };
            StudyRow {
                action: name.to_string(),
                training_frames_labelled: labelled[k],
                correlation_raw: correlation(&pooled[k][0], &pooled[k][3]),
                correlation_median3: correlation(&pooled[k][1], &pooled[k][3]),
                correlation_smoothed: correlation(&pooled[k][2], &pooled[k][3]),
                clips_raw: per(|r| r.raw),
                clips_median3: per(|r| r.median3),
                clips_smoothed: per(|r| r.smoothed),
            }
        })
        .collect()
}

/// How the features were made, for the report.
fn features_text(st: &StudySettings) -> String {
    format!(
            "68 landmarks aligned by generalised Procrustes over the whole table, minus each clip's {} shape",
            match st.centring {
                Centring::ClipMean => "mean (all its frames)".to_string(),
                Centring::Causal => "running mean (its frames so far)".to_string(),
                Centring::Neutral => format!(
                    "mean of its first {} frames",
                    st.neutral_frames.unwrap_or(1)
                ),
            }
        )
}
