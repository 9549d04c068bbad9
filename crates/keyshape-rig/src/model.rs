//! A blendshape rig seen through its landmark vertices: read from ICT FaceKit or a glTF,
//! its person (identity) and its landmark geometry.

use crate::camera::Camera;
use crate::{correspondence, read_landmark_vertices};
use keyshape_core::error::{Error, Result};
use keyshape_io::morph::MorphTargets;
use nalgebra::DMatrix;
use std::path::Path;

/// Landmarks per rig (iBUG / Multi-PIE 68, in that order).
pub const LANDMARKS: usize = 68;

/// A blendshape rig seen through its landmark vertices.
#[derive(Debug, Clone)]
pub struct Rig {
    /// Shape names, as the rig names them.
    pub names: Vec<String>,
    /// Landmark positions of the neutral face.
    pub neutral: Vec<[f64; 3]>,
    /// Per shape, the landmarks' offsets from the neutral.
    pub deltas: Vec<Vec<[f64; 3]>>,
    /// Per landmark, the track point it is read from (the tracker's numbering: iBUG 0–67,
    /// MediaPipe 0–477); the solve takes the track's points in this order.
    pub points: Vec<usize>,
    /// The track layout's point count (68, 468 or 478; see [`correspondence::LAYOUTS`]).
    pub layout: usize,
}

impl Rig {
    /// Reads the ICT FaceKit folder layout (`../shared/data/ict_facekit_face`):
    /// `neutral_face.obj`, `expressions.csv`, `expression_deltas.csv` and
    /// `landmarks_multipie68.csv`.
    pub fn read_ict(dir: &Path) -> Result<Rig> {
        let (mesh, morph, marks) = Rig::read_ict_parts(dir)?;
        Rig::from_parts(&mesh.positions, &morph, &marks)
    }

    /// The ICT folder's mesh, morph targets and landmark vertices, as read by
    /// [`Rig::read_ict`] (for exports that need the whole mesh).
    pub fn read_ict_parts(
        dir: &Path,
    ) -> Result<(keyshape_io::obj::Mesh, MorphTargets, Vec<usize>)> {
        if !dir.is_dir() {
            return Err(Error::file(
                dir,
                "is not a rig folder (neutral_face.obj, expressions.csv, expression_deltas.csv, landmarks_multipie68.csv)",
            ));
        }
        keyshape_io::atomic::register_input(dir)?;
        let mesh = keyshape_io::obj::read_obj(&dir.join("neutral_face.obj"))?;
        let n = mesh.positions.len();
        let marks = read_landmark_vertices(&dir.join("landmarks_multipie68.csv"), n)?;
        let morph = MorphTargets::read(
            &dir.join("expressions.csv"),
            &dir.join("expression_deltas.csv"),
            n,
        )?;
        Ok((mesh, morph, marks))
    }

    /// A rig from mesh positions, sparse morph targets and the vertices of the 68 iBUG
    /// landmarks, in landmark order.
    pub fn from_parts(
        positions: &[[f64; 3]],
        morph: &MorphTargets,
        marks: &[usize],
    ) -> Result<Rig> {
        let pairs: Vec<(usize, usize)> = marks.iter().copied().enumerate().collect();
        Rig::from_correspondence(positions, morph, 68, &pairs)
    }

    /// A rig reading a track of `layout` points (68, 468 or 478) through `pairs` (track
    /// point, mesh vertex): each named point is the landmark at its vertex; the others are
    /// left out.
    pub fn from_correspondence(
        positions: &[[f64; 3]],
        morph: &MorphTargets,
        layout: usize,
        pairs: &[(usize, usize)],
    ) -> Result<Rig> {
        correspondence::check_against_track(pairs, layout, "the rig's correspondence")?;
        if let Some(&(l, v)) = pairs.iter().find(|p| p.1 >= positions.len()) {
            return Err(Error::invalid(format!(
                "rig: landmark {l} names vertex {v}, but the mesh has {} vertices",
                positions.len()
            )));
        }
        let marks: Vec<usize> = pairs.iter().map(|p| p.1).collect();
        let neutral: Vec<[f64; 3]> = marks.iter().map(|&v| positions[v]).collect();
        for (l, p) in neutral.iter().enumerate() {
            if p.iter().any(|c| !c.is_finite()) {
                return Err(Error::invalid(format!(
                    "rig: landmark {} (vertex {}) has a non-finite position",
                    pairs[l].0, marks[l]
                )));
            }
        }
        let mut at: Vec<Vec<usize>> = vec![Vec::new(); positions.len()];
        for (l, &v) in marks.iter().enumerate() {
            at[v].push(l);
        }
        let mut deltas = vec![vec![[0.0; 3]; marks.len()]; morph.names.len()];
        for (s, d) in morph.deltas.iter().enumerate() {
            for &(v, o) in d {
                for &l in at.get(v).map_or(&[][..], Vec::as_slice) {
                    deltas[s][l] = o;
                }
            }
        }
        if morph.names.is_empty() {
            return Err(Error::invalid("rig: no shapes"));
        }
        morph
            .check_scale(positions)
            .map_err(|e| Error::invalid(format!("rig: {e}")))?;
        Ok(Rig {
            names: morph.names.clone(),
            neutral,
            deltas,
            points: pairs.iter().map(|p| p.0).collect(),
            layout,
        })
    }

    /// Number of landmarks.
    pub fn landmarks(&self) -> usize {
        self.neutral.len()
    }

    /// The landmarks (indices into [`Rig::neutral`]) of the outer eye corners, subject's
    /// right then left, if the rig reads both.
    pub fn eyes(&self) -> Option<[usize; 2]> {
        let [a, b] = correspondence::eye_corners(self.layout)?;
        let at = |p: usize| self.points.iter().position(|&q| q == p);
        Some([at(a)?, at(b)?])
    }

    /// Does the rig read an iris centre (so eye gaze moves its landmarks)?
    pub fn sees_pupils(&self) -> bool {
        correspondence::pupils(self.layout)
            .is_some_and(|c| self.points.iter().any(|p| c.contains(p)))
    }

    /// Number of shapes.
    pub fn k(&self) -> usize {
        self.names.len()
    }

    /// The landmarks posed by `w` (no clamping).
    pub fn posed(&self, w: &[f64]) -> Vec<[f64; 3]> {
        let mut out = self.neutral.clone();
        for (d, &wk) in self.deltas.iter().zip(w) {
            if wk == 0.0 {
                continue;
            }
            for (o, dl) in out.iter_mut().zip(d) {
                for a in 0..3 {
                    o[a] += wk * dl[a];
                }
            }
        }
        out
    }

    /// Renders a 2-D track (image axes, y down) of the rig posed by `weights` (k × frames)
    /// under per-frame cameras: the oracle of the recovery tests and the synthetic study.
    pub fn render(&self, weights: &DMatrix<f64>, cams: &[Camera]) -> DMatrix<f64> {
        let mut out = DMatrix::zeros(2 * self.landmarks(), weights.ncols());
        for f in 0..weights.ncols() {
            let w: Vec<f64> = weights.column(f).iter().copied().collect();
            for (i, p) in self.posed(&w).iter().enumerate() {
                let u = cams[f].project(p);
                out[(2 * i, f)] = u[0];
                out[(2 * i + 1, f)] = -u[1];
            }
        }
        out
    }
}

impl<'a> From<&'a Rig> for std::borrow::Cow<'a, Rig> {
    fn from(r: &'a Rig) -> Self {
        std::borrow::Cow::Borrowed(r)
    }
}

impl From<Rig> for std::borrow::Cow<'static, Rig> {
    fn from(r: Rig) -> Self {
        std::borrow::Cow::Owned(r)
    }
}
