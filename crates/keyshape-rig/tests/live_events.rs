//! The live solve's session mechanics on a real track: the tracker's confidences (a point
//! not seen does not matter where it lies), a gap in time (the warm start dropped), a
//! calibration made off the solving thread (the same weights as inline), a recalibration
//! solved with the old calibration meanwhile, and a take replayed through its recorded
//! calibrations to the same weights, bit for bit.

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_io::{read_sequence, shared_data, ReadOptions};
use keyshape_rig::correspondence::read_rig;
use keyshape_rig::live::{
    replay, CalibrationEvent, LiveFrame, LiveSolver, Observation, Replay, ReplayEvent,
    GAP_RESTART_S,
};
use keyshape_rig::{Rig, RigOptions};
use nalgebra::DMatrix;

/// The shipped d6 track's first `frames` frames through the iBUG-68 subset, and the rig.
fn track(frames: usize) -> (Rig, DMatrix<f64>) {
    let path = shared_data("mediapipe_face_tracks/liveportrait_d6.csv").unwrap();
    let opts = ReadOptions {
        format: None,
        dims: 2,
    };
    let seq = read_sequence(&path, &opts).unwrap();
    let seq = seq
        .select_points(&keyshape_rig::mediapipe_to_ibug68().unwrap())
        .unwrap();
    let (_, _, rig) = read_rig(&shared_data("ict_facekit_face").unwrap(), 68, None).unwrap();
    let seq = seq.select_points(&rig.points).unwrap();
    (rig, seq.coords.columns(0, frames).into_owned())
}

fn obs(t: &DMatrix<f64>, c: usize, confidence: Option<Vec<f64>>, time: f64) -> Observation {
    Observation {
        points: t.column(c).iter().copied().collect(),
        confidence,
        time: Some(time),
    }
}

fn bits(a: &LiveFrame, b: &LiveFrame) -> bool {
    a.weights
        .iter()
        .zip(&b.weights)
        .all(|(x, y)| x.to_bits() == y.to_bits())
}

#[test]
fn a_point_not_seen_does_not_matter_where_it_lies() {
    let (rig, t) = track(40);
    let n = rig.landmarks();
    let mut a = LiveSolver::new(rig.clone(), RigOptions::live(), 10).unwrap();
    let mut b = LiveSolver::new(rig.clone(), RigOptions::live(), 10).unwrap();
    let mut conf = vec![0.9; n];
    conf[30] = 0.1; // the nose tip: below MIN_CONFIDENCE, not seen
    for c in 0..40 {
        let time = c as f64 / 30.0;
        let mut moved = obs(&t, c, Some(conf.clone()), time);
        if c >= 10 {
            // Thrown across the image on every frame after the lead-in.
            moved.points[60] += 500.0;
            moved.points[61] -= 300.0;
        }
        let x = a
            .push_observed(obs(&t, c, Some(conf.clone()), time))
            .unwrap();
        let y = b.push_observed(moved).unwrap();
        assert_eq!(x.len(), y.len());
        for (p, q) in x.iter().zip(&y) {
            assert!(bits(p, q), "frame {c}: the unseen point moved the weights");
            assert_eq!(p.rms.to_bits(), q.rms.to_bits(), "RMS over the points seen");
        }
    }
    // Seen, the same displacement changes the weights.
    let mut seen = vec![0.9; n];
    seen[30] = 0.9;
    let mut d = obs(&t, 20, Some(seen.clone()), 40.0 / 30.0);
    d.points[60] += 500.0;
    let moved = a.push_observed(d).unwrap();
    let clean = b
        .push_observed(obs(&t, 20, Some(seen), 40.0 / 30.0))
        .unwrap();
    assert!(!bits(&moved[0], &clean[0]));
}

#[test]
fn confidences_weigh_points_against_each_other_not_against_the_priors() {
    let (rig, t) = track(40);
    let n = rig.landmarks();
    let mut plain = LiveSolver::new(rig.clone(), RigOptions::live(), 10).unwrap();
    let mut even = LiveSolver::new(rig.clone(), RigOptions::live(), 10).unwrap();
    let mut uneven = LiveSolver::new(rig.clone(), RigOptions::live(), 10).unwrap();
    let mut most = 0.0f64;
    for c in 0..40 {
        let time = c as f64 / 30.0;
        let p = plain.push_observed(obs(&t, c, None, time)).unwrap();
        let e = even
            .push_observed(obs(&t, c, Some(vec![0.6; n]), time))
            .unwrap();
        // The mouth half as sure as the rest.
        let half: Vec<f64> = (0..n).map(|i| if i >= 48 { 0.45 } else { 0.9 }).collect();
        let u = uneven.push_observed(obs(&t, c, Some(half), time)).unwrap();
        for ((p, e), u) in p.iter().zip(&e).zip(&u) {
            let d = p
                .weights
                .iter()
                .zip(&e.weights)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(d < 1e-6, "frame {c}: a uniform 0.6 moved a weight by {d}");
            most = most.max(
                p.weights
                    .iter()
                    .zip(&u.weights)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max),
            );
        }
    }
    assert!(most > 1e-4, "the mouth's lower confidence changes nothing");
}

#[test]
fn a_frame_with_too_few_points_seen_is_refused_and_changes_nothing() {
    let (rig, t) = track(20);
    let n = rig.landmarks();
    let mut live = LiveSolver::new(rig, RigOptions::live(), 10).unwrap();
    for c in 0..10 {
        live.push_observed(obs(&t, c, None, c as f64 / 30.0))
            .unwrap();
    }
    let blind = vec![0.0; n];
    let e = live
        .push_observed(obs(&t, 10, Some(blind), 10.0 / 30.0))
        .unwrap_err();
    assert!(e.to_string().contains("too few to solve"), "{e}");
    let bad_len = live
        .push_observed(obs(&t, 10, Some(vec![1.0; 3]), 10.0 / 30.0))
        .unwrap_err();
    assert!(bad_len.to_string().contains("confidences"), "{bad_len}");
    let f = live.push_observed(obs(&t, 10, None, 10.0 / 30.0)).unwrap();
    assert_eq!(f[0].index, 10, "the refused frames took no index");
}

#[test]
fn after_a_gap_the_solve_starts_afresh() {
    let (rig, t) = track(60);
    let mut live = LiveSolver::new(rig.clone(), RigOptions::live(), 10).unwrap();
    for c in 0..30 {
        live.push_observed(obs(&t, c, None, c as f64 / 30.0))
            .unwrap();
    }
    let cal = live.calibration().unwrap().clone();
    // The next frame comes after a stretch with no face.
    let later = 30.0 / 30.0 + GAP_RESTART_S + 0.5;
    let after = live.push_observed(obs(&t, 45, None, later)).unwrap();
    // A solver that has seen nothing but the calibration solves it the same.
    let mut fresh = LiveSolver::new(rig.clone(), RigOptions::live(), 10).unwrap();
    fresh.set_calibration(cal.clone()).unwrap();
    let alone = fresh.push_observed(obs(&t, 45, None, later)).unwrap();
    assert!(bits(&after[0], &alone[0]), "restarted after the gap");
    // Without the gap the warm start carries on, and the weights differ.
    let mut warm = LiveSolver::new(rig, RigOptions::live(), 10).unwrap();
    for c in 0..30 {
        warm.push_observed(obs(&t, c, None, c as f64 / 30.0))
            .unwrap();
    }
    let carried = warm.push_observed(obs(&t, 45, None, 31.0 / 30.0)).unwrap();
    assert!(!bits(&carried[0], &alone[0]), "the warm start is kept");
}

/// Pushes frames `range` (timed at 30 fps), collecting what comes out.
fn feed(live: &mut LiveSolver, t: &DMatrix<f64>, range: std::ops::Range<usize>) -> Vec<LiveFrame> {
    let mut out = Vec::new();
    for c in range {
        out.extend(
            live.push_observed(obs(t, c, None, c as f64 / 30.0))
                .unwrap(),
        );
    }
    out
}

#[test]
fn a_calibration_made_off_the_thread_solves_as_one_made_inline() {
    let (rig, t) = track(60);
    let mut inline = LiveSolver::new(rig.clone(), RigOptions::live(), 15).unwrap();
    let want = feed(&mut inline, &t, 0..60);
    let mut bg = LiveSolver::new(rig, RigOptions::live(), 15).unwrap();
    bg.set_background(true);
    let mut got = feed(&mut bg, &t, 0..15);
    assert!(got.is_empty());
    let job = bg.take_job().expect("the lead-in made a job");
    // Frames keep coming while it runs: held (no calibration may solve them yet).
    got.extend(feed(&mut bg, &t, 15..22));
    assert!(got.is_empty());
    assert_eq!(bg.collected(), (15, 15));
    let done = std::thread::spawn(move || job.run()).join().unwrap();
    got.extend(bg.install(done));
    assert_eq!(got.len(), 22, "the lead-in and the frames held");
    got.extend(feed(&mut bg, &t, 22..60));
    assert_eq!(got.len(), want.len());
    for (f, (a, b)) in want.iter().zip(&got).enumerate() {
        assert_eq!(a.index, f as u64);
        assert_eq!(b.index, f as u64);
        assert!(bits(a, b), "frame {f}");
    }
    let events = bg.take_events();
    assert_eq!(events.len(), 1);
    assert_eq!((events[0].from, events[0].lead_in), (0, Some([0, 14])));
}

#[test]
fn a_recalibration_solves_with_the_old_calibration_meanwhile_and_replays() {
    let (rig, t) = track(120);
    let opts = RigOptions::live();
    let mut live = LiveSolver::new(rig.clone(), opts, 20).unwrap();
    live.set_background(true);
    let mut out = feed(&mut live, &t, 0..20);
    let job = live.take_job().unwrap();
    out.extend(feed(&mut live, &t, 20..23));
    out.extend(live.install(job.run()));
    out.extend(feed(&mut live, &t, 23..50));
    // The person asks for a new calibration: the avatar keeps moving.
    live.recalibrate(true);
    let during = feed(&mut live, &t, 50..70);
    assert_eq!(
        during.len(),
        20,
        "every lead-in frame solved with the old calibration"
    );
    out.extend(during);
    let job = live.take_job().unwrap();
    out.extend(feed(&mut live, &t, 70..75));
    // A stale job (a recalibration asked for while one is made) is dropped.
    let stale = {
        let mut other = LiveSolver::new(rig.clone(), opts, 20).unwrap();
        other.set_background(true);
        feed(&mut other, &t, 0..20);
        other.take_job().unwrap()
    };
    assert!(live.install(stale.run()).is_empty());
    out.extend(live.install(job.run()));
    out.extend(feed(&mut live, &t, 75..120));
    assert_eq!(out.len(), 120);
    assert!(out.iter().enumerate().all(|(f, s)| s.index == f as u64));
    let mut events: Vec<CalibrationEvent> = live.take_events();
    assert_eq!(events.len(), 2);
    assert_eq!((events[1].from, events[1].lead_in), (75, Some([50, 69])));
    // Replayed through the recorded calibrations: the same weights, bit for bit.
    let as_replay: Vec<ReplayEvent> = events
        .drain(..)
        .map(|e| ReplayEvent {
            from: e.from as usize,
            lead_in: e.lead_in.map(|[a, b]| a as usize..b as usize + 1),
            calibration: Some(e.calibration),
        })
        .collect();
    let times: Vec<f64> = (0..120).map(|c| c as f64 / 30.0).collect();
    let take = Replay {
        track: &t,
        confidence: None,
        times: Some(&times),
        events: &as_replay,
    };
    let r = replay(&rig, &opts, &take).unwrap();
    for (f, s) in out.iter().enumerate() {
        let col = r.weights.column(f);
        assert!(
            col.iter()
                .zip(&s.weights)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "frame {f}"
        );
    }
    assert_eq!(r.people.len(), 2);
    // A recorded calibration its lead-in no longer gives (another rig's, say) is refused.
    let mut wrong = as_replay.clone();
    if let Some(c) = wrong[1].calibration.as_mut() {
        c.iod *= 1.5;
    }
    let e = replay(
        &rig,
        &opts,
        &Replay {
            events: &wrong,
            ..take
        },
    )
    .unwrap_err();
    assert!(
        e.to_string()
            .contains("another calibration than the take recorded"),
        "{e}"
    );
}
