//! Text for tiny-skia pictures (tiny-skia draws no glyphs): a committed subset of DejaVu
//! Sans (`assets/fonts/`, Bitstream Vera licence) rasterised with fontdue and blended into
//! an opaque pixmap.

use fontdue::{Font, FontSettings};
use std::sync::OnceLock;
use tiny_skia::{Pixmap, PremultipliedColorU8};

const FONT_BYTES: &[u8] = include_bytes!("../../../../assets/fonts/DejaVuSans-subset.ttf");

fn font() -> Option<&'static Font> {
    static FONT: OnceLock<Option<Font>> = OnceLock::new();
    FONT.get_or_init(|| Font::from_bytes(FONT_BYTES, FontSettings::default()).ok())
        .as_ref()
}

/// Horizontal anchor of a text run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Anchor {
    /// x is the left edge.
    Left,
    /// x is the centre.
    Centre,
    /// x is the right edge.
    Right,
}

/// A rendered run of text: coverage bitmap, width × height, baseline at `ascent`.
struct Run {
    w: usize,
    h: usize,
    ascent: usize,
    cov: Vec<u8>,
}

fn rasterise(text: &str, px: f32) -> Option<Run> {
    let font = font()?;
    let lm = font.horizontal_line_metrics(px)?;
    let ascent = lm.ascent.ceil() as i32;
    let h = (lm.ascent - lm.descent).ceil() as usize + 1;
    let glyphs: Vec<_> = text.chars().map(|c| font.rasterize(c, px)).collect();
    let w = glyphs
        .iter()
        .map(|(m, _)| m.advance_width)
        .sum::<f32>()
        .ceil() as usize
        + 2;
    let mut cov = vec![0u8; w * h];
    let mut pen = 0.0f32;
    for (m, bmp) in &glyphs {
        let x0 = (pen + m.xmin as f32).round() as i32;
        let y0 = ascent - m.height as i32 - m.ymin;
        for gy in 0..m.height {
            for gx in 0..m.width {
                let (x, y) = (x0 + gx as i32, y0 + gy as i32);
                if x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h {
                    let c = &mut cov[y as usize * w + x as usize];
                    *c = (*c).max(bmp[gy * m.width + gx]);
                }
            }
        }
        pen += m.advance_width;
    }
    Some(Run {
        w,
        h,
        ascent: ascent.max(0) as usize,
        cov,
    })
}

fn blend(pixmap: &mut Pixmap, x: i32, y: i32, color: [u8; 3], a: u8) {
    if x < 0 || y < 0 || x as u32 >= pixmap.width() || y as u32 >= pixmap.height() || a == 0 {
        return;
    }
    let i = y as usize * pixmap.width() as usize + x as usize;
    let px = &mut pixmap.pixels_mut()[i];
    let a = u16::from(a);
    let mix = |d: u8, s: u8| ((u16::from(d) * (255 - a) + u16::from(s) * a) / 255) as u8;
    if let Some(c) = PremultipliedColorU8::from_rgba(
        mix(px.red(), color[0]),
        mix(px.green(), color[1]),
        mix(px.blue(), color[2]),
        255,
    ) {
        *px = c;
    }
}

/// Width in pixels of `text` at size `px`.
pub fn width(text: &str, px: f32) -> f32 {
    rasterise(text, px).map_or(0.0, |r| r.w as f32)
}

/// Draws `text` with its baseline at `y`.
pub fn draw(
    pixmap: &mut Pixmap,
    text: &str,
    x: f32,
    y: f32,
    px: f32,
    anchor: Anchor,
    color: [u8; 3],
) {
    let Some(r) = rasterise(text, px) else { return };
    let left = match anchor {
        Anchor::Left => x,
        Anchor::Centre => x - r.w as f32 / 2.0,
        Anchor::Right => x - r.w as f32,
    }
    .round() as i32;
    let top = y.round() as i32 - r.ascent as i32;
    for gy in 0..r.h {
        for gx in 0..r.w {
            blend(
                pixmap,
                left + gx as i32,
                top + gy as i32,
                color,
                r.cov[gy * r.w + gx],
            );
        }
    }
}

/// Draws `text` turned 90° counter-clockwise (reading bottom to top), centred on (x, y).
pub fn draw_vertical(pixmap: &mut Pixmap, text: &str, x: f32, y: f32, px: f32, color: [u8; 3]) {
    let Some(r) = rasterise(text, px) else { return };
    let left = x.round() as i32 - r.h as i32 / 2;
    let bottom = y.round() as i32 + r.w as i32 / 2;
    for gy in 0..r.h {
        for gx in 0..r.w {
            blend(
                pixmap,
                left + gy as i32,
                bottom - gx as i32,
                color,
                r.cov[gy * r.w + gx],
            );
        }
    }
}
