//! The lab's charts: the error curves against k, the weight bars and the weights over
//! time, their labels and colours, and where a click on the chart lands.

use super::request::Computed;
use super::state::State;
use super::view::regions;
use keyshape_core::keyshapes::Method;
use nalgebra::DMatrix;
use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Style};
use ratatui::symbols::Marker;
use ratatui::text::{Line, Span};
use ratatui::widgets::{Axis, Block, Chart, Dataset, GraphType, Paragraph};
use ratatui::Frame;

/// A method's name in the chart legend, short enough for all eight to fit: `km2` is
/// kmeans2 (the frame nearest each centre), `km2m` kmeans2-mean (the cluster means).
pub fn short_label(m: &Method) -> String {
    match m {
        Method::KMeans { pcs, mean: false } => format!("km{pcs}"),
        Method::KMeans { pcs, mean: true } => format!("km{pcs}m"),
        Method::Random => "rand".into(),
        other => other.name(),
    }
}

pub(super) fn colour(rgb: [u8; 3]) -> Color {
    Color::Rgb(rgb[0], rgb[1], rgb[2])
}

/// Each method's colour in the lab. A terminal may be dark or light, so every colour is of
/// middle luminance — a WCAG contrast of at least 2.5 against black and against white — and
/// each differs from every other (the PNG plots, on white, tell the k-means variants apart
/// by dashes as well; a terminal chart has only colour). Keyed on [`Method`], with no
/// default: a new method does not compile until it has its colour.
pub fn lab_rgb(method: &Method) -> [u8; 3] {
    match *method {
        Method::Spread => [70, 130, 255],
        Method::KMeans {
            pcs: 2,
            mean: false,
        } => [40, 170, 60],
        Method::KMeans {
            pcs: 3,
            mean: false,
        } => [210, 60, 210],
        Method::KMeans { pcs: 2, mean: true } => [0, 160, 160],
        Method::KMeans { pcs: 3, mean: true } => [150, 100, 255],
        // k-means on another count of components (the lab offers 2 and 3 only).
        Method::KMeans { .. } => [200, 120, 60],
        Method::Hull => [235, 50, 50],
        Method::Greedy => [230, 140, 0],
        Method::Random => [140, 140, 140],
    }
}

/// [`lab_rgb`] of a method named as the curves' rows name it; a name that is no method is
/// grey.
fn named_rgb(name: &str) -> [u8; 3] {
    Method::parse(name).map_or([120, 120, 120], |m| lab_rgb(&m))
}

/// The chart's legend in at most `width` characters: every method, named as short as it
/// takes (`spread`, then `spr`), the solver kept, `E(k)` dropped first.
pub fn legend_labels(solver: &str, width: usize) -> (String, Vec<String>) {
    let tiny = |m: &Method| match m {
        Method::Spread => "spr".to_string(),
        Method::Greedy => "grd".to_string(),
        Method::Random => "rnd".to_string(),
        other => short_label(other),
    };
    let long: Vec<String> = Method::ALL.iter().map(short_label).collect();
    let short: Vec<String> = Method::ALL.iter().map(tiny).collect();
    let len = |head: &str, names: &[String]| {
        head.chars().count() + names.iter().map(|n| n.chars().count() + 1).sum::<usize>()
    };
    for (head, names) in [
        (format!("E(k) {solver}: "), &long),
        (format!("E(k) {solver}: "), &short),
        (format!("{solver}: "), &short),
    ] {
        if len(&head, names) <= width {
            return (head, names.clone());
        }
    }
    (String::new(), short)
}

pub(super) fn error_chart(f: &mut Frame, s: &State, area: Rect) {
    let (head, names) = legend_labels(
        s.settings.solver.name(),
        area.width.saturating_sub(2) as usize,
    );
    let mut title = vec![Span::raw(head)];
    for (m, name) in Method::ALL.iter().zip(names) {
        let rgb = lab_rgb(m);
        title.push(Span::styled(
            format!("{name} "),
            Style::default().fg(colour(rgb)),
        ));
    }
    let block = Block::bordered().title(Line::from(title));
    let Some(rows) = &s.curves else {
        f.render_widget(
            Paragraph::new(if s.curves_busy {
                "computing curves…"
            } else {
                ""
            })
            .block(block),
            area,
        );
        return;
    };
    // The same plot description the PNG renderer draws (keyshape_pictures::plot).
    let spec = keyshape_pictures::plot::curves_plot(rows, s.settings.solver.name(), "", "px");
    let ((_, xmax), (_, ymax)) = spec.bounds().unwrap_or(((2.0, 24.0), (0.0, 1.0)));
    let (xmax, ymax) = (xmax.max(2.0), ymax.max(1e-9));
    let series: Vec<(String, Vec<(f64, f64)>)> = spec
        .series
        .iter()
        .map(|x| (x.name.clone(), x.points.clone()))
        .collect();
    // The marker stands at the k shown: the hull's own count, not the k it ignores.
    let k = match s.computed.as_ref() {
        Some(c) if s.settings.method == Method::Hull && c.settings.method == Method::Hull => {
            c.keys.len() as f64
        }
        _ => s.settings.k as f64,
    };
    let current = [(k, 0.0), (k, ymax)];
    let mut datasets: Vec<Dataset> = series
        .iter()
        .map(|(m, pts)| {
            let rgb = named_rgb(m);
            let kind = if pts.len() == 1 {
                GraphType::Scatter
            } else {
                GraphType::Line
            };
            Dataset::default()
                .name(m.clone())
                .marker(Marker::Braille)
                .graph_type(kind)
                .style(Style::default().fg(colour(rgb)))
                .data(pts)
        })
        .collect();
    datasets.push(
        Dataset::default()
            .marker(Marker::Braille)
            .graph_type(GraphType::Line)
            .style(Style::default().fg(Color::Yellow))
            .data(&current),
    );
    let chart = Chart::new(datasets)
        .block(block)
        .x_axis(
            Axis::default()
                .bounds([2.0, xmax])
                .labels(vec![Line::from("2"), Line::from(format!("{xmax:.0}"))]),
        )
        .y_axis(Axis::default().bounds([0.0, ymax]).labels(vec![
            Line::from("0"),
            Line::from(keyshape_core::stats::sig(ymax, 3)),
        ]))
        .legend_position(None);
    f.render_widget(chart, area);
}

pub(super) fn weight_bars(f: &mut Frame, s: &State, c: &Computed, area: Rect) {
    let Some(v) = c.views.first() else { return };
    let t = s.frame.min(v.weights.ncols().saturating_sub(1));
    let inner_w = area.width.saturating_sub(2) as usize;
    let rows = (area.height.saturating_sub(2) as usize).max(1);
    let wmax = v.weights.iter().fold(1e-9f64, |m, x| m.max(x.abs()));
    let mean_keys = matches!(c.settings.method, Method::KMeans { mean: true, .. });
    // kmeansN-mean keys are cluster means: labelled m0, m1, … (not frames).
    let labels: Vec<String> = c
        .keys
        .iter()
        .enumerate()
        .map(|(i, &k)| {
            if mean_keys {
                format!("m{i}")
            } else {
                c.frames[k].to_string()
            }
        })
        .collect();
    let lines = weight_lines(&v.weights, t, wmax, &labels, rows, inner_w);
    let layout = if labels.len() > rows {
        "weight now"
    } else {
        "weight now | over time"
    };
    let mut title = format!(
        "{}: {layout}",
        if mean_keys {
            "cluster means"
        } else {
            "key frames"
        }
    );
    // The weights' jitter when the title has room (the header shows the target's).
    let jitter = format!(" · jitter {:.1e}", v.jitter);
    if title.chars().count() + jitter.chars().count() <= inner_w {
        title.push_str(&jitter);
    }
    f.render_widget(
        Paragraph::new(lines).block(Block::bordered().title(title)),
        area,
    );
}

/// The weights panel's lines. Every key is shown: one per row with its bar, value and a
/// heat strip over time when they fit; otherwise in columns (label, a shorter bar and the
/// value), as many as the keys need.
pub fn weight_lines(
    w: &DMatrix<f64>,
    t: usize,
    wmax: f64,
    labels: &[String],
    rows: usize,
    width: usize,
) -> Vec<Line<'static>> {
    if labels.len() <= rows {
        weight_rows(w, t, wmax, labels, width)
    } else {
        weight_columns(w, t, wmax, labels, rows, width)
    }
}

const SHADES: [char; 5] = [' ', '░', '▒', '▓', '█'];

/// Red for a negative weight, green otherwise.
fn sign_style(x: f64) -> Style {
    if x < 0.0 {
        Style::default().fg(Color::Red)
    } else {
        Style::default().fg(Color::Green)
    }
}

/// `|x| / wmax` as a bar of `width` characters.
fn bar(x: f64, wmax: f64, width: usize) -> String {
    let filled = ((x.abs() / wmax) * width as f64).round() as usize;
    std::iter::repeat_n('█', filled.min(width))
        .chain(std::iter::repeat_n(' ', width - filled.min(width)))
        .collect()
}

/// `|x| / wmax` as one of five shades.
fn shade(x: f64, wmax: f64) -> char {
    let a = (x.abs() / wmax * 4.0).round() as usize;
    SHADES[a.min(4)]
}

/// One key per row: label, bar, value and the key's weight over time as a heat strip.
fn weight_rows(
    w: &DMatrix<f64>,
    t: usize,
    wmax: f64,
    labels: &[String],
    width: usize,
) -> Vec<Line<'static>> {
    let bar_w = 10usize;
    let strip_w = width.saturating_sub(6 + bar_w + 8);
    let frames = w.ncols().max(1);
    (0..labels.len())
        .map(|i| {
            let x = w[(i, t)];
            let strip: String = (0..strip_w)
                .map(|c| {
                    let tt = c * frames / strip_w.max(1);
                    shade(w[(i, tt.min(frames - 1))], wmax)
                })
                .collect();
            Line::from(vec![
                Span::raw(format!("{:>5} ", labels[i])),
                Span::styled(bar(x, wmax, bar_w), sign_style(x)),
                Span::raw(format!("{x:>7.3} ")),
                Span::styled(strip, Style::default().fg(Color::Blue)),
            ])
        })
        .collect()
}

/// Columns: as few as hold every key. Each cell is `label bar value` when the column is
/// wide enough, `label value` when narrower, and at the least `label shade`.
fn weight_columns(
    w: &DMatrix<f64>,
    t: usize,
    wmax: f64,
    labels: &[String],
    rows: usize,
    width: usize,
) -> Vec<Line<'static>> {
    let n = labels.len();
    let cols = n.div_ceil(rows);
    let per_col = n.div_ceil(cols);
    let col_w = width / cols;
    let label_w = labels.iter().map(|l| l.chars().count()).max().unwrap_or(1);
    let bar_w = col_w.saturating_sub(label_w + 1 + 1 + 4 + 1).min(10);
    // label, a space, the value (4 characters, or 3 in a narrow column: from k ≈ 22 at
    // 80 columns, where the 4-character one left only a shade) and one space after it.
    let value_w = if col_w > label_w + 1 + 4 {
        4
    } else if col_w > label_w + 1 + 3 {
        3
    } else {
        0
    };
    let with_value = value_w > 0;
    (0..per_col)
        .map(|r| {
            let mut spans = Vec::new();
            for c in 0..cols {
                let i = c * per_col + r;
                if i >= n {
                    break;
                }
                let x = w[(i, t)];
                spans.push(Span::raw(format!("{:>label_w$} ", labels[i])));
                let mut used = label_w + 1;
                if bar_w >= 3 {
                    spans.push(Span::styled(
                        format!("{} ", bar(x, wmax, bar_w)),
                        sign_style(x),
                    ));
                    used += bar_w + 1;
                } else if with_value && col_w > label_w + 1 + 1 + value_w {
                    // No room for a bar: a one-character shade keeps the weights visible
                    // at a glance (they vanished at k ≥ 15 on 80 columns).
                    spans.push(Span::styled(shade(x, wmax).to_string(), sign_style(x)));
                    used += 1;
                }
                if with_value {
                    let v = if value_w == 4 {
                        short_value(x)
                    } else {
                        tiny_value(x)
                    };
                    spans.push(Span::styled(format!("{v:>value_w$}"), sign_style(x)));
                    used += value_w;
                } else {
                    spans.push(Span::styled(shade(x, wmax).to_string(), sign_style(x)));
                    used += 1;
                }
                spans.push(Span::raw(" ".repeat(col_w.saturating_sub(used).max(1))));
            }
            Line::from(spans)
        })
        .collect()
}

/// A weight in at most three characters: `.93`, `-.1`, `1.0`, `-2`, `12`, `>99`, `<-9`.
pub fn tiny_value(x: f64) -> String {
    let a = x.abs();
    if x >= 0.0 {
        if a < 0.995 {
            format!("{x:.2}").replacen("0.", ".", 1)
        } else if a < 9.95 {
            format!("{x:.1}")
        } else if a < 99.5 {
            format!("{x:.0}")
        } else {
            ">99".into()
        }
    } else if a < 0.95 {
        format!("{x:.1}").replacen("0.", ".", 1)
    } else if a < 9.5 {
        format!("{x:.0}")
    } else {
        "<-9".into()
    }
}

/// A weight in at most four characters: `.93`, `-.12`, `1.0`, `-2.3`, `12`, `>999`.
pub fn short_value(x: f64) -> String {
    let a = x.abs();
    let s = if a < 0.995 {
        let t = format!("{x:.2}");
        t.replacen("0.", ".", 1)
    } else if a < 9.95 {
        format!("{x:.1}")
    } else if a < 999.5 {
        format!("{x:.0}")
    } else if x > 0.0 {
        ">999".into()
    } else {
        "<-99".into()
    };
    s
}

/// The error chart's region of the screen (inside its border) for a terminal `area`.
pub fn chart_area(area: Rect) -> Rect {
    let [_, _, _, bottom, _] = regions(area);
    let [chart, _] =
        Layout::horizontal([Constraint::Percentage(55), Constraint::Percentage(45)]).areas(bottom);
    chart
}

/// The curve point nearest a click at (`col`, `row`) on the error chart, as (method, k):
/// the plot spans the chart's inside less the y-axis labels (5 columns) and the x axis
/// (2 rows), x from k = 2 to the largest k, y from 0 to the largest RMS.
pub fn chart_pick(area: Rect, s: &State, col: u16, row: u16) -> Option<(Method, usize)> {
    let rows = s.curves.as_ref()?;
    let c = chart_area(area);
    let (x0, x1) = (c.x + 1 + 5, c.x + c.width.saturating_sub(1));
    let (y0, y1) = (c.y + 1, c.y + c.height.saturating_sub(3));
    if col < x0 || col >= x1 || row < y0 || row >= y1 {
        return None;
    }
    let kmax = rows.iter().map(|r| r.k).max()? as f64;
    let ymax = rows.iter().map(|r| r.rms).fold(0.0, f64::max).max(1e-9);
    let fx = f64::from(col - x0) / f64::from((x1 - x0).max(1) - 1).max(1.0);
    let fy = 1.0 - f64::from(row - y0) / f64::from((y1 - y0).max(1) - 1).max(1.0);
    let best = rows.iter().min_by(|a, b| {
        let d = |r: &keyshape_core::keyshapes::curves::CurveRow| {
            ((r.k as f64 - 2.0) / (kmax - 2.0).max(1.0) - fx).powi(2) + (r.rms / ymax - fy).powi(2)
        };
        d(a).total_cmp(&d(b))
    })?;
    Some((Method::parse(&best.method).ok()?, best.k))
}

#[cfg(test)]
mod tiny_tests {
    use super::tiny_value;

    #[test]
    fn a_weight_in_three_characters() {
        for (x, want) in [
            (0.93, ".93"),
            (0.0, ".00"),
            (-0.12, "-.1"),
            (1.0, "1.0"),
            (-1.2, "-1"),
            (12.0, "12"),
            (150.0, ">99"),
            (-15.0, "<-9"),
            (0.996, "1.0"),
            (-0.96, "-1"),
        ] {
            assert_eq!(tiny_value(x), want, "{x}");
            assert!(tiny_value(x).chars().count() <= 3);
        }
    }
}
