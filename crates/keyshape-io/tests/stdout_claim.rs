//! Standard output is one output of a command's set: a second write to it, however
//! spelled, is refused before any byte of either goes out. (A binary of its own: the set is
//! the process's.)

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_io::{write_atomic, OutputSet};
use std::path::Path;

#[test]
fn a_second_output_to_standard_output_is_refused() {
    let _set = OutputSet::begin();
    write_atomic(Path::new("-"), |w| w.write_all(b"")).unwrap();
    let e = write_atomic(Path::new("-"), |w| w.write_all(b"")).expect_err("a second stdout");
    assert!(
        e.to_string().contains("both would go to standard output"),
        "{e}"
    );
    // The set is dropped uncommitted: nothing reaches standard output.
}
