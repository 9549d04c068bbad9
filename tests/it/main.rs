//! Integration tests, one binary: solvers against their oracles, readers on the real data in
//! `../shared/data`, alignment invariances, and the CLI's handling of bad input.

// The workspace denies unwrap/expect/panic outside tests (Cargo.toml, clippy.toml); the
// helpers here are test code too: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod bad_input;
mod book;
mod catalogue;
mod cli_results;
mod common;
mod corpus;
mod experiments;
mod keyshapes;
mod live;
mod live_captures;
mod mediapipe478;
mod modes;
mod outputs;
mod readers;
mod rig;
mod rig_accuracy;
mod rig_dense;
mod rig_map;
mod rig_neutral;
mod rig_plausible;
mod scale;
mod settings_walk;
mod smoothing;
mod stream;
mod tiny_tracks;
mod transfer;
mod tui;
mod weights_png;
mod where_things_live;
