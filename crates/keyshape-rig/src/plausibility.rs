//! Plausibility of a real track's weights, where no ground truth exists: the track's own
//! geometry constrains them. Each eye's blink against that eye's lid gap over its width,
//! `jawOpen` against the inner lips' gap, the smiles against the mouth's width, each twin
//! pair on the frames where the face is symmetric, and how often each shape is on.
//!
//! The geometry is read from the 68 iBUG points of the track (a MediaPipe track's are taken
//! through [`crate::mediapipe_to_ibug68`] by the caller) in image axes, each distance over
//! the frame's inter-ocular distance (outer eye corners 36–45), so scale drops out. iBUG
//! 36–41 is the eye on the image's left, the subject's right on an unmirrored camera (the
//! rig's camera cannot mirror), so it goes with `eyeBlink_R`.

use keyshape_core::stats::correlation;
use nalgebra::DMatrix;
use serde::Serialize;
use std::ops::Range;

/// A shape's weight above which it counts as on.
pub const ON: f64 = 0.5;

/// One geometric check: a weight series against the track's measure of the same motion.
#[derive(Debug, Clone, Serialize)]
pub struct Agreement {
    /// The weight series: a shape, or shapes summed (`mouthSmile_L+R`).
    pub weights: String,
    /// What it is compared with.
    pub geometry: &'static str,
    /// Pearson r over the frames (0 when either series is constant).
    pub r: f64,
    /// The geometry's range over the track (its 95th − 5th percentile, in inter-ocular
    /// distances): a small range means the face hardly moved that way and r says little.
    pub geometry_range: f64,
}

/// A twin pair on the symmetric frames.
#[derive(Debug, Clone, Serialize)]
pub struct Twins {
    /// The pair's name without its side (`eyeBlink`).
    pub pair: String,
    /// The mean |w_L − w_R| over the frames whose region (eyes, mouth corners or brows) is
    /// more symmetric than the track's median for it.
    pub mean_gap: f64,
    /// The largest |w_L − w_R| over those frames.
    pub max_gap: f64,
}

/// The report of [`plausibility`].
#[derive(Debug, Clone, Serialize)]
pub struct Plausibility {
    /// Frames measured.
    pub frames: usize,
    /// Blinks, jaw and smiles against the geometry.
    pub agreements: Vec<Agreement>,
    /// Every twin pair of the rig, on the symmetric frames.
    pub twins: Vec<Twins>,
    /// Per shape, the share of frames above [`ON`], in the rig's order.
    pub on_rate: Vec<(String, f64)>,
}

fn dist(t: &DMatrix<f64>, f: usize, a: usize, b: usize) -> f64 {
    let dx = t[(2 * a, f)] - t[(2 * b, f)];
    let dy = t[(2 * a + 1, f)] - t[(2 * b + 1, f)];
    (dx * dx + dy * dy).sqrt()
}

/// The 68-point geometry of one frame, each length over the inter-ocular distance.
struct Geometry {
    /// Lid gap over eye width: the image-left eye (36–41), the image-right eye (42–47).
    open: [f64; 2],
    /// The inner lips' gap (62–66).
    lips: f64,
    /// The mouth's width (48–54).
    width: f64,
    /// Each mouth corner's height above the outer lips' middle (image y down; 48 and 54
    /// against 51–57).
    corners: [f64; 2],
    /// Each brow's middle above its eye's upper lid (19–37, 24–44).
    brows: [f64; 2],
}

fn geometry(t: &DMatrix<f64>, f: usize) -> Geometry {
    let iod = dist(t, f, 36, 45).max(f64::MIN_POSITIVE);
    let eye = |c0: usize, c1: usize, u: [usize; 2], l: [usize; 2]| {
        (dist(t, f, u[0], l[0]) + dist(t, f, u[1], l[1]))
            / (2.0 * dist(t, f, c0, c1).max(f64::MIN_POSITIVE))
    };
    let y = |p: usize| t[(2 * p + 1, f)];
    let mid = (y(51) + y(57)) / 2.0;
    Geometry {
        open: [
            eye(36, 39, [37, 38], [41, 40]),
            eye(42, 45, [43, 44], [47, 46]),
        ],
        lips: dist(t, f, 62, 66) / iod,
        width: dist(t, f, 48, 54) / iod,
        corners: [(mid - y(48)) / iod, (mid - y(54)) / iod],
        brows: [dist(t, f, 19, 37) / iod, dist(t, f, 24, 44) / iod],
    }
}

fn quantile(v: &[f64], q: f64) -> f64 {
    let mut s: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if s.is_empty() {
        return f64::NAN;
    }
    s.sort_by(f64::total_cmp);
    s[((q * (s.len() - 1) as f64).round() as usize).min(s.len() - 1)]
}

/// Each series centred on its clip's mean, so a correlation over clips of different people
/// compares motion within each clip, not one person's face against another's.
fn centred(v: &[f64], clips: &[Range<usize>]) -> Vec<f64> {
    let mut out = v.to_vec();
    for c in clips {
        let c = c.start.min(v.len())..c.end.min(v.len());
        let m = out[c.clone()].iter().sum::<f64>() / c.len().max(1) as f64;
        out[c].iter_mut().for_each(|x| *x -= m);
    }
    out
}

/// The plausibility of `weights` (k × frames, shapes named `names`) solved from `track68`
/// (136 × frames: the 68 iBUG points, image axes). `clips` (consecutive frame ranges, or
/// empty for one clip) may be different people: the correlations are taken within clips.
/// Shapes the rig does not have are left out of the checks.
pub fn plausibility(
    names: &[String],
    weights: &DMatrix<f64>,
    track68: &DMatrix<f64>,
    clips: &[Range<usize>],
) -> Plausibility {
    let frames = weights.ncols().min(track68.ncols());
    let whole = std::iter::once(0..frames).collect::<Vec<_>>();
    let clips = if clips.is_empty() { &whole[..] } else { clips };
    let g: Vec<Geometry> = (0..frames).map(|f| geometry(track68, f)).collect();
    let row = |name: &str| -> Option<Vec<f64>> {
        let s = names.iter().position(|n| n == name)?;
        Some((0..frames).map(|f| weights[(s, f)]).collect())
    };
    let mut agreements = Vec::new();
    let mut agree = |label: String, w: Vec<f64>, geometry: &'static str, x: Vec<f64>| {
        agreements.push(Agreement {
            weights: label,
            geometry,
            r: correlation(&centred(&w, clips), &centred(&x, clips)),
            geometry_range: quantile(&x, 0.95) - quantile(&x, 0.05),
        });
    };
    for (shape, eye, what) in [
        (
            "eyeBlink_L",
            1,
            "closure of the image-right eye (1 − lid gap / eye width, 42–47)",
        ),
        (
            "eyeBlink_R",
            0,
            "closure of the image-left eye (1 − lid gap / eye width, 36–41)",
        ),
    ] {
        if let Some(w) = row(shape) {
            agree(
                shape.to_string(),
                w,
                what,
                g.iter().map(|m| 1.0 - m.open[eye]).collect(),
            );
        }
    }
    if let Some(w) = row("jawOpen") {
        agree(
            "jawOpen".into(),
            w,
            "inner lips' gap (62–66)",
            g.iter().map(|m| m.lips).collect(),
        );
    }
    if let (Some(l), Some(r)) = (row("mouthSmile_L"), row("mouthSmile_R")) {
        let w = l.iter().zip(&r).map(|(a, b)| a + b).collect();
        agree(
            "mouthSmile_L+R".into(),
            w,
            "mouth width (48–54)",
            g.iter().map(|m| m.width).collect(),
        );
    }
    let twins = twins(names, weights, &g);
    let on_rate = names
        .iter()
        .enumerate()
        .map(|(s, n)| {
            let on = (0..frames).filter(|&f| weights[(s, f)] > ON).count();
            (n.clone(), on as f64 / frames.max(1) as f64)
        })
        .collect();
    Plausibility {
        frames,
        agreements,
        twins,
        on_rate,
    }
}

/// Each `_L` / `_R` pair of `names`, on the frames whose region (eyes, brows or mouth
/// corners, by the name) is more symmetric than the median in the geometry `g`: the mean
/// and largest |L − R| of their `weights`.
fn twins(names: &[String], weights: &DMatrix<f64>, g: &[Geometry]) -> Vec<Twins> {
    let asym = |name: &str, m: &Geometry| -> f64 {
        if name.starts_with("eye") {
            (m.open[0] - m.open[1]).abs()
        } else if name.starts_with("brow") {
            (m.brows[0] - m.brows[1]).abs()
        } else {
            (m.corners[0] - m.corners[1]).abs()
        }
    };
    let mut twins = Vec::new();
    for (s, n) in names.iter().enumerate() {
        let Some(base) = n.strip_suffix("_L") else {
            continue;
        };
        let Some(o) = names.iter().position(|m| *m == format!("{base}_R")) else {
            continue;
        };
        let a: Vec<f64> = g.iter().map(|m| asym(base, m)).collect();
        let median = quantile(&a, 0.5);
        let gaps: Vec<f64> = (0..g.len())
            .filter(|&f| a[f] <= median)
            .map(|f| (weights[(s, f)] - weights[(o, f)]).abs())
            .collect();
        if gaps.is_empty() {
            continue;
        }
        twins.push(Twins {
            pair: base.to_string(),
            mean_gap: gaps.iter().sum::<f64>() / gaps.len() as f64,
            max_gap: gaps.iter().copied().fold(0.0, f64::max),
        });
    }
    twins
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A hand-made 68-point face whose right-image eye closes, jaw opens and mouth widens
    /// on known frames: each weight that follows its motion gets r = 1, a weight that moves
    /// against it r = −1, and on-rates count frames above 0.5.
    #[test]
    fn each_check_reads_the_motion_it_names() {
        let frames = 6;
        let mut t = DMatrix::zeros(136, frames);
        let set = |f: usize, p: usize, x: f64, y: f64, t: &mut DMatrix<f64>| {
            t[(2 * p, f)] = x;
            t[(2 * p + 1, f)] = y;
        };
        for f in 0..frames {
            let k = f as f64;
            // Eyes: corners 36, 39 and 42, 45 on y = 0; lids 4 apart, the right one closing.
            for (c0, c1, u, l, x0, gap) in [
                (36, 39, [37, 38], [41, 40], 0.0, 4.0),
                (42, 45, [43, 44], [47, 46], 60.0, 4.0 - 0.5 * k),
            ] {
                set(f, c0, x0, 0.0, &mut t);
                set(f, c1, x0 + 30.0, 0.0, &mut t);
                for (i, (a, b)) in u.iter().zip(&l).enumerate() {
                    let x = x0 + 10.0 + 10.0 * i as f64;
                    set(f, *a, x, -gap / 2.0, &mut t);
                    set(f, *b, x, gap / 2.0, &mut t);
                }
            }
            // Mouth: width 40 + 2k, inner gap k.
            set(f, 48, 25.0 - k, 60.0, &mut t);
            set(f, 54, 65.0 + k, 60.0, &mut t);
            set(f, 51, 45.0, 55.0, &mut t);
            set(f, 57, 45.0, 65.0, &mut t);
            set(f, 62, 45.0, 60.0 - k / 2.0, &mut t);
            set(f, 66, 45.0, 60.0 + k / 2.0, &mut t);
            // Brows.
            set(f, 19, 15.0, -15.0, &mut t);
            set(f, 24, 75.0, -15.0, &mut t);
        }
        // The face nearer the camera frame by frame (scaled 1 + 0.25 f) and moved: every
        // measure is over the frame's own inter-ocular distance or eye width, so nothing
        // below changes (a measure left unnormalised would lose its r of ±1).
        for f in 0..frames {
            let z = 1.0 + 0.25 * f as f64;
            for p in 0..68 {
                t[(2 * p, f)] = z * t[(2 * p, f)] + 7.0 * f as f64;
                t[(2 * p + 1, f)] = z * t[(2 * p + 1, f)] - 3.0;
            }
        }
        let names: Vec<String> = [
            "eyeBlink_L",
            "eyeBlink_R",
            "jawOpen",
            "mouthSmile_L",
            "mouthSmile_R",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        let w = DMatrix::from_fn(5, frames, |s, f| match s {
            0 => f as f64 / 5.0,
            1 => 0.1 * ((f % 2) as f64),
            2 => 0.2 * f as f64,
            3 | 4 => 0.5 - 0.1 * f as f64,
            _ => 0.0,
        });
        let p = plausibility(&names, &w, &t, &[]);
        // Within clips: the same motion split in two clips, each offset, reads the same.
        let mut t2 = t.clone();
        for f in 3..frames {
            for p in 0..68 {
                t2[(2 * p + 1, f)] += 5.0;
            }
        }
        let p2 = plausibility(&names, &w, &t2, &[0..3, 3..frames]);
        let p1 = plausibility(&names, &w, &t, &[0..3, 3..frames]);
        for (a, b) in p1.agreements.iter().zip(&p2.agreements) {
            assert!((a.r - b.r).abs() < 1e-9, "{a:?} {b:?}");
        }
        let r = |n: &str| p.agreements.iter().find(|a| a.weights == n).unwrap().r;
        assert!((r("eyeBlink_L") - 1.0).abs() < 1e-9, "{p:?}");
        assert!((r("jawOpen") - 1.0).abs() < 1e-9, "{p:?}");
        assert!((r("mouthSmile_L+R") + 1.0).abs() < 1e-9, "{p:?}");
        // The left-image eye never moves: nothing to correlate, and its range says so.
        assert!(r("eyeBlink_R").abs() < 1e-9, "{p:?}");
        let right = p
            .agreements
            .iter()
            .find(|a| a.weights == "eyeBlink_R")
            .unwrap();
        assert_eq!(right.geometry_range, 0.0);
        let on = |n: &str| p.on_rate.iter().find(|x| x.0 == n).unwrap().1;
        // 0.6, 0.8 and 1.0 are on.
        assert_eq!(on("jawOpen"), 3.0 / 6.0);
        assert_eq!(on("eyeBlink_L"), 3.0 / 6.0);
        assert_eq!(on("mouthSmile_L"), 0.0);
        // Twins: the eyes' asymmetry grows with the frame, so the symmetric frames are 0–3
        // (at or below the median); the gaps there are 0, 0.1, 0.4 and 0.5.
        let tw = p.twins.iter().find(|t| t.pair == "eyeBlink").unwrap();
        assert!((tw.max_gap - 0.5).abs() < 1e-12, "{tw:?}");
        assert!((tw.mean_gap - 0.25).abs() < 1e-12, "{tw:?}");
        let smile = p.twins.iter().find(|t| t.pair == "mouthSmile").unwrap();
        assert_eq!(smile.max_gap, 0.0);
    }
}
