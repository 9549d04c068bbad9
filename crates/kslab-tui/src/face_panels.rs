//! The lab's face panels: the tracked shape beside its reconstruction, the target mesh,
//! and the time line under them.

use super::request::Computed;
use super::rig_panels::{rig_panel, rig_weights};
use super::state::State;
use keyshape_core::solve::Solver;
use nalgebra::DMatrix;
use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Style};
use ratatui::symbols::Marker;
use ratatui::text::{Line, Span};
use ratatui::widgets::canvas::{Canvas, Line as CLine};
use ratatui::widgets::{Block, Paragraph};
use ratatui::Frame;

pub(super) fn bounds(ms: &[&DMatrix<f64>], dims: usize) -> ([f64; 2], [f64; 2]) {
    let ((x0, y0), (x1, y1)) = keyshape_pictures::render::face::bounds_of(ms, dims);
    let (cx, cy, half) = (
        (x0 + x1) / 2.0,
        (y0 + y1) / 2.0,
        (x1 - x0).max(y1 - y0) / 2.0,
    );
    ([cx - half, cx + half], [-(cy + half), -(cy - half)])
}

pub(super) fn shape_panel<'a>(
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

pub(super) fn face_panels(f: &mut Frame, s: &State, c: &Computed, area: Rect) {
    let t = s.frame.min(c.frames.len().saturating_sub(1));
    let sb = bounds(&[&c.tracked], c.dims);
    let mut targets = vec![&c.truth];
    targets.extend(c.views.iter().map(|v| &v.target));
    let tb = bounds(&targets, c.dims);
    let Some(main) = c.views.first() else { return };
    if s.split {
        split_panels(f, c, t, (sb, tb), area);
        return;
    }
    let [a, b] = Layout::horizontal([Constraint::Ratio(1, 2); 2]).areas(area);
    if let (true, Some(r)) = (s.show_rig, &s.rig) {
        let t = r.at(t);
        f.render_widget(rig_panel(r, t), a);
        f.render_widget(rig_weights(r, t, b.height.saturating_sub(2) as usize), b);
        return;
    }
    let rms = main.frame_rms.get(t).copied().unwrap_or(0.0);
    let src = shape_panel(
        format!(
            "source: tracked + recon · rms {}",
            keyshape_core::stats::sig(rms, 3)
        ),
        vec![(&c.tracked, Color::White), (&main.recon, Color::Cyan)],
        c,
        t,
        sb,
    );
    f.render_widget(src, a);
    if let (true, Some(m)) = (s.show_mesh, &s.mesh) {
        f.render_widget(mesh_panel(m, t), b);
        return;
    }
    let trms = main
        .frame_target_rms
        .get(t)
        .map_or("n/a".to_string(), |v| keyshape_core::stats::sig(*v, 3));
    let tgt = shape_panel(
        format!("target: G(q) + retargeted · rms {trms}"),
        vec![(&c.truth, Color::DarkGray), (&main.target, Color::Red)],
        c,
        t,
        tb,
    );
    f.render_widget(tgt, b);
}

/// A panel's x and y bounds, as [`bounds`] gives them.
type Bounds = ([f64; 2], [f64; 2]);

/// The split view (`s`): the source with both reconstructions, and the target under LS and
/// under NNLS (`sb`, `tb`: the source's and the targets' bounds).
fn split_panels(f: &mut Frame, c: &Computed, t: usize, (sb, tb): (Bounds, Bounds), area: Rect) {
    let (Some(ls), Some(nn)) = (c.view(Solver::Ls), c.view(Solver::Nnls)) else {
        f.render_widget(
            Paragraph::new("computing LS and NNLS for the split view…").block(Block::bordered()),
            area,
        );
        return;
    };
    let [a, b, d] = Layout::horizontal([Constraint::Ratio(1, 3); 3]).areas(area);
    // The title as long as the panel allows: at 80 columns "source ·" goes, not a
    // number ("NNLS 0.3" was all that was left).
    let (l, n) = (
        keyshape_core::stats::sig(ls.frame_rms[t], 3),
        keyshape_core::stats::sig(nn.frame_rms[t], 3),
    );
    let full = format!("source · LS {l} NNLS {n}");
    let title = if full.chars().count() + 2 <= a.width as usize {
        full
    } else {
        format!("LS {l} NNLS {n}")
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
    for (name, v, colour, at) in [("LS", ls, Color::Red, b), ("NNLS", nn, Color::Green, d)] {
        let panel = shape_panel(
            format!(
                "target {name} · rms {}",
                v.frame_target_rms
                    .get(t)
                    .map_or("n/a".into(), |x| keyshape_core::stats::sig(*x, 3))
            ),
            vec![(&c.truth, Color::DarkGray), (&v.target, colour)],
            c,
            t,
            tb,
        );
        f.render_widget(panel, at);
    }
}

/// The tracked landmarks (white) and the posed rig's under the fitted head pose (magenta).
pub(super) fn mesh_panel(
    m: &super::mesh::MeshView,
    t: usize,
) -> Canvas<'_, impl Fn(&mut ratatui::widgets::canvas::Context) + '_> {
    let t = t.min(m.frames.len().saturating_sub(1));
    Canvas::default()
        .block(Block::bordered().title("mesh: RBF + skinning · x"))
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

pub(super) fn time_line(f: &mut Frame, s: &State, c: &Computed, area: Rect) {
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
