//! A person's calibration, as the live solve makes it and `--neutral-file` keeps it, and
//! the checks a saved one must pass.

use crate::{Identity, Rig};
use keyshape_core::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// A person's calibration: what the neutral lead-in taught the solve. Saved and loaded as
/// JSON (`kslab live --neutral-file`), so a session can start without looking neutral again.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Calibration {
    /// The track layout the rig reads (68, 468 or 478 points).
    pub layout: usize,
    /// The track points the rig reads, in landmark order.
    pub points: Vec<usize>,
    /// The rig's shape names.
    pub names: Vec<String>,
    /// The person's neutral landmarks (the rig's, moved by the lead-in's averaged residual).
    pub neutral: Vec<[f64; 3]>,
    /// The inter-ocular distance that scales the magnitude prior (track units).
    pub iod: f64,
    /// The shapes solved for, in rig order (the others are held at 0).
    pub free: Vec<usize>,
    /// Frames averaged into the neutral.
    pub frames: usize,
    /// The neutral head pose (yaw, pitch, roll in radians, as [`Camera::yaw_pitch_roll`](crate::camera::Camera::yaw_pitch_roll)):
    /// the lead-in's mean rotation, which the head's rotation is sent relative to
    /// ([`LiveFrame::head`](super::LiveFrame::head)). A calibration saved before it was kept reads as 0 (the pose
    /// as fitted).
    #[serde(default)]
    pub head: [f64; 3],
}

/// The inter-ocular distance a calibration may hold (track units: pixels, or a fraction of
/// the image for normalised coordinates). `1e308` froze the avatar (every weight 0) and
/// `1e-300` changed every weight.
pub const IOD: keyshape_core::limits::Limit = keyshape_core::limits::Limit {
    lo: 1e-4,
    lo_open: false,
    hi: 1e7,
    unit: "track units (pixels, or normalised coordinates)",
};

/// The largest distance between two of the rig's neutral landmarks along an axis.
fn rig_extent(points: &[[f64; 3]]) -> f64 {
    (0..3)
        .map(|a| {
            let (lo, hi) = points
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| {
                    (l.min(p[a]), h.max(p[a]))
                });
            hi - lo
        })
        .fold(0.0, f64::max)
}

impl Calibration {
    /// Whether the calibration can serve `rig` under an `identity`: made for its layout,
    /// points and shapes, its neutral a face near the rig's, its numbers in range.
    pub fn check(&self, rig: &Rig, identity: Identity) -> Result<()> {
        let bad = |what: String| Err(Error::invalid(format!("calibration: {what}")));
        if self.layout != rig.layout || self.points != rig.points {
            return bad(format!(
                "it was made for a {}-point track read at {} points; this rig reads a {}-point track at {}",
                self.layout,
                self.points.len(),
                rig.layout,
                rig.points.len()
            ));
        }
        if self.names != rig.names {
            return bad("its shape names are not this rig's".into());
        }
        if self.neutral.len() != rig.landmarks() {
            return bad(format!(
                "its neutral has {} landmarks; this rig has {}",
                self.neutral.len(),
                rig.landmarks()
            ));
        }
        if let Some((i, why)) = self.neutral.iter().enumerate().find_map(|(i, p)| {
            p.iter()
                .find_map(|&v| keyshape_core::sequence::coord_problem(v))
                .map(|w| (i, w))
        }) {
            return bad(format!("neutral landmark {i}: {why}"));
        }
        // The neutral as seen from the front (x, y), checked as a frame a neutral is made
        // from, and against this rig's own: the lifted identity moves a landmark by a
        // fraction of the face, never by the face's size.
        let front: Vec<f64> = self.neutral.iter().flat_map(|p| [p[0], p[1]]).collect();
        if let Some(why) = keyshape_core::sequence::face_problem(&front, 2) {
            return bad(format!("its neutral is not a face: {why}"));
        }
        let size = rig_extent(&rig.neutral);
        let moved = self
            .neutral
            .iter()
            .zip(&rig.neutral)
            .map(|(p, q)| {
                ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
            })
            .fold(0.0f64, f64::max);
        if !matches!(
            moved.partial_cmp(&(0.5 * size)),
            Some(std::cmp::Ordering::Less | std::cmp::Ordering::Equal)
        ) {
            return bad(format!(
                "its neutral lies up to {moved:.3} rig units from this rig's (a face {size:.3} across): it was made for another rig"
            ));
        }
        if let Some(a) = self
            .head
            .iter()
            .find(|a| !(a.is_finite() && a.abs() <= std::f64::consts::PI))
        {
            return bad(format!(
                "its neutral head pose holds {a}, not an angle within ±π"
            ));
        }
        if !IOD.contains(self.iod) {
            return bad(format!("the inter-ocular distance {}", IOD.why(self.iod)));
        }
        if self.free.windows(2).any(|w| w[0] >= w[1]) || self.free.iter().any(|&s| s >= rig.k()) {
            return bad(format!(
                "the free shapes must be increasing shape numbers below {}",
                rig.k()
            ));
        }
        if identity == Identity::Rbf {
            return bad(
                "a saved calibration holds the neutral only, an `offset` identity; this solve asks for rbf"
                    .into(),
            );
        }
        Ok(())
    }
}
