//! The rig solve one frame at a time, as the frames arrive: the person's neutral from the
//! first N frames (the calibration: "look neutral"), then each frame solved when it comes,
//! warm-started from the one before, with nothing from frames still to come.
//!
//! It computes what [`crate::solve_rig`] computes for a causal solve
//! ([`RigOptions::causal`]) whose neutral is the lead-in `0..N`: the same person (the
//! lead-in's residuals averaged), the same shapes frozen (judged at the middle lead-in
//! frame's head pose), the prior scaled by the lead-in's inter-ocular distance, the same
//! warm-started frame solver. So a recorded take replays to the same weights, bit for bit,
//! as `kslab rig --live --neutral 0-(N-1)` gives for the file.

use super::camera::{fit_camera, Camera};
use super::checks::check_options;
use super::frame::{frame_points, FrameSolver};
use super::identifiability::identifiability_weighted;
use super::neutral::person_rig;
use super::prior::{exclusive_pairs, magnitude_prior, prior_iod, tapering};
use super::{Identity, Neutral, Rig, RigOptions, SmoothUnit};
use keyshape_core::error::{Error, Result};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// A person's calibration: what the neutral lead-in taught the solve. Saved and loaded as
/// JSON (`kslab live --neutral-file`), so a session can start without looking neutral again.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Calibration {
    /// The track layout the rig reads (68, 468 or 478 points).
    pub layout: usize,
    /// The track points the rig reads, in landmark order.
    pub points: Vec<usize>,
    /// The rig's shape names.
    pub names: Vec<String>,
    /// The person's neutral landmarks (the rig's, moved by the lead-in's averaged residual).
    pub neutral: Vec<[f64; 3]>,
    /// The inter-ocular distance that scales the magnitude prior (track units).
    pub iod: f64,
    /// The shapes solved for, in rig order (the others are held at 0).
    pub free: Vec<usize>,
    /// Frames averaged into the neutral.
    pub frames: usize,
    /// The neutral head pose (yaw, pitch, roll in radians, as [`Camera::yaw_pitch_roll`]):
    /// the lead-in's mean rotation, which the head's rotation is sent relative to
    /// ([`LiveFrame::head`]). A calibration saved before it was kept reads as 0 (the pose
    /// as fitted).
    #[serde(default)]
    pub head: [f64; 3],
}

/// The inter-ocular distance a calibration may hold (track units: pixels, or a fraction of
/// the image for normalised coordinates). `1e308` froze the avatar (every weight 0) and
/// `1e-300` changed every weight.
pub const IOD: keyshape_core::limits::Limit = keyshape_core::limits::Limit {
    lo: 1e-4,
    lo_open: false,
    hi: 1e7,
    unit: "track units (pixels, or normalised coordinates)",
};

/// The largest distance between two of the rig's neutral landmarks along an axis.
fn rig_extent(points: &[[f64; 3]]) -> f64 {
    (0..3)
        .map(|a| {
            let (lo, hi) = points
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| {
                    (l.min(p[a]), h.max(p[a]))
                });
            hi - lo
        })
        .fold(0.0, f64::max)
}

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
    /// RMS landmark error (track units).
    pub rms: f64,
}

/// The frame-by-frame rig solve (see the module's documentation).
pub struct LiveSolver {
    rig: Rig,
    opts: RigOptions,
    lw: Vec<f64>,
    needed: usize,
    /// The frames collected for the calibration (each `2 × landmarks` values, x then y
    /// per landmark, image axes).
    pending: Vec<Vec<f64>>,
    state: Option<(Calibration, FrameSolver<'static>)>,
    /// What looked wrong with the lead-in of the calibration in use.
    warning: Option<String>,
    /// Why the last full lead-in could not be used.
    slid: Option<String>,
}

/// What looks wrong with lead-in `frames` as a neutral, as the file's solve judges a
/// neutral frame: how many frames had the head turned (and the most), the lips parted
/// (and the most). `None` when every frame looks neutral.
fn lead_in_warning(rig: &Rig, frames: &[Vec<f64>]) -> Option<String> {
    let track = DMatrix::from_fn(2 * rig.landmarks(), frames.len(), |r, c| frames[c][r]);
    let (mut turned, mut parted) = ((0usize, 0.0f64), (0usize, 0.0f64));
    for f in 0..frames.len() {
        if let Ok(cam) = fit_camera(&rig.neutral, &frame_points(&track, f)) {
            let turn = cam.r[(2, 2)].clamp(-1.0, 1.0).acos().to_degrees();
            if turn > super::NEUTRAL_TURN_WARN_DEG {
                turned = (turned.0 + 1, turned.1.max(turn));
            }
        }
        if let Some((gap, _)) = super::neutral::lips_and_brows(rig, &track, f) {
            if gap > super::NEUTRAL_LIPS_WARN {
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
            rig,
            opts,
            lw,
            needed: calibrate,
            pending: Vec::new(),
            state: None,
            warning: None,
            slid: None,
        })
    }

    /// The rig solved onto.
    pub fn rig(&self) -> &Rig {
        &self.rig
    }

    /// The calibration in use, once there is one.
    pub fn calibration(&self) -> Option<&Calibration> {
        self.state.as_ref().map(|s| &s.0)
    }

    /// Frames collected towards the calibration, and how many it needs.
    pub fn collected(&self) -> (usize, usize) {
        (self.pending.len(), self.needed)
    }

    /// Starts a new calibration: the next frames are the person's neutral again (the
    /// warm start is dropped with the old person).
    pub fn recalibrate(&mut self) {
        self.state = None;
        self.pending.clear();
        self.warning = None;
        self.slid = None;
    }

    /// The causal temporal prior's λ from now on, in squared track units (≥ 0; see
    /// [`RigOptions::smooth`]), whatever unit the solver was made with.
    pub fn set_smooth(&mut self, lambda: f64) -> Result<()> {
        keyshape_core::limits::RIG_SMOOTH.check("smooth", lambda)?;
        self.opts.smooth = lambda;
        self.opts.smooth_unit = SmoothUnit::Pixels;
        if let Some((_, fs)) = &mut self.state {
            fs.lambda = lambda;
        }
        Ok(())
    }

    /// The causal temporal prior's λ in squared track units: `None` while a λ given
    /// relative to the face ([`SmoothUnit::Iod`]) waits for the calibration to measure it.
    pub fn smooth(&self) -> Option<f64> {
        match (&self.state, self.opts.smooth_unit) {
            (Some((c, _)), _) => Some(self.opts.lambda(c.iod)),
            (None, SmoothUnit::Pixels) => Some(self.opts.smooth),
            (None, SmoothUnit::Iod) => None,
        }
    }

    /// Uses a saved calibration instead of collecting one (it must be of this rig).
    pub fn set_calibration(&mut self, c: Calibration) -> Result<()> {
        let rig = &self.rig;
        let bad = |what: String| Err(Error::invalid(format!("calibration: {what}")));
        if c.layout != rig.layout || c.points != rig.points {
            return bad(format!(
                "it was made for a {}-point track read at {} points; this rig reads a {}-point track at {}",
                c.layout,
                c.points.len(),
                rig.layout,
                rig.points.len()
            ));
        }
        if c.names != rig.names {
            return bad("its shape names are not this rig's".into());
        }
        if c.neutral.len() != rig.landmarks() {
            return bad(format!(
                "its neutral has {} landmarks; this rig has {}",
                c.neutral.len(),
                rig.landmarks()
            ));
        }
        if let Some((i, why)) = c.neutral.iter().enumerate().find_map(|(i, p)| {
            p.iter()
                .find_map(|&v| keyshape_core::sequence::coord_problem(v))
                .map(|w| (i, w))
        }) {
            return bad(format!("neutral landmark {i}: {why}"));
        }
        // The neutral as seen from the front (x, y), checked as a frame a neutral is made
        // from, and against this rig's own: the lifted identity moves a landmark by a
        // fraction of the face, never by the face's size.
        let front: Vec<f64> = c.neutral.iter().flat_map(|p| [p[0], p[1]]).collect();
        if let Some(why) = keyshape_core::sequence::face_problem(&front, 2) {
            return bad(format!("its neutral is not a face: {why}"));
        }
        let size = rig_extent(&rig.neutral);
        let moved = c
            .neutral
            .iter()
            .zip(&rig.neutral)
            .map(|(p, q)| {
                ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
            })
            .fold(0.0f64, f64::max);
        if !matches!(
            moved.partial_cmp(&(0.5 * size)),
            Some(std::cmp::Ordering::Less | std::cmp::Ordering::Equal)
        ) {
            return bad(format!(
                "its neutral lies up to {moved:.3} rig units from this rig's (a face {size:.3} across): it was made for another rig"
            ));
        }
        if let Some(a) = c
            .head
            .iter()
            .find(|a| !(a.is_finite() && a.abs() <= std::f64::consts::PI))
        {
            return bad(format!(
                "its neutral head pose holds {a}, not an angle within ±π"
            ));
        }
        if !IOD.contains(c.iod) {
            return bad(format!("the inter-ocular distance {}", IOD.why(c.iod)));
        }
        if c.free.windows(2).any(|w| w[0] >= w[1]) || c.free.iter().any(|&s| s >= rig.k()) {
            return bad(format!(
                "the free shapes must be increasing shape numbers below {}",
                rig.k()
            ));
        }
        if self.opts.identity == Identity::Rbf {
            return bad(
                "a saved calibration holds the neutral only, an `offset` identity; this solve asks for rbf"
                    .into(),
            );
        }
        let person = Rig {
            neutral: c.neutral.clone(),
            ..rig.clone()
        };
        let fs = self.frame_solver(person, c.free.clone(), c.iod);
        self.pending.clear();
        self.state = Some((c, fs));
        self.warning = None;
        self.slid = None;
        Ok(())
    }

    /// Takes one frame (`2 × landmarks` values: x and y of each of the rig's landmarks,
    /// image axes, y down). Returns the frames it solved: none while calibrating, the whole
    /// lead-in when the calibration completes, then one per frame. A frame that cannot be
    /// solved (non-finite, all points together, the wrong size; while calibrating, a frame
    /// that is no face) is an error and changes nothing. A full lead-in the calibration
    /// cannot use is no error: the collection slides on by a frame (its oldest frame leaves)
    /// and [`LiveSolver::lead_in_failure`] says why.
    pub fn push(&mut self, frame: &[f64]) -> Result<Vec<LiveFrame>> {
        let n = self.rig.landmarks();
        if frame.len() != 2 * n {
            return Err(Error::invalid(format!(
                "a frame for this rig has {} values (x, y of {n} landmarks), not {}",
                2 * n,
                frame.len()
            )));
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
        if self.state.is_some() {
            return Ok(vec![self.solve(frame)?]);
        }
        // A lead-in frame becomes part of the neutral: checked as every such frame is.
        if let Some(why) = keyshape_core::sequence::face_problem(frame, 2) {
            return Err(Error::unfit(format!(
                "a calibration frame must be a face: {why}"
            )));
        }
        self.pending.push(frame.to_vec());
        if self.pending.len() < self.needed {
            return Ok(Vec::new());
        }
        // The state changes only once every step has succeeded: a lead-in the calibration
        // cannot use, or whose frames it cannot solve, slides on by a frame (its oldest
        // leaves, the collection goes on, and why is kept for the caller to say).
        let pending = std::mem::take(&mut self.pending);
        let solved = self.calibrate(&pending).and_then(|(c, fs)| {
            let warning = lead_in_warning(&self.rig, &pending);
            self.state = Some((c, fs));
            let out: Result<Vec<LiveFrame>> = pending.iter().map(|f| self.solve(f)).collect();
            if out.is_err() {
                self.state = None;
            }
            self.warning = warning;
            out
        });
        match solved {
            Ok(out) => {
                self.slid = None;
                Ok(out)
            }
            Err(e) => {
                self.pending = pending;
                self.pending.remove(0);
                self.slid = Some(e.to_string());
                Ok(Vec::new())
            }
        }
    }

    /// What is wrong with the calibration just made, if anything looked wrong: its lead-in
    /// judged as the file's solve judges a neutral frame (the head turned more than
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

    /// The person, frozen shapes and prior scale from the lead-in `frames`.
    fn calibrate(&self, frames: &[Vec<f64>]) -> Result<(Calibration, FrameSolver<'static>)> {
        let track = DMatrix::from_fn(2 * self.rig.landmarks(), frames.len(), |r, c| frames[c][r]);
        let count = frames.len();
        let person = person_rig(&self.rig, &track, None, 0..count, self.opts.identity)?;
        // As solve_rig with the neutral Span(0, count): identifiability at the middle
        // lead-in frame's head pose.
        let cam_n = fit_camera(&person.neutral, &frame_points(&track, count / 2))?;
        let shapes =
            identifiability_weighted(&person, &cam_n, self.opts.min_determination, &self.lw);
        let free: Vec<usize> = (0..self.rig.k()).filter(|&s| !shapes[s].frozen).collect();
        let iod = prior_iod(&self.rig, &track, &self.opts, 0..count);
        // The neutral pose: the lead-in's rotations averaged (the nearest rotation to their
        // sum), each the person's neutral fitted to a lead-in frame.
        let cams = (0..count)
            .map(|f| fit_camera(&person.neutral, &frame_points(&track, f)))
            .collect::<Result<Vec<Camera>>>()?;
        let head = Camera::mean_pose(&cams);
        let c = Calibration {
            layout: self.rig.layout,
            points: self.rig.points.clone(),
            names: self.rig.names.clone(),
            neutral: person.neutral.clone(),
            iod,
            free: free.clone(),
            frames: count,
            head,
        };
        Ok((c, self.frame_solver(person, free, iod)))
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

    /// Solves one frame with the calibrated solver (warm-started from the last).
    fn solve(&mut self, frame: &[f64]) -> Result<LiveFrame> {
        let n = self.rig.landmarks();
        let Some((c, fs)) = &mut self.state else {
            return Err(Error::invalid("the live solve is not calibrated yet"));
        };
        let neutral_head = c.head;
        let u: Vec<[f64; 2]> = frame.chunks_exact(2).map(|p| [p[0], -p[1]]).collect();
        fs.depth = None;
        let (_, _, e) = fs.solve(&u)?;
        let weights = fs.full_weights();
        if weights.iter().any(|v| !v.is_finite()) {
            return Err(Error::unfit(
                "the rig solve produced non-finite weights for the frame",
            ));
        }
        fs.prev = Some(fs.w.clone());
        let camera = fs.cam.unwrap_or(Camera {
            s: 1.0,
            r: nalgebra::Matrix3::identity(),
            t: [0.0, 0.0],
        });
        Ok(LiveFrame {
            weights,
            head: camera.relative_to(neutral_head),
            camera,
            rms: (e / n as f64).sqrt(),
        })
    }
}
