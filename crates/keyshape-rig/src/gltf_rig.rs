//! A rig from glTF/GLB: the first mesh with morph targets (an ARKit rig exported from
//! Blender, say) and a `landmark,vertex` CSV naming its 68 landmark vertices.

use super::{read_landmark_vertices, Rig};
use keyshape_core::error::{Error, Result};
use keyshape_core::sequence::coord_problem;
use keyshape_io::morph::MorphTargets;
use std::path::Path;

/// The mesh's positions, faces and morph targets (names from `mesh.extras.targetNames`, as
/// Blender and three.js write them, else `target<i>`). Primitives are concatenated in order;
/// vertex `i` of the landmark CSV counts across them.
pub fn read_gltf_mesh(path: &Path) -> Result<(keyshape_io::obj::Mesh, MorphTargets)> {
    let bytes = keyshape_io::read_bytes(path)?;
    let doc = gltf::Gltf::from_slice(&bytes)
        .map_err(|e| Error::file(path, format!("not a glTF file: {e}")))?;
    let data = buffers(path, &doc)?;
    let mesh = doc
        .meshes()
        .find(|m| m.primitives().any(|p| p.morph_targets().len() > 0))
        .ok_or_else(|| Error::file(path, "no mesh with morph targets"))?;
    let names_json = target_names(path, mesh.extras().as_ref().map(|r| r.get()))?;
    let mut read = Concatenated::default();
    for (pi, prim) in mesh.primitives().enumerate() {
        let pos_acc = checked_accessors(path, pi, &prim)?;
        read.push(path, pi, &prim, &pos_acc, &data)?;
    }
    let Concatenated {
        positions,
        faces,
        deltas,
        ..
    } = read;
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
    check_coordinates(path, &positions, &deltas, &names)?;
    Ok((
        keyshape_io::obj::Mesh { positions, faces },
        MorphTargets { names, deltas },
    ))
}

/// The document's buffers: the GLB's own binary chunk, or files beside a .gltf.
fn buffers(path: &Path, doc: &gltf::Gltf) -> Result<Vec<Vec<u8>>> {
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
    Ok(data)
}

/// Primitive `pi`'s POSITION accessor, after checking that it and each morph target's are
/// VEC3 FLOAT (glTF 2.0 §3.7.2.1; another type would be read as garbage, not refused, by
/// the reader), dense, and that every target has one offset per vertex.
fn checked_accessors<'a>(
    path: &Path,
    pi: usize,
    prim: &gltf::Primitive<'a>,
) -> Result<gltf::Accessor<'a>> {
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
    let pos_acc = prim
        .get(&gltf::Semantic::Positions)
        .ok_or_else(|| Error::file(path, format!("primitive {pi} has no POSITION attribute")))?;
    check(&pos_acc, "POSITION")?;
    check_sparse(path, pi, &pos_acc)?;
    for (t, target) in prim.morph_targets().enumerate() {
        if let Some(acc) = target.positions() {
            check(&acc, &format!("morph target {t}'s POSITION"))?;
            check_sparse(path, pi, &acc)?;
            // A target of another length would move the first vertices only and freeze
            // the rest of the shape, silently.
            if acc.count() != pos_acc.count() {
                return Err(Error::file(
                    path,
                    format!(
                        "primitive {pi}: morph target {t}'s POSITION accessor {} has {} entries, the mesh {} vertices (glTF 2.0 §3.7.2.2: a target has one offset per vertex)",
                        acc.index(),
                        acc.count(),
                        pos_acc.count()
                    ),
                ));
            }
        }
    }
    Ok(pos_acc)
}

/// The mesh's primitives read so far, concatenated: vertex numbers count across them.
#[derive(Default)]
struct Concatenated {
    positions: Vec<[f64; 3]>,
    faces: Vec<Vec<usize>>,
    /// Per morph target, its non-zero offsets (vertex, offset).
    deltas: Vec<Vec<(usize, [f64; 3])>>,
    /// The number of morph targets, which every primitive must have.
    count: Option<usize>,
}

impl Concatenated {
    /// Appends primitive `pi` (its POSITION accessor checked): positions, triangles and
    /// morph offsets.
    fn push(
        &mut self,
        path: &Path,
        pi: usize,
        prim: &gltf::Primitive,
        pos_acc: &gltf::Accessor,
        data: &[Vec<u8>],
    ) -> Result<()> {
        let reader = prim.reader(|b| data.get(b.index()).map(Vec::as_slice));
        let base = self.positions.len();
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
        self.positions.extend(pos.iter().map(|p| p.map(f64::from)));
        if let Some(idx) = reader.read_indices() {
            let idx: Vec<usize> = idx.into_u32().map(|i| i as usize + base).collect();
            if let Some(&bad) = idx.iter().find(|&&i| i >= base + pos.len()) {
                return Err(Error::file(
                    path,
                    format!(
                        "primitive {pi}: a triangle names vertex {} of {}",
                        bad - base,
                        pos.len()
                    ),
                ));
            }
            self.faces.extend(
                idx.chunks(3)
                    .filter(|c| c.len() == 3)
                    .map(<[usize]>::to_vec),
            );
        }
        let targets: Vec<_> = reader.read_morph_targets().collect();
        if *self.count.get_or_insert(targets.len()) != targets.len() {
            return Err(Error::file(
                path,
                "the mesh's primitives have different numbers of morph targets",
            ));
        }
        self.deltas.resize(targets.len(), Vec::new());
        for (k, (p, _, _)) in targets.into_iter().enumerate() {
            let Some(p) = p else { continue };
            for (i, d) in p.enumerate() {
                if d != [0.0; 3] {
                    self.deltas[k].push((base + i, d.map(f64::from)));
                }
            }
        }
        Ok(())
    }
}

/// Refuses positions and offsets outside the coordinates every reader accepts (±1e30),
/// naming the vertex (and the target).
fn check_coordinates(
    path: &Path,
    positions: &[[f64; 3]],
    deltas: &[Vec<(usize, [f64; 3])>],
    names: &[String],
) -> Result<()> {
    let problem = |p: &[f64; 3]| p.iter().find_map(|&c| coord_problem(c));
    if let Some((i, why)) = positions
        .iter()
        .enumerate()
        .find_map(|(i, p)| problem(p).map(|w| (i, w)))
    {
        return Err(Error::file(path, format!("vertex {i}: {why}")));
    }
    for (s, d) in deltas.iter().enumerate() {
        if let Some((v, why)) = d.iter().find_map(|(v, o)| problem(o).map(|w| (*v, w))) {
            return Err(Error::file(
                path,
                format!("morph target {} moves vertex {v}: {why}", names[s]),
            ));
        }
    }
    Ok(())
}

/// `mesh.extras.targetNames`, when the extras hold it: an array of strings, else an error
/// naming the entry that is not one (a number among them made every name `target<i>`).
fn target_names(path: &Path, extras: Option<&str>) -> Result<Option<Vec<String>>> {
    let Some(raw) = extras else {
        return Ok(None);
    };
    let v: serde_json::Value = serde_json::from_str(raw)
        .map_err(|e| Error::file(path, format!("mesh.extras is not JSON: {e}")))?;
    let Some(names) = v.get("targetNames") else {
        return Ok(None);
    };
    let list = names
        .as_array()
        .ok_or_else(|| Error::file(path, "mesh.extras.targetNames is not an array of names"))?;
    list.iter()
        .enumerate()
        .map(|(i, n)| {
            n.as_str().map(String::from).ok_or_else(|| {
                Error::file(
                    path,
                    format!("mesh.extras.targetNames[{i}] is {n}, not a name (a string)"),
                )
            })
        })
        .collect::<Result<Vec<_>>>()
        .map(Some)
}

/// A sparse accessor may replace at most as many entries as the accessor has (a count of
/// 2⁴⁰ was accepted, to be read for ever or to run out of memory).
fn check_sparse(path: &Path, pi: usize, acc: &gltf::Accessor) -> Result<()> {
    if let Some(sp) = acc.sparse() {
        if sp.count() > acc.count() {
            return Err(Error::file(
                path,
                format!(
                    "primitive {pi}: accessor {} replaces {} sparse entries of its {} (glTF 2.0 §3.6.2.3: at most as many as it has)",
                    acc.index(),
                    sp.count(),
                    acc.count()
                ),
            ));
        }
    }
    Ok(())
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
