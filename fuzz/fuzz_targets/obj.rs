//! The OBJ mesh reader on arbitrary text.
#![no_main]
use keyshape_lab::io::obj::parse_obj;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        if let Ok(mesh) = parse_obj(Path::new("fuzz.obj"), text) {
            let n = mesh.positions.len();
            assert!(mesh.faces.iter().flatten().all(|&i| i < n));
        }
    }
});
