//! The person's neutral: the automatic search over candidate frames (kept to closed lips
//! and resting brows, scored by how well the clip is explained from each), and the
//! person's rig built from a neutral frame or a recorded lead-in.

use super::camera::fit_camera;
use super::depth::{fit_from, NeutralFit};
use super::frame::{frame_depth, frame_points, FrameSolver};
use super::prior::{exclusive_pairs, magnitude_prior};
use super::{Identity, Rig, RigOptions};
use keyshape_core::error::{Error, Result};
use keyshape_core::rbf::Rbf;
use nalgebra::DMatrix;
use std::ops::Range;

/// A frame's lips and brows, each as a fraction of the frame's inter-ocular distance: the
/// inner lips' gap (iBUG 62–66 / MediaPipe 13–14) and each brow's middle above its upper lid
/// (iBUG 19–37 and 24–44 / MediaPipe 105–159 and 334–386), averaged. `None` when the rig
/// does not read those points (or the eye corners).
pub(super) fn lips_and_brows(rig: &Rig, track: &DMatrix<f64>, f: usize) -> Option<(f64, f64)> {
    let (lips, brows): ([usize; 2], [[usize; 2]; 2]) = match rig.layout {
        68 | 70 => ([62, 66], [[19, 37], [24, 44]]),
        _ => ([13, 14], [[105, 159], [334, 386]]),
    };
    let at = |p: usize| rig.points.iter().position(|&q| q == p);
    let eyes = rig.eyes()?;
    let (l0, l1) = (at(lips[0])?, at(lips[1])?);
    let brows: Vec<[usize; 2]> = brows
        .iter()
        .map(|[b, e]| Some([at(*b)?, at(*e)?]))
        .collect::<Option<_>>()?;
    let pt = |i: usize| [track[(2 * i, f)], track[(2 * i + 1, f)]];
    let dist = |a: [f64; 2], b: [f64; 2]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
    let iod = dist(pt(eyes[0]), pt(eyes[1])).max(f64::MIN_POSITIVE);
    let gap = dist(pt(l0), pt(l1)) / iod;
    let raise = brows.iter().map(|[b, e]| dist(pt(*b), pt(*e))).sum::<f64>() / (2.0 * iod);
    Some((gap, raise))
}

/// Of `frames`, those that look neutral: lips no more parted and brows no higher than the
/// median of `frames` ([`lips_and_brows`]). A frame with parted lips or raised brows is then
/// never the neutral. All of `frames` when the rig does not read those points.
pub(super) fn neutral_looking(rig: &Rig, track: &DMatrix<f64>, frames: Vec<usize>) -> Vec<usize> {
    let Some(m) = frames
        .iter()
        .map(|&f| lips_and_brows(rig, track, f))
        .collect::<Option<Vec<(f64, f64)>>>()
    else {
        return frames;
    };
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    if m.is_empty() {
        return frames;
    }
    let (g, r) = (
        median(m.iter().map(|x| x.0).collect()),
        median(m.iter().map(|x| x.1).collect()),
    );
    let kept: Vec<usize> = frames
        .iter()
        .zip(&m)
        .filter(|(_, x)| x.0 <= g && x.1 <= r)
        .map(|(&f, _)| f)
        .collect();
    if kept.is_empty() {
        frames
    } else {
        kept
    }
}

/// Neutral candidates tried per clip by [`Neutral::Auto`](super::Neutral::Auto) (all frames of shorter clips).
pub const NEUTRAL_CANDIDATES: usize = 48;
/// Frames of a clip each candidate is scored on (all frames of shorter clips).
pub const NEUTRAL_SCORED_FRAMES: usize = 64;

/// `count` evenly spaced members of `r` (all of them when it has no more), in order.
pub(super) fn evenly_spaced(r: Range<usize>, count: usize) -> Vec<usize> {
    let len = r.len();
    if len <= count {
        return r.collect();
    }
    (0..count)
        .map(|i| r.start + (i * (len - 1) + (count - 1) / 2) / (count - 1))
        .collect()
}

/// A neutral frame turned further than this (degrees from frontal) is reported as not
/// looking neutral: its identity is lifted from a turned head.
pub const NEUTRAL_TURN_WARN_DEG: f64 = 20.0;
/// A neutral frame whose inner lips are further apart than this fraction of its
/// inter-ocular distance is reported as not looking neutral (the ICT rig's neutral: 0.01).
pub const NEUTRAL_LIPS_WARN: f64 = 0.08;

/// Below this, the least active neutral candidate of a clip (its first-pass weights summed,
/// [`NeutralView::activity`]: the rig as it is, no identity) says the rig's neutral is the
/// performer's own face — a rig made of the person — and [`Neutral::Auto`](super::Neutral::Auto)
/// takes the least-active rule's frame ([`NeutralRule::OwnFace`]). Then the first pass reads
/// expression, not identity, and with no neutral frame anywhere (an expression held through
/// the take) the least active frame holds the least of it, which the error score cannot
/// tell at the noise (`kslab rig-accuracy --person same --hold 1.2`: least-active mean r
/// 0.897 / 0.837 / 0.741 / 0.728 against the score's 0.880 / 0.820 / 0.735 / 0.703). Another
/// person's neutral face reads as 5.0–6.9 on the benchmark's renders (seeds 1–10, held
/// expression or not) and 7–17 on every shipped real track; the rig's own face as 0.3–0.8,
/// and 0.8–1.9 holding 1.2 of expression.
pub const OWN_FACE_ACTIVITY: f64 = 3.0;

/// Which rule chose a neutral frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum NeutralRule {
    /// Named by the caller (a frame, or a lead-in's middle frame).
    Given,
    /// The candidate whose identity best explains the clip ([`Neutral::Auto`](super::Neutral::Auto)).
    BestExplaining,
    /// The frame whose first-pass weights sum least ([`Neutral::LeastActive`](super::Neutral::LeastActive)).
    LeastActive,
    /// [`Neutral::Auto`](super::Neutral::Auto) on a rig of the performer's own face
    /// ([`OWN_FACE_ACTIVITY`]): the least-active rule's frame.
    OwnFace,
}

/// How a neutral frame looks: its head pose and how much expression the rig as it is sees
/// in it.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct NeutralView {
    /// The frame's column in the track.
    pub frame: usize,
    /// Head yaw, pitch and roll in degrees
    /// ([`Camera::yaw_pitch_roll`](crate::camera::Camera::yaw_pitch_roll)) of the rig's
    /// neutral fitted to the frame.
    pub yaw_pitch_roll: [f64; 3],
    /// The angle in degrees between the face's forward axis and the view direction (0:
    /// frontal).
    pub turn: f64,
    /// The frame's weights summed, solved with the rig as it is (no identity, every shape
    /// free): the expression the frame holds, and the person's difference from the rig,
    /// which reads as expression too (another person's neutral face sums to 6–9 on the
    /// benchmark's renders), so it ranks a person's frames but says nothing alone.
    pub activity: f64,
    /// The inner lips' gap as a fraction of the inter-ocular distance (NaN when the rig
    /// does not read the points).
    pub lip_gap: f64,
    /// Whether the frame looks neutral: turned at most [`NEUTRAL_TURN_WARN_DEG`] and the
    /// lips parted at most [`NEUTRAL_LIPS_WARN`]. A held expression (a half smile kept
    /// through the whole take) is not caught: without a neutral frame it cannot be told
    /// from the person's face.
    pub looks_neutral: bool,
    /// The rule that chose the frame.
    pub rule: NeutralRule,
}

/// The pose and first-pass activity of each of `frames` ([`NeutralView`]).
pub(super) fn views(
    rig: &Rig,
    (track, depth): (&DMatrix<f64>, Option<&DMatrix<f64>>),
    frames: &[usize],
    opts: &RigOptions,
    lw: &[f64],
    iod: f64,
) -> Result<Vec<NeutralView>> {
    use rayon::prelude::*;
    frames
        .par_chunks(8)
        .map(|chunk| -> Result<Vec<NeutralView>> {
            let all: Vec<usize> = (0..rig.k()).collect();
            let mut fs = FrameSolver::new(rig, all, opts.solver, opts.max_steps.max(1), lw);
            fs.ridge = magnitude_prior(iod, opts, rig, &fs.free);
            fs.pairs = exclusive_pairs(rig, &fs.free, &fs.ridge);
            fs.taper = super::prior::tapering(rig, opts, &fs.free, &fs.ridge);
            chunk
                .iter()
                .map(|&f| {
                    let u = frame_points(track, f);
                    let cam = fit_camera(&rig.neutral, &u)?;
                    fs.depth = frame_depth(depth, f);
                    // Each frame from rest: a warm start would carry one frame's
                    // expression into the next candidate's.
                    fs.w.iter_mut().for_each(|w| *w = 0.0);
                    fs.state
                        .iter_mut()
                        .for_each(|b| *b = keyshape_core::solve::active_set::Bound::Lower);
                    fs.solve(&u)?;
                    let activity: f64 = fs.full_weights().iter().sum();
                    let ypr = cam.yaw_pitch_roll().map(f64::to_degrees);
                    let turn = cam.r[(2, 2)].clamp(-1.0, 1.0).acos().to_degrees();
                    let lip_gap = lips_and_brows(rig, track, f).map_or(f64::NAN, |m| m.0);
                    Ok(NeutralView {
                        frame: f,
                        yaw_pitch_roll: ypr,
                        turn,
                        activity,
                        lip_gap,
                        looks_neutral: turn <= NEUTRAL_TURN_WARN_DEG
                            && (lip_gap.is_nan() || lip_gap <= NEUTRAL_LIPS_WARN),
                        rule: NeutralRule::Given,
                    })
                })
                .collect()
        })
        .collect::<Result<Vec<Vec<NeutralView>>>>()
        .map(|v| v.into_iter().flatten().collect())
}

/// The first-pass weights summed ([`NeutralView::activity`], the weights bounded) of the
/// least active of `clip`'s neutral candidates (as [`best_explaining`] picks them), for
/// [`OWN_FACE_ACTIVITY`].
pub(super) fn least_candidate_activity(
    rig: &Rig,
    (track, depth): (&DMatrix<f64>, Option<&DMatrix<f64>>),
    clip: Range<usize>,
    opts: &RigOptions,
    lw: &[f64],
    iod: f64,
) -> Result<f64> {
    let candidates = neutral_looking(rig, track, evenly_spaced(clip, NEUTRAL_CANDIDATES));
    // Bounded whatever the solve's solver: signed (least-squares) weights cancel in a sum.
    let bounded = RigOptions {
        solver: keyshape_core::solve::Solver::Bounded,
        ..*opts
    };
    Ok(views(rig, (track, depth), &candidates, &bounded, lw, iod)?
        .iter()
        .map(|v| v.activity)
        .fold(f64::INFINITY, f64::min))
}

/// The frame of `clip` whose identity best explains the clip ([`Neutral::Auto`]), and the
/// depth that identity takes ([`NeutralFit::offsets`]; `None` when the track has depth of
/// its own): for each of up to [`NEUTRAL_CANDIDATES`] evenly spaced candidates that look
/// neutral ([`neutral_looking`]), the person's rig from that frame, its identifiability, and
/// a solve (no temporal prior) of up to [`NEUTRAL_SCORED_FRAMES`] evenly spaced frames
/// ([`fit_from`]); the candidate with the lowest (weighted) squared landmark error left
/// once each landmark's constant offset and depth are fitted over the scored frames wins,
/// ties to the earlier frame. A neutral face is one from which the rest of the performance
/// is reached with the weights inside their bounds; a frame that already holds an
/// expression (raised brows, say) leaves every frame with less of it unexplained.
/// The offset: the candidate's own landmark noise becomes part of the person and leaves
/// every scored frame the same residual; counted, that noise decided between candidates (on
/// the benchmark's blinks it took a frame inside the held smile over the lead-in). The
/// depth: one frame's residual is lifted in that frame's image plane, so a person whose face
/// is deeper or flatter than the rig's leaves a residual that grows with the head's turn
/// away from the candidate; counted, it made the candidate whose pose is central among the
/// scored frames win whatever its expression (the held smile again, on 5 of 10 seeds). The
/// search scores with the plain ridge, not the tapered prior (tapered, it took the held
/// smile again).
///
/// Three further rules were measured on renders (`kslab rig-accuracy --seeds 1..10`) and not
/// adopted; docs/src/rig_accuracy.md, "The automatic neutral", has the tables:
/// - keeping only near-frontal candidates (within 10° or 20° of the most frontal one):
///   where the frontal frames all hold an expression the rule lowered mean r (0.907 →
///   0.872 at yaw ±35°, no lead-in);
/// - keeping the less active half (first-pass weights summed at most the median), or the
///   least active of the near-best: each found the lead-in on blinks but lost elsewhere
///   and moved the shipped tracks' neutrals to frames that read worse.
///
/// `scored`: how many frames each candidate is scored on ([`NEUTRAL_SCORED_FRAMES`]; the
/// lab's preview takes fewer).
pub(super) fn best_explaining(
    rig: &Rig,
    (track, depth): (&DMatrix<f64>, Option<&DMatrix<f64>>),
    clip: Range<usize>,
    opts: &RigOptions,
    (lw, scored): (&[f64], usize),
) -> Result<(usize, Option<Vec<[f64; 3]>>)> {
    use rayon::prelude::*;
    let candidates = neutral_looking(rig, track, evenly_spaced(clip.clone(), NEUTRAL_CANDIDATES));
    let scored = evenly_spaced(clip, scored);
    let fits: Vec<Result<(usize, NeutralFit)>> = candidates
        .par_iter()
        .map(|&n| -> Result<(usize, NeutralFit)> {
            let person = person_rig(rig, track, depth, n..n + 1, opts.identity)?;
            Ok((
                n,
                fit_from(rig, &person, (track, depth), n, &scored, opts, lw)?,
            ))
        })
        .collect();
    // A candidate that cannot be a neutral (its solve fails) is passed over; the search
    // fails only when every candidate does, with the first one's error.
    let best = fits
        .iter()
        .filter_map(|s| s.as_ref().ok())
        .filter(|s| !s.1.residual.is_nan())
        .min_by(|a, b| a.1.residual.total_cmp(&b.1.residual).then(a.0.cmp(&b.0)))
        .map(|s| s.0);
    match best {
        Some(n) => {
            let fit = fits.into_iter().find_map(|s| s.ok().filter(|s| s.0 == n));
            Ok((n, fit.and_then(|s| s.1.offsets)))
        }
        None => match fits.into_iter().find_map(|s| s.err()) {
            Some(e) => Err(e),
            None => Ok((candidates[0], None)),
        },
    }
}

/// The person's rig from the neutral frames `frames` (one, or a recorded lead-in).
pub(super) fn person_rig(
    rig: &Rig,
    track: &DMatrix<f64>,
    depth: Option<&DMatrix<f64>>,
    frames: Range<usize>,
    id: Identity,
) -> Result<Rig> {
    person_rig_with(rig, (track, depth), frames, id, None)
}

/// [`person_rig`], with `offsets` (per landmark, in the rig's frame: the depth
/// [`fit_from`] found) added to the lifted identity before an RBF identity interpolates it.
pub(super) fn person_rig_with(
    rig: &Rig,
    (track, depth): (&DMatrix<f64>, Option<&DMatrix<f64>>),
    frames: Range<usize>,
    id: Identity,
    offsets: Option<&[[f64; 3]]>,
) -> Result<Rig> {
    // A neutral frame is the person with no expression: its weights are 0 by definition,
    // and its head pose is the rig's neutral fitted to it. Each frame's residual, lifted
    // into the rig's frame, is averaged over `frames`.
    let count = frames.len().max(1) as f64;
    let posed = &rig.neutral;
    let mut neutral = rig.neutral.clone();
    for n in frames {
        if let Some(why) = keyshape_core::sequence::face_problem(track.column(n).as_slice(), 2) {
            return Err(Error::unfit(format!(
                "frame column {n} cannot be a neutral: {why}"
            )));
        }
        let u = frame_points(track, n);
        let cam = fit_camera(posed, &u)?;
        // With depth, its residual too (after the best depth offset, the mean).
        let r3 = [cam.r[(2, 0)], cam.r[(2, 1)], cam.r[(2, 2)]];
        let dz: Option<Vec<f64>> = frame_depth(depth, n).map(|d| {
            let r: Vec<f64> = d.iter().zip(posed).map(|(z, p)| z - cam.depth(p)).collect();
            let mean = r.iter().sum::<f64>() / r.len().max(1) as f64;
            r.iter().map(|v| v - mean).collect()
        });
        // The residual, lifted into the rig's frame in the image plane of the neutral
        // camera (and along its depth axis, with depth).
        for (i, p) in neutral.iter_mut().enumerate() {
            let e = cam.project(&posed[i]);
            let d = [(u[i][0] - e[0]) / cam.s, (u[i][1] - e[1]) / cam.s];
            let z = dz.as_ref().map_or(0.0, |z| z[i] / cam.s);
            for a in 0..3 {
                p[a] += (cam.r[(0, a)] * d[0] + cam.r[(1, a)] * d[1] + r3[a] * z) / count;
            }
        }
    }
    for (p, o) in neutral.iter_mut().zip(offsets.unwrap_or(&[])) {
        for a in 0..3 {
            p[a] += o[a];
        }
    }
    let mut person = Rig {
        neutral,
        ..rig.clone()
    };
    if id == Identity::Rbf {
        // The RBF interpolates the identity's displacement (person − rig at the landmarks),
        // so the map is the identity plus a smooth correction: multiquadrics alone do not
        // reproduce the identity map between their centres.
        let src: Vec<f64> = rig.neutral.iter().flatten().copied().collect();
        let disp: Vec<f64> = person
            .neutral
            .iter()
            .zip(&rig.neutral)
            .flat_map(|(p, q)| [p[0] - q[0], p[1] - q[1], p[2] - q[2]])
            .collect();
        let f = Rbf::fit(&src, &disp, 3)?;
        let mut at = [0.0; 3];
        for d in person.deltas.iter_mut() {
            for (i, o) in d.iter_mut().enumerate() {
                if *o == [0.0; 3] {
                    continue;
                }
                let x = [
                    rig.neutral[i][0] + o[0],
                    rig.neutral[i][1] + o[1],
                    rig.neutral[i][2] + o[2],
                ];
                f.apply_point(&x, &mut at);
                // F(N + D) − F(N) with F(x) = x + disp(x), and disp(N) the landmark's own.
                let base = [disp[3 * i], disp[3 * i + 1], disp[3 * i + 2]];
                *o = [
                    o[0] + at[0] - base[0],
                    o[1] + at[1] - base[1],
                    o[2] + at[2] - base[2],
                ];
            }
        }
    }
    Ok(person)
}

#[cfg(test)]
mod tests {
    use super::evenly_spaced;

    #[test]
    fn evenly_spaced_candidates_keep_both_ends_and_never_repeat() {
        assert_eq!(evenly_spaced(5..9, 48), vec![5, 6, 7, 8]);
        assert_eq!(evenly_spaced(0..0, 3), Vec::<usize>::new());
        for (r, count) in [
            (0..477, 48),
            (100..1000, 48),
            (3..53, 49),
            (0..100_000, 160),
        ] {
            let v = evenly_spaced(r.clone(), count);
            assert_eq!(v.len(), count);
            assert_eq!((v[0], v[count - 1]), (r.start, r.end - 1));
            assert!(v.windows(2).all(|w| w[0] < w[1]), "{v:?}");
            // Gaps differ by at most one frame.
            let gaps: Vec<usize> = v.windows(2).map(|w| w[1] - w[0]).collect();
            let (lo, hi) = (gaps.iter().min().unwrap(), gaps.iter().max().unwrap());
            assert!(hi - lo <= 1, "{gaps:?}");
        }
    }
}
