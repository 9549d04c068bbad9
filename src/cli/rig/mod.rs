//! `kslab rig`: a 68-point track solved onto a blendshape rig (the ICT FaceKit face by
//! default), with a per-frame head pose; weights, pose and Live Link Face CSV out.

mod output;
mod summary;
mod take;
mod temporal;
pub(crate) use temporal::{smooth_of, Temporal};

use summary::{print_summary, summary_json, warn_unneutral, Done, Refined};

use super::check_outputs;
use anyhow::{Context, Result};
use clap::Args;
use keyshape_core::sequence::Sequence;
use keyshape_core::solve::Solver;
use keyshape_io::{shared_data, ReadOptions};
use keyshape_rig::{solve_rig, Identity, Neutral, RigOptions};
use std::path::PathBuf;

/// Arguments of `kslab rig`.
#[derive(Debug, Args)]
pub struct RigArgs {
    /// A 68-point track in iBUG order (OpenFace, py-feat, .pts, plain CSV), iBUG with the
    /// pupils (70 points: a `kslab live` take from OpenSeeFace), or a MediaPipe
    /// track — Face Mesh's 468 points or Face Landmarker's 478 (with irises) — solved
    /// through every point the rig covers (see --landmarks), 2-D
    /// [default: the built-in 216-frame MediaPipe sequence].
    file: Option<PathBuf>,
    /// Force the input format: mediapipe, openface, pyfeat, pts, json or csv [default:
    /// detected].
    #[arg(long)]
    format: Option<keyshape_core::sequence::Format>,
    /// 3: use the track's depth too (MediaPipe's z: relative depth in the x axis's pixels,
    /// more negative closer to the camera — `--image-size` scales it by the width as x).
    /// Each landmark's depth is fitted beside its image position, with a depth offset per
    /// frame (MediaPipe's z has its origin near the head's centre) and the same weight as
    /// x and y. A network's depth estimate, not a measurement: on the benchmark's rendered
    /// depth it raises the worst shape's r from 0.944 to 0.983 (`rig-accuracy --landmarks
    /// 468z`); on a real track, look before trusting it.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(2..=3))]
    dims: u8,
    /// The video's size in pixels, WIDTHxHEIGHT, for a track in normalised coordinates
    /// (MediaPipe's default, every x and y in [0, 1]): the camera fit needs x and y on one
    /// scale. Refused for a track in pixels. [default: the coordinates as read]
    #[arg(long, value_name = "WxH", value_parser = super::input::parse_image_size)]
    image_size: Option<(f64, f64)>,
    /// The rig: a folder in the ICT FaceKit layout (neutral_face.obj, expressions.csv,
    /// expression_deltas.csv, landmarks_multipie68.csv), or a glTF/GLB file whose first mesh
    /// with morph targets is the rig (with --rig-landmarks)
    /// [default: ict_facekit_face in the shared data folder, found through $KSLAB_SHARED or
    /// beside this repository].
    #[arg(long, value_name = "DIR")]
    rig: Option<PathBuf>,
    /// A `landmark,vertex` CSV of any length naming, for each track point the rig covers
    /// (the tracker's numbering: iBUG 0–67, MediaPipe 0–477), the mesh vertex it sits on
    /// (vertices counted across a glTF mesh's primitives); points it does not name are
    /// left out of the solve
    /// [default: required with a glTF rig; a folder's own landmarks_multipie68.csv for
    /// 68-point tracks, and for MediaPipe tracks its landmarks_mediapipe468.csv or, on the
    /// ICT face, the built-in dense correspondence].
    #[arg(long, value_name = "CSV")]
    rig_landmarks: Option<PathBuf>,
    /// How a MediaPipe track meets the rig: `dense` (every point the rig covers: 462 of the
    /// 468 on the ICT face, and with 478 points the two iris centres, which make eye gaze
    /// visible) or `68` (the 68 iBUG points, through the built-in 468 → 68
    /// correspondence; the path for comparing with iBUG trackers). Refused for a 68-point
    /// track, which has only the one
    /// [default: dense].
    #[arg(long, value_name = "dense|68", value_parser = ["dense", "68"])]
    landmarks: Option<String>,
    /// bounded (0 ≤ w ≤ 1, as rigs expect), nnls (w ≥ 0) or ls (unconstrained).
    #[arg(long, default_value = "bounded")]
    solver: Solver,
    /// The person's neutral face: `auto` (of up to 48 evenly spaced candidate frames, the
    /// one whose identity best explains the performance: the lowest landmark error of a
    /// solve of up to 64 evenly spaced frames from it; on a rig of the performer's own
    /// face, whose neutral the first pass finds nearly expressionless, the least active
    /// frame), `least-active` (the frame whose
    /// weights sum lowest in a first pass with the rig as it is), a frame number of the
    /// file, or a recorded neutral lead-in FIRST-LAST (frame numbers, inclusive: each
    /// frame's difference from the rig's neutral averaged, so no one frame's landmark noise
    /// becomes the person's face); refused with --identity none, which uses none.
    /// [default: auto; with --live, the first 30 frames].
    #[arg(long, value_name = "auto|least-active|FRAME|FIRST-LAST")]
    neutral: Option<String>,
    /// How the person's face differs from the rig's: `offset` (the neutral frame's 2-D
    /// residual, lifted into the rig at that frame's head pose, moves the rig's neutral
    /// landmarks), `rbf` (the same neutral, and every shape's landmark offsets carried over
    /// by paper 004's multiquadric RBF from the rig's neutral onto the person's) or `none`.
    #[arg(long, default_value = "offset")]
    identity: Identity,
    /// `track`: one identity for the whole file; `clip`: each clip of the file (py-feat's
    /// `clip` column) is a person of its own, with its own neutral frame chosen within the
    /// clip (for files whose clips are different people; needs --neutral auto or
    /// least-active).
    /// [default: track].
    #[arg(long, value_name = "clip|track", value_parser = ["clip", "track"])]
    identity_per: Option<String>,
    /// Shapes whose image motion is explained by other shapes beyond this share (their
    /// determination, 0–1, at the neutral frame's head pose) are frozen at 0; 0 (the
    /// default) freezes only shapes that do not move the landmarks: what others explain is
    /// settled by --prior instead (freezing lost shapes the performance used).
    #[arg(long, default_value_t = 0.0)]
    min_determination: f64,
    /// The magnitude prior (≥ 0): each frame minimises its landmark error plus μ‖w‖², with
    /// μ = PRIOR × IOD² (IOD: the track's median outer-eye-corner distance), gaze shapes
    /// (eyeLook*) held 100× harder — 68 points have no pupils — and mutually exclusive pairs
    /// (smile/frown, blink/wide, jawLeft/jawRight …) paying for being on together; tapered
    /// (its pull fades as a shape comes on) unless --no-prior-taper. 0 is off. Tuned on
    /// `kslab rig-accuracy` [default: 0.0026; with --live, 0.004, tuned on the causal path].
    #[arg(long, allow_negative_numbers = true)]
    prior: Option<f64>,
    /// The plain ridge μ‖w‖² instead of the tapered prior (the default: each shape's pull
    /// 2μw(1 − w)² fades as it comes on, so peaks are reached; see docs/src/rig_accuracy.md, "Rig accuracy
    /// against ground truth"). Needs a prior.
    #[arg(long)]
    no_prior_taper: bool,
    /// Robust landmark weights: after the solve, landmarks the rig explains much worse than
    /// the median one (their residual over the frames, the identity's share taken out) are
    /// down-weighted (Huber) and the track solved again, twice. For a tracker whose points
    /// are not where the landmark map says. Not with --live.
    #[arg(long)]
    robust_landmarks: bool,
    /// Refine the landmark map from the performance itself: solve with robust landmark
    /// weights, move each landmark to the mesh vertex within --refine-radius of the map's
    /// that best explains its track over the frames (only when it explains it far better),
    /// and solve again; three rounds. For a tracker whose points are not where the map says
    /// (any fixed map is wrong by millimetres somewhere). Save the refined map with
    /// --save-landmarks. Not with --live.
    #[arg(long)]
    refine_landmarks: bool,
    /// How far --refine-landmarks may move a landmark from the map's vertex, millimetres on
    /// the ICT face (rig units ÷ 10 on another rig) [default: 10].
    #[arg(long, value_name = "MM", allow_negative_numbers = true)]
    refine_radius: Option<f64>,
    /// Write the refined landmark map here (`landmark,vertex` CSV, as --rig-landmarks
    /// reads), so the next take can be solved with it. Needs --refine-landmarks
    /// [default: not written].
    #[arg(long, value_name = "FILE")]
    save_landmarks: Option<PathBuf>,
    /// The offline, zero-phase temporal prior: each clip's weights smoothed by a Gaussian
    /// of σ frames, no lag (it needs the whole file; --live turns it off). 0 is off.
    /// Tuned on `kslab rig-accuracy` (2 already flattens speech-rate jaw motion).
    #[arg(long, value_name = "SIGMA", allow_negative_numbers = true)]
    zero_phase: Option<f64>,
    /// Weights for live use: causal, each frame's weights from that frame, the frames
    /// before it and the neutral lead-in only — no --zero-phase, the prior scaled on the
    /// lead-in, which must be given (--neutral FIRST-LAST or FRAME; default 0-29, the first
    /// 30 frames, as `kslab live --calibrate 30` calibrates). A take `kslab live --record`
    /// recorded gives the same weights here as it gave live. The causal temporal prior, each
    /// frame pulled towards the last, is on as in `kslab live` (--smooth sets its λ).
    #[arg(long)]
    live: bool,
    /// With --live: the calibrations a `kslab live --record` take kept
    /// (TAKE/calibrations.jsonl), each taken into use at the frame it was — a take
    /// recalibrated during the session replays to the weights it gave live. Without it the
    /// one calibration is the --neutral lead-in.
    #[arg(long, value_name = "FILE")]
    pub(crate) calibrations: Option<PathBuf>,
    /// Temporal prior λ (≥ 0, squared image units per unit weight²; not across clips), in
    /// --smooth-mode: offline, each clip's weights minimise the frames' squared landmark
    /// errors plus λ Σ_t ‖w_t − w_{t−1}‖² (the whole clip at once, zero phase, with each
    /// frame's head pose from the per-frame solve); causal, each frame's weights are pulled
    /// towards the previous frame's by λ‖w − w_prev‖²
    /// [default: off, the same as 0; with --live the live path's causal prior, 0.0026 × the
    /// lead-in's squared inter-ocular distance (30 px² at 107 px), as `kslab live`].
    #[arg(long, value_name = "LAMBDA", allow_negative_numbers = true)]
    smooth: Option<f64>,
    /// offline (the whole clip; for files) or causal (the past only; for live use)
    /// [default: offline; causal with --live].
    #[arg(long, value_name = "offline|causal", value_parser = ["offline", "causal"])]
    smooth_mode: Option<String>,
    /// Weight of a group of landmarks' squared error in the fit, as `GROUP=W` (W ≥ 0;
    /// repeatable, later ones win): GROUP is jaw (0–16, the face contour), brows (17–26),
    /// nose (27–35), eyes (36–47), lips (48–59, outer), mouth (60–67, inner) or a landmark
    /// number. `jaw=0.1` trusts the contour less: a 2-D tracker's contour points slide
    /// along the silhouette as the head turns, and the rig's jaw line is not the person's
    /// [default: every landmark 1].
    #[arg(long, value_name = "GROUP=W", allow_negative_numbers = true)]
    landmark_weight: Vec<String>,
    /// Write the weights here: `frame` and one column per rig shape, named as the rig names
    /// them [default: stdout].
    #[arg(long, short)]
    out: Option<PathBuf>,
    /// Write the head pose here: frame, yaw, pitch, roll (degrees), scale, tx, ty (image
    /// units) and the RMS landmark error (image units)
    /// [default: not written].
    #[arg(long, value_name = "FILE")]
    pose: Option<PathBuf>,
    /// Write a Live Link Face CSV here (Timecode, BlendshapeCount = 61, the 52 ARKit shapes
    /// in the order the app writes its CSVs, HeadYaw/Pitch/Roll in radians, eye angles 0)
    /// [default: not written].
    #[arg(long, value_name = "FILE")]
    livelink: Option<PathBuf>,
    /// Write the rig's mesh animated by the weights as glTF (GLB): the shapes used as morph
    /// targets, named as the rig names them, and a weights animation at the track's frame
    /// rate (30 when the file has none), and the fitted head pose as the node's rotation
    /// [default: not written].
    #[arg(long, value_name = "FILE")]
    gltf: Option<PathBuf>,
    /// Write one PNG per frame here (`rig_<frame>.png`): the tracked landmarks with the
    /// posed rig's landmarks under the fitted head pose on the left, the posed rig's
    /// landmarks seen from the front on the right
    /// [default: not written].
    #[arg(long, value_name = "DIR")]
    png_dir: Option<PathBuf>,
    /// Print a JSON summary: per-shape identifiability, neutral frame, errors, steps.
    #[arg(long)]
    pub(crate) json: bool,
    /// Also check the weights against the track's own geometry, where no ground truth
    /// exists: each eye's blink against that eye's lid gap over its width, jawOpen against
    /// the inner lips' gap, the smiles against the mouth's width (Pearson r, with the
    /// geometry's range), each twin pair's gap on the frames where the face is symmetric,
    /// and the shapes on (> 0.5) on more than 20 % of frames. Printed after the summary
    /// (`--json`: `plausibility`).
    #[arg(long)]
    plausibility: bool,
}

/// Runs `kslab rig`.
pub fn run(a: &RigArgs) -> Result<()> {
    let refinement = checked_args(a)?;
    let progress = super::progress::Progress::new("rig: reading");
    let (name, seq) = read_track(a)?;
    let track68 = plausibility_rows(a, &seq)?;
    let (dir, mesh, morph, rig, seq) = read_rig(a, seq, &name)?;
    let opts = options_of(a, &seq)?;
    let neutral = opts.neutral;
    let (per_clip, clips) = clips_of(a, &seq, &name, neutral)?;
    let events = take::events(a, &seq, neutral)?;
    progress.step("rig: solving");
    let (rig, r, refined) = match events {
        Some(events) => (rig.clone(), take::replay(&rig, &seq, &opts, &events)?, None),
        None => solve(
            &rig,
            (&mesh, &morph),
            &seq,
            &clips,
            &opts,
            refinement,
            &progress,
        )?,
    };
    if let (Some(p), Some((pairs, _, _))) = (&a.save_landmarks, &refined) {
        output::save_landmarks(p, pairs)?;
    }
    progress.step("rig: writing");
    let taken = output::write_all(a, &seq, &rig, &r, &mesh, &morph, &progress)?;
    progress.finish();
    warn_unneutral(&r, &seq, neutral);
    let plausible = track68.as_ref().map(|t| {
        let clips = clip_ranges(seq.segments.as_deref().unwrap_or(&[]));
        keyshape_rig::plausibility::plausibility(&rig.names, &r.weights, t, &clips)
    });
    let done = Done {
        seq: &seq,
        rig: &rig,
        r: &r,
        opts: &opts,
        refined: refined.as_ref(),
        plausible: plausible.as_ref(),
    };
    if a.json {
        let v = summary_json(a, &done, &dir, per_clip);
        outln!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        print_summary(a, &done, taken)?;
    }
    Ok(())
}

/// Step 1: the outputs may be written, and the options fit together; the refinement asked.
fn checked_args(a: &RigArgs) -> Result<Option<keyshape_rig::refine::Refinement>> {
    super::check_json_stdout(a.json, a.out.as_ref())?;
    // Without --out (and --json) the weights go to standard output, as with `--out -`.
    let stdout = PathBuf::from("-");
    let out = a.out.as_ref().or((!a.json).then_some(&stdout));
    check_outputs(
        &[
            out,
            a.pose.as_ref(),
            a.livelink.as_ref(),
            a.gltf.as_ref(),
            a.save_landmarks.as_ref(),
        ],
        &[a.png_dir.as_ref()],
        &[
            a.file.as_deref(),
            a.rig.as_deref(),
            a.rig_landmarks.as_deref(),
        ],
    )?;
    if a.identity == Identity::None && a.neutral.is_some() {
        anyhow::bail!("--neutral does not apply with --identity none: no neutral frame is used");
    }
    let refinement = refinement_of(a.refine_landmarks, a.refine_radius)?;
    if a.save_landmarks.is_some() && refinement.is_none() {
        anyhow::bail!("--save-landmarks writes the refined landmark map: give --refine-landmarks");
    }
    if refinement.is_some() && a.live {
        anyhow::bail!("--refine-landmarks measures each landmark over the whole track: not with --live (refine on a recorded take, --save-landmarks, and go live with --rig-landmarks)");
    }
    Ok(refinement)
}

/// Step 2: the track read (the built-in one without a file), in image pixels, its layout
/// checked and, with `--landmarks 68`, reduced to the 68 iBUG points; with its name.
fn read_track(a: &RigArgs) -> Result<(String, Sequence)> {
    let name = a
        .file
        .as_ref()
        .map_or(keyshape_io::BUILTIN_NAME.to_string(), |p| {
            p.display().to_string()
        });
    let seq = match &a.file {
        Some(p) => super::input::read_noting(
            p,
            &ReadOptions {
                format: a.format,
                dims: usize::from(a.dims),
            },
        )?,
        None if a.dims == 3 => anyhow::bail!(
            "--dims 3: the built-in sequence has no depth (x and y only); give a MediaPipe track with z"
        ),
        None => keyshape_io::builtin_sequence()?,
    };
    let mut seq = seq;
    super::input::apply_image_size(&mut seq, a.image_size)?;
    keyshape_rig::correspondence::check_layout(seq.points)
        .with_context(|| format!("{name}: kslab rig"))?;
    // (A `match` on a moved value: the 468-point track is freed once its 68 points are
    // taken, instead of living on under a shadowed name.)
    let ibug = keyshape_rig::correspondence::is_ibug(seq.points);
    let seq = match (ibug, a.landmarks.as_deref()) {
        (true, Some("dense")) => anyhow::bail!(
            "--landmarks dense applies to MediaPipe tracks; {name} has the 68 iBUG points only"
        ),
        (true, _) | (_, None | Some("dense")) => seq,
        _ => seq.select_points(&keyshape_rig::mediapipe_to_ibug68()?)?,
    };
    seq.check_geometry()?;
    Ok((name, seq))
}

/// Step 3: the 68 iBUG points' image rows, for `--plausibility`'s geometry (None without
/// it).
fn plausibility_rows(a: &RigArgs, seq: &Sequence) -> Result<Option<nalgebra::DMatrix<f64>>> {
    Ok(if a.plausibility {
        let s68 = match seq.points {
            68 => None,
            // iBUG with the pupils: its first 68 points.
            70 => Some(seq.select_points(&(0..68).collect::<Vec<_>>())?),
            _ => Some(seq.select_points(&keyshape_rig::mediapipe_to_ibug68()?)?),
        };
        let s68 = s68.as_ref().unwrap_or(seq);
        let xy: Vec<usize> = (0..68)
            .flat_map(|i| [s68.dims * i, s68.dims * i + 1])
            .collect();
        Some(s68.coords.select_rows(&xy))
    } else {
        None
    })
}

type RigRead = (
    PathBuf,
    keyshape_io::obj::Mesh,
    keyshape_io::morph::MorphTargets,
    keyshape_rig::Rig,
    Sequence,
);

/// Step 4: the rig (a folder or a glTF file), and the track reduced to the points it reads.
fn read_rig(a: &RigArgs, seq: Sequence, name: &str) -> Result<RigRead> {
    let dir = match &a.rig {
        Some(d) => d.clone(),
        None => shared_data("ict_facekit_face")?,
    };
    if dir.is_file() && a.rig_landmarks.is_none() {
        anyhow::bail!(
            "{}: a glTF rig needs --rig-landmarks CSV (landmark,vertex: the mesh vertex of each track point it covers)",
            dir.display()
        );
    }
    let (mesh, morph, rig) =
        keyshape_rig::correspondence::read_rig(&dir, seq.points, a.rig_landmarks.as_deref())
            .with_context(|| format!("reading the rig {}", dir.display()))?;
    if seq.points != 68 && a.landmark_weight.iter().any(|_| true) {
        anyhow::bail!(
            "--landmark-weight names iBUG-68 landmarks and groups; {name} is solved through {} MediaPipe points (use --landmarks 68 to weigh the 68)",
            rig.landmarks()
        );
    }
    let seq = seq.select_points(&rig.points)?;
    Ok((dir, mesh, morph, rig, seq))
}

/// Step 5: the solve's options from the flags (the neutral, the causal path's refusals,
/// the priors).
fn options_of(a: &RigArgs, seq: &Sequence) -> Result<RigOptions> {
    let neutral = neutral_of(a, seq)?;
    if a.live && a.identity_per.as_deref() == Some("clip") {
        anyhow::bail!("--live takes one neutral lead-in for the track: --identity-per clip searches each clip for its own");
    }
    let t = Temporal::of(
        a.live,
        (a.zero_phase, a.smooth, a.smooth_mode.as_deref()),
        a.prior,
        a.no_prior_taper,
    )?;
    Ok(RigOptions {
        solver: a.solver,
        identity: a.identity,
        neutral,
        min_determination: a.min_determination,
        smooth: t.smooth,
        smooth_unit: t.smooth_unit,
        smooth_mode: t.smooth_mode,
        landmark_weights: keyshape_rig::landmark_weights(&a.landmark_weight)?,
        prior: t.prior,
        zero_phase: t.zero_phase,
        taper: !a.no_prior_taper,
        causal: a.live,
        robust: a.robust_landmarks,
        ..Default::default()
    })
}

/// Step 6: one identity for the track, or one per clip (`--identity-per clip`), and the
/// clips' frame ranges then.
fn clips_of(
    a: &RigArgs,
    seq: &Sequence,
    name: &str,
    neutral: Neutral,
) -> Result<(bool, Vec<std::ops::Range<usize>>)> {
    let per_clip = match a.identity_per.as_deref() {
        Some("clip") => {
            if seq.segments.is_none() {
                anyhow::bail!("--identity-per clip: {name} labels no clips");
            }
            if matches!(neutral, Neutral::Column(_) | Neutral::Span(..)) {
                anyhow::bail!("--identity-per clip needs --neutral auto or least-active: an explicit neutral frame is one identity for the whole track");
            }
            if a.identity == Identity::None {
                anyhow::bail!("--identity-per does not apply with --identity none");
            }
            true
        }
        Some(_) => {
            if a.identity == Identity::None {
                anyhow::bail!("--identity-per does not apply with --identity none");
            }
            false
        }
        None => {
            if let Some(n) = seq.segments.as_deref().map(count_clips).filter(|&n| n > 1) {
                errln!(
                    "note: {name} labels {n} clips and one identity (one neutral frame) serves them all; if the clips are different people, --identity-per clip fits each its own (on the news sample it lowers the landmark error by about 30 %)"
                );
            }
            false
        }
    };
    let clips = if per_clip {
        clip_ranges(seq.segments.as_deref().unwrap_or(&[]))
    } else {
        Vec::new()
    };
    Ok((per_clip, clips))
}

/// Step 7: the solve, through the landmark map refined from the track when asked.
fn solve(
    rig: &keyshape_rig::Rig,
    (mesh, morph): (&keyshape_io::obj::Mesh, &keyshape_io::morph::MorphTargets),
    seq: &Sequence,
    clips: &[std::ops::Range<usize>],
    opts: &RigOptions,
    refinement: Option<keyshape_rig::refine::Refinement>,
    progress: &super::progress::Progress,
) -> Result<(keyshape_rig::Rig, keyshape_rig::RigSolve, Option<Refined>)> {
    Ok(match refinement {
        Some(settings) => {
            let done = keyshape_rig::refine::refine_map(
                (&mesh.positions, morph),
                rig,
                &seq.coords,
                clips,
                opts,
                settings,
                &mut |s| progress.step(&format!("rig: {s}")),
            )?;
            let report = (done.pairs, done.moved, done.changed);
            (done.rig, done.solve, Some(report))
        }
        None => {
            let r = solve_rig(rig, &seq.coords, clips, opts)?;
            (rig.clone(), r, None)
        }
    })
}

/// The neutral lead-in `--live` takes by default: the first 30 frames, `kslab live`'s
/// default calibration.
pub(crate) const LIVE_LEAD_IN: usize = 30;

/// `--neutral`: auto, least-active, a frame number or a stretch FIRST-LAST of frames.
fn neutral_of(a: &RigArgs, seq: &Sequence) -> Result<Neutral> {
    Ok(match a.neutral.as_deref().map(str::trim) {
        None if a.live && a.identity != Identity::None => {
            Neutral::Span(0, seq.n_frames().min(LIVE_LEAD_IN))
        }
        Some(n @ ("auto" | "least-active")) if a.live => anyhow::bail!(
            "--live solves each frame from the frames before it: --neutral {n} searches the whole file; give the neutral lead-in, FIRST-LAST (by default the first {LIVE_LEAD_IN} frames, as `kslab live` calibrates)"
        ),
        None | Some("auto") => Neutral::Auto,
        Some("least-active") => Neutral::LeastActive,
        Some(f) => {
            let bad = || {
                anyhow::anyhow!(
                    "--neutral: '{f}' is neither auto, least-active, a frame number nor a stretch of frames FIRST-LAST"
                )
            };
            match f.split_once('-') {
                // FIRST-LAST (frame numbers ≥ 0, so '-' is never a sign here but for a
                // lone negative frame, which is refused by the file's frame lookup).
                Some((x, y)) if !x.is_empty() => {
                    let (x, y): (i64, i64) = (
                        x.trim().parse().map_err(|_| bad())?,
                        y.trim().parse().map_err(|_| bad())?,
                    );
                    let (cx, cy) = (seq.column_of_frame(x)?, seq.column_of_frame(y)?);
                    if cx > cy {
                        anyhow::bail!("--neutral {f}: frame {x} comes after frame {y} in the file");
                    }
                    Neutral::Span(cx, cy + 1)
                }
                _ => Neutral::Column(seq.column_of_frame(f.parse().map_err(|_| bad())?)?),
            }
        }
    })
}

/// How many distinct clips `labels` name.
fn count_clips(labels: &[String]) -> usize {
    let mut v: Vec<&String> = labels.iter().collect();
    v.sort();
    v.dedup();
    v.len()
}

/// Column ranges of consecutive equal clip labels.
fn clip_ranges(labels: &[String]) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut start = 0;
    for i in 1..=labels.len() {
        if i == labels.len() || labels[i] != labels[start] {
            out.push(start..i);
            start = i;
        }
    }
    out
}

/// `--refine-landmarks` with `--refine-radius MM`: the refinement, or None; a radius
/// without the refinement is refused.
pub(crate) fn refinement_of(
    refine: bool,
    radius_mm: Option<f64>,
) -> Result<Option<keyshape_rig::refine::Refinement>> {
    match (refine, radius_mm) {
        (false, Some(_)) => anyhow::bail!("--refine-radius applies to --refine-landmarks"),
        (false, None) => Ok(None),
        (true, Some(r)) if !(r.is_finite() && r > 0.0 && r <= 30.0) => {
            anyhow::bail!("--refine-radius {r}: give a distance in (0, 30] millimetres")
        }
        (true, r) => Ok(Some(keyshape_rig::refine::Refinement {
            // The ICT face is in centimetres.
            radius: r.unwrap_or(10.0) / 10.0,
            ..Default::default()
        })),
    }
}
