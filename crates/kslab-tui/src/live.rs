//! The lab live (`kslab tui --live SOURCE`): the incoming landmarks over the posed rig's
//! landmarks under the fitted head pose, the named weight bars, frames per second,
//! latency and dropped frames; `n` recalibrates, `l`/`L` turn the causal temporal prior's
//! λ up and down, `q` quits. Event → [`LiveAction`] (a pure keymap) → [`update`] (pure)
//! → [`draw`] (reads only), the loop generic over the backend and the event source.

use super::Events;
use crossterm::event::{Event, KeyCode, KeyEventKind, KeyModifiers};
use keyshape_live::session::{Served, Session, Step};
use keyshape_live::{Counters, Queue};
use ratatui::backend::Backend;
use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Style};
use ratatui::text::Line;
use ratatui::widgets::canvas::{Canvas, Line as CanvasLine, Points};
use ratatui::widgets::{Block, Paragraph};
use ratatui::{Frame, Terminal};
use std::time::{Duration, Instant};

/// The λ steps `l` and `L` move through (the causal prior, squared pixels per unit weight²).
pub const LAMBDAS: [f64; 7] = [0.0, 10.0, 30.0, 100.0, 300.0, 1000.0, 3000.0];

/// What the screen shows.
#[derive(Debug, Clone, Default)]
pub struct LiveState {
    /// The source's name.
    pub source: String,
    /// The rig's shape names.
    pub names: Vec<String>,
    /// The last frame's weights.
    pub weights: Vec<f64>,
    /// The last frame's landmarks as received (image x, y).
    pub tracked: Vec<[f64; 2]>,
    /// The posed rig's landmarks under the fitted head pose (image x, y).
    pub posed: Vec<[f64; 2]>,
    /// The face's contours through the tracked landmarks (indices into `tracked`): the
    /// layout's polylines, as the rig reads them.
    pub contours: Vec<Vec<usize>>,
    /// Frames taken and solved when the screen's frame was last made (to make it only anew).
    pub shown: (u64, u64),
    /// Frames solved in the last second.
    pub fps: usize,
    /// Latency p50 and p99 over the recent frames (ms).
    pub latency: (Option<f64>, Option<f64>),
    /// (received, malformed, dropped).
    pub counts: (u64, u64, u64),
    /// Calibration: Some((have, need)) while collecting.
    pub collecting: Option<(usize, usize)>,
    /// Seconds since the last frame arrived.
    pub idle: f64,
    /// The causal prior's λ in effect (squared pixels); `None` while the default, relative
    /// to the face, waits for the calibration to measure the face.
    pub smooth: Option<f64>,
    /// The last message.
    pub status: String,
    /// Ask to quit.
    pub quit: bool,
}

/// What a key asks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LiveAction {
    /// Start a new calibration.
    Recalibrate,
    /// λ one step up (true) or down.
    Smooth(bool),
    /// Leave.
    Quit,
}

/// What [`update`] asks the loop to do.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LiveEffect {
    /// Recalibrate the solve.
    Recalibrate,
    /// Set the solve's λ.
    SetSmooth(f64),
}

/// The pure keymap.
pub fn key(k: crossterm::event::KeyEvent) -> Option<LiveAction> {
    if k.kind == KeyEventKind::Release {
        return None;
    }
    Some(match k.code {
        KeyCode::Char('c') if k.modifiers.contains(KeyModifiers::CONTROL) => LiveAction::Quit,
        KeyCode::Char('q') | KeyCode::Esc => LiveAction::Quit,
        KeyCode::Char('n') => LiveAction::Recalibrate,
        KeyCode::Char('l') => LiveAction::Smooth(true),
        KeyCode::Char('L') => LiveAction::Smooth(false),
        _ => return None,
    })
}

/// The pure update.
pub fn update(s: &mut LiveState, a: LiveAction) -> Vec<LiveEffect> {
    match a {
        LiveAction::Quit => {
            s.quit = true;
            Vec::new()
        }
        LiveAction::Recalibrate => {
            s.status = "look neutral: recalibrating".into();
            vec![LiveEffect::Recalibrate]
        }
        LiveAction::Smooth(up) => {
            // The next step of LAMBDAS above or below the λ in effect (which the default,
            // relative to the face, puts between the steps).
            let now = s.smooth.unwrap_or(0.0);
            let next = if up {
                LAMBDAS.iter().copied().find(|&l| l > now * (1.0 + 1e-9))
            } else {
                LAMBDAS
                    .iter()
                    .rev()
                    .copied()
                    .find(|&l| l < now * (1.0 - 1e-9))
            }
            .unwrap_or(if up { LAMBDAS[LAMBDAS.len() - 1] } else { 0.0 });
            s.smooth = Some(next);
            s.status = format!("causal prior λ {next}");
            vec![LiveEffect::SetSmooth(next)]
        }
    }
}

/// The header's λ: squared pixels to one decimal where it is not whole (the default,
/// 0.0026 × IOD², is not), `auto` before the calibration has measured the face.
fn lambda_label(l: Option<f64>) -> String {
    match l {
        None => "auto".into(),
        Some(l) if l.fract() == 0.0 => format!("{l}"),
        Some(l) => format!("{l:.1}"),
    }
}

/// Draws the screen.
pub fn draw(f: &mut Frame, s: &LiveState) {
    let [head, body, foot] = Layout::vertical([
        Constraint::Length(1),
        Constraint::Min(3),
        Constraint::Length(1),
    ])
    .areas(f.area());
    let state = match (s.collecting, s.idle > 2.0) {
        (_, true) => format!("waiting: no frames for {:.0} s", s.idle),
        (Some((have, need)), _) => format!("look neutral: {have}/{need}"),
        (None, _) => "calibrated".into(),
    };
    let ms = |v: Option<f64>| v.map_or("–".into(), |v| format!("{v:.1}"));
    let long = format!(
        "live · {} · {state} · {} fps · latency p50/p99 {}/{} ms · dropped {} · bad {} · λ {}",
        short(&s.source),
        s.fps,
        ms(s.latency.0),
        ms(s.latency.1),
        s.counts.2,
        s.counts.1,
        lambda_label(s.smooth)
    );
    // At 80 columns the short form, which keeps every figure.
    let text = if long.chars().count() <= usize::from(head.width) {
        long
    } else {
        format!(
            "{state} · {} fps · {}/{} ms · drop {} · bad {} · λ {}",
            s.fps,
            ms(s.latency.0),
            ms(s.latency.1),
            s.counts.2,
            s.counts.1,
            lambda_label(s.smooth)
        )
    };
    f.render_widget(Paragraph::new(text), head);
    let [face, bars] =
        Layout::horizontal([Constraint::Percentage(50), Constraint::Percentage(50)]).areas(body);
    draw_face(f, face, s);
    draw_bars(f, bars, s);
    let foot_text = if s.status.is_empty() {
        "n recalibrate · l/L λ up/down · q quit".to_string()
    } else {
        format!("{} · n recalibrate · l/L λ · q quit", s.status)
    };
    f.render_widget(
        Paragraph::new(foot_text).style(Style::default().fg(Color::DarkGray)),
        foot,
    );
}

/// A source's short name: a file's name without its folder.
fn short(source: &str) -> &str {
    match source.rsplit_once('/') {
        Some((_, name)) if !source.starts_with("openseeface") => name,
        _ => source,
    }
}

fn draw_face(f: &mut Frame, area: Rect, s: &LiveState) {
    let all: Vec<[f64; 2]> = s.tracked.iter().chain(&s.posed).copied().collect();
    let block = Block::bordered().title(Line::from(vec![
        ratatui::text::Span::styled("● tracked", Style::default().fg(Color::Cyan)),
        ratatui::text::Span::raw(" "),
        ratatui::text::Span::styled("● posed rig", Style::default().fg(Color::Yellow)),
    ]));
    if all.is_empty() {
        f.render_widget(Paragraph::new("no frame yet").block(block), area);
        return;
    }
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in &all {
        x0 = x0.min(p[0]);
        x1 = x1.max(p[0]);
        y0 = y0.min(p[1]);
        y1 = y1.max(p[1]);
    }
    // Equal scales on both axes (a terminal cell is about twice as tall as wide).
    let (w, h) = (
        f64::from(area.width.saturating_sub(2).max(1)),
        2.0 * f64::from(area.height.saturating_sub(2).max(1)),
    );
    let span = ((x1 - x0) / w).max((y1 - y0) / h).max(1e-9) * 1.05;
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let (hw, hh) = (span * w / 2.0, span * h / 2.0);
    // Image y points down; the canvas's up.
    let flip = |v: &[[f64; 2]]| -> Vec<(f64, f64)> { v.iter().map(|p| (p[0], -p[1])).collect() };
    let (tracked, posed) = (flip(&s.tracked), flip(&s.posed));
    let canvas = Canvas::default()
        .block(block)
        .marker(ratatui::symbols::Marker::Braille)
        .x_bounds([cx - hw, cx + hw])
        .y_bounds([-cy - hh, -cy + hh])
        .paint(move |ctx| {
            ctx.draw(&Points {
                coords: &posed,
                color: Color::Yellow,
            });
            // The tracked face as its contours (a cloud of dots is unreadable at 80 × 24);
            // points no contour passes through as dots.
            let mut lone = vec![true; tracked.len()];
            for line in &s.contours {
                for w in line.windows(2) {
                    let (Some(a), Some(b)) = (tracked.get(w[0]), tracked.get(w[1])) else {
                        continue;
                    };
                    lone[w[0]] = false;
                    lone[w[1]] = false;
                    ctx.draw(&CanvasLine {
                        x1: a.0,
                        y1: a.1,
                        x2: b.0,
                        y2: b.1,
                        color: Color::Cyan,
                    });
                }
            }
            let dots: Vec<(f64, f64)> = tracked
                .iter()
                .zip(&lone)
                .filter(|(_, l)| **l)
                .map(|(p, _)| *p)
                .collect();
            ctx.draw(&Points {
                coords: &dots,
                color: Color::Cyan,
            });
        });
    f.render_widget(canvas, area);
}

fn draw_bars(f: &mut Frame, area: Rect, s: &LiveState) {
    let block = Block::bordered().title("weights (largest first)");
    let inner = block.inner(area);
    f.render_widget(block, area);
    let mut order: Vec<usize> = (0..s.weights.len().min(s.names.len())).collect();
    order.sort_by(|&a, &b| s.weights[b].total_cmp(&s.weights[a]).then(a.cmp(&b)));
    let name_w = 16usize.min(usize::from(inner.width) / 2);
    let bar_w = usize::from(inner.width).saturating_sub(name_w + 6);
    let lines: Vec<Line> = order
        .iter()
        .take(usize::from(inner.height))
        .map(|&i| {
            let w = s.weights[i].clamp(0.0, 1.0);
            let n = (w * bar_w as f64).round() as usize;
            let name: String = s.names[i].chars().take(name_w).collect();
            Line::from(format!(
                "{name:<name_w$} {:>4} {}",
                format!("{:.2}", s.weights[i]).trim_start_matches('0'),
                "█".repeat(n)
            ))
        })
        .collect();
    f.render_widget(Paragraph::new(lines), inner);
}

/// The screen told a calibration was taken into use.
fn calibrated(session: &Session, s: &mut LiveState) {
    s.collecting = None;
    let n = session.solver().calibration().map_or(0, |c| c.frames);
    s.status = match session.calibration_warning() {
        Some(w) => format!("calibrated on {n} frames, not neutral: {w} (n: again)"),
        None => format!("calibrated on {n} frames"),
    };
}

/// Solves every frame waiting in `queue`, in order (the newest is what is drawn) — the
/// session's own serving step, as `kslab live` runs it — noting the last arrival, and the
/// source's end once in the status.
fn drain(
    queue: &Queue,
    session: &mut Session,
    s: &mut LiveState,
    last_frame: &mut Instant,
    ended: &mut bool,
) -> anyhow::Result<()> {
    loop {
        match session.serve(queue, Duration::ZERO)? {
            Served::Took(step) => {
                *last_frame = Instant::now();
                match step {
                    Step::Collecting(have, need) => s.collecting = Some((have, need)),
                    Step::Calibrated(_) => calibrated(session, s),
                    Step::Solved => s.collecting = None,
                }
                if let Some(n) = session.notices().pop() {
                    s.status = n;
                }
            }
            Served::Calibrated(_) => {
                calibrated(session, s);
                break;
            }
            Served::Idle => break,
            Served::Closed => {
                if !*ended {
                    s.status = "the source has ended".into();
                    *ended = true;
                }
                break;
            }
        }
    }
    Ok(())
}

/// The last frame into the screen's state, when a new one was taken: the tracked landmarks
/// (while calibrating too, so the person sees they are tracked), and once solved its
/// weights and the posed rig.
fn show_last(session: &Session, s: &mut LiveState) {
    let (taken, count) = session.last_taken();
    // A frame taken, or frames solved since (a calibration made between frames).
    if (count, session.solved()) == s.shown {
        return;
    }
    s.shown = (count, session.solved());
    if session.solver().calibration().is_none() {
        s.tracked = taken.chunks_exact(2).map(|p| [p[0], p[1]]).collect();
        s.posed.clear();
        return;
    }
    if let Some((fr, solved)) = session.last() {
        s.weights.clone_from(&solved.weights);
        let rig = session.solver().rig();
        let sel = session.selection();
        s.tracked = sel
            .iter()
            .filter_map(|&p| Some([*fr.points.get(2 * p)?, *fr.points.get(2 * p + 1)?]))
            .collect();
        if let Some(c) = session.solver().calibration() {
            let person = keyshape_rig::Rig {
                neutral: c.neutral.clone(),
                ..rig.clone()
            };
            s.posed = person
                .posed(&solved.weights)
                .iter()
                .map(|p| {
                    let u = solved.camera.project(p);
                    [u[0], -u[1]]
                })
                .collect();
        }
    }
}

/// Runs the live screen until the user quits or the source ends: frames from `queue` go
/// through `session`; keys from `events`.
pub fn run_loop<B: Backend>(
    terminal: &mut Terminal<B>,
    events: &mut dyn Events,
    session: &mut Session,
    queue: &Queue,
    counters: &Counters,
    source: &str,
) -> anyhow::Result<()>
where
    B::Error: std::error::Error + Send + Sync + 'static,
{
    let mut s = LiveState {
        source: source.to_string(),
        names: session.solver().rig().names.clone(),
        collecting: match session.solver().calibration() {
            Some(_) => None,
            None => Some(session.solver().collected()),
        },
        status: "look neutral".into(),
        contours: session.solver().rig().polylines(),
        ..LiveState::default()
    };
    let mut last_frame = Instant::now();
    let mut last_draw: Option<Instant> = None;
    let mut ended = false;
    while !s.quit {
        drain(queue, session, &mut s, &mut last_frame, &mut ended)?;
        s.fps = session.rate();
        s.idle = last_frame.elapsed().as_secs_f64();
        s.counts = counters.get();
        s.latency = session.recent_latency();
        s.smooth = session.solver().smooth();
        show_last(session, &mut s);
        if last_draw.is_none_or(|t| t.elapsed() >= Duration::from_millis(33)) {
            terminal.draw(|f| draw(f, &s))?;
            last_draw = Some(Instant::now());
        }
        if let Some(Event::Key(k)) = events.next(Duration::from_millis(5))? {
            if let Some(a) = key(k) {
                for e in update(&mut s, a) {
                    match e {
                        LiveEffect::Recalibrate => {
                            session.recalibrate();
                            s.collecting = Some(session.solver().collected());
                        }
                        LiveEffect::SetSmooth(l) => session.set_smooth(l)?,
                    }
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_recalibrate_turn_lambda_and_quit() {
        let mut s = LiveState::default();
        let k = |c| crossterm::event::KeyEvent::from(KeyCode::Char(c));
        assert_eq!(
            update(&mut s, key(k('n')).unwrap()),
            [LiveEffect::Recalibrate]
        );
        assert_eq!(
            update(&mut s, key(k('l')).unwrap()),
            [LiveEffect::SetSmooth(10.0)]
        );
        update(&mut s, key(k('l')).unwrap());
        assert_eq!(
            update(&mut s, key(k('L')).unwrap()),
            [LiveEffect::SetSmooth(10.0)]
        );
        update(&mut s, LiveAction::Smooth(false));
        assert_eq!(
            update(&mut s, LiveAction::Smooth(false)),
            [LiveEffect::SetSmooth(0.0)],
            "λ stops at 0"
        );
        // The default λ, relative to the face, falls between the steps: l and L go to the
        // steps on either side of it.
        s.smooth = Some(29.8);
        assert_eq!(
            update(&mut s, LiveAction::Smooth(true)),
            [LiveEffect::SetSmooth(30.0)]
        );
        s.smooth = Some(29.8);
        assert_eq!(
            update(&mut s, LiveAction::Smooth(false)),
            [LiveEffect::SetSmooth(10.0)]
        );
        s.smooth = Some(3000.0);
        assert_eq!(
            update(&mut s, LiveAction::Smooth(true)),
            [LiveEffect::SetSmooth(3000.0)],
            "λ stops at the last step"
        );
        assert_eq!(lambda_label(None), "auto");
        assert_eq!(lambda_label(Some(29.766)), "29.8");
        assert_eq!(lambda_label(Some(30.0)), "30");
        assert!(update(&mut s, key(k('q')).unwrap()).is_empty());
        assert!(s.quit);
    }
}
