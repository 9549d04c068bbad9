//! The jitter-against-error study: does a temporal prior inside the solver beat
//! a filter applied to the weights afterwards?
//!
//! One key set (a heuristic's frames), one solver. For every approach and setting — no
//! smoothing, the offline prior (order 1 and 2) and the causal prior at each λ, and the
//! post-filters (centred moving average, exponential moving average, One Euro) at a range
//! of strengths — the weights drive the built-in cartoon target (each key shape warped by
//! its multiquadric RBF `G`), and the study measures:
//!
//! * the source error (Eq. 5 as RMS per point);
//! * the target error against two references: `G(q_t)`, the warp of the tracked points
//!   (which carries the tracker's own frame-to-frame noise, so it rewards reproducing
//!   noise), and `G(q̃_t)`, the warp of a clean reference `q̃`: the tracked points through a
//!   zero-phase Gaussian low-pass of `clean_sigma` frames within each segment. The input
//!   solved is the tracked `q` itself, i.e. `q̃` plus exactly the noise the low-pass removed;
//! * the jitter: RMS of the second temporal difference of the retargeted target points
//!   (px/frame²) and of the weights;
//! * the lag: the shift (frames) that best aligns the smoothed weights with the unsmoothed
//!   ones by cross-correlation (positive: the smoothed weights come later).

use keyshape_core::decompose::Prepared;
use keyshape_core::error::{Error, Result};
use keyshape_core::keyshapes::{Analysis, KeyOptions, Method};
use keyshape_core::solve::filters::{Lowpass, PostFilter};
use keyshape_core::solve::jitter::jitter;
use keyshape_core::solve::temporal::{segments, smooth_from, SmoothMode, Smoothing};
use keyshape_core::solve::{solve_batch, SolveOptions, Solver};
use keyshape_core::stats::lag;
use nalgebra::DMatrix;
use serde::Serialize;

use super::spec::{all_families, default_lambdas, default_sigma};
pub use super::spec::{SmoothStudySettings, FAMILIES};
use std::ops::Range;

impl SmoothStudySettings {
    /// Defaults for a method, k (None: 12, or the hull's own) and solver.
    pub fn new(method: Method, k: Option<usize>, solver: Solver) -> Self {
        SmoothStudySettings {
            method,
            k,
            solver,
            lambdas: default_lambdas(),
            filters: all_families(),
            windows: None,
            alphas: None,
            one_euro_cutoffs: None,
            one_euro_betas: None,
            clean_sigma: default_sigma(),
        }
    }

    /// The k the key-shape method is asked for (the hull ignores it).
    pub fn key_count(&self) -> usize {
        self.k.unwrap_or(12)
    }

    fn runs(&self, family: &str) -> bool {
        self.filters.iter().any(|f| f == family)
    }

    /// Checks every setting.
    pub fn check(&self, fps: f64) -> Result<()> {
        if self.method == Method::Hull && self.k.is_some() {
            return Err(Error::bad_setting(
                "k",
                self.k.unwrap_or_default(),
                "k does not apply to the hull method: the hull gives its own number of key shapes",
            ));
        }
        if self.k == Some(0) {
            return Err(Error::bad_setting(
                "k",
                self.k.unwrap_or_default(),
                "the smoothing study needs k ≥ 1",
            ));
        }
        for &l in &self.lambdas {
            Smoothing {
                lambda: l,
                order: 1,
                mode: SmoothMode::Offline,
            }
            .check()?;
        }
        for f in &self.filters {
            if !FAMILIES.contains(&f.as_str()) {
                return Err(Error::bad_setting(
                    "filters",
                    f,
                    format!("unknown filter '{f}' (filters: {})", FAMILIES.join(", ")),
                ));
            }
        }
        for (family, given, name) in [
            ("moving-average", self.windows.is_some(), "windows"),
            ("ema", self.alphas.is_some(), "alphas"),
            (
                "one-euro",
                self.one_euro_cutoffs.is_some(),
                "one-euro cutoffs",
            ),
            ("one-euro", self.one_euro_betas.is_some(), "one-euro betas"),
        ] {
            if given && !self.runs(family) {
                return Err(Error::invalid(format!(
                    "{name} set, but the {family} filter is not among the filters compared ({})",
                    self.filters.join(", ")
                )));
            }
        }
        for f in self.filters(fps) {
            f.check()?;
        }
        keyshape_core::limits::CLEAN_SIGMA.check("clean_sigma", self.clean_sigma)?;
        Ok(())
    }

    fn filters(&self, fps: f64) -> Vec<PostFilter> {
        let mut f: Vec<PostFilter> = Vec::new();
        if self.runs("moving-average") {
            let w = self
                .windows
                .clone()
                .unwrap_or_else(|| vec![3, 5, 9, 15, 25]);
            f.extend(
                w.into_iter()
                    .map(|window| PostFilter::MovingAverage { window }),
            );
        }
        if self.runs("ema") {
            let a = self
                .alphas
                .clone()
                .unwrap_or_else(|| vec![0.7, 0.5, 0.3, 0.15, 0.08]);
            f.extend(a.into_iter().map(|alpha| PostFilter::Exponential { alpha }));
        }
        if self.runs("one-euro") {
            let cutoffs = self
                .one_euro_cutoffs
                .clone()
                .unwrap_or_else(|| vec![8.0, 4.0, 2.0, 1.0, 0.5]);
            for beta in self
                .one_euro_betas
                .clone()
                .unwrap_or_else(|| vec![0.05, 0.5])
            {
                f.extend(cutoffs.iter().map(|&min_cutoff| PostFilter::OneEuro {
                    min_cutoff,
                    beta,
                    d_cutoff: 1.0,
                    rate: fps,
                }));
            }
        }
        f
    }
}

/// One approach at one setting.
#[derive(Debug, Clone, Serialize)]
pub struct SmoothRow {
    /// `none`, `prior offline order 1`, `prior offline order 2`, `prior causal order 1`,
    /// `moving-average`, `ema`, `one-euro beta B`.
    pub approach: String,
    /// The setting in words (`λ 100`, `window 5` …).
    pub setting: String,
    /// Eq. 5 as RMS per point (input units).
    pub source_rms: f64,
    /// Target RMS per point against the warp of the tracked points.
    pub target_rms_tracked: f64,
    /// Target RMS per point against the warp of the clean reference.
    pub target_rms_clean: f64,
    /// RMS second difference of the target points (units/frame²).
    pub jitter_target: f64,
    /// RMS second difference of the weights (per frame²).
    pub jitter_weights: f64,
    /// Frames by which the weights trail the unsmoothed ones (cross-correlation peak).
    pub lag_frames: i64,
    /// Offline prior: KKT residual of its solve.
    pub kkt: Option<f64>,
}

/// Runs the study on a prepared 2-D sequence with a known layout (the built-in target needs
/// one). `seq` is the sequence `prep` came from.
pub fn smoothing_study(
    seq: &keyshape_core::sequence::Sequence,
    prep: &Prepared,
    st: &SmoothStudySettings,
    opts: &KeyOptions,
) -> Result<Vec<SmoothRow>> {
    st.check(seq.fps().unwrap_or(30.0))?;
    let (s, _) = key_shapes(prep.seq.coords.clone(), prep.seq.points, st, opts);
    study_with_keys(seq, prep, st, s?)
}

/// As [`smoothing_study`], choosing the key shapes on `prep`'s own coordinates instead of
/// a copy (they are handed back): for a long track held once. `seq` is the sequence
/// `prep` came from, or `None` when `prep` keeps every point (the built-in target is then
/// made from `prep` itself).
pub fn smoothing_study_in_place(
    seq: Option<&keyshape_core::sequence::Sequence>,
    prep: &mut Prepared,
    st: &SmoothStudySettings,
    opts: &KeyOptions,
) -> Result<Vec<SmoothRow>> {
    st.check(seq.unwrap_or(&prep.seq).fps().unwrap_or(30.0))?;
    let coords = std::mem::replace(&mut prep.seq.coords, DMatrix::zeros(0, 0));
    let (s, coords) = key_shapes(coords, prep.seq.points, st, opts);
    prep.seq.coords = coords;
    let s = s?;
    study_with_keys(seq.unwrap_or(&prep.seq), prep, st, s)
}

/// The study's key shapes, and the coordinates back (empty if the analysis failed).
fn key_shapes(
    coords: DMatrix<f64>,
    points: usize,
    st: &SmoothStudySettings,
    opts: &KeyOptions,
) -> (Result<DMatrix<f64>>, DMatrix<f64>) {
    let an = match Analysis::with_axes(
        coords,
        points,
        keyshape_core::keyshapes::axes_needed(&[st.method], st.key_count()),
    ) {
        Ok(an) => an,
        Err(e) => return (Err(e), DMatrix::zeros(0, 0)),
    };
    let s = st
        .method
        .heuristic(opts)
        .select(&an, st.key_count())
        .map(|sel| sel.key_shapes(&an));
    (s, an.coords)
}

/// A setting waiting to be measured: approach, setting, weights (keys × frames) and the
/// smoothed solve's KKT residual.
type Setting = (String, String, DMatrix<f64>, Option<f64>);

/// A setting's report row from its error sums over `values` coordinates; `w0` are the
/// unsmoothed weights the lag is measured against.
fn smooth_row(
    (approach, setting, w, kkt): Setting,
    e: &ErrorSums,
    values: usize,
    segs: &[Range<usize>],
    w0: &DMatrix<f64>,
) -> SmoothRow {
    let rms = |sq: f64| (sq / values.max(1) as f64).sqrt();
    SmoothRow {
        approach,
        setting,
        source_rms: rms(e.source),
        target_rms_tracked: rms(e.tracked),
        target_rms_clean: rms(e.clean),
        jitter_target: if e.jitter_count == 0 {
            0.0
        } else {
            (e.jitter / e.jitter_count as f64).sqrt()
        },
        jitter_weights: jitter(&w, segs, w.nrows()),
        lag_frames: lag(&w, w0, segs, 15),
        kkt,
    }
}

fn study_with_keys(
    seq: &keyshape_core::sequence::Sequence,
    prep: &Prepared,
    st: &SmoothStudySettings,
    s: DMatrix<f64>,
) -> Result<Vec<SmoothRow>> {
    let fps = seq.fps().unwrap_or(30.0);
    let q = &prep.seq.coords;
    let points = prep.seq.points;
    let segs = segments(&prep.seq.frames, prep.seq.segments.as_deref());
    let (g, _) = keyshape_retarget::setup::builtin_target(seq, prep)?;
    let b = g.apply_all(&s);
    let plain = solve_batch(&s, q, &SolveOptions::new(st.solver))?;
    let w0 = &plain.weights;
    // The settings' weights (keys × frames each) are kept until they add up to a quarter
    // of the coordinates' size, or to an offline solve's own working set (about six
    // keys × frames vectors) if that is larger, then their errors are measured in one
    // pass over the frames and the weights dropped. An offline solve starts with no more
    // kept than fits beside its working set in that budget (at 68 points: none), so the
    // settings waiting to be measured never add to the solves' peak.
    let solve_set = 6 * s.ncols() * q.ncols();
    let budget = (q.len() / 4).max(solve_set).max(1);
    let held = |sets: &[Setting]| sets.iter().map(|x| x.2.len()).sum::<usize>();
    let lowpass = Lowpass::new(st.clean_sigma);
    let frames = q.ncols();
    let mut rows = Vec::new();
    let mut sets: Vec<Setting> = Vec::new();
    let mut flush = |sets: &mut Vec<Setting>| {
        let errors = frame_errors(q, &lowpass, &s, &b, &g, sets, &segs, points);
        for (set, e) in sets.drain(..).zip(errors) {
            rows.push(smooth_row(set, &e, frames * points, &segs, w0));
        }
    };
    let full = |sets: &[Setting]| held(sets) >= budget;
    // The settings in the report's order: none, the prior offline order 1, order 2,
    // causal, the filters. The order-2 solves, which need the most memory, run first,
    // while no other setting's weights are held; the rows are put back in order at the end
    // (each row's figures do not depend on which others share its pass).
    let priors = [
        (SmoothMode::Offline, 1, "prior offline order 1"),
        (SmoothMode::Offline, 2, "prior offline order 2"),
        (SmoothMode::Causal, 1, "prior causal order 1"),
    ];
    let nl = st.lambdas.len();
    let mut place: Vec<usize> = Vec::new();
    for p in [1, 0, 2] {
        if p == 0 {
            place.push(0);
            sets.push(("none".into(), "λ 0".into(), w0.clone(), None));
            if full(&sets) {
                flush(&mut sets);
            }
        }
        let (mode, order, name) = priors[p];
        for (li, &lambda) in st.lambdas.iter().enumerate() {
            let sm = Smoothing {
                lambda,
                order,
                mode,
            };
            if mode == SmoothMode::Offline && held(&sets) + solve_set > budget {
                flush(&mut sets);
            }
            let r = smooth_from(&s, q, &plain, st.solver, &sm, &segs)?;
            if r.unconverged > 0 {
                return Err(Error::unfit(format!(
                    "{name} λ {lambda}: the smoothed solve did not settle (KKT residual {:e})",
                    r.kkt
                )));
            }
            place.push(1 + p * nl + li);
            sets.push((name.into(), format!("λ {lambda}"), r.weights, Some(r.kkt)));
            if full(&sets) {
                flush(&mut sets);
            }
        }
    }
    for (fi, f) in st.filters(fps).into_iter().enumerate() {
        let w = f.apply(w0, &segs, st.solver)?;
        place.push(1 + 3 * nl + fi);
        sets.push((f.series(), f.setting(), w, None));
        if full(&sets) {
            flush(&mut sets);
        }
    }
    if !sets.is_empty() {
        flush(&mut sets);
    }
    let mut placed: Vec<(usize, SmoothRow)> = place.into_iter().zip(rows).collect();
    placed.sort_by_key(|(i, _)| *i);
    Ok(placed.into_iter().map(|(_, r)| r).collect())
}

/// One setting's sums over the frames: squared source error, squared target error
/// against the warp of the tracked and of the clean points, and the target's squared
/// second differences with their count (as [`jitter`] sums them).
#[derive(Debug, Clone, Copy, Default)]
struct ErrorSums {
    source: f64,
    tracked: f64,
    clean: f64,
    jitter: f64,
    jitter_count: usize,
}

/// Frames handled at a time by [`frame_errors`].
const ERROR_CHUNK: usize = 4096;

/// Every setting's [`ErrorSums`], a chunk of frames at a time: the reconstructions
/// `S w_t` and `B w_t` and the references `G(q_t)` and `G(clean_t)` exist for one chunk
/// only (the low-pass too, frame by frame), so a long track is held once, not six times. Each
/// sum adds the frames in order, frame by frame, exactly as a norm over the whole matrix
/// adds them (column by column), so the figures are the whole-matrix ones.
#[allow(clippy::too_many_arguments)]
fn frame_errors(
    q: &DMatrix<f64>,
    lowpass: &Lowpass,
    s: &DMatrix<f64>,
    b: &DMatrix<f64>,
    g: &keyshape_core::rbf::Rbf,
    sets: &[Setting],
    segs: &[Range<usize>],
    points: usize,
) -> Vec<ErrorSums> {
    let frames = q.ncols();
    // Frames with both neighbours in their segment: where the second difference is taken.
    let mut interior = vec![false; frames];
    // Each frame's segment, for the low-pass.
    let mut seg_of = vec![0usize; frames];
    for (k, r) in segs.iter().enumerate() {
        for t in r.start + 1..r.end.saturating_sub(1) {
            interior[t] = true;
        }
        for t in r.clone() {
            seg_of[t] = k;
        }
    }
    let mut sums = vec![ErrorSums::default(); sets.len()];
    for c0 in (0..frames).step_by(ERROR_CHUNK) {
        let len = ERROR_CHUNK.min(frames - c0);
        let truth = g.apply_all(&q.columns(c0, len).clone_owned());
        let mut clean = DMatrix::zeros(q.nrows(), len);
        for j in 0..len {
            let t = c0 + j;
            match segs.get(seg_of[t]).filter(|r| r.contains(&t)) {
                Some(r) => clean.set_column(j, &lowpass.frame(q, r, t)),
                // A frame in no segment keeps its value, as gaussian_lowpass leaves it.
                None => clean.set_column(j, &q.column(t)),
            }
        }
        let truth_clean = g.apply_all(&clean);
        // One frame of context on each side for the second difference.
        let (lo, hi) = (c0.saturating_sub(1), (c0 + len + 1).min(frames));
        for ((_, _, w, _), e) in sets.iter().zip(sums.iter_mut()) {
            let rec = s * w.columns(c0, len);
            for t in 0..len {
                let d = rec.column(t) - q.column(c0 + t);
                e.source += d.dotc(&d);
            }
            let out = b * w.columns(lo, hi - lo);
            for t in c0..c0 + len {
                let o = out.column(t - lo);
                let d = o - truth.column(t - c0);
                e.tracked += d.dotc(&d);
                let d = o - truth_clean.column(t - c0);
                e.clean += d.dotc(&d);
                if interior[t] {
                    let d2 =
                        out.column(t + 1 - lo) - out.column(t - lo) * 2.0 + out.column(t - 1 - lo);
                    e.jitter += d2.norm_squared();
                    e.jitter_count += points;
                }
            }
        }
    }
    sums
}

/// Each approach's target errors interpolated at a common jitter level (linear between the
/// two neighbouring settings on its curve that bracket it; `None` when its settings do not reach that level).
#[derive(Debug, Clone, Serialize)]
pub struct AtJitter {
    /// Approach.
    pub approach: String,
    /// The jitter level (px/frame²).
    pub jitter_target: f64,
    /// Target error against the tracked reference there.
    pub target_rms_tracked: Option<f64>,
    /// Target error against the clean reference there.
    pub target_rms_clean: Option<f64>,
    /// Lag of the nearest setting (frames).
    pub lag_frames: Option<i64>,
}

/// Interpolates every approach at `fractions` of the unsmoothed jitter.
pub fn at_equal_jitter(rows: &[SmoothRow], fractions: &[f64]) -> Vec<AtJitter> {
    let Some(none) = rows.iter().find(|r| r.approach == "none") else {
        return Vec::new();
    };
    let mut names: Vec<&str> = Vec::new();
    for r in rows.iter().filter(|r| r.approach != "none") {
        if !names.contains(&r.approach.as_str()) {
            names.push(&r.approach);
        }
    }
    let mut out = Vec::new();
    for &f in fractions {
        let level = f * none.jitter_target;
        for n in &names {
            // Along the approach's own curve, from no smoothing through its settings in the
            // order given (weakest first): the first stretch that reaches the level. A filter
            // whose jitter does not fall with strength is not interpolated between settings
            // that are not neighbours.
            let mut pts: Vec<&SmoothRow> = vec![none];
            pts.extend(rows.iter().filter(|r| r.approach == *n));
            let bracket = pts.windows(2).find(|w| {
                let (a, c) = (w[0].jitter_target, w[1].jitter_target);
                a.min(c) <= level && level <= a.max(c)
            });
            let (tr, cl, lag) = match bracket {
                Some(w) => {
                    let span = w[1].jitter_target - w[0].jitter_target;
                    let u = if span != 0.0 {
                        (level - w[0].jitter_target) / span
                    } else {
                        0.0
                    };
                    let mix = |a: f64, b: f64| a + u * (b - a);
                    let near = if u < 0.5 { w[0] } else { w[1] };
                    (
                        Some(mix(w[0].target_rms_tracked, w[1].target_rms_tracked)),
                        Some(mix(w[0].target_rms_clean, w[1].target_rms_clean)),
                        Some(near.lag_frames),
                    )
                }
                None => (None, None, None),
            };
            out.push(AtJitter {
                approach: n.to_string(),
                jitter_target: level,
                target_rms_tracked: tr,
                target_rms_clean: cl,
                lag_frames: lag,
            });
        }
    }
    out
}

/// The one line a user wants from the study: at each jitter level of `at` (as
/// [`at_equal_jitter`] gives it), the approach with the lowest target error against the
/// clean reference, and its lag.
pub fn summary(at: &[AtJitter]) -> Option<String> {
    let mut levels: Vec<f64> = Vec::new();
    for a in at {
        if !levels.contains(&a.jitter_target) {
            levels.push(a.jitter_target);
        }
    }
    let parts: Vec<String> = levels
        .iter()
        .filter_map(|l| {
            at.iter()
                .filter(|a| a.jitter_target == *l)
                // Against G(q), the one reference that does not move with the clean
                // reference's σ: the clean one favours the smoother most like its low-pass
                // (the smoothing chapter), so its winner is no finding.
                .filter_map(|a| a.target_rms_tracked.map(|e| (a, e)))
                .min_by(|x, y| x.1.total_cmp(&y.1))
                .map(|(a, e)| {
                    format!(
                        "at jitter {l:.3}: {} (target RMS vs G(q) {e:.3}, lag {} frames)",
                        a.approach,
                        a.lag_frames.map_or("?".into(), |g| g.to_string())
                    )
                })
        })
        .collect();
    (!parts.is_empty()).then(|| {
        format!(
            "lowest error against G(q) at equal jitter — {}",
            parts.join("; ")
        )
    })
}
