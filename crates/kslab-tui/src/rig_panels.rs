//! The rig view's panels (`r` in the lab): the track with the posed rig, the frame's weights
//! as named bars, and over time the largest weights and the landmark error.

use super::rig::RigView;
use super::view::lab_rgb;
use keyshape_core::keyshapes::Method;
use ratatui::layout::Rect;
use ratatui::style::{Color, Style};
use ratatui::symbols::Marker;
use ratatui::text::{Line, Span};
use ratatui::widgets::canvas::{Canvas, Line as CLine};
use ratatui::widgets::{Axis, Block, Chart, Dataset, GraphType, Paragraph};
use ratatui::Frame;

/// How many of the frame's largest weights the time chart follows.
pub const FOLLOWED: usize = 3;

/// The `n` shapes with the largest |weight| on frame `t`, largest first (ties by index).
pub fn largest(r: &RigView, t: usize, n: usize) -> Vec<usize> {
    let w = &r.weights[t];
    let mut order: Vec<usize> = (0..w.len()).collect();
    order.sort_by(|&a, &b| w[b].abs().total_cmp(&w[a].abs()).then(a.cmp(&b)));
    order.truncate(n);
    order
}

/// A shape's colour in the rig charts: the lab's palette by rank, so the three followed
/// shapes read apart on dark and light terminals.
fn rank_rgb(rank: usize) -> [u8; 3] {
    const RANKED: [Method; FOLLOWED] = [
        Method::Spread,
        Method::Greedy,
        Method::KMeans {
            pcs: 3,
            mean: false,
        },
    ];
    lab_rgb(&RANKED[rank % FOLLOWED])
}

fn rgb(c: [u8; 3]) -> Color {
    Color::Rgb(c[0], c[1], c[2])
}

/// A shape's name in at most `room` characters, still telling shapes apart: the side
/// (`_L`, `_R`, `Left`, `Right`) kept, then the vowels inside each camel-case word dropped
/// (`browDown_L` → `brwDwn_L`), then the stem cut (round three's legend read
/// "browDown_ browOuter").
pub fn abbreviate(name: &str, room: usize) -> String {
    if name.chars().count() <= room {
        return name.to_string();
    }
    let (stem, side) = ["_L", "_R", "Left", "Right"]
        .iter()
        .find_map(|s| name.strip_suffix(s).map(|st| (st, *s)))
        .unwrap_or((name, ""));
    let side = match side {
        "Left" => "L",
        "Right" => "R",
        s => s,
    };
    // Vowels dropped, except a word's first letter.
    let mut short = String::new();
    let mut prev: Option<char> = None;
    for c in stem.chars() {
        let word_start = prev.is_none_or(|p| c.is_uppercase() || !p.is_alphabetic());
        if word_start || !"aeiou".contains(c) {
            short.push(c);
        }
        prev = Some(c);
    }
    let keep = room.saturating_sub(side.chars().count()).max(1);
    let stem: String = short.chars().take(keep).collect();
    format!("{stem}{side}")
}

/// The frame's [`FOLLOWED`] largest weights over the whole sequence, named in the title in
/// their colours, with the current frame marked, drawn in `area`.
pub fn rig_weights_over_time(f: &mut Frame, r: &RigView, t: usize, area: Rect) {
    let n = r.weights.len();
    let shown = largest(r, t, FOLLOWED);
    // "over time: " and a space per name: the rest of the border is shared out.
    let room = (area.width.saturating_sub(13) as usize / FOLLOWED)
        .saturating_sub(1)
        .max(4);
    let mut title = vec![Span::raw("over time: ")];
    for (rank, &i) in shown.iter().enumerate() {
        let name = abbreviate(&r.names[i], room);
        title.push(Span::styled(
            format!("{name} "),
            Style::default().fg(rgb(rank_rgb(rank))),
        ));
    }
    let series: Vec<Vec<(f64, f64)>> = shown
        .iter()
        .map(|&i| (0..n).map(|u| (u as f64, r.weights[u][i])).collect())
        .collect();
    let mut datasets: Vec<Dataset> = series
        .iter()
        .enumerate()
        .map(|(rank, pts)| {
            Dataset::default()
                .marker(Marker::Braille)
                .graph_type(GraphType::Line)
                .style(Style::default().fg(rgb(rank_rgb(rank))))
                .data(pts)
        })
        .collect();
    let lo = series.iter().flatten().map(|p| p.1).fold(0.0f64, f64::min);
    let mark = cursor(t, lo, 1.0);
    datasets.push(cursor_set(&mark));
    let chart = Chart::new(datasets)
        .block(Block::bordered().title(Line::from(title)))
        .x_axis(frame_axis(n))
        .y_axis(
            Axis::default()
                .bounds([lo, 1.0])
                .labels(vec![Line::from(format!("{lo:.0}")), Line::from("1")]),
        )
        .legend_position(None);
    f.render_widget(chart, area);
}

/// The rig's landmark RMS per frame over the sequence, the current frame marked, drawn in
/// `area`.
pub fn rig_error_over_time(f: &mut Frame, r: &RigView, t: usize, area: Rect) {
    let n = r.rms.len();
    let top = r
        .rms
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(1e-9, f64::max);
    let pts: Vec<(f64, f64)> = r
        .rms
        .iter()
        .enumerate()
        .map(|(u, &v)| (u as f64, v))
        .collect();
    let now = r.rms.get(t).copied().unwrap_or(f64::NAN);
    let mark = cursor(t, 0.0, top);
    let chart = Chart::new(vec![
        Dataset::default()
            .marker(Marker::Braille)
            .graph_type(GraphType::Line)
            .style(Style::default().fg(Color::Magenta))
            .data(&pts),
        cursor_set(&mark),
    ])
    .block(Block::bordered().title(format!("landmark RMS over time · now {now:.2}")))
    .x_axis(frame_axis(n))
    .y_axis(
        Axis::default()
            .bounds([0.0, top])
            .labels(vec![Line::from("0"), Line::from(format!("{top:.1}"))]),
    )
    .legend_position(None);
    f.render_widget(chart, area);
}

/// A vertical line at frame `t` from `lo` to `hi`.
fn cursor(t: usize, lo: f64, hi: f64) -> [(f64, f64); 2] {
    [(t as f64, lo), (t as f64, hi)]
}

fn cursor_set(mark: &[(f64, f64); 2]) -> Dataset<'_> {
    Dataset::default()
        .marker(Marker::Braille)
        .graph_type(GraphType::Line)
        .style(Style::default().fg(Color::Yellow))
        .data(mark)
}

fn frame_axis(n: usize) -> Axis<'static> {
    let last = n.saturating_sub(1).max(1) as f64;
    Axis::default()
        .bounds([0.0, last])
        .labels(vec![Line::from("0"), Line::from(format!("{last:.0}"))])
}

/// The track (white) and the posed rig's landmarks (magenta) on frame `t` (an index
/// [`RigView::at`] gives).
pub fn rig_panel(
    r: &RigView,
    t: usize,
) -> Canvas<'_, impl Fn(&mut ratatui::widgets::canvas::Context) + '_> {
    let what = match r.preview {
        Some(0) => "first frame alone".to_string(),
        Some(f) => format!("frame column {f} alone"),
        None => "track + posed rig".to_string(),
    };
    Canvas::default()
        .block(Block::bordered().title(format!(
            "{what} · rms {}",
            keyshape_core::stats::sig(r.rms.get(t).copied().unwrap_or(f64::NAN), 3)
        )))
        .marker(Marker::Braille)
        .x_bounds(r.bounds.0)
        .y_bounds(r.bounds.1)
        .paint(move |ctx| {
            for (pts, color) in [
                (&r.tracked[t], Color::White),
                (&r.fitted[t], Color::Magenta),
            ] {
                for line in &r.polylines {
                    for w in line.windows(2) {
                        let (p, q) = (pts[w[0]], pts[w[1]]);
                        ctx.draw(&CLine {
                            x1: p[0],
                            y1: p[1],
                            x2: q[0],
                            y2: q[1],
                            color,
                        });
                    }
                }
                ctx.layer();
            }
        })
}

/// The rig's weights on frame `t` as named bars, largest first, as many as fit.
pub fn rig_weights(r: &RigView, t: usize, rows: usize) -> Paragraph<'_> {
    let w = &r.weights[t];
    let lines: Vec<Line> = largest(r, t, rows.max(1))
        .iter()
        .map(|&i| {
            let v = w[i];
            let bar = "█".repeat((v.abs().min(1.0) * 12.0).round() as usize);
            Line::from(vec![
                Span::raw(format!("{:<16.16} ", r.names[i])),
                Span::styled(
                    format!("{bar:<12}"),
                    Style::default().fg(if v < 0.0 { Color::Red } else { Color::Magenta }),
                ),
                Span::raw(format!(" {v:.2}")),
            ])
        })
        .collect();
    let active = w.iter().filter(|v| v.abs() > 1e-9).count();
    Paragraph::new(lines)
        .block(Block::bordered().title(format!("rig weights · {active} of {} active", w.len())))
}

/// What the rig view's lower panels say while they wait for the take: the frame shown was
/// solved alone (`step`: the step the take's solve is on).
pub fn rig_preview_note(step: Option<&str>) -> Paragraph<'static> {
    let now = step.map_or(String::new(), |s| format!(" (now: {s})"));
    Paragraph::new(format!(
        "The take is solving{now}. Above: its first frame solved alone, before the take: \
         the neutral searched on the 68-point map, no smoothing over time. The take's solve \
         replaces it, with the weights and the landmark error over time here."
    ))
    .wrap(ratatui::widgets::Wrap { trim: true })
    .block(Block::bordered().title("rig: preview"))
}

#[cfg(test)]
mod abbreviate_tests {
    use super::abbreviate;

    #[test]
    fn names_stay_apart_and_keep_their_side() {
        assert_eq!(abbreviate("browDown_L", 9), "brwDwn_L");
        assert_eq!(abbreviate("browOuterUp_R", 9), "brwOtrU_R");
        assert_eq!(abbreviate("eyeBlinkLeft", 9), "eyBlnkL");
        assert_eq!(abbreviate("jawOpen", 9), "jawOpen");
        assert_ne!(abbreviate("browDown_L", 8), abbreviate("browDown_R", 8));
        assert_ne!(abbreviate("browDown_L", 8), abbreviate("browOuterUp_L", 8));
        for n in ["mouthSmile_L", "cheekSquint_R", "mouthRollLower"] {
            assert!(abbreviate(n, 8).chars().count() <= 8, "{n}");
        }
    }
}
