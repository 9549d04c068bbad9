//! Every reader on the real files in ../shared/data, plus round trips through JSON and .pts.
//! (What runs the `kslab` binary is in `tests/it/readers.rs`.)

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_core::sequence::{Format, Layout};
use keyshape_io::{builtin_sequence, json, read_sequence, ReadOptions};

/// `../shared/data/<rel>` beside the repository.
fn shared(rel: &str) -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data")
        .join(rel)
}
fn read(rel: &str, dims: usize) -> keyshape_core::sequence::Sequence {
    let opts = ReadOptions { format: None, dims };
    read_sequence(&shared(rel), &opts).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

#[test]
fn mediapipe_tracks_read_with_their_frame_counts() {
    for (name, frames) in [
        ("liveportrait_d6.csv", 1008),
        ("liveportrait_d9.csv", 587),
        ("liveportrait_d18.csv", 216),
        ("pyfeat_wolfganglanger_pexels.csv", 472),
    ] {
        let s = read(&format!("mediapipe_face_tracks/{name}"), 2);
        assert_eq!(
            (s.format, s.n_frames(), s.points, s.dims),
            (Format::Mediapipe, frames, 468, 2),
            "{name}"
        );
        assert!(s.failed.is_empty());
        assert_eq!(s.frames[..3], [0, 1, 2]);
        assert!(
            (s.fps().unwrap()
                - if name.starts_with("pyfeat") {
                    23.976
                } else {
                    30.0
                })
            .abs()
                < 0.01
        );
    }
    let s3 = read("mediapipe_face_tracks/liveportrait_d18.csv", 3);
    assert_eq!((s3.dims, s3.coords.nrows()), (3, 3 * 468));
    // Point 1 (nose tip) of frame 0, as in the file: x_1, y_1, z_1.
    let s2 = read("mediapipe_face_tracks/liveportrait_d18.csv", 2);
    assert_eq!(s3.coords[(3, 0)], s2.coords[(2, 0)]);
    assert_eq!(s3.coords[(4, 0)], s2.coords[(3, 0)]);
}

#[test]
fn openface_reads_2d_pixels_and_3d_millimetres() {
    let s = read("pyfeat_samples/openface_test.csv", 2);
    assert_eq!(
        (s.format, s.n_frames(), s.points),
        (Format::Openface, 100, 68)
    );
    assert_eq!((s.frames[0], s.frames[99]), (1, 100));
    let s3 = read("pyfeat_samples/openface_test.csv", 3);
    assert_eq!((s3.dims, s3.points), (3, 68));
    // Z is depth from the camera in mm: hundreds of mm, unlike the pixel coordinates.
    let (zlo, _) = s3.ranges()[2];
    assert!(zlo > 300.0, "{zlo}");
}

#[test]
fn builtin_sequence_is_the_derived_d18_track() {
    let b = builtin_sequence().unwrap();
    assert_eq!((b.n_frames(), b.points, b.dims), (216, 468, 2));
    let full = read("mediapipe_face_tracks/liveportrait_d18.csv", 2);
    let d = (&b.coords - &full.coords).amax();
    assert!(
        d <= 0.05 + 1e-9,
        "built-in differs from the source by {d} px"
    );
    assert!((b.fps().unwrap() - 30.0).abs() < 0.01);
}

#[test]
fn json_round_trip_keeps_everything_including_failed_frames() {
    let mut s = read("pyfeat_samples/openface_test.csv", 2);
    s.failed = vec![1000];
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("seq.json");
    std::fs::write(&p, serde_json::to_string(&json::to_file(&s)).unwrap()).unwrap();
    let back = read_sequence(&p, &ReadOptions::default()).unwrap();
    assert_eq!(back.format, Format::Json);
    assert_eq!(back.coords, s.coords);
    assert_eq!(back.frames, s.frames);
    assert_eq!(back.failed, vec![1000]);
    assert_eq!(back.times, s.times);
}

#[test]
fn pts_directory_reads_in_natural_order() {
    let s = read("pyfeat_samples/openface_test.csv", 2);
    let dir = tempfile::tempdir().unwrap();
    for f in 0..12 {
        let mut text = String::from("version: 1\nn_points: 68\n{\n");
        for p in s.coords.column(f).as_slice().chunks(2) {
            text.push_str(&format!("{} {}\n", p[0], p[1]));
        }
        text.push_str("}\n");
        std::fs::write(dir.path().join(format!("frame{f}.pts")), text).unwrap();
    }
    let back = read_sequence(dir.path(), &ReadOptions::default()).unwrap();
    assert_eq!(
        (back.format, back.n_frames(), back.points),
        (Format::Pts, 12, 68)
    );
    assert_eq!(back.coords, s.coords.columns(0, 12));
}

#[test]
fn layouts_select_groups_on_real_tracks() {
    let s = read("mediapipe_face_tracks/liveportrait_d18.csv", 2);
    let lips = Layout::for_points(s.points)
        .unwrap()
        .select("lips")
        .unwrap();
    assert_eq!(lips.len(), 40);
    let sub = s.select_points(&lips).unwrap();
    assert_eq!(sub.coords.nrows(), 80);
    assert_eq!(sub.coords[(0, 5)], s.coords[(2 * lips[0], 5)]);
    let ib = Layout::ibug68().select("lips").unwrap();
    assert_eq!(ib, (48..68).collect::<Vec<_>>());
}

/// Duplicate frames are found, with the line they first appeared on, wherever they fall:
/// inside a run of consecutive frames, at a run's ends, after a gap or a blank line, out of
/// order (the reader keeps runs of frames, not one entry per frame).
#[test]
fn duplicate_frames_name_their_first_line_inside_and_across_runs() {
    let d = tempfile::tempdir().unwrap();
    // Lines: 1 header, 2–5 frames 10–13, 6 blank, 7 frame 14, 8 frame 20, 9 frame 5.
    let body = "frame,x0,y0,x1,y1\n10,0,0,1,1\n11,0,0,1,2\n12,0,0,1,3\n13,0,0,1,4\n\n14,0,0,1,5\n20,0,0,1,6\n5,0,0,1,7\n";
    for (dup, first) in [(10, 2), (12, 4), (13, 5), (14, 7), (20, 8), (5, 9)] {
        let p = d.path().join(format!("dup{dup}.csv"));
        std::fs::write(&p, format!("{body}{dup},0,0,1,9\n")).unwrap();
        let e = read_sequence(
            &p,
            &ReadOptions {
                format: None,
                dims: 2,
            },
        )
        .unwrap_err();
        let want = format!("dup{dup}.csv:10:1: frame {dup} appears twice (first on line {first})");
        assert!(e.to_string().contains(&want), "{e} (want {want})");
    }
    // Frames that only neighbour earlier ones are fine.
    let p = d.path().join("ok.csv");
    std::fs::write(&p, format!("{body}15,0,0,1,9\n9,0,0,1,9\n21,0,0,1,9\n")).unwrap();
    let s = read_sequence(
        &p,
        &ReadOptions {
            format: None,
            dims: 2,
        },
    )
    .unwrap();
    assert_eq!(s.frames, [10, 11, 12, 13, 14, 20, 5, 15, 9, 21]);
}

/// `read_sequence` parses a landmark table straight from the file (a check pass, then the
/// rows, without holding the text); it must give exactly what parsing the whole text gives,
/// and the same error where that fails.
#[test]
fn tables_read_from_the_file_equal_the_whole_text_parse() {
    use keyshape_io::{parse_sequence, read_text};
    use std::io::Write;
    let same = |path: &std::path::Path, opts: &ReadOptions| {
        let streamed = read_sequence(path, opts);
        let whole = read_text(path).and_then(|t| parse_sequence(path, &t, opts));
        match (streamed, whole) {
            (Ok(a), Ok(b)) => {
                assert_eq!(a.coords, b.coords, "{}", path.display());
                assert_eq!(a.frames, b.frames);
                assert_eq!(a.failed, b.failed);
                assert_eq!(a.times, b.times);
                assert_eq!(a.segments, b.segments);
                assert_eq!((a.format, a.dims, a.points), (b.format, b.dims, b.points));
                assert_eq!(a.source, b.source);
                a.n_frames()
            }
            (Err(a), Err(b)) => {
                assert_eq!(a.to_string(), b.to_string());
                0
            }
            (a, b) => panic!(
                "{}: streamed {:?}, whole {:?}",
                path.display(),
                a.err(),
                b.err()
            ),
        }
    };
    let d2 = ReadOptions::default();
    let d3 = ReadOptions {
        format: None,
        dims: 3,
    };
    for rel in [
        "mediapipe_face_tracks/liveportrait_d6.csv",
        "mediapipe_face_tracks/liveportrait_d9.csv",
        "mediapipe_face_tracks/liveportrait_d18.csv",
        "mediapipe_face_tracks/pyfeat_wolfganglanger_pexels.csv",
        "pyfeat_samples/news_sample_compact.csv",
        "pyfeat_samples/openface_test.csv",
    ] {
        assert!(same(&shared(rel), &d2) > 0, "{rel}");
    }
    assert!(same(&shared("mediapipe_face_tracks/liveportrait_d6.csv"), &d3) > 0);
    assert!(same(&shared("pyfeat_samples/openface_test.csv"), &d3) > 0);
    let forced = ReadOptions {
        format: Some(Format::Pyfeat),
        dims: 2,
    };
    assert!(same(&shared("pyfeat_samples/openface_test.csv"), &forced) > 0);

    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(shared("pyfeat_samples/openface_test.csv")).unwrap();
    let write = |name: &str, bytes: &[u8]| {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    };
    // gzip, CRLF line ends with blank lines, no final line end.
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    gz.write_all(text.as_bytes()).unwrap();
    assert!(same(&write("t.csv.gz", &gz.finish().unwrap()), &d2) > 0);
    let crlf = text.replace('\n', "\r\n\r\n");
    assert!(same(&write("crlf.csv", crlf.as_bytes()), &d2) > 0);
    assert!(same(&write("noend.csv", text.trim_end().as_bytes()), &d2) > 0);
    // Failures: the same message either way.
    let lines: Vec<&str> = text.lines().collect();
    let mut bad = lines[..6].join("\n").into_bytes();
    bad.extend_from_slice(b"\n\xff\xfe");
    bad.extend_from_slice(lines[6].as_bytes());
    for (name, bytes) in [
        ("utf8.csv", bad),
        ("blank_first.csv", format!("\n{text}").into_bytes()),
        ("spaces.csv", b" \n \n\t\n".to_vec()),
        ("ragged.csv", format!("{}\n1,2,3\n", lines[0]).into_bytes()),
        ("noheader.csv", b"a,b,c\n1,2,3\n".to_vec()),
        ("json.csv", b"{\"frames\": []}\n".to_vec()),
        ("badgz.csv.gz", b"not gzip at all".to_vec()),
    ] {
        assert_eq!(same(&write(name, &bytes), &d2), 0, "{name} should fail");
    }
}

/// The coordinate bound is where results stay right: a real track
/// scaled by 10^e, for e up to the bound's 30, gives the same condition number and the same
/// errors relative to its scale — and a coordinate past the bound is refused by name.
#[test]
fn results_are_scale_free_up_to_the_coordinate_bound() {
    use keyshape_core::decompose::{decompose, prepare, PrepareOptions};
    use keyshape_core::solve::{SolveOptions, Solver};
    let base = read("pyfeat_samples/openface_test.csv", 2);
    let opts = PrepareOptions::all_aligned();
    let solve = |seq: &keyshape_core::sequence::Sequence| {
        let prep = prepare(seq, &opts).unwrap();
        let d = decompose(
            &prep,
            &[1, 30, 60, 90],
            None,
            &SolveOptions::new(Solver::Nnls),
        )
        .unwrap();
        (d.condition, d.mean_rms())
    };
    let (c0, r0) = solve(&base);
    for e in [10, 20, 30] {
        let s = 10f64.powi(e);
        assert!(s <= keyshape_core::sequence::MAX_COORD);
        let scaled = base.with_coords(&base.coords * s);
        let (c, r) = solve(&scaled);
        assert!(
            (c - c0).abs() < 1e-9 * c0,
            "1e{e}: condition {c} against {c0}"
        );
        assert!(
            (r / s - r0).abs() < 1e-9 * r0,
            "1e{e}: rms {} against {r0}",
            r / s
        );
    }
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("big.csv");
    std::fs::write(&p, "frame,x0,y0,x1,y1\n0,1e31,2,3,4\n1,1,2,3,5\n").unwrap();
    let e = keyshape_io::read_sequence(&p, &Default::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("big.csv:2:2: coordinate 1e31 is beyond ±1e30"),
        "{e}"
    );
}

/// A column read twice (a second `x0`, `x_0`, `frame` or `detected`) is refused at its
/// field, not read from whichever copy came last.
#[test]
fn a_coordinate_or_frame_column_given_twice_is_refused() {
    let d = tempfile::tempdir().unwrap();
    for (name, text, want) in [
        (
            "a.csv",
            "frame,x0,y0,x1,y1,x0\n0,1,2,3,4,5\n",
            "a.csv:1:6: column 'x0' appears twice (fields 2 and 6)",
        ),
        (
            "b.csv",
            "frame,detected,x_0,x_1,y_0,y_1,x_1\n0,1,1,2,3,4,5\n",
            "b.csv:1:7: column 'x_1' appears twice (fields 4 and 7)",
        ),
        (
            "c.csv",
            "frame,x0,y0,frame\n0,1,2,3\n",
            "c.csv:1:4: column 'frame' appears twice",
        ),
    ] {
        let p = d.path().join(name);
        std::fs::write(&p, text).unwrap();
        let e = keyshape_io::read_sequence(&p, &Default::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains(want), "{e}");
    }
    // A repeated column the reader does not use is left alone.
    let p = d.path().join("ok.csv");
    std::fs::write(&p, "frame,note,x0,y0,x1,y1,note\n0,a,1,2,3,4,b\n").unwrap();
    assert_eq!(
        keyshape_io::read_sequence(&p, &Default::default())
            .unwrap()
            .points,
        2
    );
}

/// A UTF-8 byte-order mark is read past by every reader, as the CSV reader always did
/// (JSON and `.pts` refused it).
#[test]
fn a_byte_order_mark_is_read_past_by_every_reader() {
    let d = tempfile::tempdir().unwrap();
    for (name, text) in [
        ("a.csv", "frame,x0,y0,x1,y1\n0,1,2,3,4\n"),
        (
            "a.json",
            r#"{"kslab_sequence":1,"dims":2,"points":2,"frames":[{"frame":0,"coords":[1,2,3,4]}]}"#,
        ),
        ("a.pts", "version: 1\nn_points: 2\n{\n1 2\n3 4\n}\n"),
    ] {
        let p = d.path().join(name);
        std::fs::write(&p, format!("\u{feff}{text}")).unwrap();
        let seq = read_sequence(&p, &ReadOptions::default()).unwrap();
        assert_eq!((seq.points, seq.coords[(3, 0)]), (2, 4.0), "{name}");
    }
}

/// A plain CSV's per-point confidences (`c0, c1, …`, as a `kslab live` take from
/// OpenSeeFace keeps them) are read per frame and follow a point selection; a partial set
/// or a confidence that is no confidence is refused at its line and column.
#[test]
fn confidence_columns_are_read_whole_or_refused_where_they_break() {
    let d = tempfile::tempdir().unwrap();
    let opts = ReadOptions {
        format: None,
        dims: 2,
    };
    let p = d.path().join("take.csv");
    std::fs::write(
        &p,
        "frame,time_s,x0,y0,x1,y1,x2,y2,c0,c1,c2\n0,0,0,0,10,0,0,10,0.9,0.5,0\n1,0.04,0,0,10,0,0,11,1,0.25,0.75\n",
    )
    .unwrap();
    let s = read_sequence(&p, &opts).unwrap();
    let c = s.confidence.as_ref().unwrap();
    assert_eq!((c.nrows(), c.ncols()), (3, 2));
    assert_eq!(c.column(1).as_slice(), [1.0, 0.25, 0.75]);
    let picked = s.select_points(&[2, 0]).unwrap();
    assert_eq!(picked.confidence.unwrap().column(0).as_slice(), [0.0, 0.9]);
    for (name, text, want) in [
        (
            "gap.csv",
            "frame,x0,y0,x1,y1,c0,c2\n0,0,0,10,10,1,1\n",
            "gap.csv:1:7: header has 'c2' but no 'c1'",
        ),
        (
            "short.csv",
            "frame,x0,y0,x1,y1,x2,y2,c0,c1\n0,0,0,10,0,0,10,1,1\n",
            "short.csv:1:9: header has confidences c0..c1 for 3 points",
        ),
        (
            "negative.csv",
            "frame,x0,y0,x1,y1,c0,c1\n0,0,0,10,10,1,1\n1,0,0,10,10,1,-0.5\n",
            "negative.csv:3:7: 'c1' is -0.5: a confidence is finite and ≥ 0",
        ),
        (
            "nan.csv",
            "frame,x0,y0,x1,y1,c0,c1\n0,0,0,10,10,NaN,1\n",
            "nan.csv:2:6",
        ),
    ] {
        let p = d.path().join(name);
        std::fs::write(&p, text).unwrap();
        let e = read_sequence(&p, &opts).unwrap_err().to_string();
        assert!(e.contains(want), "{e} (want {want})");
    }
    // A file without them has none.
    assert!(read("mediapipe_face_tracks/liveportrait_d18.csv", 2)
        .confidence
        .is_none());
}
