//! Automatic action intensities (Cosker et al., paper 002 §4.1): a soft K-nearest-neighbour
//! classifier gives each frame a proportion per action class; each track is median-filtered
//! (window 3) and smoothed by a least-squares polynomial; quality is the correlation
//! coefficient with a ground truth (Eq. 10).

use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};

/// Soft KNN: for each query column, the share of its `k` nearest training columns
/// (Euclidean) in each class (`labels[i]` < `classes`). Rows: classes; columns: queries.
pub fn soft_knn(
    train: &DMatrix<f64>,
    labels: &[usize],
    classes: usize,
    query: &DMatrix<f64>,
    k: usize,
) -> Result<DMatrix<f64>> {
    if train.ncols() != labels.len() || train.nrows() != query.nrows() {
        return Err(Error::invalid(
            "KNN: training features, labels and queries do not match",
        ));
    }
    if k == 0 || k > train.ncols() {
        return Err(Error::invalid(format!(
            "KNN: K = {k} needs 1..={} training frames",
            train.ncols()
        )));
    }
    if let Some(&bad) = labels.iter().find(|&&l| l >= classes) {
        return Err(Error::invalid(format!(
            "KNN: label {bad} out of range (0..{classes})"
        )));
    }
    let mut out = DMatrix::zeros(classes, query.ncols());
    for q in 0..query.ncols() {
        let qc = query.column(q);
        let mut d: Vec<(f64, usize)> = (0..train.ncols())
            .map(|i| ((train.column(i) - qc).norm_squared(), i))
            .collect();
        d.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for &(_, i) in &d[..k] {
            out[(labels[i], q)] += 1.0 / k as f64;
        }
    }
    Ok(out)
}

/// Median filter with window 3; the ends keep their values.
pub fn median3(x: &[f64]) -> Vec<f64> {
    (0..x.len())
        .map(|i| {
            if i == 0 || i + 1 == x.len() {
                return x[i];
            }
            let mut w = [x[i - 1], x[i], x[i + 1]];
            w.sort_by(f64::total_cmp);
            w[1]
        })
        .collect()
}

/// Least-squares polynomial of `degree` through `(t, x[t])`, t scaled to \[−1, 1\] for
/// conditioning, evaluated at every t. The degree drops to fit short signals.
pub fn polyfit_smooth(x: &[f64], degree: usize) -> Vec<f64> {
    let n = x.len();
    if n < 2 {
        return x.to_vec();
    }
    let deg = degree.min(n - 1);
    let t = |i: usize| 2.0 * i as f64 / (n - 1) as f64 - 1.0;
    let a = DMatrix::from_fn(n, deg + 1, |i, j| t(i).powi(j as i32));
    let y = DVector::from_column_slice(x);
    let qr = a.clone().qr();
    match qr.r().solve_upper_triangular(&qr.q().tr_mul(&y)) {
        Some(c) => (&a * c).iter().copied().collect(),
        None => x.to_vec(),
    }
}

/// Paper 002 Eq. (10): the correlation coefficient of two signals (Pearson; 0 when either
/// is constant).
pub fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    if n < 2 {
        return 0.0;
    }
    let (ma, mb) = (
        a[..n].iter().sum::<f64>() / n as f64,
        b[..n].iter().sum::<f64>() / n as f64,
    );
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let (da, db) = (a[i] - ma, b[i] - mb);
        sab += da * db;
        saa += da * da;
        sbb += db * db;
    }
    if saa <= 0.0 || sbb <= 0.0 {
        0.0
    } else {
        sab / (saa * sbb).sqrt()
    }
}

/// Actions scored in the study, each the mean of its ARKit-style columns.
pub const STUDY_ACTIONS: [(&str, &[&str]); 3] = [
    ("smile", &["mouthSmileLeft", "mouthSmileRight"]),
    ("brow_raise", &["browInnerUp"]),
    ("blink", &["eyeBlinkLeft", "eyeBlinkRight"]),
];

/// Settings of the intensity study.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StudySettings {
    /// Training clips, inclusive range.
    pub train_clips: (usize, usize),
    /// K of the soft KNN.
    pub k: usize,
    /// Polynomial degree.
    pub degree: usize,
    /// Labelling threshold on the scores.
    pub threshold: f64,
}

impl Default for StudySettings {
    fn default() -> Self {
        StudySettings {
            train_clips: (1, 14),
            k: 10,
            degree: 5,
            threshold: 0.4,
        }
    }
}

/// One action's result.
#[derive(Debug, Clone, serde::Serialize)]
pub struct StudyRow {
    /// Action.
    pub action: String,
    /// Training frames labelled with it.
    pub training_frames_labelled: usize,
    /// Eq. (10) of the raw proportions.
    pub correlation_raw: f64,
    /// After the median filter.
    pub correlation_median3: f64,
    /// After the polynomial fit.
    pub correlation_smoothed: f64,
}

/// The study's result.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Study {
    /// Training frames.
    pub train_frames: usize,
    /// Test frames.
    pub test_frames: usize,
    /// Per action.
    pub actions: Vec<StudyRow>,
}

/// Soft-KNN intensities on a py-feat table (landmarks, `clip`, ARKit-style scores): train on
/// some clips, test on the rest. Features are aligned shapes minus their clip's mean shape
/// (clips are different people; otherwise KNN matches identity, not expression).
pub fn study(path: &std::path::Path, st: &StudySettings) -> Result<Study> {
    use crate::decompose::{prepare, PrepareOptions};
    use crate::io::{read_columns, read_sequence, ReadOptions};
    if !(st.threshold.is_finite() && st.threshold > 0.0 && st.threshold < 1.0) {
        return Err(Error::invalid(format!(
            "threshold {:?} must lie in (0, 1): it is an ARKit-style score",
            st.threshold
        )));
    }
    let seq = read_sequence(path, &ReadOptions::default())?;
    let clips: Vec<usize> = seq
        .segments
        .as_ref()
        .ok_or_else(|| Error::file(path, "no `clip` column"))?
        .iter()
        .map(|c| {
            c.parse::<f64>()
                .map(|v| v as usize)
                .map_err(|_| Error::file(path, format!("clip id '{c}' is not a number")))
        })
        .collect::<Result<_>>()?;
    let names: Vec<&str> = STUDY_ACTIONS
        .iter()
        .flat_map(|(_, c)| c.iter().copied())
        .collect();
    let cols = read_columns(path, &names)?;
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
    let prep = prepare(
        &seq,
        &PrepareOptions {
            points: None,
            align: true,
        },
    )?;
    let mut x = prep.seq.coords.clone();
    let ids: std::collections::BTreeSet<usize> = clips.iter().copied().collect();
    for &c in &ids {
        let members: Vec<usize> = (0..clips.len()).filter(|&t| clips[t] == c).collect();
        let mean = x.select_columns(&members).column_mean();
        for &t in &members {
            let mut col = x.column_mut(t);
            col -= &mean;
        }
    }
    let is_train = |c: usize| c >= st.train_clips.0 && c <= st.train_clips.1;
    let train: Vec<usize> = (0..clips.len()).filter(|&t| is_train(clips[t])).collect();
    let test: Vec<usize> = (0..clips.len()).filter(|&t| !is_train(clips[t])).collect();
    if train.is_empty() || test.is_empty() {
        return Err(Error::invalid(format!(
            "train clips {}..{} leave no training or no test frames",
            st.train_clips.0, st.train_clips.1
        )));
    }
    let labels: Vec<usize> = train
        .iter()
        .map(|&t| {
            let (best, v) = (0..STUDY_ACTIONS.len())
                .map(|k| (k, truth[k][t]))
                .fold((0, f64::MIN), |m, x| if x.1 > m.1 { x } else { m });
            if v > st.threshold {
                best + 1
            } else {
                0
            }
        })
        .collect();
    let p = soft_knn(
        &x.select_columns(&train),
        &labels,
        STUDY_ACTIONS.len() + 1,
        &x.select_columns(&test),
        st.k,
    )?;
    let mut rows = Vec::new();
    for (k, (name, _)) in STUDY_ACTIONS.iter().enumerate() {
        let (mut raw, mut med, mut smooth, mut gt) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for &c in ids.iter().filter(|c| !is_train(**c)) {
            let idx: Vec<usize> = (0..test.len()).filter(|&i| clips[test[i]] == c).collect();
            let r: Vec<f64> = idx.iter().map(|&i| p[(k + 1, i)]).collect();
            let m = median3(&r);
            smooth.extend(polyfit_smooth(&m, st.degree));
            raw.extend(r);
            med.extend(m);
            gt.extend(idx.iter().map(|&i| truth[k][test[i]]));
        }
        rows.push(StudyRow {
            action: name.to_string(),
            training_frames_labelled: labels.iter().filter(|&&l| l == k + 1).count(),
            correlation_raw: correlation(&raw, &gt),
            correlation_median3: correlation(&med, &gt),
            correlation_smoothed: correlation(&smooth, &gt),
        });
    }
    Ok(Study {
        train_frames: train.len(),
        test_frames: test.len(),
        actions: rows,
    })
}
