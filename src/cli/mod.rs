//! Command-line parsing and the subcommands. Only arranges library calls and prints.

/// `println!` that returns an error instead of panicking when standard output cannot be
/// written (a full disk, a closed pipe).
macro_rules! outln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        $crate::cli::progress::suspend(|| writeln!(std::io::stdout().lock(), $($t)*))
            .map_err(|e| anyhow::Error::new(e).context("writing to standard output"))?;
    }};
}

/// A one-line summary: to standard output, or to standard error when standard output
/// carries the command's data (`--out -`).
macro_rules! sayln {
    ($taken:expr, $($t:tt)*) => {{
        if $taken {
            $crate::cli::progress::suspend(|| errln!($($t)*));
        } else {
            outln!($($t)*);
        }
    }};
}

/// `eprintln!` that never panics: every message to standard error goes through it. A
/// closed standard error (`2>&-`, a reader that has gone) loses the message, never the
/// command or its outputs (`eprintln!` panicked, exit 101, and `modes` lost its output).
macro_rules! errln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr().lock(), $($t)*);
    }};
}

/// `eprint!` that never panics (see [`errln`]).
macro_rules! err {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let mut e = std::io::stderr().lock();
        let _ = write!(e, $($t)*).and_then(|()| e.flush());
    }};
}

/// `print!` that returns an error instead of panicking (see [`outln`]).
#[allow(unused_macros)]
macro_rules! out {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        write!(std::io::stdout().lock(), $($t)*)
            .map_err(|e| anyhow::Error::new(e).context("writing to standard output"))?;
    }};
}

mod actions;
mod bench;
mod curves;
mod info;
mod input;
mod intensity;
mod keys;
mod live;
mod map;
mod modes;
mod output;
mod progress;
mod retarget;
mod rig;
mod rig_accuracy;
mod run;
mod signals;
mod smooth;
mod solve;
mod template;
mod transfer;
mod tui;

use output::{broken_pipe, render_error, spell_experiment_key, spell_flag};
pub(crate) use output::{check_json_stdout, check_outputs, is_stdout};

use clap::{Parser, Subcommand};

use std::process::ExitCode;

/// keyshape-lab: with no command, the interactive lab on the built-in sequence. Pick key shapes from a tracked facial performance, solve blend weights,
/// and see how they retarget.
#[derive(Debug, Parser)]
#[command(name = "kslab", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// No progress bar (one appears on a terminal when a step runs longer than a second).
    #[arg(long, short, global = true)]
    quiet: bool,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Open the interactive lab (this is also what `kslab` alone does, on the built-in sequence).
    Tui(tui::TuiArgs),
    /// Describe a tracked sequence: format, frames, points, failed frames, ranges.
    Info(info::InfoArgs),
    /// Solve blend weights of every frame on chosen key frames (paper 000 Eq. 3/4).
    Solve(solve::SolveArgs),
    /// Choose key frames with a heuristic (paper 000 §4.2).
    Keys(keys::KeysArgs),
    /// Error against number of key shapes for each heuristic (paper 000 Fig. 6).
    Curves(curves::CurvesArgs),
    /// Write chosen key shapes as an SVG template for an artist to redraw.
    Template(template::TemplateArgs),
    /// Retarget the performance onto target key shapes (paper 000 Eq. 2, §5).
    Retarget(retarget::RetargetArgs),
    /// Solve a tracked face (68 or MediaPipe 468 points) onto a blendshape rig (ARKit-style, e.g. ICT FaceKit) with head pose; weights, Live Link Face CSV, glTF.
    Rig(rig::RigArgs),
    /// Live: a running face tracker (OpenSeeFace, stdin, a replayed file) through the rig's causal solve to an avatar (VMC, Live Link Face, CSV lines), calibrated and recorded.
    Live(live::LiveArgs),
    /// The rig accuracy benchmark: performances rendered through the rig from known weights, solved back and measured per shape against the truth.
    RigAccuracy(rig_accuracy::RigAccuracyArgs),
    /// Drive a 3-D mesh from the feature points: RBF transfer + skinning (paper 004).
    Transfer(transfer::TransferArgs),
    /// Choose one example frame per action (jaw drop, smile, blink …) for `modes` and `map`.
    Actions(actions::ActionsArgs),
    /// Action-specific modes and their orthogonality (Cosker et al., paper 002 Table 2).
    Modes(modes::ModesArgs),
    /// Map action-mode trajectories onto a second person and onto morph targets (paper 002 §3.2–3.3).
    Map(map::MapArgs),
    /// Soft-KNN action intensities against ground-truth scores (Cosker et al. §4.1, Eq. 10).
    Intensity(intensity::IntensityArgs),
    /// Jitter against error: the temporal prior in the solver against filters afterwards.
    Smooth(smooth::SmoothArgs),
    /// Run a scripted experiment (experiments/*.toml): CSV, JSON and PNG reports.
    Run(run::RunArgs),
    /// Combine the partial reports of a sharded corpus run (`kslab run … --shard i/n`) into its report.
    Merge(run::MergeArgs),
    /// Measure solver and sweep speed (the figures in BENCHMARKS.md).
    Bench(bench::BenchArgs),
}

impl Command {
    /// Does the command print its results as JSON on standard output (`--json`)?
    fn prints_json(&self) -> bool {
        match self {
            Command::Info(a) => a.json,
            Command::Solve(a) => a.json,
            Command::Keys(a) => a.json,
            Command::Retarget(a) => a.json,
            Command::Rig(a) => a.json,
            Command::RigAccuracy(a) => a.json,
            Command::Transfer(a) => a.json,
            Command::Modes(a) => a.json,
            Command::Intensity(a) => a.json,
            _ => false,
        }
    }
}

/// Runs the CLI; errors print as `error: …` with exit code 1.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    progress::set_quiet(cli.quiet);
    let command = cli.command.unwrap_or(Command::Tui(tui::TuiArgs::default()));
    // One output set per command: every file it writes is staged and renamed into place
    // only when the whole command has succeeded. The lab stages each export on its own; the
    // benchmarks write tracks that the processes they start must read at once.
    // How the library's errors name a setting: as this command's flag, or, for an
    // experiment, as its key in the file.
    let spell: fn(&str) -> String = match command {
        Command::Run(_) | Command::Merge(_) => spell_experiment_key,
        _ => spell_flag,
    };
    let set = match command {
        // Live writes as it goes (a recording flushed per frame), and its signals end the
        // session cleanly instead.
        Command::Tui(_) | Command::Bench(_) | Command::Live(_) => None,
        _ => {
            signals::install();
            Some(keyshape_io::OutputSet::begin())
        }
    };
    // `--json` prints to standard output: it is one of the command's outputs there, so a
    // file sent to `-` or `/dev/stdout` beside it is refused before any work.
    if command.prints_json() {
        if let Err(e) = keyshape_io::atomic::claim_stdout(std::path::Path::new("--json")) {
            errln!("error: {e}");
            return ExitCode::FAILURE;
        }
    }
    let result = match command {
        Command::Tui(a) => tui::run(&a),
        Command::Info(a) => info::run(&a),
        Command::Solve(a) => solve::run(&a),
        Command::Keys(a) => keys::run(&a),
        Command::Curves(a) => curves::run(&a),
        Command::Template(a) => template::run(&a),
        Command::Retarget(a) => retarget::run(&a),
        Command::Rig(a) => rig::run(&a),
        Command::Live(a) => live::run(&a),
        Command::RigAccuracy(a) => rig_accuracy::run(&a),
        Command::Transfer(a) => transfer::run(&a),
        Command::Actions(a) => actions::run(&a),
        Command::Modes(a) => modes::run(&a),
        Command::Intensity(a) => intensity::run(&a),
        Command::Smooth(a) => smooth::run(&a),
        Command::Map(a) => map::run(&a),
        Command::Run(a) => run::run(&a),
        Command::Merge(a) => run::merge(&a),
        Command::Bench(a) => bench::run(&a),
    };
    let result = result.and_then(|()| match set {
        Some(set) => set.commit().map(drop).map_err(anyhow::Error::from),
        None => Ok(()),
    });
    if result.is_err() && keyshape_io::atomic::abandoned() {
        // A signal stopped the command and its thread is ending the process with that
        // signal: an error of this thread (its writes refused since) must not exit first
        // with 1, nor print as a failure.
        loop {
            std::thread::park();
        }
    }
    match result {
        Ok(()) => {
            output::said_wrote();
            ExitCode::SUCCESS
        }
        // A reader closed the pipe after output began (`kslab … | head`): a quiet stop, as
        // a signal would have made it, but with the outputs of the set discarded.
        Err(e) if broken_pipe(&e) => ExitCode::from(141),
        Err(e) => {
            errln!("error: {}", render_error(&e, &spell));
            ExitCode::FAILURE
        }
    }
}
