//! The SVG template reader (usvg underneath) on arbitrary text.
#![no_main]
use keyshape_lab::io::svg::parse_template;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        if let Ok(set) = parse_template(Path::new("fuzz.svg"), text) {
            assert!(set.keys.iter().all(|k| k.coords.iter().all(|v| v.is_finite())));
        }
    }
});
