//! `kslab modes`: action-specific modes and their orthogonality (Cosker et al. Table 2).

use super::input::InputArgs;
use anyhow::{Context, Result};
use clap::Args;
use keyshape_actions::modes::{
    orthogonality_study, Actions, Boundary, ModeRegions, OrthogonalityStudy, Region, RegionOptions,
};
use keyshape_core::decompose::Prepared;
use std::path::PathBuf;

/// The regions of paper 002 §3.1 and how their boundaries blend (shared by `modes` and `map`).
#[derive(Debug, Args)]
pub struct RegionArgs {
    /// Regions (`builtin`, or a JSON file naming layout groups per region).
    #[arg(long, default_value = "builtin")]
    regions: String,
    /// Region boundaries: `blended` (the paper's: offsets fade out across a band of points,
    /// so regions overlap) or `disjoint` (hard edges; non-overlapping regions then score 0
    /// against each other in Table 2 by construction).
    #[arg(long, default_value = "blended")]
    boundary: Boundary,
    /// Radius of the averaging filter that blends region boundaries, as a fraction of the
    /// face's size (RMS distance of the mean shape's points from their centroid) [default:
    /// 0.15]. Refused with `--boundary disjoint`.
    #[arg(long)]
    blend_radius: Option<f64>,
}

impl RegionArgs {
    /// The regions as per-point weights on the prepared (aligned) sequence's mean shape.
    pub fn build(&self, prep: &Prepared) -> Result<(Vec<Region>, RegionOptions)> {
        let opts = RegionOptions::from_user(self.boundary, self.blend_radius)?;
        let layout = prep
            .layout
            .as_ref()
            .context("needs a known layout (468 or 68 points)")?;
        let regions = if self.regions == "builtin" {
            ModeRegions::builtin(layout)?
        } else {
            ModeRegions::read(std::path::Path::new(&self.regions))?
        };
        let w = regions.weights(layout, &prep.seq.coords, prep.seq.dims, &opts)?;
        Ok((w, opts))
    }

    /// The user's regions file, if any (an input that outputs must not overwrite).
    /// The regions as a title names them: `builtin`, or the file's name.
    pub fn name(&self) -> &str {
        super::curves::short(&self.regions)
    }

    pub fn file(&self) -> Option<&std::path::Path> {
        (self.regions != "builtin").then(|| std::path::Path::new(&self.regions))
    }
}

/// Arguments of `kslab modes`.
#[derive(Debug, Args)]
pub struct ModesArgs {
    #[command(flatten)]
    input: InputArgs,
    #[command(flatten)]
    regions: RegionArgs,
    /// Actions file: name, region and example frame of each action.
    #[arg(long)]
    actions: PathBuf,
    /// Modes of each model the actions are projected on.
    #[arg(long, default_value_t = 10)]
    modes: usize,
    /// Print the upper-triangle tables (paper 002 Table 2) for both models.
    #[arg(long)]
    table: bool,
    /// Print JSON.
    #[arg(long)]
    pub(crate) json: bool,
    /// Write both tables as a heat map PNG.
    /// [default: not drawn].
    #[arg(long)]
    png: Option<PathBuf>,
}

/// `blended (radius 0.15)` or `disjoint`.
pub fn region_label(o: &RegionOptions) -> String {
    match o.boundary {
        Boundary::Blended => format!("blended (radius {})", o.blend_radius),
        Boundary::Disjoint => "disjoint".to_string(),
    }
}

fn print_table(title: &str, names: &[String], m: &nalgebra::DMatrix<f64>) -> Result<()> {
    outln!(
        "{title} (mean of the upper triangle {:.3}; 0 = orthogonal, 1 = parallel)",
        OrthogonalityStudy::mean_upper(m)
    );
    out!("{:>18}", "");
    for j in 1..names.len() {
        out!(" {:>6}", j + 1);
    }
    outln!();
    for i in 0..names.len() - 1 {
        out!("{:>2} {:<15}", i + 1, names[i]);
        for j in 1..names.len() {
            if j > i {
                out!(" {:>6.3}", m[(i, j)]);
            } else {
                out!(" {:>6}", "");
            }
        }
        outln!();
    }
    Ok(())
}

pub fn run(a: &ModesArgs) -> Result<()> {
    if a.input.points.is_some() {
        anyhow::bail!("--points does not apply: the regions choose the points");
    }
    super::check_outputs(
        &[a.png.as_ref()],
        &[],
        &[a.input.file.as_deref(), Some(&a.actions), a.regions.file()],
    )?;
    let progress = super::progress::Progress::new("modes");
    let prep = a.input.prepare_only()?;
    let (pts, ropts) = a.regions.build(&prep)?;
    let actions = Actions::read_for(&a.actions, &prep.seq.source, &prep.seq.frames)?;
    let st = orthogonality_study(
        &prep.seq.coords,
        &prep.seq.frames,
        prep.seq.dims,
        &pts,
        &actions,
        a.modes,
    )
    .with_context(|| format!("{}", a.actions.display()))?;
    if let Some(p) = &a.png {
        // The track and the regions (which choose the points) in each table's title.
        let what = format!(
            "{} · {} regions",
            super::curves::short(&prep.seq.source),
            a.regions.name()
        );
        let (t1, t2) = (
            format!("{what}: action-specific model"),
            format!("{what}: plain PCA"),
        );
        let pm = keyshape_pictures::render::heat::heat_maps(
            &[(t1.as_str(), &st.action_model), (t2.as_str(), &st.plain)],
            &st.names,
            44,
        )?;
        keyshape_pictures::render::save_png(&pm, p)?;
        crate::cli::output::wrote(p.display().to_string());
    }
    progress.finish();
    if a.json {
        let rows = |m: &nalgebra::DMatrix<f64>| {
            (0..m.nrows())
                .map(|i| m.row(i).iter().copied().collect::<Vec<f64>>())
                .collect::<Vec<_>>()
        };
        let v = serde_json::json!({
            "actions": st.names, "modes": st.modes,
            "boundary": ropts.boundary.name(),
            "blend_radius": (ropts.boundary == Boundary::Blended).then_some(ropts.blend_radius),
            "features": "shape only (landmarks; the paper's appearance models also had texture)",
            "action_model": rows(&st.action_model), "plain_pca": rows(&st.plain),
            "mean_action_model": OrthogonalityStudy::mean_upper(&st.action_model),
            "mean_plain_pca": OrthogonalityStudy::mean_upper(&st.plain),
        });
        outln!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    if a.table {
        print_table(
            // The table is actions × actions; the modes are the model's size (9 actions on
            // 10 modes read as a 9 × 9 table under "10 modes").
            &format!(
                "action-specific model ({} regions, {} modes): Eq. 9 score of each pair of its {} actions",
                region_label(&ropts),
                st.modes,
                st.names.len()
            ),
            &st.names,
            &st.action_model,
        )?;
        outln!();
        print_table(
            &format!(
                "plain PCA ({} modes): Eq. 9 score of each pair of the {} actions",
                st.modes,
                st.names.len()
            ),
            &st.names,
            &st.plain,
        )?;
    } else {
        outln!(
            "{} actions on {} modes, {} regions, shape only: mean Eq. 9 score {:.3} (action-specific model) vs {:.3} (plain PCA); --table prints both tables",
            st.names.len(),
            st.modes,
            region_label(&ropts),
            OrthogonalityStudy::mean_upper(&st.action_model),
            OrthogonalityStudy::mean_upper(&st.plain)
        );
    }
    Ok(())
}
