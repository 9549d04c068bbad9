//! Every sequence reader, detected and forced, in 2-D and 3-D. The body is `keyshape_fuzz::sequence`, shared with
//! the smoke test that runs in every `cargo test` (crates/keyshape-fuzz/tests/smoke.rs).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| keyshape_fuzz::sequence(data));
