//! Every sequence reader (MediaPipe, OpenFace, py-feat, plain CSV, JSON, .pts) on
//! arbitrary text, in 2-D and 3-D, by detection and forced: an error or a valid sequence,
//! never a panic.
#![no_main]
use keyshape_lab::io::{parse_sequence, text_from_bytes, ReadOptions};
use keyshape_lab::sequence::Format;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
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
            }
        }
    }
});
