//! The rig solve's options checked against the rig before anything is solved: every
//! setting takes effect or is refused, naming the setting and its value.

use super::{correspondence, Identity, Neutral, Rig, RigOptions, SmoothUnit, LANDMARKS};
use keyshape_core::error::{Error, Result};

/// Checks `opts` against `rig`; returns the per-landmark weights of the fit.
pub(crate) fn check_options(rig: &Rig, opts: &RigOptions) -> Result<Vec<f64>> {
    if !(opts.min_determination >= 0.0 && opts.min_determination < 1.0) {
        return Err(Error::bad_setting(
            "min_determination",
            opts.min_determination,
            format!(
                "the minimum determination must be in [0, 1), not {}",
                opts.min_determination
            ),
        ));
    }
    if !(opts.zero_phase.is_finite() && (0.0..=1000.0).contains(&opts.zero_phase)) {
        return Err(Error::bad_setting(
            "zero_phase",
            opts.zero_phase,
            format!(
                "the zero-phase σ must be a number of frames in [0, 1000], not {}",
                opts.zero_phase
            ),
        ));
    }
    keyshape_core::limits::RIG_SMOOTH.check("smooth", opts.smooth)?;
    if !(opts.prior.is_finite() && opts.prior >= 0.0) {
        return Err(Error::bad_setting(
            "prior",
            opts.prior,
            format!(
                "the magnitude prior must be a number ≥ 0, not {}",
                opts.prior
            ),
        ));
    }
    if !(opts.smooth.is_finite() && opts.smooth >= 0.0) {
        return Err(Error::bad_setting(
            "smooth",
            opts.smooth,
            format!(
                "the temporal prior λ must be a number ≥ 0, not {}",
                opts.smooth
            ),
        ));
    }
    if let Some((i, w)) = opts
        .landmark_weights
        .iter()
        .enumerate()
        .find(|(_, w)| !(w.is_finite() && **w >= 0.0))
    {
        return Err(Error::bad_setting(
            "landmark_weights",
            w,
            format!("landmark {i}'s weight must be a finite number ≥ 0, not {w}"),
        ));
    }
    let lw = rig_landmark_weights(rig, opts)?;
    if opts.prior > 0.0 && rig.eyes().is_none() {
        let [a, b] = correspondence::eye_corners(rig.layout).unwrap_or([36, 45]);
        return Err(Error::invalid(format!(
            "the magnitude prior is scaled by the outer eye corners (track points {a} and {b}), which the rig's correspondence leaves out: name them, or set the prior to 0"
        )));
    }
    if opts.smooth > 0.0 && opts.smooth_unit == SmoothUnit::Iod && rig.eyes().is_none() {
        let [a, b] = correspondence::eye_corners(rig.layout).unwrap_or([36, 45]);
        return Err(Error::invalid(format!(
            "a temporal prior relative to the face is scaled by the outer eye corners (track points {a} and {b}), which the rig's correspondence leaves out: name them, or give λ in pixels"
        )));
    }
    let weighted = lw.iter().filter(|w| **w > 0.0).count();
    if weighted < 4 {
        return Err(Error::bad_setting("landmark_weights", weighted, format!(
            "the landmark weights leave {weighted} landmarks with weight > 0; the head pose needs at least 4"
        )));
    }
    check_causal(opts)?;
    Ok(lw)
}

/// A causal solve's settings: nothing that reads frames still to come.
fn check_causal(opts: &RigOptions) -> Result<()> {
    if !opts.causal {
        return Ok(());
    }
    if opts.zero_phase != 0.0 {
        return Err(Error::bad_setting(
            "zero_phase",
            opts.zero_phase,
            format!(
                "a causal solve cannot smooth with frames still to come: zero-phase σ {} must be 0",
                opts.zero_phase
            ),
        ));
    }
    if opts.smooth > 0.0 && opts.smooth_mode == keyshape_core::solve::temporal::SmoothMode::Offline
    {
        return Err(Error::invalid(
            "a causal solve cannot use the offline temporal prior (it solves a clip at once)",
        ));
    }
    if opts.robust {
        return Err(Error::invalid(
            "a causal solve cannot weigh landmarks robustly: that measures each landmark over the whole track",
        ));
    }
    if opts.identity != Identity::None
        && matches!(opts.neutral, Neutral::Auto | Neutral::LeastActive)
    {
        return Err(Error::invalid(
            "a causal solve needs its neutral given (a frame, or a lead-in of frames): finding it searches the whole track",
        ));
    }
    Ok(())
}

/// Per landmark, the weight of its squared error: `opts.landmark_weights` (iBUG numbering)
/// read at the rig's points on a 68-point layout (and on iBUG with pupils, whose pupils
/// weigh 1); on other layouts they must all be 1.
pub(crate) fn rig_landmark_weights(rig: &Rig, opts: &RigOptions) -> Result<Vec<f64>> {
    if rig.layout == LANDMARKS || rig.layout == crate::correspondence::IBUG_PUPILS {
        return Ok(rig
            .points
            .iter()
            .map(|&p| opts.landmark_weights.get(p).copied().unwrap_or(1.0))
            .collect());
    }
    if opts.landmark_weights.iter().any(|&w| w != 1.0) {
        return Err(Error::invalid(format!(
            "landmark weights name the 68 iBUG landmarks; this rig reads a {}-point track",
            rig.layout
        )));
    }
    Ok(vec![1.0; rig.landmarks()])
}
