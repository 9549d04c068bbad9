//! The rig view of the lab (`kslab tui FILE --rig DIR`): the track solved
//! onto a blendshape rig once when the lab opens; `r` shows the tracked landmarks with the
//! posed rig's under the fitted head pose, and the rig's weights as named bars.

use keyshape_core::error::{Error, Result};
use keyshape_core::sequence::Sequence;
use keyshape_rig::correspondence::{check_layout, RigSource};
use keyshape_rig::{solve_rig_observed, RigOptions};

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
}

/// Checks that `seq` can be solved onto the rig `source` names (its layout, the rig's
/// points, two dimensions, no degenerate frame) and returns the rig and the track reduced
/// to the rig's points: what the lab checks before it opens, so a bad track or rig fails
/// at once with its reason while the solve itself runs in the background.
pub fn prepare(seq: &Sequence, source: &RigSource) -> Result<(keyshape_rig::Rig, Sequence)> {
    check_layout(seq.points).map_err(|e| Error::invalid(format!("--rig: {e}")))?;
    let (_, _, rig) = source.read_for(seq.points)?;
    let seq = seq.select_points(&rig.points)?;
    if seq.dims != 2 {
        return Err(Error::invalid("--rig needs a 2-D track"));
    }
    seq.check_geometry()?;
    Ok((rig, seq))
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
    let (rig, seq) = prepare(seq, source)?;
    let rig = &rig;
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
    let n = seq.n_frames();
    let (mut tracked, mut fitted, mut weights) = (Vec::new(), Vec::new(), Vec::new());
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    let mut grow = |p: [f64; 2]| {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    };
    for f in 0..n {
        let w: Vec<f64> = r.weights.column(f).iter().copied().collect();
        let t: Vec<[f64; 2]> = (0..rig.landmarks())
            .map(|i| [seq.coords[(2 * i, f)], -seq.coords[(2 * i + 1, f)]])
            .collect();
        // What was fitted: the person's rig (the identity applied) under the frame's camera.
        let p: Vec<[f64; 2]> = r
            .person_of(f)
            .unwrap_or(rig)
            .posed(&w)
            .iter()
            .map(|x| r.cameras[f].project(x))
            .collect();
        t.iter().chain(&p).for_each(|&q| grow(q));
        tracked.push(t);
        fitted.push(p);
        weights.push(w);
    }
    let half = (hi[0] - lo[0]).max(hi[1] - lo[1]) * 0.55;
    let (cx, cy) = ((lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0);
    Ok(RigView {
        names: rig.names.clone(),
        weights,
        tracked,
        fitted,
        rms: r.rms,
        polylines: rig.polylines(),
        smooth,
        neutral: r.neutrals.first().copied(),
        bounds: ([cx - half, cx + half], [cy - half, cy + half]),
    })
}
