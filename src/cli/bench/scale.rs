//! `kslab bench scale`: wall time and peak memory of whole subcommands on long
//! generated tracks (`keyshape_io::synthetic`), each run as its own process so
//! its peak resident set is its own.

use anyhow::{bail, Context, Result};
use clap::Args;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

/// Arguments of `kslab bench scale`.
#[derive(Debug, Args)]
pub struct ScaleArgs {
    /// Track lengths to measure, in frames.
    #[arg(long, value_delimiter = ',', default_value = "10000,100000,300000", value_parser = crate::cli::input::count_within(&keyshape_core::limits::BENCH_FRAMES))]
    frames: Vec<usize>,
    /// Points per frame: 68 (iBUG, through the built-in 468 → 68 correspondence) or 468.
    #[arg(long, default_value_t = 68, value_parser = crate::cli::input::count_within(&keyshape_core::limits::BENCH_COUNT))]
    points: usize,
    /// What to run: solve (16 keys, nnls), stream (the same with `--stream`), kmeans2 (`keys --method kmeans2 --k 16`),
    /// greedy (`keys --method greedy --k 16`), curves (`curves --k 2..16`, default methods);
    /// and the other subcommands with their defaults: info, template, retarget (built-in
    /// target), transfer (onto the ICT face at 68 points, the MediaPipe canonical face at 468;
    /// `--json`), modes (the track's own actions, chosen untimed by `kslab actions`), rig (ICT FaceKit), smooth (needs ../shared/data for
    /// transfer, modes and rig).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "solve,stream,kmeans2,greedy,curves"
    )]
    steps: Vec<String>,
    /// Only write one generated track (the first of --frames) to this file, and stop.
    #[arg(long)]
    generate: Option<PathBuf>,
    /// Folder for the generated tracks and outputs (default: a temporary one, removed after).
    #[arg(long)]
    dir: Option<PathBuf>,
    /// Seed of the generated tracks.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

/// One measured run.
#[derive(Debug, serde::Serialize)]
struct Measure {
    step: String,
    frames: usize,
    points: usize,
    seconds: f64,
    peak_mb: Option<f64>,
    bytes_per_frame: Option<f64>,
    ok: bool,
    error: String,
}

const STEPS: [&str; 12] = [
    "solve", "stream", "kmeans2", "greedy", "curves", "info", "template", "retarget", "transfer",
    "modes", "rig", "smooth",
];

pub fn run(a: &ScaleArgs) -> Result<()> {
    if let Some(bad) = a.steps.iter().find(|s| !STEPS.contains(&s.as_str())) {
        bail!(
            "--steps: unknown step '{bad}' (known: {})",
            STEPS.join(", ")
        );
    }
    if a.frames.is_empty() || a.frames.contains(&0) {
        bail!("--frames: give frame counts ≥ 1");
    }
    if let Some(path) = &a.generate {
        if a.frames.len() != 1 {
            bail!("--generate writes one track: give one --frames value");
        }
        super::super::check_outputs(&[Some(path)], &[], &[])?;
        return generate(path, a.frames[0], a.points, a.seed);
    }
    let tmp;
    let dir = match &a.dir {
        Some(d) => {
            std::fs::create_dir_all(d).with_context(|| d.display().to_string())?;
            d.clone()
        }
        None => {
            tmp = TempDir::new()?;
            tmp.0.clone()
        }
    };
    let exe = std::env::current_exe()?;
    let mut rows = Vec::new();
    for &n in &a.frames {
        let track = dir.join(format!("track_{n}x{}.csv", a.points));
        if !track.exists() {
            generate(&track, n, a.points, a.seed)?;
        }
        let t = track.display().to_string();
        for step in &a.steps {
            let args = step_args(a, step, n, &t, &dir, &exe)?;
            let m = measure(&exe, &args, step, n, a.points)?;
            if !a.json {
                outln!(
                    "{:<8} {:>7} frames × {:>3}: {:>8.2} s  {:>8} MB  {:>8} B/frame  {}",
                    m.step,
                    m.frames,
                    m.points,
                    m.seconds,
                    m.peak_mb.map_or("?".into(), |v| format!("{v:.0}")),
                    m.bytes_per_frame.map_or("?".into(), |v| format!("{v:.0}")),
                    if m.ok {
                        String::new()
                    } else {
                        format!("failed: {}", m.error)
                    }
                );
            }
            rows.push(m);
        }
    }
    if a.json {
        outln!("{}", serde_json::to_string_pretty(&rows)?);
    }
    Ok(())
}

/// The command line that step `step` runs on track `t` of `n` frames (outputs in `dir`;
/// `exe` makes the untimed actions `modes` reads).
fn step_args(
    a: &ScaleArgs,
    step: &str,
    n: usize,
    t: &str,
    dir: &Path,
    exe: &Path,
) -> Result<Vec<String>> {
    let keys: Vec<String> = (0..16).map(|i| (i * (n - 1) / 15).to_string()).collect();
    let out = dir.join(format!("{step}_{n}.csv")).display().to_string();
    let args = |xs: &[&str]| -> Vec<String> { xs.iter().map(|x| x.to_string()).collect() };
    Ok(match step {
        // `stream` is `solve` with `--stream`: the same keys, solver and output.
        "solve" | "stream" => {
            let keys = keys.join(",");
            let mut v = args(&[
                "solve", t, "--keys", &keys, "--solver", "nnls", "--out", &out,
            ]);
            if step == "stream" {
                v.push("--stream".into());
            }
            v
        }
        "kmeans2" => args(&["keys", t, "--method", "kmeans2", "--k", "16"]),
        "greedy" => args(&["keys", t, "--method", "greedy", "--k", "16"]),
        "curves" => args(&["curves", t, "--k", "2..16", "--out", &out]),
        "info" => args(&["info", t]),
        "template" => {
            let svg = dir.join(format!("template_{n}.svg"));
            args(&["template", t, "--out", &svg.display().to_string()])
        }
        "retarget" => args(&["retarget", t, "--out", &out]),
        "transfer" => {
            let (mesh, features) = if a.points == 468 {
                (
                    "mediapipe_canonical_face/canonical_face_model.obj",
                    "mediapipe_to_canonical",
                )
            } else {
                ("ict_facekit_face/neutral_face.obj", "ibug68_to_ict")
            };
            let mesh = keyshape_io::shared_data(mesh)?.display().to_string();
            args(&[
                "transfer",
                t,
                "--mesh",
                &mesh,
                "--features",
                features,
                "--json",
            ])
        }
        "modes" => {
            // The track's own actions (untimed): another track's would be refused.
            let acts = dir.join(format!("actions_{n}x{}.json", a.points));
            if !acts.exists() {
                let st = std::process::Command::new(exe)
                    .args(["actions", t, "--out"])
                    .arg(&acts)
                    .stdout(std::process::Stdio::null())
                    .stderr(std::process::Stdio::null())
                    .status()?;
                if !st.success() {
                    bail!("kslab actions {t} failed");
                }
            }
            args(&["modes", t, "--actions", &acts.display().to_string()])
        }
        "rig" => args(&["rig", t, "--out", &out]),
        _ => {
            let smooth = dir.join(format!("smooth_{n}"));
            args(&["smooth", t, "--out", &smooth.display().to_string()])
        }
    })
}

fn generate(path: &Path, frames: usize, points: usize, seed: u64) -> Result<()> {
    keyshape_io::write_atomic(path, |w| {
        let mut w = std::io::BufWriter::new(w);
        keyshape_io::synthetic::write_long_track(&mut w, frames, points, seed)
            .map_err(std::io::Error::other)?;
        std::io::Write::flush(&mut w)
    })?;
    Ok(())
}

/// Runs `exe args` to the end; its wall time and peak resident set.
fn measure(
    exe: &Path,
    args: &[String],
    step: &str,
    frames: usize,
    points: usize,
) -> Result<Measure> {
    let t = Instant::now();
    let mut child = Command::new(exe)
        .args(args)
        .arg("--quiet")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()?;
    let mut stderr = child.stderr.take().context("child stderr")?;
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = std::io::Read::read_to_string(&mut stderr, &mut s);
        s
    });
    let (ok, peak) = wait_with_peak(child)?;
    let seconds = t.elapsed().as_secs_f64();
    let err = reader.join().unwrap_or_default();
    let peak_mb = peak.map(|b| b as f64 / 1e6);
    Ok(Measure {
        step: step.to_string(),
        frames,
        points,
        seconds,
        peak_mb,
        bytes_per_frame: peak.map(|b| b as f64 / frames as f64),
        ok,
        error: err.lines().next().unwrap_or("").to_string(),
    })
}

/// Waits for `child`; whether it succeeded and its peak resident set in bytes.
#[cfg(unix)]
#[allow(unsafe_code)] // two libc calls, each under its SAFETY comment
fn wait_with_peak(child: std::process::Child) -> Result<(bool, Option<u64>)> {
    let pid = child.id() as libc::pid_t;
    let mut status: libc::c_int = 0;
    // SAFETY: rusage is plain data that wait4 fills; the pid is our own child, which std
    // has not waited for (dropping a Child does not wait).
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let r = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    if r != pid {
        bail!("wait4: {}", std::io::Error::last_os_error());
    }
    let ok = libc::WIFEXITED(status) && libc::WEXITSTATUS(status) == 0;
    // Linux reports ru_maxrss in kilobytes.
    Ok((ok, Some(usage.ru_maxrss as u64 * 1024)))
}

#[cfg(not(unix))]
fn wait_with_peak(mut child: std::process::Child) -> Result<(bool, Option<u64>)> {
    Ok((child.wait()?.success(), None))
}

/// A temporary folder removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new() -> Result<TempDir> {
        let d = std::env::temp_dir().join(format!("kslab-scale-{}", std::process::id()));
        std::fs::create_dir_all(&d)?;
        Ok(TempDir(d))
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
