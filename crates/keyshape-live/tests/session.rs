//! A session in-process, frames from a queue to a table and a recording: the calibration
//! made on its own thread while frames keep coming, a recalibration that keeps the avatar
//! moving, every frame recorded once, and the take replaying through its calibrations.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_live::session::{Served, Session};
use keyshape_live::sink::{RecordedCalibration, Recorder, SinkOptions, SinkSpec, Sinks};
use keyshape_live::{Counters, Frame, Queue};
use keyshape_rig::live::{replay, LiveSolver, Replay, ReplayEvent};
use keyshape_rig::RigOptions;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// A writer the test reads back.
#[derive(Clone, Default)]
struct Shared(Arc<Mutex<Vec<u8>>>);

impl std::io::Write for Shared {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[test]
fn a_session_calibrates_off_the_thread_recalibrates_and_replays() {
    let data = keyshape_io::shared_data("mediapipe_face_tracks/liveportrait_d6.csv").unwrap();
    let opts = keyshape_io::ReadOptions {
        format: None,
        dims: 2,
    };
    let seq = keyshape_io::read_sequence(&data, &opts).unwrap();
    let seq = seq
        .select_points(&keyshape_rig::mediapipe_to_ibug68().unwrap())
        .unwrap();
    let ict = keyshape_io::shared_data("ict_facekit_face").unwrap();
    let (_, _, rig) = keyshape_rig::correspondence::read_rig(&ict, 68, None).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let take = dir.path().join("take");
    let out = Shared::default();
    let wait = SinkOptions {
        wait: true,
        ..SinkOptions::default()
    };
    let sinks = Sinks::open(&[SinkSpec::Stdout], &rig, Box::new(out.clone()), 30.0, wait).unwrap();
    let recorder = Recorder::create(&take, &rig, (68, false), 30.0).unwrap();
    let solver = LiveSolver::new(rig.clone(), RigOptions::live(), 20).unwrap();
    let mut session = Session::new(solver, sinks, Some(recorder), rig.points.clone());
    let (queue, counters) = (Queue::new(256, true), Counters::default());
    let frames = 150;
    let mut calibrated = 0;
    for f in 0..frames {
        if f == 80 {
            // (Frames come here faster than any tracker sends them: let the first
            // calibration be made before asking for another, as a person would.)
            while session.solver().calibrating() {
                if let Served::Calibrated(_) =
                    session.serve(&queue, Duration::from_millis(20)).unwrap()
                {
                    calibrated += 1;
                }
            }
            session.recalibrate();
        }
        queue.push(
            Frame {
                number: f as i64,
                time: f as f64 / 30.0,
                points: seq.coords.column(f).iter().copied().collect(),
                confidence: None,
                arrived: Instant::now(),
                new_face: None,
            },
            &counters,
        );
        match session.serve(&queue, Duration::from_millis(50)).unwrap() {
            Served::Took(keyshape_live::session::Step::Calibrated(_)) | Served::Calibrated(_) => {
                calibrated += 1
            }
            _ => {}
        }
        if f == 85 {
            assert!(session.solver().calibrating(), "collecting the new lead-in");
        }
    }
    // The last calibration, if still being made, is taken into use by the end.
    while let Served::Calibrated(_) = session.serve(&queue, Duration::from_millis(200)).unwrap() {
        calibrated += 1;
    }
    session.finish().unwrap();
    assert!(calibrated >= 1, "a calibration said");
    assert_eq!(session.solved(), frames as u64, "every frame solved once");
    let table = String::from_utf8(out.0.lock().unwrap().clone()).unwrap();
    assert_eq!(
        table.lines().count(),
        frames + 1,
        "the table takes every frame"
    );
    let weights = std::fs::read_to_string(take.join("weights.csv")).unwrap();
    assert_eq!(weights, table, "the recording holds what was sent");
    // Two calibrations recorded; the second solves from a frame after its lead-in (the old
    // one solved the lead-in meanwhile).
    let cals: Vec<RecordedCalibration> = std::fs::read_to_string(take.join("calibrations.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(cals.len(), 2);
    assert_eq!((cals[0].from, cals[0].lead_in), (0, Some([0, 19])));
    let [a, b] = cals[1].lead_in.unwrap();
    assert_eq!((a, b), (80, 99));
    assert!(cals[1].from > b, "{:?}", cals[1].from);
    // The take replays through them to the same weights.
    let events: Vec<ReplayEvent> = cals
        .iter()
        .map(|c| ReplayEvent {
            from: c.from as usize,
            lead_in: c.lead_in.map(|[a, b]| a as usize..b as usize + 1),
            calibration: Some(c.calibration.clone()),
        })
        .collect();
    let track = seq.select_points(&rig.points).unwrap();
    let cols = track.coords.columns(0, frames).into_owned();
    let times: Vec<f64> = (0..frames).map(|f| f as f64 / 30.0).collect();
    let r = replay(
        &rig,
        &RigOptions::live(),
        &Replay {
            track: &cols,
            confidence: None,
            times: Some(&times),
            events: &events,
        },
    )
    .unwrap();
    for (f, line) in table.lines().skip(1).enumerate() {
        let got: Vec<f64> = line
            .split(',')
            .skip(1)
            .map(|v| v.parse().unwrap())
            .collect();
        let want: Vec<f64> = r.weights.column(f).iter().copied().collect();
        let as_written: Vec<f64> = want
            .iter()
            .map(|v| keyshape_io::fmt_num(*v).parse().unwrap())
            .collect();
        assert_eq!(got, as_written, "frame {f}");
    }
}
