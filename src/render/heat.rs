//! Heat maps of square tables (the orthogonality tables of paper 002), side by side.

use super::text::{self, Anchor};
use crate::error::{Error, Result};
use nalgebra::DMatrix;
use tiny_skia::{Color, Paint, Pixmap, Rect, Transform};

/// Tables with values in [0, 1] (upper triangle drawn), each titled, labelled by `names`.
pub fn heat_maps(tables: &[(&str, &DMatrix<f64>)], names: &[String], cell: u32) -> Result<Pixmap> {
    let n = names.len() as u32;
    let label_w = 130u32;
    let (tw, th) = (label_w + n * cell + 20, 40 + n * cell + 20);
    let mut pm = Pixmap::new(tw * tables.len() as u32, th)
        .ok_or_else(|| Error::invalid("bad heat-map size"))?;
    pm.fill(Color::WHITE);
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
        for i in 0..n as usize {
            text::draw(
                &mut pm,
                &names[i],
                ox + label_w as f32 - 6.0,
                40.0 + (i as f32 + 0.7) * cell as f32,
                11.0,
                Anchor::Right,
                [30, 30, 30],
            );
            for j in 0..n as usize {
                if j <= i {
                    continue;
                }
                let v = m[(i, j)].clamp(0.0, 1.0);
                // White (0, orthogonal) to dark red (1, parallel).
                let c = |a: f64, b: f64| (a + (b - a) * v).round() as u8;
                let mut paint = Paint::default();
                paint.set_color_rgba8(c(255.0, 150.0), c(255.0, 10.0), c(255.0, 10.0), 255);
                if let Some(r) = Rect::from_xywh(
                    ox + (label_w + j as u32 * cell) as f32,
                    40.0 + (i as u32 * cell) as f32,
                    cell as f32 - 1.0,
                    cell as f32 - 1.0,
                ) {
                    pm.fill_rect(r, &paint, Transform::identity(), None);
                }
                let ink = if v > 0.5 {
                    [255, 255, 255]
                } else {
                    [30, 30, 30]
                };
                text::draw(
                    &mut pm,
                    &format!("{v:.2}"),
                    ox + (label_w + j as u32 * cell) as f32 + cell as f32 / 2.0,
                    40.0 + (i as f32 + 0.62) * cell as f32,
                    10.0,
                    Anchor::Centre,
                    ink,
                );
            }
        }
    }
    Ok(pm)
}
