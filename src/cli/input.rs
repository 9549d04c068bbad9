//! The input options every subcommand shares: file, format, dims, points, alignment.

use anyhow::Result;
use clap::Args;
use keyshape_core::decompose::{prepare, prepare_owned, PrepareOptions, Prepared};
use keyshape_core::sequence::{Format, Sequence};
use keyshape_io::{builtin_sequence, read_sequence, ReadOptions};
use std::path::PathBuf;

/// Where the performance comes from and how to prepare it.
#[derive(Debug, Clone, Args)]
pub struct InputArgs {
    /// Tracked sequence: a CSV/JSON/.pts file or a directory of .pts files
    /// (omit for the built-in 216-frame MediaPipe sequence).
    pub file: Option<PathBuf>,
    /// Force the input format instead of detecting it: mediapipe, openface, pyfeat, pts,
    /// json or csv [default: detected from the file's name and first line].
    #[arg(long)]
    pub format: Option<Format>,
    /// 2 for (x, y), 3 for (x, y, z).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(2..=3))]
    pub dims: u8,
    /// Work on these point groups only, e.g. `lips` or `eyes,brows` (see `kslab info`)
    /// [default: every point].
    #[arg(long, value_name = "GROUP[,GROUP]")]
    pub points: Option<String>,
    /// Keep raw coordinates: do not remove 2-D head motion (alignment is on by default).
    #[arg(long)]
    pub no_align: bool,
    /// The video's size in pixels, WIDTHxHEIGHT (e.g. 1280x720), for a track in normalised
    /// coordinates (MediaPipe's default: every x and y in [0, 1]): x is scaled by WIDTH, y
    /// (and z) as MediaPipe defines them, so that shapes keep their aspect and errors are
    /// in pixels. Refused for a track in pixels. [default: the coordinates as read]
    #[arg(long, value_name = "WxH", value_parser = parse_image_size)]
    pub image_size: Option<(f64, f64)>,
}

/// [`read_sequence`], with what the reader notes about the file (a cut last row) said on
/// standard error.
pub fn read_noting(path: &std::path::Path, opts: &ReadOptions) -> Result<Sequence> {
    let seq = read_sequence(path, opts)?;
    for n in &seq.notes {
        errln!("warning: {n}");
    }
    Ok(seq)
}

/// A command-line parser for a count within `limit` (the one declaration of its range in
/// `keyshape_core::limits`, which the experiment files and the library check too).
pub fn count_within(
    limit: &'static keyshape_core::limits::Limit,
) -> impl Fn(&str) -> Result<usize, String> + Clone + Send + Sync + 'static {
    move |s: &str| {
        let v: u64 = s
            .trim()
            .parse()
            .map_err(|_| format!("'{s}' is not a count: give {}", limit.describe()))?;
        if limit.contains(v as f64) {
            usize::try_from(v).map_err(|_| format!("{v}: a count beyond this machine"))
        } else {
            Err(limit.why_count(v))
        }
    }
}

/// A command-line parser for a number within `limit` (see [`count_within`]).
pub fn number_within(
    limit: &'static keyshape_core::limits::Limit,
) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync + 'static {
    move |s: &str| {
        let v: f64 = s
            .trim()
            .parse()
            .map_err(|_| format!("'{s}' is not a number: give {}", limit.describe()))?;
        if limit.contains(v) {
            Ok(v)
        } else {
            Err(limit.why(v))
        }
    }
}

/// `WIDTHxHEIGHT` in pixels.
pub fn parse_image_size(s: &str) -> Result<(f64, f64), String> {
    let bad = || format!("'{s}' is not an image size: give WIDTHxHEIGHT in pixels, e.g. 1280x720");
    let (w, h) = s.split_once(['x', 'X', '×']).ok_or_else(bad)?;
    let w: f64 = w.trim().parse().map_err(|_| bad())?;
    let h: f64 = h.trim().parse().map_err(|_| bad())?;
    if !(w.is_finite() && w >= 1.0 && h.is_finite() && h >= 1.0) {
        return Err(bad());
    }
    Ok((w, h))
}

/// Applies `--image-size` to a sequence just read, or says on standard error that its
/// coordinates are normalised (MediaPipe's default) when none was given.
pub fn apply_image_size(seq: &mut Sequence, size: Option<(f64, f64)>) -> Result<()> {
    match size {
        Some((w, h)) => seq
            .scale_to_image(w, h)
            .map_err(|e| anyhow::anyhow!("--image-size {w}x{h}: {e}"))?,
        None if seq.is_normalised() => errln!(
            "note: {}: every x and y lies in [0, 1]: normalised image coordinates (MediaPipe's default). Errors and distances are fractions of the image, and x and y are on different scales unless the video is square: give --image-size WIDTHxHEIGHT to work in pixels.",
            seq.source
        ),
        None => {}
    }
    Ok(())
}

/// How a picture's title names the track: the file's name and the point group
/// (`liveportrait_d6.csv · lips`, `… · all points`).
pub fn track_label(source: &str, points: Option<&str>) -> String {
    format!(
        "{} · {}",
        super::curves::short(source),
        points.unwrap_or("all points")
    )
}

impl InputArgs {
    /// Reads the sequence as given.
    pub fn read(&self) -> Result<Sequence> {
        let opts = ReadOptions {
            format: self.format,
            dims: usize::from(self.dims),
        };
        let mut seq = match &self.file {
            Some(p) => read_noting(p, &opts)?,
            None => {
                if self.dims == 3 {
                    anyhow::bail!("the built-in sequence is 2-D; use --dims 2 or give a file");
                }
                builtin_sequence()?
            }
        };
        apply_image_size(&mut seq, self.image_size)?;
        Ok(seq)
    }

    /// Reads and prepares, keeping only the prepared sequence: aligned in place, so a long
    /// track is held once.
    pub fn prepare_only(&self) -> Result<Prepared> {
        let seq = self.read()?;
        Ok(prepare_owned(seq, &self.prepare_options())?)
    }

    /// Prepares a sequence already read by [`InputArgs::read`].
    pub fn prepare_read(&self, seq: &Sequence) -> Result<Prepared> {
        Ok(prepare(seq, &self.prepare_options())?)
    }

    /// [`InputArgs::prepare_read`] in place (a long track held once).
    pub fn prepare_owned_read(&self, seq: Sequence) -> Result<Prepared> {
        Ok(prepare_owned(seq, &self.prepare_options())?)
    }

    fn prepare_options(&self) -> PrepareOptions {
        PrepareOptions {
            points: self.points.clone(),
            align: !self.no_align,
        }
    }

    /// Reads and prepares (selects points, aligns).
    pub fn prepare(&self) -> Result<(Sequence, Prepared)> {
        let seq = self.read()?;
        let prepared = prepare(&seq, &self.prepare_options())?;
        Ok((seq, prepared))
    }
}

/// `--head-position`: a position, or none.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum HeadPosition {
    At([f32; 3]),
    None,
}

pub(crate) fn parse_head_position(s: &str) -> std::result::Result<HeadPosition, String> {
    if s.trim() == "none" {
        return Ok(HeadPosition::None);
    }
    let v: Vec<f64> = s
        .split(',')
        .map(|c| c.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| format!("'{s}' is not X,Y,Z (three numbers, metres) or none"))?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite() && c.abs() <= 10.0) => {
            Ok(HeadPosition::At([x as f32, y as f32, z as f32]))
        }
        [_, _, _] => Err(format!(
            "'{s}': each coordinate must be a finite number of metres within ±10"
        )),
        _ => Err(format!(
            "'{s}' is not X,Y,Z (three numbers, metres) or none"
        )),
    }
}
