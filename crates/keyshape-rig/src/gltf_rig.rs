//! A rig from glTF/GLB: the first mesh with morph targets (an ARKit rig exported from
//! Blender, say) and a `landmark,vertex` CSV naming its 68 landmark vertices.

use super::{read_landmark_vertices, Rig};
use keyshape_core::error::{Error, Result};
use keyshape_io::morph::MorphTargets;
use std::path::Path;

/// The mesh's positions, faces and morph targets (names from `mesh.extras.targetNames`, as
/// Blender and three.js write them, else `target<i>`). Primitives are concatenated in order;
/// vertex `i` of the landmark CSV counts across them.
pub fn read_gltf_mesh(path: &Path) -> Result<(keyshape_io::obj::Mesh, MorphTargets)> {
    let bytes = keyshape_io::read_bytes(path)?;
    let doc = gltf::Gltf::from_slice(&bytes)
        .map_err(|e| Error::file(path, format!("not a glTF file: {e}")))?;
    // Buffers: the GLB's own binary chunk, or files beside a .gltf.
    let mut data: Vec<Vec<u8>> = Vec::new();
    for b in doc.buffers() {
        data.push(match b.source() {
            gltf::buffer::Source::Bin => doc
                .blob
                .clone()
                .ok_or_else(|| Error::file(path, "a buffer refers to a binary chunk the file lacks"))?,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                return Err(Error::file(
                    path,
                    "buffers embedded as data: URIs are not read; export as GLB (binary) or with a separate .bin",
                ))
            }
            gltf::buffer::Source::Uri(uri) => {
                let p = path.parent().unwrap_or(Path::new(".")).join(uri);
                keyshape_io::read_bytes(&p)?
            }
        });
    }
    let mesh = doc
        .meshes()
        .find(|m| m.primitives().any(|p| p.morph_targets().len() > 0))
        .ok_or_else(|| Error::file(path, "no mesh with morph targets"))?;
    let names_json: Option<Vec<String>> = mesh.extras().as_ref().and_then(|raw| {
        serde_json::from_str::<serde_json::Value>(raw.get())
            .ok()?
            .get("targetNames")?
            .as_array()?
            .iter()
            .map(|v| v.as_str().map(String::from))
            .collect()
    });
    let mut positions: Vec<[f64; 3]> = Vec::new();
    let mut faces: Vec<Vec<usize>> = Vec::new();
    let mut deltas: Vec<Vec<(usize, [f64; 3])>> = Vec::new();
    let mut count = None;
    for (pi, prim) in mesh.primitives().enumerate() {
        // Positions are VEC3 FLOAT (glTF 2.0 §3.7.2.1); another type would be read as
        // garbage, not refused, by the reader below.
        let check = |acc: &gltf::Accessor, what: &str| -> Result<()> {
            if acc.data_type() != gltf::accessor::DataType::F32
                || acc.dimensions() != gltf::accessor::Dimensions::Vec3
            {
                return Err(Error::file(
                    path,
                    format!(
                        "primitive {pi}: {what} accessor {} holds {:?} {:?}; glTF positions are VEC3 FLOAT",
                        acc.index(),
                        acc.dimensions(),
                        acc.data_type()
                    ),
                ));
            }
            Ok(())
        };
        let pos_acc = prim.get(&gltf::Semantic::Positions).ok_or_else(|| {
            Error::file(path, format!("primitive {pi} has no POSITION attribute"))
        })?;
        check(&pos_acc, "POSITION")?;
        for (t, target) in prim.morph_targets().enumerate() {
            if let Some(acc) = target.positions() {
                check(&acc, &format!("morph target {t}'s POSITION"))?;
            }
        }
        let reader = prim.reader(|b| data.get(b.index()).map(Vec::as_slice));
        let base = positions.len();
        let pos: Vec<[f32; 3]> = reader
            .read_positions()
            .ok_or_else(|| {
                Error::file(
                    path,
                    format!(
                        "primitive {pi}: the POSITION accessor {} cannot be read (no buffer view, or its buffer is missing)",
                        pos_acc.index()
                    ),
                )
            })?
            .collect();
        positions.extend(pos.iter().map(|p| p.map(f64::from)));
        if let Some(idx) = reader.read_indices() {
            let idx: Vec<usize> = idx.into_u32().map(|i| i as usize + base).collect();
            faces.extend(
                idx.chunks(3)
                    .filter(|c| c.len() == 3)
                    .map(<[usize]>::to_vec),
            );
        }
        let targets: Vec<_> = reader.read_morph_targets().collect();
        if *count.get_or_insert(targets.len()) != targets.len() {
            return Err(Error::file(
                path,
                "the mesh's primitives have different numbers of morph targets",
            ));
        }
        deltas.resize(targets.len(), Vec::new());
        for (k, (p, _, _)) in targets.into_iter().enumerate() {
            let Some(p) = p else { continue };
            for (i, d) in p.enumerate() {
                if d != [0.0; 3] {
                    deltas[k].push((base + i, d.map(f64::from)));
                }
            }
        }
    }
    let k = deltas.len();
    let names = match names_json {
        Some(n) if n.len() == k => n,
        Some(n) => {
            return Err(Error::file(
                path,
                format!(
                    "mesh.extras.targetNames names {} targets, the mesh has {k}",
                    n.len()
                ),
            ))
        }
        None => (0..k).map(|i| format!("target{i}")).collect(),
    };
    for (i, n) in names.iter().enumerate() {
        keyshape_io::morph::check_name(n, &names[..i])
            .map_err(|m| Error::file(path, format!("mesh.extras.targetNames: {m}")))?;
    }
    if let Some((i, p)) = positions
        .iter()
        .enumerate()
        .find(|(_, p)| p.iter().any(|c| !c.is_finite()))
    {
        return Err(Error::file(
            path,
            format!("vertex {i} has a non-finite position {p:?}"),
        ));
    }
    for (s, d) in deltas.iter().enumerate() {
        if let Some((v, _)) = d.iter().find(|(_, o)| o.iter().any(|c| !c.is_finite())) {
            return Err(Error::file(
                path,
                format!(
                    "morph target {} moves vertex {v} by a non-finite offset",
                    names[s]
                ),
            ));
        }
    }
    Ok((
        keyshape_io::obj::Mesh { positions, faces },
        MorphTargets { names, deltas },
    ))
}

impl Rig {
    /// A rig from a glTF/GLB with morph targets and a `landmark,vertex` CSV (68 landmarks,
    /// iBUG order, vertex indices counted across the mesh's primitives).
    pub fn read_gltf(path: &Path, landmarks: &Path) -> Result<Rig> {
        let (mesh, morph) = read_gltf_mesh(path)?;
        let marks = read_landmark_vertices(landmarks, mesh.positions.len())?;
        Rig::from_parts(&mesh.positions, &morph, &marks)
    }
}
