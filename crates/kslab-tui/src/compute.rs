//! The worker thread: every solve runs here, off the UI thread. A newer request supersedes
//! an older one (queued requests are skipped, and the error curves of a superseded request
//! are abandoned between methods).

pub use super::request::{Computed, Settings, SolverView};
use super::state::Action;
use keyshape_core::decompose::{prepare, PrepareOptions, Prepared};
use keyshape_core::error::{Error, Result};
use keyshape_core::keyshapes::curves::sweep;
use keyshape_core::keyshapes::{axes_needed, Analysis, KeyOptions, Method};
use keyshape_core::rbf::Rbf;
use keyshape_core::sequence::Sequence;
use keyshape_core::solve::temporal::{segments, SmoothMode, Smoothing};
use keyshape_core::solve::Solver;
use keyshape_io::{builtin_sequence, read_sequence, ReadOptions};
use keyshape_retarget::setup::{builtin_target, polylines_for};
use keyshape_retarget::target::TargetSet;
use keyshape_retarget::{KeyPlan, RetargetParams, Target};
use nalgebra::DMatrix;
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::mpsc::{channel, Receiver, Sender, TryRecvError};
use std::time::Instant;

struct Cached {
    prep: Prepared,
    an: Analysis,
    warp: Rbf,
    truth: DMatrix<f64>,
    lines: Vec<Vec<usize>>,
}

/// The worker's side: the sequence, an optional user target, and what it has prepared per
/// point group.
pub struct Engine {
    seq: Sequence,
    target: Option<TargetSet>,
    cache: HashMap<String, Cached>,
    /// The key plan and target of the last request shown, for its split view.
    plan: Option<(u64, Settings, KeyPlan, Target)>,
}

impl Engine {
    /// An engine over a sequence (with the built-in target).
    pub fn new(seq: Sequence) -> Engine {
        Engine {
            seq,
            target: None,
            cache: HashMap::new(),
            plan: None,
        }
    }

    /// An engine whose target key shapes come from a target set: its frames become the key
    /// frames (the artist drew those), so the method and k settings do not apply.
    pub fn with_target(seq: Sequence, target: TargetSet) -> Engine {
        Engine {
            seq,
            target: Some(target),
            cache: HashMap::new(),
            plan: None,
        }
    }

    /// The sequence.
    pub fn sequence(&self) -> &Sequence {
        &self.seq
    }

    fn cached(&mut self, points: &str) -> Result<&Cached> {
        if !self.cache.contains_key(points) {
            let sel = if points == "all" {
                None
            } else {
                Some(points.to_string())
            };
            let prep = prepare(
                &self.seq,
                &PrepareOptions {
                    points: sel,
                    align: true,
                },
            )?;
            let an = Analysis::with_axes(
                prep.seq.coords.clone(),
                prep.seq.points,
                axes_needed(&Method::ALL, 64),
            )?;
            let (warp, _) = builtin_target(&self.seq, &prep)?;
            let truth = warp.apply_all(&prep.seq.coords);
            let lines = prep
                .layout
                .as_ref()
                .map(|l| polylines_for(l, &prep.point_indices))
                .unwrap_or_default();
            self.cache.insert(
                points.to_string(),
                Cached {
                    prep,
                    an,
                    warp,
                    truth,
                    lines,
                },
            );
        }
        self.cache
            .get(points)
            .ok_or_else(|| Error::invalid("cache"))
    }

    /// A whole request: keys, and weights, reconstructions and targets for the chosen
    /// solver and for LS and NNLS (the split view) — [`Engine::compute_shown`] then
    /// [`Engine::split_views`].
    pub fn compute(&mut self, id: u64, settings: &Settings) -> Result<Computed> {
        let mut c = self.compute_shown(id, settings)?;
        let rest = self.split_views(id)?;
        c.views.extend(rest);
        Ok(c)
    }

    /// What the screen shows first: keys, and the chosen solver's weights,
    /// reconstructions and targets. The split view's other solvers follow from
    /// [`Engine::split_views`] (the worker sends them in the background).
    pub fn compute_shown(&mut self, id: u64, settings: &Settings) -> Result<Computed> {
        let t0 = Instant::now();
        let user_target = self.target.clone();
        let c = self.cached(&settings.points)?;
        let opts = KeyOptions {
            solver: settings.solver,
            ..KeyOptions::default()
        };
        let mut shapes = None;
        let (keys, target) = match &user_target {
            None => {
                let k = if settings.method == Method::Hull {
                    0
                } else {
                    settings.k.min(c.an.distinct)
                };
                let sel = settings.method.heuristic(&opts).select(&c.an, k)?;
                // kmeansN-mean: the key shapes are cluster means; the timeline marks the
                // frames nearest the centres.
                shapes = sel.shapes;
                (
                    sel.columns,
                    Target::Warp {
                        g: c.warp.clone(),
                        trace_noise: 0.0,
                    },
                )
            }
            Some(set) => {
                let frames: Vec<i64> = set.keys.iter().map(|k| k.frame).collect();
                let keys = frames
                    .iter()
                    .map(|&f| c.prep.seq.column_of_frame(f))
                    .collect::<Result<Vec<_>>>()?;
                if set.points != c.prep.seq.points || set.dims != c.prep.seq.dims {
                    return Err(Error::invalid(format!(
                        "the target has {} points, the '{}' selection {}: choose the group the target was drawn for (g)",
                        set.points, settings.points, c.prep.seq.points
                    )));
                }
                let neutral = set
                    .neutral
                    .as_ref()
                    .map(|n| nalgebra::DVector::from_vec(n.coords.clone()));
                (
                    keys,
                    Target::Shapes {
                        keys: set.for_frames(&frames)?,
                        neutral,
                    },
                )
            }
        };
        let plan = match shapes {
            Some(m) => KeyPlan::Shapes(m),
            None => KeyPlan::Global(keys.clone()),
        };
        let view = solver_view(c, settings, &plan, &target, settings.solver)?;
        let views = vec![view];
        let coords = &c.prep.seq.coords;
        let dims = c.prep.seq.dims;
        let out = Computed {
            id,
            settings: settings.clone(),
            frames: c.prep.seq.frames.clone(),
            keys,
            dims,
            polylines: c.lines.clone(),
            tracked: coords.clone(),
            truth: if user_target.is_some() {
                views_target(&views)
            } else {
                c.truth.clone()
            },
            views,
            seconds: t0.elapsed().as_secs_f64(),
            head: c.prep.head.clone(),
        };
        self.plan = Some((id, settings.clone(), plan, target));
        Ok(out)
    }

    /// The split view's solvers (LS and NNLS, less the one shown) for request `id`, which
    /// must be the last [`Engine::compute_shown`].
    pub fn split_views(&mut self, id: u64) -> Result<Vec<SolverView>> {
        let Some((pid, settings, plan, target)) = self.plan.take() else {
            return Err(Error::invalid("split view: no request shown"));
        };
        if pid != id {
            return Err(Error::invalid("split view: a newer request was shown"));
        }
        let c = self.cached(&settings.points)?;
        let mut views = Vec::new();
        for s in [Solver::Ls, Solver::Nnls] {
            if s != settings.solver {
                views.push(solver_view(c, &settings, &plan, &target, s)?);
            }
        }
        self.plan = Some((pid, settings, plan, target));
        Ok(views)
    }

    /// The error curves of every method for a request's points and solver, k = 2..24;
    /// `abandon` is asked between methods.
    pub fn curves(
        &mut self,
        settings: &Settings,
        abandon: &mut dyn FnMut() -> bool,
    ) -> Result<Option<Vec<keyshape_core::keyshapes::curves::CurveRow>>> {
        let c = self.cached(&settings.points)?;
        let hi = 24.min(c.an.distinct);
        let mut rows = Vec::new();
        for m in Method::ALL {
            if abandon() {
                return Ok(None);
            }
            let opts = KeyOptions {
                solver: settings.solver,
                ..KeyOptions::default()
            };
            rows.extend(sweep(
                &c.an,
                &[m],
                2.min(hi)..=hi,
                &[settings.solver],
                &opts,
                &|_, _| {},
            )?);
        }
        Ok(Some(rows))
    }
}

/// With a user target there is no ground truth: the chosen solver's target stands in.
fn views_target(views: &[SolverView]) -> DMatrix<f64> {
    views
        .first()
        .map(|v| v.target.clone())
        .unwrap_or_else(|| DMatrix::zeros(0, 0))
}

/// Requests to the worker.
#[derive(Debug, Clone)]
pub enum Job {
    /// Compute with these settings.
    Compute(u64, Settings),
    /// Load a sequence from a path.
    Load(u64, String),
    /// Panics in the worker: how the tests check that a failing job cannot kill it. It
    /// exists in test builds only.
    #[cfg(test)]
    Crash(u64),
}

/// One solver's weights, reconstructions and targets for a request.
fn solver_view(
    c: &Cached,
    settings: &Settings,
    plan: &KeyPlan,
    target: &Target,
    s: Solver,
) -> Result<SolverView> {
    let coords = &c.prep.seq.coords;
    let dims = c.prep.seq.dims;
    let segs = segments(&c.prep.seq.frames, c.prep.seq.segments.as_deref());
    let smoothing = Smoothing {
        lambda: settings.smooth,
        order: 1,
        mode: SmoothMode::Offline,
    };
    let r = RetargetParams::new(plan, target, s)
        .truth(&c.truth)
        .smoothed(&smoothing, &segs)
        .run(coords, dims)?;
    if r.unconverged > 0 {
        return Err(Error::invalid(format!(
            "the {s} solve did not settle (λ {}): lower λ (L)",
            settings.smooth
        )));
    }
    let points = r.target.nrows() / dims.max(1);
    let target_jitter = keyshape_core::solve::jitter::jitter(&r.target, &segs, points.max(1));
    Ok(SolverView {
        target_jitter,
        solver: s,
        frame_rms: r
            .source_sq
            .iter()
            .map(|e| (e / r.points as f64).sqrt())
            .collect(),
        frame_target_rms: r.target_rms_per_frame().unwrap_or_default(),
        source_rms: r.source_rms(),
        target_rms: r.target_rms().unwrap_or(f64::NAN),
        jitter: keyshape_core::solve::jitter::weight_jitter_all(&r.weights, &segs),
        weights: r
            .weights
            .into_iter()
            .next()
            .unwrap_or_else(|| DMatrix::zeros(0, 0)),
        recon: r.source,
        target: r.target,
    })
}

/// Loads a sequence for the lab (`builtin` or a path).
pub fn load(path: &str) -> Result<Sequence> {
    if path.trim().is_empty() || path.trim() == "builtin" {
        return builtin_sequence();
    }
    read_sequence(&PathBuf::from(path.trim()), &ReadOptions::default())
}

/// The worker thread's name: the lab's panic hook leaves the terminal alone for panics
/// there (they are caught and shown in the status line).
pub const WORKER_THREAD: &str = "kslab-worker";

/// Starts the worker thread; results come back as [`Action`]s. A job that panics is
/// reported as [`Action::Failed`] and the worker goes on with the next job. (The binary
/// starts it through [`spawn_lab`]; the tests through this.)
#[cfg(test)]
pub fn spawn(seq: Sequence, target: Option<TargetSet>) -> (Sender<Job>, Receiver<Action>) {
    spawn_with_rig(seq, target, None)
}

/// [`spawn`], with the lab's `--rig`: every sequence loaded later (`o`) is solved onto it
/// too, answered by [`Action::RigSolved`] after its [`Action::Loaded`].
#[cfg(test)]
pub fn spawn_with_rig(
    seq: Sequence,
    target: Option<TargetSet>,
    rig: Option<std::sync::Arc<keyshape_rig::correspondence::RigSource>>,
) -> (Sender<Job>, Receiver<Action>) {
    spawn_lab(seq, target, rig, None)
}

/// What the lab says about a sequence in normalised 0–1 image coordinates (MediaPipe's
/// default), or None for one in pixels.
pub fn normalised_note(seq: &Sequence) -> Option<String> {
    seq.is_normalised().then(|| {
        "normalised 0-1 coordinates: errors are fractions of the image; start the lab with --image-size WxH for pixels".to_string()
    })
}

/// Reads `path` as [`load`] does; a track in normalised coordinates is scaled to pixels of
/// `image_size` (width, height) when given. A track already in pixels is read as it is.
pub fn load_sized(path: &str, image_size: Option<(f64, f64)>) -> Result<Sequence> {
    let mut seq = load(path)?;
    if let Some((w, h)) = image_size.filter(|_| seq.is_normalised()) {
        seq.scale_to_image(w, h)?;
    }
    Ok(seq)
}

/// [`spawn_with_rig`], with the lab's `--image-size`: every normalised sequence opened with
/// `o` is scaled to it; one left normalised is answered by an [`Action::Notice`].
pub fn spawn_lab(
    seq: Sequence,
    target: Option<TargetSet>,
    rig: Option<std::sync::Arc<keyshape_rig::correspondence::RigSource>>,
    image_size: Option<(f64, f64)>,
) -> (Sender<Job>, Receiver<Action>) {
    let (jobs_tx, jobs_rx) = channel::<Job>();
    let (out_tx, out_rx) = channel::<Action>();
    // The rig solves on a thread of its own, the first track at once.
    let rig_jobs = rig.as_ref().map(|r| {
        super::rig_worker::spawn(r.clone(), std::sync::Arc::new(seq.clone()), out_tx.clone())
    });
    let worker = std::thread::Builder::new().name(WORKER_THREAD.into());
    let run = move || {
        let mut engine = match target {
            Some(t) => Engine::with_target(seq, t),
            None => Engine::new(seq),
        };
        let mut pending: Option<Job> = None;
        // The λ the rig view was last solved with (a load solves it with 0).
        let mut rig_smooth = 0.0;
        loop {
            let job = match pending.take() {
                Some(j) => j,
                None => match jobs_rx.recv() {
                    Ok(j) => j,
                    Err(_) => return,
                },
            };
            // Skip to the newest queued job.
            let mut job = job;
            while let Ok(j) = jobs_rx.try_recv() {
                job = j;
            }
            // A panic in a job must not kill the worker: it becomes this job's error and the
            // worker takes the next job (the engine is replaced only by a completed load).
            let id = match &job {
                Job::Compute(id, _) | Job::Load(id, _) => *id,
                #[cfg(test)]
                Job::Crash(id) => *id,
            };
            let step = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| match job {
                // The one deliberate panic: the tests' way to check the worker survives one.
                #[cfg(test)]
                #[allow(clippy::panic)]
                Job::Crash(id) => panic!("job {id} crashed on purpose"),
                Job::Load(id, path) => match load_sized(&path, image_size) {
                    Ok(seq) => {
                        let note = normalised_note(&seq);
                        let fps = seq.fps().unwrap_or(30.0);
                        let (name, n) = (seq.source.clone(), seq.n_frames());
                        rig_smooth = 0.0;
                        let for_rig = rig_jobs.as_ref().map(|_| std::sync::Arc::new(seq.clone()));
                        engine = Engine::new(seq);
                        let _ = out_tx.send(Action::Loaded(id, name, n, fps));
                        if let Some(note) = note {
                            let _ = out_tx.send(Action::Notice(id, note));
                        }
                        // Only after Loaded: the rig's answer (which can come at once, for a
                        // track it refuses) must find the lab on this track.
                        if let (Some(r), Some(seq)) = (&rig_jobs, for_rig) {
                            let _ = r.send(super::rig_worker::RigJob::Load(id, seq));
                        }
                    }
                    Err(e) => {
                        let _ = out_tx.send(Action::Failed(id, e.to_string()));
                    }
                },
                Job::Compute(id, settings) => {
                    // What the screen shows first; the split view's solvers and the error
                    // curves follow, each abandoned for a newer request.
                    match engine.compute_shown(id, &settings) {
                        Ok(c) => {
                            let _ = out_tx.send(Action::Computed(Box::new(c)));
                        }
                        Err(e) => {
                            let _ = out_tx.send(Action::Failed(id, e.to_string()));
                            return;
                        }
                    }
                    // `l` / `L` also steer the rig view: its offline temporal prior.
                    let lambda = settings.smooth.min(super::rig::RIG_SMOOTH_MAX);
                    if let Some(r) = rig_jobs.as_ref().filter(|_| lambda != rig_smooth) {
                        rig_smooth = lambda;
                        let _ = r.send(super::rig_worker::RigJob::Smooth(id, lambda));
                    }
                    let mut abandon = || match jobs_rx.try_recv() {
                        Ok(j) => {
                            pending = Some(j);
                            true
                        }
                        Err(TryRecvError::Empty) => false,
                        Err(TryRecvError::Disconnected) => true,
                    };
                    if abandon() {
                        return;
                    }
                    match engine.split_views(id) {
                        Ok(v) => {
                            let _ = out_tx.send(Action::SplitViews(id, v));
                        }
                        Err(e) => {
                            let _ = out_tx.send(Action::Failed(id, e.to_string()));
                            return;
                        }
                    }
                    match engine.curves(&settings, &mut abandon) {
                        Ok(Some(rows)) => {
                            let _ = out_tx.send(Action::Curves(id, rows));
                        }
                        Ok(None) => {}
                        Err(e) => {
                            let _ = out_tx.send(Action::Failed(id, e.to_string()));
                        }
                    }
                }
            }));
            if let Err(payload) = step {
                let msg = payload
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| payload.downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "unknown cause".into());
                let _ = out_tx.send(Action::Failed(
                    id,
                    format!("internal error (please report): {msg}"),
                ));
            }
        }
    };
    if let Err(e) = worker.spawn(run) {
        let (tx, rx) = channel::<Action>();
        let _ = tx.send(Action::Failed(0, format!("cannot start the worker: {e}")));
        return (jobs_tx, rx);
    }
    (jobs_tx, out_rx)
}
