//! A progress bar that appears only once a job has run for more than a second (and only on
//! a terminal: indicatif draws nothing when stderr is not one), never with `--quiet`.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

static QUIET: AtomicBool = AtomicBool::new(false);

/// The bar on screen, if any: lines printed while it is drawn go through
/// [`suspend`], so that no spinner is left between them (map's stayed on screen).
static CURRENT: std::sync::Mutex<Option<(u64, ProgressBar)>> = std::sync::Mutex::new(None);
static NEXT_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// Runs `f` (which prints) with the current bar, if any, taken off the screen meanwhile.
pub fn suspend<T>(f: impl FnOnce() -> T) -> T {
    let bar = CURRENT
        .lock()
        .ok()
        .and_then(|g| g.as_ref().map(|c| c.1.clone()));
    match bar {
        Some(b) => b.suspend(f),
        None => f(),
    }
}

/// `--quiet`: no progress bar anywhere.
pub fn set_quiet(quiet: bool) {
    QUIET.store(quiet, Ordering::SeqCst);
}

pub struct Progress {
    bar: ProgressBar,
    done: Arc<AtomicBool>,
    counting: AtomicBool,
    id: u64,
}

/// While a step's size is unknown: its name, a spinner and the time so far — no `0/0` bar.
const UNSIZED: &str = "{spinner} {msg} {elapsed}";
/// A step of known size: its name, the bar, what it counts, and the time left.
const SIZED: &str = "{spinner} {msg} [{bar:30}] {pos}/{len}{prefix} {elapsed}, ETA {eta}";

impl Progress {
    /// A bar for the step `message` (e.g. `curves: reading`), drawn once it has run a second.
    pub fn new(message: &str) -> Progress {
        let quiet = QUIET.load(Ordering::SeqCst);
        let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
        bar.set_message(message.to_string());
        let done = Arc::new(AtomicBool::new(false));
        let p = Progress {
            bar,
            done,
            counting: AtomicBool::new(false),
            id: NEXT_ID.fetch_add(1, Ordering::SeqCst),
        };
        p.style(UNSIZED);
        if let Ok(mut g) = CURRENT.lock() {
            *g = Some((p.id, p.bar.clone()));
        }
        if !quiet {
            let (bar, done) = (p.bar.clone(), p.done.clone());
            std::thread::spawn(move || {
                std::thread::sleep(Duration::from_secs(1));
                if !done.load(Ordering::SeqCst) {
                    bar.set_draw_target(ProgressDrawTarget::stderr());
                    bar.enable_steady_tick(Duration::from_millis(120));
                }
            });
        }
        p
    }

    fn style(&self, template: &str) {
        if let Ok(style) = ProgressStyle::with_template(template) {
            self.bar.set_style(style.progress_chars("=> "));
        }
    }

    /// What the counts of [`Progress::tick`] are (`frames`, `curves`, `settings` …).
    pub fn units(&self, unit: &str) {
        self.bar.set_prefix(format!(" {unit}"));
    }

    /// Records `done` of `total` units of the current step.
    pub fn tick(&self, done: usize, total: usize) {
        if total == 0 {
            return;
        }
        if !self.counting.swap(true, Ordering::SeqCst) {
            self.style(SIZED);
            self.bar.reset_eta();
        }
        self.bar.set_length(total as u64);
        self.bar.set_position(done as u64);
    }

    /// Names the step now running; its size is unknown until it ticks.
    pub fn step(&self, message: &str) {
        self.bar.set_message(message.to_string());
        if self.counting.swap(false, Ordering::SeqCst) {
            self.style(UNSIZED);
            self.bar.set_prefix("");
        }
    }

    pub fn finish(&self) {
        self.done.store(true, Ordering::SeqCst);
        self.bar.finish_and_clear();
        if let Ok(mut g) = CURRENT.lock() {
            if g.as_ref().is_some_and(|c| c.0 == self.id) {
                *g = None;
            }
        }
    }
}

impl Drop for Progress {
    /// The bar disappears however the command ends (errors included).
    fn drop(&mut self) {
        self.finish();
    }
}
