//! Issue 16: a tracked performance solved onto the ICT FaceKit rig — camera recovery,
//! known weights solved back, identifiability, Live Link Face CSV, bad rigs.

use crate::common::shared;
use keyshape_lab::rig::camera::{fit_camera, Camera};
use keyshape_lab::rig::{solve_rig, Identity, Rig, RigOptions};
use keyshape_lab::solve::Solver;
use nalgebra::DMatrix;

fn ict() -> Rig {
    Rig::read_ict(&shared("ict_facekit_face")).unwrap()
}

/// Smooth pseudo-random series in [lo, hi]: a sum of three seeded sinusoids per shape.
fn smooth_series(shape: usize, frames: usize, lo: f64, hi: f64) -> Vec<f64> {
    let s = shape as f64 + 1.0;
    (0..frames)
        .map(|f| {
            let t = f as f64;
            let v = (0.071 * s * t / 7.0 + s).sin() * 0.5
                + (0.13 * t / s.sqrt() + 2.0 * s).sin() * 0.3
                + (0.023 * t + 3.0 * s).sin() * 0.2;
            lo + (hi - lo) * (v + 1.0) / 2.0
        })
        .collect()
}

#[test]
fn rig_explore() {
    let rig = ict();
    let frames = 60;
    let cams: Vec<Camera> = (0..frames)
        .map(|f| {
            let t = f as f64 / frames as f64;
            Camera::from_angles(
                8.0,
                (20f64).to_radians() * (6.0 * t).sin(),
                (10f64).to_radians() * (4.0 * t).cos(),
                (5f64).to_radians() * (3.0 * t).sin(),
                [320.0, -240.0],
            )
        })
        .collect();
    let shapes = ["jawOpen", "mouthSmile_L", "mouthSmile_R", "browInnerUp_L", "eyeBlink_L", "eyeBlink_R", "mouthRollUpper", "browDown_R", "mouthFunnel", "cheekPuff_L", "mouthStretch_L", "noseSneer_L"];
    let mut w = DMatrix::zeros(rig.k(), frames);
    for (j, name) in shapes.iter().enumerate() {
        let s = rig.names.iter().position(|n| n == name).unwrap();
        let v = smooth_series(j, frames, 0.1, 0.9);
        for f in 0..frames {
            w[(s, f)] = v[f];
        }
    }
    let track = rig.render(&w, &cams);
    let t0 = std::time::Instant::now();
    let r = solve_rig(&rig, &track, &RigOptions { identity: Identity::None, solver: if std::env::var("LS").is_ok() { Solver::Ls } else { Solver::Bounded }, min_determination: std::env::var("MD").map(|v| v.parse().unwrap()).unwrap_or(0.02), ..Default::default() }).unwrap();
    eprintln!("{:?}", t0.elapsed());
    for s in &r.shapes {
        if shapes.contains(&s.name.as_str()) { eprintln!("{:18} motion {:8.3} det {:.4} frozen {}", s.name, s.image_motion, s.determination, s.frozen); }
    }
    let err: f64 = (0..frames).map(|f| (0..rig.k()).map(|s| (w[(s,f)] - r.weights[(s,f)]).abs()).fold(0.0, f64::max)).fold(0.0, f64::max);
    eprintln!("max weight error {err}, unconverged {}, alternations {:?}", r.unconverged, &r.alternations[..10]);
    let ang: f64 = (0..frames).map(|f| { let a = cams[f].yaw_pitch_roll(); let b = r.cameras[f].yaw_pitch_roll(); (0..3).map(|i| (a[i]-b[i]).abs()).fold(0.0, f64::max)}).fold(0.0, f64::max);
    eprintln!("max angle error {ang} rad, rms max {}", r.rms.iter().copied().fold(0.0, f64::max));
    let _ = fit_camera;
}

#[test]
fn rig_explore_bounded_given_camera() {
    let rig = ict();
    let cam = Camera::from_angles(8.0, 0.2, 0.1, 0.05, [320.0, -240.0]);
    let shapes = ["jawOpen", "mouthSmile_L", "eyeBlink_L", "browDown_R", "mouthFunnel"];
    let mut w = DMatrix::zeros(rig.k(), 1);
    for (j, name) in shapes.iter().enumerate() {
        let s = rig.names.iter().position(|n| n == name).unwrap();
        w[(s, 0)] = 0.2 + 0.1 * j as f64;
    }
    let track = rig.render(&w, &[cam]);
    // A = s R2 D with image y down: rows (x, y_down)
    let k = rig.k();
    let mut a = DMatrix::zeros(136, k);
    let mut r = DMatrix::zeros(136, 1);
    for i in 0..68 {
        let p = cam.project(&rig.neutral[i]);
        r[(2 * i, 0)] = track[(2 * i, 0)] - p[0];
        r[(2 * i + 1, 0)] = -track[(2 * i + 1, 0)] - p[1];
        for s in 0..k {
            let d = rig.deltas[s][i];
            for row in 0..2 {
                a[(2 * i + row, s)] = cam.s * (cam.r[(row, 0)] * d[0] + cam.r[(row, 1)] * d[1] + cam.r[(row, 2)] * d[2]);
            }
        }
    }
    let sol = keyshape_lab::solve::solve_batch(&a, &r, &keyshape_lab::solve::SolveOptions::new(Solver::Bounded)).unwrap();
    let err = (&sol.weights - &w).abs().max();
    eprintln!("given camera, bounded batch: max weight error {err}, unconverged {}", sol.unconverged);
    let res = (&a * &sol.weights - &r).norm();
    eprintln!("residual {res}, cond {}", sol.condition);
}
