//! The studies a spec may hold beside its error curves: paper 000's retargeting study
//! (Figs. 4–5) and paper 002's trajectory mapping (§3.2–3.3). Each returns plain data;
//! [`crate::report`] writes it.

use super::spec::{MapSpec, RetargetSpec};
use keyshape_core::decompose::{prepare, PrepareOptions};
use keyshape_core::error::{Error, Result};
use keyshape_core::keyshapes::{axes_needed, Analysis, KeyOptions};
use keyshape_io::{read_sequence, ReadOptions};
use nalgebra::DMatrix;
use serde::Serialize;
use std::path::Path;

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

/// One retargeting result.
#[derive(Debug, Clone, Serialize)]
pub struct RetargetRow {
    /// Solver.
    pub solver: String,
    /// Tracing noise on the target key shapes, in inter-ocular distances.
    pub trace_noise: f64,
    /// Key frames (frame numbers).
    pub keys: Vec<i64>,
    /// Source RMS per point.
    pub source_rms: f64,
    /// Target-domain RMS per point against G(Q_t).
    pub target_rms: f64,
    /// Weight jitter: RMS second difference of the weights within clips
    /// ([`keyshape_core::solve::jitter`]).
    pub jitter: f64,
    /// Share of negative weights.
    pub negative_share: f64,
    /// Largest |w|.
    pub max_abs_weight: f64,
}

/// Shapes for a strip of frames (aligned coordinates): per frame the tracked shape, the
/// ground truth G(q) and, per solver, the source reconstruction and the retargeted shape.
#[derive(Debug, Clone)]
pub struct Strip {
    /// Tracing noise level used.
    pub trace_noise: f64,
    /// Frame numbers.
    pub frames: Vec<i64>,
    /// Drawing contours (selection indices).
    pub polylines: Vec<Vec<usize>>,
    /// Values per point.
    pub dims: usize,
    /// Tracked shapes (n × strip frames).
    pub tracked: DMatrix<f64>,
    /// Ground truth G(q).
    pub truth: DMatrix<f64>,
    /// Per solver: what it made of the strip's frames.
    pub solvers: Vec<StripSolver>,
}

/// One solver's shapes in a [`Strip`].
#[derive(Debug, Clone)]
pub struct StripSolver {
    /// Solver name.
    pub name: String,
    /// Source reconstruction (n × strip frames).
    pub source: DMatrix<f64>,
    /// Retargeted shapes.
    pub target: DMatrix<f64>,
    /// Target-domain RMS per strip frame.
    pub target_rms: Vec<f64>,
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

/// Paper 000 Figs. 4–5 on the built-in target: the same key frames, each solver, each
/// tracing-noise level; the strip shows the highest noise level's worst frames for the
/// first solver.
pub(crate) fn retarget_study(
    r: &RetargetSpec,
    seq: &keyshape_core::sequence::Sequence,
    prep: &keyshape_core::decompose::Prepared,
    an: &Analysis,
    opts: &KeyOptions,
) -> Result<(Vec<RetargetRow>, Option<Strip>)> {
    use keyshape_retarget::{retarget, setup, KeyPlan, Target};
    let sel = if an.proj.nrows() >= keyshape_core::keyshapes::axes_needed(&[r.method], r.k) {
        r.method.heuristic(opts).select(an, r.k)?
    } else {
        let an2 = Analysis::with_axes(an.coords.clone(), an.points, axes_needed(&[r.method], r.k))?;
        r.method.heuristic(opts).select(&an2, r.k)?
    };
    let keys = sel.key_frames(&r.method, "the [retarget] study")?.to_vec();
    let key_frames: Vec<i64> = keys.iter().map(|&c| prep.seq.frames[c]).collect();
    let (g, iod) = setup::builtin_target(seq, prep)?;
    let segs =
        keyshape_core::solve::temporal::segments(&prep.seq.frames, prep.seq.segments.as_deref());
    let mut rows = Vec::new();
    let mut last = Vec::new();
    let top_noise = r.trace_noise.iter().copied().fold(0.0, f64::max);
    for &noise in &r.trace_noise {
        for &solver in &r.solvers {
            let target = Target::Warp {
                g: g.clone(),
                trace_noise: noise * iod,
            };
            let res = retarget(
                &prep.seq.coords,
                prep.seq.dims,
                &KeyPlan::Global(keys.clone()),
                &target,
                None,
                solver,
            )?;
            rows.push(RetargetRow {
                solver: solver.name().into(),
                trace_noise: noise,
                keys: key_frames.clone(),
                source_rms: res.source_rms(),
                target_rms: res.target_rms().unwrap_or(f64::NAN),
                jitter: keyshape_core::solve::jitter::weight_jitter_all(&res.weights, &segs),
                negative_share: res.negative_share(),
                max_abs_weight: res
                    .weights
                    .iter()
                    .flat_map(|w| w.iter())
                    .fold(0.0, |m, v| m.max(v.abs())),
            });
            if noise == top_noise {
                last.push((solver, res));
            }
        }
    }
    if r.strip == 0 || last.is_empty() {
        return Ok((rows, None));
    }
    // The frames where the solvers' targets differ most (with one solver, where it errs
    // most), spread over the sequence: the worst frames come in runs of near-identical
    // neighbours, and four of one run show one moment four times.
    let score: Vec<f64> = match (last.first(), last.get(1)) {
        (Some(a), Some(b)) => (0..a.1.target.ncols())
            .map(|t| (a.1.target.column(t) - b.1.target.column(t)).norm())
            .collect(),
        _ => last[0].1.target_rms_per_frame().unwrap_or_default(),
    };
    let gap = (score.len() / (4 * r.strip)).max(1);
    let cols = spaced_top(&score, r.strip, gap);
    let polylines = prep
        .layout
        .as_ref()
        .map(|l| setup::polylines_for(l, &prep.point_indices))
        .unwrap_or_default();
    let truth = last[0]
        .1
        .truth
        .clone()
        .unwrap_or_else(|| prep.seq.coords.clone());
    let strip = Strip {
        trace_noise: top_noise,
        frames: cols.iter().map(|&c| prep.seq.frames[c]).collect(),
        polylines,
        dims: prep.seq.dims,
        tracked: prep.seq.coords.select_columns(&cols),
        truth: truth.select_columns(&cols),
        solvers: last
            .iter()
            .map(|(s, res)| {
                let per = res.target_rms_per_frame().unwrap_or_default();
                StripSolver {
                    name: s.name().to_string(),
                    source: res.source.select_columns(&cols),
                    target: res.target.select_columns(&cols),
                    target_rms: cols.iter().map(|&c| per[c]).collect(),
                }
            })
            .collect(),
    };
    Ok((rows, Some(strip)))
}

/// The `count` columns of largest `score`, each at least `gap` columns from every other
/// chosen one (greedy, largest first), in column order.
pub fn spaced_top(score: &[f64], count: usize, gap: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..score.len()).collect();
    order.sort_by(|&a, &b| score[b].total_cmp(&score[a]).then(a.cmp(&b)));
    let mut chosen: Vec<usize> = Vec::with_capacity(count);
    for c in order {
        if chosen.len() == count {
            break;
        }
        if chosen.iter().all(|&p| p.abs_diff(c) >= gap) {
            chosen.push(c);
        }
    }
    chosen.sort_unstable();
    chosen
}

#[cfg(test)]
mod tests {
    use super::spaced_top;

    #[test]
    fn the_strip_takes_the_largest_scores_spread_apart() {
        // A run of large scores at 10..14 and a smaller peak at 40: with a gap of 5 the
        // run gives one frame and the others come from elsewhere.
        let mut s = vec![0.0; 60];
        for (i, v) in [
            (10, 9.0),
            (11, 10.0),
            (12, 9.5),
            (13, 9.2),
            (40, 5.0),
            (50, 4.0),
            (30, 3.0),
        ] {
            s[i] = v;
        }
        assert_eq!(spaced_top(&s, 4, 5), vec![11, 30, 40, 50]);
        // Gap 1 is the plain top four.
        assert_eq!(spaced_top(&s, 4, 1), vec![10, 11, 12, 13]);
        // Fewer columns than asked: all of them.
        assert_eq!(spaced_top(&[1.0, 2.0], 4, 1), vec![0, 1]);
    }
}
