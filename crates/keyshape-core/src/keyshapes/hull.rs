//! Convex hull (paper 000 §4.2): every frame on the convex hull of the 2-PC projection.

use super::{Analysis, Heuristic, Selection};
use crate::error::{Error, Result};
use spade::{DelaunayTriangulation, HasPosition, Point2, Triangulation};

/// The frames at the corners of the convex hull of the first two principal components
/// (spade's Delaunay triangulation). k is whatever the hull gives. Frames lying exactly on
/// a hull edge are convex combinations of its two ends and are left out; hull corners
/// closer together than 1e-9 of the projection's extent count once; frames with identical
/// projections count once (the lowest frame index is reported); when every projection is
/// collinear, or so nearly that fewer than three corners are strict within those
/// tolerances, the hull is the two ends of the line: the end farther from frame 0 second.
#[derive(Debug, Clone, Copy)]
pub struct Hull;

struct Vertex {
    p: Point2<f64>,
    frame: usize,
}

impl HasPosition for Vertex {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        self.p
    }
}

impl Heuristic for Hull {
    fn name(&self) -> String {
        "hull".into()
    }

    fn select(&self, an: &Analysis, _k: usize) -> Result<Selection> {
        // Two distinct shapes span one principal axis; fewer span none.
        an.need_distinct(2, "the convex hull (--method hull)")?;
        if an.proj.nrows() == 0 {
            return Err(Error::unfit("hull: every frame projects to the same point"));
        }
        let n = an.frames();
        let axes = an.proj.nrows().min(2);
        let pt = |t: usize| {
            (
                an.proj[(0, t)],
                if axes > 1 { an.proj[(1, t)] } else { 0.0 },
            )
        };
        let (mut lo, mut hi) = (
            (f64::INFINITY, f64::INFINITY),
            (f64::NEG_INFINITY, f64::NEG_INFINITY),
        );
        for t in 0..n {
            let (x, y) = pt(t);
            lo = (lo.0.min(x), lo.1.min(y));
            hi = (hi.0.max(x), hi.1.max(y));
        }
        let extent = (hi.0 - lo.0).max(hi.1 - lo.1);
        if extent.is_nan() || extent <= 0.0 {
            return Err(Error::unfit("hull: every frame projects to the same point"));
        }
        // Lowest frame index first, so a merged duplicate reports the earliest frame.
        let verts: Vec<Vertex> = (0..n)
            .map(|t| {
                let (x, y) = pt(t);
                Vertex {
                    p: Point2::new(x, y),
                    frame: t,
                }
            })
            .collect();
        let tri: DelaunayTriangulation<Vertex> = DelaunayTriangulation::bulk_load_stable(verts)
            .map_err(|e| Error::unfit(format!("hull: triangulation failed: {e:?}")))?;
        let columns = if tri.num_vertices() < 3 || tri.all_vertices_on_line() {
            line_ends(an, &pt)
        } else {
            let ring: Vec<(usize, (f64, f64))> = tri
                .convex_hull()
                .map(|e| {
                    let v = e.from();
                    (v.data().frame, (v.position().x, v.position().y))
                })
                .collect();
            let c = corners(&ring, extent);
            // Within tolerance of a line (a triangle 1e-12 of the extent thick has no strict
            // corner): the line's ends, as for an exact line, never an empty selection.
            if c.len() < 3 {
                line_ends(an, &pt)
            } else {
                c
            }
        };
        Ok(Selection::frames(columns))
    }
}

/// The two extreme frames along the line every projection lies on.
fn line_ends(an: &Analysis, pt: &dyn Fn(usize) -> (f64, f64)) -> Vec<usize> {
    let n = an.frames();
    let p0 = pt(0);
    let far = (0..n)
        .max_by(|&i, &j| dist2(pt(i), p0).total_cmp(&dist2(pt(j), p0)))
        .unwrap_or(0);
    let d = (pt(far).0 - p0.0, pt(far).1 - p0.1);
    let along = |t: usize| (pt(t).0 - p0.0) * d.0 + (pt(t).1 - p0.1) * d.1;
    let a = (0..n)
        .min_by(|&i, &j| along(i).total_cmp(&along(j)).then(i.cmp(&j)))
        .unwrap_or(0);
    let b = (0..n)
        .max_by(|&i, &j| along(i).total_cmp(&along(j)).then(j.cmp(&i)))
        .unwrap_or(0);
    if a == b {
        vec![a]
    } else {
        vec![a, b]
    }
}

fn dist2(a: (f64, f64), b: (f64, f64)) -> f64 {
    (a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)
}

/// Strict corners of a hull ring: drops near-duplicate neighbours and collinear points.
/// Fewer than three points left have no strict corner: the result is then empty.
fn corners(ring: &[(usize, (f64, f64))], extent: f64) -> Vec<usize> {
    let mut pts: Vec<(usize, (f64, f64))> = Vec::with_capacity(ring.len());
    for &v in ring {
        if pts
            .last()
            .is_none_or(|l| dist2(l.1, v.1).sqrt() > 1e-9 * extent)
        {
            pts.push(v);
        }
    }
    while pts.len() > 1 && dist2(pts[0].1, pts[pts.len() - 1].1).sqrt() <= 1e-9 * extent {
        pts.pop();
    }
    let m = pts.len();
    (0..m)
        .filter(|&i| {
            let (a, b, c) = (pts[(i + m - 1) % m].1, pts[i].1, pts[(i + 1) % m].1);
            let cross = (b.0 - a.0) * (c.1 - b.1) - (b.1 - a.1) * (c.0 - b.0);
            cross.abs() > 1e-12 * extent * extent
        })
        .map(|i| pts[i].0)
        .collect()
}
