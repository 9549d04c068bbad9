//! Example frames for the actions of paper 002 (§3.1: the artificial training sets are
//! built from one frame per action): each action's example is the frame where a simple
//! geometric measure, normalised by the inter-ocular distance (so that the head's distance
//! from the camera does not matter), is extreme.
//!
//! | action | measure |
//! | --- | --- |
//! | `jaw_drop` | max inner-lip gap |
//! | `smile` / `pucker` | max / min mouth width (corner to corner) |
//! | `brow_raise_*` / `brow_lower_*` | max / min brow-to-eye height (brow centroid above eye centroid) |
//! | `eyes_wide` / `blink` | max / min mean eyelid gap |
//!
//! The same rule as `tools/choose_actions.py` (which made the shipped files), on MediaPipe
//! (468 or 478 points) and iBUG-68 tracks.

use super::modes::{Action, Actions};
use keyshape_core::error::{Error, Result};
use keyshape_core::sequence::Sequence;

/// The landmarks each measure reads, per layout.
struct Marks {
    iod: (usize, usize),
    lip_gap: (usize, usize),
    corners: (usize, usize),
    left_brow: &'static [usize],
    right_brow: &'static [usize],
    left_eye: &'static [usize],
    right_eye: &'static [usize],
    /// Upper/lower lid pairs, both eyes.
    lids: &'static [(usize, usize)],
}

const MEDIAPIPE: Marks = Marks {
    iod: (33, 263),
    lip_gap: (13, 14),
    corners: (61, 291),
    left_brow: &[276, 283, 282, 295, 285, 300, 293, 334, 296, 336],
    right_brow: &[46, 53, 52, 65, 55, 70, 63, 105, 66, 107],
    left_eye: &[
        263, 249, 390, 373, 374, 380, 381, 382, 362, 398, 384, 385, 386, 387, 388, 466,
    ],
    right_eye: &[
        33, 7, 163, 144, 145, 153, 154, 155, 133, 173, 157, 158, 159, 160, 161, 246,
    ],
    lids: &[(159, 145), (386, 374)],
};

const IBUG68: Marks = Marks {
    iod: (36, 45),
    lip_gap: (62, 66),
    corners: (48, 54),
    left_brow: &[22, 23, 24, 25, 26],
    right_brow: &[17, 18, 19, 20, 21],
    left_eye: &[42, 43, 44, 45, 46, 47],
    right_eye: &[36, 37, 38, 39, 40, 41],
    lids: &[(37, 41), (38, 40), (43, 47), (44, 46)],
};

/// What [`choose_actions`] says about how it chose.
pub const HOW_CHOSEN: &str = "kslab actions: each action's example is the frame where a measure normalised by the inter-ocular distance is extreme: jaw_drop max inner-lip gap; smile max and pucker min mouth width; brow_raise/brow_lower max/min brow-to-eye height (centroids) per side; eyes_wide max and blink min mean eyelid gap";

/// One example frame per action of `seq` (2-D image coordinates, y down; MediaPipe 468/478
/// or iBUG 68 points), named by the file's frame numbers. `sequence` is recorded in the
/// file, so that the actions are later checked against the track they are used with.
pub fn choose_actions(seq: &Sequence, sequence: &str) -> Result<Actions> {
    let m = match seq.points {
        468 | 478 => &MEDIAPIPE,
        68 => &IBUG68,
        n => {
            return Err(Error::file(
                &seq.source,
                format!("actions are chosen on MediaPipe (468 or 478 points) or iBUG-68 tracks, not {n} points"),
            ))
        }
    };
    let d = seq.dims;
    let n = seq.n_frames();
    let p = |t: usize, i: usize| [seq.coords[(d * i, t)], seq.coords[(d * i + 1, t)]];
    let dist = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
    let cy =
        |t: usize, idx: &[usize]| idx.iter().map(|&i| p(t, i)[1]).sum::<f64>() / idx.len() as f64;
    let mut measures: [Vec<f64>; 5] = Default::default();
    for t in 0..n {
        let iod = dist(p(t, m.iod.0), p(t, m.iod.1));
        if iod.is_nan() || iod <= 0.0 {
            return Err(Error::file(
                &seq.source,
                format!(
                    "frame {}: the outer eye corners coincide (no inter-ocular distance)",
                    seq.frames[t]
                ),
            ));
        }
        let lid = m
            .lids
            .iter()
            .map(|&(a, b)| dist(p(t, a), p(t, b)))
            .sum::<f64>()
            / m.lids.len() as f64;
        measures[0].push(dist(p(t, m.lip_gap.0), p(t, m.lip_gap.1)) / iod);
        measures[1].push(dist(p(t, m.corners.0), p(t, m.corners.1)) / iod);
        measures[2].push((cy(t, m.left_eye) - cy(t, m.left_brow)) / iod);
        measures[3].push((cy(t, m.right_eye) - cy(t, m.right_brow)) / iod);
        measures[4].push(lid / iod);
    }
    // The frame where `sign × measure` is largest (the first such frame).
    let frame = |k: usize, sign: f64| {
        let best = (0..n)
            .max_by(|&a, &b| {
                (sign * measures[k][a])
                    .total_cmp(&(sign * measures[k][b]))
                    .then(b.cmp(&a))
            })
            .unwrap_or(0);
        seq.frames[best]
    };
    let acts = [
        ("jaw_drop", "lower_face", frame(0, 1.0)),
        ("smile", "lower_face", frame(1, 1.0)),
        ("pucker", "lower_face", frame(1, -1.0)),
        ("brow_raise_left", "left_brow", frame(2, 1.0)),
        ("brow_lower_left", "left_brow", frame(2, -1.0)),
        ("brow_raise_right", "right_brow", frame(3, 1.0)),
        ("brow_lower_right", "right_brow", frame(3, -1.0)),
        ("eyes_wide", "forehead", frame(4, 1.0)),
        ("blink", "forehead", frame(4, -1.0)),
    ];
    Ok(Actions {
        kslab_actions: 1,
        sequence: sequence.to_string(),
        how_chosen: HOW_CHOSEN.to_string(),
        actions: acts
            .iter()
            .map(|&(name, region, frame)| Action {
                name: name.into(),
                region: region.into(),
                frame,
            })
            .collect(),
    })
}
