//! Action-specific modes (Cosker et al., paper 002 §3.1) on landmark shapes, and the
//! orthogonality measure of their Table 2 (§5, Eq. 9).
//!
//! From N training shapes the artificial set holds, for every region j and frame i, the mean
//! shape with region j's offsets of frame i added (4N shapes for four regions). Its PCA
//! gives modes that act locally; plain PCA of the same frames mixes regions.
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
use keyshape_core::pca::Pca;
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
        let text = match layout.family() {
            "mediapipe_face_mesh_468" => {
                include_str!("../../../assets/cosker/regions_mediapipe_face_mesh_468.json")
            }
            "ibug68" => include_str!("../../../assets/cosker/regions_ibug68.json"),
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
            _ => Err(keyshape_core::error::Error::invalid(format!(
                "'{s}': choose blended or disjoint"
            ))),
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
            return Err(Error::invalid(format!(
                "blend radius {} must be a finite number ≥ 0 (a fraction of the face's size)",
                self.blend_radius
            )));
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
            return Err(Error::file(
                path,
                format!(
                    "these actions were chosen on {}, not on {}: their frames name other faces; choose this track's with `kslab actions {source} --out FILE`",
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
    let action_model = artificial_pca(coords, regions, dims, modes)?;
    let plain = Pca::fit_leading(coords, modes)?;
    Ok(OrthogonalityStudy {
        names: actions.actions.iter().map(|a| a.name.clone()).collect(),
        action_model: orthogonality_table(&action_model, &vecs, modes),
        plain: orthogonality_table(&plain, &vecs, modes),
        modes,
    })
}
