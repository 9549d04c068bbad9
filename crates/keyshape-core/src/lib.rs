//! keyshape-core: the numeric core of keyshape-lab — plain functions on plain data, no I/O
//! beyond what a caller hands in, no UI.
//!
//! A tracked performance is a [`sequence::Sequence`] (one column of flat point coordinates
//! per frame). [`decompose::prepare`] selects points and removes head motion
//! ([`align`]); [`keyshapes`] chooses key frames (paper 000 §3: spread along principal
//! components, k-means or the convex hull in PCA space, [`pca`]); [`decompose::decompose`]
//! solves every frame's blend weights on them with a solver from [`solve`] (LS, NNLS,
//! bounded; the temporal priors in [`solve::temporal`]). [`rbf`] is paper 004's
//! multiquadric space transform; [`stats`] compares signals. Readers and writers are in
//! the `keyshape-io` crate, whose crate documentation shows a whole solve.
//!
//! **The front door.** What a caller solving weights needs is re-exported here:
//! [`Sequence`], [`prepare()`] with [`PrepareOptions`], [`Analysis`] with a key-shape
//! [`Method`] and [`KeyOptions`], [`decompose()`] with [`SolveOptions`] and a [`Solver`], and
//! [`Error`]. The modules below hold the building blocks the other crates of the workspace
//! share (the active-set NNLS and its Cholesky updates, the banded temporal solvers, the
//! Jacobi SVD): public so they can share them, and documented, but their signatures follow
//! the workspace's needs rather than a stable API.

pub mod align;
pub mod decompose;
pub mod error;
pub mod keyshapes;
pub mod limits;
pub mod pca;
pub mod rbf;
pub mod sequence;
pub mod solve;
pub mod stats;

pub use decompose::{decompose, prepare, Decomposition, PrepareOptions, Prepared};
pub use error::{Error, ErrorKind, Result};
pub use keyshapes::{Analysis, KeyOptions, Method};
pub use sequence::{Format, Sequence};
pub use solve::{SolveOptions, Solver};
