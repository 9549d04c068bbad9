//! `kslab actions`: one example frame per action, for `kslab modes` and `kslab map`.

use super::input::InputArgs;
use anyhow::Result;
use clap::Args;
use keyshape_actions::actions::choose_actions;
use std::path::PathBuf;

/// Arguments of `kslab actions`.
#[derive(Debug, Args)]
#[command(mut_arg("no_align", |a| a.hide(true)), mut_arg("points", |a| a.hide(true)))]
pub struct ActionsArgs {
    #[command(flatten)]
    input: InputArgs,
    /// Write the actions file (JSON) here [default: standard output].
    #[arg(long, short)]
    out: Option<PathBuf>,
}

pub fn run(a: &ActionsArgs) -> Result<()> {
    if a.input.no_align || a.input.points.is_some() {
        anyhow::bail!("--no-align and --points do not apply to actions: the measures read the whole face as tracked");
    }
    if a.input.dims != 2 {
        anyhow::bail!("--dims 3 does not apply to actions: the measures are image distances");
    }
    super::check_outputs(&[a.out.as_ref()], &[], &[a.input.file.as_deref()])?;
    let seq = a.input.read()?;
    let acts = choose_actions(&seq, &seq.source)?;
    let text = serde_json::to_string_pretty(&acts)? + "\n";
    let to_stdout = a.out.is_none() || super::is_stdout(a.out.as_ref());
    match &a.out {
        Some(p) => keyshape_io::write_atomic(p, |w| w.write_all(text.as_bytes()))?,
        None => out!("{text}"),
    }
    let picked: Vec<String> = acts
        .actions
        .iter()
        .map(|x| format!("{} {}", x.name, x.frame))
        .collect();
    sayln!(
        to_stdout,
        "{} actions chosen on {} ({} frames): {}{}",
        acts.actions.len(),
        seq.source,
        seq.n_frames(),
        picked.join(", "),
        a.out
            .as_ref()
            .filter(|_| !to_stdout)
            .map_or(String::new(), |p| format!(" → {}", p.display()))
    );
    Ok(())
}
