//! Paper 004 through the command line and its files: `kslab transfer`, its picture against
//! the reviewed snapshot, the glTF export through the Khronos validator, the lab's mesh view,
//! and the message for a misfit correspondence. The library's own tests are in
//! `crates/keyshape-transfer/tests/transfer.rs`.

use crate::common::shared;
use keyshape_io::obj::read_obj;
use keyshape_transfer::features::Features;
use keyshape_transfer::Transfer;

fn ict() -> keyshape_io::obj::Mesh {
    read_obj(&shared("ict_facekit_face/neutral_face.obj")).unwrap()
}

fn news_transfer(groups: Option<&[String]>) -> (Transfer, keyshape_core::sequence::Sequence) {
    let seq = keyshape_io::read_sequence(
        &shared("pyfeat_samples/news_sample_compact.csv"),
        &Default::default(),
    )
    .unwrap();
    let prep = keyshape_core::decompose::prepare(
        &seq,
        &keyshape_core::decompose::PrepareOptions::all_aligned(),
    )
    .unwrap();
    let t = Transfer::new(
        ict(),
        Features::builtin("ibug68_to_ict").unwrap(),
        prep.seq.coords.column(0).as_slice(),
        2,
        groups,
    )
    .unwrap();
    (t, prep.seq)
}

#[test]
fn gltf_export_passes_the_khronos_validator() {
    let (t, seq) = news_transfer(None);
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("news.glb");
    let mut buf = Vec::new();
    t.write_glb(&mut buf, &seq.coords.columns(0, 40).clone_owned(), 15.0)
        .unwrap();
    std::fs::write(&p, &buf).unwrap();
    // Structure: GLB header, JSON chunk with one joint per feature plus the root.
    assert_eq!(&buf[..4], b"glTF");
    let jlen = u32::from_le_bytes(buf[12..16].try_into().unwrap()) as usize;
    let doc: serde_json::Value = serde_json::from_slice(&buf[20..20 + jlen]).unwrap();
    assert_eq!(doc["skins"][0]["joints"].as_array().unwrap().len(), 26);
    assert_eq!(
        doc["animations"][0]["channels"].as_array().unwrap().len(),
        25
    );
    // The Khronos validator (npm gltf-validator, installed by .ci/run into tools/gltf).
    crate::common::assert_valid_gltf(&p);
}

#[test]
fn the_lab_gets_a_mesh_view_per_frame() {
    let seq = keyshape_io::builtin_sequence().unwrap();
    let mesh = read_obj(&shared("mediapipe_canonical_face/canonical_face_model.obj")).unwrap();
    let mv = kslab_tui::mesh_view(
        &seq,
        mesh,
        Features::builtin("mediapipe_to_canonical").unwrap(),
    )
    .unwrap();
    assert_eq!(mv.frames.len(), 216);
    assert!(mv.frames.iter().all(|f| f.len() == 468));
    // Each triangle edge once: 898 triangles share edges, so fewer than 3 × 898.
    assert!(mv.edges.len() > 898 && mv.edges.len() < 3 * 898);
    let mut s = kslab_tui::State::new("builtin", 216, 30.0);
    kslab_tui::update(&mut s, kslab_tui::Action::Mesh);
    assert!(s.status.contains("--mesh"));
    s.mesh = Some(std::sync::Arc::new(mv));
    kslab_tui::update(&mut s, kslab_tui::Action::Mesh);
    assert!(s.show_mesh);
}

#[test]
fn transfer_cli_writes_obj_frames_and_rejects_bad_meshes() {
    let d = tempfile::tempdir().unwrap();
    let bin = env!("CARGO_BIN_EXE_kslab");
    let objs = d.path().join("objs");
    let out = std::process::Command::new(bin)
        .args([
            "transfer",
            "--mesh",
            &shared("mediapipe_canonical_face/canonical_face_model.obj")
                .display()
                .to_string(),
            "--groups",
            "mouth,jaw",
            "--every",
            "100",
            "--obj-dir",
            &objs.display().to_string(),
            "--json",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["enabled_features"], 12);
    assert_eq!(std::fs::read_dir(&objs).unwrap().count(), 3);
    let m = read_obj(&objs.join("frame_000100.obj")).unwrap();
    assert_eq!(m.positions.len(), 468);
    let bad = d.path().join("bad.obj");
    std::fs::write(&bad, "v 0 0 0\nv 1 0 0\nf 1 2 9\n").unwrap();
    let out = std::process::Command::new(bin)
        .args(["transfer", "--mesh", &bad.display().to_string()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        err.contains("bad.obj:3:1: face refers to vertex 9 but the file has 2 vertices"),
        "{err}"
    );
}

#[test]
fn transfer_frame_picture_matches_its_reviewed_snapshot() {
    let d = tempfile::tempdir().unwrap();
    let pngs = d.path().join("pngs");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_kslab"))
        .args([
            "transfer",
            "--mesh",
            &shared("mediapipe_canonical_face/canonical_face_model.obj")
                .display()
                .to_string(),
            "--every",
            "150",
            "--png-dir",
            &pngs.display().to_string(),
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    crate::experiments::assert_png_matches(
        &pngs.join("frame_000150.png"),
        &crate::experiments::repo("snapshots/transfer_canonical_frame150.png"),
    );
}

/// A correspondence that does not fit the track and mesh names the built-in one that does,
/// and only one that fits on all three counts: landmarks, layout and mesh. Run 26: the
/// hint's filter was never checked — any of its conditions inverted, or an `&&` read as
/// `||`, passed.
#[test]
fn a_misfit_correspondence_names_the_built_in_that_fits_all_three() {
    use keyshape_transfer::features::Features;
    let all: Vec<(&str, Features)> = Features::BUILTIN
        .iter()
        .map(|b| (*b, Features::builtin(b).unwrap()))
        .collect();
    for (name, f) in &all {
        let (layout, points) = (f.source_layout.as_str(), f.source_points);
        let verts = f
            .target_vertices
            .expect("the built-ins name their mesh size");
        for (other, g) in all.iter().filter(|(o, _)| o != name) {
            let hint = |layout: &str, points: usize, verts: usize| {
                let e = g
                    .check_fits(other, Some(layout), points, verts)
                    .unwrap_err();
                crate::common::as_cli(&e)
                    .rsplit(": ")
                    .next()
                    .unwrap()
                    .to_string()
            };
            assert_eq!(
                hint(layout, points, verts),
                format!("use --features {name}")
            );
            for (l, p, v) in [
                (layout, points, verts + 1),
                (layout, points + 1, verts),
                ("another_layout", points, verts),
            ] {
                let h = hint(l, p, v);
                assert!(h.starts_with("write a features file"), "{l} {p} {v}: {h}");
            }
        }
    }
}
