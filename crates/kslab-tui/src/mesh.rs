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
    let edges = drawn_edges(&tr.mesh.faces);
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

/// The edges the panel draws. In braille a terminal panel has a few thousand dots: the
/// whole wireframe of a dense mesh (the ICT face's 9,409 vertices) fills it as a solid
/// blob, so a mesh of more than [`WIREFRAME_EDGES`] edges is drawn by its open edges (those
/// of one face: the outline, the eyes, the mouth), which read as a face at any size.
pub fn drawn_edges(faces: &[Vec<usize>]) -> Vec<(u32, u32)> {
    let mut all: Vec<(u32, u32)> = faces
        .iter()
        .flat_map(|f| {
            (0..f.len()).map(move |k| {
                let (a, b) = (f[k] as u32, f[(k + 1) % f.len()] as u32);
                (a.min(b), a.max(b))
            })
        })
        .collect();
    all.sort_unstable();
    let mut open = Vec::new();
    let mut i = 0;
    while i < all.len() {
        let mut j = i + 1;
        while j < all.len() && all[j] == all[i] {
            j += 1;
        }
        if j - i == 1 {
            open.push(all[i]);
        }
        i = j;
    }
    all.dedup();
    if all.len() > WIREFRAME_EDGES && !open.is_empty() {
        open
    } else {
        all
    }
}

/// The most edges drawn as a whole wireframe.
pub const WIREFRAME_EDGES: usize = 1500;

#[cfg(test)]
mod tests {
    use super::drawn_edges;

    #[test]
    fn a_small_mesh_is_drawn_whole_and_a_dense_one_by_its_open_edges() {
        // Two triangles sharing the edge (1, 2).
        let faces = vec![vec![0, 1, 2], vec![1, 3, 2]];
        assert_eq!(drawn_edges(&faces).len(), 5);
        // A 40 × 40 grid of quads: 3,280 edges, of which the 160 on its border are open.
        let n = 41;
        let mut grid = Vec::new();
        for r in 0..n - 1 {
            for c in 0..n - 1 {
                let v = r * n + c;
                grid.push(vec![v, v + 1, v + n + 1, v + n]);
            }
        }
        let e = drawn_edges(&grid);
        assert_eq!(e.len(), 160);
        assert!(e.iter().all(|&(a, b)| {
            let on_border = |v: u32| {
                let (r, c) = (v as usize / n, v as usize % n);
                r == 0 || c == 0 || r == n - 1 || c == n - 1
            };
            on_border(a) && on_border(b)
        }));
    }
}
