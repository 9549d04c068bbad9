//! The bodies of the fuzz targets (`fuzz/fuzz_targets/*.rs`), in a crate of their own so
//! that the cargo-fuzz runs (nightly) and the smoke test in every `cargo test`
//! (`tests/smoke.rs`, stable) call exactly the same code, and no library carries a hidden
//! module for them. Each takes arbitrary bytes; a reader may refuse them, but
//! must not panic, and whatever it accepts must satisfy the reader's promises (checked with
//! `assert!`, which is how a fuzzer sees a broken promise).

use keyshape_core::sequence::Format;
use keyshape_io::{parse_sequence, text_from_bytes, ReadOptions};
use std::path::Path;

/// Every sequence reader (MediaPipe, OpenFace, py-feat, plain CSV, JSON, `.pts`), detected
/// and forced, in 2-D and 3-D.
pub fn sequence(data: &[u8]) {
    let path = Path::new("fuzz.csv");
    let Ok(text) = text_from_bytes(path, data.to_vec(), false) else {
        return;
    };
    let formats = [
        None,
        Some(Format::Mediapipe),
        Some(Format::Openface),
        Some(Format::Pyfeat),
        Some(Format::Csv),
        Some(Format::Json),
        Some(Format::Pts),
    ];
    for format in formats {
        for dims in [2, 3] {
            if let Ok(seq) = parse_sequence(path, &text, &ReadOptions { format, dims }) {
                assert!(seq.coords.iter().all(|v| v.is_finite()));
                assert_eq!(seq.coords.ncols(), seq.frames.len());
                assert!(seq.n_frames() > 0 && seq.points > 0);
            }
        }
    }
}

/// The gzip layer under every reader (single and multi-member, trailing bytes).
pub fn gzip(data: &[u8]) {
    let path = Path::new("fuzz.csv.gz");
    if let Ok(text) = text_from_bytes(path, data.to_vec(), true) {
        let _ = parse_sequence(path, &text, &ReadOptions::default());
    }
}

/// The SVG template reader (usvg underneath).
pub fn svg(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        if let Ok(set) = keyshape_retarget::svg::parse_template(Path::new("fuzz.svg"), text) {
            assert!(set
                .keys
                .iter()
                .all(|k| k.coords.iter().all(|v| v.is_finite())));
        }
    }
}

/// The OBJ mesh reader.
pub fn obj(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        if let Ok(mesh) = keyshape_io::obj::parse_obj(Path::new("fuzz.obj"), text) {
            let n = mesh.positions.len();
            assert!(mesh.faces.iter().flatten().all(|&i| i < n));
        }
    }
}

/// The experiment spec reader (TOML).
pub fn toml(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = keyshape_experiments::experiment::Spec::from_str(Path::new("fuzz.toml"), text);
    }
}
