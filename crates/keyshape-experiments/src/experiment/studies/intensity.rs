//! `[intensity]`: paper 002's soft-KNN action intensities (§4) on a py-feat table, scored by
//! correlation raw, after median-3 and after polynomial smoothing, over all test frames and
//! per clip. Writes `intensity.csv` and `intensity_clips.csv`.

use super::{Context, Finding, Output, Study};
use keyshape_actions::intensity::{study_with_format, Study as IntensityTable};
use keyshape_core::error::Result;
use keyshape_io::csv_out::Num;
use serde::Serialize;
use serde_json::{json, Map, Value};
use std::any::Any;

/// The `[intensity]` study.
pub struct IntensityStudy;

impl Study for IntensityStudy {
    fn stage(&self) -> &'static str {
        "paper002"
    }

    fn run(&self, cx: &Context) -> Result<Option<Box<dyn Finding>>> {
        let Some(st) = &cx.spec.intensity else {
            return Ok(None);
        };
        let table = study_with_format(
            &cx.base.join(&cx.spec.input),
            cx.spec.format,
            &st.settings(),
        )?;
        Ok(Some(Box::new(IntensityFinding(table))))
    }

    fn absent(&self, report: &mut Map<String, Value>) {
        report.insert("intensity".into(), Value::Null);
    }
}

/// What `[intensity]` found.
#[derive(Debug, Clone)]
pub struct IntensityFinding(pub IntensityTable);

/// A row of `intensity.csv`.
#[derive(Serialize, Default)]
struct ActionCsv<'a> {
    action: &'a str,
    training_frames_labelled: usize,
    correlation_raw: Num,
    correlation_median3: Num,
    correlation_smoothed: Num,
    clips: usize,
    clip_median_raw: Num,
    clip_median_median3: Num,
    clip_median_smoothed: Num,
    clip_q1_smoothed: Num,
    clip_q3_smoothed: Num,
}

/// A row of `intensity_clips.csv`.
#[derive(Serialize, Default)]
struct ClipCsv<'a> {
    action: &'a str,
    clip: usize,
    frames: usize,
    correlation_raw: Num,
    correlation_median3: Num,
    correlation_smoothed: Num,
}

impl Finding for IntensityFinding {
    fn write(&self, out: &mut Output) -> Result<()> {
        let st = &self.0;
        out.rows(
            "intensity.csv",
            st.actions.iter().map(|r| ActionCsv {
                action: &r.action,
                training_frames_labelled: r.training_frames_labelled,
                correlation_raw: Num(r.correlation_raw),
                correlation_median3: Num(r.correlation_median3),
                correlation_smoothed: Num(r.correlation_smoothed),
                clips: r.clips_smoothed.clips,
                clip_median_raw: Num(r.clips_raw.median),
                clip_median_median3: Num(r.clips_median3.median),
                clip_median_smoothed: Num(r.clips_smoothed.median),
                clip_q1_smoothed: Num(r.clips_smoothed.q1),
                clip_q3_smoothed: Num(r.clips_smoothed.q3),
            }),
        )?;
        out.rows(
            "intensity_clips.csv",
            st.clips.iter().map(|r| ClipCsv {
                action: &r.action,
                clip: r.clip,
                frames: r.frames,
                correlation_raw: Num(r.raw),
                correlation_median3: Num(r.median3),
                correlation_smoothed: Num(r.smoothed),
            }),
        )
    }

    fn report(&self, report: &mut Map<String, Value>) {
        report.insert("intensity".into(), json!(self.0));
    }

    fn as_any(&self) -> &dyn Any {
        self
    }
}
