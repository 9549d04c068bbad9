//! What `kslab rig` writes: the weights (a file or standard output), the head pose, Live
//! Link Face CSV, glTF and the per-frame pictures.

use super::RigArgs;
use anyhow::Result;
use keyshape_core::sequence::Sequence;
use keyshape_io::csv_out::{write_records, write_rows, Num};
use keyshape_io::morph::MorphTargets;
use keyshape_io::obj::Mesh;
use keyshape_io::{fmt_num, write_atomic};
use keyshape_rig::{livelink, Rig, RigSolve};
use serde::Serialize;
use std::io::Write;

/// Writes every output `a` asks for; returns whether the weights took standard output.
pub(super) fn write_all(
    a: &RigArgs,
    seq: &Sequence,
    rig: &Rig,
    r: &RigSolve,
    mesh: &Mesh,
    morph: &MorphTargets,
    progress: &super::super::progress::Progress,
) -> Result<bool> {
    let taken = super::super::is_stdout(a.out.as_ref()) || (a.out.is_none() && !a.json);
    match &a.out {
        Some(p) => write_atomic(p, |w| write_weights(w, seq, rig, r))?,
        None if a.json => {}
        // Standard output as `--out -` is: a reader that goes away fails the command,
        // and none of its other outputs is committed.
        None => write_atomic(std::path::Path::new("-"), |w| write_weights(w, seq, rig, r))?,
    }
    if let Some(p) = &a.pose {
        write_atomic(p, |w| write_pose(w, seq, r))?;
    }
    if let Some(p) = &a.livelink {
        let fps = seq.fps().unwrap_or(30.0);
        let times: Vec<f64> = match &seq.times {
            Some(t) => t.clone(),
            None => seq.frames.iter().map(|&f| f as f64 / fps).collect(),
        };
        let head: Vec<[f64; 3]> = r.cameras.iter().map(|c| c.yaw_pitch_roll()).collect();
        write_atomic(p, |w| {
            livelink::write(w, rig, &times, fps, &r.weights, &head)
        })?;
    }
    if let Some(p) = &a.gltf {
        // The head pose as the node's rotation: R maps the rig's frame into the camera's,
        // which is glTF's view along −z.
        let q: Vec<[f64; 4]> = r
            .cameras
            .iter()
            .map(|c| {
                let u = nalgebra::UnitQuaternion::from_rotation_matrix(
                    &keyshape_rig::camera::rotation_of(&c.r),
                );
                [u.i, u.j, u.k, u.w]
            })
            .collect();
        morph.write_used_glb(p, mesh, &r.weights, seq.fps().unwrap_or(30.0), Some(&q))?;
    }
    if let Some(dir) = &a.png_dir {
        progress.step("rig: pictures");
        progress.units("frames");
        write_pngs(dir, seq, rig, r, mesh, morph, &|f, n| progress.tick(f, n))?;
    }
    Ok(taken)
}

fn write_weights(
    w: &mut dyn Write,
    seq: &Sequence,
    rig: &Rig,
    r: &RigSolve,
) -> std::io::Result<()> {
    let header = std::iter::once("frame").chain(rig.names.iter().map(String::as_str));
    let records = seq.frames.iter().enumerate().map(|(c, frame)| {
        std::iter::once(frame.to_string())
            .chain(r.weights.column(c).iter().map(|v| fmt_num(*v)))
            .collect::<Vec<_>>()
    });
    write_records(w, header, records)
}

/// A row of `--pose-out`: the camera per frame, back to image axes (y down).
#[derive(Serialize, Default)]
struct PoseCsv {
    frame: i64,
    yaw_deg: Num,
    pitch_deg: Num,
    roll_deg: Num,
    scale: Num,
    tx: Num,
    ty: Num,
    rms: Num,
}

fn write_pose(w: &mut dyn Write, seq: &Sequence, r: &RigSolve) -> std::io::Result<()> {
    let rows = seq.frames.iter().enumerate().map(|(c, &frame)| {
        let cam = &r.cameras[c];
        let [y, p, ro] = cam.yaw_pitch_roll();
        PoseCsv {
            frame,
            yaw_deg: Num(y.to_degrees()),
            pitch_deg: Num(p.to_degrees()),
            roll_deg: Num(ro.to_degrees()),
            scale: Num(cam.s),
            tx: Num(cam.t[0]),
            ty: Num(-cam.t[1]),
            rms: Num(r.rms[c]),
        }
    });
    write_rows(w, rows)
}

/// The per-frame pictures of `--png-dir`: the track with the fitted rig, and the rig's mesh
/// posed by the weights (shaded, front view) with its landmarks.
fn write_pngs(
    dir: &std::path::Path,
    seq: &Sequence,
    rig: &Rig,
    r: &RigSolve,
    mesh: &Mesh,
    morph: &MorphTargets,
    tick: &dyn Fn(usize, usize),
) -> Result<()> {
    use keyshape_pictures::render::face::{
        bounds_of, col, render_panels, Layer, Panel, ShadedMesh,
    };
    let lines = rig.polylines();
    // The pictures are of the image: x and y of a track with depth.
    let coords = if seq.dims == 3 {
        let xy: Vec<usize> = (0..seq.points).flat_map(|i| [3 * i, 3 * i + 1]).collect();
        seq.coords.select_rows(&xy)
    } else {
        seq.coords.clone()
    };
    let n = seq.n_frames();
    let (fitted, front) = posed_landmarks(rig, r, n);
    let tb = bounds_of(&[&coords, &fitted], 2);
    // The face: the landmarks' extent over the sequence, widened a quarter each way so the
    // forehead and cheeks around them show (the rest of the head is cut at the panel).
    let fb = widened(bounds_of(&[&front], 2), 0.25);
    let mut posed = mesh.positions.clone();
    keyshape_io::create_dir_all(dir)?;
    for f in 0..n {
        tick(f, n);
        let [y, p, ro] = r.cameras[f].yaw_pitch_roll();
        morph.blend(&mesh.positions, r.weights.column(f).as_slice(), &mut posed);
        let top = match keyshape_rig::largest_weights(&rig.names, r.weights.column(f).as_slice(), 2)
        {
            t if t.is_empty() => "rig landmarks (no shape active)".to_string(),
            t => t,
        };
        let panels = [
            Panel {
                title: format!(
                    "track and fitted rig · RMS {}",
                    keyshape_core::stats::sig(r.rms[f], 3)
                ),
                layers: vec![
                    Layer {
                        name: "tracked",
                        shape: col(&coords, f),
                        dims: 2,
                        polylines: &lines,
                        color: [20, 20, 20],
                        dashed: false,
                    },
                    Layer {
                        name: "fitted: the person's rig, posed, head pose",
                        shape: col(&fitted, f),
                        dims: 2,
                        polylines: &lines,
                        color: [30, 90, 200],
                        dashed: true,
                    },
                ],
                bounds: tb,
                mesh: None,
            },
            Panel {
                title: "the rig's mesh posed by the weights, front view".into(),
                // The shapes that pose it, by name, in the legend (where long names fit).
                layers: vec![Layer {
                    name: &top,
                    shape: col(&front, f),
                    dims: 2,
                    polylines: &lines,
                    color: [200, 40, 40],
                    dashed: false,
                }],
                bounds: fb,
                mesh: Some(ShadedMesh {
                    positions: &posed,
                    faces: &mesh.faces,
                }),
            },
        ];
        let caption = format!(
            "frame {}   yaw {:.1}°  pitch {:.1}°  roll {:.1}°",
            seq.frames[f],
            y.to_degrees(),
            p.to_degrees(),
            ro.to_degrees()
        );
        let pm = render_panels(&panels, &caption, 420)?;
        keyshape_pictures::render::save_png(
            &pm,
            &dir.join(format!("rig_{:06}.png", seq.frames[f])),
        )?;
    }
    Ok(())
}

/// A picture's bounds, `((x0, y0), (x1, y1))`.
type Bounds = ((f64, f64), (f64, f64));

/// `b` widened by `share` of its extent on each side.
fn widened(b: Bounds, share: f64) -> Bounds {
    let ((a0, b0), (a1, b1)) = b;
    let (px, py) = (share * (a1 - a0), share * (b1 - b0));
    ((a0 - px, b0 - py), (a1 + px, b1 + py))
}

/// Per frame, the rig's landmarks (x, y up) as fitted (the person's rig under the frame's
/// camera) and posed by the weights in front view (the rig itself, what the exports
/// drive).
fn posed_landmarks(
    rig: &Rig,
    r: &RigSolve,
    n: usize,
) -> (nalgebra::DMatrix<f64>, nalgebra::DMatrix<f64>) {
    let (mut fitted, mut front) = (
        nalgebra::DMatrix::zeros(2 * rig.landmarks(), n),
        nalgebra::DMatrix::zeros(2 * rig.landmarks(), n),
    );
    for f in 0..n {
        let w: Vec<f64> = r.weights.column(f).iter().copied().collect();
        let person = r.person_of(f).unwrap_or(rig);
        for (i, p) in person.posed(&w).iter().enumerate() {
            let u = r.cameras[f].project(p);
            fitted[(2 * i, f)] = u[0];
            fitted[(2 * i + 1, f)] = -u[1];
        }
        for (i, p) in rig.posed(&w).iter().enumerate() {
            front[(2 * i, f)] = p[0];
            front[(2 * i + 1, f)] = -p[1];
        }
    }
    (fitted, front)
}

/// `--save-landmarks`: the refined map as `landmark,vertex` rows (as `--rig-landmarks`
/// reads them).
pub(super) fn save_landmarks(path: &std::path::Path, pairs: &[(usize, usize)]) -> Result<()> {
    write_atomic(path, |w| {
        writeln!(w, "landmark,vertex")?;
        for (l, v) in pairs {
            writeln!(w, "{l},{v}")?;
        }
        Ok(())
    })?;
    Ok(())
}
