//! keyshape-experiments: the experiments over the papers' crates — scripted studies
//! ([`experiment`], `kslab run experiments/NAME.toml`), corpus runs on a cluster
//! ([`experiment::corpus`]) and their reports ([`report`]). Their pictures are drawn by
//! keyshape-pictures.

pub mod experiment;
pub mod report;
