//! keyshape-lab: key shapes, blend weights and retargeting for tracked facial performances.
//!
//! The numeric core is plain functions on plain data: read a [`sequence::Sequence`]
//! ([`io::read_sequence`]), select points and remove head motion ([`decompose::prepare`]),
//! and solve blend weights on key frames ([`decompose::decompose`], solvers in [`solve`]).
//!
//! ```
//! use keyshape_lab::decompose::{decompose, prepare, PrepareOptions};
//! use keyshape_lab::io::builtin_sequence;
//! use keyshape_lab::solve::{SolveOptions, Solver};
//!
//! let seq = builtin_sequence()?;
//! let opts = PrepareOptions { points: Some("lips".into()), align: true };
//! let prep = prepare(&seq, &opts)?;
//! let keys: Vec<usize> = [0, 60, 120, 180, 215]
//!     .iter()
//!     .map(|&f| prep.seq.column_of_frame(f))
//!     .collect::<Result<_, _>>()?;
//! let nnls = SolveOptions::new(Solver::Nnls);
//! let d = decompose(&prep.seq.coords, prep.seq.points, &keys, None, &nnls)?;
//! assert_eq!(d.negative_share(), 0.0);
//! assert!(d.mean_rms() < 5.0); // pixels
//! # Ok::<(), keyshape_lab::Error>(())
//! ```
#![cfg_attr(
    not(test),
    deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)
)]
#![warn(missing_docs)]
// Index loops mirror the equations (g_i, G_ij) in the numeric code; iterator chains hide them.
#![allow(clippy::needless_range_loop)]

pub mod align;
pub mod cosker;
pub mod decompose;
pub mod error;
pub mod experiment;
#[doc(hidden)]
pub mod fuzzing;
pub mod io;
pub mod keyshapes;
pub mod pca;
pub mod plot;
pub mod rbf;
pub mod render;
pub mod report;
pub mod retarget;
pub mod rig;
pub mod sequence;
pub mod solve;
pub mod stats;
pub mod stream;
pub mod transfer;
pub mod tui;

pub use error::{Error, Result};
