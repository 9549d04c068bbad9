//! A mesh drawn as an orthographic front-view wireframe (x right, y up), beside the source
//! feature points.

use super::face::{render_panels, Layer, Panel};
use super::text::{self, Anchor};
use keyshape_core::error::{Error, Result};
use tiny_skia::{Color, FillRule, Paint, PathBuilder, Pixmap, PixmapPaint, Stroke, Transform};

/// Bounds (x, y) of positions, padded 5 %.
pub fn mesh_bounds(positions: &[[f64; 3]]) -> ((f64, f64), (f64, f64)) {
    let (mut lo, mut hi) = (
        (f64::INFINITY, f64::INFINITY),
        (f64::NEG_INFINITY, f64::NEG_INFINITY),
    );
    for p in positions {
        lo = (lo.0.min(p[0]), lo.1.min(p[1]));
        hi = (hi.0.max(p[0]), hi.1.max(p[1]));
    }
    let pad = 0.05 * (hi.0 - lo.0).max(hi.1 - lo.1).max(1e-9);
    ((lo.0 - pad, lo.1 - pad), (hi.0 + pad, hi.1 + pad))
}

/// The wireframe of `faces` over `positions` in a `size`-pixel square, with feature vertices
/// (`marks`) as red dots.
pub fn wireframe(
    positions: &[[f64; 3]],
    faces: &[Vec<usize>],
    marks: &[usize],
    bounds: ((f64, f64), (f64, f64)),
    size: u32,
    title: &str,
) -> Result<Pixmap> {
    let mut pm = Pixmap::new(size, size).ok_or_else(|| Error::invalid("bad picture size"))?;
    pm.fill(Color::WHITE);
    let ((x0, y0), (x1, y1)) = bounds;
    let span = (x1 - x0).max(y1 - y0).max(1e-12);
    let s = f64::from(size) * 0.9 / span;
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let map = |p: &[f64; 3]| {
        (
            (f64::from(size) / 2.0 + (p[0] - cx) * s) as f32,
            (f64::from(size) / 2.0 + 8.0 - (p[1] - cy) * s) as f32,
        )
    };
    let mut pb = PathBuilder::new();
    for f in faces {
        for (k, &v) in f.iter().enumerate() {
            let (x, y) = map(&positions[v]);
            if k == 0 {
                pb.move_to(x, y)
            } else {
                pb.line_to(x, y)
            }
        }
        pb.close();
    }
    let mut paint = Paint::default();
    paint.set_color_rgba8(60, 60, 90, 110);
    paint.anti_alias = true;
    if let Some(path) = pb.finish() {
        pm.stroke_path(
            &path,
            &paint,
            &Stroke {
                width: 0.6,
                ..Stroke::default()
            },
            Transform::identity(),
            None,
        );
    }
    paint.set_color_rgba8(210, 30, 30, 255);
    for &m in marks {
        let (x, y) = map(&positions[m]);
        if let Some(c) = PathBuilder::from_circle(x, y, 2.5) {
            pm.fill_path(&c, &paint, FillRule::Winding, Transform::identity(), None);
        }
    }
    text::draw(
        &mut pm,
        title,
        f32::from(size as u16) / 2.0,
        16.0,
        13.0,
        Anchor::Centre,
        [30, 30, 30],
    );
    Ok(pm)
}

/// Draws `faces` over `positions` (y up, z towards the viewer) flat-shaded, far faces first
/// (painter's order by mean depth), each grey by how squarely it faces a light above left of
/// the viewer; `map` takes (x, y up) to the picture, and nothing is drawn outside `clip`
/// (x, y, width, height in pixels).
pub fn draw_shaded(
    pm: &mut Pixmap,
    positions: &[[f64; 3]],
    faces: &[Vec<usize>],
    map: &dyn Fn(f64, f64) -> (f32, f32),
    clip: (f32, f32, f32, f32),
) {
    let mask = tiny_skia::Mask::new(pm.width(), pm.height()).and_then(|mut m| {
        let rect = tiny_skia::Rect::from_xywh(clip.0, clip.1, clip.2, clip.3)?;
        m.fill_path(
            &PathBuilder::from_rect(rect),
            FillRule::Winding,
            false,
            Transform::identity(),
        );
        Some(m)
    });
    let light = {
        let l: [f64; 3] = [-0.35, 0.45, 1.0];
        let n = (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]).sqrt();
        [l[0] / n, l[1] / n, l[2] / n]
    };
    let mut order: Vec<(f64, usize)> = faces
        .iter()
        .enumerate()
        .filter(|(_, f)| f.len() >= 3 && f.iter().all(|&v| v < positions.len()))
        .map(|(i, f)| {
            let z = f.iter().map(|&v| positions[v][2]).sum::<f64>() / f.len() as f64;
            (z, i)
        })
        .collect();
    order.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut paint = Paint {
        anti_alias: false,
        ..Paint::default()
    };
    for (_, i) in order {
        let f = &faces[i];
        // Newell's normal: robust for quads that are not quite planar.
        let mut n = [0.0f64; 3];
        for (k, &a) in f.iter().enumerate() {
            let (p, q) = (positions[a], positions[f[(k + 1) % f.len()]]);
            n[0] += (p[1] - q[1]) * (p[2] + q[2]);
            n[1] += (p[2] - q[2]) * (p[0] + q[0]);
            n[2] += (p[0] - q[0]) * (p[1] + q[1]);
        }
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        if len <= 0.0 || n[2] <= 0.0 {
            continue; // edge-on or facing away
        }
        let lambert = ((n[0] * light[0] + n[1] * light[1] + n[2] * light[2]) / len).max(0.0);
        let g = (70.0 + 170.0 * lambert).round().clamp(0.0, 255.0) as u8;
        paint.set_color_rgba8(g, g, (f64::from(g) * 1.02).min(255.0) as u8, 255);
        let mut pb = PathBuilder::new();
        for (k, &v) in f.iter().enumerate() {
            let (x, y) = map(positions[v][0], positions[v][1]);
            if k == 0 {
                pb.move_to(x, y)
            } else {
                pb.line_to(x, y)
            }
        }
        pb.close();
        if let Some(path) = pb.finish() {
            pm.fill_path(
                &path,
                &paint,
                FillRule::Winding,
                Transform::identity(),
                mask.as_ref(),
            );
        }
    }
}

/// A transfer frame: the tracked source as a panel beside the deformed target mesh, drawn
/// in a panel of the same size, title and height as the source's (the mesh stood higher
/// and smaller under a title of its own size), its feature points red and named in a
/// legend. `mesh_wire` draws the mesh (no title) into a square of the side it is given.
pub fn transfer_frame(
    source: &[f64],
    dims: usize,
    source_lines: &[Vec<usize>],
    source_bounds: ((f64, f64), (f64, f64)),
    mesh_wire: &dyn Fn(u32) -> Result<Pixmap>,
    size: u32,
    caption: &str,
) -> Result<Pixmap> {
    let panel = Panel {
        title: "source".into(),
        layers: vec![Layer {
            name: "tracked",
            shape: source,
            dims,
            polylines: source_lines,
            color: [20, 20, 20],
            dashed: false,
        }],
        bounds: source_bounds,
        mesh: None,
    };
    let left = render_panels(&[panel], caption, size)?;
    // The geometry render_panels gives a square panel.
    let fs = (size as f32 / 22.0).clamp(10.0, 16.0);
    let top = (fs * 2.2).floor() + fs * 1.2;
    let inner = size as f32 - 2.0 * fs;
    let mesh = mesh_wire(inner.round() as u32)?;
    let mut out = Pixmap::new(left.width() * 2, left.height())
        .ok_or_else(|| Error::invalid("bad picture size"))?;
    out.fill(Color::WHITE);
    out.draw_pixmap(
        0,
        0,
        left.as_ref(),
        &PixmapPaint::default(),
        Transform::identity(),
        None,
    );
    let ox = left.width() as f32;
    text::draw(
        &mut out,
        "target mesh",
        ox + size as f32 / 2.0,
        top - fs * 0.3,
        fs,
        Anchor::Centre,
        [30, 30, 30],
    );
    out.draw_pixmap(
        (ox + (size as f32 - inner) / 2.0) as i32,
        (top + fs * 0.3) as i32,
        mesh.as_ref(),
        &PixmapPaint::default(),
        Transform::identity(),
        None,
    );
    // The legend, where the source panel has its own.
    let y = top + inner + fs * 1.4;
    let mut paint = Paint::default();
    paint.set_color_rgba8(210, 30, 30, 255);
    if let Some(c) = PathBuilder::from_circle(ox + fs * 1.9, y - fs * 0.3, 3.0) {
        out.fill_path(&c, &paint, FillRule::Winding, Transform::identity(), None);
    }
    text::draw(
        &mut out,
        "feature points (the RBF's targets)",
        ox + fs * 3.3,
        y,
        fs * 0.9,
        Anchor::Left,
        [30, 30, 30],
    );
    Ok(out)
}
