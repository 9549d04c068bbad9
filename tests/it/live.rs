//! `kslab live` on loopback: OpenSeeFace datagrams built here (the layout written out
//! below, not the crate's decoder) → `kslab live` → VMC bundles decoded by rosc's decoder
//! and Live Link packets decoded by the layout written out below; the weights against the
//! offline causal solve of the same frames and against the weights they were rendered
//! from; malformed datagrams counted and harmless; Ctrl-C ends with exit 0 and the
//! recording complete.

use crate::common::{kslab, shared};
use keyshape_rig::accuracy::{render, Settings};
use keyshape_rig::Rig;
use std::io::Read;
use std::net::UdpSocket;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// OpenSeeFace's datagram for one face, as its `facetracker.py` writes it: f64 time, i32
/// id, f32 width, height, right and left eye openness, u8 success, f32 fit error, 4 f32
/// quaternion, 3 f32 Euler, 3 f32 translation, 68 f32 confidences, 68 × (f32 x, f32 y),
/// 70 × 3 f32, 14 f32. `ibug` is a face in iBUG-68 order; OpenSeeFace's own 68 points are
/// its 66 (iBUG without the outer mouth corners 48 and 54) and the two pupils, sent here
/// as a tracker without gaze tracking sends them: (0, 0), confidence 0.
fn osf_face(time: f64, id: i32, ibug: &[f64]) -> Vec<u8> {
    let mut b = Vec::new();
    b.extend(time.to_le_bytes());
    b.extend(id.to_le_bytes());
    for v in [640f32, 480.0, 1.0, 1.0] {
        b.extend(v.to_le_bytes());
    }
    b.push(1u8);
    for _ in 0..(1 + 4 + 3 + 3) {
        b.extend(0f32.to_le_bytes());
    }
    for i in 0..68 {
        b.extend(if i < 66 { 0.9f32 } else { 0.0 }.to_le_bytes());
    }
    let ours: Vec<usize> = (0..68).filter(|p| *p != 48 && *p != 54).collect();
    for p in ours {
        b.extend((ibug[2 * p] as f32).to_le_bytes());
        b.extend((ibug[2 * p + 1] as f32).to_le_bytes());
    }
    b.extend([0u8; 16]);
    for _ in 0..(70 * 3 + 14) {
        b.extend(0f32.to_le_bytes());
    }
    assert_eq!(b.len(), 1785);
    b
}

/// The frame `kslab live` solves for [`osf_face`]'s datagram of `ibug` (f32 as sent): 70
/// points, iBUG order, 48 and 54 repeating 60 and 64, the untracked pupils at their eyes'
/// centres.
fn osf_solved(ibug: &[f64]) -> Vec<f64> {
    let mut out: Vec<f64> = ibug.iter().map(|v| f64::from(*v as f32)).collect();
    for (a, b) in [(48, 60), (54, 64)] {
        out[2 * a] = out[2 * b];
        out[2 * a + 1] = out[2 * b + 1];
    }
    for eye in [36, 42] {
        for a in 0..2 {
            let c = (eye..eye + 6).map(|p| out[2 * p + a]).sum::<f64>() / 6.0;
            out.push(c);
        }
    }
    out
}

/// A plain CSV track of 70-point frames (columns of `frames`).
fn csv70(frames: impl IntoIterator<Item = Vec<f64>>) -> String {
    let mut csv = String::from("frame,time_s");
    for i in 0..70 {
        csv += &format!(",x{i},y{i}");
    }
    for i in 0..70 {
        csv += &format!(",c{i}");
    }
    for (f, pts) in frames.into_iter().enumerate() {
        csv += &format!("\n{f},{}", f as f64 / OSF_FPS);
        for v in pts {
            csv += &format!(",{v}");
        }
        // The confidences `kslab live` reads from `osf_face` (0.9 as f32; the pupils 0).
        for i in 0..70 {
            csv += &format!(",{}", if i < 68 { f64::from(0.9f32) } else { 0.0 });
        }
    }
    csv + "\n"
}

/// The frame rate the tests' OpenSeeFace senders stamp their datagrams with.
const OSF_FPS: f64 = 60.0;

/// A Live Link Face packet read as the decoders written against the iOS app read it
/// (PyLiveLinkFace's `decode` and the tools built on it), at fixed offsets: the version as
/// a little-endian u32 in bytes 0–3 (the app's u8 version and the top of the id's length),
/// the device id in bytes 4–40 (the length's low byte, 36 = '$', and the 36-character
/// UUID), then big-endian: i32 subject length and the subject, u32 frame and sub-frame,
/// u32 frame rate and denominator, u8 count and count × f32. (frame, frame rate, values).
pub(crate) fn decode_livelink(p: &[u8]) -> (u32, u32, Vec<f32>) {
    let be_u32 = |at: usize| u32::from_be_bytes(p[at..at + 4].try_into().unwrap());
    assert_eq!(
        u32::from_le_bytes(p[0..4].try_into().unwrap()),
        6,
        "version"
    );
    let id = std::str::from_utf8(&p[4..41]).unwrap();
    assert!(id.starts_with('$'), "a 36-character device id: {id}");
    let uuid = &id[1..];
    let hyphens: Vec<usize> = uuid.match_indices('-').map(|m| m.0).collect();
    assert_eq!(hyphens, [8, 13, 18, 23], "a UUID: {uuid}");
    assert!(uuid.chars().all(|c| c == '-' || c.is_ascii_hexdigit()));
    let name_len = be_u32(41) as usize;
    assert_eq!(&p[45..45 + name_len], b"kslab");
    let mut at = 45 + name_len;
    let frame = be_u32(at);
    let fps = be_u32(at + 8);
    assert_eq!(be_u32(at + 12), 1, "denominator");
    at += 16;
    let count = p[at] as usize;
    at += 1;
    assert_eq!(count, 61);
    assert_eq!(p.len(), at + 4 * count, "nothing after the values");
    let values = (0..count)
        .map(|i| f32::from_be_bytes(p[at + 4 * i..at + 4 * i + 4].try_into().unwrap()))
        .collect();
    (frame, fps, values)
}

pub(crate) fn free_udp_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

pub(crate) fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma).powi(2);
        sbb += (y - mb).powi(2);
    }
    sab / (saa * sbb).sqrt()
}

/// Reads a weights CSV (frame + one column per shape) into per-frame rows.
pub(crate) fn weights_rows(text: &str) -> Vec<Vec<f64>> {
    text.lines()
        .skip(1)
        .map(|l| l.split(',').skip(1).map(|v| v.parse().unwrap()).collect())
        .collect()
}

#[test]
fn a_rendered_performance_sent_at_60_fps_comes_out_as_the_offline_causal_solve() {
    let rig = Rig::read_ict(&shared("ict_facekit_face")).unwrap();
    let st = Settings {
        frames: 160,
        lead_in: 20,
        ..Settings::default()
    };
    let track = render(&rig, &st).unwrap();
    let frames = track.points.ncols();
    let dir = tempfile::tempdir().unwrap();
    let (osf, vmc_port, ll_port) = (free_udp_port(), free_udp_port(), free_udp_port());
    let vmc = UdpSocket::bind(("127.0.0.1", vmc_port)).unwrap();
    let ll = UdpSocket::bind(("127.0.0.1", ll_port)).unwrap();
    for s in [&vmc, &ll] {
        s.set_nonblocking(true).unwrap();
    }
    let take = dir.path().join("take");
    let live = Running::start(
        Command::new(env!("CARGO_BIN_EXE_kslab"))
            .args([
                "live",
                "--from",
                &format!("openseeface:127.0.0.1:{osf}"),
                "--to",
                &format!("vmc:127.0.0.1:{vmc_port},livelink:127.0.0.1:{ll_port},stdout"),
                "--calibrate",
                "20",
                // Room for a busy machine's pauses (CI runs tests side by side): this test is
                // about what comes out, the queue's dropping has its own.
                "--queue",
                "256",
                "--record",
            ])
            .arg(&take)
            .stdin(Stdio::null()),
        true,
    );
    let send = UdpSocket::bind("127.0.0.1:0").unwrap();
    let to = ("127.0.0.1", osf);
    // The frames as sent: f32, as the datagrams carry them.
    let mut sent: Vec<Vec<f64>> = Vec::with_capacity(frames);
    let start = Instant::now();
    let mut bundles: Vec<rosc::OscPacket> = Vec::new();
    let mut packets: Vec<(u32, u32, Vec<f32>)> = Vec::new();
    let mut buf = vec![0u8; 65_536];
    let mut drain = |bundles: &mut Vec<rosc::OscPacket>,
                     packets: &mut Vec<(u32, u32, Vec<f32>)>| {
        while let Ok(n) = vmc.recv(&mut buf) {
            bundles.push(rosc::decoder::decode_udp(&buf[..n]).unwrap().1);
        }
        while let Ok(n) = ll.recv(&mut buf) {
            packets.push(decode_livelink(&buf[..n]));
        }
    };
    for f in 0..frames {
        let pts: Vec<f64> = track.points.column(f).iter().copied().collect();
        sent.push(osf_solved(&pts));
        send.send_to(&osf_face(f as f64 / OSF_FPS, 0, &pts), to)
            .unwrap();
        // Malformed datagrams mixed in: short, a face and a bit, a NaN landmark, empty.
        if f % 40 == 7 {
            // (The header is 73 bytes, the confidences 272; landmark 4's x.)
            let mut nan = osf_face(0.0, 0, &pts);
            nan[73 + 272 + 32..73 + 272 + 36].copy_from_slice(&f32::NAN.to_le_bytes());
            for bad in [
                vec![1u8; 100],
                [osf_face(0.0, 0, &pts), vec![0; 7]].concat(),
                nan,
                Vec::new(),
            ] {
                send.send_to(&bad, to).unwrap();
            }
        }
        let due = start + Duration::from_secs_f64((f + 1) as f64 / 60.0);
        while Instant::now() < due {
            drain(&mut bundles, &mut packets);
        }
    }
    let end = Instant::now() + Duration::from_secs(5);
    while (bundles.len() < frames || packets.len() < frames) && Instant::now() < end {
        drain(&mut bundles, &mut packets);
    }
    // The tracker stops: shown, not an error. Then Ctrl-C: exit 0, the recording complete.
    std::thread::sleep(Duration::from_millis(2400));
    let (code, out, err) = live.stop(libc::SIGINT);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains("look neutral") && err.contains("calibrated on 20 frames"),
        "{err}"
    );
    assert!(err.contains(&format!("{frames} frames solved")), "{err}");
    assert!(err.contains("20 malformed"), "5 × 4 bad datagrams: {err}");
    assert!(err.contains(" 0 dropped"), "{err}");
    assert!(err.contains("waiting: no frames for 2 s"), "{err}");
    // The lead-in's frames (and any that came while its calibration was made) waited for
    // the calibration: recorded, and of them only the newest sent; every frame after it
    // is sent as it comes.
    let skip = frames - bundles.len();
    let waited: usize = err
        .split("frames waited for it")
        .next()
        .and_then(|s| s.rsplit("; ").next())
        .and_then(|n| n.trim().parse().ok())
        .unwrap_or_else(|| panic!("how many frames waited: {err}"));
    assert!(waited >= 20, "the 20-frame lead-in waited: {err}");
    assert_eq!(
        skip,
        waited - 1,
        "one VMC bundle per frame but the waiting ones' older"
    );
    assert_eq!(
        packets.len(),
        bundles.len(),
        "one Live Link packet per VMC bundle"
    );

    // The offline causal solve of the same frames.
    let file = dir.path().join("sent.csv");
    std::fs::write(&file, csv70(sent)).unwrap();
    let offline = dir.path().join("offline.csv");
    let r = kslab(&[
        "rig",
        file.to_str().unwrap(),
        "--live",
        "--neutral",
        "0-19",
        "--landmarks",
        "68",
        "--out",
        offline.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let offline_text = std::fs::read_to_string(&offline).unwrap();
    assert_eq!(
        out, offline_text,
        "stdout: the offline causal solve, byte for byte"
    );
    let rec = std::fs::read_to_string(take.join("weights.csv")).unwrap();
    assert_eq!(rec, offline_text, "the recorded weights");
    let rows = weights_rows(&offline_text);

    // VMC: per bundle, Val for the 52 ARKit shapes and the rig's others, Apply, then the head.
    let jaw = rig.names.iter().position(|n| n == "jawOpen").unwrap();
    let mut facing = Vec::new();
    let mut told = Vec::new();
    for (j, b) in bundles.iter().enumerate() {
        let f = skip + j;
        let rosc::OscPacket::Bundle(b) = b else {
            panic!("a bundle")
        };
        let msgs: Vec<&rosc::OscMessage> = b
            .content
            .iter()
            .map(|p| match p {
                rosc::OscPacket::Message(m) => m,
                _ => panic!("flat"),
            })
            .collect();
        let vals: Vec<&&rosc::OscMessage> = msgs
            .iter()
            .filter(|m| m.addr == "/VMC/Ext/Blend/Val")
            .collect();
        assert_eq!(
            vals.len(),
            52 + 2,
            "52 ARKit shapes and ICT's cheekRaiser_L/R"
        );
        let apply = msgs
            .iter()
            .position(|m| m.addr == "/VMC/Ext/Blend/Apply")
            .unwrap();
        assert_eq!(apply, vals.len(), "Apply after every value");
        let head = msgs.last().unwrap();
        assert_eq!(head.addr, "/VMC/Ext/Bone/Pos");
        assert_eq!(head.args[0], rosc::OscType::String("Head".into()));
        assert_eq!(head.args.len(), 8);
        // Read as EVMC4U reads it: localPosition (x, y, z), localRotation (x, y, z, w), in
        // Unity's axes (left-handed: x the avatar's right, y up, z where it faces).
        let f32s: Vec<f32> = head.args[1..]
            .iter()
            .map(|a| match a {
                rosc::OscType::Float(v) => *v,
                _ => panic!("a float"),
            })
            .collect();
        assert_eq!(f32s[..3], [0.0, 0.1, 0.0], "the head above the neck");
        let q = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            f64::from(f32s[6]),
            f64::from(f32s[3]),
            f64::from(f32s[4]),
            f64::from(f32s[5]),
        ));
        // (Unity's rotation of a vector is the quaternion's, whatever the handedness.)
        let fwd = q * nalgebra::Vector3::z();
        facing.push((fwd.x, fwd.y));
        let value = |name: &str| {
            vals.iter()
                .find(|m| m.args[0] == rosc::OscType::String(name.into()))
                .map(|m| match m.args[1] {
                    rosc::OscType::Float(v) => v,
                    _ => panic!("a float"),
                })
                .unwrap()
        };
        assert_eq!(value("JawOpen"), rows[f][jaw] as f32, "frame {f}");
        let (n, fps, ll) = &packets[j];
        assert_eq!(*n as usize, f);
        // The rate the frames came at (sent at 60 a second), not a constant; a busy
        // machine's pauses move one frame's figure a little.
        assert!(
            (40..=90).contains(fps),
            "frame {f}: Live Link told {fps} fps"
        );
        told.push(*fps);
        assert_eq!(
            ll[17], rows[f][jaw] as f32,
            "Live Link's JawOpen (column 17), frame {f}"
        );
    }

    told.sort_unstable();
    assert!(
        (57..=63).contains(&told[told.len() / 2]),
        "Live Link's frame rate, median over the take: {}",
        told[told.len() / 2]
    );

    // The avatar faces where the person does: turning to the person's left (positive
    // yaw) is the avatar facing its own left, −x in Unity; nodding down (positive pitch)
    // is facing −y. Relative to the lead-in, where it looks ahead.
    let lead = st.lead_in;
    let neutral = keyshape_rig::camera::Camera::mean_pose(&track.cameras[..lead]);
    let truth: Vec<[f64; 3]> = track
        .cameras
        .iter()
        .skip(skip)
        .map(|c| c.relative_to(neutral))
        .collect();
    let side: Vec<f64> = truth.iter().map(|t| -t[0].sin()).collect();
    let down: Vec<f64> = truth.iter().map(|t| -t[1].sin()).collect();
    let fx: Vec<f64> = facing.iter().map(|f| f.0).collect();
    let fy: Vec<f64> = facing.iter().map(|f| f.1).collect();
    let (r_side, r_down) = (pearson(&side, &fx), pearson(&down, &fy));
    assert!(
        r_side > 0.98 && r_down > 0.9,
        "turn r {r_side}, nod r {r_down}"
    );
    let worst_side = side
        .iter()
        .zip(&fx)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(
        worst_side < 0.1,
        "the avatar's turn against the person's: {worst_side}"
    );

    // Against the weights it was rendered from: the shapes the performance drives.
    let mut rs = Vec::new();
    for (s, name) in rig.names.iter().enumerate() {
        let truth: Vec<f64> = (lead..frames).map(|f| track.truth[(s, f)]).collect();
        if truth.iter().cloned().fold(0.0, f64::max) < 0.2 {
            continue;
        }
        let got: Vec<f64> = (lead..frames).map(|f| rows[f][s]).collect();
        rs.push((name.clone(), pearson(&truth, &got)));
    }
    // (The live weights are the offline causal solve's, byte for byte, so they score as
    // it does. On this 160-frame take at 68 points: mean r 0.885, jawOpen 0.995, the
    // smiles 0.95–0.99; mouthFrown_L 0.15 and eyeWide_L 0.76 are what 68 points without a
    // neutral search lose.)
    let r_of = |n: &str| rs.iter().find(|r| r.0 == n).map(|r| r.1).unwrap();
    let mean = rs.iter().map(|r| r.1).sum::<f64>() / rs.len() as f64;
    assert!(rs.len() >= 8, "{rs:?}");
    assert!(mean > 0.85, "mean r {mean}: {rs:?}");
    assert!(
        r_of("jawOpen") > 0.99 && r_of("eyeBlink_R") > 0.97,
        "{rs:?}"
    );

    // The recording replays to the same weights.
    let replay = kslab(&[
        "live",
        "--from",
        &format!("file:{}", take.join("track.csv").display()),
        "--rate",
        "2000",
        "--calibrate",
        "20",
        "--to",
        "stdout",
    ]);
    assert_eq!(replay.code, 0, "{}", replay.stderr);
    assert_eq!(replay.stdout, offline_text);
}

/// A `kslab live` process: its standard output read as it comes on a thread (a full pipe
/// would hold the solve up), its standard error kept for the end.
pub(crate) struct Running {
    child: std::process::Child,
    stderr: std::process::ChildStderr,
    said: String,
    reader: std::thread::JoinHandle<String>,
}

impl Running {
    /// Starts `cmd` (its output piped); with `listening`, returns once the first line is on
    /// standard error — a UDP source has bound its socket by then.
    pub(crate) fn start(cmd: &mut Command, listening: bool) -> Running {
        let mut child = cmd
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut stderr = child.stderr.take().unwrap();
        let mut said = String::new();
        if listening {
            let mut first = [0u8; 12];
            stderr.read_exact(&mut first).unwrap();
            said = String::from_utf8_lossy(&first).into_owned();
        }
        let mut stdout = child.stdout.take().unwrap();
        let reader = std::thread::spawn(move || {
            let mut out = String::new();
            stdout.read_to_string(&mut out).unwrap();
            out
        });
        Running {
            child,
            stderr,
            said,
            reader,
        }
    }

    /// Sends `sig` and goes on running (SIGUSR1: recalibrate).
    pub(crate) fn signal(&self, sig: i32) {
        unsafe_free_kill(self.child.id(), sig);
    }

    /// Sends `sig`, waits for the end: (exit code, standard output, standard error).
    pub(crate) fn stop(mut self, sig: i32) -> (Option<i32>, String, String) {
        unsafe_free_kill(self.child.id(), sig);
        let out = self.reader.join().unwrap();
        let mut err = self.said;
        self.stderr.read_to_string(&mut err).unwrap();
        (self.child.wait().unwrap().code(), out, err)
    }
}

/// Sends `sig` to `pid`.
fn unsafe_free_kill(pid: u32, sig: i32) {
    let ok = Command::new("kill")
        .arg(format!("-{sig}"))
        .arg(pid.to_string())
        .status()
        .unwrap();
    assert!(ok.success());
}

#[test]
fn a_replayed_real_track_gives_the_files_causal_weights_and_a_readable_take() {
    let dir = tempfile::tempdir().unwrap();
    let track = shared("mediapipe_face_tracks/liveportrait_d18.csv");
    let take = dir.path().join("take");
    let live = kslab(&[
        "live",
        "--from",
        &format!("file:{}", track.display()),
        "--rate",
        "3000",
        "--to",
        "stdout",
        "--record",
        take.to_str().unwrap(),
        "--neutral-file",
        dir.path().join("cal.json").to_str().unwrap(),
    ]);
    assert_eq!(live.code, 0, "{}", live.stderr);
    let rig = kslab(&["rig", track.to_str().unwrap(), "--live"]);
    assert_eq!(rig.code, 0, "{}", rig.stderr);
    assert_eq!(live.stdout, rig.stdout, "a 468-point take, byte for byte");
    let again = kslab(&["rig", take.join("track.csv").to_str().unwrap(), "--live"]);
    assert_eq!(again.stdout, rig.stdout, "the recorded track");
    let cal = std::fs::read_to_string(dir.path().join("cal.json")).unwrap();
    assert!(cal.contains("\"frames\": 30"), "{cal}");
    // A recording never replaces an earlier take.
    let before = std::fs::read(take.join("weights.csv")).unwrap();
    let again = kslab(&[
        "live",
        "--from",
        &format!("file:{}", track.display()),
        "--to",
        "stdout",
        "--record",
        take.to_str().unwrap(),
    ]);
    assert_eq!(again.code, 1);
    assert!(again.stderr.contains("is not empty"), "{}", again.stderr);
    assert_eq!(std::fs::read(take.join("weights.csv")).unwrap(), before);
}

#[test]
fn bad_options_fail_before_anything_starts() {
    let d6 = shared("mediapipe_face_tracks/liveportrait_d6.csv");
    let file = format!("file:{}", d6.display());
    for (args, needle) in [
        (vec!["--from", "webcam:0", "--to", "stdout"], "not a source"),
        (
            vec!["--from", "openseeface:70000", "--to", "stdout"],
            "not a port number",
        ),
        (
            vec!["--from", "openseeface:0", "--to", "stdout"],
            "not a port number",
        ),
        (vec!["--from", &file, "--to", "osc:1"], "not a sink"),
        (vec!["--from", &file, "--to", "stdout,stdout"], "twice"),
        (
            vec!["--from", "openseeface", "--to", "stdout", "--rate", "30"],
            "--rate applies to a file",
        ),
        (
            vec!["--from", &file, "--to", "stdout", "--face", "1"],
            "--face applies",
        ),
        (
            vec!["--from", &file, "--to", "stdout", "--rate", "0"],
            "'0' for '--rate <FPS>': 0: give",
        ),
        (
            vec!["--from", &file, "--to", "stdout", "--calibrate", "0"],
            "calibrate",
        ),
        (
            vec!["--from", &file, "--to", "stdout", "--smooth", "-1"],
            "smooth",
        ),
        (
            vec!["--from", "file:/no/such.csv", "--to", "stdout"],
            "/no/such.csv",
        ),
        (
            vec![
                "--from",
                &file,
                "--to",
                "stdout",
                "--landmarks",
                "68",
                "--rig",
                "/no/rig",
            ],
            "/no/rig",
        ),
    ] {
        let mut all = vec!["live"];
        all.extend(args.iter().copied());
        let r = kslab(&all);
        assert_eq!(
            r.code,
            // (Refused by the command line's parser: a usage error.)
            if needle == "calibrate" || needle.contains("--rate <FPS>") {
                2
            } else {
                1
            },
            "{all:?}: {}",
            r.stderr
        );
        assert!(r.stderr.contains(needle), "{all:?}: {}", r.stderr);
        assert!(r.stdout.is_empty(), "{all:?}: nothing sent");
    }
}

/// `kslab tui --live` in tmux, receiving a replay of a shipped track as OpenSeeFace
/// datagrams: it calibrates, shows the weights and the rate, recalibrates on `n`, turns λ
/// on `l`, quits on `q`.
#[test]
fn the_live_lab_runs_in_tmux_on_a_replay() {
    assert!(
        Command::new("tmux").arg("-V").output().is_ok(),
        "tmux is needed for this test: install it (.ci/run does)"
    );
    let d6 = keyshape_io::read_sequence(
        &shared("mediapipe_face_tracks/liveportrait_d6.csv"),
        &keyshape_io::ReadOptions::default(),
    )
    .unwrap()
    .select_points(&keyshape_rig::mediapipe_to_ibug68().unwrap())
    .unwrap();
    let port = free_udp_port();
    let name = format!("kslab-live-{}", std::process::id());
    let tmux = |args: &[&str]| Command::new("tmux").args(args).output().unwrap();
    let out = tmux(&[
        "new-session",
        "-d",
        "-s",
        &name,
        "-x",
        "80",
        "-y",
        "24",
        env!("CARGO_BIN_EXE_kslab"),
        "tui",
        "--live",
        &format!("openseeface:127.0.0.1:{port}"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let capture =
        || String::from_utf8_lossy(&tmux(&["capture-pane", "-t", &name, "-p"]).stdout).into_owned();
    // The replay: 30 frames a second on a thread, the track cycled, until the test ends.
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let sender = {
        let done = done.clone();
        std::thread::spawn(move || {
            let send = UdpSocket::bind("127.0.0.1:0").unwrap();
            let mut f = 0usize;
            while !done.load(std::sync::atomic::Ordering::Relaxed) {
                let c = f % d6.n_frames();
                let pts: Vec<f64> = d6.coords.column(c).iter().copied().collect();
                let _ = send.send_to(&osf_face(f as f64 / 30.0, 3, &pts), ("127.0.0.1", port));
                f += 1;
                std::thread::sleep(Duration::from_millis(33));
            }
        })
    };
    let finish = |screen: &str, msg: &str| -> ! {
        done.store(true, std::sync::atomic::Ordering::Relaxed);
        tmux(&["kill-session", "-t", &name]);
        panic!("{msg}:\n{screen}");
    };
    let wait_for = |needle: &str| {
        for _ in 0..150 {
            let screen = capture();
            if screen.contains(needle) {
                return screen;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        finish(&capture(), &format!("'{needle}' never appeared"))
    };
    // While the person is told to look neutral, the face is drawn as it is tracked (its
    // contours in braille), not "no frame yet".
    let collecting = wait_for("look neutral: 1");
    let braille = collecting
        .chars()
        .filter(|c| ('\u{2801}'..='\u{28FF}').contains(c))
        .count();
    if collecting.contains("no frame yet") || braille < 40 {
        finish(&collecting, "no face drawn while calibrating");
    }
    let screen = wait_for("calibrated");
    // Weight bars with the rig's names, the rate, the landmarks panel.
    if !(screen.contains("weights") && screen.contains("tracked") && screen.contains(" fps")) {
        finish(&screen, "the live screen lacks a panel");
    }
    let named = [
        "jawOpen",
        "eyeBlink_L",
        "mouthSmile_L",
        "browDown_L",
        "eyeWide_L",
    ]
    .iter()
    .filter(|n| screen.contains(*n))
    .count();
    if named == 0 {
        finish(&screen, "no named weight bar");
    }
    tmux(&["send-keys", "-t", &name, "n"]);
    wait_for("recalibrating");
    wait_for("calibrated on 30 frames");
    tmux(&["send-keys", "-t", &name, "l"]);
    wait_for("λ 10");
    tmux(&["send-keys", "-t", &name, "q"]);
    for _ in 0..50 {
        if !tmux(&["has-session", "-t", &name]).status.success() {
            done.store(true, std::sync::atomic::Ordering::Relaxed);
            sender.join().unwrap();
            return;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    finish(&capture(), "kslab did not quit on q")
}

/// Recalibration on demand: a line `calibrate` on standard input (not the source) and
/// SIGUSR1 each start a new lead-in; a VMC receiver that is not there stops nothing.
#[test]
fn a_control_line_and_sigusr1_recalibrate_and_an_absent_receiver_stops_nothing() {
    use std::io::Write;
    let track = shared("mediapipe_face_tracks/liveportrait_d6.csv");
    let nobody = free_udp_port();
    let mut live = Running::start(
        Command::new(env!("CARGO_BIN_EXE_kslab"))
            .args(["live", "--from"])
            .arg(format!("file:{}", track.display()))
            .args([
                "--rate",
                "250",
                "--calibrate",
                "10",
                "--landmarks",
                "68",
                "--to",
            ])
            .arg(format!("vmc:127.0.0.1:{nobody},stdout"))
            .stdin(Stdio::piped()),
        false,
    );
    let mut stdin = live.child.stdin.take().unwrap();
    std::thread::sleep(Duration::from_millis(1000));
    writeln!(stdin, "calibrate").unwrap();
    stdin.flush().unwrap();
    std::thread::sleep(Duration::from_millis(1000));
    let (code, out, err) = live.stop(10); // SIGUSR1
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(
        err.matches("look neutral: recalibrating").count(),
        2,
        "{err}"
    );
    assert_eq!(err.matches("calibrated on 10 frames").count(), 3, "{err}");
    // Every frame of the file is solved (a recalibration's lead-in too), once.
    assert_eq!(out.lines().count(), 1 + 1008, "{err}");
    assert!(err.contains("1008 frames solved"), "{err}");
}

/// Several faces in a datagram: `--face ID` follows that one; without it, the first seen.
#[test]
fn face_follows_one_face_of_several() {
    let d6 = keyshape_io::read_sequence(
        &shared("mediapipe_face_tracks/liveportrait_d6.csv"),
        &keyshape_io::ReadOptions::default(),
    )
    .unwrap()
    .select_points(&keyshape_rig::mediapipe_to_ibug68().unwrap())
    .unwrap();
    let frames = 40;
    let dir = tempfile::tempdir().unwrap();
    // Face 9 is the track; face 5 the track 300 frames on, shifted.
    let face = |id: i32, f: usize| -> Vec<f64> {
        let c = if id == 9 { f } else { f + 300 };
        d6.coords
            .column(c)
            .iter()
            .map(|v| v + if id == 9 { 0.0 } else { 40.0 })
            .collect()
    };
    let solve_alone = |id: i32| -> String {
        let csv = csv70((0..frames).map(|f| osf_solved(&face(id, f))));
        let file = dir.path().join(format!("face{id}.csv"));
        std::fs::write(&file, csv).unwrap();
        let r = kslab(&["rig", file.to_str().unwrap(), "--live", "--neutral", "0-9"]);
        assert_eq!(r.code, 0, "{}", r.stderr);
        r.stdout
    };
    for (follow, want) in [(Some(9), 9), (None, 5)] {
        let port = free_udp_port();
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_kslab"));
        cmd.args([
            "live",
            "--from",
            &format!("openseeface:127.0.0.1:{port}"),
            "--to",
            "stdout",
            "--calibrate",
            "10",
            "--queue",
            "256",
        ]);
        if let Some(id) = follow {
            cmd.args(["--face", &id.to_string()]);
        }
        let live = Running::start(cmd.stdin(Stdio::null()), true);
        let send = UdpSocket::bind("127.0.0.1:0").unwrap();
        for f in 0..frames {
            // Face 5 first in the datagram, face 9 second.
            let d = [
                osf_face(f as f64 / OSF_FPS, 5, &face(5, f)),
                osf_face(f as f64 / OSF_FPS, 9, &face(9, f)),
            ]
            .concat();
            send.send_to(&d, ("127.0.0.1", port)).unwrap();
            std::thread::sleep(Duration::from_millis(5));
        }
        std::thread::sleep(Duration::from_millis(300));
        let (code, out, err) = live.stop(libc::SIGINT);
        assert_eq!(code, Some(0), "{err}");
        assert_eq!(
            out,
            solve_alone(want),
            "--face {follow:?}: face {want}'s weights"
        );
    }
}

/// A table on standard input is checked before anything starts: an image size for
/// coordinates in pixels is refused naming the line.
#[test]
fn an_image_size_for_a_pixel_table_on_stdin_is_refused_naming_the_line() {
    use std::io::Write;
    let text =
        std::fs::read_to_string(shared("mediapipe_face_tracks/liveportrait_d6.csv")).unwrap();
    let head: String = text.lines().take(5).map(|l| format!("{l}\n")).collect();
    let mut child = Command::new(env!("CARGO_BIN_EXE_kslab"))
        .args([
            "live",
            "--from",
            "stdin",
            "--to",
            "stdout",
            "--image-size",
            "640x480",
        ])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(head.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("stdin:2:1: an image size applies to normalised coordinates"),
        "{err}"
    );
    assert!(out.stdout.is_empty());
}

/// Runs `kslab live --from stdin` on `input` (written from another thread) to `--stats`;
/// returns (exit code, standard error, the stats JSON), or fails the test after 60 s —
/// a session that hangs is the fault.
fn live_on_stdin(input: Vec<u8>, extra: &[&str]) -> (Option<i32>, String, serde_json::Value) {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let stats = dir.path().join("stats.json");
    let mut child = Command::new(env!("CARGO_BIN_EXE_kslab"))
        .args([
            "live",
            "--from",
            "stdin",
            "--to",
            "stdout",
            "--calibrate",
            "5",
        ])
        .args(extra)
        .arg("--stats")
        .arg(&stats)
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let writer = std::thread::spawn(move || {
        let _ = stdin.write_all(&input);
    });
    let started = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if started.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            panic!("kslab live did not end within 60 s of its input's end");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    writer.join().unwrap();
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    let v = serde_json::from_str(&std::fs::read_to_string(&stats).unwrap_or_default())
        .unwrap_or(serde_json::Value::Null);
    (status.code(), err, v)
}

/// The shipped d6 track's first `n` frames as JSON lines, as a MediaPipe script prints them.
fn d6_json_lines(n: usize) -> Vec<String> {
    let seq = keyshape_io::read_sequence(
        &shared("mediapipe_face_tracks/liveportrait_d6.csv"),
        &keyshape_io::ReadOptions {
            format: None,
            dims: 2,
        },
    )
    .unwrap();
    (0..n)
        .map(|c| {
            let pts: Vec<String> = seq
                .coords
                .column(c)
                .as_slice()
                .chunks(2)
                .map(|p| format!("[{},{}]", p[0], p[1]))
                .collect();
            format!(
                "{{\"t\":{},\"points\":[{}]}}\n",
                c as f64 / 30.0,
                pts.join(",")
            )
        })
        .collect()
}

/// Out-of-range values on any source are malformed frames, counted and skipped: a landmark
/// at (1e200, 1e200) on a JSON line sent the frame solver into an endless loop that only
/// SIGKILL stopped; a non-UTF-8 line stopped reading for the rest of the session (0
/// malformed, exit 0); a line longer than the cap was held whole (1 GiB → 1.6 GB).
#[test]
fn every_source_bounds_its_values_and_lines_before_the_solve() {
    let lines = d6_json_lines(20);
    let mut input = Vec::new();
    for (i, l) in lines.iter().enumerate() {
        match i {
            8 => input.extend(
                l.replacen(
                    &l[l.find("[[").unwrap() + 1..l.find("],").unwrap() + 1],
                    "[1e200,1e200]",
                    1,
                )
                .as_bytes(),
            ),
            10 => input.extend(b"{\"t\": 1, \"points\": [[\xff\xfe, 1]]}\n"),
            12 => {
                input.extend(std::iter::repeat_n(b' ', keyshape_io::MAX_LINE_BYTES + 10));
                input.extend(b"\n");
            }
            14 => input.extend(l.replacen("{\"t\":", "{\"t\":1e308,\"x\":", 1).as_bytes()),
            _ => input.extend(l.as_bytes()),
        }
    }
    let (code, err, stats) = live_on_stdin(input, &[]);
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(stats["malformed"], 4, "{err}\n{stats}");
    // (A live source drops frames when the solve falls behind.)
    assert_eq!(stats["received"], 16, "{err}\n{stats}");
    let solved = stats["solved"].as_u64().unwrap() + stats["dropped"].as_u64().unwrap();
    assert_eq!(solved, 16, "{err}\n{stats}");
    // (Warnings are rate-limited: the first is said.)
    assert!(
        err.contains("landmark 0 x: coordinate 1e200 is beyond"),
        "{err}"
    );
}

/// An OpenSeeFace datagram with a point at (1e38, −1e38) was solved (weights pinned at 1)
/// and recorded (the take then unreadable); one with a time of 1e308 wrote a Live Link
/// timecode of `5124095576030431:00:15`. Both are malformed: counted and skipped, and the
/// take reads back.
#[test]
fn an_openseeface_datagram_out_of_range_is_malformed_and_the_take_reads_back() {
    let d6 = keyshape_io::read_sequence(
        &shared("mediapipe_face_tracks/liveportrait_d6.csv"),
        &keyshape_io::ReadOptions {
            format: None,
            dims: 2,
        },
    )
    .unwrap();
    let d6 = d6
        .select_points(&keyshape_rig::mediapipe_to_ibug68().unwrap())
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let take = dir.path().join("take");
    let stats = dir.path().join("stats.json");
    let port = free_udp_port();
    let live = Running::start(
        Command::new(env!("CARGO_BIN_EXE_kslab"))
            .args(["live", "--from", &format!("openseeface:127.0.0.1:{port}")])
            .args(["--to", "stdout", "--calibrate", "5", "--record"])
            .arg(&take)
            .arg("--stats")
            .arg(&stats),
        true,
    );
    let send = UdpSocket::bind("127.0.0.1:0").unwrap();
    for c in 0..20 {
        let mut pts: Vec<f64> = d6.coords.column(c).iter().copied().collect();
        let mut t = 1.7e9 + c as f64 / 30.0;
        match c {
            7 => {
                pts[10] = 1e38;
                pts[11] = -1e38;
            }
            9 => t = 1e308,
            _ => {}
        }
        send.send_to(&osf_face(t, 0, &pts), ("127.0.0.1", port))
            .unwrap();
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(500));
    let (code, _, err) = live.stop(libc::SIGINT);
    assert_eq!(code, Some(0), "{err}");
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    assert_eq!(stats["malformed"], 2, "{err}\n{stats}");
    assert_eq!(stats["received"], 18, "{err}\n{stats}");
    let back = kslab(&["rig", take.join("track.csv").to_str().unwrap(), "--live"]);
    assert_eq!(back.code, 0, "{}", back.stderr);
    let ll = std::fs::read_to_string(take.join("livelink.csv")).unwrap();
    assert!(ll.lines().skip(1).all(|l| l.starts_with("00:00:")), "{ll}");
}
