//! The whole track's rig solve: the neutral and identity per clip, the identifiability
//! check, the frame-by-frame pass, and the temporal priors after or inside it.

use super::camera::{fit_camera, Camera};
use super::checks::check_options;
use super::depth::fit_from;
use super::frame::{frame_depth, frame_points, FrameSolver};
use super::identifiability::identifiability_weighted;
use super::neutral::{
    best_explaining, evenly_spaced, least_candidate_activity, person_rig, person_rig_with, views,
    NeutralRule,
};
use super::prior::{exclusive_pairs, magnitude_prior, prior_iod, tapering};
use super::{temporal, Identity, Neutral, Rig, RigOptions, RigSolve};
use keyshape_core::error::{Error, Result};
use nalgebra::DMatrix;
use std::ops::Range;

/// Solves every frame of `track` (iBUG-68 2-D points, 136 × frames, image axes) onto `rig`.
/// `clips` (consecutive column ranges covering the track, or empty for one clip) may hold
/// different people: with `Neutral::Auto` each clip takes its identity from its own least
/// active frame; an explicit neutral column gives every clip that frame's identity.
pub fn solve_rig(
    rig: &Rig,
    track: &DMatrix<f64>,
    clips: &[Range<usize>],
    opts: &RigOptions,
) -> Result<RigSolve> {
    solve_rig_observed(rig, track, clips, opts, &mut |_| {})
}

/// [`solve_rig`], naming each step to `step` as it starts (the neutral search, the first
/// pass, the frames) — what a waiting user reads.
pub fn solve_rig_observed(
    rig: &Rig,
    track: &DMatrix<f64>,
    clips: &[Range<usize>],
    opts: &RigOptions,
    step: &mut dyn FnMut(String),
) -> Result<RigSolve> {
    let (image, depth) = image_and_depth(rig, track)?;
    let track = &image;
    let depth = depth.as_ref();
    check_frames(track, rig.landmarks())?;
    let lw = check_options(rig, opts)?;
    let clips = covering(clips, track.ncols())?;
    check_neutral(opts.neutral, track.ncols())?;
    // The magnitude prior's scale: the whole track's, or a causal solve's neutral frames'.
    let iod = prior_iod(rig, track, opts, neutral_frames(opts.neutral));
    // Pass 1 (without an identity, or to find the least active frames): the rig as it is,
    // every shape free.
    let first = match (opts.identity, opts.neutral) {
        (Identity::None, _) | (_, Neutral::LeastActive) => {
            if opts.identity != Identity::None {
                step(format!(
                    "a first pass over {} frames, to find the least active",
                    track.ncols()
                ));
            }
            let whole = [(0..track.ncols(), rig.clone())];
            let all: Vec<usize> = (0..rig.k()).collect();
            Some(run(rig, (track, depth), &whole, all, opts, &lw, iod)?)
        }
        _ => None,
    };
    let (people, neutrals, rules) = identities(
        rig,
        (track, depth),
        &clips,
        opts,
        (&lw, super::NEUTRAL_SCORED_FRAMES),
        first.as_ref(),
        step,
    )?;
    // Identifiability at the first clip's neutral view (the rig and the view decide it,
    // not the person); the frozen shapes are the same in every clip.
    let cam_n = match (neutrals.first(), &first) {
        (Some(&n), _) => fit_camera(&people[0].1.neutral, &frame_points(track, n))?,
        (None, Some(first)) => first.cameras[0],
        (None, None) => fit_camera(&rig.neutral, &frame_points(track, 0))?,
    };
    let shapes = identifiability_weighted(&people[0].1, &cam_n, opts.min_determination, &lw);
    let free: Vec<usize> = (0..rig.k()).filter(|&s| !shapes[s].frozen).collect();
    step(format!(
        "solving {} frames{}",
        track.ncols(),
        if opts.smooth > 0.0 {
            format!(", temporal prior λ {:.3}", opts.lambda(iod))
        } else {
            String::new()
        }
    ));
    let mut out = run(rig, (track, depth), &people, free.clone(), opts, &lw, iod)?;
    if opts.robust {
        for round in 1..=2 {
            step(format!(
                "weighing each landmark by how well the rig explains it ({round} of 2)"
            ));
            let robust = robust_weights(&people, track, &out, &lw);
            out = run(
                rig,
                (track, depth),
                &people,
                free.clone(),
                opts,
                &robust,
                iod,
            )?;
        }
    }
    out.neutral_views = views(rig, (track, depth), &neutrals, opts, &lw, iod)?;
    for (v, rule) in out.neutral_views.iter_mut().zip(rules) {
        v.rule = rule;
    }
    out.shapes = shapes;
    out.neutrals = neutrals;
    out.people = people;
    Ok(out)
}

/// A track's image rows, and with depth (x, y, z per landmark) its depth rows with the
/// sign turned to point towards the viewer (MediaPipe's z is more negative closer).
pub(super) fn image_and_depth(
    rig: &Rig,
    track: &DMatrix<f64>,
) -> Result<(DMatrix<f64>, Option<DMatrix<f64>>)> {
    let n = rig.landmarks();
    if track.nrows() == 3 * n {
        let xy: Vec<usize> = (0..n).flat_map(|i| [3 * i, 3 * i + 1]).collect();
        let z: Vec<usize> = (0..n).map(|i| 3 * i + 2).collect();
        Ok((track.select_rows(&xy), Some(-track.select_rows(&z))))
    } else if track.nrows() == 2 * n {
        Ok((track.clone(), None))
    } else {
        Err(Error::invalid(format!(
            "the rig reads {n} landmarks (2 or 3 rows each), but the track has {} rows: select the rig's points (Rig::points) from the track first",
            track.nrows(),
        )))
    }
}

/// Refuses a track (image rows, `n` landmarks) with no frames, a value that is not finite,
/// or a frame whose landmarks all coincide (no camera fits it).
pub(super) fn check_frames(track: &DMatrix<f64>, n: usize) -> Result<()> {
    if track.ncols() == 0 {
        return Err(Error::invalid("the track has no frames"));
    }
    if let Some((i, v)) = track.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(Error::invalid(format!(
            "frame column {}: landmark {} is {v}",
            i / track.nrows(),
            (i % track.nrows()) / 2
        )));
    }
    if let Some(c) = (0..track.ncols())
        .find(|&c| keyshape_core::sequence::degenerate_shape(track.column(c).as_slice(), 2))
    {
        return Err(Error::unfit(format!(
            "frame column {c}: all {n} landmarks coincide, so no camera can be fitted to it"
        )));
    }
    Ok(())
}

/// The clips, or the whole track as one when none are given; refused unless they cover the
/// `frames` in order.
fn covering(clips: &[Range<usize>], frames: usize) -> Result<Vec<Range<usize>>> {
    if clips.is_empty() {
        return Ok(std::iter::once(0..frames).collect());
    }
    if clips.iter().any(|c| c.end > frames || c.is_empty())
        || clips.windows(2).any(|w| w[0].end != w[1].start)
        || clips[0].start != 0
        || clips[clips.len() - 1].end != frames
    {
        return Err(Error::invalid(
            "rig solve: clips must cover the frames in order",
        ));
    }
    Ok(clips.to_vec())
}

/// Refuses a named neutral column or stretch that is not inside the track's `frames`.
pub(super) fn check_neutral(neutral: Neutral, frames: usize) -> Result<()> {
    match neutral {
        Neutral::Column(c) if c >= frames => Err(Error::invalid(format!(
            "neutral frame column {c} is past the track's {frames} frames"
        ))),
        Neutral::Span(a, b) if a >= b || b > frames => Err(Error::invalid(format!(
            "neutral frame columns {a}..{b} are not a stretch of the track's {frames} frames"
        ))),
        _ => Ok(()),
    }
}

/// Per clip, its frames and the rig with its person's identity applied.
type People = Vec<(Range<usize>, Rig)>;

/// Who is in each clip: per clip (or for the whole track) the rig with the person's
/// identity applied, the neutral frame it came from and the rule that chose it. `first` is
/// the pass without an identity, which the least-active rule reads; `scored`, how many
/// frames the automatic search scores each candidate on.
pub(super) fn identities(
    rig: &Rig,
    (track, depth): (&DMatrix<f64>, Option<&DMatrix<f64>>),
    clips: &[Range<usize>],
    opts: &RigOptions,
    (lw, scored): (&[f64], usize),
    first: Option<&RigSolve>,
    step: &mut dyn FnMut(String),
) -> Result<(People, Vec<usize>, Vec<NeutralRule>)> {
    let whole = 0..track.ncols();
    Ok(match (opts.identity, opts.neutral) {
        (Identity::None, _) => (vec![(whole, rig.clone())], Vec::new(), Vec::new()),
        (_, Neutral::Column(n)) => {
            let person = lifted(rig, (track, depth), n..n + 1, n, whole.clone(), opts, lw)?;
            (vec![(whole, person)], vec![n], vec![NeutralRule::Given])
        }
        (_, Neutral::Span(a, b)) => {
            let mid = (a + b) / 2;
            let person = lifted(rig, (track, depth), a..b, mid, whole.clone(), opts, lw)?;
            (vec![(whole, person)], vec![mid], vec![NeutralRule::Given])
        }
        (id, auto) => {
            let iod = prior_iod(rig, track, opts, neutral_frames(opts.neutral));
            let (mut people, mut neutrals, mut rules) = (Vec::new(), Vec::new(), Vec::new());
            for c in clips {
                let rule = match (auto, first) {
                    (Neutral::LeastActive, _) => NeutralRule::LeastActive,
                    _ => {
                        step(format!(
                            "choosing the neutral: {} candidate frames, each scored on {}",
                            c.len().min(super::NEUTRAL_CANDIDATES),
                            c.len().min(scored)
                        ));
                        let least = least_candidate_activity(
                            rig,
                            (track, depth),
                            c.clone(),
                            opts,
                            lw,
                            iod,
                        )?;
                        if least < super::OWN_FACE_ACTIVITY {
                            step(format!(
                                "the rig reads as the performer's own face (its least active candidate sums to {least:.2}): the least active frame, from a first pass over {} frames",
                                c.len()
                            ));
                            NeutralRule::OwnFace
                        } else {
                            NeutralRule::BestExplaining
                        }
                    }
                };
                let (n, person) = match (rule, first) {
                    // The earlier rule, kept as it was (no fitted depth): its figures are
                    // tools/rig_vs_pyfeat.py's, which the experiment's test reproduces.
                    (NeutralRule::LeastActive, Some(first)) => {
                        let n = least_active(c, first);
                        (n, person_rig(rig, track, depth, n..n + 1, id)?)
                    }
                    // The same rule on the clip's own first pass, and no fitted depth: the
                    // rig is the performer's face, its depth theirs (fitted, the depth
                    // took some of a held expression: smooth 0.897 → 0.881 with
                    // `rig-accuracy --person same --hold 1.2`).
                    (NeutralRule::OwnFace | NeutralRule::LeastActive, _) => {
                        let all: Vec<usize> = (0..rig.k()).collect();
                        let own = [(c.clone(), rig.clone())];
                        let first = run(rig, (track, depth), &own, all, opts, lw, iod)?;
                        let n = least_active(c, &first);
                        (n, person_rig(rig, track, depth, n..n + 1, id)?)
                    }
                    _ => {
                        // The search has fitted its winner's depth already.
                        let (n, offsets) =
                            best_explaining(rig, (track, depth), c.clone(), opts, (lw, scored))?;
                        let frames = n..n + 1;
                        (
                            n,
                            person_rig_with(rig, (track, depth), frames, id, offsets.as_deref())?,
                        )
                    }
                };
                people.push((c.clone(), person));
                neutrals.push(n);
                rules.push(rule);
            }
            (people, neutrals, rules)
        }
    })
}

/// The person's rig from the neutral frames `frames` (`mid` the one whose view the depth is
/// fitted along), with each landmark's depth fitted over `clip`'s scored frames as the
/// automatic search fits it ([`fit_from`]): one frame, or a lead-in held still, shows no
/// depth; the performance's head turns do. A track with its own depth keeps it, and a
/// causal solve has no fitted depth (its frames ahead are not seen yet). Where the
/// fit fails (a scored frame's solve does) the identity has no fitted depth, as before,
/// and the solve itself reports that frame.
fn lifted(
    rig: &Rig,
    (track, depth): (&DMatrix<f64>, Option<&DMatrix<f64>>),
    frames: Range<usize>,
    mid: usize,
    clip: Range<usize>,
    opts: &RigOptions,
    lw: &[f64],
) -> Result<Rig> {
    let person = person_rig(rig, track, depth, frames.clone(), opts.identity)?;
    // A causal solve sees no frame ahead (the live path's neutral is its lead-in alone).
    if depth.is_some() || opts.causal {
        return Ok(person);
    }
    let scored = evenly_spaced(clip, super::NEUTRAL_SCORED_FRAMES);
    let offsets = fit_from(rig, &person, (track, depth), mid, &scored, opts, lw)
        .ok()
        .and_then(|fit| fit.offsets);
    person_rig_with(
        rig,
        (track, depth),
        frames,
        opts.identity,
        offsets.as_deref(),
    )
}

/// The frame of clip `c` whose weights in the pass without an identity sum least.
fn least_active(c: &Range<usize>, first: &RigSolve) -> usize {
    c.clone()
        .min_by(|&a, &b| {
            let s = |f: usize| first.weights.column(f).sum();
            s(a).total_cmp(&s(b))
        })
        .unwrap_or(c.start)
}

/// [`RigOptions::robust`]'s weights: per landmark, `lw` times the Huber weight
/// `min(1, cσ / sᵢ)` of its RMS residual `sᵢ` over the frames of `out` (its mean residual
/// taken out), σ the median landmark's.
fn robust_weights(
    people: &[(Range<usize>, Rig)],
    track: &DMatrix<f64>,
    out: &RigSolve,
    lw: &[f64],
) -> Vec<f64> {
    let n = lw.len();
    let frames = track.ncols();
    let (mut sum, mut sq) = (vec![[0.0; 2]; n], vec![0.0; n]);
    for (clip, person) in people {
        for f in clip.clone() {
            let w: Vec<f64> = out.weights.column(f).iter().copied().collect();
            let u = frame_points(track, f);
            for (i, p) in person.posed(&w).iter().enumerate() {
                let e = out.cameras[f].project(p);
                let d = [e[0] - u[i][0], e[1] - u[i][1]];
                sum[i][0] += d[0];
                sum[i][1] += d[1];
                sq[i] += d[0] * d[0] + d[1] * d[1];
            }
        }
    }
    let k = frames.max(1) as f64;
    let s: Vec<f64> = (0..n)
        .map(|i| ((sq[i] / k - (sum[i][0] / k).powi(2) - (sum[i][1] / k).powi(2)).max(0.0)).sqrt())
        .collect();
    let mut sorted: Vec<f64> = s.iter().copied().filter(|v| v.is_finite()).collect();
    sorted.sort_by(f64::total_cmp);
    let sigma = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0);
    let c = super::ROBUST_C;
    (0..n)
        .map(|i| {
            let h = if sigma > 0.0 && s[i] > c * sigma {
                c * sigma / s[i]
            } else {
                1.0
            };
            lw[i] * h
        })
        .collect()
}

/// The frames a causal solve measures the prior's scale on: the neutral frame or lead-in,
/// or the first frame when there is none.
pub(super) fn neutral_frames(n: Neutral) -> Range<usize> {
    match n {
        Neutral::Column(c) => c..c + 1,
        Neutral::Span(a, b) => a..b,
        Neutral::Auto | Neutral::LeastActive => 0..1,
    }
}

/// Smooths the columns `clip` of `w` along time by a Gaussian of `sigma` frames (radius
/// ⌈3σ⌉, the kernel renormalised where it passes the clip's ends): zero phase, no lag.
pub fn zero_phase(w: &mut DMatrix<f64>, clip: Range<usize>, sigma: f64) {
    // The smoothing study's zero-phase low-pass, over this one clip.
    let part = w.columns(clip.start, clip.len()).into_owned();
    let smooth = keyshape_core::solve::filters::gaussian_lowpass(
        &part,
        std::slice::from_ref(&(0..clip.len())),
        sigma,
    );
    w.columns_mut(clip.start, clip.len()).copy_from(&smooth);
}

/// The per-frame RMS landmark error of `weights` on the frames `clip`, under the frames'
/// cameras (after the weights were changed by a temporal prior).
pub(super) fn recompute_rms(
    person: &Rig,
    track: &DMatrix<f64>,
    clip: Range<usize>,
    cameras: &[Camera],
    weights: &DMatrix<f64>,
    rms: &mut [f64],
) {
    let n = person.landmarks();
    for f in clip {
        let w: Vec<f64> = weights.column(f).iter().copied().collect();
        let u = frame_points(track, f);
        let e: f64 = person
            .posed(&w)
            .iter()
            .zip(&u)
            .map(|(p, q)| {
                let x = cameras[f].project(p);
                (x[0] - q[0]).powi(2) + (x[1] - q[1]).powi(2)
            })
            .sum();
        rms[f] = (e / n as f64).sqrt();
    }
}

/// One pass over the frames with the shapes `free`, each clip with its person's rig (warm
/// starts do not cross clips).
pub(super) fn run(
    rig: &Rig,
    (track, depth): (&DMatrix<f64>, Option<&DMatrix<f64>>),
    people: &[(Range<usize>, Rig)],
    free: Vec<usize>,
    opts: &RigOptions,
    lw: &[f64],
    iod: f64,
) -> Result<RigSolve> {
    let frames = track.ncols();
    let mut tzs = vec![0.0; frames];
    let n = rig.landmarks();
    let mut weights = DMatrix::zeros(rig.k(), frames);
    let (mut cameras, mut rms, mut steps) = (Vec::new(), Vec::new(), Vec::new());
    let mut unconverged = 0;
    let offline = opts.smooth > 0.0
        && opts.smooth_mode == keyshape_core::solve::temporal::SmoothMode::Offline;
    let (mut sweeps, mut sweeps_unconverged) = (0, 0);
    for (clip, person) in people {
        let mut fs = FrameSolver::new(person, free.clone(), opts.solver, opts.max_steps.max(1), lw);
        fs.lambda = if offline { 0.0 } else { opts.lambda(iod) };
        fs.ridge = magnitude_prior(iod, opts, rig, &fs.free);
        fs.pairs = exclusive_pairs(rig, &fs.free, &fs.ridge);
        fs.taper = tapering(rig, opts, &fs.free, &fs.ridge);
        for f in clip.clone() {
            let u = frame_points(track, f);
            fs.depth = frame_depth(depth, f);
            let (it, ok, e) = fs.solve(&u)?;
            tzs[f] = fs.tz;
            unconverged += usize::from(!ok);
            steps.push(it);
            rms.push((e / n as f64).sqrt());
            let w = fs.full_weights();
            if w.iter().any(|v| !v.is_finite()) {
                return Err(Error::unfit(format!(
                    "frame column {f}: the rig solve produced non-finite weights"
                )));
            }
            weights.column_mut(f).copy_from_slice(&w);
            fs.prev = Some(fs.w.clone());
            cameras.push(fs.cam.unwrap_or(Camera {
                s: 1.0,
                r: nalgebra::Matrix3::identity(),
                t: [0.0, 0.0],
            }));
        }
        if offline {
            let (n_sweeps, ok) = temporal::offline_prior(
                &mut fs,
                (track, depth),
                clip.clone(),
                (&cameras, &tzs),
                &mut weights,
                opts.lambda(iod),
            );
            sweeps = sweeps.max(n_sweeps);
            sweeps_unconverged += usize::from(!ok);
            recompute_rms(person, track, clip.clone(), &cameras, &weights, &mut rms);
        }
    }
    if opts.zero_phase > 0.0 {
        for (clip, person) in people {
            zero_phase(&mut weights, clip.clone(), opts.zero_phase);
            recompute_rms(person, track, clip.clone(), &cameras, &weights, &mut rms);
        }
    }
    Ok(RigSolve {
        weights,
        cameras,
        rms,
        steps,
        unconverged,
        lambda: opts.lambda(iod),
        sweeps,
        sweeps_unconverged,
        shapes: Vec::new(),
        neutrals: Vec::new(),
        neutral_views: Vec::new(),
        people: Vec::new(),
    })
}
