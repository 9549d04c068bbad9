//! `kslab bench tui`: input-to-redraw latency of the lab when k or the method changes.

use anyhow::Result;
use clap::Args;
use kslab_tui::compute::Engine;
use kslab_tui::state::Settings;
use kslab_tui::{update, view, Action, State};
use ratatui::backend::TestBackend;
use ratatui::Terminal;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `kslab bench tui`.
#[derive(Debug, Args)]
pub struct TuiBenchArgs {
    /// Sequence (default ../shared/data/mediapipe_face_tracks/liveportrait_d6.csv, or the
    /// built-in one when that is missing).
    file: Option<PathBuf>,
    /// Point groups the lab works on (`all` = 468 points).
    #[arg(long, default_value = "all")]
    points: String,
}

pub fn run(a: &TuiBenchArgs) -> Result<()> {
    let default = keyshape_io::shared_data("mediapipe_face_tracks/liveportrait_d6.csv")
        .unwrap_or_else(|_| PathBuf::from("builtin"));
    let path = a.file.clone().unwrap_or_else(|| {
        if default.exists() {
            default
        } else {
            PathBuf::from("builtin")
        }
    });
    let seq = kslab_tui::compute::load(&path.display().to_string())?;
    let (frames, points) = (seq.n_frames(), seq.points);
    let mut engine = Engine::new(seq);
    let mut s = State::new(&path.display().to_string(), frames, 30.0);
    s.settings = Settings {
        points: a.points.clone(),
        ..Settings::default()
    };
    let t = Instant::now();
    let first = engine.compute(1, &s.settings)?;
    let warm = t.elapsed().as_secs_f64();
    s.request = 1;
    update(&mut s, Action::Computed(Box::new(first)));
    let mut term = Terminal::new(TestBackend::new(120, 40))?;
    let mut lat = Vec::new();
    let changes: Vec<Action> = (0..8)
        .map(|_| Action::K(1))
        .chain((0..5).map(|_| Action::Method(true)))
        .collect();
    let mut background = Vec::new();
    for a in changes {
        // Input to redraw: what the screen shows (keys, the chosen solver), as the worker
        // sends it first; the split view's LS / NNLS follow in the background.
        let t = Instant::now();
        update(&mut s, a);
        let c = engine.compute_shown(s.request, &s.settings.clone())?;
        update(&mut s, Action::Computed(Box::new(c)));
        term.draw(|f| view::draw(f, &s))?;
        lat.push((
            format!("{} k={}", s.settings.method, s.settings.k),
            t.elapsed().as_secs_f64() * 1e3,
        ));
        let t = Instant::now();
        let id = s.request;
        let v = engine.split_views(id)?;
        update(&mut s, Action::SplitViews(id, v));
        background.push(t.elapsed().as_secs_f64() * 1e3);
    }
    background.sort_by(f64::total_cmp);
    let t = Instant::now();
    let rows = engine
        .curves(&s.settings, &mut || false)?
        .unwrap_or_default();
    let curves = t.elapsed().as_secs_f64();
    let t = Instant::now();
    for _ in 0..20 {
        term.draw(|f| view::draw(f, &s))?;
    }
    let draw = t.elapsed().as_secs_f64() / 20.0 * 1e3;
    let mut ms: Vec<f64> = lat.iter().map(|x| x.1).collect();
    ms.sort_by(f64::total_cmp);
    outln!(
        "kslab bench tui: {} ({frames} frames × {points} points, group '{}'), {} threads\n",
        path.display(),
        a.points,
        rayon::current_num_threads()
    );
    outln!("| measure | value |");
    outln!("|---|---|");
    outln!(
        "| first request (alignment, PCA, warp, ground truth, weights) | {:.0} ms |",
        warm * 1e3
    );
    for (what, v) in &lat {
        outln!("| change → {what}: keys, the chosen solver's weights, redraw | {v:.0} ms |");
    }
    outln!(
        "| **median / max input-to-redraw** | **{:.0} / {:.0} ms** |",
        ms[ms.len() / 2],
        ms[ms.len() - 1]
    );
    outln!(
        "| then, in the background: LS / NNLS for the split view, median / max | {:.0} / {:.0} ms |",
        background[background.len() / 2],
        background[background.len() - 1]
    );
    outln!("| redraw alone (120 × 40) | {draw:.1} ms |");
    outln!(
        "| error curves for the chart (all methods, k = 2..24, background) | {:.0} ms ({} rows) |",
        curves * 1e3,
        rows.len()
    );
    Ok(())
}
