//! Face contours side by side: tracked source, reconstruction, retargeted target.

use super::text::{self, Anchor};
use keyshape_core::error::{Error, Result};
use tiny_skia::{
    Color, FillRule, Paint, PathBuilder, Pixmap, PixmapPaint, Stroke, StrokeDash, Transform,
};

/// One shape drawn in a panel.
#[derive(Debug, Clone)]
pub struct Layer<'a> {
    /// Legend name.
    pub name: &'a str,
    /// Flat coordinates (x, y first of each point; image axes, y down).
    pub shape: &'a [f64],
    /// Values per point.
    pub dims: usize,
    /// Contours (point indices); empty: dots at every point.
    pub polylines: &'a [Vec<usize>],
    /// RGB.
    pub color: [u8; 3],
    /// Dashed stroke.
    pub dashed: bool,
}

/// A square panel with a title and layers, drawn inside fixed data bounds.
#[derive(Debug, Clone)]
pub struct Panel<'a> {
    /// Title above the panel.
    pub title: String,
    /// Shapes, drawn in order.
    pub layers: Vec<Layer<'a>>,
    /// Data bounds ((x0, y0), (x1, y1)), kept fixed over frames so motion shows.
    pub bounds: ((f64, f64), (f64, f64)),
    /// A shaded mesh drawn under the layers (front view), or None.
    pub mesh: Option<ShadedMesh<'a>>,
}

/// A mesh to draw shaded in a panel: `positions` with y up (a rig's own frame, drawn as
/// (x, −y) in the panel's coordinates, as the layers drawn from it are) and `faces` of
/// vertex indices.
#[derive(Debug, Clone, Copy)]
pub struct ShadedMesh<'a> {
    /// Vertex positions, y up, z towards the viewer.
    pub positions: &'a [[f64; 3]],
    /// Faces (polygons) as vertex indices.
    pub faces: &'a [Vec<usize>],
}

/// Bounds of every point of every column of the matrices (flat shapes, `dims` per point),
/// padded 5 %.
pub fn bounds_of(shapes: &[&nalgebra::DMatrix<f64>], dims: usize) -> ((f64, f64), (f64, f64)) {
    let (mut lo, mut hi) = (
        (f64::INFINITY, f64::INFINITY),
        (f64::NEG_INFINITY, f64::NEG_INFINITY),
    );
    for m in shapes {
        for p in m.as_slice().chunks(dims) {
            lo = (lo.0.min(p[0]), lo.1.min(p[1]));
            hi = (hi.0.max(p[0]), hi.1.max(p[1]));
        }
    }
    let pad = 0.05 * (hi.0 - lo.0).max(hi.1 - lo.1).max(1e-9);
    ((lo.0 - pad, lo.1 - pad), (hi.0 + pad, hi.1 + pad))
}

/// Column `t` of a matrix as a slice.
pub fn col(m: &nalgebra::DMatrix<f64>, t: usize) -> &[f64] {
    let n = m.nrows();
    &m.as_slice()[t * n..(t + 1) * n]
}

fn paint(c: [u8; 3]) -> Paint<'static> {
    let mut p = Paint::default();
    p.set_color_rgba8(c[0], c[1], c[2], 255);
    p.anti_alias = true;
    p
}

fn draw_layer(pm: &mut Pixmap, l: &Layer, map: &dyn Fn(f64, f64) -> (f32, f32)) {
    let pt = |i: usize| map(l.shape[i * l.dims], l.shape[i * l.dims + 1]);
    let n = l.shape.len() / l.dims.max(1);
    let mut stroke = Stroke {
        width: 1.6,
        ..Stroke::default()
    };
    if l.dashed {
        stroke.dash = StrokeDash::new(vec![5.0, 3.0], 0.0);
    }
    if l.polylines.is_empty() {
        for i in 0..n {
            let (x, y) = pt(i);
            if let Some(c) = PathBuilder::from_circle(x, y, 1.6) {
                pm.fill_path(
                    &c,
                    &paint(l.color),
                    FillRule::Winding,
                    Transform::identity(),
                    None,
                );
            }
        }
        return;
    }
    for line in l.polylines {
        let mut pb = PathBuilder::new();
        for (j, &i) in line.iter().filter(|&&i| i < n).enumerate() {
            let (x, y) = pt(i);
            if j == 0 {
                pb.move_to(x, y)
            } else {
                pb.line_to(x, y)
            }
        }
        if let Some(path) = pb.finish() {
            pm.stroke_path(&path, &paint(l.color), &stroke, Transform::identity(), None);
        }
    }
}

/// Renders panels side by side, `size` pixels wide each, with `caption` on top. A panel is
/// square for a face and as much shorter as its content is wide (down to 0.4 of its width):
/// a lips-only shape left two thirds of a square panel empty.
pub fn render_panels(panels: &[Panel], caption: &str, size: u32) -> Result<Pixmap> {
    let fs = (size as f32 / 22.0).clamp(10.0, 16.0);
    let head = (fs * 2.2) as u32;
    let legend =
        (fs * 1.5) as u32 * panels.iter().map(|p| p.layers.len()).max().unwrap_or(0) as u32;
    let inner = size as f32 - 2.0 * fs;
    let aspect = panels
        .iter()
        .map(|p| {
            let ((x0, y0), (x1, y1)) = p.bounds;
            (y1 - y0) / (x1 - x0).max(1e-12)
        })
        .filter(|a| a.is_finite())
        .fold(0.0f64, f64::max)
        .clamp(0.4, 1.0);
    let inner_h = (inner as f64 * aspect) as f32;
    let panel_h = (size as f32 - inner + inner_h).round() as u32;
    let (w, h) = (size * panels.len().max(1) as u32, head + panel_h + legend);
    let mut pm = Pixmap::new(w, h).ok_or_else(|| Error::invalid("bad picture size"))?;
    pm.fill(Color::WHITE);
    text::draw(
        &mut pm,
        caption,
        8.0,
        fs * 1.3,
        fs,
        Anchor::Left,
        [30, 30, 30],
    );
    for (k, p) in panels.iter().enumerate() {
        let ox = (k as u32 * size) as f32;
        let top = head as f32 + fs * 1.2;
        text::draw(
            &mut pm,
            &p.title,
            ox + size as f32 / 2.0,
            top - fs * 0.3,
            fs,
            Anchor::Centre,
            [30, 30, 30],
        );
        let ((x0, y0), (x1, y1)) = p.bounds;
        let s = (inner as f64 / (x1 - x0).max(1e-12)).min(inner_h as f64 / (y1 - y0).max(1e-12));
        let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
        let (mx, my) = (ox + size as f32 / 2.0, top + fs * 0.3 + inner_h / 2.0);
        let map = |x: f64, y: f64| (mx + ((x - cx) * s) as f32, my + ((y - cy) * s) as f32);
        if let Some(m) = &p.mesh {
            let clip = (ox, top + fs * 0.3, size as f32, inner_h);
            super::mesh::draw_shaded(&mut pm, m.positions, m.faces, &|x, y| map(x, -y), clip);
        }
        for l in &p.layers {
            draw_layer(&mut pm, l, &map);
        }
        for (i, l) in p.layers.iter().enumerate() {
            let y = top + inner_h + fs * (1.4 + 1.4 * i as f32);
            let mut pb = PathBuilder::new();
            pb.move_to(ox + fs, y - fs * 0.3);
            pb.line_to(ox + fs * 2.8, y - fs * 0.3);
            if let Some(path) = pb.finish() {
                let mut st = Stroke {
                    width: 2.0,
                    ..Stroke::default()
                };
                if l.dashed {
                    st.dash = StrokeDash::new(vec![5.0, 3.0], 0.0);
                }
                pm.stroke_path(&path, &paint(l.color), &st, Transform::identity(), None);
            }
            text::draw(
                &mut pm,
                l.name,
                ox + fs * 3.3,
                y,
                fs * 0.9,
                Anchor::Left,
                [30, 30, 30],
            );
        }
    }
    Ok(pm)
}

/// Stacks pictures vertically (a strip of frames).
pub fn stack(rows: &[Pixmap]) -> Result<Pixmap> {
    let w = rows.iter().map(|p| p.width()).max().unwrap_or(1);
    let h = rows.iter().map(|p| p.height()).sum::<u32>().max(1);
    let mut out = Pixmap::new(w, h).ok_or_else(|| Error::invalid("bad strip size"))?;
    out.fill(Color::WHITE);
    let mut y = 0;
    for r in rows {
        out.draw_pixmap(
            0,
            y as i32,
            r.as_ref(),
            &PixmapPaint::default(),
            Transform::identity(),
            None,
        );
        y += r.height();
    }
    Ok(out)
}

/// The shapes of one frame for the standard picture.
#[derive(Debug, Clone)]
pub struct FrameShapes<'a> {
    /// Values per point.
    pub dims: usize,
    /// Tracked source shape.
    pub tracked: &'a [f64],
    /// Its reconstruction from the key shapes.
    pub recon: &'a [f64],
    /// The target-domain ground truth, when there is one.
    pub truth: Option<&'a [f64]>,
    /// The retargeted shape.
    pub target: &'a [f64],
    /// Source contours.
    pub source_lines: &'a [Vec<usize>],
    /// Target contours.
    pub target_lines: &'a [Vec<usize>],
    /// Fixed source-panel bounds.
    pub source_bounds: ((f64, f64), (f64, f64)),
    /// Fixed target-panel bounds.
    pub target_bounds: ((f64, f64), (f64, f64)),
}

/// The standard frame picture: the tracked source with its reconstruction beside the
/// retargeted target with its ground truth.
pub fn render_frame(f: &FrameShapes, caption: &str, size: u32) -> Result<Pixmap> {
    let layer = |name, shape, polylines, color, dashed| Layer {
        name,
        shape,
        dims: f.dims,
        polylines,
        color,
        dashed,
    };
    let mut target = vec![layer(
        "retargeted",
        f.target,
        f.target_lines,
        [200, 30, 30],
        false,
    )];
    if let Some(t) = f.truth {
        target.insert(
            0,
            layer(
                "ground truth G(q)",
                t,
                f.target_lines,
                [150, 150, 150],
                true,
            ),
        );
    }
    let panels = [
        Panel {
            title: "source".into(),
            layers: vec![
                layer("tracked", f.tracked, f.source_lines, [20, 20, 20], false),
                layer(
                    "reconstruction",
                    f.recon,
                    f.source_lines,
                    [31, 90, 200],
                    true,
                ),
            ],
            bounds: f.source_bounds,
            mesh: None,
        },
        Panel {
            title: "target".into(),
            layers: target,
            bounds: f.target_bounds,
            mesh: None,
        },
    ];
    render_panels(&panels, caption, size)
}
