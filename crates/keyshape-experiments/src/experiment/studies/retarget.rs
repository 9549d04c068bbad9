//! `[retarget]`: paper 000's retargeting study (Figs. 4–5) on the built-in target — the same
//! key frames through each solver at each tracing-noise level — with the strip of the frames
//! where the solvers differ most. Writes `retarget.csv` and `strip.png`.

use super::{Context, Finding, Output, Study};
use crate::experiment::spec::RetargetSpec;
use keyshape_core::error::Result;
use keyshape_core::keyshapes::{axes_needed, Analysis, KeyOptions};
use keyshape_io::csv_out::Num;
use nalgebra::DMatrix;
use serde::Serialize;
use serde_json::{json, Map, Value};
use std::any::Any;

/// The `[retarget]` study.
pub struct RetargetStudy;

/// What `[retarget]` found: a row per tracing-noise level and solver, and the strip.
#[derive(Debug, Clone)]
pub struct RetargetFinding {
    /// One row per tracing-noise level and solver.
    pub rows: Vec<RetargetRow>,
    /// The frames where the solvers differ most, for the strip picture.
    pub strip: Option<Strip>,
}

impl Study for RetargetStudy {
    fn stage(&self) -> &'static str {
        "retarget"
    }

    fn run(&self, cx: &Context) -> Result<Option<Box<dyn Finding>>> {
        let Some(r) = &cx.spec.retarget else {
            return Ok(None);
        };
        let (rows, strip) = retarget_study(r, cx.seq, cx.prep, cx.an, cx.opts)?;
        Ok(Some(Box::new(RetargetFinding { rows, strip })))
    }

    fn absent(&self, report: &mut Map<String, Value>) {
        report.insert("retarget".into(), json!([]));
        report.insert("strip_frames".into(), Value::Null);
    }
}

/// A row of `retarget.csv`.
#[derive(Serialize, Default)]
struct CsvRow<'a> {
    solver: &'a str,
    trace_noise: Num,
    source_rms: Num,
    target_rms: Num,
    jitter: Num,
    negative_share: Num,
    max_abs_weight: Num,
}

impl Finding for RetargetFinding {
    fn write(&self, out: &mut Output) -> Result<()> {
        if !self.rows.is_empty() {
            out.rows(
                "retarget.csv",
                self.rows.iter().map(|r| CsvRow {
                    solver: &r.solver,
                    trace_noise: Num(r.trace_noise),
                    source_rms: Num(r.source_rms),
                    target_rms: Num(r.target_rms),
                    jitter: Num(r.jitter),
                    negative_share: Num(r.negative_share),
                    max_abs_weight: Num(r.max_abs_weight),
                }),
            )?;
        }
        if let (Some(strip), true) = (&self.strip, out.spec.png) {
            out.figure("strip.png", &render_strip(strip)?)?;
        }
        Ok(())
    }

    fn report(&self, report: &mut Map<String, Value>) {
        report.insert("retarget".into(), json!(self.rows));
        report.insert(
            "strip_frames".into(),
            json!(self.strip.as_ref().map(|s| &s.frames)),
        );
    }

    fn summary(&self) -> Vec<String> {
        let clean: Vec<String> = self
            .rows
            .iter()
            .filter(|r| r.trace_noise == 0.0)
            .map(|r| format!("{} target RMS {:.4}", r.solver, r.target_rms))
            .collect();
        if clean.is_empty() {
            Vec::new()
        } else {
            vec![format!("retarget, exact target: {}", clean.join(", "))]
        }
    }

    fn as_any(&self) -> &dyn Any {
        self
    }
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
    Ok((rows, Some(worst_frames(r.strip, top_noise, prep, &last))))
}

/// The strip: `count` frames where the solvers' targets differ most at the highest noise
/// level `top_noise` (`last`: each solver's result there).
fn worst_frames(
    count: usize,
    top_noise: f64,
    prep: &keyshape_core::decompose::Prepared,
    last: &[(keyshape_core::solve::Solver, keyshape_retarget::Retargeted)],
) -> Strip {
    use keyshape_retarget::setup;
    // The frames where the solvers' targets differ most (with one solver, where it errs
    // most), spread over the sequence: the worst frames come in runs of near-identical
    // neighbours, and four of one run show one moment four times.
    let score: Vec<f64> = match (last.first(), last.get(1)) {
        (Some(a), Some(b)) => (0..a.1.target.ncols())
            .map(|t| (a.1.target.column(t) - b.1.target.column(t)).norm())
            .collect(),
        _ => last[0].1.target_rms_per_frame().unwrap_or_default(),
    };
    let gap = (score.len() / (4 * count)).max(1);
    let cols = spaced_top(&score, count, gap);
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
    Strip {
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
    }
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

/// One row per strip frame: the source with the first solver's reconstruction, then per
/// solver the target-domain truth with that solver's retargeted shape.
pub fn render_strip(s: &Strip) -> Result<tiny_skia::Pixmap> {
    use keyshape_pictures::render::face::{bounds_of, col, render_panels, Layer, Panel};
    let mut all = vec![&s.truth];
    all.extend(s.solvers.iter().map(|x| &x.target));
    let tb = bounds_of(&all, s.dims);
    let mut src = vec![&s.tracked];
    src.extend(s.solvers.iter().map(|x| &x.source));
    let sb = bounds_of(&src, s.dims);
    let colours = [[200, 30, 30], [31, 90, 200], [30, 150, 60]];
    let mut rows = Vec::new();
    for (i, frame) in s.frames.iter().enumerate() {
        let (name0, rec0) = (&s.solvers[0].name, &s.solvers[0].source);
        let mut panels = vec![Panel {
            title: "source".into(),
            layers: vec![
                Layer {
                    name: "tracked",
                    shape: col(&s.tracked, i),
                    dims: s.dims,
                    polylines: &s.polylines,
                    color: [20, 20, 20],
                    dashed: false,
                },
                Layer {
                    name: name0,
                    shape: col(rec0, i),
                    dims: s.dims,
                    polylines: &s.polylines,
                    color: [31, 90, 200],
                    dashed: true,
                },
            ],
            bounds: sb,
            mesh: None,
        }];
        for (j, sv) in s.solvers.iter().enumerate() {
            let (name, tgt, rms) = (&sv.name, &sv.target, &sv.target_rms);
            panels.push(Panel {
                title: format!(
                    "target, {name}: RMS {}",
                    keyshape_core::stats::sig(rms[i], 3)
                ),
                layers: vec![
                    Layer {
                        name: "ground truth G(q)",
                        shape: col(&s.truth, i),
                        dims: s.dims,
                        polylines: &s.polylines,
                        color: [150, 150, 150],
                        dashed: true,
                    },
                    Layer {
                        name,
                        shape: col(tgt, i),
                        dims: s.dims,
                        polylines: &s.polylines,
                        color: colours[j % 3],
                        dashed: false,
                    },
                ],
                bounds: tb,
                mesh: None,
            });
        }
        let caption = format!("frame {frame}   (tracing noise {} IOD)", s.trace_noise);
        rows.push(render_panels(&panels, &caption, 300)?);
    }
    keyshape_pictures::render::face::stack(&rows)
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
