//! Pictures with tiny-skia: line plots from [`crate::plot::PlotSpec`]. The numeric core never
//! calls in here.

pub mod apng;
mod chart;
pub mod face;
pub mod heat;
pub mod mesh;
pub mod text;
pub mod weights;

pub use chart::{log_ticks, render_plot};

use keyshape_core::error::{Error, Result};
use keyshape_io::write_atomic;
use std::path::Path;
use tiny_skia::Pixmap;

/// Writes a pixmap as PNG, atomically.
pub fn save_png(pixmap: &Pixmap, path: &Path) -> Result<()> {
    let bytes = pixmap
        .encode_png()
        .map_err(|e| Error::invalid(format!("{}: PNG encoding failed: {e}", path.display())))?;
    write_atomic(path, |w| w.write_all(&bytes))
}
