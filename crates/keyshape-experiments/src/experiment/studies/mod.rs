//! The studies a spec may hold beside its error curves, one file each. A [`Study`] runs when
//! its section of the spec is present and returns a [`Finding`]; the finding writes its own
//! files and its own keys of `report.json`. [`STUDIES`] lists them in the order they run and
//! write.
//!
//! A new study is a file here with its `Study` and `Finding`, its section on
//! [`Spec`] (serde needs a field to parse it), and a line in [`STUDIES`].

pub mod intensity;
pub mod map;
pub mod modes;
pub mod retarget;
pub mod rig;
pub mod smooth;

pub use map::{MapOutcome, MorphFace};
pub use retarget::{RetargetRow, Strip, StripSolver};

use super::Spec;
use keyshape_core::decompose::Prepared;
use keyshape_core::error::{Error, Result};
use keyshape_core::keyshapes::{Analysis, KeyOptions};
use keyshape_core::sequence::Sequence;
use keyshape_io::write_atomic;
use serde::Serialize;
use serde_json::{Map, Value};
use std::any::Any;
use std::path::{Path, PathBuf};

/// What every study may read: the spec, where its relative paths start, the sequence as
/// read, as prepared (points chosen, aligned) and its principal components.
pub struct Context<'a> {
    /// The spec as run.
    pub spec: &'a Spec,
    /// The folder its relative paths are relative to.
    pub base: &'a Path,
    /// The sequence as read.
    pub seq: &'a Sequence,
    /// The sequence prepared for the curves.
    pub prep: &'a Prepared,
    /// Its principal components.
    pub an: &'a Analysis,
    /// The curves' key-shape options (first solver, seed, shortlist).
    pub opts: &'a KeyOptions,
}

/// One study: runs when the spec asks for it.
pub trait Study: Sync {
    /// The stage of `report.json`'s `timings_s` its seconds count toward.
    fn stage(&self) -> &'static str;
    /// Runs the study, or returns `None` when the spec does not ask for it.
    fn run(&self, cx: &Context) -> Result<Option<Box<dyn Finding>>>;
    /// Puts the `report.json` keys this study owns, with their values when it did not run.
    fn absent(&self, report: &mut Map<String, Value>);
}

/// What a study found on one sequence.
pub trait Finding: std::fmt::Debug + Send + Sync {
    /// Writes its files into `out`'s folder.
    fn write(&self, out: &mut Output) -> Result<()>;
    /// Puts its keys into `report.json` (over [`Study::absent`]'s).
    fn report(&self, report: &mut Map<String, Value>);
    /// The lines a user wants on the terminal after the run.
    fn summary(&self) -> Vec<String> {
        Vec::new()
    }
    /// For a caller that needs the study's own type ([`super::Outcome::finding`]).
    fn as_any(&self) -> &dyn Any;
}

/// The studies, in the order they run and write.
pub static STUDIES: &[&dyn Study] = &[
    &retarget::RetargetStudy,
    &modes::ModesStudy,
    &intensity::IntensityStudy,
    &map::MapStudy,
    &smooth::SmoothStudy,
    &rig::RigStudy,
];

/// The report folder being written: the spec, the files written so far and the figures.
pub struct Output<'a> {
    /// The spec as run.
    pub spec: &'a Spec,
    /// The report folder.
    pub dir: &'a Path,
    /// Every file written, in order.
    pub files: Vec<PathBuf>,
    /// The figures' file names, in order (listed in `report.json`).
    pub figures: Vec<String>,
}

impl Output<'_> {
    /// Writes a CSV table of serde rows ([`keyshape_io::csv_out::write_rows`]).
    pub fn rows<R, I>(&mut self, name: &str, rows: I) -> Result<()>
    where
        R: Serialize + Default,
        I: IntoIterator<Item = R>,
    {
        self.file(name, |w| keyshape_io::csv_out::write_rows(w, rows))
    }

    /// Writes a file through `fill` (atomically) and records it.
    pub fn file<F>(&mut self, name: &str, fill: F) -> Result<()>
    where
        F: FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
    {
        let p = self.dir.join(name);
        write_atomic(&p, fill)?;
        self.files.push(p);
        Ok(())
    }

    /// Writes `value` as pretty JSON.
    pub fn json<T: Serialize>(&mut self, name: &str, value: &T) -> Result<()> {
        let text =
            serde_json::to_string_pretty(value).map_err(|e| Error::invalid(e.to_string()))?;
        self.file(name, |w| w.write_all(text.as_bytes()))
    }

    /// Saves a picture as a figure (listed in `report.json`, and after the other files).
    pub fn figure(&mut self, name: &str, picture: &tiny_skia::Pixmap) -> Result<()> {
        keyshape_pictures::render::save_png(picture, &self.dir.join(name))?;
        self.figures.push(name.to_string());
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::{Finding, Output};
    use keyshape_core::error::Result;
    use serde_json::{Map, Value};
    use std::any::Any;

    /// A finding with nothing to say on the terminal.
    #[derive(Debug)]
    struct Quiet;

    impl Finding for Quiet {
        fn write(&self, _: &mut Output) -> Result<()> {
            Ok(())
        }
        fn report(&self, _: &mut Map<String, Value>) {}
        fn as_any(&self) -> &dyn Any {
            self
        }
    }

    #[test]
    fn a_finding_prints_no_lines_unless_it_says_so() {
        assert!(Quiet.summary().is_empty());
    }
}
