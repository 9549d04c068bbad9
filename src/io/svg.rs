//! Coordinates pass through usvg in single precision: a round trip keeps about 7
//! significant digits (1e-4 px on a 500 px face).
//!
//! SVG templates of key shapes, for an artist to redraw (paper 000 Fig. 3: "we traced these
//! lip shapes by hand and used the control points along the traced shapes as the target
//! key shapes").
//!
//! [`write_template`] writes one `<g id="key-<frame>">` per key frame, laid out in a grid
//! by the group's `transform`, with one `<polyline id="key-<frame>-c<i>">` per contour and
//! `key-<frame>-rest` for points on no contour. A `<desc id="kslab-template">` holds the
//! contours' point indices as JSON. An artist moves points (Inkscape may turn polylines
//! into paths and add transforms — fine), keeping the ids and the number of points per
//! contour. [`read_template`] reads it back through usvg, which resolves transforms and
//! shapes, and returns a target set in each key group's own coordinates.

use crate::error::{Error, Result};
use crate::retarget::target::{TargetKey, TargetSet};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;

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

/// Writes a template of `keys` (frame number, flat 2-D shape) with drawing `polylines`.
pub fn write_template(
    w: &mut dyn Write,
    keys: &[(i64, Vec<f64>)],
    points: usize,
    polylines: &[Vec<usize>],
) -> std::io::Result<()> {
    let contours = contours_with_rest(points, polylines);
    let rest = contours.len() > polylines.iter().filter(|l| l.len() > 1).count();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for (_, s) in keys {
        for p in s.chunks(2) {
            lo = [lo[0].min(p[0]), lo[1].min(p[1])];
            hi = [hi[0].max(p[0]), hi[1].max(p[1])];
        }
    }
    let cell = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-9) * 1.2;
    let cols = (keys.len() as f64).sqrt().ceil().max(1.0) as usize;
    let rows = keys.len().div_ceil(cols);
    let (wd, ht) = (cell * cols as f64, cell * rows as f64);
    writeln!(w, r#"<?xml version="1.0" encoding="UTF-8"?>"#)?;
    writeln!(
        w,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{wd:.3}" height="{ht:.3}" viewBox="0 0 {wd:.3} {ht:.3}">"#
    )?;
    let origins = keys
        .iter()
        .enumerate()
        .map(|(i, (frame, _))| {
            let ox = (i % cols) as f64 * cell + 0.1 * cell - lo[0];
            let oy = (i / cols) as f64 * cell + 0.1 * cell - lo[1];
            (*frame, [ox, oy])
        })
        .collect::<BTreeMap<i64, [f64; 2]>>();
    let meta = serde_json::to_string(&Meta {
        points,
        polylines: contours.clone(),
        rest,
        origins: origins.clone(),
    })
    .map_err(std::io::Error::other)?;
    writeln!(w, r#"<desc id="kslab-template">{meta}</desc>"#)?;
    writeln!(w, "<!-- keyshape-lab key-shape template: redraw each key shape, keep the ids and the number of points of every contour. -->")?;
    let stroke = cell / 300.0;
    for (frame, s) in keys {
        let [ox, oy] = origins[frame];
        writeln!(
            w,
            r#"<g id="key-{frame}" transform="translate({ox} {oy})"><title>key frame {frame}</title>"#
        )?;
        for (c, line) in contours.iter().enumerate() {
            let id = if rest && c + 1 == contours.len() {
                format!("key-{frame}-rest")
            } else {
                format!("key-{frame}-c{c}")
            };
            let pts: Vec<String> = line
                .iter()
                .map(|&p| format!("{},{}", s[2 * p], s[2 * p + 1]))
                .collect();
            let dash = if id.ends_with("rest") {
                r#" stroke-dasharray="1,2""#
            } else {
                ""
            };
            writeln!(
                w,
                r#"  <polyline id="{id}" fill="none" stroke="black" stroke-width="{stroke}"{dash} points="{}"/>"#,
                pts.join(" ")
            )?;
        }
        writeln!(w, "</g>")?;
    }
    writeln!(w, "</svg>")
}

fn find_meta(path: &Path, text: &str) -> Result<Meta> {
    let doc = roxmltree::Document::parse(text).map_err(|e| {
        let p = e.pos();
        Error::parse(
            path,
            u64::from(p.row),
            u64::from(p.col),
            format!("not valid SVG/XML: {e}"),
        )
    })?;
    let node = doc
        .descendants()
        .find(|n| n.attribute("id") == Some("kslab-template"))
        .ok_or_else(|| {
            Error::file(
                path,
                "no <desc id=\"kslab-template\">: not a template written by `kslab template`",
            )
        })?;
    let meta: Meta = serde_json::from_str(node.text().unwrap_or(""))
        .map_err(|e| Error::file(path, format!("template description is damaged: {e}")))?;
    let damaged =
        |why: String| Error::file(path, format!("template description is damaged: {why}"));
    if meta.points == 0 || meta.points > crate::sequence::MAX_SHAPE_VALUES {
        return Err(damaged(format!(
            "points {} is not a point count",
            meta.points
        )));
    }
    if let Some(&bad) = meta.polylines.iter().flatten().find(|&&i| i >= meta.points) {
        return Err(damaged(format!(
            "a contour names point {bad}, but the template has {} points",
            meta.points
        )));
    }
    if meta.rest && meta.polylines.is_empty() {
        return Err(damaged(
            "it promises a run of loose points but lists no contours".into(),
        ));
    }
    Ok(meta)
}

/// Vertices of a path (end points of every segment), in absolute coordinates.
fn vertices(p: &usvg::Path) -> Vec<[f64; 2]> {
    use usvg::tiny_skia_path::PathSegment;
    let t = p.abs_transform();
    let mut out = Vec::new();
    for seg in p.data().segments() {
        let pt = match seg {
            PathSegment::MoveTo(q) | PathSegment::LineTo(q) => q,
            PathSegment::QuadTo(_, q) => q,
            PathSegment::CubicTo(_, _, q) => q,
            PathSegment::Close => continue,
        };
        let mut q = pt;
        t.map_points(std::slice::from_mut(&mut q));
        out.push([f64::from(q.x), f64::from(q.y)]);
    }
    out
}

fn collect<'a>(
    g: &'a usvg::Group,
    groups: &mut Vec<&'a usvg::Group>,
    paths: &mut Vec<&'a usvg::Path>,
) {
    for n in g.children() {
        match n {
            usvg::Node::Group(c) => {
                groups.push(c);
                collect(c, groups, paths);
            }
            usvg::Node::Path(p) => paths.push(p),
            _ => {}
        }
    }
}

/// Reads an edited template back as a target set (one shape per key group).
pub fn read_template(path: &Path) -> Result<TargetSet> {
    let text = crate::io::read_text(path)?;
    parse_template(path, &text)
}

/// Parses template text (`path` names the file in errors).
pub fn parse_template(path: &Path, text: &str) -> Result<TargetSet> {
    let text = text.to_string();
    let meta = find_meta(path, &text)?;
    let tree = usvg::Tree::from_str(&text, &usvg::Options::default())
        .map_err(|e| Error::file(path, format!("SVG: {e}")))?;
    let (mut groups, mut paths) = (Vec::new(), Vec::new());
    collect(tree.root(), &mut groups, &mut paths);
    let mut keys = Vec::new();
    for g in groups.iter().filter(|g| g.id().starts_with("key-")) {
        let frame: i64 = g.id()["key-".len()..].parse().map_err(|_| {
            Error::file(
                path,
                format!("group id '{}' is not key-<frame number>", g.id()),
            )
        })?;
        // Document coordinates → the key shape's own: minus the template's offset.
        let origin = match meta.origins.get(&frame) {
            Some(o) => *o,
            None if !meta.origins.is_empty() => {
                return Err(Error::file(
                    path,
                    format!(
                        "group {} is not a key of this template (its keys: {:?})",
                        g.id(),
                        meta.origins.keys().collect::<Vec<_>>()
                    ),
                ))
            }
            None => {
                // A template from before `origins`: its group carried only the offset.
                let t = g.transform();
                if (t.sx, t.kx, t.ky, t.sy) != (1.0, 0.0, 0.0, 1.0) {
                    return Err(Error::file(
                        path,
                        format!("group {} was scaled or rotated, and this template predates kslab's record of where each key sits; write it again with `kslab template`", g.id()),
                    ));
                }
                [f64::from(t.tx), f64::from(t.ty)]
            }
        };
        let mut sum = vec![0.0; 2 * meta.points];
        let mut count = vec![0usize; meta.points];
        let mine: BTreeMap<String, &usvg::Path> = paths
            .iter()
            .filter(|p| p.id().starts_with(&format!("{}-", g.id())))
            .map(|p| (p.id().to_string(), *p))
            .collect();
        for (c, line) in meta.polylines.iter().enumerate() {
            let id = if meta.rest && c + 1 == meta.polylines.len() {
                format!("{}-rest", g.id())
            } else {
                format!("{}-c{c}", g.id())
            };
            let p = mine.get(&id).ok_or_else(|| {
                if text.contains(&format!("id=\"{id}\"")) {
                    Error::file(
                        path,
                        format!("contour '{id}' is in the file, but its points could not be read (a coordinate that is not a number?)"),
                    )
                } else {
                    Error::file(
                        path,
                        format!("contour '{id}' is missing (keep the template's ids)"),
                    )
                }
            })?;
            let v = vertices(p);
            if v.len() != line.len() {
                return Err(Error::file(path, format!("contour '{id}' has {} points, the template had {} (move points, do not add or remove them)", v.len(), line.len())));
            }
            for (&pi, xy) in line.iter().zip(v) {
                if !(xy[0].is_finite() && xy[1].is_finite()) {
                    return Err(Error::file(
                        path,
                        format!("contour '{id}': point {pi} is not a finite number"),
                    ));
                }
                sum[2 * pi] += xy[0] - origin[0];
                sum[2 * pi + 1] += xy[1] - origin[1];
                count[pi] += 1;
            }
        }
        if let Some(p) = count.iter().position(|&c| c == 0) {
            return Err(Error::file(
                path,
                format!("key-{frame}: point {p} is on no contour"),
            ));
        }
        let coords = sum
            .iter()
            .enumerate()
            .map(|(i, v)| v / count[i / 2] as f64)
            .collect();
        keys.push(TargetKey { frame, coords });
    }
    if keys.is_empty() {
        return Err(Error::file(path, "no <g id=\"key-<frame>\"> groups found"));
    }
    // Drawing contours: the template's, without the run of loose points.
    let mut polylines = meta.polylines.clone();
    if meta.rest {
        polylines.pop();
    }
    let set = TargetSet {
        kslab_target: 1,
        dims: 2,
        points: meta.points,
        polylines,
        keys,
        neutral: None,
    };
    set.check().map_err(|e| Error::file(path, e.to_string()))?;
    Ok(set)
}
