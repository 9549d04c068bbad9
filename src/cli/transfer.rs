//! `kslab transfer`: the performance onto a 3-D mesh by RBF feature transfer and skinning
//! (paper 004).

use super::input::InputArgs;
use anyhow::{Context, Result};
use clap::Args;
use keyshape_io::obj::{read_obj, write_obj};
use keyshape_io::write_atomic;
use keyshape_pictures::render::face::{bounds_of, col};
use keyshape_pictures::render::mesh::{mesh_bounds, transfer_frame, wireframe};
use keyshape_pictures::render::save_png;
use keyshape_retarget::setup::polylines_for;
use keyshape_transfer::features::Features;
use keyshape_transfer::Transfer;
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `kslab transfer`.
#[derive(Debug, Args)]
pub struct TransferArgs {
    #[command(flatten)]
    input: InputArgs,
    /// Target mesh (OBJ), e.g. ../shared/data/ict_facekit_face/neutral_face.obj.
    #[arg(long)]
    mesh: PathBuf,
    /// Correspondences: a JSON file, a built-in name (mediapipe_to_canonical,
    /// ibug68_to_ict), or `builtin`: the built-in one made for this track's layout and this
    /// mesh (a mismatch is refused, naming the file that fits).
    #[arg(long, default_value = "builtin")]
    features: String,
    /// Partial retargeting: only these feature groups move (e.g. `mouth,jaw`).
    /// [default: every group moves].
    #[arg(long, value_delimiter = ',')]
    groups: Option<Vec<String>>,
    /// Source neutral frame the RBF is trained on [default: the first tracked frame].
    #[arg(long, value_name = "FRAME")]
    neutral: Option<i64>,
    /// Painted skin weights overriding the automatic ones (JSON `{"weights": [{"vertex", "feature", "weight"}]}`).
    /// [default: automatic ellipsoid weights].
    #[arg(long)]
    weights: Option<PathBuf>,
    /// Write one OBJ per frame here.
    /// [default: not written].
    #[arg(long)]
    obj_dir: Option<PathBuf>,
    /// Write a glTF 2.0 binary: the mesh skinned to one joint per feature point, animated.
    /// [default: not written].
    #[arg(long)]
    gltf: Option<PathBuf>,
    /// Write one PNG per frame here (source points beside the mesh wireframe).
    /// [default: not written].
    #[arg(long)]
    png_dir: Option<PathBuf>,
    /// Only every N-th frame for --obj-dir / --png-dir.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..))]
    every: u64,
    /// Print a JSON summary.
    #[arg(long)]
    pub(crate) json: bool,
}

/// Frames deformed at a time.
const MESH_CHUNK: usize = 256;

pub fn run(a: &TransferArgs) -> Result<()> {
    if a.input.points.is_some() {
        anyhow::bail!("--points does not apply to transfer: the feature correspondence chooses the points (use --groups)");
    }
    super::check_outputs(
        &[a.gltf.as_ref()],
        &[a.obj_dir.as_ref(), a.png_dir.as_ref()],
        &[
            a.input.file.as_deref(),
            Some(&a.mesh),
            a.weights.as_deref(),
            Some(std::path::Path::new(&a.features)),
        ],
    )?;
    let progress = super::progress::Progress::new("transfer: reading");
    let prep = a.input.prepare_only()?;
    let s = &prep.seq;
    let (tr, ncol, train) = trained(a, s)?;
    let (deform, max_disp) = write_frames(a, &prep, &tr, &progress)?;
    if let Some(p) = &a.gltf {
        tr.check_gltf()?;
        let fps = s.fps().unwrap_or(30.0);
        write_atomic(p, |w| tr.write_glb(w, &s.coords, fps))?;
    }
    progress.finish();
    report(a, s, &tr, ncol, train, deform, max_disp)
}

/// The transfer trained on the neutral frame (`--neutral`, else the first), with its
/// painted weights; its frame column, and the seconds training took.
fn trained(a: &TransferArgs, s: &keyshape_core::Sequence) -> Result<(Transfer, usize, f64)> {
    let mesh = read_obj(&a.mesh)?;
    let layout = keyshape_core::sequence::Layout::for_points(s.points);
    // A 478-point Face Landmarker track takes the Face Mesh 468's correspondences: their
    // points are its first 468.
    let features = Features::choose(
        &a.features,
        layout.as_ref().map(|l| l.family()),
        layout.as_ref().map_or(s.points, |l| l.family_points()),
        mesh.positions.len(),
    )?;
    let ncol = match a.neutral {
        Some(f) => s
            .column_of_frame(f)
            .with_context(|| format!("--neutral {f}"))?,
        None => 0,
    };
    let t0 = Instant::now();
    let mut tr = Transfer::new(
        mesh,
        features,
        s.coords.column(ncol).as_slice(),
        s.dims,
        a.groups.as_deref(),
    )
    .with_context(|| format!("{} with {}", a.mesh.display(), a.features))?;
    let train = t0.elapsed().as_secs_f64();
    if let Some(w) = &a.weights {
        let names: Vec<String> = tr
            .features
            .features
            .iter()
            .map(|f| f.name.clone())
            .collect();
        tr.skin.paint(w, &names)?;
    }
    Ok((tr, ncol, train))
}

/// Every frame deformed, a chunk at a time, and written (OBJ, PNG) every `--every` frames
/// as it comes: memory holds one chunk of meshes, not the whole track's. The seconds the
/// deforming took and the largest vertex displacement.
fn write_frames(
    a: &TransferArgs,
    prep: &keyshape_core::Prepared,
    tr: &Transfer,
    progress: &super::progress::Progress,
) -> Result<(f64, f64)> {
    let s = &prep.seq;
    let every = a.every as usize;
    for dir in [&a.obj_dir, &a.png_dir].into_iter().flatten() {
        keyshape_io::create_dir_all(dir)?;
    }
    let marks: Vec<usize> = tr.features.features.iter().map(|f| f.target).collect();
    let lines = prep
        .layout
        .as_ref()
        .map(|l| polylines_for(l, &prep.point_indices))
        .unwrap_or_default();
    let (mb, sb) = (
        mesh_bounds(&tr.mesh.positions),
        bounds_of(&[&s.coords], s.dims),
    );
    let n = s.n_frames();
    let (mut deform, mut max_disp) = (0.0, 0.0f64);
    if a.obj_dir.is_some() || a.png_dir.is_some() {
        progress.step("transfer: frames");
        progress.units("frames");
    }
    for c0 in (0..n).step_by(MESH_CHUNK) {
        let t1 = Instant::now();
        let frames = tr.frames(&s.coords, c0..n.min(c0 + MESH_CHUNK));
        deform += t1.elapsed().as_secs_f64();
        max_disp = frames
            .iter()
            .flat_map(|f| {
                f.iter().zip(&tr.mesh.positions).map(|(a, b)| {
                    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
                })
            })
            .fold(max_disp, f64::max);
        for (i, pos) in frames.iter().enumerate() {
            let t = c0 + i;
            if t % every != 0 {
                continue;
            }
            progress.tick(t, n);
            if let Some(dir) = &a.obj_dir {
                let p = dir.join(format!("frame_{:06}.obj", s.frames[t]));
                write_atomic(&p, |w| {
                    write_obj(
                        w,
                        pos,
                        &tr.mesh.faces,
                        &format!("kslab transfer: frame {} of {}", s.frames[t], s.source),
                    )
                })?;
            }
            if let Some(dir) = &a.png_dir {
                let pic = transfer_frame(
                    col(&s.coords, t),
                    s.dims,
                    &lines,
                    sb,
                    &|side| wireframe(pos, &tr.mesh.faces, &marks, mb, side, ""),
                    420,
                    &format!("frame {}", s.frames[t]),
                )?;
                save_png(&pic, &dir.join(format!("frame_{:06}.png", s.frames[t])))?;
            }
        }
    }
    Ok((deform, max_disp))
}

/// What the transfer did (`--json`, or lines): sizes, speeds, the frame it was trained on,
/// and for several people (clips) what the identity mismatch costs.
fn report(
    a: &TransferArgs,
    s: &keyshape_core::Sequence,
    tr: &Transfer,
    ncol: usize,
    train: f64,
    deform: f64,
    max_disp: f64,
) -> Result<()> {
    let moved = tr.skin.influences.iter().filter(|i| !i.is_empty()).count();
    let trained_on = format!(
        "the RBF is trained on one frame, {} ({}), mapped onto the mesh's neutral feature vertices; every frame goes through that one transform",
        s.frames[ncol],
        match &s.segments {
            Some(seg) => format!("clip {} of {}", seg[ncol], s.source),
            None => s.source.clone(),
        }
    );
    // Several people (clips) through one transform: what the identity mismatch costs.
    let mismatch = match &s.segments {
        Some(seg) if seg.iter().any(|c| c != &seg[0]) => Some(keyshape_transfer::person_mismatch(
            tr, &s.coords, &s.frames, seg,
        )?),
        _ => None,
    };
    let summary = json!({
        "trained_on": trained_on,
        "person_mismatch": mismatch,
        "frames": s.n_frames(),
        "vertices": tr.mesh.positions.len(),
        "features": tr.features.features.len(),
        "enabled_features": tr.enabled.iter().filter(|e| **e).count(),
        "skinned_vertices": moved,
        "rbf_condition": tr.rbf.condition,
        "train_seconds": train,
        "deform_seconds": deform,
        "frames_per_second": s.n_frames() as f64 / deform.max(1e-12),
        "max_vertex_displacement": max_disp,
    });
    if a.json {
        outln!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        outln!(
            "{} frames onto {} vertices ({} skinned) from {} feature points: trained in {:.1} ms, deformed at {:.0} frames/s, largest displacement {:.3}",
            s.n_frames(),
            tr.mesh.positions.len(),
            moved,
            tr.enabled.iter().filter(|e| **e).count(),
            train * 1e3,
            s.n_frames() as f64 / deform.max(1e-12),
            max_disp
        );
        outln!("{trained_on}");
        if let Some(rows) = &mismatch {
            let trained = s
                .segments
                .as_ref()
                .map(|seg| seg[ncol].clone())
                .unwrap_or_default();
            let others: Vec<&keyshape_transfer::MismatchRow> =
                rows.iter().filter(|r| r.segment != trained).collect();
            let med = |f: fn(&keyshape_transfer::MismatchRow) -> f64| {
                let mut v: Vec<f64> = others.iter().map(|r| f(r)).collect();
                v.sort_by(f64::total_cmp);
                v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
            };
            outln!(
                "{} other clips (people) through it: their neutral lands {:.3} from the mesh's (median over clips of the RMS over features, mesh units); each frame lands {:.3} from where a transform trained on the clip's own neutral puts it, against {:.3} of expression motion (--json lists every clip)",
                others.len(),
                med(|r| r.neutral_error),
                med(|r| r.mismatch),
                med(|r| r.expression)
            );
        }
    }
    Ok(())
}
