//! Which shapes a 2-D view of the rig's landmarks can tell apart: per-shape image motion
//! and determination by a pivoted Cholesky factorisation of the Gram matrix.

use super::camera::Camera;
use super::frame::Blocks;
use super::{Rig, ShapeReport};
use nalgebra::DMatrix;

/// Per-shape image motion and determination at camera `cam`. Shapes are taken greedily by a
/// pivoted Cholesky factorisation of the Gram matrix: at each step the shape with the most
/// image motion left unexplained by the shapes already taken, while that share is at least
/// `min_det`; the rest are frozen (a 2-D view cannot tell them from the taken ones). A shape's
/// determination is then `1 / (Gₖₖ (G⁻¹)ₖₖ)` against every taken shape but itself (for a
/// frozen shape: against all taken shapes).
pub fn identifiability(rig: &Rig, cam: &Camera, min_det: f64) -> Vec<ShapeReport> {
    identifiability_weighted(rig, cam, min_det, &vec![1.0; rig.landmarks()])
}

/// [`identifiability`] with each landmark's squared motion weighted by `lw` (as the solve
/// weights its error): image motion is then the weighted RMS.
pub fn identifiability_weighted(
    rig: &Rig,
    cam: &Camera,
    min_det: f64,
    lw: &[f64],
) -> Vec<ShapeReport> {
    let k = rig.k();
    let blocks = Blocks::new(&rig.deltas, lw);
    let mut g = vec![0.0; k * k];
    blocks.gram(cam, 0.0, &mut g);
    let total: f64 = lw.iter().sum();
    let motion: Vec<f64> = (0..k).map(|i| (g[i * k + i] / total).sqrt()).collect();
    // Pivoted Cholesky: `l` holds the taken shapes' columns of the factor.
    let mut resid: Vec<f64> = (0..k).map(|i| g[i * k + i]).collect();
    let mut taken: Vec<usize> = Vec::new();
    let mut l: Vec<Vec<f64>> = Vec::new();
    loop {
        let pick = (0..k)
            .filter(|i| !taken.contains(i) && g[i * k + i] > 0.0)
            .map(|i| (i, resid[i] / g[i * k + i]))
            .filter(|&(_, share)| share >= min_det.max(1e-12))
            // Ties go to the rig's earlier shape.
            .max_by(|a, b| resid[a.0].total_cmp(&resid[b.0]).then(b.0.cmp(&a.0)));
        let Some((p, _)) = pick else { break };
        let d = resid[p].sqrt();
        let col: Vec<f64> = (0..k)
            .map(|i| {
                let v = g[i * k + p] - l.iter().map(|c| c[i] * c[p]).sum::<f64>();
                v / d
            })
            .collect();
        for i in 0..k {
            resid[i] -= col[i] * col[i];
        }
        l.push(col);
        taken.push(p);
    }
    let frozen: Vec<bool> = (0..k).map(|i| !taken.contains(&i)).collect();
    let det: Vec<f64> = (0..k)
        .map(|i| {
            let others: Vec<usize> = taken.iter().copied().filter(|&j| j != i).collect();
            let gii = g[i * k + i];
            if gii.is_nan() || gii <= 0.0 {
                return 0.0;
            }
            if others.is_empty() {
                return 1.0;
            }
            // 1 − (explained share) = residual of column i against the others, over Gᵢᵢ.
            let m = others.len();
            let sub = DMatrix::from_fn(m, m, |a, b| g[others[a] * k + others[b]]);
            let rhs = nalgebra::DVector::from_fn(m, |a, _| g[others[a] * k + i]);
            match sub.cholesky() {
                Some(c) => {
                    let x = c.solve(&rhs);
                    ((gii - rhs.dot(&x)) / gii).clamp(0.0, 1.0)
                }
                None => 0.0,
            }
        })
        .collect();
    (0..k)
        .map(|i| ShapeReport {
            name: rig.names[i].clone(),
            image_motion: motion[i],
            determination: det[i],
            frozen: frozen[i],
        })
        .collect()
}
