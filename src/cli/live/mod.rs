//! `kslab live`: a running face tracker through the rig's causal solve to an avatar
//! (VMC, Live Link Face, CSV lines), calibrated on a neutral lead-in, recorded as it goes.

use anyhow::{Context, Result};
use clap::Args;
use keyshape_live::session::{Served, Session, Step};
use keyshape_live::sink::{Recorder, SinkSpec, Sinks};
use keyshape_live::source::{self, SourceOptions, SourceSpec};
use keyshape_live::{Counters, Queue};
use keyshape_rig::live::LiveSolver;
use keyshape_rig::RigOptions;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

mod report;
use report::{ms, report};

/// Arguments of `kslab live`.
#[derive(Debug, Args)]
pub struct LiveArgs {
    /// Where frames come from: `openseeface:[HOST:]PORT` (OpenSeeFace's UDP datagrams;
    /// default 127.0.0.1:11573), `stdin` (a table — a header line in any format the
    /// readers know, then one row per frame — or JSON lines `{"t": …, "points": [[x, y],
    /// …]}`, as a MediaPipe Face Landmarker script prints them) or `file:TRACK` (a file
    /// replayed in real time at --rate).
    #[arg(long, value_name = "SOURCE")]
    from: String,
    /// Where the weights go, comma-separated: `vmc:[HOST:]PORT` (the VMC protocol over
    /// OSC: one bundle per frame, /VMC/Ext/Blend/Val for each ARKit shape as Perfect Sync
    /// avatars name them, /VMC/Ext/Blend/Apply, the head as /VMC/Ext/Bone/Pos "Head";
    /// default 127.0.0.1:39539), `livelink:[HOST:]PORT` (Live Link Face UDP packets, the
    /// 61 values of the Live Link CSV; default 127.0.0.1:11111), `stdout` (weights CSV
    /// lines as `kslab rig` writes them, flushed per frame).
    /// [default: none; required]
    #[arg(long, value_name = "SINK[,SINK…]")]
    to: Option<String>,
    /// The rig, as for `kslab rig` [default: ict_facekit_face in the shared data folder].
    #[arg(long, value_name = "DIR|rig.glb")]
    rig: Option<PathBuf>,
    /// A `landmark,vertex` CSV naming the mesh vertex of each track point (as for `kslab
    /// rig`; required with a glTF rig).
    /// [default: the rig folder's own, as for `kslab rig`]
    #[arg(long, value_name = "CSV")]
    rig_landmarks: Option<PathBuf>,
    /// How a MediaPipe source meets the rig: `dense` (every point the rig covers) or `68`
    /// (the 68 iBUG points) [default: dense].
    #[arg(long, value_name = "dense|68", value_parser = ["dense", "68"])]
    landmarks: Option<String>,
    /// The calibration: the first N frames are the person's neutral face (look neutral),
    /// averaged as `kslab rig --neutral 0-(N-1)` averages a lead-in; their weights are
    /// solved and sent once it completes. Recalibrate with SIGUSR1 or a line `calibrate`
    /// on standard input (when it is not the source).
    #[arg(long, value_name = "N", default_value_t = 30, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    calibrate: u32,
    /// A calibration file (JSON): loaded when it exists (no lead-in is collected);
    /// otherwise written when the calibration completes (and again on each
    /// recalibration).
    /// [default: none: calibrate on the first frames, save nothing]
    #[arg(long, value_name = "FILE")]
    neutral_file: Option<PathBuf>,
    /// Record the take into this new (or empty) folder: track.csv (the input as solved,
    /// which `kslab rig` and `kslab live --from file:` read back), weights.csv and
    /// livelink.csv, each flushed per frame, so complete however the session ends.
    /// [default: not recorded]
    #[arg(long, value_name = "DIR")]
    record: Option<PathBuf>,
    /// OpenSeeFace: the face id to follow when several are tracked [default: the first
    /// seen].
    #[arg(long, value_name = "ID")]
    face: Option<i32>,
    /// A file source's frames per second [default: the file's own rate, else 30].
    #[arg(long, value_name = "FPS", value_parser = super::input::number_within(&keyshape_core::limits::LIVE_RATE))]
    rate: Option<f64>,
    /// The video's size WIDTHxHEIGHT, for normalised coordinates (MediaPipe's default)
    /// [default: the coordinates as they come].
    #[arg(long, value_name = "WxH", value_parser = super::input::parse_image_size)]
    image_size: Option<(f64, f64)>,
    /// A table source's format (mediapipe, openface, pyfeat, csv) [default: detected from
    /// the header].
    #[arg(long)]
    format: Option<keyshape_core::sequence::Format>,
    /// The causal temporal prior λ, squared pixels (each frame pulled towards the last; as
    /// `kslab rig --live --smooth`). 0 is off [default: 0.0026 × the calibration's squared
    /// inter-ocular distance, 30 px² at 107 px: tuned on `kslab rig-accuracy --live`, a lag
    /// of one frame].
    #[arg(long, value_name = "LAMBDA", allow_negative_numbers = true)]
    smooth: Option<f64>,
    /// The magnitude prior (as `kslab rig --live --prior`; tuned on the causal path, above
    /// the offline default 0.0026).
    #[arg(long, default_value_t = keyshape_rig::LIVE_PRIOR, allow_negative_numbers = true)]
    prior: f64,
    /// When the session ends, write its figures here as JSON: frames solved, received,
    /// dropped, malformed, untracked (the tracker's own fit failed), of other faces,
    /// refused, datagrams not sent, seconds, and the latency from a
    /// frame's arrival to its sending (p50, p99, worst, milliseconds) — what `kslab bench
    /// live` measures.
    /// [default: not written]
    #[arg(long, value_name = "FILE")]
    stats: Option<PathBuf>,
    /// Frames waiting between receiving and solving at most; when the solve falls behind
    /// a live source, the oldest are dropped (and counted). A file source waits instead.
    #[arg(long, value_name = "N", default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    queue: u32,
    /// Send the avatar as the person's reflection: its head turns to its right when the
    /// person turns to their left, and one-sided shapes swap sides (the person's left blink
    /// on the avatar's right eye), head and face together. By default the avatar is the
    /// person, as ARKit names the shapes. VMC and Live Link only; standard output and the
    /// recording keep the person's sides.
    #[arg(long)]
    mirror: bool,
    /// The head bone's local position VMC sends with its rotation, `X,Y,Z` in metres
    /// (Unity's axes: x the avatar's right, y up, z forward), or `none` to send no head bone.
    /// A receiver that applies bone positions (EVMC4U does by default) puts the head there
    /// relative to the neck: give your avatar's own (its Head bone's localPosition)
    /// [default: 0,0.1,0, a typical humanoid's head above its neck].
    #[arg(long, value_name = "X,Y,Z|none", value_parser = super::input::parse_head_position)]
    head_position: Option<super::input::HeadPosition>,
}

/// The rig, the frame's point selection and the source, opened and checked before
/// anything starts.
pub(crate) struct Setup {
    pub(crate) opened: source::Opened,
    pub(crate) sinks: Vec<SinkSpec>,
    pub(crate) rig: keyshape_rig::Rig,
    /// Per rig landmark, the value pair of the source frame it reads.
    pub(crate) select: Vec<usize>,
    pub(crate) name: String,
}

/// Every file `live` reads or writes, checked together before the first frame, as every
/// command's outputs are: the source file, the rig and its landmark map, a calibration to
/// load are inputs; `--record`'s three files, `--stats`, a calibration to save, and the
/// `stdout` sink (standard output) are outputs. No output may be an input or another
/// output (`--stats take/weights.csv` turned the take's weights into the stats;
/// `--neutral-file take/track.csv` replaced the recorded track), and each output's folder
/// must take files (`--stats /nonexistent/s.json` failed only after the session).
fn check_files(a: &LiveArgs, spec: &SourceSpec, sinks: &[SinkSpec]) -> Result<()> {
    // A calibration file that exists is loaded (an input); else it is written.
    let cal = a.neutral_file.as_ref();
    let cal_in = cal.filter(|p| keyshape_io::atomic::is_stdout(p) || p.exists());
    if cal_in.is_some_and(|p| keyshape_io::atomic::is_stdout(p)) {
        anyhow::bail!(
            "--neutral-file {}: a calibration is a file (standard output cannot be read back)",
            cal.map_or(String::new(), |p| p.display().to_string())
        );
    }
    let record: Vec<PathBuf> = a.record.as_ref().map_or(Vec::new(), |d| {
        Recorder::FILES.iter().map(|f| d.join(f)).collect()
    });
    let stdout = PathBuf::from("-");
    let files: Vec<Option<&PathBuf>> = vec![
        a.stats.as_ref(),
        cal.filter(|_| cal_in.is_none()),
        sinks.contains(&SinkSpec::Stdout).then_some(&stdout),
    ];
    let source = match spec {
        SourceSpec::File(p) => Some(p.as_path()),
        _ => None,
    };
    // The take's files go into a new or empty folder (it holds no input): they are checked
    // against the other outputs.
    let all: Vec<&std::path::Path> = files
        .iter()
        .flatten()
        .map(|p| p.as_path())
        .chain(record.iter().map(PathBuf::as_path))
        .collect();
    keyshape_io::atomic::check_distinct(&all)?;
    super::check_outputs(
        &files,
        &[a.record.as_ref()],
        &[
            source,
            a.rig.as_deref(),
            a.rig_landmarks.as_deref(),
            cal_in.map(PathBuf::as_path),
        ],
    )?;
    Ok(())
}

/// Opens the source and the rig: every bad option fails here.
fn setup(a: &LiveArgs) -> Result<Setup> {
    let spec = SourceSpec::parse(&a.from)?;
    let sinks = match &a.to {
        Some(t) => SinkSpec::parse_list(t)?,
        None => Vec::new(),
    };
    check_files(a, &spec, &sinks)?;
    let opts = SourceOptions {
        face: a.face,
        rate: a.rate,
        image_size: a.image_size,
        format: a.format,
    };
    let stdin: Box<dyn std::io::BufRead + Send> =
        Box::new(std::io::BufReader::new(std::io::stdin()));
    let opened = source::open(&spec, &opts, stdin)?;
    let name = opened.name.clone();
    let layout = opened.layout;
    keyshape_rig::correspondence::check_layout(layout)
        .with_context(|| format!("{name}: kslab live"))?;
    // A MediaPipe source read through the 68 iBUG points, or densely.
    let ibug = keyshape_rig::correspondence::is_ibug(layout);
    let (rig_layout, to68): (usize, Option<Vec<usize>>) = match (ibug, a.landmarks.as_deref()) {
        (true, Some("dense")) => anyhow::bail!(
            "--landmarks dense applies to MediaPipe sources; {name} sends the 68 iBUG points"
        ),
        (true, _) | (_, None | Some("dense")) => (layout, None),
        _ => (68, Some(keyshape_rig::mediapipe_to_ibug68()?)),
    };
    let dir = match &a.rig {
        Some(d) => d.clone(),
        None => keyshape_io::shared_data("ict_facekit_face")?,
    };
    if dir.is_file() && a.rig_landmarks.is_none() {
        anyhow::bail!(
            "{}: a glTF rig needs --rig-landmarks CSV (landmark,vertex: the mesh vertex of each track point it covers)",
            dir.display()
        );
    }
    let (_, _, rig) =
        keyshape_rig::correspondence::read_rig(&dir, rig_layout, a.rig_landmarks.as_deref())
            .with_context(|| format!("reading the rig {}", dir.display()))?;
    let select: Vec<usize> = rig
        .points
        .iter()
        .map(|&p| to68.as_ref().map_or(p, |m| m[p]))
        .collect();
    Ok(Setup {
        opened,
        sinks,
        rig,
        select,
        name,
    })
}

/// The solve, the calibration (loaded from --neutral-file when it exists), the sinks and
/// the recording; whether the calibration was loaded.
fn start_session(a: &LiveArgs, s: &Setup) -> Result<(Session, bool)> {
    let (smooth, smooth_unit) = super::rig::smooth_of(true, a.smooth);
    let opts = RigOptions {
        smooth,
        smooth_unit,
        prior: a.prior,
        ..RigOptions::live()
    };
    let mut solver = LiveSolver::new(s.rig.clone(), opts, a.calibrate as usize)?;
    let loaded = match &a.neutral_file {
        Some(p) if p.exists() => {
            let c: keyshape_rig::live::Calibration = keyshape_io::read_json(p)?;
            solver
                .set_calibration(c)
                .with_context(|| format!("{}: not a calibration of this rig", p.display()))?;
            true
        }
        _ => false,
    };
    // The take's frame rate (Live Link's timecode): the file's own, else 60.
    let fps = s.opened.fps.unwrap_or(60.0);
    let has = |vmc: bool| {
        s.sinks.iter().any(|k| match k {
            SinkSpec::Vmc(_) => vmc,
            SinkSpec::LiveLink(_) => !vmc,
            SinkSpec::Stdout => false,
        })
    };
    if a.mirror && !has(true) && !has(false) {
        anyhow::bail!("--mirror applies to the avatar's sinks (vmc, livelink); standard output and the recording keep the person's own sides");
    }
    if a.head_position.is_some() && !has(true) {
        anyhow::bail!("--head-position applies to a vmc sink (the head bone it sends)");
    }
    let options = keyshape_live::sink::SinkOptions {
        mirror: a.mirror,
        head_position: match a.head_position {
            None => Some(keyshape_live::sink::HEAD_POSITION),
            Some(super::input::HeadPosition::At(p)) => Some(p),
            Some(super::input::HeadPosition::None) => None,
        },
        // A file replayed waits for a slow sink (nothing lost); a live source does not.
        wait: s.opened.blocking,
    };
    let sinks = Sinks::open(&s.sinks, &s.rig, Box::new(std::io::stdout()), fps, options)?;
    let recorder = match &a.record {
        Some(d) => Some(Recorder::create(
            d,
            &s.rig,
            (s.opened.layout, s.opened.confidence),
            fps,
        )?),
        None => None,
    };
    let mut session = Session::new(solver, sinks, recorder, s.select.clone());
    if !loaded {
        session.save_calibrations_to(a.neutral_file.clone());
    }
    Ok((session, loaded))
}

/// Ctrl-C, SIGTERM, SIGHUP and every other signal that would end the process set `stop`
/// (the session ends, exit 0, the recording complete); SIGUSR1 and a line `calibrate` on standard input (when it is not the source)
/// set `recal`.
fn control(stdin_is_source: bool, stop: &Arc<AtomicBool>, recal: &Arc<AtomicBool>) -> Result<()> {
    #[cfg(unix)]
    {
        // Every signal that would end the process ends the session instead (the take
        // complete), but SIGUSR1, which recalibrates.
        // A second one ends a session that does not end (exit 130): the take is whole up
        // to its last frame, each written and flushed whole.
        for sig in super::signals::terminating() {
            if sig != libc::SIGUSR1 {
                signal_hook::flag::register_conditional_shutdown(sig, 130, stop.clone())?;
                signal_hook::flag::register(sig, stop.clone())?;
            }
        }
        signal_hook::flag::register(libc::SIGUSR1, recal.clone())?;
    }
    if !stdin_is_source {
        let recal = recal.clone();
        let _ = std::thread::Builder::new()
            .name("kslab-control".into())
            .spawn(move || {
                let mut line = String::new();
                let stdin = std::io::stdin();
                while stdin.read_line(&mut line).is_ok_and(|n| n > 0) {
                    match line.trim() {
                        "calibrate" => recal.store(true, Ordering::Relaxed),
                        "" => {}
                        other => errln!(
                            "kslab live: unknown control line '{other}' (the one there is: calibrate)"
                        ),
                    }
                    line.clear();
                }
            });
    }
    Ok(())
}

/// What the terminal shows while the session runs.
struct Terminal {
    /// Standard error is a terminal: a status line redrawn in place.
    tty: bool,
    last_status: Instant,
    last_frame: Instant,
    idle_said: bool,
    /// Why the lead-in slides on, said at most once a second.
    lead_in: keyshape_live::RateLimited,
}

impl Terminal {
    /// The start of a line (clearing the status line on a terminal).
    fn line(&self) -> &'static str {
        if self.tty {
            "\r\x1b[K"
        } else {
            ""
        }
    }

    /// Redraws the status line twice a second (on a terminal).
    fn status(&mut self, session: &mut Session, counters: &Counters) {
        if !self.tty || self.last_status.elapsed() < Duration::from_millis(500) {
            return;
        }
        self.last_status = Instant::now();
        let (_, malformed, dropped) = counters.get();
        let (p50, p99) = session.recent_latency();
        err!(
            "\r\x1b[K{} fps · latency p50 {} p99 {} · solved {} · dropped {dropped} · malformed {malformed}",
            session.rate(),
            ms(p50),
            ms(p99),
            session.solved()
        );
    }
}

/// Says a calibration was taken into use (after `n` frames waited for it), where it was
/// saved, and what looked wrong with its lead-in.
fn say_calibrated(a: &LiveArgs, session: &Session, t: &Terminal, n: usize) {
    let saved = a
        .neutral_file
        .as_ref()
        .filter(|_| session.saves_calibrations_to().is_some())
        .map_or(String::new(), |p| format!(" (saved to {})", p.display()));
    let lead = session.solver().calibration().map_or(0, |c| c.frames);
    errln!(
        "{}calibrated on {lead} frames{saved}{}",
        t.line(),
        if n > 1 {
            format!("; {n} frames waited for it (recorded; the newest sent)")
        } else {
            String::new()
        }
    );
    if let Some(w) = session.calibration_warning() {
        errln!("warning: the lead-in does not look neutral: {w}; the avatar reads the difference as expression: recalibrate looking ahead, relaxed, lips together (n in the lab, kill -USR1 {}, or a line `calibrate` on standard input)", std::process::id());
    }
}

/// Takes frames from `queue` through `session` until the source ends or `stop` is set.
fn serve(
    a: &LiveArgs,
    session: &mut Session,
    (queue, counters): (&Queue, &Counters),
    (stop, recal): (&AtomicBool, &AtomicBool),
) -> keyshape_core::error::Result<()> {
    let mut t = Terminal {
        tty: std::io::stderr().is_terminal(),
        last_status: Instant::now(),
        last_frame: Instant::now(),
        idle_said: false,
        lead_in: keyshape_live::RateLimited::new(),
    };
    while !stop.load(Ordering::Relaxed) {
        if recal.swap(false, Ordering::Relaxed) {
            session.recalibrate();
            errln!(
                "{}look neutral: recalibrating on the next {} frames",
                t.line(),
                a.calibrate
            );
        }
        match session.serve(queue, Duration::from_millis(100))? {
            Served::Closed => return Ok(()),
            Served::Idle => {
                if t.last_frame.elapsed() > Duration::from_secs(2) && !t.idle_said {
                    errln!(
                        "{}waiting: no frames for {:.0} s",
                        t.line(),
                        t.last_frame.elapsed().as_secs_f64()
                    );
                    t.idle_said = true;
                }
            }
            Served::Calibrated(n) => say_calibrated(a, session, &t, n),
            Served::Took(step) => {
                t.last_frame = Instant::now();
                t.idle_said = false;
                match step {
                    Step::Calibrated(n) => say_calibrated(a, session, &t, n),
                    Step::Collecting(..) => {
                        if let Some(why) = session.lead_in_failure() {
                            if let Some(m) = t.lead_in.say(&format!(
                                "the lead-in cannot be calibrated on ({why}): collecting on"
                            )) {
                                errln!("{}warning: {m}", t.line());
                            }
                        }
                    }
                    Step::Solved => {}
                }
            }
        }
        for n in session.notices() {
            errln!("{}{n}", t.line());
        }
        t.status(session, counters);
    }
    Ok(())
}

/// Runs `kslab live`.
pub fn run(a: &LiveArgs) -> Result<()> {
    let Some(to) = &a.to else {
        anyhow::bail!("--to: name where the weights go (vmc:[HOST:]PORT, livelink:[HOST:]PORT, stdout; several with commas), or watch them in `kslab tui --live SOURCE`");
    };
    // The signals first: a Ctrl-C while the rig is read or the take is made ends the
    // session before its first frame (the take, with no frame, is removed), never the
    // process by signal.
    let stop = Arc::new(AtomicBool::new(false));
    let recal = Arc::new(AtomicBool::new(false));
    control(a.from.trim() == "stdin", &stop, &recal)?;
    let s = setup(a)?;
    if stop.load(Ordering::Relaxed) {
        errln!("kslab live: stopped before the session began");
        return Ok(());
    }
    let (mut session, loaded) = start_session(a, &s)?;
    if let Some(n) = &s.opened.note {
        errln!(
            "{}",
            keyshape_core::error::spell_settings(n, &super::output::spell_flag)
        );
    }
    errln!(
        "kslab live: {} → {to} ({} landmarks, {} shapes)",
        s.name,
        s.rig.landmarks(),
        s.rig.k()
    );
    match (&a.neutral_file, loaded) {
        (Some(p), true) => errln!("calibrated: loaded from {}", p.display()),
        _ => errln!(
            "look neutral: calibrating on the first {} frames",
            a.calibrate
        ),
    }
    let counters = Arc::new(Counters::default());
    let queue = Arc::new(Queue::new(a.queue as usize, s.opened.blocking));
    let warn: source::Warn = Box::new(|m| errln!("warning: {m}"));
    let started = Instant::now();
    let thread = s
        .opened
        .spawn(queue.clone(), counters.clone(), stop.clone(), warn);
    let result = serve(a, &mut session, (&queue, &counters), (&stop, &recal));
    stop.store(true, Ordering::Relaxed);
    // A file source waiting for room in the queue is woken (and then sees the stop); a
    // source blocked in a read is left to the process's end.
    queue.close();
    if result.is_ok() && thread.is_finished() {
        let _ = thread.join();
    }
    session.finish()?;
    report(
        a,
        (&s.name, &s.rig),
        &session,
        &counters,
        started.elapsed().as_secs_f64(),
    )?;
    result.map_err(anyhow::Error::from)
}

/// `kslab tui --live SOURCE`: the live screen, solving as `kslab live` does (no sinks).
pub(crate) fn tui(
    from: &str,
    rig: Option<&std::path::Path>,
    image_size: Option<(f64, f64)>,
) -> Result<()> {
    #[derive(clap::Parser)]
    struct Wrap {
        #[command(flatten)]
        a: LiveArgs,
    }
    let mut args: Vec<String> = vec!["live".into(), "--from".into(), from.into()];
    if let Some(r) = rig {
        args.extend(["--rig".into(), r.display().to_string()]);
    }
    if let Some((w, h)) = image_size {
        args.extend(["--image-size".into(), format!("{w}x{h}")]);
    }
    let a = <Wrap as clap::Parser>::try_parse_from(args)?.a;
    if matches!(SourceSpec::parse(from)?, SourceSpec::Stdin) {
        anyhow::bail!("--live stdin: the lab reads its keys from the terminal; pipe frames through a file source or OpenSeeFace instead");
    }
    let s = setup(&a)?;
    // No sinks, no recording: the screen is the output.
    let (mut session, _) = start_session(&a, &s)?;
    let counters = Arc::new(Counters::default());
    let queue = Arc::new(Queue::new(a.queue as usize, s.opened.blocking));
    let stop = Arc::new(AtomicBool::new(false));
    let thread = s.opened.spawn(
        queue.clone(),
        counters.clone(),
        stop.clone(),
        Box::new(|_| {}),
    );
    let r = kslab_tui::run_live(&mut session, &queue, &counters, &s.name);
    stop.store(true, Ordering::Relaxed);
    queue.close();
    if thread.is_finished() {
        let _ = thread.join();
    }
    r
}
