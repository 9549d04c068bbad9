//! Every reader on the real files in ../shared/data, plus round trips through JSON and .pts.
//! Here: what runs the `kslab` binary; the library's own tests are in `crates/keyshape-io/tests/readers.rs`.

use crate::common::shared;
use keyshape_core::sequence::Format;
use keyshape_io::{read_sequence, ReadOptions};

fn read(rel: &str, dims: usize) -> keyshape_core::sequence::Sequence {
    let opts = ReadOptions { format: None, dims };
    read_sequence(&shared(rel), &opts).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

#[test]
fn pyfeat_table_keeps_clips_as_segments() {
    let s = read("pyfeat_samples/news_sample_compact.csv", 2);
    assert_eq!(
        (s.format, s.n_frames(), s.points),
        (Format::Pyfeat, 477, 68)
    );
    let mut clips = s.segments.clone().unwrap();
    clips.dedup();
    assert_eq!(clips.len(), 20);
    assert_eq!(s.frames[..2], [0, 1], "py-feat frames are numbered by row");
    let opts = ReadOptions {
        format: None,
        dims: 3,
    };
    let e = read_sequence(&shared("pyfeat_samples/news_sample_compact.csv"), &opts).unwrap_err();
    assert!(crate::common::as_cli(&e).contains("--dims 3"), "{e}");
    // The library names the setting, not a flag: an experiment file says `dims` too.
    assert!(
        e.to_string().contains("dims 3") && !e.to_string().contains("--"),
        "{e}"
    );
}

/// A gzip file cut off mid-stream is the file's error, said as a gzip error with no
/// made-up line or column.
#[test]
fn a_gzip_cut_off_mid_stream_is_a_file_error() {
    use std::io::Write;
    let d = tempfile::tempdir().unwrap();
    let mut text = String::from("frame,x0,y0,x1,y1\n");
    for i in 0..20000 {
        text += &format!("{i},{i},2,3,4\n");
    }
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    gz.write_all(text.as_bytes()).unwrap();
    let bytes = gz.finish().unwrap();
    let p = d.path().join("cut.csv.gz");
    std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
    let r = crate::common::kslab(&["info", &p.display().to_string()]);
    assert_eq!(r.code, 1);
    assert!(
        r.stderr.contains("cut.csv.gz: not a valid gzip file"),
        "{}",
        r.stderr
    );
    assert!(!r.stderr.contains("CSV error"), "{}", r.stderr);
}

/// The face check that every neutral and calibration frame passes
/// (`keyshape_core::sequence::face_problem`) holds on every frame of every shipped track, in
/// every layout the rig reads: no real face is refused by it.
#[test]
fn every_frame_of_every_shipped_track_is_a_face() {
    use keyshape_core::sequence::{face_problem, MAX_FACE_SPREAD_RATIO};
    let to68 = keyshape_rig::mediapipe_to_ibug68().unwrap();
    for rel in [
        "mediapipe_face_tracks/liveportrait_d6.csv",
        "mediapipe_face_tracks/liveportrait_d9.csv",
        "mediapipe_face_tracks/liveportrait_d18.csv",
        "mediapipe_face_tracks/pyfeat_wolfganglanger_pexels.csv",
        "pyfeat_samples/news_sample_compact.csv",
        "pyfeat_samples/openface_test.csv",
    ] {
        let seq = keyshape_io::read_sequence(
            &crate::common::shared(rel),
            &keyshape_io::ReadOptions {
                format: None,
                dims: 2,
            },
        )
        .unwrap();
        let mut views = vec![seq.clone()];
        if seq.points >= 468 {
            views.push(seq.select_points(&to68).unwrap());
        }
        for v in &views {
            for (c, col) in v.coords.column_iter().enumerate() {
                assert_eq!(
                    face_problem(col.as_slice(), 2),
                    None,
                    "{rel} ({} points), frame {}",
                    v.points,
                    v.frames[c]
                );
            }
        }
    }
    // What it refuses: a landmark far off, points on a line, points together.
    let mut face: Vec<f64> = (0..68)
        .flat_map(|i| {
            let a = i as f64 * 0.37;
            [100.0 + 40.0 * a.cos(), 100.0 + 50.0 * a.sin()]
        })
        .collect();
    assert_eq!(face_problem(&face, 2), None);
    face[70] = 1e15;
    assert!(face_problem(&face, 2).unwrap().contains("landmark 35"));
    face[70] = 100.0 + 50.0 * 1.5 * MAX_FACE_SPREAD_RATIO;
    assert!(face_problem(&face, 2).is_some());
    let line: Vec<f64> = (0..68)
        .flat_map(|i| [i as f64, 2.0 * i as f64 + 1.0])
        .collect();
    assert!(face_problem(&line, 2).unwrap().contains("on a line"));
    assert!(face_problem(&[5.0; 136], 2).unwrap().contains("coincide"));
}
