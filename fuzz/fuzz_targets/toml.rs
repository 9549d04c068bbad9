//! The experiment spec reader (TOML) on arbitrary text.
#![no_main]
use keyshape_lab::experiment::Spec;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = Spec::from_str(Path::new("fuzz.toml"), text);
    }
});
