//! The depth a person's identity takes from the performance: one frame's residual, lifted
//! in that frame's image plane, has none; the head's turns over the clip show it. Fitted per
//! landmark (a depth along the neutral frame's view axis and a constant image offset) over
//! the frames the neutral search scores, under a prior ([`DEPTH_PRIOR`]).

use super::camera::fit_camera;
use super::frame::{frame_depth, frame_points, FrameSolver};
use super::identifiability::identifiability_weighted;
use super::prior::{exclusive_pairs, magnitude_prior};
use super::{Rig, RigOptions};
use keyshape_core::error::Result;
use nalgebra::DMatrix;

/// The prior on a landmark's depth, fitted over the neutral search's scored frames, as a share
/// of the rig's inter-ocular distance, for a landmark whose residual is one (squared) unit
/// per coordinate: the depth's prior variance is τ² = ([`DEPTH_PRIOR`] × IOD)² times the
/// landmark's mean squared residual, so a depth is believed where the solve explains the
/// landmark well and the head turns enough to show it. On the shipped real tracks a weaker
/// prior (0.1) took depth from expression (the built-in track's blinks fell from r 0.744 /
/// 0.783 to 0.681 / 0.694 against its lid gaps); on the benchmark's renders 0.01 and 0.1
/// give the same figures (docs/src/rig_accuracy.md).
pub const DEPTH_PRIOR: f64 = 0.01;

/// The rig's inter-ocular distance (outer eye corners), or a third of the neutral's width
/// when the rig does not read them.
fn rig_iod(rig: &Rig) -> f64 {
    let n = &rig.neutral;
    let d = |a: &[f64; 3], b: &[f64; 3]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>();
    let iod = match rig.eyes() {
        Some([a, b]) => d(&n[a], &n[b]).sqrt(),
        None => {
            let (lo, hi) = n
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| {
                    (l.min(p[0]), h.max(p[0]))
                });
            (hi - lo) / 3.0
        }
    };
    iod.max(f64::MIN_POSITIVE)
}

/// How well a person's rig lifted from one neutral frame explains the scored frames.
pub(super) struct NeutralFit {
    /// The (weighted) squared landmark error summed over the scored frames, less what each
    /// landmark's constant image offset and (without the track's own depth) its depth along
    /// the neutral frame's view axis explain.
    pub(super) residual: f64,
    /// Per landmark, that depth as an offset in the rig's frame (`None` when the track has
    /// depth: the identity takes the track's own).
    pub(super) offsets: Option<Vec<[f64; 3]>>,
}

/// Solves the `scored` frames (no temporal prior) with `person`, lifted from frame `n`,
/// and measures what is left once two things the single frame cannot give are fitted per
/// landmark over the frames: a constant image offset (frame `n`'s own landmark noise, which
/// the identity took up and every scored frame then leaves alike) and, for a track without
/// depth, a depth along `n`'s view axis (one frame sees none of it; a face deeper or
/// flatter than the rig's leaves a residual that grows with the head's turn away from
/// `n`'s pose), under the prior [`DEPTH_PRIOR`].
pub(super) fn fit_from(
    rig: &Rig,
    person: &Rig,
    (track, depth): (&DMatrix<f64>, Option<&DMatrix<f64>>),
    n: usize,
    scored: &[usize],
    opts: &RigOptions,
    lw: &[f64],
) -> Result<NeutralFit> {
    use nalgebra::{Matrix3, Vector3};
    // (Never causal: a causal solve is given its neutral.)
    let iod = super::prior::prior_iod(rig, track, opts, 0..1);
    let cam = fit_camera(&person.neutral, &frame_points(track, n))?;
    let shapes = identifiability_weighted(person, &cam, opts.min_determination, lw);
    let free: Vec<usize> = (0..rig.k()).filter(|&s| !shapes[s].frozen).collect();
    let mut fs = FrameSolver::new(person, free, opts.solver, opts.max_steps.max(1), lw);
    fs.ridge = magnitude_prior(iod, opts, rig, &fs.free);
    fs.pairs = exclusive_pairs(rig, &fs.free, &fs.ridge);
    let view = Vector3::new(cam.r[(2, 0)], cam.r[(2, 1)], cam.r[(2, 2)]);
    // Per landmark, the normal equations of (depth z, offset cx, cy), the image shift
    // z·a_f + c in frame f with a_f the view axis as frame f's camera draws it, against the
    // residual e (drawn − tracked); and Σ|e|².
    let mut eqs = vec![(Matrix3::<f64>::zeros(), Vector3::<f64>::zeros(), 0.0f64); lw.len()];
    let mut total = 0.0;
    for &f in scored {
        let u = frame_points(track, f);
        fs.depth = frame_depth(depth, f);
        fs.solve(&u)?;
        let cam_f = fs.cam.unwrap_or(cam);
        total += fs.sq_error_with(&cam_f, &u, lw);
        let a = (cam_f.r * view) * cam_f.s;
        let rows = [Vector3::new(a[0], 1.0, 0.0), Vector3::new(a[1], 0.0, 1.0)];
        for (i, (p, q)) in person.posed(&fs.full_weights()).iter().zip(&u).enumerate() {
            let drawn = cam_f.project(p);
            for (row, e) in rows.iter().zip([drawn[0] - q[0], drawn[1] - q[1]]) {
                eqs[i].0 += row * row.transpose();
                eqs[i].1 += row * e;
                eqs[i].2 += e * e;
            }
        }
    }
    let coords = (2 * scored.len()).max(1) as f64;
    let tau = DEPTH_PRIOR * rig_iod(rig);
    let mut explained = 0.0;
    let mut offsets = vec![[0.0; 3]; lw.len()];
    for (i, (m, b, sq)) in eqs.iter().enumerate() {
        // The depth's prior: σᵢ²/τ², σᵢ² the landmark's squared residual per coordinate.
        // With the track's depth, z is held at 0 (the identity has its depth).
        let prior = depth.is_none().then(|| (sq / coords) / (tau * tau));
        if let Some((z, gain)) = landmark_fit(m, b, *sq, prior) {
            explained += lw[i] * gain;
            offsets[i] = [z * view[0], z * view[1], z * view[2]];
        }
    }
    Ok(NeutralFit {
        residual: total - explained,
        offsets: depth.is_none().then_some(offsets),
    })
}

/// One landmark's fit over the scored frames, from its normal equations `m`, `b` in
/// (depth z, offset cx, cy) and its summed squared residual `sq`: the minimum of
/// |A x + e|² + prior·z² is at x = −M⁻¹b and explains bᵀM⁻¹b of `sq` (M with the prior
/// added to its depth entry). Returns the depth z and what it explains; with no prior
/// (`None`: the track has depth of its own) z is held at 0 and only the offset is fitted.
/// `None` when M is singular (no frame scored).
fn landmark_fit(
    m: &nalgebra::Matrix3<f64>,
    b: &nalgebra::Vector3<f64>,
    sq: f64,
    prior: Option<f64>,
) -> Option<(f64, f64)> {
    let mut m = *m;
    let mut b = *b;
    match prior {
        Some(p) => m[(0, 0)] += p + 1e-12 * m[(0, 0)].max(f64::MIN_POSITIVE),
        None => {
            m.row_mut(0).fill(0.0);
            m.column_mut(0).fill(0.0);
            m[(0, 0)] = 1.0;
            b[0] = 0.0;
        }
    }
    let x = m.cholesky()?.solve(&b);
    Some((-x[0], b.dot(&x).clamp(0.0, sq)))
}

#[cfg(test)]
mod tests {
    use super::{landmark_fit, rig_iod};
    use crate::accuracy::{render, Kind, Settings};
    use crate::neutral::{best_explaining, person_rig, person_rig_with};
    use crate::{Rig, RigOptions};
    use nalgebra::{Matrix3, Vector3};

    /// Brute force: one landmark's fit is the least-squares solution of the system written
    /// out (rows (a_f, 1, 0) and (a_f, 0, 1) against the residual, and the prior's row
    /// √p·(1, 0, 0) against 0), solved by SVD; what it explains is Σ|e|² less that
    /// minimum. With no prior the depth's column is dropped.
    #[test]
    fn a_landmarks_depth_and_offset_are_the_least_squares_solution() {
        use nalgebra::{DMatrix, DVector};
        let mut seed = 11u64;
        let mut rnd = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        for prior in [Some(0.0), Some(3.0), Some(40.0), None] {
            for _ in 0..5 {
                let frames = 7;
                let (mut rows, mut e) = (Vec::new(), Vec::new());
                for _ in 0..frames {
                    let a = [5.0 * rnd(), 5.0 * rnd()];
                    rows.push([a[0], 1.0, 0.0]);
                    rows.push([a[1], 0.0, 1.0]);
                    e.extend([rnd(), rnd()]);
                }
                let a = DMatrix::from_fn(rows.len(), 3, |r, c| rows[r][c]);
                let e = DVector::from_vec(e);
                let m = Matrix3::from_iterator((a.transpose() * &a).iter().copied());
                let b = Vector3::from_iterator((a.transpose() * &e).iter().copied());
                let sq = e.norm_squared();
                let (z, gain) = landmark_fit(&m, &b, sq, prior).unwrap();
                // The system written out, its first column dropped when z is held at 0.
                let cols: Vec<usize> = if prior.is_some() {
                    vec![0, 1, 2]
                } else {
                    vec![1, 2]
                };
                let extra = usize::from(prior.is_some());
                let big = DMatrix::from_fn(a.nrows() + extra, cols.len(), |r, c| {
                    if r < a.nrows() {
                        a[(r, cols[c])]
                    } else if cols[c] == 0 {
                        prior.unwrap().sqrt()
                    } else {
                        0.0
                    }
                });
                let rhs =
                    DVector::from_fn(
                        a.nrows() + extra,
                        |r, _| if r < e.len() { -e[r] } else { 0.0 },
                    );
                let x = big.clone().svd(true, true).solve(&rhs, 1e-14).unwrap();
                let left = (&big * &x - &rhs).norm_squared();
                let want_z = if prior.is_some() { x[0] } else { 0.0 };
                assert!(
                    (z - want_z).abs() < 1e-9,
                    "{prior:?}: z {z} against {want_z}"
                );
                assert!(
                    (gain - (sq - left)).abs() < 1e-9 * sq.max(1.0),
                    "{prior:?}: {gain} against {}",
                    sq - left
                );
            }
        }
        // No frame: nothing to fit.
        assert!(landmark_fit(&Matrix3::zeros(), &Vector3::zeros(), 0.0, None).is_none());
    }

    /// The rig's inter-ocular distance is its outer eye corners' distance (ICT: about 9 cm),
    /// and a third of the neutral's width when the rig reads no eye corner.
    #[test]
    fn the_rigs_inter_ocular_distance_is_its_eye_corners_distance() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let rig = Rig::read_ict(&dir.join("../../../shared/data/ict_facekit_face")).unwrap();
        let [a, b] = rig.eyes().unwrap();
        let (p, q) = (Vector3::from(rig.neutral[a]), Vector3::from(rig.neutral[b]));
        assert!((rig_iod(&rig) - (p - q).norm()).abs() < 1e-12);
        assert!((5.0..15.0).contains(&rig_iod(&rig)), "{}", rig_iod(&rig));
        let no_eyes = Rig {
            neutral: vec![[-3.0, 0.0, 1.0], [6.0, 2.0, 0.0], [0.0, -1.0, 4.0]],
            points: vec![1000, 1001, 1002],
            ..rig.clone()
        };
        assert!(no_eyes.eyes().is_none());
        assert!(
            (rig_iod(&no_eyes) - 3.0).abs() < 1e-12,
            "{}",
            rig_iod(&no_eyes)
        );
    }

    /// RMS distance between `a` and `b` after the similarity that best carries `a` onto `b`
    /// (Umeyama): the identity is lifted in the frame a fitted camera gives it, so only its
    /// shape is compared.
    fn shape_rms(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
        let n = a.len() as f64;
        let mean = |p: &[[f64; 3]]| {
            p.iter()
                .fold(Vector3::zeros(), |m, q| m + Vector3::from(*q))
                / n
        };
        let (ma, mb) = (mean(a), mean(b));
        let ca: Vec<Vector3<f64>> = a.iter().map(|q| Vector3::from(*q) - ma).collect();
        let cb: Vec<Vector3<f64>> = b.iter().map(|q| Vector3::from(*q) - mb).collect();
        let h: Matrix3<f64> = ca.iter().zip(&cb).map(|(x, y)| y * x.transpose()).sum();
        let svd = h.svd(true, true);
        let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
        let d = (u * vt).determinant().signum();
        let fix = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d));
        let r = u * fix * vt;
        let var: f64 = ca.iter().map(|x| x.norm_squared()).sum();
        let scale = (svd
            .singular_values
            .component_mul(&Vector3::new(1.0, 1.0, d)))
        .sum()
            / var;
        let sq: f64 = ca
            .iter()
            .zip(&cb)
            .map(|(x, y)| (r * x * scale - y).norm_squared())
            .sum();
        (sq / n).sqrt()
    }

    /// Against ground truth: renders of another person whose face is deeper or flatter than
    /// the rig's, the head turning ±35° yaw and ±20° pitch, no lead-in. The depth the search
    /// fits over the scored frames brings the identity lifted from the chosen frame closer to
    /// the rendered person's true neutral (compared as shapes) on every seed, and the search
    /// picks a frame whose true expression is no larger than with the depth left out.
    #[test]
    fn the_fitted_depth_brings_the_identity_towards_the_true_face() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let rig = Rig::read_ict(&dir.join("../../../shared/data/ict_facekit_face")).unwrap();
        let opts = RigOptions::recommended();
        let lw = crate::checks::check_options(&rig, &opts).unwrap();
        let mut gains = Vec::new();
        for seed in 1..=4 {
            let t = render(&rig, &Settings::turned_head(Kind::Smooth, seed)).unwrap();
            let clip = 0..t.points.ncols();
            let (n, offsets) = best_explaining(
                &rig,
                (&t.points, None),
                clip,
                &opts,
                (&lw, crate::NEUTRAL_SCORED_FRAMES),
            )
            .unwrap();
            let offsets = offsets.expect("a track without depth gets a fitted depth");
            let flat = person_rig(&rig, &t.points, None, n..n + 1, opts.identity).unwrap();
            let deep = person_rig_with(
                &rig,
                (&t.points, None),
                n..n + 1,
                opts.identity,
                Some(&offsets),
            )
            .unwrap();
            let (before, after) = (
                shape_rms(&flat.neutral, &t.person.neutral),
                shape_rms(&deep.neutral, &t.person.neutral),
            );
            assert!(after < before, "seed {seed}: {after} against {before}");
            gains.push(before / after);
        }
        gains.sort_by(f64::total_cmp);
        // Measured 2026-12-07: the identity's shape error falls by 1.04–1.06× on these seeds
        // (most of another person's difference is in the image plane, which one frame sees).
        assert!(gains[gains.len() / 2] > 1.02, "{gains:?}");
    }
}
