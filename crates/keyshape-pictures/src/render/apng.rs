//! Animated PNG output (the `png` crate's APNG support), written atomically.

use keyshape_core::error::Result;
use keyshape_io::write_atomic;
use std::path::Path;
use tiny_skia::Pixmap;

/// Writes `count` frames made on demand by `frame(i)` as an APNG playing at `fps`,
/// looping forever. All frames must have the first frame's size.
pub fn write_apng(
    path: &Path,
    count: usize,
    fps: f64,
    frame: &dyn Fn(usize) -> Result<Pixmap>,
) -> Result<()> {
    let first = frame(0)?;
    let (w, h) = (first.width(), first.height());
    let delay_ms = (1000.0 / fps.clamp(0.1, 1000.0)).round() as u16;
    write_atomic(path, |out| {
        let err = |e: png::EncodingError| std::io::Error::other(e.to_string());
        let mut enc = png::Encoder::new(out, w, h);
        enc.set_color(png::ColorType::Rgba);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_animated(count.max(1) as u32, 0).map_err(err)?;
        enc.set_frame_delay(delay_ms.max(1), 1000).map_err(err)?;
        let mut writer = enc.write_header().map_err(err)?;
        writer.write_image_data(first.data()).map_err(err)?;
        for i in 1..count {
            let pm = frame(i).map_err(|e| std::io::Error::other(e.to_string()))?;
            if pm.width() != w || pm.height() != h {
                return Err(std::io::Error::other("APNG frames differ in size"));
            }
            writer.write_image_data(pm.data()).map_err(err)?;
        }
        writer.finish().map_err(err)
    })
}
