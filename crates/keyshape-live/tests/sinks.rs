//! The sinks as receivers read them: a VMC bundle as EVMC4U applies it (Unity's axes), a
//! Live Link packet at the fixed offsets PyLiveLinkFace-style decoders read, and the
//! mirror flipping head and face together.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_live::sink::{SinkOptions, SinkSpec, Sinks};
use keyshape_rig::Rig;
use std::net::UdpSocket;
use std::time::{Duration, Instant};

fn rig() -> Rig {
    Rig::read_ict(&keyshape_io::shared_data("ict_facekit_face").unwrap()).unwrap()
}

/// The head bone as sent: local position, local rotation (x, y, z, w).
type Bone = ([f32; 3], [f32; 4]);

/// One frame through a VMC sink: (blend values by name, the head bone).
fn vmc_frame(
    options: SinkOptions,
    w: &[f64],
    head: [f64; 3],
) -> (Vec<(String, f32)>, Option<Bone>) {
    let recv = UdpSocket::bind("127.0.0.1:0").unwrap();
    recv.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let spec = SinkSpec::Vmc(recv.local_addr().unwrap());
    let mut sinks = Sinks::open(&[spec], &rig(), Box::new(std::io::sink()), 30.0, options).unwrap();
    sinks.send(0, (w, head), Instant::now(), true).unwrap();
    let mut buf = vec![0u8; 65_536];
    let n = recv.recv(&mut buf).unwrap();
    let rosc::OscPacket::Bundle(b) = rosc::decoder::decode_udp(&buf[..n]).unwrap().1 else {
        panic!("a bundle")
    };
    let mut vals = Vec::new();
    let mut bone = None;
    for p in b.content {
        let rosc::OscPacket::Message(m) = p else {
            panic!("flat")
        };
        let f = |i: usize| match m.args[i] {
            rosc::OscType::Float(v) => v,
            _ => panic!("a float"),
        };
        match m.addr.as_str() {
            "/VMC/Ext/Blend/Val" => {
                let rosc::OscType::String(name) = &m.args[0] else {
                    panic!("a name")
                };
                vals.push((name.clone(), f(1)));
            }
            "/VMC/Ext/Bone/Pos" => bone = Some(([f(1), f(2), f(3)], [f(4), f(5), f(6), f(7)])),
            _ => {}
        }
    }
    (vals, bone)
}

/// Where a Unity avatar's face points under the local rotation (x, y, z, w): x its right.
fn facing(q: [f32; 4]) -> [f64; 3] {
    let q = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
        f64::from(q[3]),
        f64::from(q[0]),
        f64::from(q[1]),
        f64::from(q[2]),
    ));
    let v = q * nalgebra::Vector3::z();
    [v.x, v.y, v.z]
}

/// The person smiles on their left and turns to their left: by default the avatar smiles
/// on its left and faces its left (−x); mirrored, it smiles on its right and faces its
/// right, head and face flipped together. The head bone sits where the options put it.
#[test]
fn the_avatar_turns_and_smiles_on_the_persons_side_unless_mirrored() {
    let rig = rig();
    let mut w = vec![0.0; rig.k()];
    w[rig.names.iter().position(|n| n == "mouthSmile_L").unwrap()] = 0.8;
    let yaw = 0.4;
    let value = |vals: &[(String, f32)], n: &str| vals.iter().find(|v| v.0 == n).unwrap().1;
    let (vals, bone) = vmc_frame(SinkOptions::default(), &w, [yaw, 0.0, 0.0]);
    let (pos, rot) = bone.unwrap();
    assert_eq!(pos, [0.0, 0.1, 0.0]);
    assert_eq!(
        (
            value(&vals, "MouthSmileLeft"),
            value(&vals, "MouthSmileRight")
        ),
        (0.8, 0.0)
    );
    let f = facing(rot);
    assert!((f[0] + yaw.sin()).abs() < 1e-6, "faces its left: {f:?}");
    let mirrored = SinkOptions {
        mirror: true,
        head_position: Some([0.0, 0.07, 0.01]),
        ..SinkOptions::default()
    };
    let (vals, bone) = vmc_frame(mirrored, &w, [yaw, 0.0, 0.0]);
    let (pos, rot) = bone.unwrap();
    assert_eq!(pos, [0.0, 0.07, 0.01]);
    assert_eq!(
        (
            value(&vals, "MouthSmileLeft"),
            value(&vals, "MouthSmileRight")
        ),
        (0.0, 0.8)
    );
    let f = facing(rot);
    assert!((f[0] - yaw.sin()).abs() < 1e-6, "faces its right: {f:?}");
    // A nod down is a nod down either way; no bone when asked for none.
    for mirror in [false, true] {
        let o = SinkOptions {
            mirror,
            head_position: None,
            ..SinkOptions::default()
        };
        let (_, bone) = vmc_frame(o, &w, [0.0, 0.3, 0.0]);
        assert!(bone.is_none());
        let (_, bone) = vmc_frame(
            SinkOptions {
                mirror,
                ..SinkOptions::default()
            },
            &w,
            [0.0, 0.3, 0.0],
        );
        let f = facing(bone.unwrap().1);
        assert!((f[1] + 0.3f64.sin()).abs() < 1e-6, "{f:?}");
    }
}

/// A writer that takes a line every `pause` (a reader that has stalled), or fails (one that
/// went away), keeping what it took.
struct Slow {
    pause: Duration,
    fail: bool,
    took: std::sync::Arc<std::sync::Mutex<Vec<u8>>>,
}

impl std::io::Write for Slow {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        if self.fail {
            return Err(std::io::Error::new(
                std::io::ErrorKind::BrokenPipe,
                "reader gone",
            ));
        }
        std::thread::sleep(self.pause);
        self.took.lock().unwrap().extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

fn slow(pause_ms: u64, fail: bool) -> (Box<Slow>, std::sync::Arc<std::sync::Mutex<Vec<u8>>>) {
    let took = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let w = Slow {
        pause: Duration::from_millis(pause_ms),
        fail,
        took: took.clone(),
    };
    (Box::new(w), took)
}

/// A stalled standard-output reader does not stall the solve: a live source's frames are
/// handed off at once and the ones the table could not take counted; a file replayed waits
/// and loses nothing; a reader that went away ends the session, named.
#[test]
fn a_stalled_reader_never_stalls_the_solve() {
    let rig = rig();
    let w = vec![0.1; rig.k()];
    let (out, took) = slow(20, false);
    let mut live =
        Sinks::open(&[SinkSpec::Stdout], &rig, out, 30.0, SinkOptions::default()).unwrap();
    let t0 = Instant::now();
    for f in 0..200 {
        live.send(f, (&w, [0.0; 3]), Instant::now(), true).unwrap();
    }
    let handing = t0.elapsed();
    // 200 lines at 20 ms each would take 4 s on the solve's thread.
    assert!(handing < Duration::from_millis(500), "{handing:?}");
    assert!(
        live.behind() > 0,
        "the lines the table could not take are counted"
    );
    live.close().unwrap();
    let lines = String::from_utf8(took.lock().unwrap().clone()).unwrap();
    assert_eq!(
        lines.lines().count() as u64,
        1 + 200 - live.behind(),
        "the header and each line handed off, whole"
    );

    let (out, took) = slow(1, false);
    let wait = SinkOptions {
        wait: true,
        ..SinkOptions::default()
    };
    let mut file = Sinks::open(&[SinkSpec::Stdout], &rig, out, 30.0, wait).unwrap();
    for f in 0..150 {
        file.send(f, (&w, [0.0; 3]), Instant::now(), f % 2 == 0)
            .unwrap();
    }
    file.close().unwrap();
    assert_eq!(file.behind(), 0);
    let lines = String::from_utf8(took.lock().unwrap().clone()).unwrap();
    let frames: Vec<&str> = lines
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap())
        .collect();
    let want: Vec<String> = (0..150).map(|f| f.to_string()).collect();
    assert_eq!(
        frames, want,
        "every frame, in order, the table takes every frame"
    );

    let (out, _) = slow(0, true);
    let mut gone =
        Sinks::open(&[SinkSpec::Stdout], &rig, out, 30.0, SinkOptions::default()).unwrap();
    let mut err = None;
    for f in 0..50 {
        if let Err(e) = gone.send(f, (&w, [0.0; 3]), Instant::now(), true) {
            err = Some(e);
            break;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let e = err
        .or_else(|| gone.close().err())
        .expect("the failure is reported");
    assert!(e.to_string().contains("standard output"), "{e}");
}
