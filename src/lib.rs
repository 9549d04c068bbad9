//! keyshape-lab: key shapes, blend weights and retargeting for tracked facial performances.
#![cfg_attr(
    not(test),
    deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)
)]
#![warn(missing_docs)]
// Index loops mirror the equations (g_i, G_ij) in the numeric code; iterator chains hide them.
#![allow(clippy::needless_range_loop)]

pub mod align;
pub mod decompose;
pub mod error;
pub mod io;
pub mod pca;
pub mod sequence;
pub mod solve;

pub use error::{Error, Result};
