//! The gzip layer under every reader. The body is `keyshape_experiments::fuzzing::gzip`, shared with
//! the smoke test that runs in every `cargo test` (tests/it/fuzz_smoke.rs).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| keyshape_experiments::fuzzing::gzip(data));
