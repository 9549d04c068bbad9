//! Reading a redrawn template back through usvg: transforms resolved, each key shape in its
//! own group's coordinates, untouched dots following the redrawn contours.

use super::Meta;
use crate::target::{TargetKey, TargetSet};
use keyshape_core::error::{Error, Needed, Result};
use std::collections::BTreeMap;
use std::path::Path;

/// Parses the template as XML; a malformed file is an error at its line and column.
fn parse_xml<'a>(path: &Path, text: &'a str) -> Result<roxmltree::Document<'a>> {
    roxmltree::Document::parse(text).map_err(|e| {
        let p = e.pos();
        Error::parse(
            path,
            u64::from(p.row),
            u64::from(p.col),
            format!("not valid SVG/XML: {e}"),
        )
    })
}

fn find_meta(path: &Path, text: &str) -> Result<Meta> {
    let doc = parse_xml(path, text)?;
    let node = doc
        .descendants()
        .find(|n| n.attribute("id") == Some("kslab-template"))
        .ok_or_else(|| {
            Error::needs_in(
                path,
                Needed::Template,
                "no <desc id=\"kslab-template\">: not a template written by this program",
            )
        })?;
    let meta: Meta = serde_json::from_str(node.text().unwrap_or(""))
        .map_err(|e| Error::file(path, format!("template description is damaged: {e}")))?;
    let damaged =
        |why: String| Error::file(path, format!("template description is damaged: {why}"));
    if meta.points == 0 || meta.points > keyshape_core::sequence::MAX_SHAPE_VALUES {
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

/// Moves the loose points (`loose`) that were left where the template put them by the
/// displacement field of the contour points: a multiquadric RBF (paper 004's) fitted on the
/// contour points' original positions and their displacements, so that a point with no
/// moved neighbour stays put and a redrawn mouth carries the mesh inside it. A point the
/// artist moved keeps its position. If the contours did not move, nothing changes.
fn follow_contours(coords: &mut [f64], orig: &[f64], loose: &[usize]) {
    let n = coords.len() / 2;
    let mut is_loose = vec![false; n];
    loose.iter().for_each(|&p| is_loose[p] = true);
    let extent = orig
        .chunks(2)
        .flat_map(|q| q.iter().copied())
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(1.0);
    // Coordinates pass through single precision (the module's note): 1e-5 of the extent.
    let tol = 1e-5 * extent;
    let moved: Vec<bool> = (0..n)
        .map(|p| {
            (coords[2 * p] - orig[2 * p]).abs() > tol
                || (coords[2 * p + 1] - orig[2 * p + 1]).abs() > tol
        })
        .collect();
    let anchors: Vec<usize> = (0..n).filter(|&p| !is_loose[p]).collect();
    if anchors.is_empty() || !anchors.iter().any(|&p| moved[p]) {
        return;
    }
    let src: Vec<f64> = anchors
        .iter()
        .flat_map(|&p| [orig[2 * p], orig[2 * p + 1]])
        .collect();
    let disp: Vec<f64> = anchors
        .iter()
        .flat_map(|&p| {
            [
                coords[2 * p] - orig[2 * p],
                coords[2 * p + 1] - orig[2 * p + 1],
            ]
        })
        .collect();
    let Ok(rbf) = keyshape_core::rbf::Rbf::fit(&src, &disp, 2) else {
        return;
    };
    let mut d = [0.0; 2];
    for &p in loose {
        if !moved[p] {
            rbf.apply_point(&orig[2 * p..2 * p + 2], &mut d);
            coords[2 * p] = orig[2 * p] + d[0];
            coords[2 * p + 1] = orig[2 * p + 1] + d[1];
        }
    }
}

/// A dot's centre attributes must be numbers: usvg reads a malformed `cx` as 0, which would
/// put the point at the panel's corner without a word.
fn check_dots(path: &Path, text: &str) -> Result<()> {
    let doc = parse_xml(path, text)?;
    for n in doc.descendants().filter(|n| n.is_element()) {
        let Some(id) = n
            .attribute("id")
            .filter(|id| id.starts_with("key-") && id.contains("-p"))
        else {
            continue;
        };
        for a in ["cx", "cy", "r"] {
            if let Some(v) = n.attribute(a) {
                let num = v.trim().trim_end_matches("px");
                if !num.parse::<f64>().is_ok_and(f64::is_finite) {
                    let pos = doc.text_pos_at(n.range().start);
                    return Err(Error::parse(
                        path,
                        u64::from(pos.row),
                        u64::from(pos.col),
                        format!("dot '{id}': {a}=\"{v}\" is not a number"),
                    ));
                }
            }
        }
    }
    Ok(())
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
    let text = keyshape_io::read_text(path)?;
    parse_template(path, &text)
}

/// Why the points of element `id` cannot be read: the first value of its `points` that is
/// not a number an SVG (32-bit floats) can hold.
fn unreadable_points(text: &str, id: &str) -> String {
    let Ok(doc) = roxmltree::Document::parse(text) else {
        return "the file is not well-formed XML".into();
    };
    let Some(points) = doc
        .descendants()
        .find(|n| n.attribute("id") == Some(id))
        .and_then(|n| n.attribute("points"))
    else {
        return "it has no points attribute".into();
    };
    for v in points
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|v| !v.is_empty())
    {
        match v.parse::<f64>() {
            Err(_) => return format!("'{v}' is not a number"),
            Ok(x) if x.is_nan() || x.abs() > f64::from(f32::MAX) => {
                return format!("coordinate {v} is beyond what an SVG holds (±3.4e38)")
            }
            Ok(_) => {}
        }
    }
    "the SVG renderer dropped it: a zero size, or a transform that hides it?".into()
}

/// Parses template text (`path` names the file in errors).
pub fn parse_template(path: &Path, text: &str) -> Result<TargetSet> {
    let meta = find_meta(path, text)?;
    if meta.loose_dots {
        check_dots(path, text)?;
    }
    let tree = usvg::Tree::from_str(text, &usvg::Options::default())
        .map_err(|e| Error::file(path, format!("SVG: {e}")))?;
    let (mut groups, mut paths) = (Vec::new(), Vec::new());
    collect(tree.root(), &mut groups, &mut paths);
    let mut keys = Vec::new();
    for g in groups
        .iter()
        .filter(|g| g.id().starts_with("key-") && !is_sub_group(g.id()))
    {
        let frame: i64 = g.id()["key-".len()..].parse().map_err(|_| {
            Error::file(
                path,
                format!("group id '{}' is not key-<frame number>", g.id()),
            )
        })?;
        let origin = key_origin(path, &meta, g, frame)?;
        let panel = Panel {
            path,
            text,
            meta: &meta,
            id: g.id(),
            origin,
            paths: paths
                .iter()
                .filter(|p| p.id().starts_with(&format!("{}-", g.id())))
                .map(|p| (p.id().to_string(), *p))
                .collect(),
        };
        let (mut coords, loose) = panel.points(frame)?;
        if let Some(orig) = meta.shapes.get(&frame).filter(|o| o.len() == coords.len()) {
            follow_contours(&mut coords, orig, &loose);
        }
        keys.push(TargetKey { frame, coords });
    }
    check_keys(path, &meta, &keys)?;
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

/// Sub-groups of a panel (`key-<frame>-lips`, `key-<frame>-loose`) are not keys.
fn is_sub_group(id: &str) -> bool {
    let r = &id["key-".len()..];
    let digits = r.strip_prefix('-').unwrap_or(r);
    let n = digits.chars().take_while(|c| c.is_ascii_digit()).count();
    n > 0 && digits[n..].starts_with('-')
}

/// Where key `frame`'s panel `g` sits in the document: its coordinates minus this are the
/// key shape's own.
fn key_origin(path: &Path, meta: &Meta, g: &usvg::Group, frame: i64) -> Result<[f64; 2]> {
    match meta.origins.get(&frame) {
        Some(o) => Ok(*o),
        None if !meta.origins.is_empty() => Err(Error::file(
            path,
            format!(
                "group {} is not a key of this template (its keys: {:?})",
                g.id(),
                meta.origins.keys().collect::<Vec<_>>()
            ),
        )),
        None => {
            // A template from before `origins`: its group carried only the offset.
            let t = g.transform();
            if (t.sx, t.kx, t.ky, t.sy) != (1.0, 0.0, 0.0, 1.0) {
                return Err(Error::needs_in(
                    path,
                    Needed::Template,
                    format!("group {} was scaled or rotated, and this template predates the record of where each key sits; write it again", g.id()),
                ));
            }
            Ok([f64::from(t.tx), f64::from(t.ty)])
        }
    }
}

/// One key's panel of a template being read: its group's id, where it sits, and its paths
/// by id.
struct Panel<'a> {
    path: &'a Path,
    text: &'a str,
    meta: &'a Meta,
    id: &'a str,
    origin: [f64; 2],
    paths: BTreeMap<String, &'a usvg::Path>,
}

impl Panel<'_> {
    /// The key's points (x, y interleaved, its own coordinates), each the mean over the
    /// contours it is on, and the loose dots among them.
    fn points(&self, frame: i64) -> Result<(Vec<f64>, Vec<usize>)> {
        let meta = self.meta;
        let mut sum = vec![0.0; 2 * meta.points];
        let mut count = vec![0usize; meta.points];
        let mut add = |pi: usize, xy: [f64; 2]| {
            sum[2 * pi] += xy[0] - self.origin[0];
            sum[2 * pi + 1] += xy[1] - self.origin[1];
            count[pi] += 1;
        };
        let mut loose: Vec<usize> = Vec::new();
        for (c, line) in meta.polylines.iter().enumerate() {
            let is_rest = meta.rest && c + 1 == meta.polylines.len();
            if is_rest && meta.loose_dots {
                for &pi in line {
                    add(pi, self.dot(pi)?);
                    loose.push(pi);
                }
                continue;
            }
            let id = if is_rest {
                format!("{}-rest", self.id)
            } else {
                format!("{}-c{c}", self.id)
            };
            for (&pi, xy) in line.iter().zip(self.contour(&id, line.len())?) {
                if !(xy[0].is_finite() && xy[1].is_finite()) {
                    return Err(Error::file(
                        self.path,
                        format!("contour '{id}': point {pi} is not a finite number"),
                    ));
                }
                add(pi, xy);
            }
        }
        if let Some(p) = count.iter().position(|&c| c == 0) {
            return Err(Error::file(
                self.path,
                format!("key-{frame}: point {p} is on no contour"),
            ));
        }
        let coords = sum
            .iter()
            .enumerate()
            .map(|(i, v)| v / count[i / 2] as f64)
            .collect();
        Ok((coords, loose))
    }

    /// Loose point `pi`'s dot: the centre of its drawing, in document coordinates.
    fn dot(&self, pi: usize) -> Result<[f64; 2]> {
        let id = format!("{}-p{pi}", self.id);
        let p = self.paths.get(&id).ok_or_else(|| {
            Error::file(
                self.path,
                format!("dot '{id}' is missing (keep the template's ids; move dots, do not delete them)"),
            )
        })?;
        let v = vertices(p);
        let centre = |d: usize| {
            let lo = v.iter().map(|q| q[d]).fold(f64::INFINITY, f64::min);
            let hi = v.iter().map(|q| q[d]).fold(f64::NEG_INFINITY, f64::max);
            (lo + hi) / 2.0
        };
        let xy = [centre(0), centre(1)];
        if !(xy[0].is_finite() && xy[1].is_finite()) {
            return Err(Error::file(
                self.path,
                format!("dot '{id}': its position is not a finite number"),
            ));
        }
        Ok(xy)
    }

    /// Contour `id`'s points, in document coordinates; refused unless it has the
    /// template's `len`.
    fn contour(&self, id: &str, len: usize) -> Result<Vec<[f64; 2]>> {
        let p = self.paths.get(id).ok_or_else(|| {
            if self.text.contains(&format!("id=\"{id}\"")) {
                Error::file(
                    self.path,
                    format!(
                        "contour '{id}' is in the file, but its points could not be read ({})",
                        unreadable_points(self.text, id)
                    ),
                )
            } else {
                Error::file(
                    self.path,
                    format!("contour '{id}' is missing (keep the template's ids)"),
                )
            }
        })?;
        let v = vertices(p);
        if v.len() != len {
            return Err(Error::file(self.path, format!("contour '{id}' has {} points, the template had {len} (move points, do not add or remove them)", v.len())));
        }
        Ok(v)
    }
}

/// Refuses a template read back with no keys, a key the template wrote missing, or a key
/// whose points all coincide.
fn check_keys(path: &Path, meta: &Meta, keys: &[TargetKey]) -> Result<()> {
    if keys.is_empty() {
        return Err(Error::file(path, "no <g id=\"key-<frame>\"> groups found"));
    }
    // Every key the template wrote must come back: a panel deleted, hidden or scaled to
    // nothing (which the SVG renderer drops) would otherwise be read as one key fewer.
    if let Some(frame) = meta
        .origins
        .keys()
        .find(|f| !keys.iter().any(|k| k.frame == **f))
    {
        return Err(Error::file(
            path,
            format!(
                "key-{frame} is missing or draws nothing (deleted, hidden or scaled to zero?): a template's keys all come back, {} of {} here",
                keys.len(),
                meta.origins.len()
            ),
        ));
    }
    for k in keys {
        if keyshape_core::sequence::degenerate_shape(&k.coords, 2) {
            return Err(Error::file(
                path,
                format!("key-{}: all its points coincide (scaled to zero?)", k.frame),
            ));
        }
    }
    Ok(())
}
