//! The OpenSeeFace source against what the real tracker sent: the captures in
//! `../shared/data/openseeface_captures` (OpenSeeFace at dee5bb7, model 0, on LivePortrait
//! driving videos), not datagrams built from the protocol's documentation.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_live::openseeface::{capture_records, decode, Face, IBUG70_POINTS};
use keyshape_live::source::{open, SourceOptions, SourceSpec};
use keyshape_live::{Counters, Popped, Queue};
use std::net::UdpSocket;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

const CAPTURES: [(&str, usize); 3] = [
    ("liveportrait_d11.osfcap", 225),
    ("liveportrait_d11_nogaze.osfcap", 225),
    ("liveportrait_d14.osfcap", 536),
];

fn capture(name: &str) -> Vec<u8> {
    let p = keyshape_io::shared_data(&format!("openseeface_captures/{name}")).unwrap();
    std::fs::read(p).unwrap()
}

fn faces(name: &str) -> Vec<Face> {
    let bytes = capture(name);
    capture_records(&bytes)
        .unwrap()
        .into_iter()
        .map(|(_, d)| {
            let mut f = decode(d).unwrap();
            assert_eq!(f.len(), 1, "{name}: one face per datagram");
            f.remove(0)
        })
        .collect()
}

fn pt(p: &[f64], i: usize) -> [f64; 2] {
    [p[2 * i], p[2 * i + 1]]
}

/// How many of a frame's mouth checks fail, for a frame in iBUG order: the corners 60 and
/// 64 are the mouth's leftmost and rightmost points, the upper lip lies above the lower
/// (outer 51 above inner 62 above inner 66 above outer 57, 1 px to spare), the nose tip
/// between the eyes and the mouth.
fn mouth_faults(p: &[f64]) -> usize {
    let lips: Vec<usize> = (49..68).filter(|&i| i != 54).collect();
    let xs: Vec<f64> = lips.iter().map(|&i| pt(p, i)[0]).collect();
    let (lo, hi) = xs
        .iter()
        .fold((f64::MAX, f64::MIN), |(l, h), &x| (l.min(x), h.max(x)));
    let y = |i| pt(p, i)[1];
    let eyes = (y(36) + y(45)) / 2.0;
    [
        pt(p, 60)[0] <= lo + 1.0,
        pt(p, 64)[0] >= hi - 1.0,
        y(51) <= y(62) + 1.0,
        y(62) <= y(66) + 1.0,
        y(66) <= y(57) + 1.0,
        eyes < y(30) && y(30) < y(51),
    ]
    .iter()
    .filter(|ok| !**ok)
    .count()
}

/// Every captured datagram decodes to one tracked face of a 512 × 512 video, and put in
/// iBUG order its mouth is a mouth in every frame — which reading OpenSeeFace's points as
/// iBUG 68 (what kslab did) fails on nearly every frame.
#[test]
fn the_real_trackers_points_land_where_ibug_has_them() {
    for (name, count) in CAPTURES {
        let faces = faces(name);
        assert_eq!(faces.len(), count, "{name}: datagrams (the data's README)");
        let mut misread = 0;
        for (k, f) in faces.iter().enumerate() {
            assert!(
                f.success && f.id == 0 && f.size == [512.0, 512.0],
                "{name} {k}"
            );
            let (p, _) = f.ibug70();
            assert_eq!(p.len(), 2 * IBUG70_POINTS);
            assert_eq!(mouth_faults(&p), 0, "{name} frame {k}");
            // The untracked outer corners repeat the inner ones.
            assert_eq!((pt(&p, 48), pt(&p, 54)), (pt(&p, 60), pt(&p, 64)));
            if mouth_faults(&f.points) > 0 {
                misread += 1;
            }
        }
        assert!(
            misread == count,
            "{name}: read as iBUG 68, {misread} of {count} frames have a broken mouth"
        );
    }
}

/// The pupils: with gaze tracking, inside their eyes' outlines (the eye's six points'
/// box, 2 px to spare) on nearly every frame; without it (`--gaze-tracking 0`: (0, 0),
/// confidence 0), at the eye's centre — and the other 66 points are the gaze capture's.
#[test]
fn pupils_are_in_their_eyes_and_an_untracked_pupil_looks_ahead() {
    let gaze = faces("liveportrait_d11.osfcap");
    let off = faces("liveportrait_d11_nogaze.osfcap");
    let mut inside = 0;
    for (g, o) in gaze.iter().zip(&off) {
        let (pg, ug) = g.ibug70();
        let (po, uo) = o.ibug70();
        assert_eq!(uo, [true, true]);
        assert_eq!(
            &pg[..136],
            &po[..136],
            "the landmarks do not depend on gaze"
        );
        for (side, eye) in [(0usize, 36usize), (1, 42)] {
            let ring: Vec<[f64; 2]> = (eye..eye + 6).map(|i| pt(&po, i)).collect();
            let centre = [0, 1].map(|a| ring.iter().map(|q| q[a]).sum::<f64>() / 6.0);
            assert_eq!(pt(&po, 68 + side), centre);
            if !ug[side] {
                let p = pt(&pg, 68 + side);
                let within = (0..2).all(|a| {
                    let lo = ring.iter().map(|q| q[a]).fold(f64::MAX, f64::min);
                    let hi = ring.iter().map(|q| q[a]).fold(f64::MIN, f64::max);
                    p[a] >= lo - 2.0 && p[a] <= hi + 2.0
                });
                inside += usize::from(within);
            }
        }
    }
    assert!(
        inside as f64 >= 0.95 * (2 * gaze.len()) as f64,
        "{inside} of {} pupils inside their eyes",
        2 * gaze.len()
    );
}

/// An OpenSeeFace source listening on a free loopback port, its thread running.
struct Running {
    to: std::net::SocketAddr,
    queue: Arc<Queue>,
    counters: Arc<Counters>,
    stop: Arc<AtomicBool>,
    thread: std::thread::JoinHandle<()>,
}

fn running_source() -> Running {
    let port = UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let spec = SourceSpec::parse(&format!("openseeface:127.0.0.1:{port}")).unwrap();
    let opened = open(&spec, &SourceOptions::default(), Box::new(std::io::empty())).unwrap();
    assert_eq!(opened.layout, IBUG70_POINTS);
    let to = opened.address().unwrap();
    let queue = Arc::new(Queue::new(1024, false));
    let counters = Arc::new(Counters::default());
    let stop = Arc::new(AtomicBool::new(false));
    let thread = opened.spawn(
        queue.clone(),
        counters.clone(),
        stop.clone(),
        Box::new(|_| {}),
    );
    Running {
        to,
        queue,
        counters,
        stop,
        thread,
    }
}

/// The source over loopback: the captured datagrams arrive as 70-point frames in iBUG
/// order, the tracker's time kept; a face whose 3-D fit failed is counted as untracked and
/// not queued; a cut datagram is malformed.
#[test]
fn the_source_delivers_captured_datagrams_as_ibug_frames_and_skips_failed_fits() {
    let bytes = capture("liveportrait_d14.osfcap");
    let records = capture_records(&bytes).unwrap();
    let Running {
        to,
        queue,
        counters,
        stop,
        thread,
    } = running_source();
    let send = UdpSocket::bind("127.0.0.1:0").unwrap();
    let sent = 60;
    for (k, (_, d)) in records.iter().take(sent).enumerate() {
        let mut d = d.to_vec();
        if k == 10 {
            d[28] = 0; // success: the tracker's 3-D fit failed
        }
        send.send_to(&d, to).unwrap();
        if k == 20 {
            send.send_to(&d[..100], to).unwrap();
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let mut got = Vec::new();
    while got.len() < sent - 1 {
        match queue.pop(Duration::from_secs(5)) {
            Popped::Frame(f) => got.push(f),
            _ => break,
        }
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    thread.join().unwrap();
    let want: Vec<(usize, Face)> = records
        .iter()
        .take(sent)
        .enumerate()
        .filter(|(k, _)| *k != 10)
        .map(|(k, (_, d))| (k, decode(d).unwrap().remove(0)))
        .collect();
    assert_eq!(got.len(), want.len());
    for (f, (k, face)) in got.iter().zip(&want) {
        assert_eq!(f.points, face.ibug70().0, "datagram {k}");
        assert_eq!(f.time, face.time);
    }
    let (received, malformed, dropped) = counters.get();
    let untracked = counters
        .untracked
        .load(std::sync::atomic::Ordering::Relaxed);
    assert_eq!((received, malformed, dropped, untracked), (59, 1, 0, 1));
}

/// Another tracker for the same face id (a new sender), or another image size, marks the
/// next frame as a new face; faces of other ids are counted, not queued.
#[test]
fn a_new_sender_or_image_size_begins_a_new_face_and_other_faces_are_counted() {
    let bytes = capture("liveportrait_d11.osfcap");
    let records = capture_records(&bytes).unwrap();
    let Running {
        to,
        queue,
        counters,
        stop,
        thread,
    } = running_source();
    let (a, b) = (
        UdpSocket::bind("127.0.0.1:0").unwrap(),
        UdpSocket::bind("127.0.0.1:0").unwrap(),
    );
    for k in 0..12 {
        let mut d = records[k].1.to_vec();
        if k >= 8 {
            d[12..16].copy_from_slice(&640f32.to_le_bytes()); // another image width
        }
        if k == 2 {
            // A second face, id 7, after the followed one.
            let mut other = d.clone();
            other[8..12].copy_from_slice(&7i32.to_le_bytes());
            d.extend(other);
        }
        let from = if k < 4 { &a } else { &b };
        from.send_to(&d, to).unwrap();
        std::thread::sleep(Duration::from_millis(5));
    }
    let mut got = Vec::new();
    while got.len() < 12 {
        match queue.pop(Duration::from_secs(5)) {
            Popped::Frame(f) => got.push(f),
            _ => break,
        }
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    thread.join().unwrap();
    let marked: Vec<(usize, String)> = got
        .iter()
        .enumerate()
        .filter_map(|(k, f)| f.new_face.clone().map(|w| (k, w)))
        .collect();
    assert_eq!(marked.len(), 2, "{marked:?}");
    assert_eq!(marked[0].0, 4);
    assert!(marked[0].1.contains("face 0 now comes from"), "{marked:?}");
    assert_eq!(marked[1].0, 8);
    assert!(
        marked[1]
            .1
            .contains("the image size changed from 512x512 to 640x512"),
        "{marked:?}"
    );
    assert_eq!(
        counters
            .other_faces
            .load(std::sync::atomic::Ordering::Relaxed),
        1
    );
}
