//! The rig solve one frame at a time, as the frames arrive: the person's neutral from N
//! frames (the calibration: "look neutral"), then each frame solved when it comes,
//! warm-started from the one before, with nothing from frames still to come.
//!
//! It computes what [`crate::solve_rig`] computes for a causal solve
//! ([`RigOptions::causal`]) whose neutral is the lead-in `0..N`: the same person (the
//! lead-in's residuals averaged), the same shapes frozen (judged at the middle lead-in
//! frame's head pose), the prior scaled by the lead-in's inter-ocular distance, the same
//! warm-started frame solver. Beyond a file's solve it weighs each landmark by the
//! tracker's confidence, starts afresh after a gap in time, and recalibrates during a
//! session; each calibration is kept as a [`CalibrationEvent`], and [`replay`] solves a
//! recorded take through the same events to the same weights, bit for bit.
//!
//! A calibration can be made off the solving thread ([`LiveSolver::set_background`]):
//! the completed lead-in becomes a [`CalibrationJob`] to run anywhere, and the frames
//! meanwhile are solved against the calibration in use (a recalibration) or held (the
//! first, or another face's).

use super::camera::Camera;
use super::checks::check_options;
use super::{Identity, Neutral, Rig, RigOptions, SmoothUnit};
use keyshape_core::error::{Error, Result};
use serde::{Deserialize, Serialize};

mod calibration;
mod engine;
mod replay;
pub use calibration::{Calibration, IOD};
use engine::{lead_in_warning, Calibrated, Maker};
pub use engine::{Observation, GAP_RESTART_S, MIN_SEEN};
pub use replay::{replay, Replay, ReplayEvent};

/// One solved frame.
#[derive(Debug, Clone, PartialEq)]
pub struct LiveFrame {
    /// The weights, in the rig's shape order.
    pub weights: Vec<f64>,
    /// The fitted head pose.
    pub camera: Camera,
    /// The head's yaw, pitch and roll (radians) relative to the calibration's neutral pose
    /// ([`Camera::relative_to`]): what an avatar is turned by, so it looks ahead while the
    /// person looks as they did in the lead-in.
    pub head: [f64; 3],
    /// RMS landmark error over the landmarks the solve saw (track units).
    pub rms: f64,
    /// Gauss–Newton steps taken, and whether they converged before the cap.
    pub steps: u32,
    /// See `steps`.
    pub converged: bool,
    /// The frame's number among the frames the solver took (0, 1, …: each frame pushed
    /// and not refused), which says which frame this is when frames are held.
    pub index: u64,
}

/// A calibration taken into use during a session: what a recording keeps, so a take
/// replays ([`replay`]) through the same calibrations at the same frames.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationEvent {
    /// The first frame (its [`LiveFrame::index`]) solved with it.
    pub from: u64,
    /// The lead-in it was made from (first and last frame index, the frames between them
    /// all taken), or None for a saved calibration given to the solver.
    pub lead_in: Option<[u64; 2]>,
    /// The calibration.
    pub calibration: Calibration,
}

/// A completed lead-in to be made a calibration, on whatever thread the caller likes
/// ([`CalibrationJob::run`]), then handed back ([`LiveSolver::install`]).
pub struct CalibrationJob {
    maker: Maker,
    frames: Vec<(u64, Observation)>,
    /// Whether the lead-in's frames are to be solved with the new calibration (they were
    /// not solved with another).
    solve_lead_in: bool,
    /// The solver's calibration count when the job was made (a job from before a
    /// recalibration is stale).
    generation: u64,
}

/// A finished [`CalibrationJob`].
pub struct CalibrationDone {
    result: Result<(Calibrated, Vec<LiveFrame>, Option<String>)>,
    frames: Vec<(u64, Observation)>,
    generation: u64,
}

impl CalibrationJob {
    /// Makes the calibration and, when the lead-in was not solved with another, solves the
    /// lead-in's frames with it.
    pub fn run(self) -> CalibrationDone {
        let pts: Vec<&[f64]> = self
            .frames
            .iter()
            .map(|(_, o)| o.points.as_slice())
            .collect();
        let result = self.maker.calibrate(&pts).and_then(|mut c| {
            let warning = lead_in_warning(&self.maker.rig, &pts);
            let mut out = Vec::new();
            if self.solve_lead_in {
                for (i, o) in &self.frames {
                    out.push(c.solve(o, *i)?);
                }
            }
            Ok((c, out, warning))
        });
        CalibrationDone {
            result,
            frames: self.frames,
            generation: self.generation,
        }
    }
}

/// The frame-by-frame rig solve (see the module's documentation).
pub struct LiveSolver {
    maker: Maker,
    needed: usize,
    /// The lead-in being collected (frame index and frame), when collecting.
    pending: Vec<(u64, Observation)>,
    /// Collecting a lead-in (from the start, and after [`LiveSolver::recalibrate`]).
    collecting: bool,
    /// The lead-in's frames are another face's than the calibration in use: held, not
    /// solved with it.
    fresh: bool,
    /// A lead-in handed out as a job, not yet installed.
    awaiting: bool,
    /// Frames taken while a job runs and no calibration may solve them.
    held: Vec<(u64, Observation)>,
    current: Option<Calibrated>,
    /// Make calibrations as jobs ([`LiveSolver::take_job`]) rather than inline.
    background: bool,
    job: Option<CalibrationJob>,
    /// Calibrations taken into use since the last [`LiveSolver::take_events`].
    events: Vec<CalibrationEvent>,
    /// Frames taken so far (the next frame's index).
    taken: u64,
    /// Recalibrations so far (a job made before the last is stale).
    generation: u64,
    /// What looked wrong with the lead-in of the calibration in use.
    warning: Option<String>,
    /// Why the last full lead-in could not be used.
    slid: Option<String>,
}

impl LiveSolver {
    /// A solver for `rig` that calibrates on its first `calibrate` frames (≥ 1). `opts`
    /// must be causal ([`RigOptions::live`]), with an identity of `offset` or `rbf`.
    pub fn new(rig: Rig, opts: RigOptions, calibrate: usize) -> Result<LiveSolver> {
        if calibrate == 0 {
            return Err(Error::bad_setting(
                "calibration_frames",
                0,
                "the calibration needs at least 1 neutral frame",
            ));
        }
        if !opts.causal {
            return Err(Error::invalid(
                "a live solve is causal: give RigOptions::live() or set causal",
            ));
        }
        if opts.identity == Identity::None {
            return Err(Error::invalid(
                "a live solve calibrates the person's neutral: the identity cannot be none",
            ));
        }
        let opts = RigOptions {
            neutral: Neutral::Span(0, calibrate),
            ..opts
        };
        let lw = check_options(&rig, &opts)?;
        Ok(LiveSolver {
            maker: Maker { rig, opts, lw },
            needed: calibrate,
            pending: Vec::new(),
            collecting: true,
            fresh: true,
            awaiting: false,
            held: Vec::new(),
            current: None,
            background: false,
            job: None,
            events: Vec::new(),
            taken: 0,
            generation: 0,
            warning: None,
            slid: None,
        })
    }

    /// The rig solved onto.
    pub fn rig(&self) -> &Rig {
        &self.maker.rig
    }

    /// The calibration in use, once there is one.
    pub fn calibration(&self) -> Option<&Calibration> {
        self.current.as_ref().map(|c| &c.calibration)
    }

    /// Frames collected towards the calibration, and how many it needs (the lead-in
    /// complete while its calibration is made).
    pub fn collected(&self) -> (usize, usize) {
        if self.awaiting {
            return (self.needed, self.needed);
        }
        (self.pending.len(), self.needed)
    }

    /// Whether the solver is collecting or making a calibration.
    pub fn calibrating(&self) -> bool {
        self.collecting || self.awaiting
    }

    /// Makes each calibration as a [`CalibrationJob`] for the caller to run
    /// ([`LiveSolver::take_job`], [`LiveSolver::install`]) rather than inline in
    /// [`LiveSolver::push`].
    pub fn set_background(&mut self, on: bool) {
        self.background = on;
    }

    /// The calibration job a completed lead-in made (background mode), once.
    pub fn take_job(&mut self) -> Option<CalibrationJob> {
        self.job.take()
    }

    /// The calibrations taken into use since the last call (drained).
    pub fn take_events(&mut self) -> Vec<CalibrationEvent> {
        std::mem::take(&mut self.events)
    }

    /// Starts a new calibration: the next frames are the person's neutral again. With
    /// `same_face` the calibration in use goes on solving them meanwhile (the avatar keeps
    /// moving); otherwise (another face) they wait for the new one. A calibration being
    /// made is dropped.
    pub fn recalibrate(&mut self, same_face: bool) {
        self.pending.clear();
        self.held.clear();
        self.job = None;
        self.awaiting = false;
        self.collecting = true;
        self.generation += 1;
        self.fresh = !same_face || self.current.is_none();
        if self.fresh {
            self.current = None;
        }
        self.slid = None;
    }

    /// The causal temporal prior's λ from now on, in squared track units (≥ 0; see
    /// [`RigOptions::smooth`]), whatever unit the solver was made with.
    pub fn set_smooth(&mut self, lambda: f64) -> Result<()> {
        keyshape_core::limits::RIG_SMOOTH.check("smooth", lambda)?;
        self.maker.opts.smooth = lambda;
        self.maker.opts.smooth_unit = SmoothUnit::Pixels;
        if let Some(c) = &mut self.current {
            c.fs.lambda = lambda;
        }
        Ok(())
    }

    /// The causal temporal prior's λ in squared track units: `None` while a λ given
    /// relative to the face ([`SmoothUnit::Iod`]) waits for the calibration to measure it.
    pub fn smooth(&self) -> Option<f64> {
        let opts = &self.maker.opts;
        match (&self.current, opts.smooth_unit) {
            (Some(c), _) => Some(opts.lambda(c.calibration.iod)),
            (None, SmoothUnit::Pixels) => Some(opts.smooth),
            (None, SmoothUnit::Iod) => None,
        }
    }

    /// Uses a saved calibration instead of collecting one (it must be of this rig, and an
    /// `offset` identity's: a saved calibration holds the neutral only). It solves from the
    /// next frame taken on.
    pub fn set_calibration(&mut self, c: Calibration) -> Result<()> {
        c.check(&self.maker.rig, self.maker.opts.identity)?;
        let neutral: Vec<f64> = c.neutral.iter().flat_map(|p| [p[0], -p[1]]).collect();
        let calibrated = self.maker.restore(c.clone(), &neutral)?;
        self.recalibrate(false);
        self.collecting = false;
        self.fresh = false;
        self.current = Some(calibrated);
        self.warning = None;
        self.events.push(CalibrationEvent {
            from: self.taken,
            lead_in: None,
            calibration: c,
        });
        Ok(())
    }

    /// Takes one frame (`2 × landmarks` values: x and y of each of the rig's landmarks,
    /// image axes, y down): [`LiveSolver::push_observed`] with nothing observed beside the
    /// points.
    pub fn push(&mut self, frame: &[f64]) -> Result<Vec<LiveFrame>> {
        self.push_observed(Observation {
            points: frame.to_vec(),
            confidence: None,
            time: None,
        })
    }

    /// Takes one frame. Returns the frames it solved: none while calibrating on another
    /// face, the whole lead-in when its calibration completes inline, then one per frame. A
    /// frame that cannot be solved (non-finite, all points together, the wrong size, too
    /// few points seen; while calibrating, a frame that is no face) is an error and changes
    /// nothing. A full lead-in the calibration cannot use is no error: the collection
    /// slides on by a frame (its oldest frame leaves) and [`LiveSolver::lead_in_failure`]
    /// says why.
    pub fn push_observed(&mut self, obs: Observation) -> Result<Vec<LiveFrame>> {
        self.check(&obs)?;
        if self.collecting {
            // A lead-in frame becomes part of the neutral: checked as every such frame is.
            if let Some(why) = keyshape_core::sequence::face_problem(&obs.points, 2) {
                return Err(Error::unfit(format!(
                    "a calibration frame must be a face: {why}"
                )));
            }
        }
        let index = self.taken;
        let mut out = Vec::new();
        match &mut self.current {
            Some(c) if !self.fresh => out.push(c.solve(&obs, index)?),
            _ if self.awaiting => self.held.push((index, obs.clone())),
            _ if self.collecting => {}
            _ => return Err(Error::invalid("the live solve is not calibrated")),
        }
        self.taken += 1;
        if !self.collecting {
            return Ok(out);
        }
        self.pending.push((index, obs));
        if self.pending.len() < self.needed {
            return Ok(out);
        }
        let job = CalibrationJob {
            maker: self.maker.clone(),
            frames: std::mem::take(&mut self.pending),
            solve_lead_in: self.fresh,
            generation: self.generation,
        };
        self.collecting = false;
        self.awaiting = true;
        if self.background {
            self.job = Some(job);
            return Ok(out);
        }
        out.extend(self.install(job.run()));
        Ok(out)
    }

    /// Takes a finished calibration into use: the frames it solves (the lead-in, when it was
    /// not solved with another, then the frames held meanwhile). A lead-in the calibration
    /// could not use slides on by its oldest frame, the frames held meanwhile joining it;
    /// [`LiveSolver::lead_in_failure`] says why. A job from before a
    /// [`LiveSolver::recalibrate`] is dropped.
    pub fn install(&mut self, done: CalibrationDone) -> Vec<LiveFrame> {
        if !self.awaiting || done.generation != self.generation {
            return Vec::new();
        }
        self.awaiting = false;
        let lead = [
            done.frames.first().map_or(0, |f| f.0),
            done.frames.last().map_or(0, |f| f.0),
        ];
        match done.result {
            Ok((mut c, mut out, warning)) => {
                let held = std::mem::take(&mut self.held);
                for (i, o) in &held {
                    // A held frame the new calibration cannot solve is refused, as it
                    // would have been on arrival.
                    if let Ok(f) = c.solve(o, *i) {
                        out.push(f);
                    }
                }
                self.events.push(CalibrationEvent {
                    from: if self.fresh { lead[0] } else { self.taken },
                    lead_in: Some(lead),
                    calibration: c.calibration.clone(),
                });
                self.current = Some(c);
                self.fresh = false;
                self.warning = warning;
                self.slid = None;
                out
            }
            Err(e) => {
                let mut frames = done.frames;
                frames.remove(0);
                frames.append(&mut self.held);
                frames
                    .retain(|(_, o)| keyshape_core::sequence::face_problem(&o.points, 2).is_none());
                let keep = frames.len().min(self.needed.saturating_sub(1));
                self.pending = frames.split_off(frames.len() - keep);
                self.collecting = true;
                self.slid = Some(e.to_string());
                Vec::new()
            }
        }
    }

    /// What is wrong with the calibration in use, if its lead-in looked wrong: judged as
    /// the file's solve judges a neutral frame (the head turned more than
    /// [`NEUTRAL_TURN_WARN_DEG`](crate::NEUTRAL_TURN_WARN_DEG), the lips parted more than
    /// [`NEUTRAL_LIPS_WARN`](crate::NEUTRAL_LIPS_WARN) of the eye-corner distance).
    pub fn calibration_warning(&self) -> Option<&str> {
        self.warning.as_deref()
    }

    /// Why the last full lead-in could not be calibrated on (it slid on by a frame), while
    /// collecting.
    pub fn lead_in_failure(&self) -> Option<&str> {
        self.slid.as_deref()
    }

    /// The checks every frame passes before it is taken.
    fn check(&self, obs: &Observation) -> Result<()> {
        let n = self.maker.rig.landmarks();
        let frame = &obs.points;
        if frame.len() != 2 * n {
            return Err(Error::invalid(format!(
                "a frame for this rig has {} values (x, y of {n} landmarks), not {}",
                2 * n,
                frame.len()
            )));
        }
        if let Some(c) = &obs.confidence {
            if c.len() != n {
                return Err(Error::invalid(format!(
                    "a frame for this rig has {n} confidences, one per landmark, not {}",
                    c.len()
                )));
            }
        }
        if let Some(t) = obs.time.filter(|t| !t.is_finite()) {
            return Err(Error::invalid(format!("the frame's time is {t}")));
        }
        if let Some((i, why)) = frame
            .iter()
            .enumerate()
            .find_map(|(i, &v)| keyshape_core::sequence::coord_problem(v).map(|w| (i, w)))
        {
            return Err(Error::invalid(format!(
                "landmark {}: {why} ({})",
                i / 2,
                frame[i]
            )));
        }
        if keyshape_core::sequence::degenerate_shape(frame, 2) {
            return Err(Error::unfit(format!(
                "all {n} landmarks coincide, so no camera can be fitted to the frame"
            )));
        }
        Ok(())
    }
}
