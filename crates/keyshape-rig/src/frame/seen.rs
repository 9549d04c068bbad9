//! What of a frame the solve sees: each landmark weighed by the tracker's confidence in
//! it (a landmark below the threshold left out), the camera fitted to the landmarks seen,
//! and the warm start dropped when the frame follows a gap.

use super::{Blocks, FrameSolver};
use crate::camera::{fit_camera, Camera};
use keyshape_core::error::Result;
use keyshape_core::solve::active_set::{Bound, Workspace};

/// A landmark's weight for the tracker's confidence `c` in it: `c`, or 0 below
/// [`MIN_CONFIDENCE`](keyshape_core::sequence::MIN_CONFIDENCE) (not seen).
fn confidence_weight(c: f64) -> f64 {
    if c >= keyshape_core::sequence::MIN_CONFIDENCE {
        c
    } else {
        0.0
    }
}

impl FrameSolver<'_> {
    /// Weighs the next frames' landmarks by the tracker's confidence in them (`None`: every
    /// landmark at its own weight): each landmark's weight times its confidence over the
    /// frame's mean confidence, a landmark
    /// below [`MIN_CONFIDENCE`](keyshape_core::sequence::MIN_CONFIDENCE) left out (weight
    /// 0). The Gram blocks are made anew only when the weights change.
    pub(crate) fn set_confidence(&mut self, conf: Option<&[f64]>) {
        let lw: Vec<f64> = match conf {
            None => self.base_lw.clone(),
            Some(c) => {
                // Relative to the frame's mean over the landmarks seen: the confidences
                // weigh the landmarks against each other, not the landmarks against the
                // priors (a tracker that is 0.8 sure of every point is no vaguer a face).
                let seen: Vec<f64> = c.iter().map(|&c| confidence_weight(c)).collect();
                let k = seen.iter().filter(|&&v| v > 0.0).count();
                let mean = seen.iter().sum::<f64>() / k.max(1) as f64;
                self.base_lw
                    .iter()
                    .zip(&seen)
                    .map(|(w, &v)| if v > 0.0 { w * (v / mean) } else { 0.0 })
                    .collect()
            }
        };
        let same = lw.len() == self.blocks.lw.len()
            && lw
                .iter()
                .zip(&self.blocks.lw)
                .all(|(a, b)| a.to_bits() == b.to_bits());
        if !same {
            let sub: Vec<Vec<[f64; 3]>> = self
                .free
                .iter()
                .map(|&s| self.rig.deltas[s].clone())
                .collect();
            self.blocks = Blocks::new(&sub, &lw);
        }
    }

    /// Drops the warm start: the next frame is solved as the first of a clip (weights from
    /// 0, the camera fitted anew, no last weights for the temporal prior).
    pub(crate) fn restart(&mut self) {
        let m = self.free.len();
        self.w = vec![0.0; m];
        self.state = vec![Bound::Lower; m];
        self.ws = Workspace::new(m);
        self.cam = None;
        self.prev = None;
    }

    /// The landmarks the solve sees (weight above 0): all of them unless a frame's
    /// confidences left some out.
    pub(crate) fn seen(&self) -> usize {
        self.blocks.lw.iter().filter(|&&w| w > 0.0).count()
    }

    /// The camera the steps start from: the posed rig fitted to the landmarks the solve
    /// sees (all of them, unless a frame's confidences left some out).
    pub(super) fn first_camera(&self, u: &[[f64; 2]]) -> Result<Camera> {
        let posed = self.posed_now();
        if self.blocks.lw.iter().all(|&w| w > 0.0) {
            return fit_camera(&posed, u);
        }
        let seen = |i: &usize| self.blocks.lw[*i] > 0.0;
        let x: Vec<[f64; 3]> = (0..posed.len()).filter(seen).map(|i| posed[i]).collect();
        let v: Vec<[f64; 2]> = (0..u.len()).filter(seen).map(|i| u[i]).collect();
        fit_camera(&x, &v)
    }
}

#[cfg(test)]
mod tests {
    /// Each landmark's weight is its own times its confidence over the mean of the
    /// confidences seen: a point not seen counts in neither, so a frame that is equally
    /// sure of every point it sees keeps the landmarks' own weights exactly.
    #[test]
    fn confidences_weigh_each_landmark_against_the_mean_of_those_seen() {
        let n = 5;
        let rig = crate::Rig {
            names: vec!["s0".into()],
            neutral: (0..n).map(|i| [i as f64, (i * i) as f64, 0.0]).collect(),
            deltas: vec![(0..n).map(|i| [0.1, 0.2 * i as f64, 0.0]).collect()],
            points: (0..n).collect(),
            layout: n,
        };
        let base = [1.0, 2.0, 0.5, 1.0, 3.0];
        let mut fs = super::FrameSolver::new(
            &rig,
            vec![0],
            keyshape_core::solve::Solver::Bounded,
            5,
            &base,
        );
        // Equally sure of the four it sees, the fifth not seen.
        fs.set_confidence(Some(&[0.7, 0.7, 0.7, 0.05, 0.7]));
        assert_eq!(fs.blocks.lw, [1.0, 2.0, 0.5, 0.0, 3.0]);
        assert_eq!(fs.seen(), 4);
        // Unequally: 0.9 and 0.3 over their mean 0.6.
        fs.set_confidence(Some(&[0.9, 0.3, 0.9, 0.3, 0.0]));
        let mean = (0.9 + 0.3 + 0.9 + 0.3) / 4.0;
        let want: Vec<f64> = [0.9, 0.3, 0.9, 0.3]
            .iter()
            .zip(&base)
            .map(|(c, w)| w * (c / mean))
            .chain([0.0])
            .collect();
        assert_eq!(fs.blocks.lw, want);
        fs.set_confidence(None);
        assert_eq!(fs.blocks.lw, base);
    }
}
