//! The lab's state and its pure update function: actions in, state changes and effects
//! out. Nothing here draws or computes; tests drive it without a terminal.

pub use super::request::{Computed, Settings, SMOOTH_STEPS};
use keyshape_core::keyshapes::curves::CurveRow;
use keyshape_core::keyshapes::Method;
use keyshape_core::solve::Solver;
use std::time::Duration;

/// Point groups the `g` key cycles through.
pub const GROUPS: [&str; 5] = ["lips", "all", "eyes", "brows", "eyes,brows"];

/// Everything the user or the worker can do to the state.
#[derive(Debug, Clone)]
pub enum Action {
    /// Leave.
    Quit,
    /// Space: play or pause.
    TogglePlay,
    /// ← / →: step frames.
    Step(i64),
    /// Home.
    First,
    /// End.
    Last,
    /// ] faster, [ slower.
    Speed(bool),
    /// m / M: next / previous method.
    Method(bool),
    /// + / −.
    K(i64),
    /// g: next point group.
    Group,
    /// s: next solver.
    Solver,
    /// l / L: stronger / weaker temporal prior (λ in decades, off at the bottom).
    Smooth(bool),
    /// v: LS against NNLS side by side.
    Split,
    /// ?: help.
    Help,
    /// e: export.
    Export,
    /// o: open a file (prompt).
    Open,
    /// x: the transferred 3-D mesh in place of the 2-D target (with `--mesh`).
    Mesh,
    /// r: the track solved onto the rig (with `--rig`) in place of the two top panels.
    Rig,
    /// A digit starts a frame-number prompt; other characters go to an open prompt.
    Char(char),
    /// Enter in a prompt.
    Enter,
    /// Backspace in a prompt.
    Backspace,
    /// Esc: close a prompt or help, else quit.
    Escape,
    /// Time passed (playback).
    Tick(Duration),
    /// Seek to a fraction of the sequence (timeline click).
    Seek(f64),
    /// Choose a method and k (a click on the error chart).
    Pick(Method, usize),
    /// The worker finished a request.
    Computed(Box<Computed>),
    /// The worker finished the error curves of a request.
    Curves(u64, Vec<CurveRow>),
    /// The worker failed a request.
    Failed(u64, String),
    /// A new sequence was loaded (name, frames, fps).
    Loaded(u64, String, usize, f64),
    /// The split view's other solvers for a request already shown.
    SplitViews(u64, Vec<super::request::SolverView>),
    /// Something the user should know about the sequence of a load (its coordinates are
    /// normalised …), shown in the status line while that sequence is loaded.
    Notice(u64, String),
    /// The loaded sequence solved onto the lab's `--rig`, or why it could not be.
    RigSolved(u64, Result<std::sync::Arc<super::rig::RigView>, String>),
    /// The rig solved again for a request's temporal prior λ (`l` / `L`).
    RigSmoothed(u64, Result<std::sync::Arc<super::rig::RigView>, String>),
    /// A preview of a loaded sequence's rig solve: one frame solved alone, before the take
    /// (`rig_preview`); the take's [`Action::RigSolved`] replaces it.
    RigPreview(u64, std::sync::Arc<super::rig::RigView>),
    /// The rig's worker started a step of a request's solve (named for the screen).
    RigStep(u64, String),
}

/// Side effects for the loop to carry out.
#[derive(Debug, Clone, PartialEq)]
pub enum Effect {
    /// Recompute with these settings; the id supersedes earlier ones.
    Compute(u64, Settings),
    /// Load another sequence.
    Load(u64, String),
    /// Write the exports.
    Export,
}

/// An open text prompt.
#[derive(Debug, Clone, PartialEq)]
pub enum Prompt {
    /// Jump to a frame number.
    Jump(String),
    /// Open a file.
    Open(String),
}

/// The whole UI state.
#[derive(Debug)]
pub struct State {
    /// Sequence name.
    pub source: String,
    /// `e` export: re-apply the head motion alignment removed (pose columns in the CSV, the
    /// picture in image coordinates), or keep aligned coordinates (`kslab tui --head-motion`).
    pub export_head_motion: bool,
    /// Valid frames.
    pub frames: usize,
    /// Frames per second of the sequence.
    pub fps: f64,
    /// Current frame (column).
    pub frame: usize,
    /// Playing.
    pub playing: bool,
    /// Playback speed factor.
    pub speed: f64,
    /// Current settings.
    pub settings: Settings,
    /// LS against NNLS view.
    pub split: bool,
    /// Help shown.
    pub help: bool,
    /// Open prompt.
    pub prompt: Option<Prompt>,
    /// Status line (errors, exports).
    pub status: String,
    /// The sequence is in normalised 0–1 image coordinates: the header says so for as
    /// long as it is open (the status line's note is replaced by the next message).
    pub normalised: bool,
    /// Id of the newest request; results of older ones are dropped.
    pub request: u64,
    /// A request is running.
    pub busy: bool,
    /// The curves are still being computed.
    pub curves_busy: bool,
    /// Latest result.
    pub computed: Option<Computed>,
    /// Latest curves.
    pub curves: Option<Vec<CurveRow>>,
    /// Leave the loop.
    pub quit: bool,
    /// Ticks seen (animates the spinner).
    pub ticks: u64,
    /// The transferred mesh per frame (`kslab tui --mesh`).
    pub mesh: Option<std::sync::Arc<super::mesh::MeshView>>,
    /// Show the mesh in the target panel.
    pub show_mesh: bool,
    /// The track solved onto a rig (`kslab tui --rig`).
    pub rig: Option<std::sync::Arc<super::rig::RigView>>,
    /// Show the rig view (track + posed rig, named weights) in place of the two top panels.
    pub show_rig: bool,
    /// The step the rig's worker is on (`None` when it is idle or there is no rig).
    pub rig_step: Option<String>,
    /// The request id of the sequence loaded last (its rig solve answers to it).
    pub loaded: u64,
    /// The key frames come from a user target set (`kslab tui --target`), not a method.
    pub target_keys: bool,
    clock: f64,
}

impl State {
    /// A fresh state; call [`State::start`] for the first computation.
    pub fn new(source: &str, frames: usize, fps: f64) -> State {
        State {
            source: source.into(),
            export_head_motion: true,
            frames,
            fps,
            frame: 0,
            playing: false,
            speed: 1.0,
            settings: Settings::default(),
            split: false,
            help: false,
            prompt: None,
            status: String::new(),
            normalised: false,
            request: 0,
            busy: false,
            curves_busy: false,
            computed: None,
            curves: None,
            quit: false,
            ticks: 0,
            mesh: None,
            show_mesh: false,
            rig: None,
            show_rig: false,
            rig_step: None,
            loaded: 0,
            target_keys: false,
            clock: 0.0,
        }
    }

    /// The first computation.
    pub fn start(&mut self) -> Vec<Effect> {
        self.recompute()
    }

    fn recompute(&mut self) -> Vec<Effect> {
        self.request += 1;
        self.busy = true;
        self.curves_busy = true;
        vec![Effect::Compute(self.request, self.settings.clone())]
    }
}

const METHODS: [Method; 8] = Method::ALL;

/// Applies an action; returns the effects the loop must carry out.
pub fn update(s: &mut State, action: Action) -> Vec<Effect> {
    if let Some(p) = s.prompt.clone() {
        return prompt(s, p, action);
    }
    match action {
        Action::Quit
        | Action::Escape
        | Action::Help
        | Action::TogglePlay
        | Action::Step(_)
        | Action::First
        | Action::Last
        | Action::Speed(_)
        | Action::Seek(_)
        | Action::Tick(_) => {
            playback(s, action);
            vec![]
        }
        Action::Method(_)
        | Action::K(_)
        | Action::Group
        | Action::Solver
        | Action::Smooth(_)
        | Action::Pick(..) => change_setting(s, action),
        Action::Split
        | Action::Mesh
        | Action::Rig
        | Action::Export
        | Action::Open
        | Action::Char(_)
        | Action::Enter
        | Action::Backspace => view_or_prompt(s, action),
        Action::Computed(_)
        | Action::Curves(..)
        | Action::Failed(..)
        | Action::Loaded(..)
        | Action::SplitViews(..)
        | Action::Notice(..)
        | Action::RigStep(..)
        | Action::RigSmoothed(..)
        | Action::RigPreview(..)
        | Action::RigSolved(..) => answer(s, action),
    }
}

/// Quitting, help, and moving through the frames: play, step, seek, the clock's ticks.
fn playback(s: &mut State, action: Action) {
    let last = s.frames.saturating_sub(1);
    match action {
        Action::Quit => s.quit = true,
        Action::Escape if s.help => s.help = false,
        Action::Escape => s.quit = true,
        Action::Help => s.help = !s.help,
        Action::TogglePlay => s.playing = !s.playing,
        Action::Step(d) => {
            s.playing = false;
            s.frame = (s.frame as i64 + d).clamp(0, last as i64) as usize;
        }
        Action::First => s.frame = 0,
        Action::Last => s.frame = last,
        Action::Speed(up) => {
            s.speed = if up {
                (s.speed * 2.0).min(8.0)
            } else {
                (s.speed / 2.0).max(0.125)
            }
        }
        Action::Seek(f) => s.frame = ((f.clamp(0.0, 1.0) * last as f64).round() as usize).min(last),
        Action::Tick(_) if !s.playing => s.ticks += 1,
        Action::Tick(dt) if s.frames > 0 => {
            s.ticks += 1;
            s.clock += dt.as_secs_f64() * s.fps * s.speed;
            let steps = s.clock.floor();
            s.clock -= steps;
            s.frame = (s.frame + steps as usize) % s.frames;
        }
        Action::Tick(_) => {}
        _ => {}
    }
}

/// A setting changed (method, k, group, solver, λ, a point picked on the chart): a new
/// request, or a status line saying why it does not apply.
fn change_setting(s: &mut State, action: Action) -> Vec<Effect> {
    match action {
        Action::Method(_) | Action::K(_) | Action::Pick(..) if s.target_keys => {
            s.status = "the key frames come from --target: method and k do not apply".into();
        }
        Action::K(_) if s.settings.method == Method::Hull => {
            s.status = "the hull picks its own number of key shapes: + and - do not apply (m changes the method)".into();
        }
        Action::Method(fwd) => {
            let i = METHODS
                .iter()
                .position(|m| *m == s.settings.method)
                .unwrap_or(0);
            let n = METHODS.len();
            s.settings.method = METHODS[if fwd { (i + 1) % n } else { (i + n - 1) % n }];
            return s.recompute();
        }
        Action::K(d) => {
            let k = (s.settings.k as i64 + d).clamp(1, 64) as usize;
            if k == s.settings.k {
                return vec![];
            }
            s.settings.k = k;
            return s.recompute();
        }
        Action::Group => {
            let i = GROUPS
                .iter()
                .position(|g| *g == s.settings.points)
                .map_or(0, |i| (i + 1) % GROUPS.len());
            s.settings.points = GROUPS[i].into();
            return s.recompute();
        }
        Action::Solver => {
            s.settings.solver = match s.settings.solver {
                Solver::Nnls => Solver::Ls,
                Solver::Ls => Solver::Bounded,
                Solver::Bounded => Solver::Nnls,
            };
            return s.recompute();
        }
        Action::Smooth(up) => {
            let i = SMOOTH_STEPS
                .iter()
                .position(|l| *l >= s.settings.smooth)
                .unwrap_or(0);
            let j = if up {
                (i + 1).min(SMOOTH_STEPS.len() - 1)
            } else {
                i.saturating_sub(1)
            };
            if SMOOTH_STEPS[j] == s.settings.smooth {
                s.status = if up {
                    format!("λ is at its largest step ({})", SMOOTH_STEPS[j])
                } else {
                    "the temporal prior is already off (l turns it on)".into()
                };
                return vec![];
            }
            s.settings.smooth = SMOOTH_STEPS[j];
            return s.recompute();
        }
        Action::Pick(m, k) => {
            if m == s.settings.method && k == s.settings.k {
                return vec![];
            }
            s.settings.method = m;
            s.settings.k = k.clamp(1, 64);
            return s.recompute();
        }
        _ => {}
    }
    vec![]
}

/// The views (split, mesh, rig), the export, and the prompts a key opens.
fn view_or_prompt(s: &mut State, action: Action) -> Vec<Effect> {
    match action {
        Action::Split => s.split = !s.split,
        Action::Mesh if s.mesh.is_some() => s.show_mesh = !s.show_mesh,
        Action::Mesh => s.status = "no mesh: open the lab with --mesh M.obj".into(),
        Action::Rig if s.rig.is_some() => s.show_rig = !s.show_rig,
        Action::Rig if s.rig_step.is_some() => {
            s.status = format!(
                "the rig is still solving ({}); its view opens when done",
                s.rig_step.as_deref().unwrap_or("")
            )
        }
        Action::Rig => {
            s.status =
                "no rig: open the lab with --rig DIR (e.g. ../shared/data/ict_facekit_face)".into()
        }
        Action::Export => return vec![Effect::Export],
        Action::Open => s.prompt = Some(Prompt::Open(String::new())),
        Action::Char(c) if c.is_ascii_digit() => s.prompt = Some(Prompt::Jump(c.to_string())),
        Action::Char(_) | Action::Enter | Action::Backspace => {}
        _ => {}
    }
    vec![]
}

/// The workers' answers: taken when they answer the newest request (or the loaded
/// sequence), dropped when a newer one has superseded them.
fn answer(s: &mut State, action: Action) -> Vec<Effect> {
    match action {
        Action::Computed(c) if c.id == s.request => {
            s.busy = false;
            s.status.clear();
            s.frame = s.frame.min(c.frames.len().saturating_sub(1));
            s.computed = Some(*c);
        }
        Action::Curves(id, rows) if id == s.request => {
            s.curves_busy = false;
            s.curves = Some(rows);
        }
        Action::Failed(id, msg) if id == s.request => {
            s.busy = false;
            s.curves_busy = false;
            s.status = format!("error: {msg}");
        }
        Action::Loaded(id, name, frames, fps) if id == s.request => {
            s.loaded = id;
            s.normalised = false;
            s.source = name;
            s.frames = frames;
            s.fps = fps;
            s.frame = 0;
            s.computed = None;
            s.curves = None;
            s.mesh = None;
            s.show_mesh = false;
            // With `--rig` the worker solves the new track onto the rig next
            // (RigSolved); until then the key-shape view shows.
            s.show_rig = false;
            s.rig = None;
            s.target_keys = false;
            return s.recompute();
        }
        Action::SplitViews(id, views) => {
            if let Some(c) = s.computed.as_mut().filter(|c| c.id == id) {
                c.views.extend(views);
            }
        }
        Action::Notice(id, note) if id == s.loaded => {
            s.normalised = true;
            s.status = note;
        }
        Action::RigStep(id, step) if id == s.request || id == s.loaded => {
            s.rig_step = Some(step);
        }
        Action::RigSmoothed(id, r) => {
            s.rig_step = None;
            // Only the newest request's: an older λ's solve is dropped.
            if id == s.request {
                match r {
                    Ok(v) => s.rig = Some(v),
                    Err(e) => s.status = format!("rig: {e}"),
                }
            }
        }
        // Only for the loaded sequence, and never over its take's solve.
        Action::RigPreview(id, v) if id == s.loaded && s.rig.is_none() => {
            s.rig = Some(v);
            s.show_rig = true;
        }
        Action::RigSolved(id, r) => {
            s.rig_step = None;
            if id == s.loaded {
                match r {
                    Ok(v) => {
                        s.rig = Some(v);
                        s.show_rig = true;
                    }
                    Err(e) => {
                        s.show_rig = false;
                        s.status = format!("rig: {e}");
                    }
                }
            }
        }
        _ => {}
    }
    vec![]
}

fn prompt(s: &mut State, p: Prompt, action: Action) -> Vec<Effect> {
    let (mut text, jump) = match p {
        Prompt::Jump(t) => (t, true),
        Prompt::Open(t) => (t, false),
    };
    match action {
        Action::Escape => {
            s.prompt = None;
            return vec![];
        }
        Action::Char(c) if !jump || c.is_ascii_digit() => text.push(c),
        Action::Backspace => {
            text.pop();
        }
        Action::Enter => {
            s.prompt = None;
            if jump {
                let frames = s
                    .computed
                    .as_ref()
                    .map(|c| c.frames.clone())
                    .unwrap_or_default();
                match text
                    .parse::<i64>()
                    .ok()
                    .and_then(|f| frames.iter().position(|&x| x == f))
                {
                    Some(c) => s.frame = c,
                    None => s.status = format!("no tracked frame {text}"),
                }
                return vec![];
            }
            s.request += 1;
            s.busy = true;
            return vec![Effect::Load(s.request, text)];
        }
        // Anything else (ticks, results) passes through to the normal update.
        other => {
            s.prompt = None;
            let effects = update(s, other);
            if s.prompt.is_none() {
                s.prompt = Some(if jump {
                    Prompt::Jump(text)
                } else {
                    Prompt::Open(text)
                });
            }
            return effects;
        }
    }
    s.prompt = Some(if jump {
        Prompt::Jump(text)
    } else {
        Prompt::Open(text)
    });
    vec![]
}
