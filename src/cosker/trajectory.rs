//! Action-mode trajectories and their mapping between people (paper 002 §3.2).
//!
//! A performance projected on an action-specific model gives one weight track per mode;
//! each track is normalised to [−1, 1] by its extreme value over the model's training
//! frames. A mode-alignment table maps a source mode to a target mode (with a sign flip
//! where the two models encode the action in opposite directions), and the normalised
//! tracks, scaled by the target's own extremes, synthesise the target person's shapes.

use crate::cosker::modes::{action_vectors, artificial_set, Actions};
use crate::error::{Error, Result};
use crate::pca::Pca;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// An action-specific model of one person with its actions located on its modes.
#[derive(Debug, Clone)]
pub struct PersonModel {
    /// PCA of the artificial (region-wise) training set.
    pub pca: Pca,
    /// Per mode: the largest |weight| over the person's training frames.
    pub limits: Vec<f64>,
    /// Per action: (name, mode, sign of the action along the mode).
    pub actions: Vec<(String, usize, f64)>,
}

/// Builds a person's model from their aligned shapes and action labels.
pub fn person_model(
    coords: &DMatrix<f64>,
    frames: &[i64],
    dims: usize,
    regions: &[(String, Vec<usize>)],
    actions: &Actions,
    modes: usize,
) -> Result<PersonModel> {
    if modes == 0 {
        return Err(Error::invalid(
            "a person's model needs at least 1 mode (--modes)",
        ));
    }
    let pca = Pca::fit_leading(&artificial_set(coords, regions, dims), modes)?;
    let m = pca.components.ncols();
    let b = pca.project(coords, m);
    let limits: Vec<f64> = (0..m)
        .map(|k| {
            b.row(k)
                .iter()
                .fold(0.0f64, |a, v| a.max(v.abs()))
                .max(f64::MIN_POSITIVE)
        })
        .collect();
    let located = action_vectors(coords, frames, dims, regions, actions)?
        .into_iter()
        .zip(&actions.actions)
        .map(|(v, a)| {
            let c = pca.components.tr_mul(&(v - &pca.mean));
            let mode = c.iamax();
            (a.name.clone(), mode, c[mode].signum())
        })
        .collect();
    Ok(PersonModel {
        pca,
        limits,
        actions: located,
    })
}

/// Normalised trajectories (modes × frames, each in [−1, 1]) of shapes on a model.
pub fn trajectories(model: &PersonModel, coords: &DMatrix<f64>) -> DMatrix<f64> {
    let m = model.pca.components.ncols();
    let mut b = model.pca.project(coords, m);
    for k in 0..m {
        let l = model.limits[k];
        b.row_mut(k)
            .iter_mut()
            .for_each(|v| *v = (*v / l).clamp(-1.0, 1.0));
    }
    b
}

/// One source mode driving one target mode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModePair {
    /// Source mode (0-based).
    pub source_mode: usize,
    /// Target mode (0-based).
    pub target_mode: usize,
    /// Invert the trajectory.
    pub flip: bool,
    /// The action that identified the pair (informative).
    #[serde(default)]
    pub action: String,
}

/// A mode-alignment file: `{"pairs": [{"source_mode": 0, "target_mode": 2, "flip": true}]}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModeAlignment {
    /// The pairs; a source mode appears at most once.
    pub pairs: Vec<ModePair>,
}

impl ModeAlignment {
    /// Reads an alignment file.
    pub fn read(path: &Path) -> Result<ModeAlignment> {
        crate::io::read_json(path)
    }

    /// Pairs the modes of actions both models label alike (the paper aligns by hand; the
    /// labels do it here). Each source mode is used once, by its first action.
    pub fn by_actions(source: &PersonModel, target: &PersonModel) -> ModeAlignment {
        let mut pairs: Vec<ModePair> = Vec::new();
        for (name, sm, ss) in &source.actions {
            if pairs.iter().any(|p| p.source_mode == *sm) {
                continue;
            }
            if let Some((_, tm, ts)) = target.actions.iter().find(|(n, _, _)| n == name) {
                pairs.push(ModePair {
                    source_mode: *sm,
                    target_mode: *tm,
                    flip: ss != ts,
                    action: name.clone(),
                });
            }
        }
        ModeAlignment { pairs }
    }

    /// Checks the modes exist in both models.
    pub fn check(&self, source: &PersonModel, target: &PersonModel) -> Result<()> {
        let (ns, nt) = (source.pca.components.ncols(), target.pca.components.ncols());
        for p in &self.pairs {
            if p.source_mode >= ns || p.target_mode >= nt {
                return Err(Error::invalid(format!(
                    "alignment pair {} → {}: the models have {ns} and {nt} modes",
                    p.source_mode, p.target_mode
                )));
            }
        }
        Ok(())
    }
}

/// The target person's shapes (columns) driven by source trajectories (modes × frames).
pub fn synthesise(
    target: &PersonModel,
    alignment: &ModeAlignment,
    source_traj: &DMatrix<f64>,
) -> DMatrix<f64> {
    let n = source_traj.ncols();
    let mut out = DMatrix::from_fn(target.pca.mean.len(), n, |i, _| target.pca.mean[i]);
    for p in &alignment.pairs {
        let s = if p.flip { -1.0 } else { 1.0 } * target.limits[p.target_mode];
        let u: DVector<f64> = target.pca.components.column(p.target_mode).clone_owned();
        for t in 0..n {
            let w = s * source_traj[(p.source_mode, t)];
            let mut col = out.column_mut(t);
            col.axpy(w, &u, 1.0);
        }
    }
    out
}
