//! `kslab tui` (and `kslab` alone): the interactive lab.

use anyhow::Result;
use clap::Args;
use keyshape_retarget::target::TargetSet;
use std::io::IsTerminal;
use std::path::PathBuf;

/// Arguments of `kslab tui`.
#[derive(Debug, Args)]
// --image-size scales a track: FILE's, or a live source's.
#[command(group(clap::ArgGroup::new("track").args(["file", "live"]).multiple(false)))]
pub struct TuiArgs {
    /// Tracked sequence (omit for the built-in one).
    file: Option<PathBuf>,
    /// Target key shapes (JSON target set or SVG template): its frames become the key frames.
    /// [default: none: key frames chosen from the sequence].
    #[arg(long)]
    target: Option<PathBuf>,
    /// A target mesh (OBJ) to drive by RBF transfer + skinning (paper 004); `x` shows it.
    /// [default: none].
    #[arg(long)]
    mesh: Option<PathBuf>,
    /// Feature correspondences for --mesh (`builtin`, a built-in name, or a JSON file).
    #[arg(long, default_value = "builtin", requires = "mesh")]
    features: String,
    /// A blendshape rig (ICT FaceKit folder layout, e.g. ../shared/data/ict_facekit_face) to
    /// solve the track onto when the lab opens (68-point or MediaPipe 468-point tracks, as
    /// `kslab rig` with its defaults); `r` toggles the rig view.
    /// [default: none].
    #[arg(long, value_name = "DIR")]
    rig: Option<PathBuf>,
    /// Head motion (removed by alignment) in what `e` exports: `apply` adds the per-frame
    /// pose to weights.csv (head_scale, head_angle_deg, head_tx, head_ty) and draws view.png
    /// in image coordinates, as `kslab retarget` does; `none` keeps both aligned.
    #[arg(long, default_value = "apply", value_parser = ["apply", "none"])]
    head_motion: String,
    /// The image size, WIDTHxHEIGHT in pixels, of a track in MediaPipe's normalised 0-1
    /// coordinates: the track (and every normalised one opened with `o`) is scaled to pixels.
    /// Needs FILE; refused for a track already in pixels.
    /// [default: none: a normalised track is shown as it is, with a note]
    #[arg(long, value_name = "WxH", value_parser = super::input::parse_image_size, requires = "track")]
    image_size: Option<(f64, f64)>,
    /// The lab live: frames from SOURCE (as `kslab live --from`: `openseeface:[HOST:]PORT`,
    /// `stdin`, `file:TRACK`) solved onto the rig (--rig, or the ICT face in the shared data
    /// folder) as they come, calibrated on the first 30 frames: the incoming landmarks over
    /// the posed rig, the named weight bars, frames per second, latency, dropped frames;
    /// `n` recalibrates, `l`/`L` turn the causal prior's λ up and down. With --image-size
    /// for normalised coordinates.
    /// [default: none: the lab on FILE or the built-in sequence]
    #[arg(long, value_name = "SOURCE", conflicts_with_all = ["file", "target", "mesh"])]
    live: Option<String>,
}

pub fn run(a: &TuiArgs) -> Result<()> {
    if !std::io::stdout().is_terminal() {
        anyhow::bail!("the lab needs a terminal (stdout is not one); see `kslab --help` for the headless commands");
    }
    if let Some(src) = &a.live {
        if a.head_motion != "apply" {
            anyhow::bail!(
                "--head-motion applies to the lab's export; the live screen exports nothing"
            );
        }
        return super::live::tui(src, a.rig.as_deref(), a.image_size);
    }
    let path = a
        .file
        .as_ref()
        .map_or("builtin".to_string(), |p| p.display().to_string());
    let mut seq = kslab_tui::load(&path)?;
    if let Some((w, h)) = a.image_size {
        seq.scale_to_image(w, h)
            .map_err(|e| anyhow::anyhow!("--image-size {w}x{h}: {e}"))?;
    }
    let target = match &a.target {
        None => None,
        Some(p) if p.extension().is_some_and(|e| e.eq_ignore_ascii_case("svg")) => {
            Some(keyshape_retarget::svg::read_template(p)?)
        }
        Some(p) => Some(TargetSet::read_json(p)?),
    };
    let mesh = match &a.mesh {
        None => None,
        Some(m) => {
            let obj = keyshape_io::obj::read_obj(m)?;
            let layout = keyshape_core::sequence::Layout::for_points(seq.points);
            let features = keyshape_transfer::features::Features::choose(
                &a.features,
                layout.as_ref().map(|l| l.name.as_str()),
                seq.points,
                obj.positions.len(),
            )?;
            Some(kslab_tui::mesh_view(&seq, obj, features)?)
        }
    };
    let rig = match &a.rig {
        None => None,
        Some(d) => {
            let rig = keyshape_rig::correspondence::RigSource::new(d);
            // Checked now, so a track or rig that cannot be solved fails with its reason;
            // solved in the background once the lab is open.
            kslab_tui::prepare_rig(&seq, &rig)?;
            Some(rig)
        }
    };
    kslab_tui::run_sized(
        seq,
        &path,
        target,
        mesh,
        rig,
        a.head_motion == "apply",
        a.image_size,
    )
}

impl Default for TuiArgs {
    fn default() -> Self {
        TuiArgs {
            file: None,
            target: None,
            mesh: None,
            rig: None,
            features: "builtin".into(),
            head_motion: "apply".into(),
            image_size: None,
            live: None,
        }
    }
}
