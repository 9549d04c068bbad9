//! Feature-point retargeting onto a mesh (paper 004): an RBF space transform carries the
//! source feature points into the target's space each frame (§2), and linear-blend skinning
//! with automatic ellipsoid weights moves the mesh (§3). Partial retargeting (§4) keeps the
//! disabled groups' feature points at neutral. 2-D sources get z = 0 (§4).

pub mod features;
pub mod skin;

use crate::error::{Error, Result};
use crate::io::obj::Mesh;
use crate::retarget::rbf::Rbf;
use features::Features;
use nalgebra::DMatrix;
use skin::Skin;

/// A trained transfer from a source layout onto a mesh.
#[derive(Debug, Clone)]
pub struct Transfer {
    /// The target mesh at rest (neutral).
    pub mesh: Mesh,
    /// The correspondences.
    pub features: Features,
    /// The space transform, trained on the source neutral → target neutral feature points.
    pub rbf: Rbf,
    /// Target neutral feature points `T₀`.
    pub t0: Vec<[f64; 3]>,
    /// Skin weights.
    pub skin: Skin,
    /// Features whose group is enabled.
    pub enabled: Vec<bool>,
    /// Values per source point (2 or 3).
    pub dims: usize,
}

/// A source frame's feature points as 3-D points (z = 0 for 2-D sources), flat.
pub fn source_points(shape: &[f64], dims: usize, features: &Features) -> Vec<f64> {
    features
        .features
        .iter()
        .flat_map(|f| {
            let p = &shape[f.source * dims..(f.source + 1) * dims];
            [p[0], p[1], if dims == 3 { p[2] } else { 0.0 }]
        })
        .collect()
}

impl Transfer {
    /// Trains the RBF on `neutral` (a full source shape, `dims` per point) → the mesh's
    /// feature vertices, and computes automatic skin weights.
    pub fn new(
        mesh: Mesh,
        features: Features,
        neutral: &[f64],
        dims: usize,
        groups: Option<&[String]>,
    ) -> Result<Transfer> {
        features.check(neutral.len() / dims, mesh.positions.len())?;
        let enabled = features.enabled(groups)?;
        let t0: Vec<[f64; 3]> = features
            .features
            .iter()
            .map(|f| mesh.positions[f.target])
            .collect();
        let src = source_points(neutral, dims, &features);
        let dst: Vec<f64> = t0.iter().flatten().copied().collect();
        let rbf = Rbf::fit(&src, &dst, 3)?;
        let factors: Vec<f64> = features
            .features
            .iter()
            .map(|f| features.radius_factor.get(&f.group).copied().unwrap_or(1.5))
            .collect();
        if let Some(bad) = factors.iter().find(|f| !(f.is_finite() && **f > 0.0)) {
            return Err(Error::invalid(format!(
                "radius factors must be positive, got {bad}"
            )));
        }
        let radii = skin::radii(&t0, &factors);
        let skin = Skin::automatic(&mesh.positions, &t0, &radii);
        Ok(Transfer {
            mesh,
            features,
            rbf,
            t0,
            skin,
            enabled,
            dims,
        })
    }

    /// Feature displacements `d_i = F(s_i) − t0_i` of one source frame (zero when disabled).
    pub fn displacements(&self, shape: &[f64]) -> Vec<[f64; 3]> {
        let src = source_points(shape, self.dims, &self.features);
        let mapped = self.rbf.apply(&src);
        self.t0
            .iter()
            .enumerate()
            .map(|(i, t)| {
                if self.enabled[i] {
                    [
                        mapped[3 * i] - t[0],
                        mapped[3 * i + 1] - t[1],
                        mapped[3 * i + 2] - t[2],
                    ]
                } else {
                    [0.0; 3]
                }
            })
            .collect()
    }

    /// The deformed mesh positions for one source frame.
    pub fn frame(&self, shape: &[f64]) -> Vec<[f64; 3]> {
        let d = self.displacements(shape);
        let mut out = vec![[0.0; 3]; self.mesh.positions.len()];
        self.skin.deform(&self.mesh.positions, &d, &mut out);
        out
    }

    /// Deformed positions of every frame (columns of `coords`), in parallel.
    pub fn all_frames(&self, coords: &DMatrix<f64>) -> Vec<Vec<[f64; 3]>> {
        use rayon::prelude::*;
        (0..coords.ncols())
            .into_par_iter()
            .map(|c| self.frame(coords.column(c).as_slice()))
            .collect()
    }
}
