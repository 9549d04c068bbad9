//! `kslab info`.

use super::input::InputArgs;
use anyhow::Result;
use clap::Args;
use keyshape_core::sequence::Layout;
use serde_json::json;

/// Arguments of `kslab info`.
#[derive(Debug, Args)]
#[command(mut_arg("no_align", |a| a.hide(true)))]
pub struct InfoArgs {
    #[command(flatten)]
    input: InputArgs,
    /// Print JSON instead of text.
    #[arg(long)]
    pub(crate) json: bool,
}

pub fn run(a: &InfoArgs) -> Result<()> {
    if a.input.no_align {
        anyhow::bail!(
            "--no-align does not apply to info: it always reports the file's own coordinates"
        );
    }
    let progress = super::progress::Progress::new("info: reading");
    let seq = a.input.read()?;
    progress.finish();
    let mut ranges = seq.ranges();
    let selected = match (&a.input.points, Layout::for_points(seq.points)) {
        (Some(spec), Some(l)) => {
            let idx = l.select(spec)?;
            // Ranges of the selected points only.
            ranges = seq.select_points(&idx)?.ranges();
            Some(idx.len())
        }
        (Some(spec), None) => anyhow::bail!(
            "--points {spec}: no built-in layout has {} points",
            seq.points
        ),
        _ => None,
    };
    let layout = Layout::for_points(seq.points);
    if a.json {
        return print_json(a, &seq, selected, layout.as_ref(), &ranges);
    }
    print_text(a, &seq, selected, layout.as_ref(), &ranges)
}

/// The report as JSON.
fn print_json(
    a: &InfoArgs,
    seq: &keyshape_core::sequence::Sequence,
    selected: Option<usize>,
    layout: Option<&Layout>,
    ranges: &[(f64, f64)],
) -> Result<()> {
    let axes = ["x", "y", "z"];
    let r: serde_json::Map<_, _> = ranges
        .iter()
        .zip(axes)
        .map(|((lo, hi), ax)| (ax.to_string(), json!([lo, hi])))
        .collect();
    let v = json!({
        "source": seq.source,
        "format": seq.format.name(),
        "frames": seq.n_frames(),
        "failed_frames": seq.failed,
        "points": seq.points,
        "selected_points": selected,
        "dims": seq.dims,
        "normalised": seq.is_normalised(),
        "image_size": a.input.image_size.map(|(w, h)| json!([w, h])),
        "layout": layout.map(|l| l.name.clone()),
        "groups": layout.map(|l| l.names()),
        "fps": seq.fps(),
        "segments": seq.segments.as_ref().map(|s| count_segments(s)),
        "ranges": r,
    });
    outln!("{}", serde_json::to_string_pretty(&v)?);
    Ok(())
}

/// The report as text, a line per fact.
fn print_text(
    a: &InfoArgs,
    seq: &keyshape_core::sequence::Sequence,
    selected: Option<usize>,
    layout: Option<&Layout>,
    ranges: &[(f64, f64)],
) -> Result<()> {
    let axes = ["x", "y", "z"];
    outln!("source         {}", seq.source);
    outln!("format         {}", seq.format);
    outln!("frames         {} tracked", seq.n_frames());
    let failed = if seq.failed.is_empty() {
        "none".to_string()
    } else {
        let shown: Vec<String> = seq.failed.iter().take(12).map(i64::to_string).collect();
        let more = if seq.failed.len() > 12 { ", …" } else { "" };
        format!("{} ({}{more})", seq.failed.len(), shown.join(", "))
    };
    outln!("failed frames  {failed}");
    if let (Some(first), Some(last)) = (seq.frames.iter().min(), seq.frames.iter().max()) {
        let order = if seq.frames.windows(2).all(|w| w[0] < w[1]) {
            ""
        } else {
            " (not in order in the file)"
        };
        outln!("frame numbers  {first}..={last}{order}");
    }
    outln!(
        "points         {}{}",
        seq.points,
        selected
            .map(|s| format!(" ({s} selected)"))
            .unwrap_or_default()
    );
    outln!("dims           {}", seq.dims);
    if let Some((w, h)) = a.input.image_size {
        outln!("coordinates    pixels: normalised coordinates scaled by --image-size {w}x{h} (x × {w}, y × {h})");
    } else if seq.is_normalised() {
        outln!("coordinates    normalised: every x and y in [0, 1] (MediaPipe's default; --image-size WxH for pixels)");
    }
    match layout {
        Some(l) => outln!(
            "layout         {} (groups: {})",
            l.name,
            l.names().join(", ")
        ),
        None => outln!(
            "layout         none built in for {} points (--points unavailable)",
            seq.points
        ),
    }
    if let Some(fps) = seq.fps() {
        outln!("fps            {fps:.3}");
    }
    if let Some(s) = &seq.segments {
        outln!("segments       {}", count_segments(s));
    }
    for ((lo, hi), ax) in ranges.iter().zip(axes) {
        outln!("{ax} range        {lo:.3} .. {hi:.3}");
    }
    Ok(())
}

fn count_segments(s: &[String]) -> usize {
    let mut v: Vec<&String> = s.iter().collect();
    v.sort();
    v.dedup();
    v.len()
}
