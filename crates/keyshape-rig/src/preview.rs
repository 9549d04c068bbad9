//! One frame's weights before the take is solved: the neutral searched on a sparser view
//! of the take (a MediaPipe track's 68 iBUG points on the rig's 68-landmark map), the
//! identity lifted from it, and that frame alone solved through every landmark. What the lab shows while the whole take
//! solves in the background.
//!
//! It differs from the take's solve in three ways, each measured (BENCHMARKS.md, "A
//! preview of the current frame"): the neutral is searched on fewer landmarks and frames,
//! the identity has no fitted depth, and the frame is not smoothed with its neighbours
//! (the zero-phase Gaussian or the offline prior).

use super::camera::{fit_camera, Camera};
use super::checks::check_options;
use super::frame::frame_points;
use super::identifiability::identifiability_weighted;
use super::neutral::{person_rig, NeutralRule};
use super::prior::prior_iod;
use super::solve::{check_frames, check_neutral, identities, image_and_depth, neutral_frames, run};
use super::{Identity, Neutral, Rig, RigOptions};
use keyshape_core::error::{Error, Result};
use nalgebra::DMatrix;

/// How many frames the preview's neutral search scores each candidate on: half the take's
/// [`super::NEUTRAL_SCORED_FRAMES`] (the search takes 0.14 s instead of 0.23 s on d6, and
/// finds the take's neutral on every shipped track either way; BENCHMARKS.md).
pub const PREVIEW_SCORED_FRAMES: usize = 32;

/// A preview of one frame of a track ([`preview_frame`]).
#[derive(Debug, Clone)]
pub struct FramePreview {
    /// The frame column previewed.
    pub frame: usize,
    /// The frame column the identity was taken from (`None` with [`Identity::None`]), and
    /// the rule that chose it.
    pub neutral: Option<(usize, NeutralRule)>,
    /// Every shape's weight at the frame.
    pub weights: Vec<f64>,
    /// The frame's head pose.
    pub camera: Camera,
    /// The frame's RMS landmark error (track units).
    pub rms: f64,
    /// The person's rig (the identity applied), to draw the fitted landmarks with.
    pub person: Rig,
}

/// Frame column `frame` of `track` (as [`super::solve_rig`] reads it) solved onto `rig`
/// without the rest of the take: with [`Neutral::Auto`] or [`Neutral::LeastActive`] the
/// neutral is chosen by the same rule as the take's solve, each candidate scored on
/// [`PREVIEW_SCORED_FRAMES`] frames instead of the take's 64, and on `search` (another rig
/// and the same take's track read through it, e.g. the 68-landmark map and the track's 68
/// iBUG points; `None`: `rig` and `track` themselves); the identity is lifted from it
/// without a fitted depth; and the frame is solved alone, with no temporal prior and no
/// robust weights.
pub fn preview_frame(
    rig: &Rig,
    track: &DMatrix<f64>,
    frame: usize,
    opts: &RigOptions,
    search: Option<(&Rig, &DMatrix<f64>)>,
) -> Result<FramePreview> {
    let (image, depth) = image_and_depth(rig, track)?;
    let depth = depth.as_ref();
    check_frames(&image, rig.landmarks())?;
    let lw = check_options(rig, opts)?;
    check_neutral(opts.neutral, image.ncols())?;
    if frame >= image.ncols() {
        return Err(Error::invalid(format!(
            "preview: frame column {frame} is past the track's {} frames",
            image.ncols()
        )));
    }
    if let Some((_, t)) = search.filter(|(_, t)| t.ncols() != image.ncols()) {
        return Err(Error::invalid(format!(
            "preview: the search's track has {} frames, the track {}",
            t.ncols(),
            image.ncols()
        )));
    }
    let neutral = match (opts.identity, opts.neutral) {
        (Identity::None, _) => None,
        (_, Neutral::Column(c)) => Some((c..c + 1, c, NeutralRule::Given)),
        (_, Neutral::Span(a, b)) => Some((a..b, (a + b) / 2, NeutralRule::Given)),
        (_, Neutral::Auto | Neutral::LeastActive) => {
            let (sub, sub_track) = search.unwrap_or((rig, track));
            let (sub_image, sub_depth) = image_and_depth(sub, sub_track)?;
            let sub_lw = check_options(sub, opts)?;
            let all = 0..image.ncols();
            let whole = std::slice::from_ref(&all);
            let (_, neutrals, rules) = identities(
                sub,
                (&sub_image, sub_depth.as_ref()),
                whole,
                opts,
                (&sub_lw, PREVIEW_SCORED_FRAMES),
                None,
                &mut |_| {},
            )?;
            match (neutrals.first(), rules.first()) {
                (Some(&n), Some(&rule)) => Some((n..n + 1, n, rule)),
                _ => None,
            }
        }
    };
    let person = match &neutral {
        Some((frames, _, _)) => person_rig(rig, &image, depth, frames.clone(), opts.identity)?,
        None => rig.clone(),
    };
    let iod = prior_iod(rig, &image, opts, neutral_frames(opts.neutral));
    let view = neutral.as_ref().map_or(frame, |n| n.1);
    let cam_n = fit_camera(&person.neutral, &frame_points(&image, view))?;
    let shapes = identifiability_weighted(&person, &cam_n, opts.min_determination, &lw);
    let free: Vec<usize> = (0..rig.k()).filter(|&s| !shapes[s].frozen).collect();
    let one = image.columns(frame, 1).into_owned();
    let one_depth = depth.map(|d| d.columns(frame, 1).into_owned());
    // One frame: no temporal prior or zero-phase Gaussian applies (both are no-ops on a
    // one-frame clip; set off so no sweep runs), and `run` has no robust re-solve.
    let alone = RigOptions {
        smooth: 0.0,
        zero_phase: 0.0,
        ..*opts
    };
    let people = [(0..1, person)];
    let out = run(
        rig,
        (&one, one_depth.as_ref()),
        &people,
        free,
        &alone,
        &lw,
        iod,
    )?;
    let [(_, person)] = people;
    Ok(FramePreview {
        frame,
        neutral: neutral.map(|(_, n, rule)| (n, rule)),
        weights: out.weights.column(0).iter().copied().collect(),
        camera: out.cameras[0],
        rms: out.rms[0],
        person,
    })
}
