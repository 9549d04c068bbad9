//! Action-specific modes (Cosker et al., paper 002 §3.1) on landmark shapes, and the
//! orthogonality measure of their Table 2 (§5, Eq. 9).
//!
//! From N training shapes the artificial set holds, for every region j and frame i, the mean
//! shape with region j's offsets of frame i added (4N shapes for four regions). Its PCA
//! gives modes that act locally; plain PCA of the same frames mixes regions. The regions and
//! their boundaries are in [`crate::regions`] (re-exported here).

use keyshape_core::error::{setting, Error, Needed, Result};
use keyshape_core::pca::Pca;
use nalgebra::{DMatrix, DVector};
use serde::Deserialize;
use std::path::Path;

pub use crate::regions::{
    region_shape, region_weights, shape_size, Boundary, ModeRegions, Region, RegionOptions,
    DEFAULT_BLEND_RADIUS,
};

/// The artificial training set: for every region and frame, [`region_shape`] (regions in
/// order, frames in order within each).
pub fn artificial_set(coords: &DMatrix<f64>, regions: &[Region], dims: usize) -> DMatrix<f64> {
    let mean = coords.column_mean();
    let n = coords.ncols();
    let mut out = DMatrix::zeros(coords.nrows(), n * regions.len());
    for (r, region) in regions.iter().enumerate() {
        for i in 0..n {
            out.set_column(
                r * n + i,
                &region_shape(&mean, coords.column(i).as_slice(), &region.weights, dims),
            );
        }
    }
    out
}

/// The action-specific model: the PCA of [`artificial_set`] (leading `modes` axes), made
/// from its columns a block at a time instead of the set itself, which is as many copies
/// of the sequence as there are regions. The same axes as fitting the set's matrix with
/// [`Pca::fit_leading`] where that takes the full decomposition (up to 176 values per
/// shape: 88 points in 2-D; tested bit for bit); with more values per shape it replaces
/// fit_leading's subspace iteration by the full decomposition, which is exact rather than
/// converged to 1e-10.
pub fn artificial_pca(
    coords: &DMatrix<f64>,
    regions: &[Region],
    dims: usize,
    modes: usize,
) -> Result<Pca> {
    let (rows, n) = coords.shape();
    keyshape_core::keyshapes::need_distinct(
        keyshape_core::keyshapes::distinct_shapes(coords),
        n,
        2,
        "an action-specific model",
    )?;
    let total = n * regions.len();
    if total <= rows {
        // Fewer shapes than values: the set is small; fit it whole.
        return Pca::fit_leading(&artificial_set(coords, regions, dims), modes);
    }
    let mean = coords.column_mean();
    let block = |start: usize, width: usize| -> DMatrix<f64> {
        let mut out = DMatrix::zeros(rows, width);
        for j in 0..width {
            let (r, i) = ((start + j) / n, (start + j) % n);
            out.set_column(
                j,
                &region_shape(
                    &mean,
                    coords.column(i).as_slice(),
                    &regions[r].weights,
                    dims,
                ),
            );
        }
        out
    };
    let mut p = Pca::fit_blocks(rows, total, &block)?;
    p.truncate(modes.min(rows.min(total)));
    Ok(p)
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
        keyshape_io::read_json(path)
    }

    /// Reads an actions file to use with the track `source` (a path): refused when the file
    /// names another track (compared by file name, since the paths differ from machine to
    /// machine), or names a frame `frames` lacks.
    pub fn read_for(path: &Path, source: &str, frames: &[i64]) -> Result<Actions> {
        let a = Actions::read(path)?;
        let name = |s: &str| {
            Path::new(s)
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default()
        };
        if !a.sequence.is_empty() && name(&a.sequence) != name(source) {
            return Err(Error::needs_in(
                path,
                Needed::ActionsFor(source.into()),
                format!(
                    "these actions were chosen on {}, not on {}: their frames name other faces; choose this track's",
                    a.sequence, source
                ),
            ));
        }
        if let Some(x) = a.actions.iter().find(|x| !frames.contains(&x.frame)) {
            return Err(Error::file(
                path,
                format!(
                    "action {} names frame {}, which {} does not have (or the tracker failed on)",
                    x.name, x.frame, source
                ),
            ));
        }
        Ok(a)
    }
}

/// Each action's shape vector: the mean shape with only its region's offsets of its
/// example frame added (§5). Actions naming unknown regions or frames are errors.
pub fn action_vectors(
    coords: &DMatrix<f64>,
    frames: &[i64],
    dims: usize,
    regions: &[Region],
    actions: &Actions,
) -> Result<Vec<DVector<f64>>> {
    let mean = coords.column_mean();
    actions
        .actions
        .iter()
        .map(|a| {
            let region = regions.iter().find(|r| r.name == a.region).ok_or_else(|| {
                let names: Vec<&str> = regions.iter().map(|r| r.name.as_str()).collect();
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
                &region.weights,
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

/// Refuses 0 modes: `what` needs at least one.
pub(crate) fn need_modes(modes: usize, what: &str) -> Result<()> {
    if modes == 0 {
        return Err(Error::bad_setting(
            "modes",
            0,
            format!("{what} needs at least 1 mode ({})", setting("modes")),
        ));
    }
    Ok(())
}

/// Builds both models from `coords` (aligned shapes, `dims` per point) and measures the
/// actions. Actions naming unknown regions or frames are errors.
pub fn orthogonality_study(
    coords: &DMatrix<f64>,
    frames: &[i64],
    dims: usize,
    regions: &[Region],
    actions: &Actions,
    modes: usize,
) -> Result<OrthogonalityStudy> {
    need_modes(modes, "the orthogonality study")?;
    if actions.actions.len() < 2 {
        return Err(Error::invalid(
            "the orthogonality table needs at least two actions",
        ));
    }
    let vecs = action_vectors(coords, frames, dims, regions, actions)?;
    let action_model = artificial_pca(coords, regions, dims, modes)?;
    let plain = Pca::fit_leading(coords, modes)?;
    Ok(OrthogonalityStudy {
        names: actions.actions.iter().map(|a| a.name.clone()).collect(),
        action_model: orthogonality_table(&action_model, &vecs, modes),
        plain: orthogonality_table(&plain, &vecs, modes),
        modes,
    })
}
