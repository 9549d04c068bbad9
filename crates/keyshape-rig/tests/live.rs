//! The frame-by-frame solve against the file's causal solve on real tracks: the same
//! weights, bit for bit, however the frames arrive; calibration saved and loaded; bad
//! frames refused without changing the state.

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_core::ErrorKind;
use keyshape_io::{read_sequence, shared_data, ReadOptions};
use keyshape_rig::correspondence::read_rig;
use keyshape_rig::live::LiveSolver;
use keyshape_rig::{solve_rig, Neutral, Rig, RigOptions, SmoothUnit, LIVE_SMOOTH};
use nalgebra::DMatrix;

/// A shipped MediaPipe track read through `layout` points (68: the iBUG subset; 468:
/// dense), its first `frames` frames, and the ICT rig for it.
fn track(layout: usize, frames: usize) -> (Rig, DMatrix<f64>) {
    let path = shared_data("mediapipe_face_tracks/liveportrait_d6.csv").unwrap();
    let seq = read_sequence(
        &path,
        &ReadOptions {
            format: None,
            dims: 2,
        },
    )
    .unwrap();
    let seq = if layout == 68 {
        seq.select_points(&keyshape_rig::mediapipe_to_ibug68().unwrap())
            .unwrap()
    } else {
        seq
    };
    let (_, _, rig) = read_rig(&shared_data("ict_facekit_face").unwrap(), layout, None).unwrap();
    let seq = seq.select_points(&rig.points).unwrap();
    let n = frames.min(seq.n_frames());
    (rig, seq.coords.columns(0, n).into_owned())
}

fn live_weights(solver: &mut LiveSolver, track: &DMatrix<f64>) -> DMatrix<f64> {
    let mut out = Vec::new();
    for c in 0..track.ncols() {
        let col: Vec<f64> = track.column(c).iter().copied().collect();
        out.extend(solver.push(&col).unwrap());
    }
    assert_eq!(out.len(), track.ncols(), "every frame is solved once");
    DMatrix::from_fn(solver.rig().k(), out.len(), |s, f| out[f].weights[s])
}

#[test]
fn the_live_solve_is_the_files_causal_solve_bit_for_bit() {
    // The live default (λ relative to the face), a λ in pixels, and none.
    for (layout, calibrate, smooth) in [(68, 30, None), (68, 7, Some(50.0)), (468, 20, Some(0.0))] {
        let (rig, t) = track(layout, 90);
        let live = RigOptions::live();
        let opts = RigOptions {
            smooth: smooth.unwrap_or(live.smooth),
            smooth_unit: smooth.map_or(live.smooth_unit, |_| SmoothUnit::Pixels),
            ..live
        };
        let file = solve_rig(
            &rig,
            &t,
            &[],
            &RigOptions {
                neutral: Neutral::Span(0, calibrate),
                ..opts
            },
        )
        .unwrap();
        let mut live = LiveSolver::new(rig.clone(), opts, calibrate).unwrap();
        let w = live_weights(&mut live, &t);
        assert_eq!(
            w, file.weights,
            "{layout} points, calibrate {calibrate}, λ {smooth:?}"
        );
        assert!(w.iter().any(|&v| v > 0.05), "the take moves the face");
    }
}

#[test]
fn a_saved_calibration_solves_as_the_one_it_was_saved_from() {
    let (rig, t) = track(68, 60);
    // Without the causal prior: a loaded calibration has no frame before its first (the
    // first session's had the lead-in's last), which the prior would pull towards.
    let opts = RigOptions {
        smooth: 0.0,
        ..RigOptions::live()
    };
    let mut first = LiveSolver::new(rig.clone(), opts, 30).unwrap();
    let w = live_weights(&mut first, &t);
    let saved = first.calibration().unwrap().clone();
    // The default λ, relative to the face, is measured by the loaded calibration as by
    // the one collected.
    let mut default = LiveSolver::new(rig.clone(), RigOptions::live(), 30).unwrap();
    default.set_calibration(saved.clone()).unwrap();
    assert_eq!(
        default.smooth(),
        Some(keyshape_rig::LIVE_SMOOTH * saved.iod * saved.iod)
    );
    assert_eq!(saved.frames, 30);
    let text = serde_json::to_string(&saved).unwrap();
    let back: keyshape_rig::live::Calibration = serde_json::from_str(&text).unwrap();
    assert_eq!(back, saved, "JSON keeps every bit");
    let mut second = LiveSolver::new(rig.clone(), opts, 30).unwrap();
    second.set_calibration(back).unwrap();
    // The frames after the lead-in: solved at once (no lead-in to collect), to the
    // solver's tolerance of the first session's (whose warm start came from the lead-in).
    for c in 30..60 {
        let col: Vec<f64> = t.column(c).iter().copied().collect();
        let f = second.push(&col).unwrap();
        assert_eq!(f.len(), 1, "calibrated: each frame solved as it comes");
        let worst = f[0]
            .weights
            .iter()
            .zip(w.column(c).iter())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-4, "frame {c}: {worst}");
    }
    // Another rig's calibration is refused, naming why.
    let mut other = saved.clone();
    other.names[0] = "notAShape".into();
    let err = second
        .set_calibration(other)
        .unwrap_err()
        .kind_is(ErrorKind::Invalid);
    assert!(err.contains("shape names"), "{err}");
    let mut nan = saved;
    nan.iod = f64::NAN;
    assert!(second.set_calibration(nan).is_err());
}

#[test]
fn a_bad_frame_is_refused_and_changes_nothing() {
    let (rig, t) = track(68, 40);
    let mut clean = LiveSolver::new(rig.clone(), RigOptions::live(), 10).unwrap();
    let want = live_weights(&mut clean, &t);
    let mut live = LiveSolver::new(rig.clone(), RigOptions::live(), 10).unwrap();
    let mut got = Vec::new();
    for c in 0..t.ncols() {
        if c % 7 == 3 {
            let mut bad: Vec<f64> = t.column(c).iter().copied().collect();
            bad[5] = f64::NAN;
            assert!(live
                .push(&bad)
                .unwrap_err()
                .kind_is(ErrorKind::Invalid)
                .contains("NaN"));
            assert!(live.push(&bad[..10]).is_err());
            assert!(
                live.push(&vec![3.0; bad.len()]).is_err(),
                "coincident points"
            );
        }
        let col: Vec<f64> = t.column(c).iter().copied().collect();
        got.extend(live.push(&col).unwrap());
    }
    let got = DMatrix::from_fn(rig.k(), got.len(), |s, f| got[f].weights[s]);
    assert_eq!(got, want);
}

#[test]
fn recalibrating_starts_a_new_lead_in() {
    let (rig, t) = track(68, 50);
    let mut live = LiveSolver::new(rig, RigOptions::live(), 10).unwrap();
    let mut n = 0;
    for c in 0..25 {
        let col: Vec<f64> = t.column(c).iter().copied().collect();
        n += live.push(&col).unwrap().len();
    }
    assert_eq!(n, 25);
    live.recalibrate(false);
    assert!(live.calibration().is_none());
    assert_eq!(live.collected(), (0, 10));
    for c in 25..34 {
        let col: Vec<f64> = t.column(c).iter().copied().collect();
        assert!(live.push(&col).unwrap().is_empty(), "collecting");
    }
    let col: Vec<f64> = t.column(34).iter().copied().collect();
    assert_eq!(
        live.push(&col).unwrap().len(),
        10,
        "the new lead-in, solved"
    );
}

#[test]
fn settings_a_live_solve_cannot_honour_are_refused() {
    let (rig, _) = track(68, 1);
    assert!(LiveSolver::new(rig.clone(), RigOptions::live(), 0).is_err());
    assert!(LiveSolver::new(rig.clone(), RigOptions::recommended(), 10).is_err());
    let mut live = LiveSolver::new(rig, RigOptions::live(), 10).unwrap();
    assert!(live.set_smooth(f64::NAN).is_err());
    assert!(live.set_smooth(-1.0).is_err());
    live.set_smooth(20.0).unwrap();
    assert_eq!(live.smooth(), Some(20.0));
}

/// The live path's default causal prior is relative to the face (λ = LIVE_SMOOTH × IOD²,
/// the IOD the calibration measured), so a face drawn twice as large is solved to the
/// same weights; a λ in pixels pulls a larger face less, and the weights change.
#[test]
fn the_default_causal_prior_does_not_depend_on_the_face_s_size() {
    let (rig, t) = track(68, 90);
    let mut live = LiveSolver::new(rig.clone(), RigOptions::live(), 30).unwrap();
    assert_eq!(live.smooth(), None, "unknown until the face is measured");
    let w = live_weights(&mut live, &t);
    let iod = live.calibration().unwrap().iod;
    assert!(iod > 10.0, "{iod}");
    assert_eq!(live.smooth(), Some(LIVE_SMOOTH * iod * iod));
    let large = &t * 2.0;
    let mut twice = LiveSolver::new(rig.clone(), RigOptions::live(), 30).unwrap();
    let w2 = live_weights(&mut twice, &large);
    assert_eq!(twice.smooth(), Some(LIVE_SMOOTH * 4.0 * iod * iod));
    let moved = (&w - &w2).amax();
    assert!(moved < 1e-6, "the same weights at twice the size: {moved}");
    // The same λ in pixels on both: the larger face is pulled a quarter as much.
    let pixels = RigOptions {
        smooth: LIVE_SMOOTH * iod * iod,
        smooth_unit: SmoothUnit::Pixels,
        ..RigOptions::live()
    };
    let mut small = LiveSolver::new(rig.clone(), pixels, 30).unwrap();
    assert_eq!(
        live_weights(&mut small, &t),
        w,
        "the same λ, given in pixels"
    );
    let mut large_px = LiveSolver::new(rig, pixels, 30).unwrap();
    let moved = (&w - &live_weights(&mut large_px, &large)).amax();
    assert!(moved > 1e-3, "a λ in pixels depends on the size: {moved}");
}

/// A library error's kind checked before its words are read: a test acts on the kind, as a
/// caller would, and reads the message only for what it must name.
trait KindIs {
    fn kind_is(self, kind: keyshape_core::ErrorKind) -> String;
}

impl KindIs for keyshape_core::Error {
    #[track_caller]
    fn kind_is(self, kind: keyshape_core::ErrorKind) -> String {
        assert_eq!(self.kind(), kind, "{self}");
        self.to_string()
    }
}

/// No input makes the frame solver loop without end: a landmark at 1e200 (finite, so a
/// JSON source took it) hung it in the head rotation's nearest-rotation iteration, beyond
/// any signal. Every extreme frame is answered (refused, or solved to bounded weights)
/// within seconds, and the frames after it are solved as before.
#[test]
fn extreme_frames_are_answered_and_change_nothing() {
    let (rig, t) = track(68, 20);
    let mut clean = LiveSolver::new(rig.clone(), RigOptions::live(), 10).unwrap();
    let want = live_weights(&mut clean, &t);
    let (tx, rx) = std::sync::mpsc::channel();
    let worker = std::thread::spawn(move || {
        let mut live = LiveSolver::new(rig.clone(), RigOptions::live(), 10).unwrap();
        let mut got = Vec::new();
        for c in 0..t.ncols() {
            let col: Vec<f64> = t.column(c).iter().copied().collect();
            if c >= 10 {
                for v in [1e200, -1e300, f64::MAX, 1e31, 1e38] {
                    for at in [0, 5, col.len() - 1] {
                        let mut bad = col.clone();
                        bad[at] = v;
                        let r = live.push(&bad);
                        assert!(r.is_err(), "{v:e} at value {at}: refused as out of range");
                    }
                }
                // Every point far out: the face offset beyond what 64-bit numbers resolve.
                let far: Vec<f64> = col.iter().map(|v| v + 1e29).collect();
                assert!(live.push(&far).is_err(), "a face at 1e29 is refused");
            }
            got.extend(live.push(&col).unwrap());
        }
        tx.send(got).unwrap();
    });
    let got = rx
        .recv_timeout(std::time::Duration::from_secs(120))
        .expect("the frame solver answered every extreme frame");
    worker.join().unwrap();
    let got = DMatrix::from_fn(want.nrows(), got.len(), |s, f| got[f].weights[s]);
    assert_eq!(got, want, "the refused frames changed nothing");
}

/// A lead-in frame that is no face — one landmark at 1e15 (inside the readers' ±1e30), or
/// every point on a line — is refused on its own, and the calibration is made of the other
/// frames: the same weights as a lead-in without it. (It was averaged into the neutral, and
/// every later weight moved.)
#[test]
fn a_lead_in_frame_that_is_no_face_is_refused_and_the_calibration_made_without_it() {
    let (rig, t) = track(68, 30);
    let mut clean = LiveSolver::new(rig.clone(), RigOptions::live(), 10).unwrap();
    let want = live_weights(&mut clean, &t);
    for bad in ["far", "line"] {
        let mut live = LiveSolver::new(rig.clone(), RigOptions::live(), 10).unwrap();
        let mut got = Vec::new();
        for c in 0..t.ncols() {
            let col: Vec<f64> = t.column(c).iter().copied().collect();
            if c == 4 {
                let mut b = col.clone();
                match bad {
                    "far" => b[70] = 1e15,
                    _ => {
                        for (i, p) in b.chunks_mut(2).enumerate() {
                            p[0] = i as f64;
                            p[1] = 3.0 * i as f64;
                        }
                    }
                }
                let e = live.push(&b).unwrap_err();
                let said = e.to_string();
                assert!(
                    e.kind_is(ErrorKind::Unfit)
                        .contains("a calibration frame must be a face"),
                    "{bad}: {said}"
                );
            }
            got.extend(live.push(&col).unwrap());
        }
        let got = DMatrix::from_fn(rig.k(), got.len(), |s, f| got[f].weights[s]);
        assert_eq!(got, want, "{bad}");
    }
}

/// A saved calibration is checked as a reader checks a track: an inter-ocular distance of
/// 1e308 froze the avatar and 1e-300 changed every weight; a neutral landmark at 1e308, or
/// every landmark at one place, said "calibrated: loaded" and then refused every frame; a
/// neutral of another rig was taken.
#[test]
fn a_saved_calibration_out_of_range_or_of_another_rig_is_refused() {
    let (rig, t) = track(68, 12);
    let mut first = LiveSolver::new(rig.clone(), RigOptions::live(), 10).unwrap();
    live_weights(&mut first, &t);
    let good = first.calibration().unwrap().clone();
    let refuse = |c: keyshape_rig::live::Calibration, needle: &str| {
        let mut live = LiveSolver::new(rig.clone(), RigOptions::live(), 10).unwrap();
        let e = live.set_calibration(c).unwrap_err().to_string();
        assert!(e.contains(needle), "{needle}: {e}");
    };
    for iod in [1e308, 1e-300, 0.0, -1.0] {
        refuse(
            keyshape_rig::live::Calibration {
                iod,
                ..good.clone()
            },
            "the inter-ocular distance",
        );
    }
    for a in [f64::NAN, 4.0, -1e300] {
        let mut c = good.clone();
        c.head[1] = a;
        refuse(c, "its neutral head pose holds");
    }
    let mut c = good.clone();
    c.neutral[3][1] = 1e308;
    refuse(c, "neutral landmark 3: coordinate 1e308 is beyond");
    let mut c = good.clone();
    c.neutral.iter_mut().for_each(|p| *p = [1.0, 2.0, 3.0]);
    refuse(c, "its neutral is not a face");
    // Another rig's neutral: this one scaled up tenfold (the same names and points).
    let mut c = good.clone();
    c.neutral
        .iter_mut()
        .for_each(|p| *p = [p[0] * 10.0, p[1] * 10.0, p[2] * 10.0]);
    refuse(c, "it was made for another rig");
    let mut live = LiveSolver::new(rig, RigOptions::live(), 10).unwrap();
    live.set_calibration(good).unwrap();
}

/// The head is sent relative to the calibration's neutral pose: on a render whose head
/// turns ±18° and nods ±9° about a lead-in held pitched and turned, the live head angles
/// follow the true ones measured from the true lead-in's mean pose (median error under
/// 1.5°, worst under 5°), so a person who looks at a camera from below is an avatar that
/// looks ahead.
#[test]
fn the_head_turns_relative_to_the_calibrated_neutral() {
    use keyshape_rig::accuracy::{render, Settings};
    let rig = Rig::read_ict(&shared_data("ict_facekit_face").unwrap()).unwrap();
    let st = Settings {
        frames: 150,
        lead_in: 20,
        ..Settings::default()
    };
    let r = render(&rig, &st).unwrap();
    let mut live = LiveSolver::new(rig.clone(), RigOptions::live(), st.lead_in).unwrap();
    let mut got = Vec::new();
    for c in 0..r.points.ncols() {
        let col: Vec<f64> = r.points.column(c).iter().copied().collect();
        got.extend(live.push(&col).unwrap());
    }
    // The truth's neutral: the lead-in's true rotations averaged.
    let mean = keyshape_rig::camera::Camera::mean_pose(&r.cameras[..st.lead_in]);
    let neutral = live.calibration().unwrap().head;
    assert!(
        neutral[1].to_degrees().abs() > 3.0,
        "the lead-in is pitched: {neutral:?}"
    );
    let mut errors = Vec::new();
    for (f, frame) in got.iter().enumerate() {
        let truth = r.cameras[f].relative_to(mean);
        for a in 0..3 {
            errors.push((frame.head[a] - truth[a]).abs().to_degrees());
        }
    }
    errors.sort_by(f64::total_cmp);
    let (median, worst) = (errors[errors.len() / 2], errors[errors.len() - 1]);
    assert!(
        median < 1.5 && worst < 5.0,
        "median {median}°, worst {worst}°"
    );
    // Absolute, the pose is off by the lead-in's pitch throughout.
    let absolute: Vec<f64> = got.iter().map(|f| f.camera.yaw_pitch_roll()[1]).collect();
    let rel: Vec<f64> = got.iter().map(|f| f.head[1]).collect();
    let mean_of = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    assert!(
        (mean_of(&absolute) - mean_of(&rel) - neutral[1]).abs() < 0.02,
        "relative = absolute − the neutral's pitch, on average"
    );
}

/// A lead-in that does not look neutral is calibrated on and said: its frames judged as the
/// file's solve judges a neutral frame. A talking face's most open frames: "the lips
/// parted"; a relaxed lead-in: nothing.
#[test]
fn a_lead_in_with_parted_lips_is_said() {
    let (rig, t) = track(68, 300);
    let at = |c: usize, p: usize| (t[(2 * p, c)], t[(2 * p + 1, c)]);
    let gap = |c: usize| {
        let d = |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).hypot(a.1 - b.1);
        let pos = |p: usize| rig.points.iter().position(|&q| q == p).unwrap();
        d(at(c, pos(62)), at(c, pos(66))) / d(at(c, pos(36)), at(c, pos(45)))
    };
    let mut frames: Vec<usize> = (0..t.ncols()).collect();
    frames.sort_by(|&a, &b| gap(b).total_cmp(&gap(a)));
    let open: Vec<usize> = frames[..10].to_vec();
    let closed: Vec<usize> = frames[frames.len() - 10..].to_vec();
    for (lead, parted) in [(open, true), (closed, false)] {
        let mut live = LiveSolver::new(rig.clone(), RigOptions::live(), 10).unwrap();
        let mut solved = 0;
        for &c in &lead {
            let col: Vec<f64> = t.column(c).iter().copied().collect();
            solved += live.push(&col).unwrap().len();
        }
        assert_eq!(solved, 10);
        let w = live.calibration_warning();
        assert_eq!(w.is_some(), parted, "{w:?}");
        if parted {
            assert!(w.unwrap().contains("the lips parted on 10 of 10"), "{w:?}");
        }
    }
}
