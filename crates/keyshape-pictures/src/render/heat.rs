//! Heat maps of square tables (the orthogonality tables of paper 002), side by side.

use super::text::{self, Anchor};
use keyshape_core::error::{Error, Result};
use nalgebra::DMatrix;
use tiny_skia::{Color, Paint, Pixmap, Rect, Transform};

/// The colour of `v` in [0, 1]: white (0, orthogonal) to dark red (1, parallel).
fn shade(v: f64) -> [u8; 3] {
    let v = v.clamp(0.0, 1.0);
    let c = |a: f64, b: f64| (a + (b - a) * v).round() as u8;
    [c(255.0, 150.0), c(255.0, 10.0), c(255.0, 10.0)]
}

/// Tables with values in [0, 1] (upper triangle drawn), each titled, labelled by `names`
/// on both axes (rows on the left, columns above, read bottom to top), with a colour scale
/// under them.
pub fn heat_maps(tables: &[(&str, &DMatrix<f64>)], names: &[String], cell: u32) -> Result<Pixmap> {
    let n = names.len() as u32;
    let label_w = 130u32;
    // Room above the grid for the column names, as long as the longest.
    let label_h = names
        .iter()
        .map(|s| text::width(s, 11.0).ceil() as u32)
        .max()
        .unwrap_or(0)
        + 10;
    let grid_top = 40 + label_h;
    let scale_h = 56u32;
    let (tw, th) = (label_w + n * cell + 20, grid_top + n * cell + 20 + scale_h);
    let mut pm = Pixmap::new(tw * tables.len() as u32, th)
        .ok_or_else(|| Error::invalid("bad heat-map size"))?;
    pm.fill(Color::WHITE);
    let gt = grid_top as f32;
    for (k, (title, m)) in tables.iter().enumerate() {
        let ox = (k as u32 * tw) as f32;
        text::draw(
            &mut pm,
            title,
            ox + (label_w + n * cell / 2) as f32,
            22.0,
            14.0,
            Anchor::Centre,
            [30, 30, 30],
        );
        for (j, name) in names.iter().enumerate() {
            let w = text::width(name, 11.0);
            text::draw_vertical(
                &mut pm,
                name,
                ox + (label_w + j as u32 * cell) as f32 + cell as f32 / 2.0,
                gt - 6.0 - w / 2.0,
                11.0,
                [30, 30, 30],
            );
        }
        draw_grid(&mut pm, m, names, (ox + label_w as f32, gt), cell);
        draw_scale(
            &mut pm,
            (ox + label_w as f32, gt + (n * cell) as f32 + 18.0),
            (n * cell) as f32,
        );
    }
    Ok(pm)
}

/// One table's grid, its top-left corner at `(x0, y0)`: each row's name on the left and,
/// above the diagonal, each cell shaded by its value and labelled with it.
fn draw_grid(pm: &mut Pixmap, m: &DMatrix<f64>, names: &[String], (x0, y0): (f32, f32), cell: u32) {
    let n = names.len();
    let c = cell as f32;
    let mut paint = Paint::default();
    for i in 0..n {
        text::draw(
            pm,
            &names[i],
            x0 - 6.0,
            y0 + (i as f32 + 0.7) * c,
            11.0,
            Anchor::Right,
            [30, 30, 30],
        );
        for j in i + 1..n {
            let v = m[(i, j)].clamp(0.0, 1.0);
            let rgb = shade(v);
            paint.set_color_rgba8(rgb[0], rgb[1], rgb[2], 255);
            let x = x0 + (j as u32 * cell) as f32;
            if let Some(r) = Rect::from_xywh(x, y0 + (i as u32 * cell) as f32, c - 1.0, c - 1.0) {
                pm.fill_rect(r, &paint, Transform::identity(), None);
            }
            let ink = if v > 0.5 {
                [255, 255, 255]
            } else {
                [30, 30, 30]
            };
            text::draw(
                pm,
                &format!("{v:.2}"),
                x + c / 2.0,
                y0 + (i as f32 + 0.62) * c,
                10.0,
                Anchor::Centre,
                ink,
            );
        }
    }
}

/// The colour scale, `width` wide from `(sx, sy)`: 0 (orthogonal) … 1 (parallel).
fn draw_scale(pm: &mut Pixmap, (sx, sy): (f32, f32), sw: f32) {
    let mut paint = Paint::default();
    for x in 0..sw as usize {
        let c = shade(x as f64 / (sw as f64 - 1.0).max(1.0));
        paint.set_color_rgba8(c[0], c[1], c[2], 255);
        if let Some(r) = Rect::from_xywh(sx + x as f32, sy, 1.0, 12.0) {
            pm.fill_rect(r, &paint, Transform::identity(), None);
        }
    }
    for (frac, label, anchor) in [
        (0.0, "0 orthogonal", Anchor::Left),
        (0.5, "0.5", Anchor::Centre),
        (1.0, "1 parallel", Anchor::Right),
    ] {
        text::draw(
            pm,
            label,
            sx + frac * sw,
            sy + 28.0,
            11.0,
            anchor,
            [30, 30, 30],
        );
    }
}
