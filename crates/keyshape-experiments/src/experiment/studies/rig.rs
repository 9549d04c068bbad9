//! `[rig]`: the rig-solve study — recovery of known weights from synthetic tracks
//! of the ICT rig, and, with a py-feat input, agreement with the input's own ARKit-style
//! scores. Writes `rig_recovery.csv`, `rig_vs_input_scores.csv` and
//! `rig_vs_input_summary.csv`.

use super::{Context, Finding, Output, Study};
use crate::experiment::rig_study::{PeerRow, PeerSummary, RecoveryRow};
use keyshape_core::error::{Error, Result};
use keyshape_io::csv_out::{opt, Num};
use serde::Serialize;
use serde_json::{json, Map, Value};
use std::any::Any;

/// The `[rig]` study.
pub struct RigStudy;

/// The report keys of the rig study, each null when its table is empty.
const KEYS: [&str; 3] = [
    "rig_recovery",
    "rig_vs_input_scores",
    "rig_vs_input_summary",
];

impl Study for RigStudy {
    fn stage(&self) -> &'static str {
        "rig"
    }

    fn run(&self, cx: &Context) -> Result<Option<Box<dyn Finding>>> {
        let Some(st) = &cx.spec.rig else {
            return Ok(None);
        };
        let rig = keyshape_rig::Rig::read_ict(&keyshape_io::shared_data("ict_facekit_face")?)?;
        let recovery = crate::experiment::rig_study::recovery(&rig, st)?;
        let (peer, peer_summary) = if st.against_input_scores {
            against_input_scores(cx, &rig)?
        } else {
            (Vec::new(), Vec::new())
        };
        Ok(Some(Box::new(RigFinding {
            recovery,
            peer,
            peer_summary,
        })))
    }

    fn absent(&self, report: &mut Map<String, Value>) {
        for k in KEYS {
            report.insert(k.into(), Value::Null);
        }
    }
}

/// The rig study's part (ii): the rig's weights against the ARKit-named score columns of
/// the input (a 68-point py-feat table).
fn against_input_scores(
    cx: &Context,
    rig: &keyshape_rig::Rig,
) -> Result<(Vec<PeerRow>, Vec<PeerSummary>)> {
    let seq = cx.seq;
    if seq.points != keyshape_rig::LANDMARKS || cx.spec.input == "builtin" {
        return Err(Error::invalid(
            "[rig] against_input_scores needs a 68-point py-feat table as input",
        ));
    }
    let p = cx.base.join(&cx.spec.input);
    let header = keyshape_io::read_text(&p)?;
    let names: Vec<&str> = header
        .lines()
        .next()
        .unwrap_or("")
        .split(',')
        .map(str::trim)
        .filter(|n| {
            keyshape_rig::livelink::COLUMNS[..52]
                .iter()
                .any(|c| c.eq_ignore_ascii_case(n))
        })
        .collect();
    if names.is_empty() {
        return Err(Error::file(
            &p,
            "[rig] against_input_scores: no ARKit-named score columns",
        ));
    }
    let cols = keyshape_io::read_columns(&p, &names)?;
    let scores: Vec<(String, Vec<f64>)> = names.iter().map(|n| n.to_string()).zip(cols).collect();
    crate::experiment::rig_study::against_peer(rig, &seq.coords, &scores, seq.segments.as_deref())
}

/// What `[rig]` found.
#[derive(Debug, Clone)]
pub struct RigFinding {
    /// Recovery of known weights, per solver, noise level and shape.
    pub recovery: Vec<RecoveryRow>,
    /// Agreement with the input's own scores, per setting, clip and shape.
    pub peer: Vec<PeerRow>,
    /// Part (ii)'s summary per setting, with the calibrated references.
    pub peer_summary: Vec<PeerSummary>,
}

/// A row of `rig_recovery.csv`.
#[derive(Serialize, Default)]
struct RecoveryCsv<'a> {
    solver: &'a str,
    noise_px: Num,
    shape: &'a str,
    r: Num,
    rmse: Num,
    frozen: bool,
}

/// A row of `rig_vs_input_scores.csv`.
#[derive(Serialize, Default)]
struct PeerCsv<'a> {
    identity: &'a str,
    neutral: &'a str,
    clip: &'a str,
    shape: &'a str,
    r: Option<Num>,
}

/// A row of `rig_vs_input_summary.csv`.
#[derive(Serialize, Default)]
struct SummaryCsv<'a> {
    setting: &'a str,
    shapes: usize,
    mean_r: Num,
    median_r: Num,
    clip_median_mean_r: Option<Num>,
    rms: Option<Num>,
}

impl Finding for RigFinding {
    fn write(&self, out: &mut Output) -> Result<()> {
        if !self.recovery.is_empty() {
            out.rows(
                "rig_recovery.csv",
                self.recovery.iter().map(|r| RecoveryCsv {
                    solver: &r.solver,
                    noise_px: Num(r.noise_px),
                    shape: &r.shape,
                    r: Num(r.r),
                    rmse: Num(r.rmse),
                    frozen: r.frozen,
                }),
            )?;
        }
        if !self.peer.is_empty() {
            out.rows(
                "rig_vs_input_scores.csv",
                self.peer.iter().map(|r| PeerCsv {
                    identity: &r.identity,
                    neutral: &r.neutral,
                    clip: &r.clip,
                    shape: &r.shape,
                    r: opt(r.r),
                }),
            )?;
        }
        if !self.peer_summary.is_empty() {
            out.rows(
                "rig_vs_input_summary.csv",
                self.peer_summary.iter().map(|r| SummaryCsv {
                    setting: &r.setting,
                    shapes: r.shapes,
                    mean_r: Num(r.mean_r),
                    median_r: Num(r.median_r),
                    clip_median_mean_r: opt(r.clip_mean_r),
                    rms: opt(r.rms),
                }),
            )?;
        }
        Ok(())
    }

    fn report(&self, report: &mut Map<String, Value>) {
        let tables = [
            json!(self.recovery),
            json!(self.peer),
            json!(self.peer_summary),
        ];
        for (k, v) in KEYS.into_iter().zip(tables) {
            let empty = v.as_array().is_some_and(|a| a.is_empty());
            report.insert(k.into(), if empty { Value::Null } else { v });
        }
    }

    fn as_any(&self) -> &dyn Any {
        self
    }
}
