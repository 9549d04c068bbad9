//! A recorded take solved again as it was solved live: its frames in order, each
//! calibration taken into use at the frame it was, each frame weighed by the tracker's
//! confidence and restarted after a gap as the live solve did.

use super::engine::{Calibrated, Maker, Observation};
use super::{Calibration, LiveSolver};
use crate::neutral::{views, NeutralRule};
use crate::{Rig, RigOptions, RigSolve};
use keyshape_core::error::{Error, Result};
use nalgebra::DMatrix;
use std::ops::Range;

/// A calibration of a replay: taken into use at column `from`, made from the lead-in's
/// columns (and then, when the take recorded it, checked against the recorded one), or the
/// recorded one itself when there was no lead-in (a saved calibration).
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayEvent {
    /// The first column solved with it.
    pub from: usize,
    /// The lead-in's columns.
    pub lead_in: Option<Range<usize>>,
    /// The calibration as recorded.
    pub calibration: Option<Calibration>,
}

/// What a take holds for its replay.
#[derive(Debug, Clone, Copy)]
pub struct Replay<'a> {
    /// The rig's landmarks, `2 × landmarks` rows (x, y; image axes) × frames.
    pub track: &'a DMatrix<f64>,
    /// Per landmark and frame, the tracker's confidence.
    pub confidence: Option<&'a DMatrix<f64>>,
    /// Per frame, its time (seconds).
    pub times: Option<&'a [f64]>,
    /// The calibrations, by their first column (the first at column 0).
    pub events: &'a [ReplayEvent],
}

/// Solves `take` onto `rig` as [`LiveSolver`] solved it live with `opts` (causal, with an
/// identity): the same weights, bit for bit, for the same frames, calibrations,
/// confidences and times.
pub fn replay(rig: &Rig, opts: &RigOptions, take: &Replay) -> Result<RigSolve> {
    let track = take.track;
    let frames = track.ncols();
    let n = rig.landmarks();
    if track.nrows() != 2 * n {
        return Err(Error::invalid(format!(
            "the rig reads {n} landmarks, x and y each, but the track has {} rows",
            track.nrows()
        )));
    }
    check_events(take.events, frames)?;
    let maker = LiveSolver::new(rig.clone(), *opts, 1)?.maker;
    let column = |f: usize| -> Observation {
        Observation {
            points: track.column(f).iter().copied().collect(),
            confidence: take
                .confidence
                .map(|c| c.column(f).iter().copied().collect()),
            time: take.times.map(|t| t[f]),
        }
    };
    let mut out = RigSolve {
        weights: DMatrix::zeros(rig.k(), frames),
        cameras: Vec::with_capacity(frames),
        rms: Vec::with_capacity(frames),
        steps: Vec::with_capacity(frames),
        sweeps: 0,
        sweeps_unconverged: 0,
        unconverged: 0,
        lambda: 0.0,
        shapes: Vec::new(),
        neutrals: Vec::new(),
        neutral_views: Vec::new(),
        people: Vec::new(),
    };
    let mut first_iod = 0.0;
    for (e, event) in take.events.iter().enumerate() {
        let end = take.events.get(e + 1).map_or(frames, |x| x.from);
        let mut c = calibration_of(&maker, track, event, e)?;
        if e == 0 {
            first_iod = c.calibration.iod;
            out.lambda = opts.lambda(c.calibration.iod);
            out.shapes.clone_from(&c.shapes);
        }
        out.neutrals.push(match &event.lead_in {
            Some(r) => (r.start + r.end) / 2,
            None => event.from,
        });
        out.people.push((event.from..end, c.person.clone()));
        for f in event.from..end {
            let s = c
                .solve(&column(f), f as u64)
                .map_err(|err| Error::unfit(format!("frame column {f}: {err}")))?;
            out.weights.column_mut(f).copy_from_slice(&s.weights);
            out.cameras.push(s.camera);
            out.rms.push(s.rms);
            out.steps.push(s.steps);
            out.unconverged += usize::from(!s.converged);
        }
    }
    out.neutral_views = views(
        rig,
        (track, None),
        &out.neutrals,
        &maker.opts,
        &maker.lw,
        first_iod,
    )?;
    for v in &mut out.neutral_views {
        v.rule = NeutralRule::Given;
    }
    Ok(out)
}

/// The calibration of event `e`: made from its lead-in (and checked against the recorded
/// one), or the recorded one.
fn calibration_of(
    maker: &Maker,
    track: &DMatrix<f64>,
    event: &ReplayEvent,
    e: usize,
) -> Result<Calibrated> {
    match (&event.lead_in, &event.calibration) {
        (Some(r), recorded) => {
            let cols: Vec<Vec<f64>> = r
                .clone()
                .map(|f| track.column(f).iter().copied().collect())
                .collect();
            let pts: Vec<&[f64]> = cols.iter().map(Vec::as_slice).collect();
            let c = maker.calibrate(&pts)?;
            if let Some(rec) = recorded {
                if *rec != c.calibration {
                    return Err(Error::invalid(format!(
                        "calibration {} (frame columns {}..{}): its lead-in gives another calibration than the take recorded: the take was solved with another rig, landmark map or options",
                        e + 1,
                        r.start,
                        r.end
                    )));
                }
            }
            Ok(c)
        }
        (None, Some(rec)) => {
            let first: Vec<f64> = track.column(event.from).iter().copied().collect();
            maker.restore(rec.clone(), &first)
        }
        (None, None) => Err(Error::invalid(format!(
            "calibration {}: neither a lead-in nor a recorded calibration",
            e + 1
        ))),
    }
}

/// The events cover the take from its first column, in order, their lead-ins inside it.
fn check_events(events: &[ReplayEvent], frames: usize) -> Result<()> {
    let Some(first) = events.first() else {
        return Err(Error::invalid("a replay needs a calibration"));
    };
    if first.from != 0 {
        return Err(Error::invalid(format!(
            "the first calibration is taken into use at frame column {}: the frames before it have none",
            first.from
        )));
    }
    for (e, ev) in events.iter().enumerate() {
        if ev.from >= frames {
            return Err(Error::invalid(format!(
                "calibration {} is taken into use at frame column {}, past the take's {frames} frames",
                e + 1,
                ev.from
            )));
        }
        if e > 0 && ev.from <= events[e - 1].from {
            return Err(Error::invalid(format!(
                "calibration {} is taken into use at frame column {}, not after the one before it ({})",
                e + 1,
                ev.from,
                events[e - 1].from
            )));
        }
        if let Some(r) = &ev.lead_in {
            if r.is_empty() || r.end > frames {
                return Err(Error::invalid(format!(
                    "calibration {}: its lead-in, frame columns {}..{}, is not within the take's {frames} frames",
                    e + 1,
                    r.start,
                    r.end
                )));
            }
        }
    }
    Ok(())
}
