//! `kslab bench tui`: input-to-redraw latency of the lab when k or the method changes.

use anyhow::Result;
use clap::Args;
use kslab_tui::Engine;
use kslab_tui::Settings;
use kslab_tui::{draw, update, Action, State};
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
    /// The rig whose view is measured too (opening it, a new λ, stepping frames)
    /// [default: ../shared/data/ict_facekit_face when it is there; none otherwise].
    #[arg(long, value_name = "DIR")]
    rig: Option<PathBuf>,
}

pub fn run(a: &TuiBenchArgs) -> Result<()> {
    let path = bench_file(a);
    let seq = kslab_tui::load(&path.display().to_string())?;
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
    // k up eight times, then every method in turn (greedy among them) back to the first.
    let changes: Vec<Action> = (0..8)
        .map(|_| Action::K(1))
        .chain((0..keyshape_core::keyshapes::Method::ALL.len()).map(|_| Action::Method(true)))
        .collect();
    let mut background = Vec::new();
    for a in changes {
        // Input to redraw: what the screen shows (keys, the chosen solver), as the worker
        // sends it first; the split view's LS / NNLS follow in the background.
        let t = Instant::now();
        update(&mut s, a);
        let c = engine.compute_shown(s.request, &s.settings.clone())?;
        update(&mut s, Action::Computed(Box::new(c)));
        term.draw(|f| draw(f, &s))?;
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
        term.draw(|f| draw(f, &s))?;
    }
    let draw = t.elapsed().as_secs_f64() / 20.0 * 1e3;
    let rig = rig_view_times(a, &engine_seq(&path)?, &mut s, &mut term)?;
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
    if let Some(r) = rig {
        print_rig_rows(&r)?;
    }
    Ok(())
}

/// The bench's sequence: the file given, else d6 from the shared data, else the built-in.
fn bench_file(a: &TuiBenchArgs) -> PathBuf {
    let default = keyshape_io::shared_data("mediapipe_face_tracks/liveportrait_d6.csv")
        .unwrap_or_else(|_| PathBuf::from("builtin"));
    a.file.clone().unwrap_or_else(|| {
        if default.exists() {
            default
        } else {
            PathBuf::from("builtin")
        }
    })
}

/// The rig view's rows of the table.
fn print_rig_rows(r: &RigTimes) -> Result<()> {
    for (step, ms) in &r.open {
        outln!("| rig view, opening: {step} | {ms:.0} ms |");
    }
    if let Some(ms) = r.preview {
        outln!(
            "| **rig view, the first frame shown** (solved alone, from the worker's start) | **{ms:.0} ms** |"
        );
    }
    outln!(
        "| **rig view open, total** (in the background: the lab answers meanwhile) | **{:.0} ms** |",
        r.open.iter().map(|x| x.1).sum::<f64>()
    );
    outln!(
        "| rig view, a new λ (`l`, λ 100: the neutral reused, no search) | {:.0} ms |",
        r.lambda
    );
    outln!(
        "| rig view, stepping a frame (→) and redrawing, median / max of 30 | {:.1} / {:.1} ms |",
        r.step[0],
        r.step[1]
    );
    Ok(())
}

/// The sequence the bench measures, as the lab loads it.
fn engine_seq(path: &std::path::Path) -> Result<keyshape_core::sequence::Sequence> {
    Ok(kslab_tui::load(&path.display().to_string())?)
}

/// What the rig view costs: each step of opening it, a new λ, and stepping frames in it.
struct RigTimes {
    open: Vec<(String, f64)>,
    /// From the worker's start to the first frame's preview (none: no 68-point view).
    preview: Option<f64>,
    lambda: f64,
    step: [f64; 2],
}

fn rig_view_times(
    a: &TuiBenchArgs,
    seq: &keyshape_core::sequence::Sequence,
    s: &mut State,
    term: &mut Terminal<TestBackend>,
) -> Result<Option<RigTimes>> {
    let dir = match &a.rig {
        Some(d) => d.clone(),
        None => match keyshape_io::shared_data("ict_facekit_face") {
            Ok(d) if d.exists() => d,
            _ => return Ok(None),
        },
    };
    let source = keyshape_rig::correspondence::RigSource::new(&dir);
    // The lab's own rig worker, from its start: each step's time from its start to the
    // next's (the last to the answer), and when the first frame's preview arrived.
    let mut marks: Vec<(String, Instant)> = Vec::new();
    let (tx, rx) = std::sync::mpsc::channel();
    let start = Instant::now();
    let _jobs = kslab_tui::spawn_rig_worker(
        std::sync::Arc::new(source.clone()),
        std::sync::Arc::new(seq.clone()),
        tx,
    );
    let mut preview = None;
    let view = loop {
        match rx.recv_timeout(std::time::Duration::from_secs(600)) {
            Ok(Action::RigStep(_, t)) => marks.push((t, Instant::now())),
            Ok(Action::RigPreview(..)) => preview = Some(start.elapsed().as_secs_f64() * 1e3),
            Ok(Action::RigSolved(_, r)) => break r.map_err(|e| anyhow::anyhow!("rig: {e}"))?,
            Ok(_) => {}
            Err(e) => anyhow::bail!("the rig's worker did not answer: {e}"),
        }
    };
    let end = Instant::now();
    let open = marks
        .iter()
        .enumerate()
        .map(|(i, (t, at))| {
            let next = marks.get(i + 1).map_or(end, |m| m.1);
            (t.clone(), (next - *at).as_secs_f64() * 1e3)
        })
        .collect();
    let view = std::sync::Arc::unwrap_or_clone(view);
    let t = Instant::now();
    kslab_tui::rig_view_observed(seq, &source, 100.0, view.neutral, &mut |_| {})?;
    let lambda = t.elapsed().as_secs_f64() * 1e3;
    s.rig = Some(std::sync::Arc::new(view));
    s.show_rig = true;
    let mut step = Vec::new();
    for _ in 0..30 {
        let t = Instant::now();
        update(s, Action::Step(1));
        term.draw(|f| draw(f, s))?;
        step.push(t.elapsed().as_secs_f64() * 1e3);
    }
    step.sort_by(f64::total_cmp);
    Ok(Some(RigTimes {
        open,
        preview,
        lambda,
        step: [step[step.len() / 2], step[step.len() - 1]],
    }))
}
