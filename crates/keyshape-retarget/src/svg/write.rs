//! Writing a template: one labelled group per key shape, the contours and dots inside it,
//! and the metadata that reads it back.

use super::{contours_with_rest, Meta};
use std::collections::BTreeMap;
use std::io::Write;

/// Labels for a group's contours as a person reads them: the group's name alone, or — for
/// a group drawn as two contours — `outer`/`inner` when one's bounding box holds the
/// other's (lips), else `upper`/`lower` by height (brows; y points down), else numbered.
fn contour_labels(polylines: &[(String, Vec<usize>)], shape: &[f64]) -> Vec<String> {
    let bbox = |l: &[usize]| {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for &p in l {
            for d in 0..2 {
                lo[d] = lo[d].min(shape[2 * p + d]);
                hi[d] = hi[d].max(shape[2 * p + d]);
            }
        }
        (lo, hi)
    };
    let mut out = Vec::with_capacity(polylines.len());
    for (i, (name, line)) in polylines.iter().enumerate() {
        let same: Vec<usize> = (0..polylines.len())
            .filter(|&j| polylines[j].0 == *name)
            .collect();
        let pretty = name.replace('_', " ");
        let label = match same.len() {
            1 => pretty,
            2 => {
                let other = &polylines[same[usize::from(same[0] == i)]].1;
                let ((a0, a1), (b0, b1)) = (bbox(line), bbox(other));
                let holds = |(l0, l1): ([f64; 2], [f64; 2]), (m0, m1): ([f64; 2], [f64; 2])| {
                    (0..2).all(|d| l0[d] <= m0[d] && l1[d] >= m1[d])
                };
                let mean_y =
                    |l: &[usize]| l.iter().map(|&p| shape[2 * p + 1]).sum::<f64>() / l.len() as f64;
                if holds((a0, a1), (b0, b1)) {
                    format!("{pretty} outer")
                } else if holds((b0, b1), (a0, a1)) {
                    format!("{pretty} inner")
                } else if mean_y(line) <= mean_y(other) {
                    format!("{pretty} upper")
                } else {
                    format!("{pretty} lower")
                }
            }
            _ => format!(
                "{pretty} {}",
                same.iter().position(|&j| j == i).unwrap_or(0) + 1
            ),
        };
        out.push(label);
    }
    out
}

/// Escapes text for XML content and attributes.
fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Writes a template of `keys` (frame number, flat 2-D shape) with drawing `polylines`, each
/// named by the layout group it belongs to.
///
/// Each key is a panel `<g id="key-<frame>">` captioned with its number and source frame;
/// inside it, one sub-group per layout group (`key-<frame>-<group>`, labelled for
/// Inkscape's Objects panel) holds that group's contours as polylines `key-<frame>-c<i>`.
/// Points on no contour (MediaPipe's mesh interior) are small dots `key-<frame>-p<point>` in
/// a `key-<frame>-loose` sub-group: the artist may move them, and those left where they were
/// follow the redrawn contours when the template is read ([`parse_template`](super::parse_template)).
pub fn write_template(
    w: &mut dyn Write,
    keys: &[(i64, Vec<f64>)],
    points: usize,
    polylines: &[(String, Vec<usize>)],
) -> std::io::Result<()> {
    let lines: Vec<(String, Vec<usize>)> = polylines
        .iter()
        .filter(|(_, l)| l.len() > 1)
        .cloned()
        .collect();
    let plain: Vec<Vec<usize>> = lines.iter().map(|(_, l)| l.clone()).collect();
    let contours = contours_with_rest(points, &plain);
    let rest = contours.len() > lines.len();
    let sheet = Sheet::of(keys);
    let (wd, ht) = (
        sheet.cell_w * sheet.cols as f64,
        sheet.cell_h * sheet.rows as f64,
    );
    writeln!(w, r#"<?xml version="1.0" encoding="UTF-8"?>"#)?;
    writeln!(
        w,
        r#"<svg xmlns="http://www.w3.org/2000/svg" xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape" width="{wd:.3}" height="{ht:.3}" viewBox="0 0 {wd:.3} {ht:.3}">"#
    )?;
    let origins = sheet.origins(keys);
    let meta = serde_json::to_string(&Meta {
        points,
        polylines: contours.clone(),
        rest,
        origins: origins.clone(),
        loose_dots: rest,
        shapes: if rest {
            keys.iter().map(|(f, s)| (*f, s.clone())).collect()
        } else {
            BTreeMap::new()
        },
    })
    .map_err(std::io::Error::other)?;
    writeln!(w, r#"<desc id="kslab-template">{meta}</desc>"#)?;
    writeln!(w, "<!-- keyshape-lab key-shape template: redraw each key shape, keep the ids and the number of points of every contour. Dots are points on no contour: move them or leave them to follow the contours. -->")?;
    let labels = keys
        .first()
        .map(|(_, s)| contour_labels(&lines, s))
        .unwrap_or_default();
    let loose: &[usize] = if rest {
        contours.last().map_or(&[], Vec::as_slice)
    } else {
        &[]
    };
    for (n, (frame, s)) in keys.iter().enumerate() {
        let panel = PanelOut {
            frame: *frame,
            n,
            of: keys.len(),
            origin: origins[frame],
            s,
        };
        panel.write(w, &sheet, &lines, &labels, rest.then_some(loose))?;
    }
    writeln!(w, "</svg>")
}

/// How a template's panels are laid out: the shapes' bounds, each panel's size and the
/// grid's columns and rows.
struct Sheet {
    lo: [f64; 2],
    /// The shapes' larger extent.
    m: f64,
    cell_w: f64,
    cell_h: f64,
    cols: usize,
    rows: usize,
}

impl Sheet {
    /// A panel as wide and as tall as the shapes plus a margin of a tenth of their larger
    /// extent each side: a face's panel is square, a lips-only one wide and low (square
    /// panels left two thirds of each empty). The columns make the sheet about square.
    fn of(keys: &[(i64, Vec<f64>)]) -> Sheet {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for (_, s) in keys {
            for p in s.chunks(2) {
                lo = [lo[0].min(p[0]), lo[1].min(p[1])];
                hi = [hi[0].max(p[0]), hi[1].max(p[1])];
            }
        }
        let (dx, dy) = ((hi[0] - lo[0]).max(1e-9), (hi[1] - lo[1]).max(1e-9));
        let m = dx.max(dy);
        let (cell_w, cell_h) = (dx + 0.2 * m, dy + 0.2 * m);
        let cols = ((keys.len() as f64 * cell_h / cell_w).sqrt().ceil() as usize)
            .clamp(1, keys.len().max(1));
        let rows = keys.len().div_ceil(cols);
        Sheet {
            lo,
            m,
            cell_w,
            cell_h,
            cols,
            rows,
        }
    }

    /// Each key's offset on the sheet (what its panel's `translate` adds).
    fn origins(&self, keys: &[(i64, Vec<f64>)]) -> BTreeMap<i64, [f64; 2]> {
        keys.iter()
            .enumerate()
            .map(|(i, (frame, _))| {
                let ox = (i % self.cols) as f64 * self.cell_w + 0.1 * self.m - self.lo[0];
                let oy = (i / self.cols) as f64 * self.cell_h + 0.1 * self.m - self.lo[1];
                (*frame, [ox, oy])
            })
            .collect()
    }

    /// The size of a square panel, which strokes and captions scale with.
    fn cell(&self) -> f64 {
        1.2 * self.m
    }
}

/// Key `n` of `of` (source frame `frame`, flat 2-D shape `s`) as its template panel.
struct PanelOut<'a> {
    frame: i64,
    n: usize,
    of: usize,
    origin: [f64; 2],
    s: &'a [f64],
}

impl PanelOut<'_> {
    /// The panel's group: its caption, its contours grouped by layout group in
    /// first-appearance order, and with `loose` the dots of the points on no contour.
    fn write(
        &self,
        w: &mut dyn Write,
        sheet: &Sheet,
        lines: &[(String, Vec<usize>)],
        labels: &[String],
        loose: Option<&[usize]>,
    ) -> std::io::Result<()> {
        let (frame, n, s) = (self.frame, self.n, self.s);
        let [ox, oy] = self.origin;
        let cell = sheet.cell();
        let stroke = cell / 300.0;
        let font = cell / 28.0;
        writeln!(
            w,
            r#"<g id="key-{frame}" inkscape:label="key {} · frame {frame}" transform="translate({ox} {oy})"><title>key {} of {}: frame {frame}</title>"#,
            n + 1,
            n + 1,
            self.of
        )?;
        writeln!(
            w,
            r##"  <text id="key-{frame}-caption" x="{}" y="{}" font-family="sans-serif" font-size="{font}" fill="#444">key {} · frame {frame}</text>"##,
            sheet.lo[0] - 0.05 * cell,
            sheet.lo[1] - 0.04 * cell,
            n + 1
        )?;
        let mut order: Vec<&str> = Vec::new();
        for (name, _) in lines {
            if !order.contains(&name.as_str()) {
                order.push(name);
            }
        }
        for name in order {
            writeln!(
                w,
                r#"  <g id="key-{frame}-{}" inkscape:label="{}">"#,
                xml_escape(name),
                xml_escape(&name.replace('_', " "))
            )?;
            for (c, (cname, line)) in lines.iter().enumerate() {
                if cname != name {
                    continue;
                }
                let pts: Vec<String> = line
                    .iter()
                    .map(|&p| format!("{},{}", s[2 * p], s[2 * p + 1]))
                    .collect();
                writeln!(
                    w,
                    r#"    <polyline id="key-{frame}-c{c}" inkscape:label="{}" fill="none" stroke="black" stroke-width="{stroke}" points="{}"/>"#,
                    xml_escape(&labels[c]),
                    pts.join(" ")
                )?;
            }
            writeln!(w, "  </g>")?;
        }
        if let Some(loose) = loose {
            writeln!(
                w,
                r##"  <g id="key-{frame}-loose" inkscape:label="points on no contour (left alone, they follow the contours)" fill="#888">"##
            )?;
            for &p in loose {
                writeln!(
                    w,
                    r#"    <circle id="key-{frame}-p{p}" cx="{}" cy="{}" r="{}"/>"#,
                    s[2 * p],
                    s[2 * p + 1],
                    2.0 * stroke
                )?;
            }
            writeln!(w, "  </g>")?;
        }
        writeln!(w, "</g>")
    }
}
