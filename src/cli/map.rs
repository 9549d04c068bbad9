//! `kslab map`: action-mode trajectories of one person drive a second person's model and
//! the ICT face's morph targets (paper 002 §3.2–3.3).

use super::input::InputArgs;
use super::modes::RegionArgs;
use anyhow::{Context, Result};
use clap::Args;
use keyshape_actions::modes::Actions;
use keyshape_actions::morph::MorphMapping;
use keyshape_actions::trajectory::{
    person_model, synthesise, trajectories, ModeAlignment, Normalisation, PersonModel,
};
use keyshape_core::decompose::{prepare, PrepareOptions, Prepared};
use keyshape_io::csv_out::write_records;
use keyshape_io::morph::MorphTargets;
use keyshape_io::obj::{read_obj, write_obj};
use keyshape_io::{read_sequence, write_atomic, ReadOptions};
use keyshape_pictures::render::face::{bounds_of, col, render_panels, Layer, Panel};
use keyshape_pictures::render::{apng::write_apng, save_png};
use keyshape_retarget::setup::polylines_for;
use nalgebra::DMatrix;
use std::path::{Path, PathBuf};

/// Arguments of `kslab map`.
#[derive(Debug, Args)]
pub struct MapArgs {
    #[command(flatten)]
    input: InputArgs,
    /// Actions of the source sequence (name, region, example frame).
    #[arg(long)]
    actions: PathBuf,
    /// Modes of each person's action-specific model.
    #[arg(long, default_value_t = 10)]
    modes: usize,
    #[command(flatten)]
    regions: RegionArgs,
    /// How trajectories are normalised to [-1, 1] and scaled onto the target: `two-sided`
    /// (the paper's: positive values by the training maximum, negative by the minimum's
    /// magnitude, so both extremes map to ±1) or `one-sided` (both by the largest magnitude).
    #[arg(long, default_value = "two-sided")]
    normalisation: Normalisation,
    /// A second person's sequence, whose model the trajectories drive.
    /// [default: none: only the source person's trajectories].
    #[arg(long)]
    target_sequence: Option<PathBuf>,
    /// The second person's actions.
    /// [default: none; needed with --target-sequence].
    #[arg(long, requires = "target_sequence")]
    target_actions: Option<PathBuf>,
    /// Mode alignment (default: pair the modes of identically named actions).
    #[arg(long, requires = "target_sequence")]
    alignment: Option<PathBuf>,
    /// Write the alignment used, to edit and pass back with --alignment.
    /// [default: not written].
    #[arg(long, requires = "target_sequence")]
    write_alignment: Option<PathBuf>,
    /// Write the normalised action trajectories as CSV.
    /// [default: not written].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Side-by-side PNGs (source beside the second person) here.
    /// [default: not written].
    #[arg(long, requires = "target_sequence")]
    png_dir: Option<PathBuf>,
    /// The same as an animated PNG.
    /// [default: not written].
    #[arg(long, requires = "target_sequence")]
    apng: Option<PathBuf>,
    /// Folder of the ICT face (neutral_face.obj, expressions.csv, expression_deltas.csv) to
    /// drive with morph targets (Eq. 8).
    /// [default: none: no morph targets].
    #[arg(long)]
    morph: Option<PathBuf>,
    /// Action → morph-target mapping (JSON, or `builtin`).
    #[arg(long, default_value = "builtin", requires = "morph")]
    mapping: String,
    /// Write one OBJ per frame of the morphed face here.
    /// [default: not written].
    #[arg(long, requires = "morph")]
    morph_obj_dir: Option<PathBuf>,
    /// Write one PNG per frame of the morphed face (wireframe) here.
    /// [default: not written].
    #[arg(long, requires = "morph")]
    morph_png_dir: Option<PathBuf>,
    /// Write the morphed face as glTF with morph-target animation.
    /// [default: not written].
    #[arg(long, requires = "morph")]
    morph_gltf: Option<PathBuf>,
    /// Only every N-th frame for the per-frame outputs.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..))]
    every: u64,
}

fn model_of(prep: &Prepared, actions: &Actions, a: &MapArgs) -> Result<PersonModel> {
    let (regions, _) = a.regions.build(prep)?;
    Ok(person_model(
        &prep.seq.coords,
        &prep.seq.frames,
        prep.seq.dims,
        &regions,
        actions,
        a.modes,
        a.normalisation,
    )?)
}

pub fn run(a: &MapArgs) -> Result<()> {
    if a.input.points.is_some() {
        anyhow::bail!("--points does not apply: the regions choose the points");
    }
    if a.target_sequence.is_none() && a.morph.is_none() && a.out.is_none() {
        anyhow::bail!("nothing to do: give --target-sequence, --morph or --out");
    }
    super::check_outputs(
        &[
            a.out.as_ref(),
            a.apng.as_ref(),
            a.write_alignment.as_ref(),
            a.morph_gltf.as_ref(),
        ],
        &[
            a.png_dir.as_ref(),
            a.morph_obj_dir.as_ref(),
            a.morph_png_dir.as_ref(),
        ],
        &[
            a.input.file.as_deref(),
            Some(&a.actions),
            a.target_sequence.as_deref(),
            a.target_actions.as_deref(),
            a.alignment.as_deref(),
            a.regions.file(),
            a.morph.as_deref(),
            (a.mapping != "builtin").then(|| Path::new(&a.mapping)),
        ],
    )?;
    let progress = super::progress::Progress::new("map: reading");
    let prep = a.input.prepare_only()?;
    let actions = Actions::read_for(&a.actions, &prep.seq.source, &prep.seq.frames)?;
    let src = model_of(&prep, &actions, a).with_context(|| format!("{}", a.actions.display()))?;
    let traj = trajectories(&src, &prep.seq.coords);
    let names: Vec<String> = src.actions.iter().map(|x| x.0.clone()).collect();
    let action_traj = DMatrix::from_fn(names.len(), traj.ncols(), |i, t| {
        src.actions[i].2 * traj[(src.actions[i].1, t)]
    });
    if let Some(p) = &a.out {
        let header = std::iter::once("frame").chain(names.iter().map(String::as_str));
        let at = &action_traj;
        let records = prep.seq.frames.iter().enumerate().map(|(t, f)| {
            std::iter::once(f.to_string())
                .chain((0..names.len()).map(move |i| format!("{:.5}", at[(i, t)])))
                .collect::<Vec<_>>()
        });
        write_atomic(p, |w| write_records(w, header, records))?;
    }
    let every = a.every as usize;
    if let Some(tpath) = &a.target_sequence {
        let tseq = read_sequence(tpath, &ReadOptions::default())?;
        let tprep = prepare(&tseq, &PrepareOptions::all_aligned())?;
        let tact = Actions::read_for(
            a.target_actions
                .as_deref()
                .context("--target-sequence needs --target-actions")?,
            &tseq.source,
            &tprep.seq.frames,
        )?;
        let tgt = model_of(&tprep, &tact, a)?;
        let alignment = match &a.alignment {
            Some(p) => ModeAlignment::read(p)?,
            None => ModeAlignment::by_actions(&src, &tgt),
        };
        alignment.check(&src, &tgt)?;
        if let Some(p) = &a.write_alignment {
            let text = serde_json::to_string_pretty(&alignment)?;
            write_atomic(p, |w| w.write_all(text.as_bytes()))?;
        }
        let shapes = synthesise(&tgt, &alignment, &traj);
        outln!(
            "mapped {} frames through {} mode pairs onto {} ({} normalisation)",
            traj.ncols(),
            alignment.pairs.len(),
            tpath.display(),
            a.normalisation.name()
        );
        let ex = keyshape_actions::trajectory::extremes(&src, &tgt, &alignment);
        let (lo, hi) = ex
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), r| {
                (l.min(r.ratio), h.max(r.ratio))
            });
        if !ex.is_empty() {
            outln!(
                "a source extreme reaches the target's extreme exactly two-sided; one-sided it reaches {lo:.2}–{hi:.2}× it"
            );
        }
        progress.step("map: pictures");
        progress.units("frames");
        side_by_side(a, &prep, &tprep, &shapes, every, &progress)?;
    }
    if let Some(dir) = &a.morph {
        progress.step("map: morph targets");
        progress.units("frames");
        morph(a, &prep, dir, &names, &action_traj, every, &progress)?;
    }
    Ok(())
}

fn side_by_side(
    a: &MapArgs,
    prep: &Prepared,
    tprep: &Prepared,
    shapes: &DMatrix<f64>,
    every: usize,
    progress: &super::progress::Progress,
) -> Result<()> {
    if a.png_dir.is_none() && a.apng.is_none() {
        return Ok(());
    }
    let dims = prep.seq.dims;
    let lines = prep
        .layout
        .as_ref()
        .map(|l| polylines_for(l, &prep.point_indices))
        .unwrap_or_default();
    let tlines = tprep
        .layout
        .as_ref()
        .map(|l| polylines_for(l, &tprep.point_indices))
        .unwrap_or_default();
    let (sb, tb) = (
        bounds_of(&[&prep.seq.coords], dims),
        bounds_of(&[shapes], dims),
    );
    let frame = |t: usize| {
        let panels = [
            Panel {
                title: "source performance".into(),
                layers: vec![Layer {
                    name: "tracked",
                    shape: col(&prep.seq.coords, t),
                    dims,
                    polylines: &lines,
                    color: [20, 20, 20],
                    dashed: false,
                }],
                bounds: sb,
                mesh: None,
            },
            Panel {
                title: "second person's model".into(),
                layers: vec![Layer {
                    name: "mapped",
                    shape: col(shapes, t),
                    dims,
                    polylines: &tlines,
                    color: [200, 30, 30],
                    dashed: false,
                }],
                bounds: tb,
                mesh: None,
            },
        ];
        render_panels(&panels, &format!("frame {}", prep.seq.frames[t]), 320)
    };
    if let Some(dir) = &a.png_dir {
        keyshape_io::create_dir_all(dir)?;
        for t in (0..shapes.ncols()).step_by(every) {
            progress.tick(t, shapes.ncols());
            save_png(
                &frame(t)?,
                &dir.join(format!("map_{:06}.png", prep.seq.frames[t])),
            )?;
        }
    }
    if let Some(p) = &a.apng {
        let n = shapes.ncols();
        write_apng(p, n, prep.seq.fps().unwrap_or(30.0), &|t| {
            progress.tick(t, n);
            frame(t)
        })?;
    }
    Ok(())
}

fn morph(
    a: &MapArgs,
    prep: &Prepared,
    dir: &Path,
    names: &[String],
    traj: &DMatrix<f64>,
    every: usize,
    progress: &super::progress::Progress,
) -> Result<()> {
    keyshape_io::atomic::register_input(dir)?;
    let mesh = read_obj(&dir.join("neutral_face.obj"))?;
    let targets = MorphTargets::read(
        &dir.join("expressions.csv"),
        &dir.join("expression_deltas.csv"),
        mesh.positions.len(),
    )?;
    let mapping = if a.mapping == "builtin" {
        MorphMapping::builtin()?
    } else {
        MorphMapping::read(Path::new(&a.mapping))?
    };
    let w = mapping.weights(&targets, names, traj)?;
    let n = w.ncols();
    if let Some(d) = &a.morph_obj_dir {
        keyshape_io::create_dir_all(d)?;
        let mut out = mesh.positions.clone();
        for t in (0..n).step_by(every) {
            progress.tick(t, n);
            targets.blend(&mesh.positions, w.column(t).as_slice(), &mut out);
            let p = d.join(format!("frame_{:06}.obj", prep.seq.frames[t]));
            write_atomic(&p, |f| {
                write_obj(
                    f,
                    &out,
                    &mesh.faces,
                    &format!("kslab map: Eq. 8 morph of frame {}", prep.seq.frames[t]),
                )
            })?;
        }
    }
    if let Some(d) = &a.morph_png_dir {
        keyshape_io::create_dir_all(d)?;
        let mb = keyshape_pictures::render::mesh::mesh_bounds(&mesh.positions);
        let mut out = mesh.positions.clone();
        for t in (0..n).step_by(every) {
            progress.tick(t, n);
            targets.blend(&mesh.positions, w.column(t).as_slice(), &mut out);
            let pic = keyshape_pictures::render::mesh::wireframe(
                &out,
                &mesh.faces,
                &[],
                mb,
                420,
                &format!("ICT face, Eq. 8 morph, frame {}", prep.seq.frames[t]),
            )?;
            save_png(
                &pic,
                &d.join(format!("morph_{:06}.png", prep.seq.frames[t])),
            )?;
        }
    }
    if let Some(p) = &a.morph_gltf {
        targets.write_used_glb(p, &mesh, &w, prep.seq.fps().unwrap_or(30.0), None)?;
    }
    outln!(
        "drove {} morph targets of {} over {n} frames",
        mapping.actions.values().map(|v| v.len()).sum::<usize>(),
        dir.display()
    );
    Ok(())
}
