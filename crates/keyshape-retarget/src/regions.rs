//! Face regions (paper 000 §5): "the eye region and the mouth region are modelled
//! separately … the resulting faces are blended with linear weights in the intermediate
//! region". Regions are data (`assets/regions/<layout>.json` or a user file).

use keyshape_core::error::{Error, Result};
use keyshape_core::sequence::Layout;
use nalgebra::DMatrix;
use serde::Deserialize;
use std::path::Path;

/// One region: layout groups and its number of key shapes.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionDef {
    /// Name (e.g. `eyes`).
    pub name: String,
    /// Layout groups it covers.
    pub groups: Vec<String>,
    /// Its number of key shapes.
    pub k: usize,
}

/// A regions file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Regions {
    /// Layout the group names refer to.
    pub layout: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// The regions.
    pub regions: Vec<RegionDef>,
    /// Points in no region are blended between the regions too (else they are an error).
    #[serde(default)]
    pub blend_rest: bool,
}

impl Regions {
    /// The built-in regions of a layout.
    pub fn builtin(layout: &Layout) -> Result<Regions> {
        keyshape_io::builtin_json(
            "regions",
            layout.family(),
            &[
                (
                    "mediapipe_face_mesh_468",
                    include_str!("../../../assets/regions/mediapipe_face_mesh_468.json"),
                ),
                (
                    "ibug68",
                    include_str!("../../../assets/regions/ibug68.json"),
                ),
            ],
        )
    }

    /// Reads a regions file.
    pub fn read(path: &Path) -> Result<Regions> {
        keyshape_io::read_json(path)
    }
}

/// Regions resolved against a point selection.
#[derive(Debug, Clone)]
pub struct RegionPlan {
    /// Region names.
    pub names: Vec<String>,
    /// Per region: indices (into the selection) of the points whose fit it uses.
    pub members: Vec<Vec<usize>>,
    /// Per region: key shapes.
    pub k: Vec<usize>,
    /// Blend weight of each region at each selected point (points × regions, rows sum to 1).
    pub blend: DMatrix<f64>,
}

/// Resolves `regions` for the selected points (`selected[i]` = layout index of selection
/// point i) with `mean` the flat 2-D mean shape of the selection. A point in one region
/// belongs to it; a point in several, or (with `blend_rest`) in none, is blended linearly
/// between the two nearest region centres by its position along the line joining them.
pub fn plan(
    regions: &Regions,
    layout: &Layout,
    selected: &[usize],
    mean: &[f64],
    dims: usize,
) -> Result<RegionPlan> {
    if regions.layout != layout.family() {
        return Err(Error::invalid(format!(
            "regions are for layout {}, the sequence is {}",
            regions.layout, layout.name
        )));
    }
    if regions.regions.is_empty() {
        return Err(Error::invalid("regions file lists no regions"));
    }
    let mut members = Vec::new();
    for r in &regions.regions {
        let pts = layout.select(&r.groups.join(","))?;
        let m: Vec<usize> = (0..selected.len())
            .filter(|&i| pts.binary_search(&selected[i]).is_ok())
            .collect();
        if m.is_empty() {
            return Err(Error::invalid(format!(
                "region '{}' covers none of the selected points",
                r.name
            )));
        }
        if r.k == 0 {
            return Err(Error::bad_setting(
                "k",
                0,
                format!("region '{}' has k = 0", r.name),
            ));
        }
        members.push(m);
    }
    let nr = members.len();
    let centre = |m: &[usize]| {
        let n = m.len() as f64;
        m.iter().fold([0.0, 0.0], |c, &i| {
            [c[0] + mean[i * dims] / n, c[1] + mean[i * dims + 1] / n]
        })
    };
    let centres: Vec<[f64; 2]> = members.iter().map(|m| centre(m)).collect();
    let mut blend = DMatrix::zeros(selected.len(), nr);
    let mut uncovered = 0;
    for i in 0..selected.len() {
        let inside: Vec<usize> = (0..nr).filter(|&r| members[r].contains(&i)).collect();
        if inside.len() == 1 || nr == 1 {
            blend[(i, inside.first().copied().unwrap_or(0))] = 1.0;
            continue;
        }
        if inside.is_empty() && !regions.blend_rest {
            uncovered += 1;
            continue;
        }
        let cand: Vec<usize> = if inside.is_empty() {
            (0..nr).collect()
        } else {
            inside
        };
        let p = [mean[i * dims], mean[i * dims + 1]];
        let d2 = |r: usize| (p[0] - centres[r][0]).powi(2) + (p[1] - centres[r][1]).powi(2);
        let mut by = cand.clone();
        by.sort_by(|&a, &b| d2(a).total_cmp(&d2(b)));
        let (a, b) = (by[0], by[1]);
        let (ca, cb) = (centres[a], centres[b]);
        let axis = [cb[0] - ca[0], cb[1] - ca[1]];
        let len2 = axis[0] * axis[0] + axis[1] * axis[1];
        let t = if len2 > 0.0 {
            (((p[0] - ca[0]) * axis[0] + (p[1] - ca[1]) * axis[1]) / len2).clamp(0.0, 1.0)
        } else {
            0.5
        };
        blend[(i, a)] = 1.0 - t;
        blend[(i, b)] = t;
    }
    if uncovered > 0 {
        return Err(Error::invalid(format!(
            "regions leave {uncovered} of the {} selected points uncovered (add their groups, or set \"blend_rest\": true)",
            selected.len()
        )));
    }
    Ok(RegionPlan {
        names: regions.regions.iter().map(|r| r.name.clone()).collect(),
        members,
        k: regions.regions.iter().map(|r| r.k).collect(),
        blend,
    })
}
