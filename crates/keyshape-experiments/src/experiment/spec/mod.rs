//! The experiment file: TOML parsed into [`Spec`], checked, with errors naming file, line,
//! column and key.

use keyshape_actions::modes::RegionOptions;

use keyshape_core::error::{Error, Result};
use keyshape_core::keyshapes::Method;
use keyshape_core::sequence::Format;
use keyshape_core::solve::Solver;
use serde::{Deserialize, Deserializer, Serialize};

mod sections;
pub use sections::*;
use std::path::{Path, PathBuf};

/// An experiment file.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Spec {
    /// Title for plots and the report.
    pub title: String,
    /// Input sequence, relative to the spec file, or `builtin` (give this or `inputs`).
    #[serde(default)]
    pub input: String,
    /// A corpus: many input sequences, each a path or glob relative to the spec file, or
    /// `@list.txt` (a file of such lines, relative to itself). The curves and `[retarget]`
    /// run on each and the report aggregates across them ([`super::corpus`]).
    #[serde(default)]
    pub inputs: Option<Vec<String>>,
    /// With `inputs`: each clip of a file that has a clip column (py-feat) is its own
    /// sequence of the corpus.
    #[serde(default)]
    pub split_clips: bool,
    /// With `inputs`: bootstrap resamples of the corpus' sequences for the 95 % intervals
    /// (default 2000).
    #[serde(default)]
    pub bootstrap: Option<usize>,
    /// Force an input format.
    #[serde(default)]
    pub format: Option<Format>,
    /// 2 or 3.
    #[serde(default = "default_dims")]
    pub dims: usize,
    /// Point groups (e.g. `lips`); None = whole face.
    #[serde(default)]
    pub points: Option<String>,
    /// Remove 2-D head motion first.
    #[serde(default = "on")]
    pub align: bool,
    /// Also sweep the curves on the raw (unaligned) coordinates and draw both side by side
    /// (needs `align = true`).
    #[serde(default)]
    pub compare_raw: bool,
    /// Key-shape methods for error curves (empty: no curves).
    #[serde(default, deserialize_with = "methods", serialize_with = "method_names")]
    pub methods: Vec<Method>,
    /// Inclusive k range of the curves.
    #[serde(default = "default_k", deserialize_with = "k_range")]
    pub k: (usize, usize),
    /// Solvers of the curves.
    #[serde(default = "default_solvers")]
    pub solvers: Vec<Solver>,
    /// A retargeting study (paper 000 Figs. 4–5), optional.
    #[serde(default)]
    pub retarget: Option<RetargetSpec>,
    /// Paper 002 orthogonality table, optional.
    #[serde(default)]
    pub modes: Option<ModesSpec>,
    /// Paper 002 soft-KNN intensity study (the input must be a py-feat table), optional.
    #[serde(default)]
    pub intensity: Option<IntensitySpec>,
    /// Paper 002 trajectory mapping onto a second person and the ICT morph targets, optional.
    #[serde(default)]
    pub map: Option<MapSpec>,
    /// The jitter-against-error study of the temporal prior and post-filters, optional.
    #[serde(default)]
    pub smooth: Option<SmoothStudySettings>,
    /// The rig-solve study: recovery of known weights on synthetic tracks of the
    /// ICT rig, and (with a py-feat input) agreement with its ARKit-style scores, optional.
    #[serde(default)]
    pub rig: Option<RigStudySettings>,
    /// Seed for kmeans and random.
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// Greedy shortlist for nnls/bounded.
    #[serde(default = "default_shortlist")]
    pub shortlist: usize,
    /// Write PNG plots.
    #[serde(default = "on")]
    pub png: bool,
}

/// The curves' k range by default.
fn default_k() -> (usize, usize) {
    (2, 24)
}
/// The curves' solvers by default: NNLS alone.
fn default_solvers() -> Vec<Solver> {
    vec![Solver::Nnls]
}

pub(crate) fn method<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<Method, D::Error> {
    Method::parse(&String::deserialize(d)?).map_err(serde::de::Error::custom)
}

pub(crate) fn method_name<S: serde::Serializer>(
    m: &Method,
    s: S,
) -> std::result::Result<S::Ok, S::Error> {
    s.serialize_str(&m.name())
}

/// Tracks are 2-D unless said.
fn default_dims() -> usize {
    2
}
/// A switch that is on unless turned off.
fn on() -> bool {
    true
}
/// The k-means and random seed by default.
fn default_seed() -> u64 {
    7
}
/// Greedy's shortlist by default.
fn default_shortlist() -> usize {
    8
}

fn methods<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<Vec<Method>, D::Error> {
    let names = Vec::<String>::deserialize(d)?;
    names
        .iter()
        .map(|n| Method::parse(n).map_err(serde::de::Error::custom))
        .collect()
}

fn method_names<S: serde::Serializer>(m: &[Method], s: S) -> std::result::Result<S::Ok, S::Error> {
    s.collect_seq(m.iter().map(Method::name))
}

fn k_range<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<(usize, usize), D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum K {
        One(usize),
        Pair([usize; 2]),
        Text(String),
    }
    let bad = |s: &str| {
        serde::de::Error::custom(format!(
            "'{s}' is not a k range: write \"2..24\", [2, 24] or 12"
        ))
    };
    let k = K::deserialize(d).map_err(|_| {
        serde::de::Error::custom(
            "not a k range: write a whole number (12), a string \"2..24\" or an array [2, 24]",
        )
    })?;
    match k {
        K::One(k) => Ok((k, k)),
        K::Pair([a, b]) => Ok((a, b)),
        K::Text(t) => {
            let parts: Vec<&str> = t.split("..").collect();
            let num = |s: &str| {
                s.trim()
                    .trim_start_matches('=')
                    .parse::<usize>()
                    .map_err(|_| bad(&t))
            };
            match parts.as_slice() {
                [a, b] => Ok((num(a)?, num(b)?)),
                [a] => num(a).map(|k| (k, k)),
                _ => Err(bad(&t)),
            }
        }
    }
}

impl Spec {
    /// Reads and validates a spec; errors name the file, line, column and key.
    pub fn from_path(path: &Path) -> Result<(Spec, PathBuf)> {
        let text = keyshape_io::read_text(path)?;
        let spec = Spec::from_str(path, &text)?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Ok((spec, base))
    }

    /// Parses spec text (`path` only names the file in errors).
    pub fn from_str(path: &Path, text: &str) -> Result<Spec> {
        let spec: Spec = toml::from_str(text).map_err(|e| match e.span() {
            Some(s) => {
                let (line, col) = line_col(text, s.start);
                Error::parse(path, line, col, e.message().to_string())
            }
            None => Error::file(path, e.message().to_string()),
        })?;
        let at = |key: &str, msg: String| match find_key(text, key) {
            Some((line, col)) => Error::parse(path, line, col, format!("{key}: {msg}")),
            None => Error::file(path, format!("{key}: {msg}")),
        };
        spec.check(&|key| top_level_key(text, key))
            .map_err(|(key, msg)| at(key, msg))?;
        Ok(spec)
    }
}

impl Spec {
    /// The checks beyond the file's syntax: what must hold together, counts within their
    /// bounds, options that apply. `given(key)` tells whether a top-level key was written
    /// in the file (an option that does not apply is refused only when given). The error
    /// names the key and says what is wrong. Run on every spec read: an experiment file,
    /// and the spec a partial report carries.
    pub fn check(&self, given: &dyn Fn(&str) -> bool) -> std::result::Result<(), KeyError> {
        self.check_inputs()?;
        self.check_curves()?;
        self.check_applies(given)?;
        self.check_retarget()?;
        self.check_rig()?;
        self.check_sections()?;
        if self.dims != 2 && self.dims != 3 {
            return Err(("dims", format!("must be 2 or 3, got {}", self.dims)));
        }
        Ok(())
    }

    /// One `input` or a corpus of `inputs`, and what only a corpus (or only one input) takes.
    fn check_inputs(&self) -> std::result::Result<(), KeyError> {
        let spec = self;
        match (&spec.inputs, spec.input.is_empty()) {
            (None, true) => {
                return Err((
                    "input",
                    "missing: name the sequence (`input = \"file.csv\"` or \"builtin\"), or a corpus (`inputs = [\"tracks/*.csv\"]`)".into(),
                ))
            }
            (Some(_), false) => {
                return Err((
                    "inputs",
                    "give `input` (one sequence) or `inputs` (a corpus), not both".into(),
                ))
            }
            (Some(list), true) => {
                if list.is_empty() {
                    return Err(("inputs", "name at least one sequence".into()));
                }
                let other = [
                    ("modes", spec.modes.is_some()),
                    ("intensity", spec.intensity.is_some()),
                    ("map", spec.map.is_some()),
                    ("smooth", spec.smooth.is_some()),
                    ("rig", spec.rig.is_some()),
                ];
                if let Some((name, _)) = other.iter().find(|o| o.1) {
                    return Err((
                        "inputs",
                        format!("a corpus runs the error curves and [retarget] on each sequence; [{name}] works on one input (use `input`)"),
                    ));
                }
                if spec.compare_raw {
                    return Err((
                        "compare_raw",
                        "a corpus aggregates the curves of one coordinate frame; run the raw curves as their own corpus (align = false)".into(),
                    ));
                }
                if spec.bootstrap == Some(0) {
                    return Err(("bootstrap", "needs at least 1 resample".into()));
                }
                if let Some(b) = spec.bootstrap {
                    if b > MAX_BOOTSTRAP {
                        return Err((
                            "bootstrap",
                            format!("{b} resamples: give 1 to {MAX_BOOTSTRAP}"),
                        ));
                    }
                }
            }
            (None, false) => {
                if spec.split_clips {
                    return Err((
                        "split_clips",
                        "splits the files of a corpus (`inputs`) into clips; with one `input` it has nothing to split".into(),
                    ));
                }
                if spec.bootstrap.is_some() {
                    return Err((
                        "bootstrap",
                        "sets the resamples of a corpus' intervals (`inputs`); one `input` has none".into(),
                    ));
                }
            }
        }
        Ok(())
    }

    /// The error curves: a k range, methods (or a study), solvers, each named once.
    fn check_curves(&self) -> std::result::Result<(), KeyError> {
        let spec = self;
        if spec.k.0 == 0 || spec.k.0 > spec.k.1 {
            return Err((
                "k",
                format!("range {}..{} is empty or starts at 0", spec.k.0, spec.k.1),
            ));
        }
        let studies = spec.retarget.is_some()
            || spec.modes.is_some()
            || spec.intensity.is_some()
            || spec.map.is_some()
            || spec.smooth.is_some()
            || spec.rig.is_some();
        if spec.methods.is_empty() && !studies {
            return Err(("methods", "name at least one method (or add a [retarget], [modes], [intensity], [map], [smooth] or [rig] table)".into()));
        }
        if spec.compare_raw && (!spec.align || spec.methods.is_empty()) {
            return Err((
                "compare_raw",
                "compares aligned with raw curves: it needs align = true and at least one method"
                    .into(),
            ));
        }
        if spec.solvers.is_empty() {
            return Err(("solvers", "name at least one solver".into()));
        }
        if let Some(m) = repeated(&spec.methods, |m| m.name()) {
            return Err(("methods", format!("{m} is listed twice")));
        }
        if let Some(sv) = repeated(&spec.solvers, |s| *s) {
            return Err(("solvers", format!("{sv} is listed twice")));
        }
        Ok(())
    }

    /// Options that cannot apply are refused when given, as on the command line.
    fn check_applies(&self, given: &dyn Fn(&str) -> bool) -> std::result::Result<(), KeyError> {
        let spec = self;
        let choosers = || {
            spec.methods
                .iter()
                .chain(spec.retarget.as_ref().map(|r| &r.method))
        };
        if given("seed")
            && spec.inputs.is_none()
            && !choosers().any(|m| matches!(m, Method::KMeans { .. } | Method::Random))
        {
            return Err((
                "seed",
                "applies to kmeans and random (and a corpus' bootstrap) only".into(),
            ));
        }
        if given("shortlist")
            && !(spec.methods.contains(&Method::Greedy)
                && spec.solvers.iter().any(|s| *s != Solver::Ls))
        {
            return Err((
                "shortlist",
                "applies to greedy with the nnls or bounded solver only".into(),
            ));
        }
        Ok(())
    }

    /// The `[retarget]` table: its strip, k, solvers and trace noise.
    fn check_retarget(&self) -> std::result::Result<(), KeyError> {
        let spec = self;
        if let Some(r) = &spec.retarget {
            if keyshape_core::limits::STRIP_FRAMES
                .check_count("strip", r.strip as u64)
                .is_err()
            {
                return Err((
                    "strip",
                    keyshape_core::limits::STRIP_FRAMES.why_count(r.strip as u64),
                ));
            }
            if r.solvers.is_empty() || r.k == 0 {
                return Err(("retarget", "needs k ≥ 1 and at least one solver".into()));
            }
            if let Some(v) = r
                .trace_noise
                .iter()
                .find(|v| !(v.is_finite() && (0.0..=1.0).contains(*v)))
            {
                return Err((
                    "trace_noise",
                    format!("{v:?} is not a fraction of the inter-ocular distance in [0, 1]"),
                ));
            }
            if let Some(sv) = repeated(&r.solvers, |s| *s) {
                return Err(("retarget", format!("solver {sv} is listed twice")));
            }
        }
        Ok(())
    }

    /// The `[rig]` study: its frames, noise levels and solvers.
    fn check_rig(&self) -> std::result::Result<(), KeyError> {
        let spec = self;
        if let Some(r) = &spec.rig {
            if !(1..=MAX_STUDY_FRAMES).contains(&r.frames) {
                return Err((
                    "frames",
                    format!("{} frames: give 1 to {MAX_STUDY_FRAMES}", r.frames),
                ));
            }
            if let Some(&n) = r.noise_px.iter().find(|&&n| {
                keyshape_core::limits::NOISE_PX
                    .check("noise_px", n)
                    .is_err()
            }) {
                return Err(("noise_px", keyshape_core::limits::NOISE_PX.why(n)));
            }
            if let Some(sv) = repeated(&r.solvers, |s| *s) {
                return Err(("rig", format!("solver {sv} is listed twice")));
            }
        }
        Ok(())
    }

    /// The `[modes]`, `[map]`, `[intensity]` and `[smooth]` tables, checked by their own settings.
    fn check_sections(&self) -> std::result::Result<(), KeyError> {
        let spec = self;
        if let Some(m) = &spec.modes {
            RegionOptions::from_user(m.boundary, m.blend_radius)
                .map_err(|e| ("blend_radius", e.to_string()))?;
        }
        if let Some(m) = &spec.map {
            RegionOptions::from_user(m.boundary, m.blend_radius)
                .map_err(|e| ("blend_radius", e.to_string()))?;
        }
        if let Some(i) = &spec.intensity {
            // The key is the setting the error names, never a guess from its words.
            i.settings().check().map_err(|e| {
                let key = match e.setting().map(|(name, _)| name) {
                    Some("train_clips") => "train_clips",
                    Some("threshold") => "threshold",
                    _ => "neutral_frames",
                };
                (key, e.to_string())
            })?;
        }
        if let Some(sm) = &spec.smooth {
            sm.check(30.0).map_err(|e| ("smooth", e.to_string()))?;
        }
        Ok(())
    }
}

/// A refusal: the key at fault and what is wrong with it.
type KeyError = (&'static str, String);

/// 1-based line and column of a byte offset.
fn line_col(text: &str, offset: usize) -> (u64, u64) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() as u64 + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) as u64 + 1;
    (line, col)
}

/// Line and column of `key = …` at the start of a line, or of a table header `[key]`
/// (None if absent).
fn find_key(text: &str, key: &str) -> Option<(u64, u64)> {
    for (i, l) in text.lines().enumerate() {
        let t = l.trim_start();
        let assigns = t
            .strip_prefix(key)
            .is_some_and(|r| r.trim_start().starts_with('='));
        let header = t
            .strip_prefix('[')
            .and_then(|r| r.trim_start().strip_prefix(key))
            .is_some_and(|r| r.trim_start().starts_with(']'));
        if assigns || header {
            return Some((i as u64 + 1, (l.len() - t.len()) as u64 + 1));
        }
    }
    None
}

/// Is `key = …` set at the top level (before the first table header)?
fn top_level_key(text: &str, key: &str) -> bool {
    text.lines()
        .map(str::trim_start)
        .take_while(|t| !t.starts_with('['))
        .any(|t| {
            t.strip_prefix(key)
                .is_some_and(|r| r.trim_start().starts_with('='))
        })
}

/// The most bootstrap resamples (ample for a 95 % interval; each one costs a pass over the
/// corpus' sequences).
pub const MAX_BOOTSTRAP: usize = 100_000;
/// The most frames of a synthetic track in the `[rig]` study.
pub const MAX_STUDY_FRAMES: usize = 1_000_000;

/// The first entry of `list` that appears twice, by `name`.
fn repeated<T, N: PartialEq>(list: &[T], name: impl Fn(&T) -> N) -> Option<N> {
    list.iter()
        .enumerate()
        .find(|(i, a)| list[..*i].iter().any(|b| name(b) == name(a)))
        .map(|(_, a)| name(a))
}
