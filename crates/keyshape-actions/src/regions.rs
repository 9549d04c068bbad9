//! The face regions of paper 002's action-specific modes (§3.1), and how a region's offsets
//! fade at its boundary.
//!
//! As in the paper, the regions overlap (the forehead R1 contains both brows, R3 and R4) and
//! a region's boundary is **blended**: each point carries a weight in [0, 1], the region's
//! indicator passed through an averaging filter over the mean shape (the mean of the
//! indicator over the points within a radius), so the offsets fade out across a band of
//! points instead of stopping at the region's edge ([`Boundary::Blended`]). The disjoint
//! variant ([`Boundary::Disjoint`]: weight 1 inside, 0 outside) makes the covariance of
//! non-overlapping regions block-diagonal, so their cross terms in Table 2 are 0 by
//! construction; it is kept only as an explicitly named option.

use keyshape_core::error::{Error, Result};
use keyshape_core::sequence::Layout;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
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
    /// Regions that tile the face between them (the paper's R1 and R2): every point no
    /// region's groups name joins the region of the nearest named point of these regions in
    /// the mean shape, so they meet at a boundary (which blending then softens) instead of
    /// leaving cheeks and forehead at the mean.
    #[serde(default)]
    pub cover: Vec<String>,
}

impl ModeRegions {
    /// The built-in regions of a layout.
    pub fn builtin(layout: &Layout) -> Result<ModeRegions> {
        keyshape_io::builtin_json(
            "Cosker regions",
            layout.family(),
            &[
                (
                    "mediapipe_face_mesh_468",
                    include_str!("../../../assets/actions/regions_mediapipe_face_mesh_468.json"),
                ),
                (
                    "ibug68",
                    include_str!("../../../assets/actions/regions_ibug68.json"),
                ),
            ],
        )
    }

    /// Reads a regions file.
    pub fn read(path: &Path) -> Result<ModeRegions> {
        keyshape_io::read_json(path)
    }

    /// Point indices of each region (name order); unknown groups and empty regions are errors.
    pub fn points(&self, layout: &Layout) -> Result<Vec<(String, Vec<usize>)>> {
        if self.layout != layout.family() {
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

    /// Gives every point no region names to the `cover` region of its nearest named point.
    fn fill_cover(
        &self,
        regions: &mut [(String, Vec<usize>)],
        mean: &[f64],
        dims: usize,
    ) -> Result<()> {
        if self.cover.is_empty() {
            return Ok(());
        }
        let idx: Vec<usize> = self
            .cover
            .iter()
            .map(|c| {
                regions.iter().position(|r| &r.0 == c).ok_or_else(|| {
                    Error::invalid(format!(
                        "cover names region '{c}', which the file does not define"
                    ))
                })
            })
            .collect::<Result<_>>()?;
        let n = mean.len() / dims.max(1);
        let mut named = vec![false; n];
        for (_, pts) in regions.iter() {
            for &p in pts {
                if p < n {
                    named[p] = true;
                }
            }
        }
        let owners: Vec<(usize, usize)> = idx
            .iter()
            .flat_map(|&r| regions[r].1.iter().map(move |&p| (p, r)))
            .filter(|&(p, _)| p < n)
            .collect();
        let at = |p: usize| &mean[p * dims..(p + 1) * dims];
        let d2 = |a: usize, b: usize| -> f64 {
            at(a)
                .iter()
                .zip(at(b))
                .map(|(x, y)| (x - y) * (x - y))
                .sum()
        };
        let mut extra: Vec<(usize, usize)> = Vec::new();
        for p in (0..n).filter(|&p| !named[p]) {
            if let Some(&(_, r)) = owners
                .iter()
                .min_by(|a, b| d2(p, a.0).total_cmp(&d2(p, b.0)))
            {
                extra.push((r, p));
            }
        }
        for (r, p) in extra {
            regions[r].1.push(p);
        }
        Ok(())
    }

    /// Each region's per-point weights on the mean of `coords` (shapes as columns, `dims`
    /// values per point), by [`region_weights`].
    pub fn weights(
        &self,
        layout: &Layout,
        coords: &DMatrix<f64>,
        dims: usize,
        opts: &RegionOptions,
    ) -> Result<Vec<Region>> {
        let mean = coords.column_mean();
        let mut regions = self.points(layout)?;
        self.fill_cover(&mut regions, mean.as_slice(), dims)?;
        regions
            .into_iter()
            .map(|(name, pts)| {
                Ok(Region {
                    weights: region_weights(mean.as_slice(), dims, &pts, opts)?,
                    name,
                })
            })
            .collect()
    }
}

/// How a region's boundary meets the mean shape.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Boundary {
    /// The paper's: the region's indicator through an averaging filter of radius
    /// [`RegionOptions::blend_radius`] over the mean shape.
    #[default]
    Blended,
    /// Weight 1 on the region's points, 0 elsewhere (non-overlapping regions then give
    /// exactly 0 cross terms in Table 2, by construction).
    Disjoint,
}

impl std::str::FromStr for Boundary {
    type Err = keyshape_core::error::Error;

    /// The option's spelling on the command line and in experiment files.
    fn from_str(s: &str) -> keyshape_core::error::Result<Boundary> {
        match s {
            "blended" => Ok(Boundary::Blended),
            "disjoint" => Ok(Boundary::Disjoint),
            _ => Err(keyshape_core::error::Error::bad_setting(
                "boundaries",
                s,
                format!("'{s}': choose blended or disjoint"),
            )),
        }
    }
}

impl Boundary {
    /// `blended` or `disjoint`.
    pub fn name(self) -> &'static str {
        match self {
            Boundary::Blended => "blended",
            Boundary::Disjoint => "disjoint",
        }
    }
}

/// The default averaging-filter radius, as a fraction of the mean shape's size (the RMS
/// distance of its points from their centroid).
pub const DEFAULT_BLEND_RADIUS: f64 = 0.15;

/// How regions become per-point weights.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RegionOptions {
    /// Blended or disjoint.
    pub boundary: Boundary,
    /// Averaging-filter radius (blended only), as a fraction of the mean shape's size.
    pub blend_radius: f64,
}

impl Default for RegionOptions {
    fn default() -> Self {
        RegionOptions {
            boundary: Boundary::Blended,
            blend_radius: DEFAULT_BLEND_RADIUS,
        }
    }
}

impl RegionOptions {
    /// Options from what a user gave: a radius only applies to blended boundaries, so a
    /// radius with `disjoint` is an error rather than ignored.
    pub fn from_user(boundary: Boundary, blend_radius: Option<f64>) -> Result<RegionOptions> {
        if boundary == Boundary::Disjoint && blend_radius.is_some() {
            return Err(Error::invalid(
                "a blend radius applies only to blended region boundaries, not to disjoint ones",
            ));
        }
        let o = RegionOptions {
            boundary,
            blend_radius: blend_radius.unwrap_or(DEFAULT_BLEND_RADIUS),
        };
        o.check()?;
        Ok(o)
    }

    /// Checks the radius (finite, ≥ 0).
    pub fn check(&self) -> Result<()> {
        if !(self.blend_radius.is_finite() && self.blend_radius >= 0.0) {
            return Err(Error::bad_setting(
                "blend_radius",
                self.blend_radius,
                format!(
                    "blend radius {} must be a finite number ≥ 0 (a fraction of the face's size)",
                    self.blend_radius
                ),
            ));
        }
        Ok(())
    }
}

/// A region as per-point weights in [0, 1] (one per point): the share of each point's
/// offset from the mean that the region's artificial shapes carry.
#[derive(Debug, Clone, PartialEq)]
pub struct Region {
    /// Region name.
    pub name: String,
    /// Per-point weight.
    pub weights: Vec<f64>,
}

/// The size of a shape: RMS distance of its points from their centroid.
pub fn shape_size(shape: &[f64], dims: usize) -> f64 {
    let n = shape.len() / dims.max(1);
    if n == 0 {
        return 0.0;
    }
    let c: Vec<f64> = (0..dims)
        .map(|d| (0..n).map(|p| shape[p * dims + d]).sum::<f64>() / n as f64)
        .collect();
    let ss: f64 = (0..n)
        .map(|p| {
            (0..dims)
                .map(|d| (shape[p * dims + d] - c[d]).powi(2))
                .sum::<f64>()
        })
        .sum();
    (ss / n as f64).sqrt()
}

/// Per-point weights of a region (`points` of the `mean` shape): the indicator itself
/// (disjoint), or its average over the points within `blend_radius × size` of each point
/// (blended: 1 deep inside, 0 far outside, a ramp across the boundary).
pub fn region_weights(
    mean: &[f64],
    dims: usize,
    points: &[usize],
    opts: &RegionOptions,
) -> Result<Vec<f64>> {
    opts.check()?;
    let n = mean.len() / dims.max(1);
    let mut inside = vec![false; n];
    for &p in points {
        if p >= n {
            return Err(Error::invalid(format!(
                "region point {p} is beyond the shape's {n} points"
            )));
        }
        inside[p] = true;
    }
    let indicator: Vec<f64> = inside.iter().map(|&i| f64::from(u8::from(i))).collect();
    if opts.boundary == Boundary::Disjoint || opts.blend_radius == 0.0 {
        return Ok(indicator);
    }
    let r = opts.blend_radius * shape_size(mean, dims);
    let r2 = r * r;
    let at = |p: usize| &mean[p * dims..(p + 1) * dims];
    Ok((0..n)
        .map(|p| {
            let (mut sum, mut count) = (0.0, 0usize);
            for q in 0..n {
                let d2: f64 = at(p)
                    .iter()
                    .zip(at(q))
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum();
                if d2 <= r2 {
                    sum += indicator[q];
                    count += 1;
                }
            }
            sum / count as f64
        })
        .collect())
}

/// The mean shape plus `weights` × the offsets of `shape` from it (`dims` values per point).
pub fn region_shape(
    mean: &DVector<f64>,
    shape: &[f64],
    weights: &[f64],
    dims: usize,
) -> DVector<f64> {
    let mut v = mean.clone();
    for (p, &w) in weights.iter().enumerate() {
        if w == 0.0 {
            continue;
        }
        for d in 0..dims {
            let i = p * dims + d;
            v[i] = mean[i] + w * (shape[i] - mean[i]);
        }
    }
    v
}
