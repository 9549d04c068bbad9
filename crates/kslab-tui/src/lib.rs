//! The interactive lab (ratatui + crossterm): event → [`Action`] (a pure keymap) →
//! [`update`] (pure) → [`draw`] (reads only). Solves run on a worker thread
//! (`compute`); the loop is generic over the ratatui backend so tests drive it with
//! `TestBackend`.

mod charts;
mod compute;
mod export;
mod face_panels;
mod live;
mod mesh;
mod request;
mod rig;
mod rig_panels;
mod rig_worker;
mod state;
#[cfg(test)]
mod tests;
mod view;

// What the lab offers: its loops for the binary, the sequence loaders and views it opens
// at start-up, and the pure state machine with its engine and screen for `kslab bench tui`.
pub use compute::{load, load_sized, normalised_note, Engine};
pub use export::export;
pub use mesh::{mesh_view, MeshView};
pub use request::Settings;
pub use rig::{prepare as prepare_rig, rig_view, rig_view_observed, RigView};
pub use rig_worker::spawn as spawn_rig_worker;
pub use view::draw;

use crossterm::event::{
    self, Event, KeyCode, KeyEvent, KeyEventKind, KeyModifiers, MouseButton, MouseEventKind,
};
use keyshape_core::sequence::Sequence;
use ratatui::backend::Backend;
use ratatui::Terminal;
pub use state::{update, Action, Effect, State};
use std::sync::mpsc::{Receiver, Sender};
use std::time::{Duration, Instant};

/// The pure keymap.
pub fn key_action(k: KeyEvent) -> Option<Action> {
    if k.kind == KeyEventKind::Release {
        return None;
    }
    let ctrl = k.modifiers.contains(KeyModifiers::CONTROL);
    Some(match k.code {
        KeyCode::Char('c') if ctrl => Action::Quit,
        KeyCode::Char(' ') => Action::TogglePlay,
        KeyCode::Left => Action::Step(-1),
        KeyCode::Right => Action::Step(1),
        KeyCode::Home => Action::First,
        KeyCode::End => Action::Last,
        KeyCode::Enter => Action::Enter,
        KeyCode::Backspace => Action::Backspace,
        KeyCode::Esc => Action::Escape,
        KeyCode::Char(c) => Action::Char(c),
        _ => return None,
    })
}

/// Characters outside a prompt that are commands.
pub fn command(c: char) -> Option<Action> {
    Some(match c {
        'q' => Action::Quit,
        '[' => Action::Speed(false),
        ']' => Action::Speed(true),
        'm' => Action::Method(true),
        'M' => Action::Method(false),
        '+' | '=' => Action::K(1),
        '-' | '_' => Action::K(-1),
        'g' => Action::Group,
        's' => Action::Solver,
        'l' => Action::Smooth(true),
        'L' => Action::Smooth(false),
        'v' => Action::Split,
        '?' | 'h' => Action::Help,
        'e' => Action::Export,
        'o' => Action::Open,
        'x' => Action::Mesh,
        'r' => Action::Rig,
        _ => return None,
    })
}

/// Turns a raw key into the action the current state means by it.
pub fn interpret(s: &State, k: KeyEvent) -> Option<Action> {
    match key_action(k)? {
        Action::Char(c) if s.prompt.is_none() => command(c).or(Some(Action::Char(c))),
        // In a prompt a space is text (a path may hold one), not play / pause.
        Action::TogglePlay if s.prompt.is_some() => Some(Action::Char(' ')),
        a => Some(a),
    }
}

/// Where input comes from: the terminal, or a script in tests.
pub trait Events {
    /// The next event within `timeout`, if any.
    fn next(&mut self, timeout: Duration) -> std::io::Result<Option<Event>>;
}

/// Crossterm's event queue.
pub struct TerminalEvents;

impl Events for TerminalEvents {
    fn next(&mut self, timeout: Duration) -> std::io::Result<Option<Event>> {
        if event::poll(timeout)? {
            Ok(Some(event::read()?))
        } else {
            Ok(None)
        }
    }
}

/// Carries out effects: requests go to the worker, exports are written here.
fn perform(s: &mut State, effects: Vec<Effect>, jobs: &Sender<compute::Job>, seq_path: &str) {
    for e in effects {
        match e {
            Effect::Compute(id, settings) => {
                let _ = jobs.send(compute::Job::Compute(id, settings));
            }
            Effect::Load(id, path) => {
                let _ = jobs.send(compute::Job::Load(id, path));
            }
            Effect::Export => {
                // The folder, then the file names: short enough for an 80-column footer.
                let dir = export::next_dir(std::path::Path::new("."));
                s.status = match export::export(s, seq_path, &dir) {
                    Ok(files) => export::status_line(&dir, &files),
                    Err(e) => format!("error: export failed: {e}"),
                };
            }
        }
    }
}

/// Runs the lab until the user quits. Generic over the backend and the event source.
pub fn run_loop<B: Backend>(
    terminal: &mut Terminal<B>,
    events: &mut dyn Events,
    s: &mut State,
    jobs: &Sender<compute::Job>,
    results: &Receiver<Action>,
    seq_path: &str,
) -> anyhow::Result<()>
where
    B::Error: std::error::Error + Send + Sync + 'static,
{
    let effects = s.start();
    perform(s, effects, jobs, seq_path);
    let mut last = Instant::now();
    while !s.quit {
        terminal.draw(|f| view::draw(f, s))?;
        let ev = events.next(Duration::from_millis(30))?;
        let mut actions = Vec::new();
        match ev {
            Some(Event::Key(k)) => actions.extend(interpret(s, k)),
            Some(Event::Mouse(m)) if m.kind == MouseEventKind::Down(MouseButton::Left) => {
                let area = terminal.size()?;
                let [_, _, tl, _, _] =
                    view::regions(ratatui::layout::Rect::new(0, 0, area.width, area.height));
                let full = ratatui::layout::Rect::new(0, 0, area.width, area.height);
                if m.row >= tl.y && m.row < tl.y + tl.height && tl.width > 2 {
                    actions.push(Action::Seek(
                        f64::from(m.column.saturating_sub(tl.x + 1)) / f64::from(tl.width - 3),
                    ));
                } else if let Some((method, k)) = view::chart_pick(full, s, m.column, m.row) {
                    actions.push(Action::Pick(method, k));
                }
            }
            _ => {}
        }
        while let Ok(a) = results.try_recv() {
            actions.push(a);
        }
        let now = Instant::now();
        actions.push(Action::Tick(now - last));
        last = now;
        for a in actions {
            let effects = update(s, a);
            perform(s, effects, jobs, seq_path);
        }
    }
    Ok(())
}

/// Opens the lab in this terminal on `seq` (loaded from `path`, or `builtin`);
/// `export_head_motion` says whether `e` re-applies the head motion. The
/// terminal is restored on every exit path, panics included (ratatui's panic hook).
pub fn run(
    seq: Sequence,
    path: &str,
    target: Option<keyshape_retarget::target::TargetSet>,
    mesh: Option<mesh::MeshView>,
    rig: Option<keyshape_rig::correspondence::RigSource>,
    export_head_motion: bool,
) -> anyhow::Result<()> {
    run_sized(seq, path, target, mesh, rig, export_head_motion, None)
}

/// [`run`], with the lab's `--image-size` (width, height): sequences in normalised 0–1
/// coordinates opened with `o` are scaled to it (the first one is scaled by the caller).
pub fn run_sized(
    seq: Sequence,
    path: &str,
    target: Option<keyshape_retarget::target::TargetSet>,
    mesh: Option<mesh::MeshView>,
    rig: Option<keyshape_rig::correspondence::RigSource>,
    export_head_motion: bool,
    image_size: Option<(f64, f64)>,
) -> anyhow::Result<()> {
    let mut s = State::new(&seq.source, seq.n_frames(), seq.fps().unwrap_or(30.0));
    s.export_head_motion = export_head_motion;
    s.target_keys = target.is_some();
    s.mesh = mesh.map(std::sync::Arc::new);
    s.show_mesh = false; // the 2-D target first; `x` shows the mesh
                         // Opened with --rig: the rig view shows once its worker has solved the track (the
                         // key-shape view meanwhile, the step named in the header); `r` toggles.
    if rig.is_some() {
        s.rig_step = Some("starting".into());
    }
    let rig = rig.map(std::sync::Arc::new);
    // The rig stays with the lab: a sequence opened with `o` is solved onto it too.
    if let Some(note) = compute::normalised_note(&seq) {
        s.normalised = true;
        s.status = note;
    }
    let (jobs, results) = compute::spawn_lab(seq, target, rig, image_size);
    let mut terminal = ratatui::try_init()?;
    // ratatui's hook restores the terminal on a panic; a panic in the worker is caught and
    // reported in the status line instead, so the lab must keep its screen.
    let restore_hook = std::sync::Arc::new(std::panic::take_hook());
    {
        let restore_hook = restore_hook.clone();
        std::panic::set_hook(Box::new(move |info| {
            let name = std::thread::current().name().map(str::to_string);
            if !matches!(
                name.as_deref(),
                Some(compute::WORKER_THREAD | rig_worker::RIG_THREAD)
            ) {
                restore_hook(info);
            }
        }));
    }
    let _ = crossterm::execute!(std::io::stdout(), crossterm::event::EnableMouseCapture);
    let r = run_loop(
        &mut terminal,
        &mut TerminalEvents,
        &mut s,
        &jobs,
        &results,
        path,
    );
    let _ = crossterm::execute!(std::io::stdout(), crossterm::event::DisableMouseCapture);
    ratatui::restore();
    r
}

/// Opens the live screen (`live`) in this terminal: frames from `queue` through
/// `session` until the user quits; the terminal is restored on every exit path.
pub fn run_live(
    session: &mut keyshape_live::session::Session,
    queue: &keyshape_live::Queue,
    counters: &keyshape_live::Counters,
    source: &str,
) -> anyhow::Result<()> {
    let mut terminal = ratatui::try_init()?;
    let r = live::run_loop(
        &mut terminal,
        &mut TerminalEvents,
        session,
        queue,
        counters,
        source,
    );
    ratatui::restore();
    r
}
