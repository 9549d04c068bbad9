//! The glTF rig reader refuses what it cannot represent (round three found each accepted):
//! a morph target shorter than its mesh (the shape silently frozen past it), a sparse
//! accessor replacing more entries than it has (2⁴⁰), a `targetNames` entry that is not a
//! string (every name became `target<i>`), a vertex beyond the ±1e30 every reader keeps.
//! Each case is a small GLB written by the project's writer, then edited as a person or a
//! broken exporter would.

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_rig::gltf_rig::read_gltf_mesh;
use nalgebra::DMatrix;
use std::path::Path;

/// A triangle with two morph targets as GLB bytes, vertex 0 at `v0`.
fn glb(v0: [f64; 3]) -> Vec<u8> {
    let neutral = vec![v0, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let targets = vec![
        ("a".to_string(), vec![[0.1, 0.0, 0.0]; 3]),
        ("b".to_string(), vec![[0.0, 0.2, 0.0]; 3]),
    ];
    let mut out = Vec::new();
    keyshape_io::gltf::write_morph_glb(
        &mut out,
        &neutral,
        &[vec![0, 1, 2]],
        &targets,
        &DMatrix::zeros(2, 2),
        30.0,
    )
    .unwrap();
    out
}

/// The GLB with its JSON chunk edited by `edit`.
fn edited(bytes: &[u8], edit: impl Fn(&mut serde_json::Value)) -> Vec<u8> {
    let u32_at = |i: usize| u32::from_le_bytes(bytes[i..i + 4].try_into().unwrap()) as usize;
    let json_len = u32_at(12);
    let mut json: serde_json::Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    let rest = &bytes[20 + json_len..];
    edit(&mut json);
    let mut text = serde_json::to_vec(&json).unwrap();
    while text.len() % 4 != 0 {
        text.push(b' ');
    }
    let total = 12 + 8 + text.len() + rest.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&text);
    out.extend_from_slice(rest);
    out
}

fn read(dir: &Path, name: &str, bytes: &[u8]) -> Result<usize, String> {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    read_gltf_mesh(&p)
        .map(|(m, _)| m.positions.len())
        .map_err(|e| e.to_string())
}

/// The accessor index of morph target `t`'s POSITION in the first primitive.
fn target_accessor(json: &serde_json::Value, t: usize) -> usize {
    json["meshes"][0]["primitives"][0]["targets"][t]["POSITION"]
        .as_u64()
        .unwrap() as usize
}

#[test]
fn the_unedited_triangle_reads() {
    let d = tempfile::tempdir().unwrap();
    assert_eq!(read(d.path(), "ok.glb", &glb([0.0; 3])), Ok(3));
}

#[test]
fn a_morph_target_shorter_than_its_mesh_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let bytes = edited(&glb([0.0; 3]), |j| {
        let a = target_accessor(j, 1);
        j["accessors"][a]["count"] = 1.into();
    });
    let e = read(d.path(), "short.glb", &bytes).unwrap_err();
    assert!(
        e.contains("short.glb: primitive 0: morph target 1's POSITION accessor")
            && e.contains("has 1 entries, the mesh 3 vertices"),
        "{e}"
    );
}

#[test]
fn a_sparse_accessor_replacing_more_entries_than_it_has_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let bytes = edited(&glb([0.0; 3]), |j| {
        let a = target_accessor(j, 0);
        j["accessors"][a]["sparse"] = serde_json::json!({
            "count": 1u64 << 40,
            "indices": {"bufferView": 0, "componentType": 5125},
            "values": {"bufferView": 0}
        });
    });
    let e = read(d.path(), "sparse.glb", &bytes).unwrap_err();
    assert!(
        e.contains("replaces 1099511627776 sparse entries of its 3"),
        "{e}"
    );
}

#[test]
fn a_target_name_that_is_not_a_string_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let bytes = edited(&glb([0.0; 3]), |j| {
        j["meshes"][0]["extras"]["targetNames"][1] = 5.into();
    });
    let e = read(d.path(), "names.glb", &bytes).unwrap_err();
    assert!(
        e.contains("mesh.extras.targetNames[1] is 5, not a name"),
        "{e}"
    );
}

#[test]
fn a_vertex_beyond_the_coordinate_limit_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let e = read(d.path(), "far.glb", &glb([3e38, 0.0, 0.0])).unwrap_err();
    assert!(
        e.contains("far.glb: vertex 0: coordinate 3") && e.contains("is beyond ±1e30"),
        "{e}"
    );
}
