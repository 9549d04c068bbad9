//! Feature-point retargeting onto a mesh (paper 004): an RBF space transform carries the
//! source feature points into the target's space each frame (§2), and linear-blend skinning
//! with automatic ellipsoid weights moves the mesh (§3). Partial retargeting (§4) keeps the
//! disabled groups' feature points at neutral. 2-D sources get z = 0 (§4).

pub mod features;
pub mod skin;

use features::Features;
use keyshape_core::error::{Error, Result};
use keyshape_core::rbf::Rbf;
use keyshape_io::obj::Mesh;
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
            return Err(Error::bad_setting(
                "radius_factors",
                bad,
                format!("radius factors must be positive, got {bad}"),
            ));
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

    /// Checks that the features fit glTF's 16-bit joint indices ([`Transfer::write_glb`]).
    pub fn check_gltf(&self) -> Result<()> {
        keyshape_io::gltf::check_joints(self.t0.len())
    }

    /// Writes the transfer of `frames` source shapes (columns, `fps`) as GLB: the skin as
    /// glTF's linear-blend skinning, one joint per feature point animated by its
    /// translation ([`keyshape_io::gltf::write_skinned_glb`]).
    pub fn write_glb(
        &self,
        w: &mut dyn std::io::Write,
        frames: &nalgebra::DMatrix<f64>,
        fps: f64,
    ) -> std::io::Result<()> {
        let tracks: Vec<Vec<[f64; 3]>> = (0..frames.ncols())
            .map(|t| {
                let d = self.displacements(frames.column(t).as_slice());
                self.t0
                    .iter()
                    .zip(&d)
                    .map(|(t0, d)| [t0[0] + d[0], t0[1] + d[1], t0[2] + d[2]])
                    .collect()
            })
            .collect();
        let names: Vec<&str> = self
            .features
            .features
            .iter()
            .map(|f| f.name.as_str())
            .collect();
        keyshape_io::gltf::write_skinned_glb(
            w,
            &keyshape_io::gltf::Skinned {
                positions: &self.mesh.positions,
                faces: &self.mesh.faces,
                influences: &self.skin.influences,
                names: &names,
                rest: &self.t0,
                tracks: &tracks,
                fps,
            },
        )
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
        self.frames(coords, 0..coords.ncols())
    }

    /// The deformed mesh of the frames (columns of `coords`) in `range`, in parallel: what
    /// a caller walking a long track chunk by chunk asks for (a mesh of 9,409 vertices is
    /// 226 kB, so every frame of an hour at once would be 24 GB).
    pub fn frames(
        &self,
        coords: &DMatrix<f64>,
        range: std::ops::Range<usize>,
    ) -> Vec<Vec<[f64; 3]>> {
        use rayon::prelude::*;
        range
            .into_par_iter()
            .map(|c| self.frame(coords.column(c).as_slice()))
            .collect()
    }
}

/// What one transform trained on one person costs another (paper 004 trains on the
/// performer's own neutral; driving other people through it carries their identity — face
/// shape, proportions — into the target as if it were expression). Per segment (clip,
/// person), in the target's units:
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct MismatchRow {
    /// Segment (clip) id.
    pub segment: String,
    /// Frames in it.
    pub frames: usize,
    /// Its neutral: the segment's first frame on which an RBF can be trained (frame number;
    /// a frame whose feature points coincide, e.g. a blink closing both lids onto each
    /// other, cannot be).
    pub neutral_frame: i64,
    /// RMS over features of `F(n_c) − T₀`: where this person's neutral lands under the
    /// shared transform (0 for the person it was trained on).
    pub neutral_error: f64,
    /// RMS over frames and features of `F(s_t) − F_c(s_t)`, `F_c` trained on the segment's
    /// own neutral: what the shared transform adds to every frame.
    pub mismatch: f64,
    /// RMS over frames and features of `F_c(s_t) − T₀`: the expression motion itself.
    pub expression: f64,
}

/// [`MismatchRow`] for every segment of `coords` (`segments[t]` names frame t's segment,
/// whose frames are in time order; `frames[t]` its number).
pub fn person_mismatch(
    tr: &Transfer,
    coords: &DMatrix<f64>,
    frames: &[i64],
    segments: &[String],
) -> Result<Vec<MismatchRow>> {
    if segments.len() != coords.ncols() || frames.len() != coords.ncols() {
        return Err(Error::invalid(
            "segments, frame numbers and frames differ in count",
        ));
    }
    let mut order: Vec<&String> = Vec::new();
    for s in segments {
        if !order.contains(&s) {
            order.push(s);
        }
    }
    let dst: Vec<f64> = tr.t0.iter().flatten().copied().collect();
    let nf = tr.t0.len() as f64;
    let sq = |a: &[f64], b: &[f64]| -> f64 { a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum() };
    order
        .into_iter()
        .map(|seg| {
            let cols: Vec<usize> = (0..segments.len())
                .filter(|&t| &segments[t] == seg)
                .collect();
            let (n, own) = cols
                .iter()
                .find_map(|&c| {
                    let src = source_points(coords.column(c).as_slice(), tr.dims, &tr.features);
                    Rbf::fit(&src, &dst, 3).ok().map(|r| (c, r))
                })
                .ok_or_else(|| {
                    Error::unfit(format!(
                        "segment {seg}: no frame whose feature points can train an RBF"
                    ))
                })?;
            let n0 = coords.column(n);
            let shared0 = tr
                .rbf
                .apply(&source_points(n0.as_slice(), tr.dims, &tr.features));
            let (mut mis, mut expr) = (0.0, 0.0);
            for &c in &cols {
                let src = source_points(coords.column(c).as_slice(), tr.dims, &tr.features);
                let (a, b) = (tr.rbf.apply(&src), own.apply(&src));
                mis += sq(&a, &b);
                expr += sq(&b, &dst);
            }
            let denom = nf * cols.len() as f64;
            Ok(MismatchRow {
                segment: seg.clone(),
                frames: cols.len(),
                neutral_frame: frames[n],
                neutral_error: (sq(&shared0, &dst) / nf).sqrt(),
                mismatch: (mis / denom).sqrt(),
                expression: (expr / denom).sqrt(),
            })
        })
        .collect()
}
