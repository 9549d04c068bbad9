//! The built-in default sequence, so `kslab` runs with no data files.
//!
//! `assets/builtin_d18.csv.gz` is derived by `tools/make_builtin.py` from
//! `../shared/data/mediapipe_face_tracks/liveportrait_d18.csv`: a MediaPipe Face Mesh
//! (468 points) track of LivePortrait's driving clip d18 (216 frames, 30 fps, a man going
//! from neutral to "oo" to a wide-open scream), x/y in pixels rounded to 0.1 px.

use super::table;
use keyshape_core::error::{Error, Result};
use keyshape_core::sequence::{Format, Sequence};
use std::io::Read;
use std::path::Path;

/// The name the built-in sequence goes by (`source` of the returned sequence).
pub const BUILTIN_NAME: &str = "builtin:liveportrait_d18";

const BYTES: &[u8] = include_bytes!("../../../assets/builtin_d18.csv.gz");

/// The built-in 468-point, 216-frame 2-D sequence.
pub fn builtin_sequence() -> Result<Sequence> {
    let mut text = String::new();
    flate2::read::GzDecoder::new(BYTES)
        .read_to_string(&mut text)
        .map_err(|e| Error::file(BUILTIN_NAME, format!("embedded data is corrupt: {e}")))?;
    let mut seq = table::read(Path::new(BUILTIN_NAME), &text, Format::Csv, 2)?;
    seq.source = BUILTIN_NAME.to_string();
    seq.validate()?;
    Ok(seq)
}

/// A table built into the binary for a layout family: the text `table` holds for `family`
/// (pairs of family and JSON text), parsed. `what` names the table in the errors: a family
/// with no table, and a table that does not parse (a fault of the build, not of the user).
pub fn builtin_json<T: serde::de::DeserializeOwned>(
    what: &str,
    family: &str,
    table: &[(&str, &str)],
) -> Result<T> {
    let Some((_, text)) = table.iter().find(|(f, _)| *f == family) else {
        return Err(Error::invalid(format!(
            "no built-in {what} for layout {family}"
        )));
    };
    serde_json::from_str(text).map_err(|e| Error::invalid(format!("built-in {what}: {e}")))
}
