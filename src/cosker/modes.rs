//! Action-specific modes (Cosker et al., paper 002 §3.1) on landmark shapes, and the
//! orthogonality measure of their Table 2 (§5, Eq. 9).
//!
//! From N training shapes the artificial set holds, for every region j and frame i, the mean
//! shape with only region j's offsets of frame i added (4N shapes for four regions). Its PCA
//! gives modes that act locally; plain PCA of the same frames mixes regions.

use crate::error::{Error, Result};
use crate::pca::Pca;
use crate::sequence::Layout;
use nalgebra::{DMatrix, DVector};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;

/// Named regions of a layout (data, not code).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModeRegions {
    /// Layout the groups refer to.
    pub layout: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// Region name → layout groups.
    pub regions: BTreeMap<String, Vec<String>>,
}

impl ModeRegions {
    /// The built-in regions of a layout.
    pub fn builtin(layout: &Layout) -> Result<ModeRegions> {
        let text = match layout.name.as_str() {
            "mediapipe_face_mesh_468" => {
                include_str!("../../assets/cosker/regions_mediapipe_face_mesh_468.json")
            }
            "ibug68" => include_str!("../../assets/cosker/regions_ibug68.json"),
            other => {
                return Err(Error::invalid(format!(
                    "no built-in Cosker regions for layout {other}"
                )))
            }
        };
        serde_json::from_str(text).map_err(|e| Error::invalid(format!("built-in regions: {e}")))
    }

    /// Reads a regions file.
    pub fn read(path: &Path) -> Result<ModeRegions> {
        crate::io::read_json(path)
    }

    /// Point indices of each region (name order); unknown groups and empty regions are errors.
    pub fn points(&self, layout: &Layout) -> Result<Vec<(String, Vec<usize>)>> {
        if self.layout != layout.name {
            return Err(Error::invalid(format!(
                "regions are for layout {}, the sequence is {}",
                self.layout, layout.name
            )));
        }
        if self.regions.is_empty() {
            return Err(Error::invalid("regions file names no regions"));
        }
        self.regions
            .iter()
            .map(|(name, groups)| {
                if groups.is_empty() {
                    return Err(Error::invalid(format!("region '{name}' names no groups")));
                }
                let pts = layout
                    .select(&groups.join(","))
                    .map_err(|e| Error::invalid(format!("region '{name}': {e}")))?;
                Ok((name.clone(), pts))
            })
            .collect()
    }
}

/// The mean shape with only `points`' offsets of `shape` added (`dims` values per point).
pub fn region_shape(
    mean: &DVector<f64>,
    shape: &[f64],
    points: &[usize],
    dims: usize,
) -> DVector<f64> {
    let mut v = mean.clone();
    for &p in points {
        for d in 0..dims {
            v[p * dims + d] = shape[p * dims + d];
        }
    }
    v
}

/// The artificial training set: for every region and frame, [`region_shape`] (regions in
/// order, frames in order within each).
pub fn artificial_set(
    coords: &DMatrix<f64>,
    regions: &[(String, Vec<usize>)],
    dims: usize,
) -> DMatrix<f64> {
    let mean = coords.column_mean();
    let n = coords.ncols();
    let mut out = DMatrix::zeros(coords.nrows(), n * regions.len());
    for (r, (_, pts)) in regions.iter().enumerate() {
        for i in 0..n {
            out.set_column(
                r * n + i,
                &region_shape(&mean, coords.column(i).as_slice(), pts, dims),
            );
        }
    }
    out
}

/// Paper 002 Eq. (9): `M(cᵢ, cⱼ) = (cᵢ·cⱼ)² / ((cⱼ·cⱼ)(cᵢ·cᵢ))` — 0 for orthogonal vectors,
/// 1 for parallel ones (0 when either is zero).
pub fn orthogonality(ci: &DVector<f64>, cj: &DVector<f64>) -> f64 {
    let d = ci.dot(ci) * cj.dot(cj);
    if d > 0.0 {
        ci.dot(cj).powi(2) / d
    } else {
        0.0
    }
}

/// The pairwise Eq. (9) table of action vectors projected on a model's first `modes` modes.
pub fn orthogonality_table(model: &Pca, actions: &[DVector<f64>], modes: usize) -> DMatrix<f64> {
    let proj: Vec<DVector<f64>> = actions
        .iter()
        .map(|a| {
            let m = modes.min(model.components.ncols());
            model.components.columns(0, m).tr_mul(&(a - &model.mean))
        })
        .collect();
    DMatrix::from_fn(actions.len(), actions.len(), |i, j| {
        orthogonality(&proj[i], &proj[j])
    })
}

/// One labelled action: a region and an example frame.
#[derive(Debug, Clone, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Action {
    /// Action name (smile, blink, …).
    pub name: String,
    /// The region it lives in.
    pub region: String,
    /// A frame (number) showing it.
    pub frame: i64,
}

/// An actions file.
#[derive(Debug, Clone, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Actions {
    /// Format version, 1.
    pub kslab_actions: u32,
    /// The sequence the frames refer to.
    #[serde(default)]
    pub sequence: String,
    /// How the frames were chosen.
    #[serde(default)]
    pub how_chosen: String,
    /// The actions.
    pub actions: Vec<Action>,
}

impl Actions {
    /// Reads an actions file.
    pub fn read(path: &Path) -> Result<Actions> {
        crate::io::read_json(path)
    }
}

/// Each action's shape vector: the mean shape with only its region's offsets of its
/// example frame added (§5). Actions naming unknown regions or frames are errors.
pub fn action_vectors(
    coords: &DMatrix<f64>,
    frames: &[i64],
    dims: usize,
    regions: &[(String, Vec<usize>)],
    actions: &Actions,
) -> Result<Vec<DVector<f64>>> {
    let mean = coords.column_mean();
    actions
        .actions
        .iter()
        .map(|a| {
            let (_, pts) = regions
                .iter()
                .find(|(n, _)| *n == a.region)
                .ok_or_else(|| {
                    let names: Vec<&str> = regions.iter().map(|r| r.0.as_str()).collect();
                    Error::invalid(format!(
                        "action '{}' names region '{}' (regions: {})",
                        a.name,
                        a.region,
                        names.join(", ")
                    ))
                })?;
            let col = frames.iter().position(|&f| f == a.frame).ok_or_else(|| {
                Error::invalid(format!(
                    "action '{}' names frame {}, which is not a tracked frame",
                    a.name, a.frame
                ))
            })?;
            Ok(region_shape(
                &mean,
                coords.column(col).as_slice(),
                pts,
                dims,
            ))
        })
        .collect()
}

/// Table 2 for one sequence: the Eq. (9) tables of the action-specific model and of plain
/// PCA, on their first `modes` modes.
#[derive(Debug, Clone)]
pub struct OrthogonalityStudy {
    /// Action names.
    pub names: Vec<String>,
    /// Action-specific model.
    pub action_model: DMatrix<f64>,
    /// Plain PCA.
    pub plain: DMatrix<f64>,
    /// Modes used.
    pub modes: usize,
}

impl OrthogonalityStudy {
    /// Mean of the upper triangle.
    pub fn mean_upper(m: &DMatrix<f64>) -> f64 {
        let n = m.nrows();
        let (mut s, mut c) = (0.0, 0);
        for i in 0..n {
            for j in i + 1..n {
                s += m[(i, j)];
                c += 1;
            }
        }
        if c == 0 {
            0.0
        } else {
            s / c as f64
        }
    }
}

/// Builds both models from `coords` (aligned shapes, `dims` per point) and measures the
/// actions. Actions naming unknown regions or frames are errors.
pub fn orthogonality_study(
    coords: &DMatrix<f64>,
    frames: &[i64],
    dims: usize,
    regions: &[(String, Vec<usize>)],
    actions: &Actions,
    modes: usize,
) -> Result<OrthogonalityStudy> {
    if modes == 0 {
        return Err(Error::invalid(
            "the orthogonality study needs at least 1 mode (--modes)",
        ));
    }
    if actions.actions.len() < 2 {
        return Err(Error::invalid(
            "the orthogonality table needs at least two actions",
        ));
    }
    let vecs = action_vectors(coords, frames, dims, regions, actions)?;
    let artificial = artificial_set(coords, regions, dims);
    let action_model = Pca::fit_leading(&artificial, modes)?;
    let plain = Pca::fit_leading(coords, modes)?;
    Ok(OrthogonalityStudy {
        names: actions.actions.iter().map(|a| a.name.clone()).collect(),
        action_model: orthogonality_table(&action_model, &vecs, modes),
        plain: orthogonality_table(&plain, &vecs, modes),
        modes,
    })
}
