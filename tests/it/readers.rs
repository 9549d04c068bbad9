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
