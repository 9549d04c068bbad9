//! The lab: pure update, screens on ratatui's TestBackend (text snapshots), the generic loop
//! driven by scripted keys, and the real binary in tmux.

use keyshape_io::builtin_sequence;
use kslab_tui::compute::Engine;
use kslab_tui::state::{Prompt, Settings};
use kslab_tui::{update, view, Action, Effect, Events, State};
use ratatui::backend::TestBackend;
use ratatui::Terminal;
use std::path::Path;
use std::time::Duration;

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
    if crate::experiments::update() {
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
    let (jobs, results) = kslab_tui::compute::spawn(seq, None);
    let mut t = Terminal::new(TestBackend::new(100, 30)).unwrap();
    kslab_tui::run_loop(&mut t, &mut script, &mut s, &jobs, &results, "builtin").unwrap();
    assert!(s.quit);
    assert_eq!(s.frame, 2);
    assert_eq!(s.settings.k, 13);
    assert_eq!(s.settings.solver, keyshape_core::solve::Solver::Ls);
}

/// The real binary in tmux: start, step, change k, toggle solver, quit.
#[test]
fn the_binary_runs_in_tmux() {
    use std::process::Command;
    assert!(
        Command::new("tmux").arg("-V").output().is_ok(),
        "tmux is needed for this test: install it (.ci/run does)"
    );
    let name = format!("kslab-test-{}", std::process::id());
    let tmux = |args: &[&str]| Command::new("tmux").args(args).output().unwrap();
    let bin = env!("CARGO_BIN_EXE_kslab");
    let out = tmux(&[
        "new-session",
        "-d",
        "-s",
        &name,
        "-x",
        "100",
        "-y",
        "30",
        bin,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let capture =
        || String::from_utf8_lossy(&tmux(&["capture-pane", "-t", &name, "-p"]).stdout).into_owned();
    let wait_for = |needle: &str| {
        for _ in 0..100 {
            let screen = capture();
            if screen.contains(needle) {
                return screen;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        let screen = capture();
        tmux(&["kill-session", "-t", &name]);
        panic!("'{needle}' never appeared:\n{screen}");
    };
    wait_for("key frames:");
    tmux(&["send-keys", "-t", &name, "Right", "Right", "Right"]);
    wait_for("frame 3 ");
    tmux(&["send-keys", "-t", &name, "+"]);
    wait_for("k=13");
    // k = 24: every key's frame number is in the weights panel (columns when the rows run
    // out), each once. The keys are the engine's for the same settings.
    for _ in 0..11 {
        tmux(&["send-keys", "-t", &name, "+"]);
    }
    wait_for("k=24");
    let want: std::collections::BTreeSet<String> = {
        let settings = Settings {
            k: 24,
            ..Settings::default()
        };
        let c = Engine::new(builtin_sequence().unwrap())
            .compute(1, &settings)
            .unwrap();
        c.keys.iter().map(|&k| c.frames[k].to_string()).collect()
    };
    let mut got = std::collections::BTreeSet::new();
    for _ in 0..300 {
        let screen = capture();
        let panel: Vec<String> = screen
            .lines()
            .skip_while(|l| !l.contains("key frames:"))
            .skip(1)
            // The panel's rows are the lines where it meets the panel on its left
            // ("││"); its bottom border does not. (Not "up to the first '└'": the
            // E(k) plot's axis corner can share a line with the last row.)
            .take_while(|l| l.contains("││"))
            .filter_map(|l| {
                l.rsplit_once("││")
                    .map(|(_, r)| r.trim_end_matches('│').to_string())
            })
            .collect();
        // Frame numbers are the integer tokens; weights are printed with a point.
        got = panel
            .iter()
            .flat_map(|l| l.split(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-')))
            .filter(|t| !t.is_empty() && t.chars().all(|c| c.is_ascii_digit()))
            .map(str::to_string)
            .collect();
        if got == want {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    assert_eq!(got, want, "the weights panel at k = 24:\n{}", capture());
    tmux(&["send-keys", "-t", &name, "s"]);
    let screen = wait_for("· ls ·");
    assert!(screen.contains("E(k) ls:"));
    tmux(&["send-keys", "-t", &name, "q"]);
    for _ in 0..50 {
        if !tmux(&["has-session", "-t", &name]).status.success() {
            return;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    tmux(&["kill-session", "-t", &name]);
    panic!("kslab did not quit on q");
}

#[test]
fn clicking_the_error_chart_picks_the_nearest_method_and_k() {
    let mut s = computed_state(Settings::default());
    let area = ratatui::layout::Rect::new(0, 0, 80, 24);
    let c = view::chart_area(area);
    // Bottom-right corner of the plot: the largest k, the lowest error.
    let (col, row) = (c.x + c.width - 2, c.y + c.height - 4);
    let (m, k) = view::chart_pick(area, &s, col, row).unwrap();
    assert_eq!(k, 24);
    let rows = s.curves.clone().unwrap();
    let lowest = rows
        .iter()
        .filter(|r| r.k == 24)
        .min_by(|a, b| a.rms.total_cmp(&b.rms))
        .unwrap();
    assert_eq!(m.name(), lowest.method);
    assert!(
        view::chart_pick(area, &s, 1, 1).is_none(),
        "a click outside the chart picks nothing"
    );
    let fx = update(&mut s, Action::Pick(m, k));
    assert_eq!(
        fx,
        vec![Effect::Compute(
            2,
            Settings {
                method: m,
                k,
                ..Settings::default()
            }
        )]
    );
}

/// A job that panics becomes that job's error, and the worker goes on: the next job is
/// answered (a dead worker left "computing…" spinning forever).
#[test]
fn a_panicking_job_does_not_kill_the_worker() {
    use kslab_tui::compute::{spawn, Job};
    use kslab_tui::state::Action;
    use std::time::Duration;
    let seq = builtin_sequence().unwrap();
    let (jobs, results) = spawn(seq, None);
    jobs.send(Job::Crash(7)).unwrap();
    match results.recv_timeout(Duration::from_secs(30)).unwrap() {
        Action::Failed(id, msg) => {
            assert_eq!(id, 7);
            assert!(
                msg.contains("internal error") && msg.contains("crashed on purpose"),
                "{msg}"
            );
        }
        other => panic!("expected the crash as an error, got {other:?}"),
    }
    jobs.send(Job::Load(8, "builtin".into())).unwrap();
    match results.recv_timeout(Duration::from_secs(30)).unwrap() {
        Action::Loaded(id, _, frames, _) => {
            assert_eq!(id, 8);
            assert_eq!(frames, 216);
        }
        other => panic!("the worker did not answer after a crash: {other:?}"),
    }
}

/// `e` writes head motion the way `kslab retarget --head-motion` does: with `apply` the CSV
/// carries each frame's pose (the similarity alignment removed) and the picture is drawn in
/// image coordinates; with `none`, neither. kmeansN-mean weights are named by cluster.
#[test]
fn export_applies_head_motion_or_not_and_names_mean_keys() {
    let seq = builtin_sequence().unwrap();
    let mut engine = Engine::new(seq);
    let mut s = state();
    let c = engine.compute(1, &Settings::default()).unwrap();
    let head = c.head.clone().unwrap();
    s.computed = Some(c);
    s.frame = 150;
    let dir = tempfile::tempdir().unwrap();
    let read =
        |sub: &str| std::fs::read_to_string(dir.path().join(sub).join("weights.csv")).unwrap();
    kslab_tui::export::export(&s, "builtin", &dir.path().join("apply")).unwrap();
    s.export_head_motion = false;
    kslab_tui::export::export(&s, "builtin", &dir.path().join("none")).unwrap();
    let (a, n) = (read("apply"), read("none"));
    assert!(a
        .lines()
        .next()
        .unwrap()
        .ends_with(",head_scale,head_angle_deg,head_tx,head_ty"));
    assert!(!n.contains("head_"));
    // Row of frame 150: the pose is the alignment's similarity for that frame.
    let row: Vec<f64> = a
        .lines()
        .nth(151)
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    let h = head[150];
    let pose = &row[row.len() - 4..];
    assert!((pose[0] - h.scale).abs() < 1e-9 && (pose[1] - h.angle.to_degrees()).abs() < 1e-9);
    assert!((pose[2] - h.t[0]).abs() < 1e-9 && (pose[3] - h.t[1]).abs() < 1e-9);
    assert_ne!(
        std::fs::read(dir.path().join("apply/view.png")).unwrap(),
        std::fs::read(dir.path().join("none/view.png")).unwrap(),
        "the picture follows the option"
    );
    // kmeans2-mean: weights belong to cluster means, not to frames.
    let m = Settings {
        method: keyshape_core::keyshapes::Method::parse("kmeans2-mean").unwrap(),
        ..Settings::default()
    };
    s.computed = Some(engine.compute(2, &m).unwrap());
    s.settings = m;
    kslab_tui::export::export(&s, "builtin", &dir.path().join("mean")).unwrap();
    let header = read("mean").lines().next().unwrap().to_string();
    assert!(
        header.contains(",w_mean0,") && !header.contains(",w_1"),
        "{header}"
    );
    let toml = std::fs::read_to_string(dir.path().join("mean/experiment.toml")).unwrap();
    assert!(
        toml.contains("\"kmeans2-mean\"") && !toml.contains("\n[retarget]"),
        "{toml}"
    );
}

/// `l` / `L`: λ in decades from off; each step recomputes, the weights are the library's
/// smoothed solve of the same keys, jitter falls, the header shows λ and jitter at 80
/// columns, and the export's `[smooth]` table reproduces the exported weights' errors.
#[test]
// One segment is written `&[0..t]`: a slice holding one range, as the API takes.
#[allow(clippy::single_range_in_vec_init)]
fn the_lambda_knob_smooths_the_weights_and_the_export_reproduces_them() {
    use kslab_tui::state::SMOOTH_STEPS;
    let mut s = state();
    s.start();
    assert!(
        update(&mut s, Action::Smooth(false)).is_empty(),
        "off is the bottom"
    );
    assert!(s.status.contains("already off"), "{}", s.status);
    let fx = update(&mut s, Action::Smooth(true));
    assert_eq!(
        fx,
        vec![Effect::Compute(
            2,
            Settings {
                smooth: 1.0,
                ..Settings::default()
            }
        )]
    );
    for _ in 0..20 {
        update(&mut s, Action::Smooth(true));
    }
    assert_eq!(s.settings.smooth, *SMOOTH_STEPS.last().unwrap());
    assert!(s.status.contains("largest"), "{}", s.status);
    update(&mut s, Action::Smooth(false));
    assert_eq!(s.settings.smooth, 1e5);

    let mut engine = Engine::new(builtin_sequence().unwrap());
    let plain = engine.compute(1, &Settings::default()).unwrap();
    let set = Settings {
        smooth: 1e4,
        ..Settings::default()
    };
    let smooth = engine.compute(2, &set).unwrap();
    let (p, q) = (&plain.views[0], &smooth.views[0]);
    assert!(
        q.target_jitter < 0.6 * p.target_jitter,
        "{} {}",
        q.target_jitter,
        p.target_jitter
    );
    assert!(q.source_rms > p.source_rms);
    // The same keys through the library's smoothed solve.
    let prep = keyshape_core::decompose::prepare(
        &builtin_sequence().unwrap(),
        &keyshape_core::decompose::PrepareOptions::group_aligned("lips"),
    )
    .unwrap();
    let sk = prep.seq.coords.select_columns(&smooth.keys);
    let r = keyshape_core::solve::temporal::solve_smooth(
        &sk,
        &prep.seq.coords,
        keyshape_core::solve::Solver::Nnls,
        &keyshape_core::solve::temporal::Smoothing {
            lambda: 1e4,
            order: 1,
            mode: keyshape_core::solve::temporal::SmoothMode::Offline,
        },
        &[0..prep.seq.coords.ncols()],
    )
    .unwrap();
    assert!((&r.weights - &q.weights).amax() < 1e-12);

    let mut t = state();
    t.settings = set.clone();
    t.request = 2;
    update(&mut t, Action::Computed(Box::new(smooth.clone())));
    let head = screen(&t, 80, 24).lines().next().unwrap().to_string();
    for part in [
        "nnls λ=1e4",
        "frame 0",
        "spread k=12",
        &format!("err {:.2} jit {:.2}", q.target_rms, q.target_jitter),
    ] {
        assert!(head.contains(part), "{part} not in {head:?}");
    }
    let dir = tempfile::tempdir().unwrap();
    kslab_tui::export::export(&t, "builtin", dir.path()).unwrap();
    let out = dir.path().join("run");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_kslab"))
        .args(["run", dir.path().join("experiment.toml").to_str().unwrap()])
        .args(["--out", out.to_str().unwrap(), "-q"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_to_string(out.join("smoothing.csv")).unwrap();
    let row: Vec<f64> = csv
        .lines()
        .find(|l| l.starts_with("prior offline order 1,λ 10000,"))
        .unwrap()
        .split(',')
        .skip(2)
        .take(4)
        .map(|v| v.parse().unwrap())
        .collect();
    // source RMS, target RMS against G(q), …, target-point jitter.
    assert!(
        (row[0] - q.source_rms).abs() < 1e-9,
        "{row:?} {}",
        q.source_rms
    );
    assert!(
        (row[1] - q.target_rms).abs() < 1e-9,
        "{row:?} {}",
        q.target_rms
    );
    assert!(
        (row[3] - q.target_jitter).abs() < 1e-9,
        "{row:?} {}",
        q.target_jitter
    );
}

/// Keys that cannot apply say why instead of recomputing; the hull's k is the one it
/// picked; a long path in the prompt shows its end.
#[test]
fn keys_that_do_not_apply_say_why_and_the_hull_shows_its_k() {
    let mut s = state();
    s.start();
    s.target_keys = true;
    for a in [
        Action::Method(true),
        Action::K(1),
        Action::Pick(keyshape_core::keyshapes::Method::Random, 5),
    ] {
        s.status.clear();
        assert!(update(&mut s, a).is_empty());
        assert!(s.status.contains("come from --target"), "{}", s.status);
    }
    assert_eq!(s.settings, Settings::default());
    let hull = Settings {
        method: keyshape_core::keyshapes::Method::Hull,
        ..Settings::default()
    };
    let mut h = computed_state(hull.clone());
    assert!(update(&mut h, Action::K(1)).is_empty());
    assert!(h.status.contains("hull picks its own"), "{}", h.status);
    let n = h.computed.as_ref().unwrap().keys.len();
    let head = screen(&h, 80, 24).lines().next().unwrap().to_string();
    assert!(head.contains(&format!("hull k={n} (hull's own)")), "{head}");
    assert_ne!(n, 12, "the hull's k is its own, not the setting's");
    // The prompt.
    assert_eq!(view::prompt_line("ab", 10), "ab▏");
    let long = "/a/very/long/path/to/some/track.csv";
    let line = view::prompt_line(long, 12);
    assert_eq!(line, "…/track.csv▏");
    assert_eq!(line.chars().count(), 12);
}

/// `kslab tui --rig DIR` — the track solved onto the ICT rig when the lab
/// opens; `r` shows the tracked landmarks with the posed rig and the rig's weights as named
/// bars, largest first (on frame 150, the scream, jawOpen among the first). Without a rig,
/// `r` says how to get one.
#[test]
fn the_rig_view_names_the_largest_weights_and_r_toggles_it() {
    let rig =
        keyshape_rig::correspondence::RigSource::new(crate::common::shared("ict_facekit_face"));
    let view = kslab_tui::rig::rig_view(&builtin_sequence().unwrap(), &rig).unwrap();
    let mut s = computed_state(Settings::default());
    update(&mut s, Action::Rig);
    assert!(s.status.contains("open the lab with --rig"), "{}", s.status);
    s.rig = Some(std::sync::Arc::new(view.clone()));
    s.frame = 150;
    update(&mut s, Action::Rig);
    assert!(s.show_rig);
    let text = screen(&s, 80, 24);
    assert!(text.contains("track + posed rig"), "{text}");
    assert!(text.contains("of 55 active"), "{text}");
    // The bars are the frame's largest weights, in order, each with its name.
    let w = &view.weights[150];
    let mut order: Vec<usize> = (0..w.len()).collect();
    order.sort_by(|&a, &b| w[b].abs().total_cmp(&w[a].abs()).then(a.cmp(&b)));
    let first: Vec<&str> = order[..5].iter().map(|&i| view.names[i].as_str()).collect();
    assert!(first.contains(&"jawOpen"), "{first:?}");
    let pos: Vec<usize> = first
        .iter()
        .map(|n| text.find(&format!("{n} ")).unwrap())
        .collect();
    assert!(
        pos.windows(2).all(|p| p[0] < p[1]),
        "bars out of order: {first:?}"
    );
    // The lower panels describe the rig solve too: the frame's largest
    // weights and the landmark error over time, with no key-shape chart, bars or key marks.
    // (At the scream both lead: jawOpen, and the smile that stretches the mouth's corners.)
    let over = text.find("over time: ").unwrap();
    let title = &text[over..over + 60];
    assert!(
        title.contains("jawOpen") && (title.contains("mouthSmil") || title.contains("mthSml")),
        "{text}"
    );
    assert!(text.contains("landmark RMS over time"), "{text}");
    for key_shape_only in ["E(k)", "key frames", "◆"] {
        assert!(
            !text.contains(key_shape_only),
            "{key_shape_only} in\n{text}"
        );
    }
    assert_screen(&text, "tui_rig_80x24.txt");
    // `e` in the rig view exports the rig's weights on screen, not the key-shape solve's
    // (round three).
    let dir = tempfile::tempdir().unwrap();
    let files = kslab_tui::export::export(&s, "builtin", dir.path()).unwrap();
    assert!(files[0].ends_with("rig_weights.csv"), "{files:?}");
    let text_csv = std::fs::read_to_string(&files[0]).unwrap();
    let mut lines = text_csv.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(head[..2], ["frame", "rms"]);
    assert_eq!(
        head[2..],
        view.names.iter().map(String::as_str).collect::<Vec<_>>()[..]
    );
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), view.weights.len());
    let row150: Vec<f64> = rows[150]
        .split(',')
        .skip(2)
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(row150, view.weights[150]);
    assert!(std::path::Path::new(&files[1]).exists());
    update(&mut s, Action::Rig);
    assert!(!s.show_rig);
    let text = screen(&s, 80, 24);
    assert!(text.contains("key frames") && text.contains("◆"), "{text}");
}

/// In the open prompt a space is part of the path, not play / pause (`o`
/// dropped spaces from a path).
#[test]
fn a_space_in_the_open_prompt_is_part_of_the_path() {
    use crossterm::event::{KeyCode, KeyEvent, KeyModifiers};
    use kslab_tui::interpret;
    let mut s = State::new("builtin", 216, 30.0);
    let key = |c: KeyCode| KeyEvent::new(c, KeyModifiers::NONE);
    // Outside a prompt, space plays.
    assert!(matches!(
        interpret(&s, key(KeyCode::Char(' '))),
        Some(Action::TogglePlay)
    ));
    update(&mut s, Action::Open);
    for c in "my tracks/a b.csv".chars() {
        let a = interpret(&s, key(KeyCode::Char(c))).unwrap();
        update(&mut s, a);
    }
    assert!(!s.playing, "the space toggled playback");
    let effects = update(&mut s, Action::Enter);
    assert_eq!(effects.len(), 1);
    assert!(
        matches!(&effects[0], Effect::Load(_, p) if p == "my tracks/a b.csv"),
        "{effects:?}"
    );
}

/// A sequence opened with `o` in a lab started with `--rig` is solved onto the rig too
/// (the rig was forgotten), and a track the rig cannot take says why.
#[test]
fn the_rig_stays_with_the_lab_when_another_sequence_is_opened() {
    use kslab_tui::compute::{spawn_with_rig, Job};
    let rig = std::sync::Arc::new(keyshape_rig::correspondence::RigSource::new(
        crate::common::shared("ict_facekit_face"),
    ));
    let (jobs, results) = spawn_with_rig(builtin_sequence().unwrap(), None, Some(rig));
    let d18 = crate::common::shared("mediapipe_face_tracks/liveportrait_d18.csv");
    jobs.send(Job::Load(3, d18.display().to_string())).unwrap();
    let mut s = State::new("builtin", 216, 30.0);
    s.request = 3;
    // The rig solves on its own worker, each step named, until its answer to request 3.
    let mut got = Vec::new();
    let mut steps = Vec::new();
    loop {
        let a = results.recv_timeout(Duration::from_secs(60)).unwrap();
        got.push(format!("{a:?}").chars().take(12).collect::<String>());
        let done = matches!(a, Action::RigSolved(3, _));
        if let Action::RigStep(3, step) = &a {
            steps.push(step.clone());
        }
        update(&mut s, a);
        if done {
            break;
        }
    }
    assert!(
        s.rig.is_some() && s.show_rig,
        "{got:?}: the new track is not on the rig"
    );
    assert!(s.rig_step.is_none(), "{:?}", s.rig_step);
    assert!(
        steps.iter().any(|t| t.starts_with("choosing the neutral"))
            && steps.iter().any(|t| t.starts_with("solving 216 frames")),
        "{steps:?}"
    );
    // A track of no layout the rig knows: the key-shape view, and the reason.
    let d = tempfile::tempdir().unwrap();
    let plain = d.path().join("three.csv");
    std::fs::write(
        &plain,
        "frame,x0,y0,x1,y1,x2,y2\n0,0,0,1,0,0,1\n1,0,0,2,0,0,1\n",
    )
    .unwrap();
    jobs.send(Job::Load(4, plain.display().to_string()))
        .unwrap();
    s.request = 4;
    loop {
        let a = results.recv_timeout(Duration::from_secs(60)).unwrap();
        let done = matches!(a, Action::RigSolved(4, _));
        update(&mut s, a);
        if done {
            break;
        }
    }
    assert!(s.rig.is_none() && !s.show_rig);
    assert!(s.status.starts_with("rig: "), "{}", s.status);
}

/// `l` steers the rig view too: a request with λ solves the rig again with
/// the offline temporal prior at that λ — a larger λ, smoother weights — and the screen says
/// which prior it shows; an older request's rig is dropped.
#[test]
fn l_solves_the_rig_view_again_with_the_offline_prior() {
    use kslab_tui::compute::{spawn_with_rig, Job};
    let rig = std::sync::Arc::new(keyshape_rig::correspondence::RigSource::new(
        crate::common::shared("ict_facekit_face"),
    ));
    let (jobs, results) = spawn_with_rig(builtin_sequence().unwrap(), None, Some(rig.clone()));
    let plain = kslab_tui::rig::rig_view(&builtin_sequence().unwrap(), &rig).unwrap();
    let mut s = State::new("builtin", 216, 30.0);
    s.rig = Some(std::sync::Arc::new(plain.clone()));
    s.show_rig = true;
    let solve_at = |s: &mut State, presses: usize| {
        let mut last = None;
        for _ in 0..presses {
            last = update(s, Action::Smooth(true)).into_iter().next();
        }
        let Some(Effect::Compute(id, settings)) = last else {
            panic!("l asks for no computation");
        };
        jobs.send(Job::Compute(id, settings.clone())).unwrap();
        loop {
            let a = results.recv_timeout(Duration::from_secs(120)).unwrap();
            let got = match &a {
                Action::RigSmoothed(i, v) => Some((*i, v.clone().unwrap())),
                _ => None,
            };
            update(s, a);
            if let Some((i, v)) = got {
                assert_eq!(i, id);
                assert_eq!(v.smooth, settings.smooth);
                assert!(std::sync::Arc::ptr_eq(s.rig.as_ref().unwrap(), &v));
                return (id, v);
            }
        }
    };
    let jitter = |r: &kslab_tui::rig::RigView| {
        let w = nalgebra::DMatrix::from_fn(r.names.len(), r.weights.len(), |i, f| r.weights[f][i]);
        keyshape_core::solve::jitter::weight_jitter(&w, std::slice::from_ref(&(0..r.weights.len())))
    };
    let (_, v100) = solve_at(&mut s, 3);
    assert_eq!(v100.smooth, 100.0);
    assert_ne!(v100.weights, plain.weights);
    let top = screen(&s, 80, 24);
    assert!(top.contains("bounded λ100"), "{top}");
    let (id, v1000) = solve_at(&mut s, 1);
    assert!(
        jitter(&v1000) < jitter(&v100),
        "{} vs {}",
        jitter(&v1000),
        jitter(&v100)
    );
    // A rig answer for an older request is dropped.
    update(
        &mut s,
        Action::RigSmoothed(id - 1, Ok(std::sync::Arc::new(plain))),
    );
    assert!(std::sync::Arc::ptr_eq(s.rig.as_ref().unwrap(), &v1000));
}

/// The worker's first answer is what the screen shows; the split view's solvers follow and
/// join the same request, and a stale answer is dropped.
#[test]
fn the_split_view_follows_the_first_answer_and_joins_its_request() {
    let mut engine = Engine::new(builtin_sequence().unwrap());
    let mut s = State::new("builtin", 216, 30.0);
    s.request = 1;
    let shown = engine.compute_shown(1, &Settings::default()).unwrap();
    assert_eq!(shown.views.len(), 1);
    update(&mut s, Action::Computed(Box::new(shown)));
    s.split = true;
    assert!(screen(&s, 100, 30).contains("computing LS and NNLS for the split view"));
    let rest = engine.split_views(1).unwrap();
    assert_eq!(rest.len(), 1, "nnls is shown: ls follows");
    // A stale request's views are dropped.
    update(&mut s, Action::SplitViews(0, rest.clone()));
    assert_eq!(s.computed.as_ref().unwrap().views.len(), 1);
    update(&mut s, Action::SplitViews(1, rest));
    assert_eq!(s.computed.as_ref().unwrap().views.len(), 2);
    let whole = Engine::new(builtin_sequence().unwrap())
        .compute(1, &Settings::default())
        .unwrap();
    let c = s.computed.as_ref().unwrap();
    for (a, b) in c.views.iter().zip(&whole.views) {
        assert_eq!((a.solver, &a.weights), (b.solver, &b.weights));
    }
    assert!(!screen(&s, 100, 30).contains("computing LS and NNLS"));
}

/// At 80 × 24: the chart's legend names every method, the header keeps
/// a long file name, and at k ≥ 15 every key still shows its weight as a shade and a value.
#[test]
fn eighty_columns_keep_the_legend_the_file_name_and_the_weights() {
    let legend = view::legend_labels("nnls", 40);
    assert_eq!(legend.1.len(), 8);
    assert!(legend.0.chars().count() + legend.1.iter().map(|n| n.len() + 1).sum::<usize>() <= 40);
    assert_eq!(view::legend_labels("nnls", 80).0, "E(k) nnls: ");
    let mut s = computed_state(Settings {
        k: 16,
        ..Settings::default()
    });
    s.source = "/home/someone/tracks/liveportrait_d18.csv".into();
    let text = screen(&s, 80, 24);
    let header = text.lines().next().unwrap();
    // The name, shortened from the left when the settings need the room.
    assert!(header.contains("d18.csv"), "{header}");
    assert!(
        header.contains("spread k=16") && header.contains("err "),
        "{header}"
    );
    let chart_row = text.lines().find(|l| l.contains("km2m")).unwrap();
    for name in ["spr", "km2", "km3", "km2m", "km3m", "hull", "grd", "rnd"] {
        assert!(chart_row.contains(name), "{name} missing: {chart_row}");
    }
    // The weights panel: 16 keys, each with a shade and a value.
    let panel: Vec<&str> = text.lines().skip(15).take(6).collect();
    let shaded = panel
        .iter()
        .map(|l| l.split("││").nth(1).unwrap_or(""))
        .map(|l| l.chars().filter(|c| "░▒▓█".contains(*c)).count())
        .sum::<usize>();
    assert!(shaded >= 1, "no weight shown as a shade: {text}");
    // The split view's source title keeps both numbers whole ("NNLS 0.3" was cut).
    s.split = true;
    let text = screen(&s, 80, 24);
    let title = text.lines().nth(1).unwrap();
    let nnls = title.split("NNLS ").nth(1).unwrap();
    let num: String = nnls
        .chars()
        .take_while(|c| c.is_ascii_digit() || *c == '.')
        .collect();
    // Whole: three significant digits, then the border.
    let digits = num.trim_start_matches(['0', '.']).len();
    assert_eq!(digits, 3, "{title}");
    assert!(nnls[num.len()..].starts_with('─'), "{title}");
}

/// The README's and the book's picture of the lab (100×30, frame 150) is the lab's screen,
/// so it cannot drift from the code (round three: "rms 0.42" there while the lab showed
/// 0.417).
#[test]
fn the_readme_screen_is_the_labs_screen() {
    let mut s = computed_state(Settings::default());
    s.source = "builtin:liveportrait_d18".into();
    let want = screen(&s, 100, 30);
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    for doc in ["README.md", "docs/src/introduction.md"] {
        let text = std::fs::read_to_string(root.join(doc)).unwrap();
        let start = text
            .find("```text\n kslab ")
            .expect("the lab's screen block")
            + 8;
        let end = start + text[start..].find("```").unwrap();
        let got: Vec<&str> = text[start..end].lines().map(str::trim_end).collect();
        let want: Vec<&str> = want.lines().map(str::trim_end).collect();
        if std::env::var_os("UPDATE_SNAPSHOTS").is_some() && got != want[..got.len()] {
            let block = want[..got.len()].join("\n") + "\n";
            std::fs::write(
                root.join(doc),
                format!("{}{block}{}", &text[..start], &text[end..]),
            )
            .unwrap();
            continue;
        }
        assert_eq!(
            got,
            want[..got.len()],
            "{doc}: its screen block is not the lab's (UPDATE_SNAPSHOTS=1 rewrites it)"
        );
    }
}

/// The rig solves on a worker of its own, so the lab opens at once: while it solves, the
/// header names the step, `r` says the view is coming, and a new λ reuses the neutral of the
/// last solve — the same weights as a solve that searches for it again, without the search.
#[test]
fn the_rig_solves_in_the_background_and_names_its_steps() {
    let rig =
        keyshape_rig::correspondence::RigSource::new(crate::common::shared("ict_facekit_face"));
    let seq = builtin_sequence().unwrap();
    let mut s = computed_state(Settings::default());
    let (request, loaded) = (s.request, s.loaded);
    update(
        &mut s,
        Action::RigStep(
            request,
            "choosing the neutral: 48 candidate frames, each scored on 64".into(),
        ),
    );
    let text = screen(&s, 120, 30);
    assert!(text.contains("rig: choosing the neutral"), "{text}");
    update(&mut s, Action::Rig);
    assert!(
        s.status.contains("the rig is still solving"),
        "{}",
        s.status
    );
    assert!(!s.show_rig);
    // A λ with the neutral of the first solve: the same as searching again.
    let mut steps = Vec::new();
    let first =
        kslab_tui::rig::rig_view_observed(&seq, &rig, 0.0, None, &mut |t| steps.push(t)).unwrap();
    assert!(
        steps.iter().any(|t| t.starts_with("choosing the neutral")),
        "{steps:?}"
    );
    let mut again = Vec::new();
    let hinted =
        kslab_tui::rig::rig_view_observed(&seq, &rig, 100.0, first.neutral, &mut |t| again.push(t))
            .unwrap();
    assert!(
        !again.iter().any(|t| t.starts_with("choosing the neutral")),
        "{again:?}"
    );
    let searched = kslab_tui::rig::rig_view_smoothed(&seq, &rig, 100.0).unwrap();
    assert_eq!(hinted.neutral, searched.neutral);
    assert_eq!(hinted.weights, searched.weights);
    // Its answer ends the step.
    update(
        &mut s,
        Action::RigSolved(loaded, Ok(std::sync::Arc::new(first))),
    );
    assert!(s.rig_step.is_none() && s.show_rig);
}
