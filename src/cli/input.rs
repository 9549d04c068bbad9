//! The input options every subcommand shares: file, format, dims, points, alignment.

use anyhow::Result;
use clap::Args;
use keyshape_lab::decompose::{prepare, prepare_owned, PrepareOptions, Prepared};
use keyshape_lab::io::{builtin_sequence, read_sequence, ReadOptions};
use keyshape_lab::sequence::{Format, Sequence};
use std::path::PathBuf;

/// Where the performance comes from and how to prepare it.
#[derive(Debug, Clone, Args)]
pub struct InputArgs {
    /// Tracked sequence: a CSV/JSON/.pts file or a directory of .pts files
    /// (omit for the built-in 216-frame MediaPipe sequence).
    pub file: Option<PathBuf>,
    /// Force the input format instead of detecting it: mediapipe, openface, pyfeat, pts,
    /// json or csv [default: detected from the file's name and first line].
    #[arg(long, value_parser = parse_format)]
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
}

fn parse_format(s: &str) -> Result<Format, String> {
    Format::parse(s).map_err(|e| e.to_string())
}

impl InputArgs {
    /// Reads the sequence as given.
    pub fn read(&self) -> Result<Sequence> {
        let opts = ReadOptions {
            format: self.format,
            dims: usize::from(self.dims),
        };
        Ok(match &self.file {
            Some(p) => read_sequence(p, &opts)?,
            None => {
                if self.dims == 3 {
                    anyhow::bail!("the built-in sequence is 2-D; use --dims 2 or give a file");
                }
                builtin_sequence()?
            }
        })
    }

    /// Reads and prepares, keeping only the prepared sequence: aligned in place, so a long
    /// track is held once.
    pub fn prepare_only(&self) -> Result<Prepared> {
        let seq = self.read()?;
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
