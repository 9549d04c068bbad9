//! The transferred mesh for the lab (paper 004): every frame's vertices in the front view,
//! computed once when the lab opens with `--mesh`.

use keyshape_core::decompose::{prepare, PrepareOptions};
use keyshape_core::error::Result;
use keyshape_core::sequence::Sequence;
use keyshape_io::obj::Mesh;
use keyshape_transfer::features::Features;
use keyshape_transfer::Transfer;
use rayon::prelude::*;

/// Front-view (x, y) positions of the deformed mesh per frame, with its unique edges.
#[derive(Debug, Clone)]
pub struct MeshView {
    /// Unique edges (vertex pairs).
    pub edges: Vec<(u32, u32)>,
    /// Per valid frame, (x, y) per vertex.
    pub frames: Vec<Vec<[f32; 2]>>,
    /// Feature vertices.
    pub marks: Vec<usize>,
    /// x and y bounds over all frames.
    pub bounds: ([f64; 2], [f64; 2]),
}

/// Trains the transfer on the first frame and deforms every frame.
pub fn mesh_view(seq: &Sequence, mesh: Mesh, features: Features) -> Result<MeshView> {
    let prep = prepare(seq, &PrepareOptions::all_aligned())?;
    let tr = Transfer::new(
        mesh,
        features,
        prep.seq.coords.column(0).as_slice(),
        prep.seq.dims,
        None,
    )?;
    let mut edges: Vec<(u32, u32)> = tr
        .mesh
        .faces
        .iter()
        .flat_map(|f| {
            (0..f.len()).map(move |k| {
                let (a, b) = (f[k] as u32, f[(k + 1) % f.len()] as u32);
                (a.min(b), a.max(b))
            })
        })
        .collect();
    edges.sort_unstable();
    edges.dedup();
    let frames: Vec<Vec<[f32; 2]>> = (0..prep.seq.n_frames())
        .into_par_iter()
        .map(|c| {
            tr.frame(prep.seq.coords.column(c).as_slice())
                .iter()
                .map(|p| [p[0] as f32, p[1] as f32])
                .collect()
        })
        .collect();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in frames.iter().flatten() {
        for k in 0..2 {
            lo[k] = lo[k].min(f64::from(p[k]));
            hi[k] = hi[k].max(f64::from(p[k]));
        }
    }
    let half = (hi[0] - lo[0]).max(hi[1] - lo[1]) * 0.55;
    let (cx, cy) = ((lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0);
    Ok(MeshView {
        edges,
        frames,
        marks: tr.features.features.iter().map(|f| f.target).collect(),
        bounds: ([cx - half, cx + half], [cy - half, cy + half]),
    })
}
