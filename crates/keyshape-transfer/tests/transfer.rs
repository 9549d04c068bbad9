//! Paper 004's transfer on the real data: OBJ meshes read and round-tripped, skin weights,
//! the RBF transfer of feature points, partial retargeting, glTF joint tracks, painted
//! weights, and the person-mismatch measure.

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_core::ErrorKind;
use keyshape_io::obj::{parse_obj, read_obj, write_obj};
use keyshape_transfer::features::Features;
use keyshape_transfer::skin::{radii, Skin};
use keyshape_transfer::Transfer;
use std::path::Path;

/// `../shared/data/<rel>` beside the repository.
fn shared(rel: &str) -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data")
        .join(rel)
}

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
fn obj_reader_reads_both_target_meshes_and_round_trips() {
    let m = ict();
    assert_eq!((m.positions.len(), m.faces.len()), (9409, 9230));
    let c = read_obj(&shared("mediapipe_canonical_face/canonical_face_model.obj")).unwrap();
    assert_eq!((c.positions.len(), c.faces.len()), (468, 898));
    assert!(c
        .faces
        .iter()
        .all(|f| f.len() == 3 && f.iter().all(|&v| v < 468)));
    let mut buf = Vec::new();
    write_obj(&mut buf, &c.positions, &c.faces, "test").unwrap();
    let back = parse_obj(Path::new("x.obj"), &String::from_utf8(buf).unwrap()).unwrap();
    assert_eq!(back.faces, c.faces);
    assert!(back
        .positions
        .iter()
        .zip(&c.positions)
        .all(|(a, b)| (0..3).all(|k| (a[k] - b[k]).abs() < 1e-5)));
}

#[test]
fn bad_obj_files_name_line_and_column() {
    let e = parse_obj(Path::new("m.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n")
        .unwrap_err()
        .kind_is(ErrorKind::Parse);
    assert_eq!(
        e,
        "m.obj:4:1: face refers to vertex 4 but the file has 3 vertices"
    );
    let e = parse_obj(Path::new("m.obj"), "v 0 0 0\nv 1 x 0\n")
        .unwrap_err()
        .kind_is(ErrorKind::Parse);
    assert_eq!(e, "m.obj:2:5: not a number: 'x'");
    let e = parse_obj(Path::new("m.obj"), "v 0 0 0\nf 1 0 1\n")
        .unwrap_err()
        .kind_is(ErrorKind::Parse);
    assert!(e.starts_with("m.obj:2:5: face index 0"), "{e}");
}

#[test]
fn skin_weights_are_nonnegative_sum_to_at_most_one_and_far_vertices_stay() {
    let m = ict();
    let f = Features::builtin("ibug68_to_ict").unwrap();
    let t0: Vec<[f64; 3]> = f.features.iter().map(|x| m.positions[x.target]).collect();
    let factors = vec![1.5; t0.len()];
    let skin = Skin::automatic(&m.positions, &t0, &radii(&t0, &factors));
    for inf in &skin.influences {
        if inf.is_empty() {
            continue;
        }
        assert!(inf.len() <= 4 && inf.iter().all(|x| x.1 >= 0.0));
        assert!(inf.iter().map(|x| x.1).sum::<f64>() <= 1.0 + 1e-12);
    }
    // On a feature point, its weight is 1 (the raw weights there sum above 1, so scaled
    // to sum 1, the feature's own the largest).
    for (i, x) in f.features.iter().enumerate() {
        let inf = &skin.influences[x.target];
        assert!((inf.iter().map(|w| w.1).sum::<f64>() - 1.0).abs() < 1e-12);
        assert_eq!(inf[0].0, i);
    }
    // A vertex far from every feature point (the back of the scalp region) does not move.
    let far = (0..m.positions.len())
        .max_by(|&a, &b| {
            let d = |v: usize| {
                t0.iter()
                    .map(|p| {
                        (0..3)
                            .map(|k| (m.positions[v][k] - p[k]).powi(2))
                            .sum::<f64>()
                    })
                    .fold(f64::INFINITY, f64::min)
            };
            d(a).total_cmp(&d(b))
        })
        .unwrap();
    assert!(skin.influences[far].is_empty());
    let mut out = vec![[0.0; 3]; m.positions.len()];
    skin.deform(&m.positions, &vec![[1.0, 2.0, 3.0]; t0.len()], &mut out);
    assert_eq!(out[far], m.positions[far]);
}

#[test]
fn the_neutral_frame_maps_to_the_neutral_mesh_and_other_frames_move_it() {
    let (t, seq) = news_transfer(None);
    let rest = t.frame(seq.coords.column(0).as_slice());
    let d = rest
        .iter()
        .zip(&t.mesh.positions)
        .map(|(a, b)| (0..3).map(|k| (a[k] - b[k]).abs()).fold(0.0, f64::max))
        .fold(0.0, f64::max);
    assert!(d < 1e-8, "neutral frame moves the mesh by {d}");
    // Another frame: each feature vertex influenced by its own feature alone lands on
    // F(s) = t0 + d, with F evaluated directly through the RBF on the frame's landmarks.
    let later = seq.coords.column(200);
    let disp = t.displacements(later.as_slice());
    let moved = t.frame(later.as_slice());
    let mut landed = 0;
    for (i, f) in t.features.features.iter().enumerate() {
        let v = f.target;
        assert_eq!(
            t.t0[i], t.mesh.positions[v],
            "t0 of {} is its vertex",
            f.name
        );
        let p = &later.as_slice()[2 * f.source..2 * f.source + 2];
        let mut fs = [0.0; 3];
        t.rbf
            .apply_point(&[p[0], p[1], 0.0][..t.rbf.dims], &mut fs[..t.rbf.dims]);
        for k in 0..3 {
            assert!(
                (t.t0[i][k] + disp[i][k] - fs[k]).abs() < 1e-9,
                "{}: d = F(s) − t0 fails on axis {k}",
                f.name
            );
        }
        if let [(j, w)] = t.skin.influences[v][..] {
            if j == i && (w - 1.0).abs() < 1e-12 {
                landed += 1;
                for k in 0..3 {
                    assert!(
                        (moved[v][k] - fs[k]).abs() < 1e-9,
                        "{} does not land on F(s)",
                        f.name
                    );
                }
            }
        }
    }
    // Skin influences overlap (ellipsoids, paper 004 §3), so most feature vertices blend
    // several features; the two influenced by their own feature alone must land exactly.
    assert!(
        landed >= 2,
        "only {landed} feature vertices have a single influence"
    );
    assert!(disp.iter().any(|x| x.iter().any(|v| v.abs() > 1e-3)));
}

#[test]
fn partial_retargeting_keeps_disabled_groups_at_neutral() {
    let groups = vec!["mouth".to_string(), "jaw".to_string()];
    let (t, seq) = news_transfer(Some(&groups));
    let disp = t.displacements(seq.coords.column(200).as_slice());
    for (f, d) in t.features.features.iter().zip(&disp) {
        if f.group != "mouth" && f.group != "jaw" {
            assert_eq!(*d, [0.0; 3], "{} moved", f.name);
        }
    }
    let moved = t.frame(seq.coords.column(200).as_slice());
    // Every vertex influenced by disabled features only stays exactly where it was. (The
    // eye feature vertices are not among them: the mouth and jaw skins reach them.)
    let still = (0..moved.len())
        .filter(|&v| {
            !t.skin.influences[v].is_empty()
                && t.skin.influences[v].iter().all(|(i, _)| !t.enabled[*i])
        })
        .inspect(|&v| assert_eq!(moved[v], t.mesh.positions[v], "vertex {v} moved"))
        .count();
    assert!(still > 100, "{still} vertices under disabled features only");
    let e = Transfer::new(
        ict(),
        Features::builtin("ibug68_to_ict").unwrap(),
        seq.coords.column(0).as_slice(),
        2,
        Some(&["lipz".to_string()]),
    )
    .unwrap_err()
    .kind_is(ErrorKind::Setting);
    assert!(e.contains("no feature group 'lipz'"), "{e}");
}

#[test]
fn bad_correspondences_are_explained() {
    let seq_shape = vec![0.0; 136];
    let mut f = Features::builtin("ibug68_to_ict").unwrap();
    f.features[3].target = 99_999;
    let e = Transfer::new(ict(), f, &seq_shape, 2, None)
        .unwrap_err()
        .kind_is(ErrorKind::Invalid);
    assert!(
        e.contains("names target vertex 99999, but the mesh has 9409"),
        "{e}"
    );
    let mut f = Features::builtin("ibug68_to_ict").unwrap();
    f.features[4].source = f.features[2].source;
    let e = Transfer::new(ict(), f, &seq_shape, 2, None)
        .unwrap_err()
        .kind_is(ErrorKind::Unfit);
    assert!(e.contains("share a point"), "{e}");
    let f = Features::builtin("mediapipe_to_canonical").unwrap();
    let e = Transfer::new(ict(), f, &seq_shape, 2, None)
        .unwrap_err()
        .kind_is(ErrorKind::Invalid);
    assert!(e.contains("names source landmark"), "{e}");
}

/// The GLB's animation holds, for every feature joint and frame, the target's neutral
/// feature point plus the transfer's displacement (`t0 + d`, in f32), read back through the
/// `gltf` crate; and a transfer with more features than glTF's 16-bit joints is refused.
#[test]
fn gltf_joint_tracks_are_the_neutral_plus_each_frames_displacement() {
    let (mut t, seq) = news_transfer(None);
    let frames = seq.coords.columns(0, 5).clone_owned();
    let mut buf = Vec::new();
    t.write_glb(&mut buf, &frames, 15.0).unwrap();
    let g = gltf::Gltf::from_slice(&buf).unwrap();
    let blob = g.blob.clone().unwrap();
    let anim = g.animations().next().unwrap();
    let mut checked = 0;
    for (j, ch) in anim.channels().enumerate() {
        assert_eq!(
            ch.target().node().index(),
            j + 2,
            "channel {j} drives joint {j}"
        );
        let r = ch.reader(|_| Some(&blob[..]));
        let Some(gltf::animation::util::ReadOutputs::Translations(out)) = r.read_outputs() else {
            panic!("channel {j} animates no translation")
        };
        for (f, got) in out.enumerate() {
            let d = t.displacements(frames.column(f).as_slice());
            for k in 0..3 {
                let want = (t.t0[j][k] + d[j][k]) as f32;
                assert_eq!(got[k], want, "joint {j} frame {f} axis {k}");
            }
            checked += 1;
        }
    }
    assert_eq!(checked, t.t0.len() * 5);
    assert!(t.check_gltf().is_ok());
    t.t0.resize(u16::MAX as usize, [0.0; 3]);
    assert!(t.check_gltf().is_err());
}

#[test]
fn painted_weights_override_the_automatic_ones() {
    let (mut t, _) = news_transfer(None);
    let names: Vec<String> = t.features.features.iter().map(|f| f.name.clone()).collect();
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("w.json");
    std::fs::write(&p, r#"{"weights": [{"vertex": 5, "feature": "chin", "weight": 3}, {"vertex": 5, "feature": "mouth_left", "weight": 1}]}"#).unwrap();
    t.skin.paint(&p, &names).unwrap();
    let chin = names.iter().position(|n| n == "chin").unwrap();
    assert_eq!(
        t.skin.influences[5],
        vec![
            (chin, 0.75),
            (names.iter().position(|n| n == "mouth_left").unwrap(), 0.25)
        ]
    );
    std::fs::write(
        &p,
        r#"{"weights": [{"vertex": 5, "feature": "nose_wing", "weight": 1}]}"#,
    )
    .unwrap();
    let e = t
        .skin
        .paint(&p, &names)
        .unwrap_err()
        .kind_is(ErrorKind::File);
    assert!(e.contains("no feature named 'nose_wing'"), "{e}");
    // Painted all 0, a vertex has no influence left: it stays where it is (no 0/0).
    std::fs::write(
        &p,
        r#"{"weights": [{"vertex": 9, "feature": "chin", "weight": 0}]}"#,
    )
    .unwrap();
    t.skin.paint(&p, &names).unwrap();
    assert!(
        t.skin.influences[9].is_empty(),
        "{:?}",
        t.skin.influences[9]
    );
    // A negative weight, and a vertex past the mesh, are refused and change nothing.
    let before = t.skin.influences.clone();
    for (text, needle) in [
        (
            r#"{"weights": [{"vertex": 7, "feature": "chin", "weight": -0.5}]}"#,
            "vertex 7: weight must be ≥ 0, got -0.5",
        ),
        (
            r#"{"weights": [{"vertex": 99999, "feature": "chin", "weight": 1}]}"#,
            "vertex 99999 is not in the mesh",
        ),
    ] {
        std::fs::write(&p, text).unwrap();
        let e = t
            .skin
            .paint(&p, &names)
            .unwrap_err()
            .kind_is(ErrorKind::File);
        assert!(e.contains(needle), "{e}");
        assert_eq!(t.skin.influences, before);
    }
}

/// One transform trained on one person, driving others (the news sample's 20 clips): the
/// mismatch is 0 for the person it was trained on, and for another clip it equals the
/// difference between the shared transfer's and a transfer trained on that clip's own neutral
/// feature displacements, computed here through `Transfer` itself.
#[test]
fn person_mismatch_is_the_gap_to_a_transform_trained_on_each_person() {
    use keyshape_transfer::{features::Features, person_mismatch, Transfer};
    let raw = keyshape_io::read_sequence(
        &shared("pyfeat_samples/news_sample_compact.csv"),
        &Default::default(),
    )
    .unwrap();
    // Aligned, as `kslab transfer` prepares it.
    let seq = keyshape_core::decompose::prepare(
        &raw,
        &keyshape_core::decompose::PrepareOptions::all_aligned(),
    )
    .unwrap()
    .seq;
    let mesh = keyshape_io::obj::read_obj(&shared("ict_facekit_face/neutral_face.obj")).unwrap();
    let features = Features::choose("builtin", Some("ibug68"), 68, mesh.positions.len()).unwrap();
    let seg = seq.segments.clone().unwrap();
    let tr = Transfer::new(
        mesh.clone(),
        features.clone(),
        seq.coords.column(0).as_slice(),
        2,
        None,
    )
    .unwrap();
    let rows = person_mismatch(&tr, &seq.coords, &seq.frames, &seg).unwrap();
    assert_eq!(rows.len(), 20);
    assert!(
        rows[0].mismatch < 1e-9 && rows[0].neutral_error < 1e-9,
        "{:?}",
        rows[0]
    );
    let r = rows.iter().find(|r| r.segment == "8").unwrap();
    let n = seq.column_of_frame(r.neutral_frame).unwrap();
    let own = Transfer::new(mesh, features, seq.coords.column(n).as_slice(), 2, None).unwrap();
    let (mut mis, mut expr, mut count) = (0.0, 0.0, 0);
    for t in (0..seq.n_frames()).filter(|&t| seg[t] == "8") {
        let (a, b) = (
            tr.displacements(seq.coords.column(t).as_slice()),
            own.displacements(seq.coords.column(t).as_slice()),
        );
        for (x, y) in a.iter().zip(&b) {
            mis += (0..3).map(|d| (x[d] - y[d]).powi(2)).sum::<f64>();
            expr += (0..3).map(|d| y[d].powi(2)).sum::<f64>();
            count += 1;
        }
    }
    assert_eq!(count, r.frames * 25);
    assert!(
        (r.mismatch - (mis / count as f64).sqrt()).abs() < 1e-9,
        "{r:?}"
    );
    assert!(
        (r.expression - (expr / count as f64).sqrt()).abs() < 1e-9,
        "{r:?}"
    );
    // Measured on this sample (kslab transfer --json): clip 8's neutral lands 0.64 cm off.
    assert!((r.neutral_error - 0.6415456950357211).abs() < 1e-6, "{r:?}");
    // Counts that disagree with the frames are refused, each on its own.
    let short_frames = &seq.frames[1..];
    let short_segments = &seg[1..];
    for (frames, segments) in [(short_frames, &seg[..]), (&seq.frames[..], short_segments)] {
        let e = person_mismatch(&tr, &seq.coords, frames, segments).unwrap_err();
        assert!(e.to_string().contains("differ in count"), "{e}");
    }
}

/// `all_frames` is `frames` over every column, and each is `frame` of that column.
#[test]
fn all_frames_deforms_every_frame_as_frame_does() {
    let (t, seq) = news_transfer(None);
    let cols = [0usize, 57, 200, 476];
    let sub = seq.coords.select_columns(&cols);
    let all = t.all_frames(&sub);
    assert_eq!(all.len(), cols.len());
    assert_eq!(all, t.frames(&sub, 0..cols.len()));
    for (k, &c) in cols.iter().enumerate() {
        assert_eq!(all[k], t.frame(seq.coords.column(c).as_slice()));
        assert_eq!(all[k].len(), t.mesh.positions.len());
    }
    assert_ne!(all[0], all[2], "frame 200 should move the mesh");
}

/// Round three's neck tear (G.17), reproduced on a shipped track: at LivePortrait d6's
/// widest mouth (frame 863) the ICT face tore into a jagged edge at the jaw line and the
/// neck and grew a spike on the skull, because a vertex at the very edge of one ellipsoid
/// had its lone weight normalised to 1 and moved with the feature in full while its
/// neighbour outside stayed. Across an edge of the mesh, how far one end moves and the
/// other does not was 1.00 of the largest displacement before the fix (a vertex moving in
/// full beside one that stays); it is 0.24 now.
#[test]
fn no_edge_of_the_mesh_tears_at_an_ellipsoids_border() {
    let seq = keyshape_io::read_sequence(
        &shared("mediapipe_face_tracks/liveportrait_d6.csv"),
        &Default::default(),
    )
    .unwrap();
    let prep = keyshape_core::decompose::prepare(
        &seq,
        &keyshape_core::decompose::PrepareOptions::all_aligned(),
    )
    .unwrap();
    let m = ict();
    let f = Features::builtin("mediapipe_to_ict").unwrap();
    let t = Transfer::new(m.clone(), f, prep.seq.coords.column(0).as_slice(), 2, None).unwrap();
    let c = prep.seq.frames.iter().position(|&x| x == 863).unwrap();
    let moved = t.frame(prep.seq.coords.column(c).as_slice());
    let disp: Vec<[f64; 3]> = moved
        .iter()
        .zip(&m.positions)
        .map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]])
        .collect();
    let norm = |d: [f64; 3]| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let largest = disp.iter().map(|d| norm(*d)).fold(0.0, f64::max);
    assert!(largest > 1.0, "frame 863 moves the face: {largest}");
    let mut worst = 0.0f64;
    for face in &m.faces {
        for k in 0..face.len() {
            let (a, b) = (face[k], face[(k + 1) % face.len()]);
            // How far one end moves and the other does not (a lip opening moves both ends
            // apart; a tear moves one end only).
            let jump = (norm(disp[a]) - norm(disp[b])).abs();
            worst = worst.max(jump / largest);
        }
    }
    assert!(
        worst < 0.3,
        "an edge's displacement jumps by {worst:.2} of the largest"
    );
}

/// A library error's kind checked before its words are read: a test acts on the kind, as a
/// caller would, and reads the message only for what it must name.
trait KindIs {
    fn kind_is(self, kind: keyshape_core::ErrorKind) -> String;
}

impl KindIs for keyshape_core::Error {
    #[track_caller]
    fn kind_is(self, kind: keyshape_core::ErrorKind) -> String {
        assert_eq!(self.kind(), kind, "{self}");
        self.to_string()
    }
}
