//! The rig view of the lab (`kslab tui FILE --rig DIR`): the track solved
//! onto a blendshape rig once when the lab opens; `r` shows the tracked landmarks with the
//! posed rig's under the fitted head pose, and the rig's weights as named bars.

use keyshape_core::error::{Error, Result};
use keyshape_core::sequence::Sequence;
use keyshape_rig::camera::Camera;
use keyshape_rig::correspondence::{check_layout, search_rig, RigSource};
use keyshape_rig::{preview_frame, solve_rig_observed, Rig, RigOptions};
use nalgebra::DMatrix;

/// What the lab draws of a rig solve.
#[derive(Debug, Clone)]
pub struct RigView {
    /// Shape names, as the rig names them.
    pub names: Vec<String>,
    /// Per frame, every shape's weight.
    pub weights: Vec<Vec<f64>>,
    /// Per frame, the tracked landmarks the rig reads (x, y up).
    pub tracked: Vec<Vec<[f64; 2]>>,
    /// Per frame, the posed rig's landmarks under the fitted head pose (x, y up).
    pub fitted: Vec<Vec<[f64; 2]>>,
    /// Per frame, RMS landmark error (track units).
    pub rms: Vec<f64>,
    /// The track layout's contours through them.
    pub polylines: Vec<Vec<usize>>,
    /// x and y bounds over all frames of both.
    pub bounds: ([f64; 2], [f64; 2]),
    /// The offline temporal prior's λ it was solved with (0: off, the zero-phase Gaussian
    /// of [`RigOptions::recommended`] instead).
    pub smooth: f64,
    /// The neutral frame's column the identity was taken from (a solve for another λ
    /// reuses it instead of searching again: the search does not depend on λ).
    pub neutral: Option<usize>,
    /// `Some(f)`: a preview, frame `f` alone solved before the take (`rig_preview`); its
    /// per-frame fields hold that one frame. `None`: the whole take.
    pub preview: Option<usize>,
}

impl RigView {
    /// The index into the per-frame fields that shows frame `t`: `t` itself (the last
    /// frame past the end), or 0 in a preview, which holds one frame.
    pub fn at(&self, t: usize) -> usize {
        match self.preview {
            Some(_) => 0,
            None => t.min(self.weights.len().saturating_sub(1)),
        }
    }
}

/// Checks that `seq` can be solved onto the rig `source` names (its layout, the rig's
/// points, two dimensions, no degenerate frame) and returns the rig and the track reduced
/// to the rig's points: what the lab checks before it opens, so a bad track or rig fails
/// at once with its reason while the solve itself runs in the background.
pub fn prepare(seq: &Sequence, source: &RigSource) -> Result<(keyshape_rig::Rig, Sequence)> {
    prepare_with_search(seq, source).map(|p| (p.rig, p.seq))
}

/// A track ready to solve onto the lab's rig ([`prepare_with_search`]).
pub struct Prepared {
    /// The rig, read for the track's layout.
    pub rig: Rig,
    /// The track reduced to the rig's points.
    pub seq: Sequence,
    /// For a MediaPipe track on a rig folder: the folder's 68-landmark rig and the track's
    /// 68 iBUG points (image rows), on which [`rig_preview`] searches the neutral.
    pub search: Option<(Rig, DMatrix<f64>)>,
}

/// [`prepare`], with the sparser view a preview's neutral search reads (none where the rig
/// has no 68-point map: a glTF rig).
pub fn prepare_with_search(seq: &Sequence, source: &RigSource) -> Result<Prepared> {
    check_layout(seq.points).map_err(|e| Error::invalid(format!("--rig: {e}")))?;
    let parts = source.read_for(seq.points)?;
    // No search rig is no preview, never a failure of the lab.
    let search = match search_rig(&source.path, seq.points, &parts) {
        Ok(Some(r68)) => keyshape_rig::mediapipe_to_ibug68()
            .and_then(|to68| seq.select_points(&to68))
            .ok()
            .filter(|s| s.dims == 2)
            .map(|s| (r68, s.coords)),
        _ => None,
    };
    let (_, _, rig) = parts;
    let seq = seq.select_points(&rig.points)?;
    if seq.dims != 2 {
        return Err(Error::invalid("--rig needs a 2-D track"));
    }
    seq.check_geometry()?;
    Ok(Prepared { rig, seq, search })
}

/// Solves `seq` (68 points, or MediaPipe 468 / 478 through every point the rig covers) onto
/// the rig `source` names, with `kslab rig`'s offline defaults ([`RigOptions::recommended`]).
pub fn rig_view(seq: &Sequence, source: &RigSource) -> Result<RigView> {
    rig_view_smoothed(seq, source, 0.0)
}

/// The largest λ the lab's `l` gives the rig's offline prior (the key-shape solve goes on
/// to 1e6): the rig's weights barely change beyond it, and its solve slows (564 sweeps, 7 s
/// for the built-in sequence at 1e4; at 1e5 the sweeps stop at their cap).
pub const RIG_SMOOTH_MAX: f64 = keyshape_core::limits::RIG_SMOOTH.hi;

/// [`rig_view`] with the offline temporal prior λ (the lab's `l` / `L`) in place of the
/// zero-phase Gaussian; 0 is [`rig_view`].
pub fn rig_view_smoothed(seq: &Sequence, source: &RigSource, smooth: f64) -> Result<RigView> {
    rig_view_observed(seq, source, smooth, None, &mut |_| {})
}

/// `rig_view_smoothed`, taking the identity from the frame column `neutral` when given
/// (a [`RigView::neutral`] of the same track: the same weights, without the search) and
/// naming each step to `step` as it starts.
pub fn rig_view_observed(
    seq: &Sequence,
    source: &RigSource,
    smooth: f64,
    neutral: Option<usize>,
    step: &mut dyn FnMut(String),
) -> Result<RigView> {
    step("reading the rig".into());
    let p = prepare_with_search(seq, source)?;
    rig_view_prepared(&p, smooth, neutral, step)
}

/// [`rig_view_observed`] on a track already [`prepare_with_search`]d.
pub fn rig_view_prepared(
    p: &Prepared,
    smooth: f64,
    neutral: Option<usize>,
    step: &mut dyn FnMut(String),
) -> Result<RigView> {
    let (rig, seq) = (&p.rig, &p.seq);
    let mut opts = if smooth > 0.0 {
        RigOptions {
            smooth,
            smooth_mode: keyshape_core::solve::temporal::SmoothMode::Offline,
            zero_phase: 0.0,
            ..RigOptions::recommended()
        }
    } else {
        RigOptions::recommended()
    };
    if let Some(n) = neutral.filter(|&n| n < seq.n_frames()) {
        opts.neutral = keyshape_rig::Neutral::Column(n);
    }
    let r = solve_rig_observed(rig, &seq.coords, &[], &opts, step)?;
    let frames: Vec<Solved> = (0..seq.n_frames())
        .map(|f| Solved {
            frame: f,
            weights: r.weights.column(f).iter().copied().collect(),
            person: r.person_of(f).unwrap_or(rig),
            camera: r.cameras[f],
        })
        .collect();
    let mut v = view_of(rig, seq, &frames, r.rms.clone());
    v.smooth = smooth;
    v.neutral = r.neutrals.first().copied();
    Ok(v)
}

/// Frame `frame` of the prepared track solved alone, before the take, as
/// [`keyshape_rig::preview_frame`] solves it with `kslab rig`'s offline defaults: its
/// neutral searched on the 68-point view where there is one. A one-frame [`RigView`] with
/// [`RigView::preview`] set.
pub fn rig_preview(p: &Prepared, frame: usize) -> Result<RigView> {
    let search = p.search.as_ref().map(|(r, t)| (r, t));
    let opts = RigOptions::recommended();
    let fp = preview_frame(&p.rig, &p.seq.coords, frame, &opts, search)?;
    let solved = [Solved {
        frame,
        weights: fp.weights.clone(),
        person: &fp.person,
        camera: fp.camera,
    }];
    let mut v = view_of(&p.rig, &p.seq, &solved, vec![fp.rms]);
    v.neutral = fp.neutral.map(|n| n.0);
    v.preview = Some(frame);
    Ok(v)
}

/// One solved frame, as a view draws it.
struct Solved<'a> {
    frame: usize,
    weights: Vec<f64>,
    /// The person's rig (the identity applied) the frame was solved with.
    person: &'a Rig,
    camera: Camera,
}

/// The view of the solved `frames` (the tracked landmarks, the posed person's under each
/// frame's camera, the weights), with their RMS errors; λ 0, no neutral, not a preview.
fn view_of(rig: &Rig, seq: &Sequence, frames: &[Solved], rms: Vec<f64>) -> RigView {
    let (mut tracked, mut fitted, mut weights) = (Vec::new(), Vec::new(), Vec::new());
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    let mut grow = |p: [f64; 2]| {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    };
    for s in frames {
        let f = s.frame;
        let t: Vec<[f64; 2]> = (0..rig.landmarks())
            .map(|i| [seq.coords[(2 * i, f)], -seq.coords[(2 * i + 1, f)]])
            .collect();
        // What was fitted: the person's rig (the identity applied) under the frame's camera.
        let p: Vec<[f64; 2]> = s
            .person
            .posed(&s.weights)
            .iter()
            .map(|x| s.camera.project(x))
            .collect();
        t.iter().chain(&p).for_each(|&q| grow(q));
        tracked.push(t);
        fitted.push(p);
        weights.push(s.weights.clone());
    }
    let half = (hi[0] - lo[0]).max(hi[1] - lo[1]) * 0.55;
    let (cx, cy) = ((lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0);
    RigView {
        names: rig.names.clone(),
        weights,
        tracked,
        fitted,
        rms,
        polylines: rig.polylines(),
        smooth: 0.0,
        neutral: None,
        preview: None,
        bounds: ([cx - half, cx + half], [cy - half, cy + half]),
    }
}
