//! Feature-point correspondences between a source layout and a target mesh (paper 004 §2:
//! 15–30 points, e.g. 3 per brow, 2 per eye, 3 nose, 8 mouth).

use keyshape_core::error::{setting, Error, Result};
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
    /// The vertex count of that mesh, when known: a mesh with another count is refused.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_vertices: Option<usize>,
    /// Skin radius factor per group (× distance to the 2nd-nearest other feature point).
    pub radius_factor: BTreeMap<String, f64>,
    /// The feature points.
    pub features: Vec<Feature>,
}

impl Features {
    /// A built-in correspondence: `mediapipe_to_canonical`, `ibug68_to_ict` or
    /// `mediapipe_to_ict` (the latter made from `ibug68_to_ict` through the built-in
    /// 468 → 68 correspondence that `kslab rig` reads MediaPipe tracks by).
    pub fn builtin(name: &str) -> Result<Features> {
        if name == "mediapipe_to_ict" {
            let mut f = Features::builtin("ibug68_to_ict")?;
            let to68 = keyshape_core::sequence::mediapipe_to_ibug68()?;
            for feat in &mut f.features {
                feat.source = *to68.get(feat.source).ok_or_else(|| {
                    Error::invalid(format!(
                        "built-in features: iBUG landmark {} has no MediaPipe point",
                        feat.source
                    ))
                })?;
            }
            f.description = format!(
                "ibug68_to_ict read through the built-in MediaPipe 468 → iBUG 68 correspondence (assets/features/mediapipe468_to_ibug68.json, as kslab rig reads MediaPipe tracks). {}",
                f.description
            );
            f.source_layout = "mediapipe_face_mesh_468".into();
            f.source_points = 468;
            return Ok(f);
        }
        let text = match name {
            "mediapipe_to_canonical" => {
                include_str!("../../../assets/features/mediapipe_to_canonical.json")
            }
            "ibug68_to_ict" => include_str!("../../../assets/features/ibug68_to_ict.json"),
            other => {
                return Err(Error::bad_setting("features", other, format!(
                    "no built-in features '{other}' (mediapipe_to_canonical, ibug68_to_ict, mediapipe_to_ict)"
                )))
            }
        };
        serde_json::from_str(text).map_err(|e| Error::invalid(format!("built-in features: {e}")))
    }

    /// The names of the built-in correspondences.
    pub const BUILTIN: [&'static str; 3] = [
        "mediapipe_to_canonical",
        "ibug68_to_ict",
        "mediapipe_to_ict",
    ];

    /// One line saying what this correspondence fits.
    pub fn fits(&self) -> String {
        format!(
            "{}-point {} tracks onto {}{}",
            self.source_points,
            self.source_layout,
            if self.target.is_empty() {
                "a mesh"
            } else {
                &self.target
            },
            self.target_vertices
                .map_or(String::new(), |v| format!(" ({v} vertices)"))
        )
    }

    /// Errors unless this correspondence was made for a track of `points` landmarks in
    /// `layout` and a mesh of `vertices` vertices. `name` names it in the message.
    pub fn check_fits(
        &self,
        name: &str,
        layout: Option<&str>,
        points: usize,
        vertices: usize,
    ) -> Result<()> {
        let layout_ok = layout.is_none_or(|l| l == self.source_layout);
        let mesh_ok = self.target_vertices.is_none_or(|v| v == vertices);
        if self.source_points == points && layout_ok && mesh_ok {
            return Ok(());
        }
        let track = match layout {
            Some(l) => format!("{points}-point {l} track"),
            None => format!("{points}-point track"),
        };
        let fitting: Vec<String> = Features::BUILTIN
            .iter()
            .filter_map(|b| Features::builtin(b).ok().map(|f| (b, f)))
            .filter(|(_, f)| {
                f.source_points == points
                    && layout.is_none_or(|l| l == f.source_layout)
                    && f.target_vertices.is_none_or(|v| v == vertices)
            })
            .map(|(b, _)| b.to_string())
            .collect();
        let hint = if fitting.is_empty() {
            format!(
                "no built-in correspondence fits a {track} and a {vertices}-vertex mesh: write a features file for them (see assets/features/)"
            )
        } else {
            format!("use {} {}", setting("features"), fitting.join(" or "))
        };
        Err(Error::invalid(format!(
            "features {name} are for {}, not a {track} onto a {vertices}-vertex mesh: {hint}",
            self.fits()
        )))
    }

    /// The correspondence `spec` names (`builtin`: the built-in one that fits; a built-in
    /// name; or a JSON file), checked against the track (`layout`, `points`) and the mesh
    /// (`vertices`) by layout and size, never picked by point count alone.
    pub fn choose(
        spec: &str,
        layout: Option<&str>,
        points: usize,
        vertices: usize,
    ) -> Result<Features> {
        if spec == "builtin" {
            for b in Features::BUILTIN {
                let f = Features::builtin(b)?;
                if f.check_fits(b, layout, points, vertices).is_ok() {
                    return Ok(f);
                }
            }
            let all: Vec<String> = Features::BUILTIN
                .iter()
                .filter_map(|b| {
                    Features::builtin(b)
                        .ok()
                        .map(|f| format!("{b} fits {}", f.fits()))
                })
                .collect();
            let track = layout.map_or(format!("{points}-point track"), |l| {
                format!("{points}-point {l} track")
            });
            return Err(Error::invalid(format!(
                "no built-in feature correspondence fits a {track} onto a {vertices}-vertex mesh ({}); give {} FILE",
                all.join("; "),
                setting("features")
            )));
        }
        let (f, name) = if Features::BUILTIN.contains(&spec) {
            (Features::builtin(spec)?, spec.to_string())
        } else {
            (Features::read(Path::new(spec))?, spec.to_string())
        };
        f.check_fits(&name, layout, points, vertices)?;
        Ok(f)
    }

    /// Reads a correspondence file.
    pub fn read(path: &Path) -> Result<Features> {
        keyshape_io::read_json(path)
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
                    return Err(Error::unfit(format!(
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
                return Err(Error::bad_setting(
                    "feature_groups",
                    g,
                    format!(
                        "no feature group '{g}' (groups: {})",
                        known.into_iter().collect::<Vec<_>>().join(", ")
                    ),
                ));
            }
        }
        Ok(self
            .features
            .iter()
            .map(|f| gs.contains(&f.group))
            .collect())
    }
}
