//! Morph targets (paper 002 §3.3, Eq. 8): `E = N + Σ (m(i) − N) w(i)`, w in [0, 1], on
//! the ICT face's expression shapes (sparse offsets from its neutral), driven by action
//! trajectories through a mapping file (action → shape names with gains).

use keyshape_core::error::{Error, Result};
use keyshape_io::morph::MorphTargets;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;

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
        serde_json::from_str(include_str!(
            "../../../assets/actions/morph_mapping_ict.json"
        ))
        .map_err(|e| Error::invalid(format!("built-in mapping: {e}")))
    }

    /// Reads a mapping file.
    pub fn read(path: &Path) -> Result<MorphMapping> {
        keyshape_io::read_json(path)
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
