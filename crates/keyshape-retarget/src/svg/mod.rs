//! Coordinates pass through usvg in single precision: a round trip keeps about 7
//! significant digits (1e-4 px on a 500 px face).
//!
//! SVG templates of key shapes, for an artist to redraw (paper 000 Fig. 3: "we traced these
//! lip shapes by hand and used the control points along the traced shapes as the target
//! key shapes").
//!
//! [`write_template`] writes one `<g id="key-<frame>">` per key frame, laid out in a grid
//! by the group's `transform` and captioned "key N · frame F". Inside it each layout group
//! (brows, eyes, nose, lips, oval …) is a labelled sub-group `key-<frame>-<group>` of
//! polylines `key-<frame>-c<i>` ("lips outer", "lips inner", …), and points on no contour
//! are dots `key-<frame>-p<point>` in `key-<frame>-loose` (templates before the dots drew
//! them as one polyline, `key-<frame>-rest`, still read). A `<desc id="kslab-template">`
//! holds the contours' point indices, where each key sits and the shapes as written, as
//! JSON. An artist moves points (Inkscape may turn polylines into paths and add transforms
//! — fine), keeping the ids and the number of points per contour. [`read_template`] reads
//! it back through usvg, which resolves transforms and shapes, and returns a target set in
//! each key group's own coordinates; dots the artist left alone follow the redrawn contours.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

mod read;
mod write;
pub use read::{parse_template, read_template};
pub use write::write_template;

#[derive(Debug, Serialize, Deserialize)]
struct Meta {
    points: usize,
    polylines: Vec<Vec<usize>>,
    /// The last polyline is the run of points on no contour (`key-<frame>-rest`).
    rest: bool,
    /// Where the template placed each key shape's origin in the document (frame → x, y).
    /// A redrawn shape is read in document coordinates, with every transform the artist
    /// or the editor added resolved, and then moved back by this offset. Templates written
    /// before this field fall back to undoing the group's translation.
    #[serde(default)]
    origins: BTreeMap<i64, [f64; 2]>,
    /// The points on no contour are dots `key-<frame>-p<point>` (templates before this
    /// field drew them as one polyline `key-<frame>-rest`).
    #[serde(default)]
    loose_dots: bool,
    /// Each key shape as written, so that dots left where they were can follow the
    /// redrawn contours (frame → flat 2-D shape).
    #[serde(default)]
    shapes: BTreeMap<i64, Vec<f64>>,
}

/// Contours for a template: the given polylines plus one run of every point on none.
pub fn contours_with_rest(points: usize, polylines: &[Vec<usize>]) -> Vec<Vec<usize>> {
    let mut on = vec![false; points];
    polylines
        .iter()
        .flatten()
        .filter(|&&p| p < points)
        .for_each(|&p| on[p] = true);
    let rest: Vec<usize> = (0..points).filter(|&p| !on[p]).collect();
    let mut all: Vec<Vec<usize>> = polylines.iter().filter(|l| l.len() > 1).cloned().collect();
    if !rest.is_empty() {
        all.push(rest);
    }
    all
}
