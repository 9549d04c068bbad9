//! keyshape-pictures: what the lab draws. [`plot`] describes a chart as plain data (the
//! PNG renderer and the terminal's chart both draw from a [`plot::PlotSpec`]); [`render`]
//! draws charts, faces, meshes, weight strips and heat maps with tiny-skia and writes them
//! as PNG or APNG, each file whole or not at all.

pub mod plot;
pub mod render;
