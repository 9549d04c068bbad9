//! The core's oracles, runnable alone (`cargo test -p keyshape-core`, the fast tier):
//! solvers against KKT conditions, brute force, a textbook Lawson–Hanson and SciPy's numbers;
//! PCA and alignment invariances. The real-data cases read `../shared/data`.

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
// Index loops mirror the maths, as in the library.
#![allow(clippy::needless_range_loop)]

mod align;
mod common;
mod keyshapes;
mod pca;
mod pinned;
mod reference;
mod solvers;
mod temporal;
