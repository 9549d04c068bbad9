//! Morph targets (paper 002 §3.3, Eq. 8): `E = N + Σ (m(i) − N) w(i)`, w in [0, 1], on
//! the ICT face's expression shapes (sparse offsets from its neutral), driven by action
//! trajectories through a mapping file (action → shape names with gains).

use crate::error::{Error, Result};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;

/// A named morph target as dense per-vertex offsets.
pub type DenseTarget = (String, Vec<[f64; 3]>);

/// Morph targets as sparse offsets from the neutral mesh.
#[derive(Debug, Clone)]
pub struct MorphTargets {
    /// Shape names, in id order.
    pub names: Vec<String>,
    /// Per shape: (vertex, offset).
    pub deltas: Vec<Vec<(usize, [f64; 3])>>,
}

impl MorphTargets {
    /// Reads `expressions.csv` (id, name, …) and `expression_deltas.csv` (shape_id, vertex,
    /// dx, dy, dz); vertices must be below `vertices`.
    pub fn read(expressions: &Path, deltas: &Path, vertices: usize) -> Result<MorphTargets> {
        let mut names = Vec::new();
        let mut rdr = csv::Reader::from_path(expressions)
            .map_err(|e| Error::file(expressions, e.to_string()))?;
        for (i, r) in rdr.records().enumerate() {
            let r = r.map_err(|e| Error::parse(expressions, i as u64 + 2, 0, e.to_string()))?;
            let id: usize = r.get(0).unwrap_or("").parse().map_err(|_| {
                Error::parse(expressions, i as u64 + 2, 1, "shape id is not a number")
            })?;
            if id != names.len() {
                return Err(Error::parse(
                    expressions,
                    i as u64 + 2,
                    1,
                    format!("shape ids must run 0, 1, …; found {id}"),
                ));
            }
            names.push(r.get(1).unwrap_or("").to_string());
        }
        let mut out = vec![Vec::new(); names.len()];
        let mut rdr =
            csv::Reader::from_path(deltas).map_err(|e| Error::file(deltas, e.to_string()))?;
        for (i, r) in rdr.records().enumerate() {
            let line = i as u64 + 2;
            let r = r.map_err(|e| Error::parse(deltas, line, 0, e.to_string()))?;
            let num = |c: usize| -> Result<f64> {
                r.get(c).unwrap_or("").parse::<f64>().map_err(|_| {
                    Error::parse(
                        deltas,
                        line,
                        c as u64 + 1,
                        format!("not a number: '{}'", r.get(c).unwrap_or("")),
                    )
                })
            };
            let index = |c: usize| -> Result<usize> {
                r.get(c).unwrap_or("").trim().parse::<usize>().map_err(|_| {
                    Error::parse(
                        deltas,
                        line,
                        c as u64 + 1,
                        format!("not an index: '{}'", r.get(c).unwrap_or("")),
                    )
                })
            };
            let (s, v) = (index(0)?, index(1)?);
            let o = [num(2)?, num(3)?, num(4)?];
            if let Some(c) = o.iter().position(|x| !x.is_finite()) {
                return Err(Error::parse(
                    deltas,
                    line,
                    c as u64 + 3,
                    format!("offset is not finite: '{}'", r.get(c + 2).unwrap_or("")),
                ));
            }
            if s >= names.len() || v >= vertices {
                return Err(Error::parse(
                    deltas,
                    line,
                    1,
                    format!(
                        "shape {s} / vertex {v} out of range ({} shapes, {vertices} vertices)",
                        names.len()
                    ),
                ));
            }
            out[s].push((v, o));
        }
        Ok(MorphTargets { names, deltas: out })
    }

    /// The shapes with any nonzero weight in `weights` (shapes × frames), as (name, dense
    /// per-vertex offsets), with their weight rows — what a glTF export needs.
    pub fn used_dense(
        &self,
        weights: &nalgebra::DMatrix<f64>,
        vertices: usize,
    ) -> (Vec<DenseTarget>, nalgebra::DMatrix<f64>) {
        let used: Vec<usize> = (0..self.names.len())
            .filter(|&s| weights.row(s).iter().any(|v| *v > 0.0))
            .collect();
        let dense = used
            .iter()
            .map(|&s| {
                let mut d = vec![[0.0; 3]; vertices];
                for &(v, o) in &self.deltas[s] {
                    d[v] = o;
                }
                (self.names[s].clone(), d)
            })
            .collect();
        (dense, weights.select_rows(&used))
    }

    /// Writes `mesh` animated by `weights` (shapes × frames) as GLB at `path` (atomically):
    /// only the shapes with a nonzero weight, densified, as morph targets; `rotations` (one
    /// `[x, y, z, w]` quaternion per frame) animate the node's rotation too.
    pub fn write_used_glb(
        &self,
        path: &Path,
        mesh: &crate::io::obj::Mesh,
        weights: &nalgebra::DMatrix<f64>,
        fps: f64,
        rotations: Option<&[[f64; 4]]>,
    ) -> Result<()> {
        let (dense, used) = self.used_dense(weights, mesh.positions.len());
        crate::io::write_atomic(path, |f| {
            crate::io::gltf::write_morph_glb_posed(
                f,
                &mesh.positions,
                &mesh.faces,
                &dense,
                &used,
                fps,
                rotations,
            )
        })
    }

    /// Eq. (8) into `out` (starting from `neutral`), weights clamped to [0, 1].
    pub fn blend(&self, neutral: &[[f64; 3]], weights: &[f64], out: &mut [[f64; 3]]) {
        out.copy_from_slice(neutral);
        for (s, &w) in weights.iter().enumerate() {
            let w = w.clamp(0.0, 1.0);
            if w == 0.0 {
                continue;
            }
            for &(v, d) in &self.deltas[s] {
                for k in 0..3 {
                    out[v][k] += w * d[k];
                }
            }
        }
    }
}

/// `{"actions": {"smile": [["mouthSmile_L", 1.0], ["mouthSmile_R", 1.0]], …}}`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MorphMapping {
    /// Action name → (shape name, gain) pairs.
    pub actions: BTreeMap<String, Vec<(String, f64)>>,
}

impl MorphMapping {
    /// The built-in mapping of the d6/d9 action names onto ICT's ARKit-style shapes.
    pub fn builtin() -> Result<MorphMapping> {
        serde_json::from_str(include_str!("../../assets/cosker/morph_mapping_ict.json"))
            .map_err(|e| Error::invalid(format!("built-in mapping: {e}")))
    }

    /// Reads a mapping file.
    pub fn read(path: &Path) -> Result<MorphMapping> {
        crate::io::read_json(path)
    }

    /// Shape weights per frame (shapes × frames) from action trajectories (actions ×
    /// frames, [−1, 1], positive = the action): `w = clamp(Σ gain · max(0, a(t)), 0, 1)`.
    /// Unknown shape or action names are errors.
    pub fn weights(
        &self,
        targets: &MorphTargets,
        action_names: &[String],
        traj: &nalgebra::DMatrix<f64>,
    ) -> Result<nalgebra::DMatrix<f64>> {
        let mut w = nalgebra::DMatrix::<f64>::zeros(targets.names.len(), traj.ncols());
        for (action, shapes) in &self.actions {
            let a = action_names
                .iter()
                .position(|n| n == action)
                .ok_or_else(|| {
                    Error::invalid(format!(
                        "mapping names action '{action}' (actions: {})",
                        action_names.join(", ")
                    ))
                })?;
            for (shape, gain) in shapes {
                let s = targets
                    .names
                    .iter()
                    .position(|n| n == shape)
                    .ok_or_else(|| {
                        Error::invalid(format!(
                            "mapping names shape '{shape}', which the morph targets do not have"
                        ))
                    })?;
                for t in 0..traj.ncols() {
                    w[(s, t)] += gain * traj[(a, t)].max(0.0);
                }
            }
        }
        w.iter_mut().for_each(|v| *v = v.clamp(0.0, 1.0));
        Ok(w)
    }
}
