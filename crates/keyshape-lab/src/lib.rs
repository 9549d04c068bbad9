//! keyshape-lab: the experiments over the papers' crates — scripted studies
//! ([`experiment`], `kslab run experiments/NAME.toml`), corpus runs on a cluster
//! ([`experiment::corpus`]), their reports ([`report`]), charts ([`plot`]), pictures
//! ([`render`]) and streaming solves of long tracks ([`stream`]).

pub mod experiment;
#[doc(hidden)]
pub mod fuzzing;
pub mod plot;
pub mod render;
pub mod report;
pub mod stream;
