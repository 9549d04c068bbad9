//! A readable line plot: axes with ticks and numbers, axis titles, title, legend.

use super::text::{self, Anchor};
use crate::plot::{PlotSpec, Style};
use keyshape_core::error::{Error, Result};
use tiny_skia::{Color, FillRule, Paint, PathBuilder, Pixmap, Rect, Stroke, StrokeDash, Transform};

const INK: [u8; 3] = [30, 30, 30];
const GRID: [u8; 3] = [225, 225, 225];

fn paint(c: [u8; 3]) -> Paint<'static> {
    let mut p = Paint::default();
    p.set_color_rgba8(c[0], c[1], c[2], 255);
    p.anti_alias = true;
    p
}

/// About `n` "nice" tick values (1, 2, 5 × 10^e) covering [lo, hi].
pub fn ticks(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    if hi.is_nan() || lo.is_nan() || hi <= lo {
        return vec![lo];
    }
    let raw = (hi - lo) / n.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let start = (lo / step).ceil() as i64;
    let end = (hi / step).floor() as i64;
    (start..=end).map(|i| i as f64 * step).collect()
}

fn label(v: f64, step: f64) -> String {
    let decimals = if step >= 1.0 {
        0
    } else {
        (-step.log10().floor()) as usize
    };
    format!("{v:.decimals$}")
}

fn line(pixmap: &mut Pixmap, pts: &[(f32, f32)], color: [u8; 3], width: f32, dash: bool) {
    let mut pb = PathBuilder::new();
    for (i, &(x, y)) in pts.iter().enumerate() {
        if i == 0 {
            pb.move_to(x, y)
        } else {
            pb.line_to(x, y)
        }
    }
    let Some(path) = pb.finish() else { return };
    let mut stroke = Stroke {
        width,
        ..Stroke::default()
    };
    if dash {
        stroke.dash = StrokeDash::new(vec![7.0, 5.0], 0.0);
    }
    pixmap.stroke_path(&path, &paint(color), &stroke, Transform::identity(), None);
}

/// A closed polygon filled at low opacity (a [`Style::Band`]).
fn band(pixmap: &mut Pixmap, pts: &[(f32, f32)], color: [u8; 3]) {
    let mut pb = PathBuilder::new();
    let Some(&(x, y)) = pts.first() else { return };
    pb.move_to(x, y);
    for &(x, y) in &pts[1..] {
        pb.line_to(x, y);
    }
    pb.close();
    if let Some(path) = pb.finish() {
        let mut p = paint(color);
        p.set_color_rgba8(color[0], color[1], color[2], 48);
        pixmap.fill_path(&path, &p, FillRule::Winding, Transform::identity(), None);
    }
}

fn dot(pixmap: &mut Pixmap, x: f32, y: f32, r: f32, color: [u8; 3]) {
    if let Some(path) = PathBuilder::from_circle(x, y, r) {
        pixmap.fill_path(
            &path,
            &paint(color),
            FillRule::Winding,
            Transform::identity(),
            None,
        );
    }
}

/// Renders `spec` into a `width × height` picture.
pub fn render_plot(spec: &PlotSpec, width: u32, height: u32) -> Result<Pixmap> {
    let mut pm = Pixmap::new(width, height)
        .ok_or_else(|| Error::invalid(format!("bad picture size {width}×{height}")))?;
    pm.fill(Color::WHITE);
    let (xs, ys) = ranges(spec)?;
    let fs = (height as f32 / 40.0).clamp(11.0, 18.0);
    let axes = Axes {
        xs,
        ys,
        log: spec.log_y(),
        left: fs * 5.5,
        right: width as f32 - fs * 1.2,
        top: fs * 3.0,
        bottom: height as f32 - fs * 3.6,
        fs,
    };
    axes.draw_grid(&mut pm);
    axes.draw_titles(&mut pm, spec, height);
    // Series.
    for s in &spec.series {
        let pts: Vec<(f32, f32)> = s.points.iter().map(|&p| axes.at(p)).collect();
        match s.style {
            Style::Band => band(&mut pm, &pts, s.color),
            Style::Thin => line(&mut pm, &pts, s.color, 1.0, false),
            Style::Marker => pts
                .iter()
                .for_each(|&(x, y)| dot(&mut pm, x, y, fs * 0.45, s.color)),
            Style::Line | Style::Dashed => {
                line(&mut pm, &pts, s.color, 2.0, s.style == Style::Dashed);
                pts.iter()
                    .for_each(|&(x, y)| dot(&mut pm, x, y, 2.5, s.color));
            }
        }
    }
    // The legend goes in the corner its box covers the least of the curves in.
    let drawn: Vec<Vec<(f32, f32)>> = spec
        .series
        .iter()
        .map(|s| s.points.iter().map(|&p| axes.at(p)).collect())
        .collect();
    let Axes {
        left,
        right,
        top,
        bottom,
        ..
    } = axes;
    legend(&mut pm, spec, (left, right, top, bottom), fs, &drawn);
    Ok(pm)
}

/// The x and y ranges a plot shows: the data's, a little wider (y in decades on a log
/// axis), or ±1 around a single value.
fn ranges(spec: &PlotSpec) -> Result<((f64, f64), (f64, f64))> {
    let ((x0, x1), (y0, y1)) = spec
        .bounds()
        .ok_or_else(|| Error::invalid("nothing to plot: every series is empty"))?;
    let xs = if x1 > x0 {
        (x0 - 0.02 * (x1 - x0), x1 + 0.02 * (x1 - x0))
    } else {
        (x0 - 1.0, x1 + 1.0)
    };
    let ys = if spec.log_y() {
        // The data's own range, a little wider, in decades.
        let lo = spec
            .series
            .iter()
            .flat_map(|s| s.points.iter())
            .map(|p| p.1)
            .filter(|y| y.is_finite() && *y > 0.0)
            .fold(f64::INFINITY, f64::min);
        (lo / 1.25, y1 * 1.25)
    } else if y1 > y0 {
        (y0, y1 + 0.05 * (y1 - y0))
    } else {
        (y0 - 1.0, y1 + 1.0)
    };
    Ok((xs, ys))
}

/// A plot's axes: the ranges shown, whether y is on a log scale, the plot area's edges
/// (pixels) and the font size.
struct Axes {
    xs: (f64, f64),
    ys: (f64, f64),
    log: bool,
    left: f32,
    right: f32,
    top: f32,
    bottom: f32,
    fs: f32,
}

impl Axes {
    fn sx(&self, x: f64) -> f32 {
        let (x0, x1) = self.xs;
        self.left + ((x - x0) / (x1 - x0)) as f32 * (self.right - self.left)
    }

    fn sy(&self, y: f64) -> f32 {
        let (y0, y1) = self.ys;
        let f = if self.log {
            (y.max(y0).ln() - y0.ln()) / (y1.ln() - y0.ln())
        } else {
            (y - y0) / (y1 - y0)
        };
        self.bottom - f as f32 * (self.bottom - self.top)
    }

    /// A data point's pixel.
    fn at(&self, (x, y): (f64, f64)) -> (f32, f32) {
        (self.sx(x), self.sy(y))
    }

    /// Grid, ticks and their numbers, and the axes' lines.
    fn draw_grid(&self, pm: &mut Pixmap) {
        let (left, right, top, bottom, fs) =
            (self.left, self.right, self.top, self.bottom, self.fs);
        let xt = ticks(self.xs.0, self.xs.1, 10);
        let xstep = if xt.len() > 1 { xt[1] - xt[0] } else { 1.0 };
        for &t in &xt {
            let x = self.sx(t);
            line(pm, &[(x, top), (x, bottom)], GRID, 1.0, false);
            line(pm, &[(x, bottom), (x, bottom + 5.0)], INK, 1.0, false);
            text::draw(
                pm,
                &label(t, xstep),
                x,
                bottom + 7.0 + fs,
                fs,
                Anchor::Centre,
                INK,
            );
        }
        let (yt, ystep) = if self.log {
            let t = log_ticks(self.ys.0, self.ys.1);
            let step = t.first().copied().unwrap_or(1.0);
            (t, step)
        } else {
            let t = ticks(self.ys.0, self.ys.1, 8);
            let step = if t.len() > 1 { t[1] - t[0] } else { 1.0 };
            (t, step)
        };
        for &t in &yt {
            let ystep = if self.log { t } else { ystep };
            let y = self.sy(t);
            line(pm, &[(left, y), (right, y)], GRID, 1.0, false);
            line(pm, &[(left - 5.0, y), (left, y)], INK, 1.0, false);
            text::draw(
                pm,
                &label(t, ystep),
                left - 8.0,
                y + fs * 0.35,
                fs,
                Anchor::Right,
                INK,
            );
        }
        line(
            pm,
            &[(left, top), (left, bottom), (right, bottom)],
            INK,
            1.5,
            false,
        );
    }

    /// The plot's title, and its axes' labels (y's says when it is a log scale).
    fn draw_titles(&self, pm: &mut Pixmap, spec: &PlotSpec, height: u32) {
        let (left, right, top, bottom, fs) =
            (self.left, self.right, self.top, self.bottom, self.fs);
        text::draw(
            pm,
            &spec.title,
            (left + right) / 2.0,
            top - fs * 1.0,
            fs * 1.15,
            Anchor::Centre,
            INK,
        );
        text::draw(
            pm,
            &spec.x_label,
            (left + right) / 2.0,
            height as f32 - fs * 0.6,
            fs,
            Anchor::Centre,
            INK,
        );
        let y_label = if self.log {
            format!("{} (log scale)", spec.y_label)
        } else {
            spec.y_label.clone()
        };
        text::draw_vertical(pm, &y_label, fs * 1.0, (top + bottom) / 2.0, fs, INK);
    }
}

/// Tick values for a log axis over [lo, hi]: 1, 2, 5 × 10^e, thinned to 1 × 10^e when
/// they would crowd (more than three decades).
pub fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    if !(lo > 0.0 && hi > lo) {
        return vec![lo];
    }
    let decades = (hi / lo).log10();
    let mults: &[f64] = if decades > 3.0 {
        &[1.0]
    } else {
        &[1.0, 2.0, 5.0]
    };
    let mut out = Vec::new();
    let mut e = lo.log10().floor() as i32;
    while 10f64.powi(e) <= hi {
        for m in mults {
            let v = m * 10f64.powi(e);
            if v >= lo && v <= hi {
                out.push(v);
            }
        }
        e += 1;
    }
    out
}

/// How much of the drawn curves a box covers: points and samples along each segment
/// inside it.
fn covered(drawn: &[Vec<(f32, f32)>], r: (f32, f32, f32, f32)) -> usize {
    let inside = |(x, y): (f32, f32)| x >= r.0 && x <= r.0 + r.2 && y >= r.1 && y <= r.1 + r.3;
    drawn
        .iter()
        .map(|pts| {
            pts.windows(2)
                .map(|w| {
                    (0..=16)
                        .filter(|i| {
                            let f = *i as f32 / 16.0;
                            inside((
                                w[0].0 + f * (w[1].0 - w[0].0),
                                w[0].1 + f * (w[1].1 - w[0].1),
                            ))
                        })
                        .count()
                })
                .sum::<usize>()
                + pts.iter().filter(|p| inside(**p)).count()
        })
        .sum()
}

fn legend(
    pm: &mut Pixmap,
    spec: &PlotSpec,
    (left, right, top, bottom): (f32, f32, f32, f32),
    fs: f32,
    drawn: &[Vec<(f32, f32)>],
) {
    let listed: Vec<&crate::plot::Series> = spec
        .series
        .iter()
        .filter(|s| !matches!(s.style, Style::Band | Style::Thin))
        .collect();
    let wmax = listed
        .iter()
        .map(|s| text::width(&s.name, fs))
        .fold(0.0, f32::max);
    let (w, row) = (wmax + fs * 3.6, fs * 1.4);
    let h = row * listed.len() as f32 + fs * 0.6;
    let pad = fs * 0.5;
    // Top right first (ties keep it), then top left, bottom right, bottom left.
    let corners = [
        (right - w - pad, top + pad),
        (left + pad * 2.0, top + pad),
        (right - w - pad, bottom - h - pad),
        (left + pad * 2.0, bottom - h - pad),
    ];
    let (x, y) = corners
        .iter()
        .copied()
        .min_by_key(|&(x, y)| covered(drawn, (x, y, w, h)))
        .unwrap_or(corners[0]);
    if let Some(r) = Rect::from_xywh(x, y, w, h) {
        pm.fill_rect(r, &paint([255, 255, 255]), Transform::identity(), None);
        let mut pb = PathBuilder::new();
        pb.push_rect(r);
        if let Some(p) = pb.finish() {
            pm.stroke_path(
                &p,
                &paint([160, 160, 160]),
                &Stroke::default(),
                Transform::identity(),
                None,
            );
        }
    }
    for (i, s) in listed.iter().enumerate() {
        let cy = y + fs * 0.3 + row * (i as f32 + 0.5);
        let (lx0, lx1) = (x + fs * 0.5, x + fs * 2.4);
        match s.style {
            Style::Marker => dot(pm, (lx0 + lx1) / 2.0, cy, fs * 0.45, s.color),
            _ => line(
                pm,
                &[(lx0, cy), (lx1, cy)],
                s.color,
                2.0,
                s.style == Style::Dashed,
            ),
        }
        text::draw(
            pm,
            &s.name,
            lx1 + fs * 0.5,
            cy + fs * 0.35,
            fs,
            Anchor::Left,
            INK,
        );
    }
}
