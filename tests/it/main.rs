//! Integration tests, one binary: solvers against their oracles, readers on the real data in
//! `../shared/data`, alignment invariances, and the CLI's handling of bad input.

mod align;
mod bad_input;
mod common;
mod readers;
mod reference;
mod solvers;
