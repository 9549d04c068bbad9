//! The scaled orthographic camera of a rig solve: `u = s R₂ X + t`, with `X` in the rig's
//! frame (x the subject's left, y up, z out of the face) and `u` in image axes with y turned
//! up (`(x, −y)` of the track), so a frontal face has `R = I`.

use keyshape_core::error::{Error, Result};
use nalgebra::{Matrix2x3, Matrix3, Vector3};

/// The rotation nearest to `m`, found in a bounded number of steps: nalgebra's
/// `from_matrix` iterates until it converges, which a matrix of huge or non-finite entries
/// never does (a landmark at 1e200 hung the frame solver in it, beyond any signal).
pub fn rotation_of(m: &Matrix3<f64>) -> nalgebra::Rotation3<f64> {
    // The nearest rotation of `c m` is that of `m` for any c > 0: a matrix of huge or tiny
    // entries is scaled to entries of at most 1 (an ordinary one, a product of rotations,
    // is taken as it is, bit for bit as before), so nothing overflows on the way.
    let big = m.amax();
    if !(big.is_finite() && big > 0.0) {
        return nalgebra::Rotation3::identity();
    }
    let scaled;
    let m = if (1e-100..=1e100).contains(&big) {
        m
    } else {
        scaled = m / big;
        &scaled
    };
    let r =
        nalgebra::Rotation3::from_matrix_eps(m, f64::EPSILON, 100, nalgebra::Rotation3::identity());
    if r.matrix().iter().all(|v| v.is_finite()) {
        r
    } else {
        nalgebra::Rotation3::identity()
    }
}

/// A scaled orthographic projection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Scale: image units per rig unit.
    pub s: f64,
    /// Head rotation (rows: image x, image y-up, view direction).
    pub r: Matrix3<f64>,
    /// Image translation (x, y-up).
    pub t: [f64; 2],
}

impl Camera {
    /// The projection of a rig point, in image axes with y up.
    pub fn project(&self, x: &[f64; 3]) -> [f64; 2] {
        let v = Vector3::new(x[0], x[1], x[2]);
        [
            self.s * self.r.row(0).dot(&v.transpose()) + self.t[0],
            self.s * self.r.row(1).dot(&v.transpose()) + self.t[1],
        ]
    }

    /// The depth of a rig point towards the viewer, `s r₃·x` (no offset: a track's depth
    /// has an origin of its own).
    pub fn depth(&self, x: &[f64; 3]) -> f64 {
        self.s * (self.r[(2, 0)] * x[0] + self.r[(2, 1)] * x[1] + self.r[(2, 2)] * x[2])
    }

    /// The camera a fraction `alpha` of the way from this one to `other` (scale and
    /// translation linearly, rotation along the geodesic).
    pub fn toward(&self, other: &Camera, alpha: f64) -> Camera {
        let rel = rotation_of(&(self.r.transpose() * other.r));
        let step = rel.scaled_axis() * alpha;
        Camera {
            s: self.s + alpha * (other.s - self.s),
            r: self.r * nalgebra::Rotation3::new(step).matrix(),
            t: [
                self.t[0] + alpha * (other.t[0] - self.t[0]),
                self.t[1] + alpha * (other.t[1] - self.t[1]),
            ],
        }
    }

    /// The head's yaw, pitch and roll relative to a neutral pose `neutral` (its yaw, pitch
    /// and roll): the rotation `R₀ᵀ R` that takes the neutral head to this one, in the
    /// head's own axes, so a person who turns about their own neck turns by a yaw alone
    /// whatever the camera's tilt.
    pub fn relative_to(&self, neutral: [f64; 3]) -> [f64; 3] {
        let r0 = Camera::from_angles(1.0, neutral[0], neutral[1], neutral[2], [0.0; 2]).r;
        Camera {
            s: 1.0,
            r: r0.transpose() * self.r,
            t: [0.0; 2],
        }
        .yaw_pitch_roll()
    }

    /// The mean head pose of `cameras` (yaw, pitch, roll as [`Camera::yaw_pitch_roll`]):
    /// the rotation nearest their rotations' sum — a calibration's neutral pose.
    pub fn mean_pose<'a>(cameras: impl IntoIterator<Item = &'a Camera>) -> [f64; 3] {
        let sum = cameras
            .into_iter()
            .fold(Matrix3::zeros(), |acc, c| acc + c.r);
        Camera {
            s: 1.0,
            r: rotation_of(&sum).into_inner(),
            t: [0.0; 2],
        }
        .yaw_pitch_roll()
    }

    /// A camera from head angles in radians (see [`Camera::yaw_pitch_roll`]).
    pub fn from_angles(s: f64, yaw: f64, pitch: f64, roll: f64, t: [f64; 2]) -> Camera {
        let (sa, ca) = yaw.sin_cos();
        let (sb, cb) = pitch.sin_cos();
        let (sc, cc) = roll.sin_cos();
        let ry = Matrix3::new(ca, 0.0, sa, 0.0, 1.0, 0.0, -sa, 0.0, ca);
        let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, cb, -sb, 0.0, sb, cb);
        let rz = Matrix3::new(cc, -sc, 0.0, sc, cc, 0.0, 0.0, 0.0, 1.0);
        Camera {
            s,
            r: ry * rx * rz,
            t,
        }
    }

    /// Head yaw (about the rig's up axis; positive turns the face towards image +x),
    /// pitch (about the rig's x axis; positive tips the face down, forehead forward) and roll (in the image
    /// plane; positive counter-clockwise as seen, y up), in radians: `R = R_y(yaw) R_x(pitch)
    /// R_z(roll)`.
    pub fn yaw_pitch_roll(&self) -> [f64; 3] {
        let r = &self.r;
        let pitch = (-r[(1, 2)]).clamp(-1.0, 1.0).asin();
        let yaw = r[(0, 2)].atan2(r[(2, 2)]);
        let roll = r[(1, 0)].atan2(r[(1, 1)]);
        [yaw, pitch, roll]
    }
}

/// Fits a scaled orthographic camera to 2-D points `u` (y up) of rig points `x`: the affine
/// least-squares camera, then the nearest one with orthonormal rows (eos's
/// `estimate_orthographic_projection_linear`): exact when `u` is an exact scaled orthographic
/// view of `x`.
pub fn fit_camera(x: &[[f64; 3]], u: &[[f64; 2]]) -> Result<Camera> {
    let n = x.len();
    if n < 4 || u.len() != n {
        return Err(Error::invalid(format!(
            "camera fit: {n} rig points against {} image points (need the same, at least 4)",
            u.len()
        )));
    }
    let mx = x
        .iter()
        .fold(Vector3::zeros(), |a, p| a + Vector3::from(*p))
        / n as f64;
    let (mut mu0, mut mu1) = (0.0, 0.0);
    for p in u {
        mu0 += p[0] / n as f64;
        mu1 += p[1] / n as f64;
    }
    let mut xx = Matrix3::zeros();
    let mut ux = Matrix2x3::zeros();
    for (p, q) in x.iter().zip(u) {
        let d = Vector3::from(*p) - mx;
        xx += d * d.transpose();
        let e = nalgebra::Vector2::new(q[0] - mu0, q[1] - mu1);
        ux += e * d.transpose();
    }
    let inv = xx
        .try_inverse()
        .ok_or_else(|| Error::unfit("camera fit: the rig's landmarks are coplanar"))?;
    let a = ux * inv;
    // A view with no extent (its points coincide, or lie so close that their squares
    // underflow) has no camera; nalgebra's SVD would panic on what it gives.
    if !(a.iter().all(|v| v.is_finite()) && a.norm() > 0.0) {
        return Err(Error::unfit(
            "camera fit: the image points have no extent (they coincide)",
        ));
    }
    let svd = a.svd(true, true);
    let (Some(uu), Some(vt)) = (svd.u, svd.v_t) else {
        return Err(Error::unfit("camera fit: SVD failed"));
    };
    let r2 = uu * vt; // 2×2 · 2×3: the nearest matrix with orthonormal rows
    let r0 = Vector3::new(r2[(0, 0)], r2[(0, 1)], r2[(0, 2)]);
    let r1 = Vector3::new(r2[(1, 0)], r2[(1, 1)], r2[(1, 2)]);
    let r3 = r0.cross(&r1);
    let r = Matrix3::from_rows(&[r0.transpose(), r1.transpose(), r3.transpose()]);
    // The least-squares scale for these rows.
    let (mut num, mut den) = (0.0, 0.0);
    for (p, q) in x.iter().zip(u) {
        let d = Vector3::from(*p) - mx;
        let (a0, a1) = (r0.dot(&d), r1.dot(&d));
        num += a0 * (q[0] - mu0) + a1 * (q[1] - mu1);
        den += a0 * a0 + a1 * a1;
    }
    if den.is_nan() || den <= 0.0 || !num.is_finite() {
        return Err(Error::unfit("camera fit: degenerate points"));
    }
    let s = num / den;
    let t = [mu0 - s * r0.dot(&mx), mu1 - s * r1.dot(&mx)];
    Ok(Camera { s, r, t })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// Relative to its own angles a pose is no turn; a head pitched by a camera above it
    /// that then turns about its own neck turns by a yaw alone.
    #[test]
    fn a_pose_relative_to_a_neutral_is_the_turn_in_the_heads_own_axes() {
        let n = [0.2, 0.3, -0.1];
        let c = Camera::from_angles(2.0, n[0], n[1], n[2], [1.0, 2.0]);
        for v in c.relative_to(n) {
            assert!(v.abs() < 1e-12);
        }
        let turn = Camera::from_angles(1.0, 0.4, 0.0, 0.0, [0.0; 2]);
        let pitched = Camera::from_angles(1.0, 0.0, 0.3, 0.0, [0.0; 2]);
        let turned = Camera {
            s: 1.0,
            r: pitched.r * turn.r,
            t: [0.0; 2],
        };
        let rel = turned.relative_to([0.0, 0.3, 0.0]);
        assert!(
            (rel[0] - 0.4).abs() < 1e-12 && rel[1].abs() < 1e-12 && rel[2].abs() < 1e-12,
            "{rel:?}"
        );
        // Its absolute angles mix the two.
        assert!(turned.yaw_pitch_roll()[2].abs() > 0.05);
    }

    /// nalgebra's `from_matrix` never returns on these (it iterates until convergence);
    /// `rotation_of` answers each with a rotation.
    #[test]
    fn the_nearest_rotation_of_any_matrix_is_found_in_bounded_steps() {
        let a = Camera::from_angles(1.0, 0.3, -0.2, 0.1, [0.0, 0.0]);
        for v in [
            1e200,
            -1e300,
            f64::MAX,
            f64::MIN_POSITIVE,
            0.0,
            f64::NAN,
            f64::INFINITY,
        ] {
            let mut m = a.r;
            m[(0, 1)] = v;
            let r = rotation_of(&m);
            let rtr = r.matrix().transpose() * r.matrix();
            assert!((rtr - Matrix3::identity()).norm() < 1e-9, "{v:e}: {r:?}");
            let b = Camera { r: m, ..a };
            let c = a.toward(&b, 0.5);
            assert!(c.r.iter().all(|x| x.is_finite()), "{v:e}");
        }
        // An ordinary matrix: the rotation itself.
        assert!((rotation_of(&a.r).matrix() - a.r).norm() < 1e-12);
    }
}
