//! Target key shapes: one target shape Bᵢ per source key frame, any point count and
//! dimension, read from JSON (or from an SVG template, see [`crate::svg`]), or made by
//! the built-in cartoon warp.

use keyshape_core::error::{Error, Result};
use keyshape_core::rbf::Rbf;
use keyshape_core::sequence::Layout;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// One target shape, tied to the source frame it stands for.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TargetKey {
    /// The source frame number this shape corresponds to.
    pub frame: i64,
    /// Flat coordinates, `dims` per point.
    pub coords: Vec<f64>,
}

/// A target set as stored in JSON:
///
/// ```json
/// { "kslab_target": 1, "dims": 2, "points": 3, "polylines": [[0, 1, 2, 0]],
///   "keys": [ { "frame": 12, "coords": [x0, y0, x1, y1, x2, y2] }, … ],
///   "neutral": { "frame": 0, "coords": [ … ] } }
/// ```
/// `polylines` (optional) say how to draw the target; `neutral` is needed for delta mode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TargetSet {
    /// Format version, 1.
    pub kslab_target: u32,
    /// 2 or 3.
    pub dims: usize,
    /// Points per target shape.
    pub points: usize,
    /// Drawing contours (point indices; a loop repeats its first index).
    #[serde(default)]
    pub polylines: Vec<Vec<usize>>,
    /// One shape per source key frame.
    pub keys: Vec<TargetKey>,
    /// The target's neutral shape (delta mode).
    #[serde(default)]
    pub neutral: Option<TargetKey>,
}

impl TargetSet {
    /// Reads and checks a JSON target set.
    pub fn read_json(path: &Path) -> Result<TargetSet> {
        let text = keyshape_io::read_text(path)?;
        let t: TargetSet = serde_json::from_str(&text)
            .map_err(|e| Error::parse(path, e.line() as u64, e.column() as u64, e.to_string()))?;
        t.check().map_err(|e| Error::file(path, e.to_string()))?;
        Ok(t)
    }

    /// Checks counts, finiteness and polylines.
    pub fn check(&self) -> Result<()> {
        if self.dims != 2 && self.dims != 3 {
            return Err(Error::bad_setting(
                "dims",
                self.dims,
                format!("dims must be 2 or 3, got {}", self.dims),
            ));
        }
        let want = self.dims * self.points;
        for (i, k) in self.keys.iter().chain(self.neutral.iter()).enumerate() {
            if k.coords.len() != want {
                return Err(Error::invalid(format!(
                    "target shape {i} (frame {}) has {} coordinates; dims {} × points {} = {want} — target shapes must all have the same point count",
                    k.frame,
                    k.coords.len(),
                    self.dims,
                    self.points
                )));
            }
            if k.coords.iter().any(|v| !v.is_finite()) {
                return Err(Error::invalid(format!(
                    "target shape for frame {} has a non-finite coordinate",
                    k.frame
                )));
            }
        }
        if let Some(bad) = self.polylines.iter().flatten().find(|&&p| p >= self.points) {
            return Err(Error::invalid(format!(
                "polyline names point {bad}, but target shapes have {} points",
                self.points
            )));
        }
        Ok(())
    }

    /// The target shapes for source key frames `frames`, as columns, in that order. Every
    /// key needs exactly one target shape: missing and extra shapes are errors.
    pub fn for_frames(&self, frames: &[i64]) -> Result<DMatrix<f64>> {
        let by_frame: BTreeMap<i64, &TargetKey> = self.keys.iter().map(|k| (k.frame, k)).collect();
        if by_frame.len() != self.keys.len() {
            return Err(Error::invalid(
                "target set has two shapes for the same frame",
            ));
        }
        let missing: Vec<i64> = frames
            .iter()
            .copied()
            .filter(|f| !by_frame.contains_key(f))
            .collect();
        let extra: Vec<i64> = by_frame
            .keys()
            .copied()
            .filter(|f| !frames.contains(f))
            .collect();
        if !missing.is_empty() || !extra.is_empty() {
            return Err(Error::invalid(format!(
                "the target has {} shapes for {} key frames: missing frames {missing:?}, extra frames {extra:?}",
                self.keys.len(),
                frames.len()
            )));
        }
        let cols: Vec<DVector<f64>> = frames
            .iter()
            .map(|f| DVector::from_vec(by_frame[f].coords.clone()))
            .collect();
        Ok(DMatrix::from_columns(&cols))
    }
}

#[derive(Debug, Deserialize)]
struct CartoonFile {
    iod_points: BTreeMap<String, [usize; 2]>,
    /// A warp of the whole face about the centroid of all its points: it moves each group's
    /// centre (a narrower face brings eyes and brows closer together); each group's own
    /// scale is then about that moved centre, relative to the group's source size. (Scaling
    /// each feature about a fixed centre let the widened brows cross the narrowed outline.)
    #[serde(default)]
    face: Option<GroupWarp>,
    groups: BTreeMap<String, GroupWarp>,
}

#[derive(Debug, Deserialize)]
struct GroupWarp {
    #[serde(default)]
    scale: Option<f64>,
    #[serde(default)]
    scale_x: Option<f64>,
    #[serde(default)]
    scale_y: Option<f64>,
    #[serde(default)]
    shift: [f64; 2],
}

impl GroupWarp {
    /// (x, y) scale factors: `scale_x`/`scale_y` where given, else `scale`, else 1.
    fn scales(&self) -> (f64, f64) {
        (
            self.scale_x.or(self.scale).unwrap_or(1.0),
            self.scale_y.or(self.scale).unwrap_or(1.0),
        )
    }
}

const CARTOON: &str = include_str!("../../../assets/targets/cartoon.json");

/// Inter-ocular distance of a flat 2-D mean shape of the full layout (outer eye corners).
pub fn iod(mean: &[f64], layout: &Layout) -> Result<f64> {
    let file: CartoonFile = serde_json::from_str(CARTOON)
        .map_err(|e| Error::invalid(format!("built-in cartoon: {e}")))?;
    let [a, b] = *file.iod_points.get(layout.family()).ok_or_else(|| {
        Error::invalid(format!("no eye corners known for layout {}", layout.name))
    })?;
    Ok(((mean[2 * a] - mean[2 * b]).powi(2) + (mean[2 * a + 1] - mean[2 * b + 1]).powi(2)).sqrt())
}

/// Control points per group at most (evenly spaced through the group's points).
const CONTROLS_PER_GROUP: usize = 24;

/// The built-in cartoon warp G for a 2-D layout, fitted on the source mean shape `mean`
/// (flat, all the layout's points): eyes and mouth enlarged about their centres, brows
/// raised, jaw narrowed, as `assets/targets/cartoon.json` says, and a multiquadric RBF
/// (paper 004) through the groups' points so that G maps any point smoothly.
pub fn cartoon_warp(mean: &[f64], layout: &Layout) -> Result<Rbf> {
    let file: CartoonFile = serde_json::from_str(CARTOON)
        .map_err(|e| Error::invalid(format!("built-in cartoon: {e}")))?;
    let pt = |i: usize| [mean[2 * i], mean[2 * i + 1]];
    let [a, b] = *file.iod_points.get(layout.family()).ok_or_else(|| {
        Error::invalid(format!(
            "the built-in cartoon target has no rule for layout {}",
            layout.name
        ))
    })?;
    let iod = ((pt(a)[0] - pt(b)[0]).powi(2) + (pt(a)[1] - pt(b)[1]).powi(2)).sqrt();
    let centre = |points: &mut dyn Iterator<Item = [f64; 2]>| {
        let (mut c, mut n) = ([0.0, 0.0], 0.0);
        for q in points {
            c = [c[0] + q[0], c[1] + q[1]];
            n += 1.0;
        }
        [c[0] / n, c[1] / n]
    };
    let face = file.face.as_ref();
    let fc = centre(&mut (0..mean.len() / 2).map(pt));
    let (fx, fy) = face.map_or((1.0, 1.0), GroupWarp::scales);
    let fshift = face.map_or([0.0, 0.0], |w| w.shift);
    let narrowed = |q: [f64; 2]| {
        [
            fc[0] + fx * (q[0] - fc[0]) + fshift[0] * iod,
            fc[1] + fy * (q[1] - fc[1]) + fshift[1] * iod,
        ]
    };
    let (mut src, mut dst) = (Vec::new(), Vec::new());
    let mut used = std::collections::BTreeSet::new();
    for (name, warp) in &file.groups {
        let Some(group) = layout.groups.get(name) else {
            continue;
        };
        // The face warp moves the group's centre; the group's own scale is relative to
        // its size in the source (so "lips × 1.5" is 1.5 × the source's mouth).
        let c = centre(&mut group.points.iter().map(|&p| pt(p)));
        let nc = narrowed(c);
        let moved = [nc[0] - c[0], nc[1] - c[1]];
        let (sx, sy) = warp.scales();
        let step = group.points.len().div_ceil(CONTROLS_PER_GROUP).max(1);
        for &p in group.points.iter().step_by(step) {
            if !used.insert(p) {
                continue;
            }
            let q = pt(p);
            src.extend_from_slice(&q);
            dst.push(c[0] + moved[0] + sx * (q[0] - c[0]) + warp.shift[0] * iod);
            dst.push(c[1] + moved[1] + sy * (q[1] - c[1]) + warp.shift[1] * iod);
        }
    }
    Rbf::fit(&src, &dst, 2)
}
