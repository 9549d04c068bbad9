//! The head motion that alignment removed, put back on the retargeted shapes (paper 000 §5).

use keyshape_core::align::Similarity;
use keyshape_core::error::{Error, Result};
use nalgebra::DMatrix;

/// Applies per-frame head motion to every column (paper 000 §5: "only scaled 2D translation
/// and rotation are applied to the output motion").
pub fn with_head_motion(
    shapes: &DMatrix<f64>,
    head: &[Similarity],
    dims: usize,
) -> Result<DMatrix<f64>> {
    if head.len() != shapes.ncols() {
        return Err(Error::invalid("head motion and frames differ in count"));
    }
    let cols: Vec<f64> = (0..shapes.ncols())
        .flat_map(|c| head[c].apply(shapes.column(c).as_slice(), dims))
        .collect();
    Ok(DMatrix::from_vec(shapes.nrows(), shapes.ncols(), cols))
}

/// Applies the source's head motion to shapes in another coordinate frame (a target face
/// with its own points): each frame's rotation and scale *relative to the first frame*
/// about the target's own centroid, and its translation relative to the first frame,
/// in units of the source's image size turned into the target's: × `size_ratio` (target
/// size / aligned source size) / the first frame's scale. Paper 000 §5: "only scaled 2D
/// translation and rotation are applied to the output motion".
pub fn with_relative_head_motion(
    shapes: &DMatrix<f64>,
    head: &[Similarity],
    dims: usize,
    size_ratio: f64,
) -> Result<DMatrix<f64>> {
    if head.len() != shapes.ncols() || head.is_empty() {
        return Err(Error::invalid("head motion and frames differ in count"));
    }
    let h0 = head[0];
    let mut out = shapes.clone();
    for (c, mut col) in out.column_iter_mut().enumerate() {
        let h = head[c];
        let rel = Similarity {
            scale: h.scale / h0.scale,
            angle: h.angle - h0.angle,
            t: [0.0; 3],
        };
        let n = (col.len() / dims).max(1);
        let mut centre = [0.0; 3];
        for p in col.as_slice().chunks(dims) {
            for d in 0..dims {
                centre[d] += p[d] / n as f64;
            }
        }
        let centred: Vec<f64> = col
            .as_slice()
            .chunks(dims)
            .flat_map(|p| (0..dims).map(move |d| p[d] - centre[d]))
            .collect();
        let moved = rel.apply(&centred, dims);
        for (i, v) in col.iter_mut().enumerate() {
            let d = i % dims;
            *v = moved[i] + centre[d] + size_ratio * (h.t[d] - h0.t[d]) / h0.scale;
        }
    }
    Ok(out)
}
