//! Action-mode trajectories and their mapping between people (paper 002 §3.2).
//!
//! A performance projected on an action-specific model gives one weight track per mode;
//! each track is normalised to [−1, 1] as §3.2 says, "by dividing through by their maximum
//! or minimum value": positive values by the largest value over the model's training
//! frames, negative values by the magnitude of the smallest, so both observed extremes map
//! to ±1 ([`Normalisation::TwoSided`]). The older one-sided variant divides both sides by
//! the largest magnitude, which leaves one side short of ±1
//! ([`Normalisation::OneSided`]). A mode-alignment table maps a source mode to a target mode (with a sign flip
//! where the two models encode the action in opposite directions), and the normalised
//! tracks, scaled by the target's own extremes, synthesise the target person's shapes.

use crate::modes::{action_vectors, artificial_pca, Actions, Region};
use keyshape_core::error::{Error, Result};
use keyshape_core::pca::Pca;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// How a mode's trajectory is scaled into [−1, 1] (and back onto another person).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Normalisation {
    /// The paper's: positive values over the training maximum, negative values over the
    /// magnitude of the training minimum; both extremes map to ±1.
    #[default]
    TwoSided,
    /// Both sides over the largest magnitude (one side then stops short of ±1).
    OneSided,
}

impl std::str::FromStr for Normalisation {
    type Err = keyshape_core::error::Error;

    /// The option's spelling on the command line and in experiment files.
    fn from_str(s: &str) -> keyshape_core::error::Result<Normalisation> {
        match s {
            "two-sided" => Ok(Normalisation::TwoSided),
            "one-sided" => Ok(Normalisation::OneSided),
            _ => Err(keyshape_core::error::Error::bad_setting(
                "trajectory_normalise",
                s,
                format!("'{s}': choose two-sided or one-sided"),
            )),
        }
    }
}

impl Normalisation {
    /// `two-sided` or `one-sided`.
    pub fn name(self) -> &'static str {
        match self {
            Normalisation::TwoSided => "two-sided",
            Normalisation::OneSided => "one-sided",
        }
    }

    /// The scale of a value `v` on a mode whose training weights span `[lower, upper]`
    /// (`lower` ≤ 0 ≤ `upper`, each side at least `f64::MIN_POSITIVE` in magnitude).
    pub fn scale(self, v: f64, lower: f64, upper: f64) -> f64 {
        match self {
            Normalisation::OneSided => upper.max(-lower),
            Normalisation::TwoSided if v >= 0.0 => upper,
            Normalisation::TwoSided => -lower,
        }
    }
}

/// An action-specific model of one person with its actions located on its modes.
#[derive(Debug, Clone)]
pub struct PersonModel {
    /// PCA of the artificial (region-wise) training set.
    pub pca: Pca,
    /// Per mode: the smallest weight over the person's training frames (≤ −MIN_POSITIVE).
    pub lower: Vec<f64>,
    /// Per mode: the largest weight over the person's training frames (≥ MIN_POSITIVE).
    pub upper: Vec<f64>,
    /// How trajectories are normalised by `lower` and `upper`.
    pub normalisation: Normalisation,
    /// Per action: (name, mode, sign of the action along the mode).
    pub actions: Vec<(String, usize, f64)>,
}

/// Builds a person's model from their aligned shapes and action labels.
pub fn person_model(
    coords: &DMatrix<f64>,
    frames: &[i64],
    dims: usize,
    regions: &[Region],
    actions: &Actions,
    modes: usize,
    normalisation: Normalisation,
) -> Result<PersonModel> {
    crate::modes::need_modes(modes, "a person's model")?;
    let pca = artificial_pca(coords, regions, dims, modes)?;
    let m = pca.components.ncols();
    if m == 0 {
        return Err(keyshape_core::Error::unfit(
            "an action-specific model: the regions' training set does not vary (no mode)",
        ));
    }
    let b = pca.project(coords, m);
    let upper: Vec<f64> = (0..m)
        .map(|k| b.row(k).iter().fold(f64::MIN_POSITIVE, |a, &v| a.max(v)))
        .collect();
    let lower: Vec<f64> = (0..m)
        .map(|k| b.row(k).iter().fold(-f64::MIN_POSITIVE, |a, &v| a.min(v)))
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
        lower,
        upper,
        normalisation,
        actions: located,
    })
}

/// Normalised trajectories (modes × frames, each in [−1, 1]) of shapes on a model.
pub fn trajectories(model: &PersonModel, coords: &DMatrix<f64>) -> DMatrix<f64> {
    let m = model.pca.components.ncols();
    let mut b = model.pca.project(coords, m);
    for k in 0..m {
        let (lo, hi) = (model.lower[k], model.upper[k]);
        b.row_mut(k).iter_mut().for_each(|v| {
            *v = (*v / model.normalisation.scale(*v, lo, hi)).clamp(-1.0, 1.0);
        });
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
        keyshape_io::read_json(path)
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

/// The target person's shapes (columns) driven by source trajectories (modes × frames):
/// each normalised value, flipped where the pair says so, scaled by the target's own
/// extreme on that side (two-sided) or its largest magnitude (one-sided).
pub fn synthesise(
    target: &PersonModel,
    alignment: &ModeAlignment,
    source_traj: &DMatrix<f64>,
) -> DMatrix<f64> {
    let n = source_traj.ncols();
    let mut out = DMatrix::from_fn(target.pca.mean.len(), n, |i, _| target.pca.mean[i]);
    // Each target mode once, driven by every pair that names it.
    let mut modes: Vec<usize> = alignment.pairs.iter().map(|p| p.target_mode).collect();
    modes.sort_unstable();
    modes.dedup();
    for m in modes {
        let pairs: Vec<&ModePair> = alignment
            .pairs
            .iter()
            .filter(|p| p.target_mode == m)
            .collect();
        let (lo, hi) = (target.lower[m], target.upper[m]);
        let u: DVector<f64> = target.pca.components.column(m).clone_owned();
        // On a shared mode each pair drives only its own action's side (the target's
        // model says which): the other side of a smile mode is not a pucker.
        let sides: Vec<Option<f64>> = pairs
            .iter()
            .map(|p| {
                (pairs.len() > 1)
                    .then(|| {
                        target
                            .actions
                            .iter()
                            .find(|(name, mode, _)| *name == p.action && *mode == m)
                            .map(|a| a.2)
                    })
                    .flatten()
            })
            .collect();
        for t in 0..n {
            let vs = pairs.iter().zip(&sides).map(|(p, side)| {
                let sign = if p.flip { -1.0 } else { 1.0 };
                let v = sign * source_traj[(p.source_mode, t)];
                match side {
                    Some(s) if v * s < 0.0 => 0.0,
                    _ => v,
                }
            });
            let v = combine(vs);
            let w = v * target.normalisation.scale(v, lo, hi);
            let mut col = out.column_mut(t);
            col.axpy(w, &u, 1.0);
        }
    }
    out
}

/// The value of a target mode that several pairs drive (the target's model put two actions,
/// say jaw drop and pucker, on its two sides), from each pair's normalised value (already
/// cut to its action's side): their mean weighted by |v|², so the action the source
/// performs more drives the mode
/// (continuously: equal and opposite values give 0). Added up, as before, the other
/// action's trajectory cancelled the first — a jaw drop mapped to a closed mouth. One pair
/// gives its own value.
pub fn combine(vs: impl Iterator<Item = f64>) -> f64 {
    let (mut num, mut den, mut count, mut only) = (0.0, 0.0, 0, 0.0);
    for v in vs {
        num += v * v * v;
        den += v * v;
        count += 1;
        only = v;
    }
    match count {
        1 => only,
        _ if den > 0.0 => num / den,
        _ => 0.0,
    }
}

/// Where a source extreme lands on the target under each normalisation, for one mode pair
/// and one side of the source mode.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ExtremeRow {
    /// The action that identified the pair.
    pub action: String,
    /// Source mode.
    pub source_mode: usize,
    /// Target mode.
    pub target_mode: usize,
    /// `+` for the source's maximum, `-` for its minimum.
    pub side: String,
    /// The source's training extreme on that side.
    pub source_extreme: f64,
    /// The target's training extreme on the side it maps to (after any flip).
    pub target_extreme: f64,
    /// The target weight reached, two-sided (equals `target_extreme`).
    pub two_sided: f64,
    /// The target weight reached, one-sided.
    pub one_sided: f64,
    /// `one_sided / two_sided`: 1 when both people's modes are symmetric.
    pub ratio: f64,
}

/// For every pair and both sides of its source mode, the target weight a source extreme
/// maps to under each normalisation (what the paper's "observed extrema … relate to the
/// same observed extrema" asks for is a ratio of 1).
pub fn extremes(
    source: &PersonModel,
    target: &PersonModel,
    alignment: &ModeAlignment,
) -> Vec<ExtremeRow> {
    let mut rows = Vec::new();
    for p in &alignment.pairs {
        let (slo, shi) = (source.lower[p.source_mode], source.upper[p.source_mode]);
        let (tlo, thi) = (target.lower[p.target_mode], target.upper[p.target_mode]);
        let sign = if p.flip { -1.0 } else { 1.0 };
        for (side, s) in [("+", shi), ("-", slo)] {
            let map = |n: Normalisation| {
                let v = (s / n.scale(s, slo, shi)).clamp(-1.0, 1.0) * sign;
                v * n.scale(v, tlo, thi)
            };
            let (two, one) = (map(Normalisation::TwoSided), map(Normalisation::OneSided));
            rows.push(ExtremeRow {
                action: p.action.clone(),
                source_mode: p.source_mode,
                target_mode: p.target_mode,
                side: side.to_string(),
                source_extreme: s,
                target_extreme: if sign * s >= 0.0 { thi } else { tlo },
                two_sided: two,
                one_sided: one,
                ratio: one / two,
            });
        }
    }
    rows
}

#[cfg(test)]
mod combine_tests {
    use super::combine;

    #[test]
    fn the_action_performed_more_drives_a_shared_mode() {
        assert_eq!(combine([0.7].into_iter()), 0.7);
        // Jaw drop at its extreme, the flipped pucker trajectory against it.
        let jaw = combine([1.0, -0.4].into_iter());
        assert!(jaw > 0.8, "{jaw}");
        let pucker = combine([0.1, -0.9].into_iter());
        assert!(pucker < -0.85, "{pucker}");
        assert_eq!(combine([0.5, -0.5].into_iter()), 0.0);
        assert_eq!(combine([0.0, 0.0].into_iter()), 0.0);
        // Never beyond the largest magnitude given.
        let v = combine([0.9, 0.3, -0.2].into_iter());
        assert!(v <= 0.9 && v > 0.7, "{v}");
    }
}
