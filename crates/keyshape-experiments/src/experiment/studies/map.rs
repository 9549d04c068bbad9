//! `[map]`: paper 002's trajectory mapping (§3.2–3.3) — action trajectories normalised and
//! mapped onto a second person's model, and onto the ICT morph targets. Writes
//! `trajectories.csv`, `normalisation.csv`, `alignment.json` and `morph.glb`.

use super::{Context, Finding, Output, Study};
use crate::experiment::spec::MapSpec;
use keyshape_core::decompose::{prepare, PrepareOptions};
use keyshape_core::error::{Error, Result};
use keyshape_io::csv_out::Num;
use keyshape_io::fmt_num;
use keyshape_io::{read_sequence, ReadOptions};
use nalgebra::DMatrix;
use serde::Serialize;
use serde_json::{json, Map, Value};
use std::any::Any;
use std::path::Path;

/// The `[map]` study.
pub struct MapStudy;

impl Study for MapStudy {
    fn stage(&self) -> &'static str {
        "paper002"
    }

    fn run(&self, cx: &Context) -> Result<Option<Box<dyn Finding>>> {
        let Some(m) = &cx.spec.map else {
            return Ok(None);
        };
        let found = map_study(m, cx.seq, cx.base, cx.spec.align)?;
        Ok(Some(Box::new(found)))
    }

    fn absent(&self, report: &mut Map<String, Value>) {
        report.insert("alignment".into(), Value::Null);
        report.insert("normalisation_extremes".into(), Value::Null);
        report.insert("paper002_features".into(), Value::Null);
    }
}

/// What paper 002's studies say about their features, in `report.json`.
pub(crate) const PAPER002_FEATURES: &str =
    "shape only: landmark tracks, no texture (the paper's appearance models had both)";

/// A row of `normalisation.csv`.
#[derive(Serialize, Default)]
struct ExtremeCsv<'a> {
    action: &'a str,
    source_mode: usize,
    target_mode: usize,
    side: &'a str,
    source_extreme: Num,
    target_extreme: Num,
    two_sided: Num,
    one_sided: Num,
    ratio: Num,
}

impl Finding for MapOutcome {
    fn write(&self, out: &mut Output) -> Result<()> {
        let m = self;
        let header = std::iter::once("frame".to_string()).chain(m.actions.iter().cloned());
        let records = m.frames.iter().enumerate().map(|(t, f)| {
            std::iter::once(f.to_string())
                .chain((0..m.actions.len()).map(move |i| fmt_num(m.trajectories[(i, t)])))
        });
        out.file("trajectories.csv", |w| {
            keyshape_io::csv_out::write_records(w, header, records)
        })?;
        out.rows(
            "normalisation.csv",
            m.extremes.iter().map(|r| ExtremeCsv {
                action: &r.action,
                source_mode: r.source_mode,
                target_mode: r.target_mode,
                side: &r.side,
                source_extreme: Num(r.source_extreme),
                target_extreme: Num(r.target_extreme),
                two_sided: Num(r.two_sided),
                one_sided: Num(r.one_sided),
                ratio: Num(r.ratio),
            }),
        )?;
        out.json("alignment.json", &m.alignment)?;
        if let Some(f) = &m.morph {
            out.file("morph.glb", |w| {
                keyshape_io::gltf::write_morph_glb(
                    w, &f.neutral, &f.faces, &f.targets, &f.weights, m.fps,
                )
            })?;
        }
        Ok(())
    }

    fn report(&self, report: &mut Map<String, Value>) {
        report.insert("alignment".into(), json!(self.alignment));
        report.insert("normalisation_extremes".into(), json!(self.extremes));
        report.insert("paper002_features".into(), json!(PAPER002_FEATURES));
    }

    fn as_any(&self) -> &dyn Any {
        self
    }
}

/// A morph-target face ready to export: neutral positions, faces, the used targets (name,
/// dense offsets) and their weights (targets × frames).
#[derive(Debug, Clone)]
pub struct MorphFace {
    /// Neutral positions.
    pub neutral: Vec<[f64; 3]>,
    /// Faces.
    pub faces: Vec<Vec<usize>>,
    /// Used targets.
    pub targets: Vec<(String, Vec<[f64; 3]>)>,
    /// Weights, targets × frames.
    pub weights: DMatrix<f64>,
}

/// What `[map]` produced.
#[derive(Debug, Clone)]
pub struct MapOutcome {
    /// Where each source extreme lands on the target under both normalisations.
    pub extremes: Vec<keyshape_actions::trajectory::ExtremeRow>,
    /// The mode alignment used.
    pub alignment: keyshape_actions::trajectory::ModeAlignment,
    /// Action names and their normalised trajectories (actions × frames).
    pub actions: Vec<String>,
    /// Trajectories.
    pub trajectories: DMatrix<f64>,
    /// Frame numbers.
    pub frames: Vec<i64>,
    /// Frames per second.
    pub fps: f64,
    /// The morph face, if asked: neutral positions, faces, used targets (name, dense
    /// offsets) and their weights (targets × frames).
    pub morph: Option<MorphFace>,
}

pub(crate) fn map_study(
    m: &MapSpec,
    seq: &keyshape_core::sequence::Sequence,
    base: &Path,
    align: bool,
) -> Result<MapOutcome> {
    use keyshape_actions::trajectory::{extremes, person_model, trajectories, ModeAlignment};
    let region_opts =
        keyshape_actions::modes::RegionOptions::from_user(m.boundary, m.blend_radius)?;
    let model_of = |s: &keyshape_core::sequence::Sequence,
                    actions: &str|
     -> Result<(
        keyshape_actions::trajectory::PersonModel,
        keyshape_core::decompose::Prepared,
    )> {
        let prep = prepare(
            s,
            &PrepareOptions {
                points: None,
                align,
            },
        )?;
        let layout = prep
            .layout
            .as_ref()
            .ok_or_else(|| Error::invalid("[map] needs a known layout"))?;
        let regions = keyshape_actions::modes::ModeRegions::builtin(layout)?.weights(
            layout,
            &prep.seq.coords,
            prep.seq.dims,
            &region_opts,
        )?;
        let acts = keyshape_actions::modes::Actions::read_for(
            &base.join(actions),
            &prep.seq.source,
            &prep.seq.frames,
        )?;
        Ok((
            person_model(
                &prep.seq.coords,
                &prep.seq.frames,
                prep.seq.dims,
                &regions,
                &acts,
                m.modes,
                m.normalisation,
            )?,
            prep,
        ))
    };
    let (src, prep) = model_of(seq, &m.actions)?;
    let tseq = read_sequence(&base.join(&m.target_sequence), &ReadOptions::default())?;
    let (tgt, _) = model_of(&tseq, &m.target_actions)?;
    let alignment = ModeAlignment::by_actions(&src, &tgt);
    let extremes = extremes(&src, &tgt, &alignment);
    let traj = trajectories(&src, &prep.seq.coords);
    let actions: Vec<String> = src.actions.iter().map(|a| a.0.clone()).collect();
    let at = DMatrix::from_fn(actions.len(), traj.ncols(), |i, t| {
        src.actions[i].2 * traj[(src.actions[i].1, t)]
    });
    let morph = match &m.morph {
        None => None,
        Some(dir) => {
            let dir = base.join(dir);
            keyshape_io::atomic::register_input(&dir)?;
            let mesh = keyshape_io::obj::read_obj(&dir.join("neutral_face.obj"))?;
            let targets = keyshape_io::morph::MorphTargets::read(
                &dir.join("expressions.csv"),
                &dir.join("expression_deltas.csv"),
                mesh.positions.len(),
            )?;
            let w = keyshape_actions::morph::MorphMapping::builtin()?
                .weights(&targets, &actions, &at)?;
            let (targets, weights) = targets.used_dense(&w, mesh.positions.len());
            Some(MorphFace {
                neutral: mesh.positions,
                faces: mesh.faces,
                targets,
                weights,
            })
        }
    };
    Ok(MapOutcome {
        extremes,
        alignment,
        actions,
        trajectories: at,
        frames: prep.seq.frames.clone(),
        fps: seq.fps().unwrap_or(30.0),
        morph,
    })
}
