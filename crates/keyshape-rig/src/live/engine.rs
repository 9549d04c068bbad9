//! What the live solve and its replay share: a calibration made from lead-in frames (the
//! person, the frozen shapes, the prior's scale, the neutral head pose), and a calibrated
//! solver taking one frame at a time — its landmarks weighed by the tracker's confidence,
//! its warm start dropped after a gap in time.

use super::{Calibration, LiveFrame};
use crate::camera::{fit_camera, Camera};
use crate::frame::{frame_points, FrameSolver};
use crate::identifiability::identifiability_weighted;
use crate::neutral::person_rig;
use crate::prior::{exclusive_pairs, magnitude_prior, prior_iod, tapering};
use crate::{Rig, RigOptions, ShapeReport};
use keyshape_core::error::{Error, Result};
use nalgebra::DMatrix;

/// A gap in the frames' time stamps longer than this (seconds), or time running back,
/// starts the solve afresh: the warm start and the temporal prior's last weights belong to
/// a face seen before the gap (a stretch with no face, a tracker restarted), and would
/// pull the first frames after it towards a stale expression.
pub const GAP_RESTART_S: f64 = 0.25;

/// One frame as the solve takes it: the rig's landmarks (x then y, image axes), and what
/// the tracker said beside them.
#[derive(Debug, Clone, PartialEq)]
pub struct Observation {
    /// `2 × landmarks` values: x and y of each of the rig's landmarks (y down).
    pub points: Vec<f64>,
    /// Per landmark, the tracker's confidence (None: every landmark alike). A landmark
    /// below [`MIN_CONFIDENCE`](keyshape_core::sequence::MIN_CONFIDENCE) is left out of
    /// the frame's solve; the others are weighed by it.
    pub confidence: Option<Vec<f64>>,
    /// The frame's time (seconds), to see a gap ([`GAP_RESTART_S`]).
    pub time: Option<f64>,
}

/// A calibration in use: the calibration, the person's rig and solver, what was learnt
/// of the shapes.
pub(crate) struct Calibrated {
    pub(crate) calibration: Calibration,
    pub(crate) person: Rig,
    pub(crate) fs: FrameSolver<'static>,
    /// Per shape, identifiability at the lead-in's middle frame's head pose.
    pub(crate) shapes: Vec<ShapeReport>,
    /// The time of the last frame solved.
    last_time: Option<f64>,
}

/// The rig, the options and the landmark weights every calibration is made with.
#[derive(Clone)]
pub(crate) struct Maker {
    pub(crate) rig: Rig,
    pub(crate) opts: RigOptions,
    pub(crate) lw: Vec<f64>,
}

impl Maker {
    /// The calibration from lead-in `frames` (each `2 × landmarks` values): the person, the
    /// shapes frozen, the prior's scale and the neutral pose, as a causal file solve makes
    /// them for the neutral `Span` of those frames.
    pub(crate) fn calibrate(&self, frames: &[&[f64]]) -> Result<Calibrated> {
        let rig = &self.rig;
        let track = DMatrix::from_fn(2 * rig.landmarks(), frames.len(), |r, c| frames[c][r]);
        let count = frames.len();
        let person = person_rig(rig, &track, None, 0..count, self.opts.identity)?;
        // As solve_rig with the neutral Span(0, count): identifiability at the middle
        // lead-in frame's head pose.
        let cam_n = fit_camera(&person.neutral, &frame_points(&track, count / 2))?;
        let shapes =
            identifiability_weighted(&person, &cam_n, self.opts.min_determination, &self.lw);
        let free: Vec<usize> = (0..rig.k()).filter(|&s| !shapes[s].frozen).collect();
        let iod = prior_iod(rig, &track, &self.opts, 0..count);
        // The neutral pose: the lead-in's rotations averaged (the nearest rotation to their
        // sum), each the person's neutral fitted to a lead-in frame.
        let cams = (0..count)
            .map(|f| fit_camera(&person.neutral, &frame_points(&track, f)))
            .collect::<Result<Vec<Camera>>>()?;
        let calibration = Calibration {
            layout: rig.layout,
            points: rig.points.clone(),
            names: rig.names.clone(),
            neutral: person.neutral.clone(),
            iod,
            free: free.clone(),
            frames: count,
            head: Camera::mean_pose(&cams),
        };
        let fs = self.frame_solver(person.clone(), free, iod);
        Ok(Calibrated {
            calibration,
            person,
            fs,
            shapes,
            last_time: None,
        })
    }

    /// A saved calibration taken into use (checked against the rig); `first` the first
    /// frame it solves, where its shapes' identifiability is judged.
    pub(crate) fn restore(&self, c: Calibration, first: &[f64]) -> Result<Calibrated> {
        c.check(&self.rig, self.opts.identity)?;
        let person = Rig {
            neutral: c.neutral.clone(),
            ..self.rig.clone()
        };
        let u: Vec<[f64; 2]> = first.chunks_exact(2).map(|p| [p[0], -p[1]]).collect();
        let shapes = match fit_camera(&person.neutral, &u) {
            Ok(cam) => {
                let mut s =
                    identifiability_weighted(&person, &cam, self.opts.min_determination, &self.lw);
                for (i, r) in s.iter_mut().enumerate() {
                    r.frozen = c.free.binary_search(&i).is_err();
                }
                s
            }
            Err(_) => Vec::new(),
        };
        let fs = self.frame_solver(person.clone(), c.free.clone(), c.iod);
        Ok(Calibrated {
            calibration: c,
            person,
            fs,
            shapes,
            last_time: None,
        })
    }

    /// The frame solver for `person`, set up as the file's solve sets up a clip's.
    fn frame_solver(&self, person: Rig, free: Vec<usize>, iod: f64) -> FrameSolver<'static> {
        let opts = &self.opts;
        let mut fs = FrameSolver::new(person, free, opts.solver, opts.max_steps.max(1), &self.lw);
        fs.lambda = opts.lambda(iod);
        fs.ridge = magnitude_prior(iod, opts, &self.rig, &fs.free);
        fs.pairs = exclusive_pairs(&self.rig, &fs.free, &fs.ridge);
        fs.taper = tapering(&self.rig, opts, &fs.free, &fs.ridge);
        fs
    }
}

impl Calibrated {
    /// Solves one frame (warm-started from the last unless a gap lies between them).
    /// `index` is carried into the result.
    pub(crate) fn solve(&mut self, obs: &Observation, index: u64) -> Result<LiveFrame> {
        let fs = &mut self.fs;
        if let (Some(t), Some(last)) = (obs.time, self.last_time) {
            if !(0.0..=GAP_RESTART_S).contains(&(t - last)) {
                fs.restart();
            }
        }
        fs.set_confidence(obs.confidence.as_deref());
        let seen = fs.seen();
        if seen < MIN_SEEN.min(fs.rig.landmarks()) {
            return Err(Error::unfit(format!(
                "the tracker is confident of {seen} of the frame's {} landmarks: too few to solve",
                fs.rig.landmarks()
            )));
        }
        let u: Vec<[f64; 2]> = obs.points.chunks_exact(2).map(|p| [p[0], -p[1]]).collect();
        fs.depth = None;
        let (steps, converged, e) = fs.solve(&u)?;
        let weights = fs.full_weights();
        if weights.iter().any(|v| !v.is_finite()) {
            return Err(Error::unfit(
                "the rig solve produced non-finite weights for the frame",
            ));
        }
        fs.prev = Some(fs.w.clone());
        self.last_time = obs.time.or(self.last_time);
        let camera = fs.cam.unwrap_or(Camera {
            s: 1.0,
            r: nalgebra::Matrix3::identity(),
            t: [0.0, 0.0],
        });
        Ok(LiveFrame {
            weights,
            head: camera.relative_to(self.calibration.head),
            camera,
            rms: (e / seen as f64).sqrt(),
            steps,
            converged,
            index,
        })
    }
}

/// The fewest landmarks a frame's solve must see (confident of) to be solved: the camera
/// alone has six parameters, and a face's expression needs more than its outline.
pub const MIN_SEEN: usize = 12;

/// What looks wrong with lead-in `frames` as a neutral, as the file's solve judges a
/// neutral frame: how many frames had the head turned (and the most), the lips parted
/// (and the most). `None` when every frame looks neutral.
pub(crate) fn lead_in_warning(rig: &Rig, frames: &[&[f64]]) -> Option<String> {
    let track = DMatrix::from_fn(2 * rig.landmarks(), frames.len(), |r, c| frames[c][r]);
    let (mut turned, mut parted) = ((0usize, 0.0f64), (0usize, 0.0f64));
    for f in 0..frames.len() {
        if let Ok(cam) = fit_camera(&rig.neutral, &frame_points(&track, f)) {
            let turn = cam.r[(2, 2)].clamp(-1.0, 1.0).acos().to_degrees();
            if turn > crate::NEUTRAL_TURN_WARN_DEG {
                turned = (turned.0 + 1, turned.1.max(turn));
            }
        }
        if let Some((gap, _)) = crate::neutral::lips_and_brows(rig, &track, f) {
            if gap > crate::NEUTRAL_LIPS_WARN {
                parted = (parted.0 + 1, parted.1.max(gap));
            }
        }
    }
    let n = frames.len();
    let mut what = Vec::new();
    if turned.0 > 0 {
        what.push(format!(
            "the head turned on {} of {n} frames (up to {:.0}°)",
            turned.0, turned.1
        ));
    }
    if parted.0 > 0 {
        what.push(format!(
            "the lips parted on {} of {n} (up to {:.0} % of the eye-corner distance)",
            parted.0,
            100.0 * parted.1
        ));
    }
    (!what.is_empty()).then(|| what.join(", "))
}
