//! The rig view of the lab (issue 16 item 8, `kslab tui FILE --rig DIR`): the track solved
//! onto a blendshape rig once when the lab opens; `r` shows the tracked landmarks with the
//! posed rig's under the fitted head pose, and the rig's weights as named bars.

use crate::error::{Error, Result};
use crate::rig::{mediapipe_to_ibug68, solve_rig, Rig, RigOptions, LANDMARKS};
use crate::sequence::{Layout, Sequence};

/// What the lab draws of a rig solve.
#[derive(Debug, Clone)]
pub struct RigView {
    /// Shape names, as the rig names them.
    pub names: Vec<String>,
    /// Per frame, every shape's weight.
    pub weights: Vec<Vec<f64>>,
    /// Per frame, the tracked 68 landmarks (x, y up).
    pub tracked: Vec<Vec<[f64; 2]>>,
    /// Per frame, the posed rig's landmarks under the fitted head pose (x, y up).
    pub fitted: Vec<Vec<[f64; 2]>>,
    /// Per frame, RMS landmark error (track units).
    pub rms: Vec<f64>,
    /// iBUG-68 contours.
    pub polylines: Vec<Vec<usize>>,
    /// x and y bounds over all frames of both.
    pub bounds: ([f64; 2], [f64; 2]),
}

/// Solves `seq` (68 points, or MediaPipe 468 through the built-in correspondence) onto
/// `rig` with the default options (bounded, offset identity, automatic neutral).
pub fn rig_view(seq: &Sequence, rig: &Rig) -> Result<RigView> {
    let seq = match seq.points {
        LANDMARKS => seq.clone(),
        468 | 478 => seq.select_points(&mediapipe_to_ibug68()?)?,
        n => {
            return Err(Error::invalid(format!(
                "--rig needs a 68-point or MediaPipe (468 or 478-point) track, not {n} points"
            )))
        }
    };
    if seq.dims != 2 {
        return Err(Error::invalid("--rig needs a 2-D track"));
    }
    seq.check_geometry()?;
    let r = solve_rig(rig, &seq.coords, &[], &RigOptions::recommended())?;
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
        let t: Vec<[f64; 2]> = (0..LANDMARKS)
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
    let all: Vec<usize> = (0..LANDMARKS).collect();
    Ok(RigView {
        names: rig.names.clone(),
        weights,
        tracked,
        fitted,
        rms: r.rms,
        polylines: crate::retarget::setup::polylines_for(&Layout::ibug68(), &all),
        bounds: ([cx - half, cx + half], [cy - half, cy + half]),
    })
}
