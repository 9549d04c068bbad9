//! Weights over time as a picture: one row per key shape, one column per frame (or per
//! pixel of frames), negative weights red and positive blue on a scale symmetric about 0, so
//! LS's counteracting weights and NNLS's sparsity are visible at a glance.

use super::text::{self, Anchor};
use keyshape_core::error::{Error, Result};
use nalgebra::DMatrix;
use tiny_skia::{Color, Paint, Pixmap, Rect, Transform};

/// The colour of `v` on a scale of ±`scale`: white at 0, blue towards +scale, red towards
/// −scale.
pub fn diverging(v: f64, scale: f64) -> [u8; 3] {
    let a = if scale > 0.0 {
        (v.abs() / scale).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mix = |from: f64, to: f64| (from + (to - from) * a).round() as u8;
    if v < 0.0 {
        [mix(255.0, 200.0), mix(255.0, 20.0), mix(255.0, 20.0)]
    } else {
        [mix(255.0, 20.0), mix(255.0, 70.0), mix(255.0, 190.0)]
    }
}

/// For each of `width` pixel columns, the frame whose weight has the largest magnitude in
/// that row among the frames the column covers (so a one-frame spike stays visible).
fn column_frames(frames: usize, width: usize) -> Vec<std::ops::Range<usize>> {
    (0..width)
        .map(|x| {
            let a = x * frames / width;
            let b = ((x + 1) * frames / width).max(a + 1).min(frames);
            a..b
        })
        .collect()
}

/// Renders `w` (keys × frames). `labels` name the rows (key frames, or `region/w_N`),
/// `frames` the columns' frame numbers.
pub fn weights_picture(
    w: &DMatrix<f64>,
    labels: &[String],
    frames: &[i64],
    title: &str,
) -> Result<Pixmap> {
    weights_picture_marked(w, labels, frames, title, &[])
}

/// [`weights_picture`] with the key frames (`keys`, frame numbers) marked on the time axis.
/// The colour scale is one-sided (0 … max) when no weight is negative (NNLS, bounded), so
/// no half of it stands unused.
pub fn weights_picture_marked(
    w: &DMatrix<f64>,
    labels: &[String],
    frames: &[i64],
    title: &str,
    keys: &[i64],
) -> Result<Pixmap> {
    let (k, n) = w.shape();
    if k == 0 || n == 0 || labels.len() != k || frames.len() != n {
        return Err(Error::invalid(format!(
            "weights picture: {k} × {n} weights with {} labels and {} frame numbers",
            labels.len(),
            frames.len()
        )));
    }
    let (left, right, top) = (110u32, 30u32, 46u32);
    let plot_w = 1100u32;
    let row_h = (560 / k as u32).clamp(6, 28);
    let plot_h = row_h * k as u32;
    let at = Layout {
        left,
        top,
        plot_w,
        row_h,
        axis_y: (top + plot_h) as f32,
    };
    let (width, height) = (left + plot_w + right, top + plot_h + 110);
    let mut pm =
        Pixmap::new(width, height).ok_or_else(|| Error::invalid("bad weights picture size"))?;
    pm.fill(Color::WHITE);
    let scale = w.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    text::draw(
        &mut pm,
        title,
        (width / 2) as f32,
        26.0,
        15.0,
        Anchor::Centre,
        INK,
    );
    draw_rows(&mut pm, &at, w, labels, scale);
    draw_frame_axis(&mut pm, &at, frames, keys);
    draw_colour_scale(&mut pm, &at, w, scale);
    Ok(pm)
}

/// The weights picture's ink.
const INK: [u8; 3] = [30, 30, 30];

/// Where the weights picture's plot sits: its left and top edges, width, row height, and
/// the frame axis's y.
struct Layout {
    left: u32,
    top: u32,
    plot_w: u32,
    row_h: u32,
    axis_y: f32,
}

impl Layout {
    /// The x of frame column `t` of `n`, at its middle.
    fn x_of(&self, t: usize, n: usize) -> f32 {
        self.left as f32 + (t as f32 + 0.5) * self.plot_w as f32 / n as f32
    }
}

/// One row per key: its label, and per pixel column the weight of largest magnitude among
/// the frames it covers, coloured on the diverging scale.
fn draw_rows(pm: &mut Pixmap, at: &Layout, w: &DMatrix<f64>, labels: &[String], scale: f64) {
    let (k, n) = w.shape();
    let row_h = at.row_h;
    let cols = column_frames(n, at.plot_w as usize);
    let mut paint = Paint::default();
    for i in 0..k {
        let y = (at.top + i as u32 * row_h) as f32;
        // Label every row while they are tall enough to read, else every few.
        let every = (12 / row_h as usize).max(1);
        if i % every == 0 {
            text::draw(
                pm,
                &labels[i],
                at.left as f32 - 8.0,
                y + row_h as f32 * 0.5 + 4.0,
                11.0,
                Anchor::Right,
                INK,
            );
        }
        for (x, r) in cols.iter().enumerate() {
            let v =
                r.clone()
                    .map(|t| w[(i, t)])
                    .fold(0.0f64, |m, v| if v.abs() > m.abs() { v } else { m });
            let c = diverging(v, scale);
            paint.set_color_rgba8(c[0], c[1], c[2], 255);
            if let Some(rect) = Rect::from_xywh(
                (at.left as usize + x) as f32,
                y,
                1.0,
                row_h as f32 - if row_h > 8 { 1.0 } else { 0.0 },
            ) {
                pm.fill_rect(rect, &paint, Transform::identity(), None);
            }
        }
    }
}

/// The frame axis: ticks at the first frame, the quarters and the last, and an orange mark
/// at each key frame among `frames`.
fn draw_frame_axis(pm: &mut Pixmap, at: &Layout, frames: &[i64], keys: &[i64]) {
    let n = frames.len();
    let axis_y = at.axis_y;
    let mut paint = Paint::default();
    for q in 0..=4usize {
        let t = (q * (n - 1)) / 4;
        let x = at.x_of(t, n);
        paint.set_color_rgba8(90, 90, 90, 255);
        if let Some(r) = Rect::from_xywh(x, axis_y, 1.0, 5.0) {
            pm.fill_rect(r, &paint, Transform::identity(), None);
        }
        text::draw(
            pm,
            &frames[t].to_string(),
            x,
            axis_y + 18.0,
            11.0,
            Anchor::Centre,
            INK,
        );
    }
    // Key frames: a dark mark on the axis at each (under the plot, above the numbers).
    let mut marked = 0;
    for key in keys {
        if let Some(t) = frames.iter().position(|f| f == key) {
            let x = at.x_of(t, n);
            paint.set_color_rgba8(230, 120, 0, 255);
            if let Some(r) = Rect::from_xywh(x - 1.5, axis_y + 1.0, 3.0, 7.0) {
                pm.fill_rect(r, &paint, Transform::identity(), None);
            }
            marked += 1;
        }
    }
    let axis_title = if marked > 0 {
        "frame (orange marks: the key frames)"
    } else {
        "frame"
    };
    text::draw(
        pm,
        axis_title,
        (at.left + at.plot_w / 2) as f32,
        axis_y + 36.0,
        12.0,
        Anchor::Centre,
        INK,
    );
}

/// The colour scale under the axis: −scale … 0 … +scale, or 0 … +scale when no weight is
/// negative, with the share of negative weights.
fn draw_colour_scale(pm: &mut Pixmap, at: &Layout, w: &DMatrix<f64>, scale: f64) {
    let (k, n) = w.shape();
    let tol = keyshape_core::decompose::NEGATIVE_TOLERANCE * scale;
    let any_negative = w.iter().any(|v| *v < -tol);
    let (sx, sy, sw) = (
        at.left as f32 + at.plot_w as f32 / 2.0 - 200.0,
        at.axis_y + 52.0,
        400.0,
    );
    let mut paint = Paint::default();
    let lo = if any_negative { -1.0 } else { 0.0 };
    for x in 0..sw as usize {
        let v = (lo + x as f64 / (sw as f64 - 1.0) * (1.0 - lo)) * scale;
        let c = diverging(v, scale);
        paint.set_color_rgba8(c[0], c[1], c[2], 255);
        if let Some(r) = Rect::from_xywh(sx + x as f32, sy, 1.0, 14.0) {
            pm.fill_rect(r, &paint, Transform::identity(), None);
        }
    }
    let ticks: &[(f32, f64)] = if any_negative {
        &[(0.0, -1.0), (0.5, 0.0), (1.0, 1.0)]
    } else {
        &[(0.0, 0.0), (0.5, 0.5), (1.0, 1.0)]
    };
    for &(frac, v) in ticks {
        let v = v * scale;
        text::draw(
            pm,
            &format!("{v:.3}"),
            sx + frac * sw,
            sy + 30.0,
            11.0,
            Anchor::Centre,
            INK,
        );
    }
    let negative = w.iter().filter(|v| **v < -tol).count() as f64 / (k * n) as f64;
    text::draw(
        pm,
        &format!(
            "weight (red negative, blue positive) · negative {:.1} %",
            100.0 * negative
        ),
        sx + sw + 20.0,
        sy + 12.0,
        11.0,
        Anchor::Left,
        INK,
    );
}
