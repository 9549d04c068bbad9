//! The gzip layer under every reader (single and multi-member, trailing bytes).
#![no_main]
use keyshape_lab::io::{parse_sequence, text_from_bytes, ReadOptions};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz.csv.gz");
    if let Ok(text) = text_from_bytes(path, data.to_vec(), true) {
        let _ = parse_sequence(path, &text, &ReadOptions::default());
    }
});
