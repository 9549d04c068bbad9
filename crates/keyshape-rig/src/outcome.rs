//! What a rig solve gives: the weights, each shape's report, the people it used.

use crate::camera::Camera;
use crate::NeutralView;
use crate::Rig;
use nalgebra::DMatrix;
use std::ops::Range;

/// The `n` largest weights of one frame (at least 0.01), largest first, as "name .83"
/// — what a picture of the frame names.
pub fn largest_weights(names: &[String], w: &[f64], n: usize) -> String {
    let mut order: Vec<usize> = (0..w.len().min(names.len()))
        .filter(|&i| w[i] >= 0.01)
        .collect();
    order.sort_by(|&a, &b| w[b].total_cmp(&w[a]).then(a.cmp(&b)));
    order
        .iter()
        .take(n)
        .map(|&i| {
            format!(
                "{} {}",
                names[i],
                format!("{:.2}", w[i]).trim_start_matches('0')
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// How well a 2-D view determines one shape.
#[derive(Debug, Clone, PartialEq)]
pub struct ShapeReport {
    /// The rig's name for it.
    pub name: String,
    /// RMS landmark motion in the image at weight 1, in track units (px).
    pub image_motion: f64,
    /// `1 / (Gₖₖ (G⁻¹)ₖₖ)` over the shapes not frozen before it: 1 when no other shape moves
    /// the landmarks alike, 0 when others explain its motion entirely.
    pub determination: f64,
    /// Held at 0 by the solve.
    pub frozen: bool,
}

/// A rig solve of every frame.
#[derive(Debug, Clone)]
pub struct RigSolve {
    /// k × frames, in the rig's shape order (frozen shapes are 0).
    pub weights: DMatrix<f64>,
    /// Per frame, the fitted camera.
    pub cameras: Vec<Camera>,
    /// Per frame, RMS 2-D landmark error (track units).
    pub rms: Vec<f64>,
    /// Per frame, Gauss–Newton steps used.
    pub steps: Vec<u32>,
    /// Sweeps of the offline temporal prior (the most any clip took; 0 when it is off).
    pub sweeps: usize,
    /// Clips whose offline temporal prior stopped at [`temporal::MAX_SWEEPS`](crate::temporal::MAX_SWEEPS).
    pub sweeps_unconverged: usize,
    /// Frames whose steps stopped at the cap.
    pub unconverged: usize,
    /// The temporal prior's λ the solve used, in squared track units
    /// ([`RigOptions::lambda`](crate::RigOptions::lambda): a λ relative to the face resolved
    /// with its inter-ocular distance); 0 when it is off.
    pub lambda: f64,
    /// Per shape, identifiability.
    pub shapes: Vec<ShapeReport>,
    /// The neutral column of each clip's identity (empty with `Identity::None`; one with
    /// an explicit neutral).
    pub neutrals: Vec<usize>,
    /// Per entry of `neutrals`, how that frame looks (head pose, the expression the rig as
    /// it is sees in it); for a lead-in, its middle frame.
    pub neutral_views: Vec<NeutralView>,
    /// The rig each range of frames was solved with: the person's (the rig with the
    /// identity applied), or the rig itself with `Identity::None`.
    pub people: Vec<(Range<usize>, Rig)>,
}

impl RigSolve {
    /// The rig frame `f` was solved with (see [`RigSolve::people`]).
    pub fn person_of(&self, f: usize) -> Option<&Rig> {
        self.people
            .iter()
            .find(|(r, _)| r.contains(&f))
            .map(|(_, p)| p)
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_frame_names_its_largest_weights_largest_first() {
        let names: Vec<String> = ["a", "b", "c", "d"].iter().map(|s| s.to_string()).collect();
        assert_eq!(
            super::largest_weights(&names, &[0.2, 0.9, 0.005, 0.4], 3),
            "b .90, d .40, a .20"
        );
        assert_eq!(super::largest_weights(&names, &[0.0; 4], 3), "");
    }
}
