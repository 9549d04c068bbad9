//! Drawing the state. Views take `&State` and never change it.

use super::request::Computed;
use super::rig_panels::{rig_error_over_time, rig_panel, rig_weights, rig_weights_over_time};
use super::state::{Prompt, State};
use crate::keyshapes::Method;
use crate::solve::Solver;
use nalgebra::DMatrix;
use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Modifier, Style};
use ratatui::symbols::Marker;
use ratatui::text::{Line, Span};
use ratatui::widgets::canvas::{Canvas, Line as CLine};
use ratatui::widgets::{Axis, Block, Borders, Chart, Clear, Dataset, GraphType, Paragraph, Wrap};
use ratatui::Frame;

/// Smallest terminal the lab draws in.
pub const MIN_SIZE: (u16, u16) = (80, 24);

/// The screen regions, so mouse clicks can be mapped back.
pub fn regions(area: Rect) -> [Rect; 5] {
    // The chart and the weights get a third of a tall screen (9 rows at 24), so at 40 rows
    // twelve keys have a row each with their heat strip.
    let bottom_h = (area.height / 3 + 1).max(9);
    let [head, faces, timeline, bottom, foot] = Layout::vertical([
        Constraint::Length(1),
        Constraint::Min(8),
        Constraint::Length(2),
        Constraint::Length(bottom_h),
        Constraint::Length(1),
    ])
    .areas(area);
    [head, faces, timeline, bottom, foot]
}

/// Draws the whole screen.
pub fn draw(f: &mut Frame, s: &State) {
    let area = f.area();
    if area.width < MIN_SIZE.0 || area.height < MIN_SIZE.1 {
        let msg = format!(
            "terminal too small: {}×{}; the lab needs at least {}×{}. Enlarge it, or q to quit.",
            area.width, area.height, MIN_SIZE.0, MIN_SIZE.1
        );
        f.render_widget(Paragraph::new(msg).wrap(Wrap { trim: true }), area);
        return;
    }
    let [head, faces, timeline, bottom, foot] = regions(area);
    header(f, s, head);
    match &s.computed {
        Some(c) => {
            face_panels(f, s, c, faces);
            time_line(f, s, c, timeline);
            let [chart, weights] =
                Layout::horizontal([Constraint::Percentage(55), Constraint::Percentage(45)])
                    .areas(bottom);
            // The rig view's lower panels describe the rig solve: its largest weights and
            // its landmark error over time (the key-shape chart and bars belong to the
            // key-shape view).
            if let (true, Some(r)) = (s.show_rig, &s.rig) {
                let t = s.frame.min(r.weights.len().saturating_sub(1));
                rig_weights_over_time(f, r, t, chart);
                rig_error_over_time(f, r, t, weights);
            } else {
                error_chart(f, s, chart);
                weight_bars(f, s, c, weights);
            }
        }
        None => {
            let msg = if s.busy {
                "computing…"
            } else {
                "no result yet"
            };
            f.render_widget(Paragraph::new(msg).block(Block::bordered()), faces);
        }
    }
    footer(f, s, foot);
    if s.help {
        help(f, area);
    }
    if let Some(p) = &s.prompt {
        prompt(f, p, area);
    }
}

const SPINNER: [&str; 4] = ["⠋", "⠙", "⠹", "⠸"];

fn header(f: &mut Frame, s: &State, area: Rect) {
    let st = &s.settings;
    // The hull picks its own k: show how many it picked.
    let k = if st.method == Method::Hull {
        match s.computed.as_ref() {
            Some(c) if c.settings.method == Method::Hull => {
                format!("k={} (hull's own)", c.keys.len())
            }
            _ => "k=hull's own".to_string(),
        }
    } else {
        format!("k={}", st.k)
    };
    let frame_no = s
        .computed
        .as_ref()
        .and_then(|c| c.frames.get(s.frame))
        .copied()
        .unwrap_or(s.frame as i64);
    let play = if s.playing { "▶" } else { "⏸" };
    let busy = if s.busy || s.curves_busy {
        format!(" {} computing", SPINNER[(s.ticks / 3 % 4) as usize])
    } else {
        String::new()
    };
    let short = s.source.rsplit('/').next().unwrap_or(&s.source);
    let keys = if s.target_keys {
        "keys from --target".to_string()
    } else {
        format!("{} {k}", st.method)
    };
    let solver = if st.smooth > 0.0 {
        format!("{} λ={}", st.solver, lambda_label(st.smooth))
    } else {
        st.solver.to_string()
    };
    // The whole sequence's target error and the jitter of the retargeted points.
    let mut quality = s
        .computed
        .as_ref()
        .and_then(|c| c.views.first())
        .map(|v| format!("err {:.2} jit {:.2}", v.target_rms, v.target_jitter));
    // The rig view shows the rig solve: its shapes, solver and landmark error, not the
    // key-shape settings (which still drive the panels below and `e`).
    let (keys, solver) = match (s.show_rig, &s.rig) {
        (true, Some(r)) => {
            let n = r.rms.len().max(1) as f64;
            quality = Some(format!("landmark RMS {:.2}", r.rms.iter().sum::<f64>() / n));
            (
                format!("rig: {} shapes", r.names.len()),
                // The temporal prior: the offline λ (`l`), or the zero-phase σ of the default.
                if r.smooth > 0.0 {
                    format!("bounded λ{}", r.smooth)
                } else {
                    "bounded σ1".to_string()
                },
            )
        }
        _ => (keys, solver),
    };
    // Parts in display order with a priority: the lowest go first when 80 columns are not
    // enough (never the frame, method, k, solver or error).
    let mut parts: Vec<(String, u8)> = vec![
        // The file name goes only after everything but the settings and the error.
        (short.to_string(), 8),
        (format!("{} frames", s.frames), 0),
        (st.points.clone(), 3),
        (keys, 9),
        (solver, 9),
        (format!("frame {frame_no} {play}"), 9),
        (format!("{}×", s.speed), 1),
    ];
    if let Some(q) = quality {
        parts.push((q, 9));
    }
    let room = (area.width as usize).saturating_sub(8 + busy.chars().count());
    let width = |p: &[(String, u8)]| {
        p.iter().map(|(t, _)| t.chars().count()).sum::<usize>() + 3 * p.len().saturating_sub(1)
    };
    // Dropped first: the frame count, then the speed; then a long name is shortened to its
    // end; then the point group, then the name.
    let mut shortened = false;
    while width(&parts) > room {
        let lowest = parts
            .iter()
            .enumerate()
            .filter(|(_, (_, pr))| *pr < 9)
            .min_by_key(|(_, (_, pr))| *pr)
            .map(|(i, (_, pr))| (i, *pr));
        match lowest {
            Some((i, pr)) if pr < 2 || shortened || short.chars().count() <= 16 => {
                parts.remove(i);
            }
            Some(_) => {
                let tail: String = short.chars().rev().take(15).collect();
                parts[0].0 = format!("…{}", tail.chars().rev().collect::<String>());
                shortened = true;
            }
            None => break,
        }
    }
    let body: Vec<&str> = parts.iter().map(|(t, _)| t.as_str()).collect();
    let line = Line::from(vec![
        Span::styled(
            " kslab ",
            Style::default().add_modifier(Modifier::BOLD | Modifier::REVERSED),
        ),
        Span::raw(format!(" {}{busy}", body.join(" · "))),
    ]);
    f.render_widget(Paragraph::new(line), area);
}

/// λ for the header: `100`, then powers of ten as `1e5`.
pub fn lambda_label(l: f64) -> String {
    if l >= 1000.0 {
        format!("{l:e}")
    } else {
        format!("{l}")
    }
}

fn bounds(ms: &[&DMatrix<f64>], dims: usize) -> ([f64; 2], [f64; 2]) {
    let ((x0, y0), (x1, y1)) = crate::render::face::bounds_of(ms, dims);
    let (cx, cy, half) = (
        (x0 + x1) / 2.0,
        (y0 + y1) / 2.0,
        (x1 - x0).max(y1 - y0) / 2.0,
    );
    ([cx - half, cx + half], [-(cy + half), -(cy - half)])
}

fn shape_panel<'a>(
    title: String,
    layers: Vec<(&'a DMatrix<f64>, Color)>,
    c: &'a Computed,
    t: usize,
    b: ([f64; 2], [f64; 2]),
) -> Canvas<'a, impl Fn(&mut ratatui::widgets::canvas::Context) + 'a> {
    let (dims, lines) = (c.dims, &c.polylines);
    Canvas::default()
        .block(Block::bordered().title(title))
        .marker(Marker::Braille)
        .x_bounds(b.0)
        .y_bounds(b.1)
        .paint(move |ctx| {
            for (m, colour) in &layers {
                let col = m.column(t);
                let p = |i: usize| (col[i * dims], -col[i * dims + 1]);
                for line in lines {
                    for w in line.windows(2) {
                        let (a, b) = (p(w[0]), p(w[1]));
                        ctx.draw(&CLine {
                            x1: a.0,
                            y1: a.1,
                            x2: b.0,
                            y2: b.1,
                            color: *colour,
                        });
                    }
                }
                ctx.layer();
            }
        })
}

fn face_panels(f: &mut Frame, s: &State, c: &Computed, area: Rect) {
    let t = s.frame.min(c.frames.len().saturating_sub(1));
    let sb = bounds(&[&c.tracked], c.dims);
    let mut targets = vec![&c.truth];
    targets.extend(c.views.iter().map(|v| &v.target));
    let tb = bounds(&targets, c.dims);
    let Some(main) = c.views.first() else { return };
    let rms = main.frame_rms.get(t).copied().unwrap_or(0.0);
    let trms = main
        .frame_target_rms
        .get(t)
        .map_or("n/a".to_string(), |v| format!("{v:.2}"));
    if s.split {
        let (Some(ls), Some(nn)) = (c.view(Solver::Ls), c.view(Solver::Nnls)) else {
            f.render_widget(
                Paragraph::new("computing LS and NNLS for the split view…")
                    .block(Block::bordered()),
                area,
            );
            return;
        };
        let [a, b, d] = Layout::horizontal([Constraint::Ratio(1, 3); 3]).areas(area);
        // The title as long as the panel allows: at 80 columns "source ·" goes, not a
        // number ("NNLS 0.3" was all that was left).
        let full = format!(
            "source · LS {:.2} NNLS {:.2}",
            ls.frame_rms[t], nn.frame_rms[t]
        );
        let title = if full.chars().count() + 2 <= a.width as usize {
            full
        } else {
            format!("LS {:.2} NNLS {:.2}", ls.frame_rms[t], nn.frame_rms[t])
        };
        let src = shape_panel(
            title,
            vec![
                (&c.tracked, Color::White),
                (&ls.recon, Color::Red),
                (&nn.recon, Color::Green),
            ],
            c,
            t,
            sb,
        );
        f.render_widget(src, a);
        let tl = shape_panel(
            format!(
                "target LS · rms {}",
                ls.frame_target_rms
                    .get(t)
                    .map_or("n/a".into(), |v| format!("{v:.2}"))
            ),
            vec![(&c.truth, Color::DarkGray), (&ls.target, Color::Red)],
            c,
            t,
            tb,
        );
        f.render_widget(tl, b);
        let tn = shape_panel(
            format!(
                "target NNLS · rms {}",
                nn.frame_target_rms
                    .get(t)
                    .map_or("n/a".into(), |v| format!("{v:.2}"))
            ),
            vec![(&c.truth, Color::DarkGray), (&nn.target, Color::Green)],
            c,
            t,
            tb,
        );
        f.render_widget(tn, d);
        return;
    }
    let [a, b] = Layout::horizontal([Constraint::Ratio(1, 2); 2]).areas(area);
    if let (true, Some(r)) = (s.show_rig, &s.rig) {
        let t = t.min(r.weights.len().saturating_sub(1));
        f.render_widget(rig_panel(r, t), a);
        f.render_widget(rig_weights(r, t, b.height.saturating_sub(2) as usize), b);
        return;
    }
    if let (true, Some(m)) = (s.show_mesh, &s.mesh) {
        let src = shape_panel(
            format!("source: tracked + recon · rms {rms:.2}"),
            vec![(&c.tracked, Color::White), (&main.recon, Color::Cyan)],
            c,
            t,
            sb,
        );
        f.render_widget(src, a);
        f.render_widget(mesh_panel(m, t), b);
        return;
    }
    let src = shape_panel(
        format!("source: tracked + recon · rms {rms:.2}"),
        vec![(&c.tracked, Color::White), (&main.recon, Color::Cyan)],
        c,
        t,
        sb,
    );
    f.render_widget(src, a);
    let tgt = shape_panel(
        format!("target: G(q) + retargeted · rms {trms}"),
        vec![(&c.truth, Color::DarkGray), (&main.target, Color::Red)],
        c,
        t,
        tb,
    );
    f.render_widget(tgt, b);
}

/// The tracked landmarks (white) and the posed rig's under the fitted head pose (magenta).
fn mesh_panel(
    m: &super::mesh::MeshView,
    t: usize,
) -> Canvas<'_, impl Fn(&mut ratatui::widgets::canvas::Context) + '_> {
    let t = t.min(m.frames.len().saturating_sub(1));
    Canvas::default()
        .block(
            Block::bordered().title("target mesh: RBF transfer + skinning (paper 004) · x toggles"),
        )
        .marker(Marker::Braille)
        .x_bounds(m.bounds.0)
        .y_bounds(m.bounds.1)
        .paint(move |ctx| {
            let Some(p) = m.frames.get(t) else { return };
            for &(a, b) in &m.edges {
                let (pa, pb) = (p[a as usize], p[b as usize]);
                ctx.draw(&CLine {
                    x1: f64::from(pa[0]),
                    y1: f64::from(pa[1]),
                    x2: f64::from(pb[0]),
                    y2: f64::from(pb[1]),
                    color: Color::Gray,
                });
            }
            ctx.layer();
            for &v in &m.marks {
                let q = p[v];
                ctx.print(
                    f64::from(q[0]),
                    f64::from(q[1]),
                    Span::styled("•", Style::default().fg(Color::Red)),
                );
            }
        })
}

fn time_line(f: &mut Frame, s: &State, c: &Computed, area: Rect) {
    let w = area.width.saturating_sub(2) as usize;
    let n = c.frames.len().max(1);
    let col = |i: usize| (i * w.saturating_sub(1)) / (n - 1).max(1);
    let mut marks = vec!['─'; w];
    // Key frames belong to the key-shape solve; the rig view has none.
    let keys: &[usize] = if s.show_rig && s.rig.is_some() {
        &[]
    } else {
        &c.keys
    };
    for &k in keys {
        if let Some(m) = marks.get_mut(col(k)) {
            *m = '◆';
        }
    }
    let mut cursor = vec![' '; w];
    if let Some(m) = cursor.get_mut(col(s.frame)) {
        *m = '▲';
    }
    let lines = vec![
        Line::from(Span::styled(
            format!(" {}", marks.iter().collect::<String>()),
            Style::default().fg(Color::Yellow),
        )),
        Line::from(format!(" {}", cursor.iter().collect::<String>().trim_end())),
    ];
    f.render_widget(Paragraph::new(lines), area);
}

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

fn colour(rgb: [u8; 3]) -> Color {
    Color::Rgb(rgb[0], rgb[1], rgb[2])
}

/// Each method's colour in the lab. A terminal may be dark or light, so every colour is of
/// middle luminance — a WCAG contrast of at least 2.5 against black and against white — and
/// each differs from every other (the PNG plots, on white, tell the k-means variants apart
/// by dashes as well; a terminal chart has only colour).
pub fn lab_rgb(method: &str) -> [u8; 3] {
    match method {
        "spread" => [70, 130, 255],
        "kmeans2" => [40, 170, 60],
        "kmeans3" => [210, 60, 210],
        "kmeans2-mean" => [0, 160, 160],
        "kmeans3-mean" => [150, 100, 255],
        "hull" => [235, 50, 50],
        "greedy" => [230, 140, 0],
        "random" => [140, 140, 140],
        _ => [200, 120, 60],
    }
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

fn error_chart(f: &mut Frame, s: &State, area: Rect) {
    let (head, names) = legend_labels(
        s.settings.solver.name(),
        area.width.saturating_sub(2) as usize,
    );
    let mut title = vec![Span::raw(head)];
    for (m, name) in Method::ALL.iter().zip(names) {
        let rgb = lab_rgb(&m.name());
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
    // The same plot description the PNG renderer draws (crate::plot).
    let spec = crate::plot::curves_plot(rows, s.settings.solver.name(), "", "px");
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
            let rgb = lab_rgb(m);
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
        .y_axis(
            Axis::default()
                .bounds([0.0, ymax])
                .labels(vec![Line::from("0"), Line::from(format!("{ymax:.1}"))]),
        )
        .legend_position(None);
    f.render_widget(chart, area);
}

fn weight_bars(f: &mut Frame, s: &State, c: &Computed, area: Rect) {
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
    let shades = [' ', '░', '▒', '▓', '█'];
    let colour = |x: f64| {
        if x < 0.0 {
            Style::default().fg(Color::Red)
        } else {
            Style::default().fg(Color::Green)
        }
    };
    let bar = |x: f64, width: usize| -> String {
        let filled = ((x.abs() / wmax) * width as f64).round() as usize;
        std::iter::repeat_n('█', filled.min(width))
            .chain(std::iter::repeat_n(' ', width - filled.min(width)))
            .collect()
    };
    let n = labels.len();
    if n <= rows {
        let bar_w = 10usize;
        let strip_w = width.saturating_sub(6 + bar_w + 8);
        let frames = w.ncols().max(1);
        return (0..n)
            .map(|i| {
                let x = w[(i, t)];
                let strip: String = (0..strip_w)
                    .map(|c| {
                        let tt = c * frames / strip_w.max(1);
                        let a = (w[(i, tt.min(frames - 1))].abs() / wmax * 4.0).round() as usize;
                        shades[a.min(4)]
                    })
                    .collect();
                Line::from(vec![
                    Span::raw(format!("{:>5} ", labels[i])),
                    Span::styled(bar(x, bar_w), colour(x)),
                    Span::raw(format!("{x:>7.3} ")),
                    Span::styled(strip, Style::default().fg(Color::Blue)),
                ])
            })
            .collect();
    }
    // Columns: as few as hold every key. Each cell is `label bar value` when the column is
    // wide enough, `label value` when narrower, and at the least `label shade`.
    let cols = n.div_ceil(rows);
    let per_col = n.div_ceil(cols);
    let col_w = width / cols;
    let label_w = labels.iter().map(|l| l.chars().count()).max().unwrap_or(1);
    let bar_w = col_w.saturating_sub(label_w + 1 + 1 + 4 + 1).min(10);
    // label, a space, the 4-character value and at least one space after it.
    let with_value = col_w > label_w + 1 + 4;
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
                    spans.push(Span::styled(format!("{} ", bar(x, bar_w)), colour(x)));
                    used += bar_w + 1;
                } else if with_value && col_w > label_w + 1 + 1 + 4 {
                    // No room for a bar: a one-character shade keeps the weights visible
                    // at a glance (they vanished at k ≥ 15 on 80 columns).
                    let a = (x.abs() / wmax * 4.0).round() as usize;
                    spans.push(Span::styled(shades[a.min(4)].to_string(), colour(x)));
                    used += 1;
                }
                if with_value {
                    spans.push(Span::styled(format!("{:>4}", short_value(x)), colour(x)));
                    used += 4;
                } else {
                    let a = (x.abs() / wmax * 4.0).round() as usize;
                    spans.push(Span::styled(shades[a.min(4)].to_string(), colour(x)));
                    used += 1;
                }
                spans.push(Span::raw(" ".repeat(col_w.saturating_sub(used).max(1))));
            }
            Line::from(spans)
        })
        .collect()
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

fn footer(f: &mut Frame, s: &State, area: Rect) {
    let text = if s.status.is_empty() {
        "space play ←→ step m method +- k g group s solver l λ v split e export ? q quit"
            .to_string()
    } else {
        format!(" {}", s.status)
    };
    let style = if s.status.starts_with("error") {
        Style::default().fg(Color::Red)
    } else {
        Style::default().add_modifier(Modifier::DIM)
    };
    f.render_widget(Paragraph::new(Span::styled(text, style)), area);
}

/// Every key, for the help overlay and the README.
pub const KEYS: [(&str, &str); 21] = [
    ("space", "play / pause"),
    ("← / →", "step one frame"),
    ("Home / End", "first / last frame"),
    ("0-9 … Enter", "jump to a frame number"),
    ("[ / ]", "slower / faster playback"),
    (
        "m / M",
        "next / prev method; km2 = kmeans2, km2m = kmeans2-mean",
    ),
    ("+ / -", "more / fewer key shapes"),
    ("g", "next point group (lips, all, eyes, brows, eyes+brows)"),
    ("s", "next solver (nnls, ls, bounded)"),
    (
        "l / L",
        "temporal prior λ ×10 / ÷10 (off … 1e6; the rig's ≤ 1e4)",
    ),
    ("v", "LS and NNLS side by side"),
    ("e", "export weights CSV, view PNG, experiment TOML"),
    ("o", "open another sequence"),
    ("x", "3-D mesh of `--mesh` in place of the 2-D target"),
    (
        "r",
        "the track solved onto `--rig` (posed rig, named weights)",
    ),
    ("click", "timeline: seek; chart: nearest method and k"),
    ("?", "this help"),
    ("q / Ctrl-C", "quit (Esc: close help or prompt, else quit)"),
    ("err", "header: target RMS vs G(q) over all frames (px)"),
    (
        "jit",
        "header: jitter, RMS 2nd difference of the target (px/f²)",
    ),
    ("rms", "panel titles: this frame's RMS error (px)"),
];

fn centred(area: Rect, w: u16, h: u16) -> Rect {
    let (w, h) = (w.min(area.width), h.min(area.height));
    Rect {
        x: area.x + (area.width - w) / 2,
        y: area.y + (area.height - h) / 2,
        width: w,
        height: h,
    }
}

fn help(f: &mut Frame, area: Rect) {
    let r = centred(area, 74, KEYS.len() as u16 + 2);
    let lines: Vec<Line> = KEYS
        .iter()
        .map(|(k, d)| {
            Line::from(vec![
                Span::styled(
                    format!(" {k:<15}"),
                    Style::default().add_modifier(Modifier::BOLD),
                ),
                Span::raw(*d),
            ])
        })
        .collect();
    f.render_widget(Clear, r);
    f.render_widget(
        Paragraph::new(lines).block(Block::default().borders(Borders::ALL).title("keys")),
        r,
    );
}

fn prompt(f: &mut Frame, p: &Prompt, area: Rect) {
    let (title, text) = match p {
        Prompt::Jump(t) => ("jump to frame (Enter)", t),
        Prompt::Open(t) => ("open sequence: path or 'builtin' (Enter)", t),
    };
    let r = centred(area, 60, 3);
    f.render_widget(Clear, r);
    f.render_widget(
        Paragraph::new(prompt_line(text, r.width.saturating_sub(2) as usize))
            .block(Block::bordered().title(title)),
        r,
    );
}

/// The prompt's text with the cursor, scrolled so the end (where typing happens) is in
/// view: a path longer than the box shows `…` and its last characters.
pub fn prompt_line(text: &str, width: usize) -> String {
    let n = text.chars().count();
    if n < width {
        return format!("{text}▏");
    }
    let keep = width.saturating_sub(2);
    let tail: String = text.chars().skip(n - keep).collect();
    format!("…{tail}▏")
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
        let d = |r: &crate::keyshapes::curves::CurveRow| {
            ((r.k as f64 - 2.0) / (kmax - 2.0).max(1.0) - fx).powi(2) + (r.rms / ymax - fy).powi(2)
        };
        d(a).total_cmp(&d(b))
    })?;
    Some((Method::parse(&best.method).ok()?, best.k))
}

#[cfg(test)]
mod tests {
    use super::lab_rgb;
    use crate::keyshapes::Method;

    /// WCAG 2 relative luminance.
    fn luminance(c: [u8; 3]) -> f64 {
        let lin = |v: u8| {
            let v = f64::from(v) / 255.0;
            if v <= 0.03928 {
                v / 12.92
            } else {
                ((v + 0.055) / 1.055).powf(2.4)
            }
        };
        0.2126 * lin(c[0]) + 0.7152 * lin(c[1]) + 0.0722 * lin(c[2])
    }

    /// Issue 41 item 8: greedy (20, 20, 20), kmeans2-mean (10, 90, 30) and kmeans3-mean
    /// (110, 20, 120) vanished on a dark terminal, and kmeans2 and kmeans2-mean shared a
    /// green. Every method now reads on black and on white and differs from every other.
    #[test]
    fn every_method_reads_on_dark_and_light_terminals_and_differs_from_the_others() {
        let all: Vec<[u8; 3]> = Method::ALL.iter().map(|m| lab_rgb(&m.name())).collect();
        for (m, &c) in Method::ALL.iter().zip(&all) {
            let l = luminance(c);
            let on_black = (l + 0.05) / 0.05;
            let on_white = 1.05 / (l + 0.05);
            assert!(
                on_black >= 2.5 && on_white >= 2.5,
                "{m}: {on_black:.2} on black, {on_white:.2} on white"
            );
        }
        for i in 0..all.len() {
            for j in 0..i {
                let d: f64 = (0..3)
                    .map(|k| (f64::from(all[i][k]) - f64::from(all[j][k])).powi(2))
                    .sum::<f64>()
                    .sqrt();
                assert!(
                    d >= 80.0,
                    "{} and {} differ by {d:.0}",
                    Method::ALL[i],
                    Method::ALL[j]
                );
            }
        }
    }
}
