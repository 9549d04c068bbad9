//! The lab's own tests: pure update, screens on ratatui's TestBackend (text snapshots in
//! `crates/kslab-tui/snapshots/`, reviewed), the generic loop driven by scripted keys, the
//! export, the λ knob and the rig view. The real binary in tmux is tested with the binary
//! (`tests/it/tui.rs`).

mod rig;
mod settings;

use crate::compute::Engine;
use crate::state::{Prompt, Settings};
use crate::{update, view, Action, Effect, Events, State};
use keyshape_io::builtin_sequence;
use ratatui::backend::TestBackend;
use ratatui::Terminal;
use std::path::Path;
use std::path::PathBuf;
use std::time::Duration;

/// `../shared/data/<rel>` beside the repository.
fn shared(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data")
        .join(rel)
}

/// Whether this run rewrites the reviewed snapshots (`UPDATE_SNAPSHOTS=1`) instead of
/// checking them.
fn update_snapshots() -> bool {
    std::env::var_os("UPDATE_SNAPSHOTS").is_some()
}

fn state() -> State {
    State::new("builtin", 216, 30.0)
}

#[test]
fn changing_a_setting_requests_a_newer_computation_and_drops_stale_results() {
    let mut s = state();
    assert_eq!(s.start(), vec![Effect::Compute(1, Settings::default())]);
    let fx = update(&mut s, Action::K(1));
    assert_eq!(
        fx,
        vec![Effect::Compute(
            2,
            Settings {
                k: 13,
                ..Settings::default()
            }
        )]
    );
    assert!(s.busy);
    let mut engine = Engine::new(builtin_sequence().unwrap());
    let old = engine.compute(1, &Settings::default()).unwrap();
    update(&mut s, Action::Computed(Box::new(old)));
    assert!(
        s.computed.is_none() && s.busy,
        "a superseded result is dropped"
    );
    let new = engine.compute(2, &s.settings.clone()).unwrap();
    update(&mut s, Action::Computed(Box::new(new)));
    assert_eq!(s.computed.as_ref().unwrap().keys.len(), 13);
    assert!(!s.busy);
    update(&mut s, Action::Failed(2, "boom".into()));
    assert_eq!(s.status, "error: boom");
    assert!(update(&mut s, Action::K(-100)).len() == 1 && s.settings.k == 1);
    assert!(update(&mut s, Action::K(-1)).is_empty(), "k stays at 1");
}

#[test]
fn playback_steps_seek_and_prompts() {
    let mut s = state();
    update(&mut s, Action::Step(-5));
    assert_eq!(s.frame, 0);
    update(&mut s, Action::Last);
    assert_eq!(s.frame, 215);
    update(&mut s, Action::Step(3));
    assert_eq!(s.frame, 215);
    update(&mut s, Action::First);
    update(&mut s, Action::TogglePlay);
    update(&mut s, Action::Speed(true));
    update(&mut s, Action::Tick(Duration::from_millis(500)));
    assert_eq!(s.frame, 30, "0.5 s at 30 fps × 2");
    update(&mut s, Action::Seek(0.5));
    assert_eq!(s.frame, 108);
    // Typing a number opens the jump prompt; Enter jumps (once frames are known).
    let mut engine = Engine::new(builtin_sequence().unwrap());
    s.request = 1;
    update(
        &mut s,
        Action::Computed(Box::new(engine.compute(1, &Settings::default()).unwrap())),
    );
    update(&mut s, Action::Char('4'));
    update(&mut s, Action::Char('2'));
    assert_eq!(s.prompt, Some(Prompt::Jump("42".into())));
    update(&mut s, Action::Enter);
    assert_eq!((s.frame, s.prompt.clone()), (42, None));
    update(&mut s, Action::Open);
    for c in "nope.csv".chars() {
        update(&mut s, Action::Char(c));
    }
    assert_eq!(
        update(&mut s, Action::Enter),
        vec![Effect::Load(2, "nope.csv".into())]
    );
    update(&mut s, Action::Help);
    update(&mut s, Action::Escape);
    assert!(!s.help && !s.quit);
    update(&mut s, Action::Escape);
    assert!(s.quit);
}

/// The screen as text, one line per row.
fn screen(s: &State, w: u16, h: u16) -> String {
    let mut t = Terminal::new(TestBackend::new(w, h)).unwrap();
    t.draw(|f| view::draw(f, s)).unwrap();
    let buf = t.backend().buffer().clone();
    (0..h)
        .map(|y| {
            (0..w)
                .map(|x| buf[(x, y)].symbol().to_string())
                .collect::<String>()
                .trim_end()
                .to_string()
        })
        .collect::<Vec<_>>()
        .join("\n")
        + "\n"
}

fn assert_screen(got: &str, name: &str) {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("snapshots")
        .join(name);
    if update_snapshots() {
        std::fs::write(&p, got).unwrap();
        return;
    }
    let want = std::fs::read_to_string(&p).unwrap_or_else(|_| {
        panic!(
            "missing {}: run with UPDATE_SNAPSHOTS=1 and review",
            p.display()
        )
    });
    assert_eq!(got, want, "screen differs from {}", p.display());
}

fn computed_state(settings: Settings) -> State {
    let mut s = state();
    s.settings = settings.clone();
    s.request = 1;
    let mut engine = Engine::new(builtin_sequence().unwrap());
    update(
        &mut s,
        Action::Computed(Box::new(engine.compute(1, &settings).unwrap())),
    );
    let rows = engine.curves(&settings, &mut || false).unwrap().unwrap();
    update(&mut s, Action::Curves(1, rows));
    s.frame = 150;
    s
}

#[test]
fn main_screens_match_their_reviewed_snapshots() {
    let mut s = computed_state(Settings::default());
    assert_screen(&screen(&s, 80, 24), "tui_main_80x24.txt");
    assert_screen(&screen(&s, 120, 40), "tui_main_120x40.txt");
    s.split = true;
    assert_screen(&screen(&s, 100, 30), "tui_split_100x30.txt");
    s.split = false;
    s.help = true;
    assert_screen(&screen(&s, 80, 24), "tui_help_80x24.txt");
    assert_screen(&screen(&s, 120, 40), "tui_help_120x40.txt");
    s.help = false;
    update(
        &mut s,
        Action::Failed(
            1,
            "tests/nope.csv: No such file or directory (os error 2)".into(),
        ),
    );
    assert_screen(&screen(&s, 80, 24), "tui_error_80x24.txt");
    assert_screen(&screen(&s, 60, 20), "tui_tiny_60x20.txt");
}

struct Script(std::collections::VecDeque<crossterm::event::Event>, usize);

impl Events for Script {
    fn next(&mut self, timeout: Duration) -> std::io::Result<Option<crossterm::event::Event>> {
        // Idle polls first, so the worker's results arrive before the keys.
        if self.1 > 0 {
            self.1 -= 1;
            std::thread::sleep(timeout);
            return Ok(None);
        }
        self.1 = 3;
        Ok(self.0.pop_front())
    }
}

#[test]
fn the_generic_loop_runs_on_a_test_backend_with_scripted_keys() {
    use crossterm::event::{Event, KeyCode, KeyEvent, KeyModifiers};
    let key = |c: KeyCode| Event::Key(KeyEvent::new(c, KeyModifiers::NONE));
    let mut script = Script(
        [
            key(KeyCode::Right),
            key(KeyCode::Right),
            key(KeyCode::Char('+')),
            key(KeyCode::Char('s')),
            key(KeyCode::Char('q')),
        ]
        .into(),
        40,
    );
    let seq = builtin_sequence().unwrap();
    let mut s = State::new(&seq.source, seq.n_frames(), 30.0);
    let (jobs, results) = crate::compute::spawn(seq, None);
    let mut t = Terminal::new(TestBackend::new(100, 30)).unwrap();
    crate::run_loop(&mut t, &mut script, &mut s, &jobs, &results, "builtin").unwrap();
    assert!(s.quit);
    assert_eq!(s.frame, 2);
    assert_eq!(s.settings.k, 13);
    assert_eq!(s.settings.solver, keyshape_core::solve::Solver::Ls);
}
