//! `kslab bench live`: a `kslab live` process fed in real time on loopback, as a tracker
//! would feed it — 68 points as OpenSeeFace datagrams, or 478 points as MediaPipe JSON
//! lines on its standard input — sending VMC and Live Link Face to receivers here. Reports
//! the latency from a frame's arrival to its sending (p50, p99, worst; the process's own
//! `--stats`), frames dropped, datagrams received, and the process's CPU use.

use anyhow::{Context, Result};
use clap::Args;
use keyshape_rig::accuracy::{render, Kind, Settings};
use std::io::Write;
use std::net::UdpSocket;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Arguments of `kslab bench live`.
#[derive(Debug, Args)]
pub struct LiveBenchArgs {
    /// Landmarks per frame: 68 (OpenSeeFace datagrams over UDP) or 478 (MediaPipe Face
    /// Landmarker JSON lines on standard input, solved densely).
    #[arg(long, default_value = "68", value_parser = ["68", "478"])]
    points: String,
    /// Seconds of performance to send (after the 30-frame calibration).
    #[arg(long, default_value_t = 20.0, value_parser = crate::cli::input::number_within(&keyshape_core::limits::BENCH_SECONDS))]
    seconds: f64,
    /// Frames per second.
    #[arg(long, default_value_t = 60.0, value_parser = crate::cli::input::number_within(&keyshape_core::limits::BENCH_FPS))]
    fps: f64,
}

/// A rendered performance (the rig accuracy benchmark's smooth one, 0.5 px noise, another
/// person's face) as `points`-point frames: 30 neutral frames, then `frames` frames.
fn frames(points: usize, frames: usize) -> Result<Vec<Vec<f64>>> {
    let dir = keyshape_io::shared_data("ict_facekit_face")?;
    let (_, _, rig) = keyshape_rig::correspondence::read_rig(&dir, points, None)?;
    // The performance repeats every 600 frames (a render of 10 minutes is not needed to
    // measure 10 minutes).
    let st = Settings {
        kind: Kind::Smooth,
        frames: 600,
        lead_in: 30,
        ..Settings::default()
    };
    let t = render(&rig, &st)?;
    let mut out = Vec::with_capacity(30 + frames);
    for f in 0..30 + frames {
        let c = if f < 30 { f } else { 30 + (f - 30) % 600 };
        // Every point of the layout; the ones the rig does not read sit on its first.
        let mut v = vec![0.0; 2 * points];
        for p in 0..points {
            v[2 * p] = t.points[(0, c)];
            v[2 * p + 1] = t.points[(1, c)];
        }
        for (l, &p) in rig.points.iter().enumerate() {
            v[2 * p] = t.points[(2 * l, c)];
            v[2 * p + 1] = t.points[(2 * l + 1, c)];
        }
        out.push(v);
    }
    Ok(out)
}

/// OpenSeeFace's face record (see `keyshape_live::openseeface`), little-endian, for a face
/// in iBUG order: OpenSeeFace's own points are iBUG's without the outer mouth corners,
/// then the two pupils (sent untracked: (0, 0), confidence 0, as without gaze tracking).
fn osf_datagram(time: f64, ibug: &[f64]) -> Vec<u8> {
    let mut b = Vec::with_capacity(keyshape_live::openseeface::FACE_BYTES);
    b.extend(time.to_le_bytes());
    b.extend(0i32.to_le_bytes());
    for v in [640f32, 480.0, 1.0, 1.0] {
        b.extend(v.to_le_bytes());
    }
    b.push(1u8);
    b.extend(std::iter::repeat_n(0u8, 4 * (1 + 4 + 3 + 3)));
    for i in 0..68 {
        b.extend(if i < 66 { 1f32 } else { 0.0 }.to_le_bytes());
    }
    for p in (0..68).filter(|&p| p != 48 && p != 54) {
        b.extend((ibug[2 * p] as f32).to_le_bytes());
        b.extend((ibug[2 * p + 1] as f32).to_le_bytes());
    }
    b.extend([0u8; 16]);
    b.extend(std::iter::repeat_n(0u8, 4 * (70 * 3 + 14)));
    b
}

/// A Live Link receiver keeping each packet's frame number and arrival: the latency from
/// the sender's side (a packet carries its frame's number; a VMC bundle does not).
fn livelink_receiver(got: Arc<std::sync::Mutex<Vec<(u32, Instant)>>>) -> Result<u16> {
    let s = UdpSocket::bind("127.0.0.1:0")?;
    let port = s.local_addr()?.port();
    std::thread::spawn(move || {
        let mut buf = vec![0u8; 65_536];
        while let Ok(n) = s.recv(&mut buf) {
            let at = Instant::now();
            // u8 version, then two length-prefixed strings, then the i32 frame number.
            let be = |i: usize| {
                buf.get(i..i + 4)
                    .map(|b| u32::from_be_bytes([b[0], b[1], b[2], b[3]]))
            };
            let frame = be(1).and_then(|a| {
                let at2 = 5 + a as usize;
                be(at2).and_then(|b| be(at2 + 4 + b as usize))
            });
            if let (Some(f), Ok(mut g)) = (frame.filter(|_| n > 0), got.lock()) {
                g.push((f, at));
            }
        }
    });
    Ok(port)
}

fn receiver(counter: Arc<AtomicU64>) -> Result<u16> {
    let s = UdpSocket::bind("127.0.0.1:0")?;
    let port = s.local_addr()?.port();
    std::thread::spawn(move || {
        let mut buf = vec![0u8; 65_536];
        while s.recv(&mut buf).is_ok() {
            counter.fetch_add(1, Ordering::Relaxed);
        }
    });
    Ok(port)
}

/// The process's CPU seconds so far (user + system), from /proc.
fn cpu_seconds(pid: u32) -> Option<f64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    let rest = stat.rsplit_once(')')?.1;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

pub fn run(a: &LiveBenchArgs) -> Result<()> {
    if !(a.fps > 0.0 && a.fps <= 1000.0 && a.seconds > 0.0 && a.seconds <= 86_400.0) {
        anyhow::bail!("--fps in (0, 1000] and --seconds in (0, 86400]");
    }
    let points: usize = a.points.parse()?;
    let n = (a.seconds * a.fps).round() as usize;
    let progress = crate::cli::progress::Progress::new("bench live: rendering");
    let frames = frames(points, n)?;
    let vmc = Arc::new(AtomicU64::new(0));
    let ll = Arc::new(std::sync::Mutex::new(Vec::new()));
    let (vmc_port, ll_port) = (receiver(vmc.clone())?, livelink_receiver(ll.clone())?);
    let osf_port = UdpSocket::bind("127.0.0.1:0")?.local_addr()?.port();
    let stats = std::env::temp_dir().join(format!("kslab-bench-live-{}.json", std::process::id()));
    let from = if points == 68 {
        format!("openseeface:127.0.0.1:{osf_port}")
    } else {
        "stdin".to_string()
    };
    let to = format!("vmc:127.0.0.1:{vmc_port},livelink:127.0.0.1:{ll_port}");
    let (mut child, taskset) = start_live(&from, &to, &stats)?;
    let pid = child.id();
    // Its first line comes once the source is open (a UDP source: then it can receive;
    // standard input is opened by reading its first line, which the pipe holds).
    let mut err = child.stderr.take().context("stderr")?;
    if points == 68 {
        let mut first = [0u8; 12];
        std::io::Read::read_exact(&mut err, &mut first)?;
    }
    let err_thread = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = std::io::Read::read_to_string(&mut err, &mut s);
        s
    });
    let mut stdin = child.stdin.take().context("stdin")?;
    progress.step("bench live: sending in real time");
    let start = Instant::now();
    let cpu0 = cpu_seconds(pid);
    let sent = send_frames(&frames, a.fps, points, osf_port, &mut stdin, (start, pid))?;
    std::thread::sleep(Duration::from_millis(300));
    let wall = start.elapsed().as_secs_f64();
    let cpu = match (cpu0, cpu_seconds(pid)) {
        (Some(a), Some(b)) => Some(100.0 * (b - a) / wall),
        _ => None,
    };
    let _ = Command::new("kill")
        .args(["-INT", &pid.to_string()])
        .status();
    drop(stdin);
    let status = child.wait()?;
    let log = err_thread.join().unwrap_or_default();
    progress.finish();
    if !status.success() {
        anyhow::bail!("kslab live failed: {log}");
    }
    let s: serde_json::Value = keyshape_io::read_json(&stats)?;
    let _ = std::fs::remove_file(&stats);
    let num = |k: &str| s[k].as_f64().unwrap_or(f64::NAN);
    let lat = |k: &str| s["latency_ms"][k].as_f64().unwrap_or(f64::NAN);
    outln!(
        "kslab live{}: {} frames ({} points, {} landmarks solved, 55 shapes) at {} fps over {:.0} s, VMC + Live Link Face out, on loopback",
        if taskset { " on one core (taskset -c 0)" } else { "" },
        frames.len(),
        points,
        num("landmarks"),
        a.fps,
        wall
    );
    // From the sender's side: each frame's sending to its Live Link packet's arrival, the
    // whole session — the calibration (made on its own thread, the frames that waited for
    // it recorded and only the newest sent) and a recalibration halfway included.
    let got = ll.lock().map(|g| g.clone()).unwrap_or_default();
    let whole = from_sender(&got, &sent);
    let q = |p: f64| keyshape_live::session::quantile(&whole, p).unwrap_or(f64::NAN);
    outln!("| points | fps | frames sent | solved | dropped | VMC bundles | Live Link packets | latency p50 | p99 | worst | from the sender, whole session: p50 | p99 | worst | frames over 8 ms | CPU |");
    outln!("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    outln!(
        "| {points} | {} | {} | {} | {} | {} | {} | {:.2} ms | {:.2} ms | {:.2} ms | {:.2} ms | {:.2} ms | {:.2} ms | {} | {} |",
        a.fps,
        frames.len(),
        num("solved"),
        num("dropped"),
        vmc.load(Ordering::Relaxed),
        got.len(),
        lat("p50"),
        lat("p99"),
        lat("worst"),
        q(0.5),
        q(0.99),
        q(1.0),
        whole.iter().filter(|&&v| v > 8.0).count(),
        cpu.map_or("–".into(), |c| format!("{c:.0} %"))
    );
    Ok(())
}

/// Per Live Link packet received (its frame's number, its arrival), milliseconds from its
/// frame's sending (`sent`), sorted.
fn from_sender(got: &[(u32, Instant)], sent: &[Instant]) -> Vec<f64> {
    let mut whole: Vec<f64> = got
        .iter()
        .filter_map(|(f, at)| {
            let s = sent.get(*f as usize)?;
            Some(at.saturating_duration_since(*s).as_secs_f64() * 1e3)
        })
        .collect();
    whole.sort_by(f64::total_cmp);
    whole
}

/// Starts `kslab live --from FROM --to TO --stats STATS` on one core (as a tracker's
/// machine would spare it) when `taskset` is there; says whether it is.
fn start_live(
    from: &str,
    to: &str,
    stats: &std::path::Path,
) -> Result<(std::process::Child, bool)> {
    let exe = std::env::current_exe()?;
    let taskset = std::path::Path::new("/usr/bin/taskset").exists();
    let mut cmd = if taskset {
        let mut c = Command::new("/usr/bin/taskset");
        c.args(["-c", "0"]).arg(&exe);
        c
    } else {
        Command::new(&exe)
    };
    cmd.args(["live", "--from", from, "--to"])
        .arg(to)
        .arg("--stats")
        .arg(stats)
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    let child = cmd.spawn().context("starting kslab live")?;
    Ok((child, taskset))
}

/// Sends each frame at its time from `start` at `fps`: as an OpenSeeFace datagram to
/// `osf_port` for 68 points, else as a JSON line on `stdin`; halfway, asks the session
/// (process `pid`) to recalibrate. Each frame's sending instant.
fn send_frames(
    frames: &[Vec<f64>],
    fps: f64,
    points: usize,
    osf_port: u16,
    stdin: &mut impl Write,
    (start, pid): (Instant, u32),
) -> Result<Vec<Instant>> {
    let send = UdpSocket::bind("127.0.0.1:0")?;
    let period = Duration::from_secs_f64(1.0 / fps);
    let mut sent = Vec::with_capacity(frames.len());
    for (f, v) in frames.iter().enumerate() {
        let due = start + period.mul_f64(f as f64);
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
        if f == frames.len() / 2 {
            let _ = Command::new("kill")
                .args(["-USR1", &pid.to_string()])
                .status();
        }
        sent.push(Instant::now());
        let t = f as f64 / fps;
        if points == 68 {
            send.send_to(&osf_datagram(t, v), ("127.0.0.1", osf_port))?;
        } else {
            let pts: Vec<String> = v
                .chunks(2)
                .map(|p| format!("[{},{}]", p[0], p[1]))
                .collect();
            writeln!(stdin, "{{\"t\":{t},\"points\":[{}]}}", pts.join(","))?;
            stdin.flush()?;
        }
    }
    Ok(sent)
}
