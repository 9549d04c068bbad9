//! Generalised Procrustes alignment with a 2-D similarity (translation, rotation, uniform
//! scale). The removed motion is kept per frame as a [`Similarity`] so retargeting can put
//! it back (paper 000, §5: "2D head motion").
//!
//! For 3-D shapes the similarity acts in the image (x, y) plane; z is centred and scaled
//! by the same factor. Aligned shapes are centred on the origin and keep the mean size of
//! the input shapes, so errors measured on them stay in the input's units.

use crate::error::{setting, Error, Result};
use nalgebra::{DMatrix, DVector};

/// A 2-D similarity `p = scale · R(angle) · a + t` taking an aligned shape `a` back to
/// where the tracker saw it.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Similarity {
    /// Uniform scale.
    pub scale: f64,
    /// Rotation in radians (counter-clockwise in x-right, y-up axes).
    pub angle: f64,
    /// Translation (x, y, z; z is 0 for 2-D shapes).
    pub t: [f64; 3],
}

impl Similarity {
    /// Applies the similarity to a flat shape with `dims` values per point.
    pub fn apply(&self, shape: &[f64], dims: usize) -> Vec<f64> {
        let (s, c) = (self.scale * self.angle.sin(), self.scale * self.angle.cos());
        let mut out = shape.to_vec();
        for p in out.chunks_mut(dims) {
            let (x, y) = (p[0], p[1]);
            p[0] = c * x - s * y + self.t[0];
            p[1] = s * x + c * y + self.t[1];
            if dims == 3 {
                p[2] = self.scale * p[2] + self.t[2];
            }
        }
        out
    }
}

/// Shapes after alignment, with the motion that was taken out.
#[derive(Debug, Clone)]
pub struct Aligned {
    /// Aligned shapes, one per column, same layout as the input.
    pub coords: DMatrix<f64>,
    /// Per frame: aligned → original.
    pub head: Vec<Similarity>,
    /// The Procrustes mean shape the frames were aligned to.
    pub mean: DVector<f64>,
    /// Iterations until the mean stopped moving.
    pub iterations: usize,
}

/// Centroid of a flat shape.
fn centroid(shape: &[f64], dims: usize) -> [f64; 3] {
    let mut c = [0.0; 3];
    let n = (shape.len() / dims) as f64;
    for p in shape.chunks(dims) {
        for d in 0..dims {
            c[d] += p[d] / n;
        }
    }
    c
}

/// Best `(scale, angle)` with `scale · R(angle) · x ≈ y` for centred x, y (least squares,
/// no reflection). Only the first two coordinates of each point take part in the rotation.
fn fit_rotation_scale(x: &[f64], y: &[f64], dims: usize) -> Option<(f64, f64)> {
    let (mut a, mut b, mut nx) = (0.0, 0.0, 0.0);
    for (p, q) in x.chunks(dims).zip(y.chunks(dims)) {
        a += p[0] * q[0] + p[1] * q[1];
        b += p[0] * q[1] - p[1] * q[0];
        nx += p[0] * p[0] + p[1] * p[1];
        if dims == 3 {
            nx += p[2] * p[2];
        }
    }
    if nx <= f64::MIN_POSITIVE || !(a.is_finite() && b.is_finite()) {
        return None;
    }
    let angle = b.atan2(a);
    // The rotation turns x-y only; with z the scale below still minimises the error.
    let (s, c) = angle.sin_cos();
    let mut dot = 0.0;
    for (p, q) in x.chunks(dims).zip(y.chunks(dims)) {
        dot += (c * p[0] - s * p[1]) * q[0] + (s * p[0] + c * p[1]) * q[1];
        if dims == 3 {
            dot += p[2] * q[2];
        }
    }
    Some((dot / nx, angle))
}

fn size(shape: &[f64]) -> f64 {
    shape.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// Rotates and scales a centred shape in place.
fn transform(shape: &mut [f64], dims: usize, scale: f64, angle: f64) {
    let (s, c) = angle.sin_cos();
    for p in shape.chunks_mut(dims) {
        let (x, y) = (p[0], p[1]);
        p[0] = scale * (c * x - s * y);
        p[1] = scale * (s * x + c * y);
        if dims == 3 {
            p[2] *= scale;
        }
    }
}

/// Centres a flat shape on its centroid in place; returns the centroid.
pub fn centre(shape: &mut [f64], dims: usize) -> [f64; 3] {
    let c = centroid(shape, dims);
    for p in shape.chunks_mut(dims) {
        for d in 0..dims {
            p[d] -= c[d];
        }
    }
    c
}

fn degenerate(i: usize) -> Error {
    Error::unfit(format!(
        "frame column {i}: all points coincide, so the shape cannot be aligned (use {})",
        setting("no_align")
    ))
}

/// Aligns a centred shape onto the Procrustes `mean` in place (frame column `i`, for the
/// message when it cannot be); returns the similarity taking it back to where it was, given
/// its centroid `c`.
pub fn align_to(
    shape: &mut [f64],
    mean: &[f64],
    dims: usize,
    c: [f64; 3],
    i: usize,
) -> Result<Similarity> {
    let (s, a) = fit_rotation_scale(shape, mean, dims).ok_or_else(|| degenerate(i))?;
    transform(shape, dims, s, a);
    Ok(Similarity {
        scale: 1.0 / s,
        angle: -a,
        t: c,
    })
}

/// The generalised Procrustes mean of `n` centred shapes that `replay` presents, each time
/// it is called, in order: `replay(f)` calls `f(i, shape_i)` for i = 0..n. The frames are
/// visited once for their sizes and once per round, so they need not be in memory: a file
/// can be read again each time (a streamed solve does). Returns the mean and the rounds.
///
/// The mean is started at frame 0, re-estimated until it moves less than 1e-10 of its
/// size (at most 100 rounds), and kept at the input's mean centroid size and frame 0's
/// orientation, so the result does not drift.
pub fn procrustes_mean<F>(n: usize, dims: usize, mut replay: F) -> Result<(Vec<f64>, usize)>
where
    F: FnMut(&mut dyn FnMut(usize, &[f64]) -> Result<()>) -> Result<()>,
{
    if n == 0 {
        return Err(Error::invalid("cannot align an empty sequence"));
    }
    let mut sizes = 0.0;
    let mut reference = Vec::new();
    replay(&mut |i, x| {
        if i == 0 {
            reference = x.to_vec();
        }
        sizes += size(x);
        Ok(())
    })?;
    let target_size = sizes / n as f64;
    let mut mean = reference.clone();
    let mut iterations = 0;
    let mut y = vec![0.0; mean.len()];
    for it in 0..100 {
        iterations = it + 1;
        let mut next = vec![0.0; mean.len()];
        replay(&mut |i, x| {
            let (s, a) = fit_rotation_scale(x, &mean, dims).ok_or_else(|| degenerate(i))?;
            y.copy_from_slice(x);
            transform(&mut y, dims, s, a);
            for (m, v) in next.iter_mut().zip(&y) {
                *m += v / n as f64;
            }
            Ok(())
        })?;
        // Fix the gauge: frame 0's orientation, the input's mean size.
        let (_, a) = fit_rotation_scale(&next, &reference, dims).ok_or_else(|| degenerate(0))?;
        let ns = size(&next);
        if ns <= f64::MIN_POSITIVE {
            return Err(degenerate(0));
        }
        transform(&mut next, dims, target_size / ns, a);
        let moved = next
            .iter()
            .zip(&mean)
            .map(|(p, q)| (p - q).powi(2))
            .sum::<f64>()
            .sqrt();
        mean = next;
        if moved <= 1e-10 * target_size.max(f64::MIN_POSITIVE) {
            break;
        }
    }
    Ok((mean, iterations))
}

/// Generalised Procrustes alignment of every column of `coords` (`dims` values per point):
/// [`procrustes_mean`], then every frame aligned onto it ([`align_to`]).
pub fn procrustes(coords: &DMatrix<f64>, dims: usize) -> Result<Aligned> {
    procrustes_owned(coords.clone(), dims)
}

/// [`procrustes`] on coordinates the caller gives up: aligned in place, so no second copy
/// of a long track is held.
pub fn procrustes_owned(mut out: DMatrix<f64>, dims: usize) -> Result<Aligned> {
    let n = out.ncols();
    if n == 0 {
        return Err(Error::invalid("cannot align an empty sequence"));
    }
    // Centred here, each frame aligned in place at the end (the rounds only need the mean,
    // not every aligned frame).
    let centroids: Vec<[f64; 3]> = out
        .column_iter_mut()
        .map(|mut col| centre(col.as_mut_slice(), dims))
        .collect();
    let (mean, iterations) = procrustes_mean(n, dims, |f| {
        for (i, x) in out.column_iter().enumerate() {
            f(i, x.as_slice())?;
        }
        Ok(())
    })?;
    let mut head = Vec::with_capacity(n);
    for (i, mut x) in out.column_iter_mut().enumerate() {
        head.push(align_to(x.as_mut_slice(), &mean, dims, centroids[i], i)?);
    }
    Ok(Aligned {
        coords: out,
        head,
        mean: DVector::from_vec(mean),
        iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn similarity_round_trip_restores_the_input() {
        let shape =
            DMatrix::from_column_slice(6, 2, &[0., 0., 1., 0., 0., 2., 5., 5., 6., 5., 5., 7.]);
        let al = procrustes(&shape, 2).unwrap();
        for c in 0..2 {
            let back = al.head[c].apply(al.coords.column(c).as_slice(), 2);
            for (a, b) in back.iter().zip(shape.column(c).iter()) {
                assert!((a - b).abs() < 1e-12);
            }
        }
    }
}
