//! Drawing the state. Views take `&State` and never change it.

use super::rig_panels::{rig_error_over_time, rig_preview_note, rig_weights_over_time};
use super::state::{Prompt, State};
use keyshape_core::keyshapes::Method;
use keyshape_core::stats::sig;
use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Modifier, Style};
use ratatui::text::{Line, Span};
use ratatui::widgets::{Block, Borders, Clear, Paragraph, Wrap};
use ratatui::Frame;

pub(crate) use super::charts::{chart_pick, lab_rgb};
use super::charts::{error_chart, weight_bars};
use super::face_panels::{face_panels, time_line};

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
                if r.preview.is_some() {
                    f.render_widget(rig_preview_note(s.rig_step.as_deref()), bottom);
                } else {
                    let t = r.at(s.frame);
                    rig_weights_over_time(f, r, t, chart);
                    rig_error_over_time(f, r, t, weights);
                }
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
    let busy = match (&s.rig_step, s.busy || s.curves_busy) {
        (Some(step), _) => format!(" {} rig: {step}", SPINNER[(s.ticks / 3 % 4) as usize]),
        (None, true) => format!(" {} computing", SPINNER[(s.ticks / 3 % 4) as usize]),
        (None, false) => String::new(),
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
    let mut quality = s.computed.as_ref().and_then(|c| c.views.first()).map(|v| {
        format!(
            "err {} jit {}",
            sig(v.target_rms, 3),
            sig(v.target_jitter, 3)
        )
    });
    // The rig view shows the rig solve: its shapes, solver and landmark error, not the
    // key-shape settings (which still drive the panels below and `e`).
    let (keys, solver) = match (s.show_rig, &s.rig) {
        (true, Some(r)) => {
            let n = r.rms.len().max(1) as f64;
            quality = Some(format!(
                "landmark RMS {}",
                sig(r.rms.iter().sum::<f64>() / n, 3)
            ));
            (
                format!("rig: {} shapes{}", r.names.len(), preview_tag(r)),
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
        // The unit beside the numbers while the track is normalised (0–1 of the image).
        let q = if s.normalised {
            format!("{q} (0–1 units)")
        } else {
            q
        };
        parts.push((q, 9));
    }
    let (badge, body) = fit_header(parts, short, area.width as usize, busy.chars().count());
    let mut spans = Vec::new();
    if badge {
        spans.push(Span::styled(
            " kslab ",
            Style::default().add_modifier(Modifier::BOLD | Modifier::REVERSED),
        ));
    }
    spans.push(Span::raw(format!(" {}{busy}", body.join(" · "))));
    let line = Line::from(spans);
    f.render_widget(Paragraph::new(line), area);
}

/// `, preview` for a rig view of one frame solved before the take.
fn preview_tag(r: &super::rig::RigView) -> &'static str {
    match r.preview {
        Some(_) => ", preview",
        None => "",
    }
}

/// The header's parts fitted to `width` columns (`busy`: the spinner's), and whether the
/// ` kslab ` badge still fits. What gives way, in order: the frame count, the speed; the
/// file name shortened to its last 15 characters; the badge; the name cut to its last 8,
/// then 4; `frame 150` as `f150`; only then the point group and the name. The settings, the frame and the error always
/// stay (at 80 columns with `kmeans3-mean` and a λ the group and a name still show).
pub fn fit_header(
    mut parts: Vec<(String, u8)>,
    short: &str,
    width: usize,
    busy: usize,
) -> (bool, Vec<String>) {
    let used = |p: &[(String, u8)], badge: bool| {
        p.iter().map(|(t, _)| t.chars().count()).sum::<usize>()
            + 3 * p.len().saturating_sub(1)
            + 1
            + busy
            + if badge { 7 } else { 0 }
    };
    let tail = |n: usize| -> String {
        if short.chars().count() <= n + 1 {
            return short.to_string();
        }
        let t: String = short.chars().rev().take(n).collect();
        format!("…{}", t.chars().rev().collect::<String>())
    };
    let mut badge = true;
    let mut stage = 0;
    while used(&parts, badge) > width {
        let name = parts.iter().position(|(_, pr)| *pr == 8);
        match stage {
            // The frame count and the speed.
            0 | 1 => {
                let pr = stage as u8;
                if let Some(i) = parts.iter().position(|(_, p)| *p == pr) {
                    parts.remove(i);
                }
            }
            2 => {
                if let Some(i) = name {
                    parts[i].0 = tail(15);
                }
            }
            3 => badge = false,
            4 => {
                if let Some(i) = name {
                    parts[i].0 = tail(8);
                }
            }
            5 => {
                if let Some(i) = name {
                    parts[i].0 = tail(4);
                }
            }
            // "frame 150 ⏸" as "f150 ⏸".
            6 => {
                for (t, _) in parts.iter_mut() {
                    if let Some(rest) = t.strip_prefix("frame ") {
                        *t = format!("f{rest}");
                    }
                }
            }
            // The point group, then the name.
            7 | 8 => {
                let pr = if stage == 7 { 3 } else { 8 };
                if let Some(i) = parts.iter().position(|(_, p)| *p == pr) {
                    parts.remove(i);
                }
            }
            _ => break,
        }
        stage += 1;
    }
    (badge, parts.into_iter().map(|(t, _)| t).collect())
}

/// A status message in `width` columns: whole when it fits, else its start and its end
/// with the middle (usually a long path) elided, so the reason at the end stays ("No such
/// fil" was all an 80-column error showed).
pub fn fit_status(msg: &str, width: usize) -> String {
    let n = msg.chars().count();
    if n <= width || width < 8 {
        return msg.chars().take(width).collect();
    }
    let head = width / 3;
    let tail = width - head - 1;
    let start: String = msg.chars().take(head).collect();
    let end: String = msg.chars().skip(n - tail).collect();
    format!("{start}…{end}")
}

/// λ for the header: `100`, then powers of ten as `1e5`.
pub fn lambda_label(l: f64) -> String {
    if l >= 1000.0 {
        format!("{l:e}")
    } else {
        format!("{l}")
    }
}

fn footer(f: &mut Frame, s: &State, area: Rect) {
    let text = if s.status.is_empty() {
        "space play ←→ step m method +- k g group s solver l λ v split e export ? q quit"
            .to_string()
    } else {
        format!(
            " {}",
            fit_status(&s.status, (area.width as usize).saturating_sub(1))
        )
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

#[cfg(test)]
mod tests {
    use super::lab_rgb;
    use keyshape_core::keyshapes::Method;

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

    /// Greedy (20, 20, 20), kmeans2-mean (10, 90, 30) and kmeans3-mean
    /// (110, 20, 120) vanished on a dark terminal, and kmeans2 and kmeans2-mean shared a
    /// green. Every method now reads on black and on white and differs from every other.
    #[test]
    fn every_method_reads_on_dark_and_light_terminals_and_differs_from_the_others() {
        let all: Vec<[u8; 3]> = Method::ALL.iter().map(lab_rgb).collect();
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

#[cfg(test)]
mod header_tests {
    use super::{fit_header, fit_status};

    #[test]
    fn a_long_status_keeps_its_start_and_its_reason() {
        let msg = "error: /home/someone/a/very/long/folder/of/tracks/take_017_final.csv: No such file or directory (os error 2)";
        let s = fit_status(msg, 79);
        assert_eq!(s.chars().count(), 79);
        assert!(s.starts_with("error: /home"), "{s}");
        assert!(s.ends_with("No such file or directory (os error 2)"), "{s}");
        assert_eq!(fit_status("short", 79), "short");
    }

    fn parts(method: &str, solver: &str) -> Vec<(String, u8)> {
        vec![
            ("liveportrait_d18".into(), 8),
            ("216 frames".into(), 0),
            ("lips".into(), 3),
            (format!("{method} k=12"), 9),
            (solver.into(), 9),
            ("frame 150 ⏸".into(), 9),
            ("1×".into(), 1),
            ("err 0.705 jit 1.40".into(), 9),
        ]
    }

    /// Round three: at 80 columns the point group never showed, and the file name went
    /// with kmeans3-mean, the hull or a λ.
    #[test]
    fn eighty_columns_keep_the_group_and_a_name_with_the_longest_settings() {
        for (m, sv) in [
            ("kmeans3-mean", "nnls λ=1e5"),
            ("hull", "bounded λ=100"),
            ("kmeans2-mean", "nnls"),
        ] {
            let (badge, body) = fit_header(parts(m, sv), "liveportrait_d18", 80, 0);
            let line = body.join(" · ");
            let width = line.chars().count() + 1 + if badge { 7 } else { 0 };
            assert!(width <= 80, "{line} is {width} wide");
            assert!(body.iter().any(|p| p == "lips"), "{line}");
            assert!(body.iter().any(|p| p.ends_with("d18")), "{line}");
            assert!(
                line.contains(m) && line.contains(sv) && line.contains("err"),
                "{line}"
            );
        }
        // With room, nothing gives way.
        let (badge, body) = fit_header(parts("spread", "nnls"), "liveportrait_d18", 120, 0);
        assert!(badge);
        assert_eq!(body.len(), 8);
    }
}
