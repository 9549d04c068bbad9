//! The magnitude prior's parts: its scale (the track's inter-ocular distance), the gaze
//! shapes it holds harder, the mutually exclusive pairs, and which shapes it tapers for.

use super::{Rig, RigOptions};
use nalgebra::DMatrix;

/// The track's median distance between the outer eye corners (`eyes`: the two landmarks,
/// as [`Rig::eyes`] gives them; iBUG 36 and 45 on a 68-point track), the scale the
/// magnitude prior is given in.
pub fn track_iod(track: &DMatrix<f64>, eyes: [usize; 2]) -> f64 {
    let [a, b] = eyes;
    let mut d: Vec<f64> = (0..track.ncols())
        .map(|f| {
            let (dx, dy) = (
                track[(2 * b, f)] - track[(2 * a, f)],
                track[(2 * b + 1, f)] - track[(2 * a + 1, f)],
            );
            (dx * dx + dy * dy).sqrt()
        })
        .collect();
    d.sort_by(f64::total_cmp);
    d.get(d.len() / 2).copied().unwrap_or(0.0)
}

/// The inter-ocular distance that scales the magnitude prior: the track's median over
/// every frame, or, for a causal solve ([`RigOptions::causal`]), over the neutral frames
/// only (`neutral`), so that no frame still to come changes a frame's weights.
pub(super) fn prior_iod(
    rig: &Rig,
    track: &DMatrix<f64>,
    opts: &RigOptions,
    neutral: std::ops::Range<usize>,
) -> f64 {
    let Some(eyes) = rig.eyes() else {
        return 0.0;
    };
    if opts.causal {
        track_iod(
            &track.columns(neutral.start, neutral.len()).into_owned(),
            eyes,
        )
    } else {
        track_iod(track, eyes)
    }
}

/// How much more the magnitude prior holds the gaze shapes (`eyeLook*`) when the rig reads
/// no iris (iBUG 68, MediaPipe 468): eye gaze then moves the landmarks only through the
/// lids, and a free gaze shape explains lid and brow motion instead of the shapes that made
/// it. With iris centres (478 points) the gaze shapes are held like any other.
pub const GAZE_DAMPING: f64 = 100.0;

/// Is this a gaze shape (ARKit's eyeLookIn/Out/Up/Down)?
pub fn is_gaze(name: &str) -> bool {
    name.starts_with("eyeLook")
}

/// Pairs of shapes that undo each other and are rarely on together in a performance: the
/// jaw and the mouth to either side, smile against frown, blink against wide, and each eye's
/// gaze in against out and up against down (ARKit names, one side each), each with the
/// share of the full term, γ = 2√(μ_a μ_b), it pays for being on together.
///
/// Smile and frown pay a twentieth of it. Their landmark motions are far from opposite
/// (cosine −0.48 at 68 points, where blink and wide are −0.95 and jaw left and right
/// −0.99), so the landmarks tell a corner raised and lowered at once from a corner at rest,
/// and the full term only bends such frames: on the rig accuracy benchmark's smooth
/// performance, which raises both at random times, the worst shape's 10th percentile fell
/// to 0.564 against a ridge reference's 0.636 (0.679 at a twentieth). Dropping the pair
/// altogether turned `eyeWide_R` on for 42 % of the frames of the real track d18; a
/// twentieth leaves every real track's report within 0.006 of the full term's (the rig
/// accuracy chapter, "The hardest shape, against the reference").
pub const EXCLUSIVE: [(&str, &str, f64); 12] = [
    ("jawLeft", "jawRight", 1.0),
    ("mouthLeft", "mouthRight", 1.0),
    ("mouthSmile_L", "mouthFrown_L", SMILE_FROWN),
    ("mouthSmile_R", "mouthFrown_R", SMILE_FROWN),
    ("eyeBlink_L", "eyeWide_L", 1.0),
    ("eyeBlink_R", "eyeWide_R", 1.0),
    ("eyeLookIn_L", "eyeLookOut_L", 1.0),
    ("eyeLookIn_R", "eyeLookOut_R", 1.0),
    ("eyeLookUp_L", "eyeLookDown_L", 1.0),
    ("eyeLookUp_R", "eyeLookDown_R", 1.0),
    ("mouthRollLower", "mouthShrugLower", 1.0),
    ("mouthRollUpper", "mouthShrugUpper", 1.0),
];

/// The smile / frown pairs' share of the full exclusive term (see [`EXCLUSIVE`]).
const SMILE_FROWN: f64 = 0.05;

/// The [`EXCLUSIVE`] pairs among the free shapes, as free indices with their γ: the pair's
/// share of 2√(μ_a μ_b).
pub(super) fn exclusive_pairs(
    rig: &Rig,
    free: &[usize],
    ridge: &[f64],
) -> Vec<(usize, usize, f64)> {
    let at = |name: &str| free.iter().position(|&s| rig.names[s] == name);
    EXCLUSIVE
        .iter()
        .filter_map(|&(a, b, share)| {
            let (a, b) = (at(a)?, at(b)?);
            Some((a, b, share * 2.0 * (ridge[a] * ridge[b]).sqrt()))
        })
        .filter(|p| p.2 > 0.0)
        .collect()
}

/// Per free shape (`free`, rig order), the magnitude prior's μ: `opts.prior × IOD²`, times
/// [`GAZE_DAMPING`] for gaze shapes.
pub(super) fn magnitude_prior(iod: f64, opts: &RigOptions, rig: &Rig, free: &[usize]) -> Vec<f64> {
    // solve_rig refuses a prior without the eye corners, whose distance `iod` is.
    let mu = if rig.eyes().is_some() {
        opts.prior * iod.powi(2)
    } else {
        0.0
    };
    let damp = !rig.sees_pupils();
    free.iter()
        .map(|&s| {
            if damp && is_gaze(&rig.names[s]) {
                GAZE_DAMPING * mu
            } else {
                mu
            }
        })
        .collect()
}

/// Per free shape, does its magnitude prior taper ([`RigOptions::taper`])? Every shape with
/// a prior but the gaze shapes [`GAZE_DAMPING`] holds.
pub(super) fn tapering(rig: &Rig, opts: &RigOptions, free: &[usize], ridge: &[f64]) -> Vec<bool> {
    let damped = !rig.sees_pupils();
    free.iter()
        .zip(ridge)
        .map(|(&s, &mu)| opts.taper && mu > 0.0 && !(damped && is_gaze(&rig.names[s])))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::tapering;
    use crate::{Rig, RigOptions};

    fn rig(layout: usize, points: Vec<usize>) -> Rig {
        let names = ["eyeLookIn_L", "jawOpen", "mouthSmile_L"];
        let n = points.len();
        Rig {
            names: names.iter().map(|s| s.to_string()).collect(),
            neutral: vec![[0.0; 3]; n],
            deltas: vec![vec![[0.0; 3]; n]; names.len()],
            points,
            layout,
        }
    }

    /// The taper frees every shape with a prior but the gaze shapes the damping holds (no
    /// iris in the track); with the iris centres the gaze shapes taper too; a shape with no
    /// prior (μ = 0) has nothing to taper; and `taper: false` tapers none.
    #[test]
    fn the_taper_spares_the_held_gaze_and_shapes_without_a_prior() {
        let opts = RigOptions {
            taper: true,
            ..RigOptions::default()
        };
        let free = [0, 1, 2];
        let no_iris = rig(68, (0..68).collect());
        assert_eq!(
            tapering(&no_iris, &opts, &free, &[100.0, 1.0, 1.0]),
            [false, true, true]
        );
        assert_eq!(
            tapering(&no_iris, &opts, &free, &[100.0, 0.0, 1.0]),
            [false, false, true]
        );
        let irises = rig(478, (0..468).chain([468, 473]).collect());
        assert!(irises.sees_pupils());
        assert_eq!(
            tapering(&irises, &opts, &free, &[1.0, 1.0, 1.0]),
            [true, true, true]
        );
        let off = RigOptions {
            taper: false,
            ..opts
        };
        assert_eq!(
            tapering(&irises, &off, &free, &[1.0, 1.0, 1.0]),
            [false, false, false]
        );
    }
}
