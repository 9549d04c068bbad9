//! Feature-point correspondences between a source layout and a target mesh (paper 004 §2:
//! 15–30 points, e.g. 3 per brow, 2 per eye, 3 nose, 8 mouth).

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// One feature point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Feature {
    /// Name (e.g. `mouth_left`).
    pub name: String,
    /// Group (brows, eyes, nose, mouth, jaw …) for partial retargeting and skin radii.
    pub group: String,
    /// Landmark index in the source layout.
    pub source: usize,
    /// Vertex index in the target mesh.
    pub target: usize,
}

/// A correspondence file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Features {
    /// Format version, 1.
    pub kslab_features: u32,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// Source layout name.
    pub source_layout: String,
    /// Source point count.
    pub source_points: usize,
    /// What mesh the target indices refer to.
    #[serde(default)]
    pub target: String,
    /// Skin radius factor per group (× distance to the 2nd-nearest other feature point).
    pub radius_factor: BTreeMap<String, f64>,
    /// The feature points.
    pub features: Vec<Feature>,
}

impl Features {
    /// A built-in correspondence: `mediapipe_to_canonical` or `ibug68_to_ict`.
    pub fn builtin(name: &str) -> Result<Features> {
        let text = match name {
            "mediapipe_to_canonical" => {
                include_str!("../../assets/features/mediapipe_to_canonical.json")
            }
            "ibug68_to_ict" => include_str!("../../assets/features/ibug68_to_ict.json"),
            other => {
                return Err(Error::invalid(format!(
                    "no built-in features '{other}' (mediapipe_to_canonical, ibug68_to_ict)"
                )))
            }
        };
        serde_json::from_str(text).map_err(|e| Error::invalid(format!("built-in features: {e}")))
    }

    /// The built-in correspondence for a source point count.
    pub fn builtin_for(points: usize) -> Result<Features> {
        match points {
            468 => Features::builtin("mediapipe_to_canonical"),
            68 => Features::builtin("ibug68_to_ict"),
            n => Err(Error::invalid(format!(
                "no built-in features for {n}-point sequences: give --features"
            ))),
        }
    }

    /// Reads a correspondence file.
    pub fn read(path: &Path) -> Result<Features> {
        crate::io::read_json(path)
    }

    /// Checks the indices against a source with `points` landmarks and a mesh with
    /// `vertices` vertices; duplicate feature points are errors (they make H singular).
    pub fn check(&self, points: usize, vertices: usize) -> Result<()> {
        if self.features.is_empty() {
            return Err(Error::invalid("the correspondence lists no feature points"));
        }
        for f in &self.features {
            if f.source >= points {
                return Err(Error::invalid(format!(
                    "feature '{}' names source landmark {}, but the sequence has {points}",
                    f.name, f.source
                )));
            }
            if f.target >= vertices {
                return Err(Error::invalid(format!(
                    "feature '{}' names target vertex {}, but the mesh has {vertices}",
                    f.name, f.target
                )));
            }
        }
        for (i, a) in self.features.iter().enumerate() {
            for b in &self.features[..i] {
                if a.source == b.source || a.target == b.target {
                    return Err(Error::invalid(format!(
                        "features '{}' and '{}' share a point (the RBF system would be singular)",
                        b.name, a.name
                    )));
                }
            }
        }
        Ok(())
    }

    /// Which features belong to the enabled groups (all when `groups` is None).
    pub fn enabled(&self, groups: Option<&[String]>) -> Result<Vec<bool>> {
        let Some(gs) = groups else {
            return Ok(vec![true; self.features.len()]);
        };
        for g in gs {
            if !self.features.iter().any(|f| &f.group == g) {
                let known: std::collections::BTreeSet<&str> =
                    self.features.iter().map(|f| f.group.as_str()).collect();
                return Err(Error::invalid(format!(
                    "no feature group '{g}' (groups: {})",
                    known.into_iter().collect::<Vec<_>>().join(", ")
                )));
            }
        }
        Ok(self
            .features
            .iter()
            .map(|f| gs.contains(&f.group))
            .collect())
    }
}
