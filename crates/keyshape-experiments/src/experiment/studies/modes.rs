//! `[modes]`: paper 002's orthogonality table (Table 2) — how far the action-specific modes
//! of the region-based training sets are from orthogonal, beside plain PCA. Writes
//! `orthogonality.csv` and `orthogonality.png`.

use super::map::PAPER002_FEATURES;
use super::{Context, Finding, Output, Study};
use keyshape_actions::modes::{
    orthogonality_study, Actions, ModeRegions, OrthogonalityStudy, RegionOptions,
};
use keyshape_core::decompose::{prepare, PrepareOptions};
use keyshape_core::error::{Error, Result};
use keyshape_io::csv_out::Num;
use serde::Serialize;
use serde_json::{json, Map, Value};
use std::any::Any;

/// The `[modes]` study.
pub struct ModesStudy;

impl Study for ModesStudy {
    fn stage(&self) -> &'static str {
        "paper002"
    }

    fn run(&self, cx: &Context) -> Result<Option<Box<dyn Finding>>> {
        let Some(m) = &cx.spec.modes else {
            return Ok(None);
        };
        let full = prepare(
            cx.seq,
            &PrepareOptions {
                points: None,
                align: cx.spec.align,
            },
        )?;
        let layout = full
            .layout
            .as_ref()
            .ok_or_else(|| Error::invalid("[modes] needs a known layout"))?;
        let opts = RegionOptions::from_user(m.boundary, m.blend_radius)?;
        let regions = ModeRegions::builtin(layout)?.weights(
            layout,
            &full.seq.coords,
            full.seq.dims,
            &opts,
        )?;
        let actions = Actions::read_for(
            &cx.base.join(&m.actions),
            &full.seq.source,
            &full.seq.frames,
        )?;
        let st = orthogonality_study(
            &full.seq.coords,
            &full.seq.frames,
            full.seq.dims,
            &regions,
            &actions,
            m.modes,
        )?;
        Ok(Some(Box::new(ModesFinding(st))))
    }

    fn absent(&self, report: &mut Map<String, Value>) {
        report.insert("orthogonality_mean".into(), Value::Null);
        report.insert("paper002_features".into(), Value::Null);
    }
}

/// What `[modes]` found: the two orthogonality tables.
#[derive(Debug, Clone)]
pub struct ModesFinding(pub OrthogonalityStudy);

/// A row of `orthogonality.csv`.
#[derive(Serialize, Default)]
struct CsvRow<'a> {
    model: &'a str,
    action_i: &'a str,
    action_j: &'a str,
    eq9: Num,
}

impl Finding for ModesFinding {
    fn write(&self, out: &mut Output) -> Result<()> {
        let st = &self.0;
        let n = st.names.len();
        let tables = [
            ("action_specific", &st.action_model),
            ("plain_pca", &st.plain),
        ];
        let rows = tables.into_iter().flat_map(|(model, m)| {
            (0..n).flat_map(move |i| {
                (i + 1..n).map(move |j| CsvRow {
                    model,
                    action_i: &st.names[i],
                    action_j: &st.names[j],
                    eq9: Num(m[(i, j)]),
                })
            })
        });
        out.rows("orthogonality.csv", rows)?;
        if out.spec.png {
            let pm = keyshape_pictures::render::heat::heat_maps(
                &[
                    ("action-specific model", &st.action_model),
                    ("plain PCA", &st.plain),
                ],
                &st.names,
                44,
            )?;
            out.figure("orthogonality.png", &pm)?;
        }
        Ok(())
    }

    fn report(&self, report: &mut Map<String, Value>) {
        let st = &self.0;
        report.insert(
            "orthogonality_mean".into(),
            json!({
                "action_specific": OrthogonalityStudy::mean_upper(&st.action_model),
                "plain_pca": OrthogonalityStudy::mean_upper(&st.plain),
            }),
        );
        report.insert("paper002_features".into(), json!(PAPER002_FEATURES));
    }

    fn as_any(&self) -> &dyn Any {
        self
    }
}
