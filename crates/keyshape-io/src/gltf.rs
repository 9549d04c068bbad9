//! glTF 2.0 binary (GLB) export, two kinds:
//!
//! * a skinned mesh ([`write_skinned_glb`]), as a feature-point transfer exports it
//!   (`transfer`): linear-blend skinning, which glTF has natively: one joint per feature
//!   point (plus a still root joint for vertices no feature reaches), the skin weights as
//!   `JOINTS_0` / `WEIGHTS_0`, and the performance as translation animation of the joints.
//!   A skinned vertex is then `Σ wᵢ (v + dᵢ) = v + Σ wᵢ dᵢ` — exactly the transfer's
//!   skinning. Chosen over baked morph targets because it stays small (joints × frames × 3
//!   floats, not vertices × frames) and keeps the rig editable in Blender;
//! * a mesh with morph targets and a weights animation ([`write_morph_glb`]).

use keyshape_core::error::{Error, Result};
use serde_json::{json, Value};
use std::io::Write;

/// A binary buffer under construction, with its buffer views and accessors.
struct Bin {
    data: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Bin {
    /// Appends `bytes` (4-byte aligned) as a buffer view and an accessor over it.
    fn push(&mut self, bytes: &[u8], target: Option<u32>, accessor: Value) -> usize {
        while self.data.len() % 4 != 0 {
            self.data.push(0);
        }
        let mut view =
            json!({ "buffer": 0, "byteOffset": self.data.len(), "byteLength": bytes.len() });
        if let Some(t) = target {
            view["target"] = json!(t);
        }
        self.data.extend_from_slice(bytes);
        self.views.push(view);
        let mut acc = accessor;
        acc["bufferView"] = json!(self.views.len() - 1);
        self.accessors.push(acc);
        self.accessors.len() - 1
    }
}

impl Bin {
    /// The mesh's POSITION accessor (with bounds) and triangulated index accessor.
    fn geometry(&mut self, positions: &[[f64; 3]], faces: &[Vec<usize>]) -> (usize, usize) {
        let (pos_bytes, pos) = f32s(positions.iter().flatten().copied());
        let (lo, hi) = min_max3(&pos);
        let a_pos = self.push(
            &pos_bytes,
            Some(34962),
            json!({ "componentType": 5126, "count": positions.len(), "type": "VEC3", "min": lo, "max": hi }),
        );
        let tris: Vec<u32> = faces
            .iter()
            .flat_map(|f| {
                (1..f.len() - 1).flat_map(move |k| [f[0] as u32, f[k] as u32, f[k + 1] as u32])
            })
            .collect();
        let idx: Vec<u8> = tris.iter().flat_map(|x| x.to_le_bytes()).collect();
        let a_idx = self.push(
            &idx,
            Some(34963),
            json!({ "componentType": 5125, "count": tris.len(), "type": "SCALAR" }),
        );
        (a_pos, a_idx)
    }
}

fn f32s(v: impl IntoIterator<Item = f64>) -> (Vec<u8>, Vec<f32>) {
    let vals: Vec<f32> = v.into_iter().map(|x| x as f32).collect();
    (vals.iter().flat_map(|x| x.to_le_bytes()).collect(), vals)
}

fn min_max3(vals: &[f32]) -> (Vec<f32>, Vec<f32>) {
    let mut lo = vec![f32::INFINITY; 3];
    let mut hi = vec![f32::NEG_INFINITY; 3];
    for p in vals.chunks(3) {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo, hi)
}

/// A skinned, animated mesh in plain data: what [`write_skinned_glb`] writes.
#[derive(Debug, Clone, Copy)]
pub struct Skinned<'a> {
    /// The mesh at rest.
    pub positions: &'a [[f64; 3]],
    /// Its faces (polygons, triangulated as fans).
    pub faces: &'a [Vec<usize>],
    /// Per vertex: (joint, weight) pairs, at most 4 used; none binds the vertex to the
    /// still root joint.
    pub influences: &'a [Vec<(usize, f64)>],
    /// Joint names.
    pub names: &'a [&'a str],
    /// Joint positions at rest.
    pub rest: &'a [[f64; 3]],
    /// Per frame, each joint's position (frames × joints).
    pub tracks: &'a [Vec<[f64; 3]>],
    /// Frames per second.
    pub fps: f64,
}

/// Writes a skinned mesh animated by its joints' translations as GLB.
pub fn write_skinned_glb(w: &mut dyn Write, sk: &Skinned) -> std::io::Result<()> {
    let mut bin = Bin {
        data: Vec::new(),
        views: Vec::new(),
        accessors: Vec::new(),
    };
    let nv = sk.positions.len();
    let nf = sk.rest.len();
    // Geometry.
    let (a_pos, a_idx) = bin.geometry(sk.positions, sk.faces);
    let mut joints = Vec::with_capacity(nv * 8);
    let mut weights = Vec::with_capacity(nv * 4);
    for inf in sk.influences {
        let mut j = [0u16; 4];
        let mut wt = [0f32; 4];
        if inf.is_empty() {
            wt[0] = 1.0; // the still root joint
        }
        for (k, &(f, x)) in inf.iter().take(4).enumerate() {
            j[k] = (f + 1) as u16;
            wt[k] = x as f32;
        }
        // Make the float weights sum to 1 exactly in f32, as validators check.
        let s: f32 = wt.iter().sum();
        let i = wt
            .iter()
            .enumerate()
            .fold(0, |m, (i, x)| if *x > wt[m] { i } else { m });
        wt[i] += 1.0 - s;
        joints.extend(j.iter().flat_map(|x| x.to_le_bytes()));
        weights.extend(wt.iter().flat_map(|x| x.to_le_bytes()));
    }
    let a_j = bin.push(
        &joints,
        Some(34962),
        json!({ "componentType": 5123, "count": nv, "type": "VEC4" }),
    );
    let a_w = bin.push(
        &weights,
        Some(34962),
        json!({ "componentType": 5126, "count": nv, "type": "VEC4" }),
    );
    // Skin: inverse bind matrices (column-major), identity for the root, −t0 for features.
    let mut ibm = Vec::new();
    for f in 0..=nf {
        let t = if f == 0 { [0.0; 3] } else { sk.rest[f - 1] };
        let m = [
            1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -t[0], -t[1], -t[2], 1.0,
        ];
        ibm.extend(m.iter().flat_map(|x| (*x as f32).to_le_bytes()));
    }
    let a_ibm = bin.push(
        &ibm,
        None,
        json!({ "componentType": 5126, "count": nf + 1, "type": "MAT4" }),
    );
    // Animation: per frame, each joint's translation t0 + d.
    let n = sk.tracks.len();
    let times: Vec<f32> = (0..n).map(|t| (t as f64 / sk.fps) as f32).collect();
    let tb: Vec<u8> = times.iter().flat_map(|x| x.to_le_bytes()).collect();
    let a_time = bin.push(&tb, None, json!({ "componentType": 5126, "count": n, "type": "SCALAR", "min": [times[0]], "max": [times[n - 1]] }));
    let (mut samplers, mut channels) = (Vec::new(), Vec::new());
    for f in 0..nf {
        let (bytes, _) = f32s(sk.tracks.iter().flat_map(|p| p[f]));
        let a = bin.push(
            &bytes,
            None,
            json!({ "componentType": 5126, "count": n, "type": "VEC3" }),
        );
        samplers.push(json!({ "input": a_time, "output": a, "interpolation": "LINEAR" }));
        channels.push(json!({ "sampler": f, "target": { "node": f + 2, "path": "translation" } }));
    }
    let mut nodes = vec![
        json!({ "name": "face", "mesh": 0, "skin": 0 }),
        json!({ "name": "root", "children": (2..nf + 2).collect::<Vec<_>>() }),
    ];
    for (name, t) in sk.names.iter().zip(sk.rest) {
        nodes.push(
            json!({ "name": name, "translation": t.iter().map(|x| *x as f32).collect::<Vec<_>>() }),
        );
    }
    let doc = json!({
        "asset": { "version": "2.0", "generator": concat!("keyshape-lab ", env!("CARGO_PKG_VERSION")) },
        "scene": 0,
        "scenes": [{ "nodes": [0, 1] }],
        "nodes": nodes,
        "meshes": [{ "name": "face", "primitives": [{ "attributes": { "POSITION": a_pos, "JOINTS_0": a_j, "WEIGHTS_0": a_w }, "indices": a_idx, "mode": 4 }] }],
        "skins": [{ "joints": (1..nf + 2).collect::<Vec<_>>(), "inverseBindMatrices": a_ibm, "skeleton": 1 }],
        "animations": [{ "name": "performance", "samplers": samplers, "channels": channels }],
        "accessors": bin.accessors,
        "bufferViews": bin.views,
        "buffers": [{ "byteLength": bin.data.len() }],
    });
    write_glb_chunks(w, doc, bin.data)
}

/// Checks that `joints` (plus the root) fit glTF's 16-bit joint indices.
pub fn check_joints(joints: usize) -> Result<()> {
    if joints + 1 > u16::MAX as usize {
        return Err(Error::invalid("too many feature points for glTF joints"));
    }
    Ok(())
}

/// Writes a mesh with morph targets and a weights animation as GLB: `targets` are
/// (name, dense per-vertex offsets), `weights` is targets × frames. Target names go in
/// `mesh.extras.targetNames` (Blender, three.js).
pub fn write_morph_glb(
    w: &mut dyn Write,
    neutral: &[[f64; 3]],
    faces: &[Vec<usize>],
    targets: &[(String, Vec<[f64; 3]>)],
    weights: &nalgebra::DMatrix<f64>,
    fps: f64,
) -> std::io::Result<()> {
    write_morph_glb_posed(w, neutral, faces, targets, weights, fps, None)
}

/// [`write_morph_glb`] with the node's rotation animated too: one unit quaternion per frame
/// (`[x, y, z, w]`, glTF's order), e.g. a fitted head pose.
pub fn write_morph_glb_posed(
    w: &mut dyn Write,
    neutral: &[[f64; 3]],
    faces: &[Vec<usize>],
    targets: &[(String, Vec<[f64; 3]>)],
    weights: &nalgebra::DMatrix<f64>,
    fps: f64,
    rotations: Option<&[[f64; 4]]>,
) -> std::io::Result<()> {
    let mut bin = Bin {
        data: Vec::new(),
        views: Vec::new(),
        accessors: Vec::new(),
    };
    let nv = neutral.len();
    let (a_pos, a_idx) = bin.geometry(neutral, faces);
    let mut tacc = Vec::new();
    for (_, d) in targets {
        let (bytes, vals) = f32s(d.iter().flatten().copied());
        let (lo, hi) = min_max3(&vals);
        tacc.push(json!({ "POSITION": bin.push(&bytes, Some(34962), json!({ "componentType": 5126, "count": nv, "type": "VEC3", "min": lo, "max": hi })) }));
    }
    let n = weights.ncols();
    let times: Vec<f32> = (0..n).map(|t| (t as f64 / fps) as f32).collect();
    let tb: Vec<u8> = times.iter().flat_map(|x| x.to_le_bytes()).collect();
    let a_time = bin.push(&tb, None, json!({ "componentType": 5126, "count": n, "type": "SCALAR", "min": [times[0]], "max": [times[n - 1]] }));
    let (wb, _) =
        f32s((0..n).flat_map(|t| (0..targets.len()).map(move |s| weights[(s, t)].clamp(0.0, 1.0))));
    let a_w = bin.push(
        &wb,
        None,
        json!({ "componentType": 5126, "count": n * targets.len(), "type": "SCALAR" }),
    );
    let names: Vec<&str> = targets.iter().map(|t| t.0.as_str()).collect();
    let mut samplers = vec![json!({ "input": a_time, "output": a_w, "interpolation": "LINEAR" })];
    let mut channels = vec![json!({ "sampler": 0, "target": { "node": 0, "path": "weights" } })];
    if let Some(q) = rotations {
        if q.len() != n {
            return Err(std::io::Error::other(format!(
                "{} head rotations for {n} frames",
                q.len()
            )));
        }
        let (qb, _) = f32s(q.iter().flatten().copied());
        let a_q = bin.push(
            &qb,
            None,
            json!({ "componentType": 5126, "count": n, "type": "VEC4" }),
        );
        samplers.push(json!({ "input": a_time, "output": a_q, "interpolation": "LINEAR" }));
        channels.push(json!({ "sampler": 1, "target": { "node": 0, "path": "rotation" } }));
    }
    let doc = json!({
        "asset": { "version": "2.0", "generator": concat!("keyshape-lab ", env!("CARGO_PKG_VERSION")) },
        "scene": 0,
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "name": "face", "mesh": 0 }],
        "meshes": [{ "name": "face", "primitives": [{ "attributes": { "POSITION": a_pos }, "indices": a_idx, "mode": 4, "targets": tacc }],
                     "weights": vec![0.0; targets.len()], "extras": { "targetNames": names } }],
        "animations": [{ "name": "performance", "samplers": samplers, "channels": channels }],
        "accessors": bin.accessors,
        "bufferViews": bin.views,
        "buffers": [{ "byteLength": bin.data.len() }],
    });
    write_glb_chunks(w, doc, bin.data)
}

fn write_glb_chunks(w: &mut dyn Write, doc: Value, mut data: Vec<u8>) -> std::io::Result<()> {
    let mut js = serde_json::to_vec(&doc).map_err(std::io::Error::other)?;
    while js.len() % 4 != 0 {
        js.push(b' ');
    }
    while data.len() % 4 != 0 {
        data.push(0);
    }
    let total = 12 + 8 + js.len() + 8 + data.len();
    w.write_all(b"glTF")?;
    w.write_all(&2u32.to_le_bytes())?;
    w.write_all(&(total as u32).to_le_bytes())?;
    w.write_all(&(js.len() as u32).to_le_bytes())?;
    w.write_all(b"JSON")?;
    w.write_all(&js)?;
    w.write_all(&(data.len() as u32).to_le_bytes())?;
    w.write_all(b"BIN\0")?;
    w.write_all(&data)
}

#[cfg(test)]
mod tests {
    use super::check_joints;

    /// glTF's JOINTS_0 holds u16 indices and the still root joint takes one: 65,534
    /// feature joints fit, 65,535 do not, and the refusal says why.
    #[test]
    fn joints_past_sixteen_bits_are_refused() {
        assert!(check_joints(0).is_ok());
        assert!(check_joints(u16::MAX as usize - 1).is_ok());
        let e = check_joints(u16::MAX as usize).unwrap_err().to_string();
        assert!(e.contains("too many feature points for glTF joints"), "{e}");
    }
}
