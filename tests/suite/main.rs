//! The integration tests of the service's library and binaries in f32, in one binary: each
//! test binary links the whole service, so one binary links it once where fourteen linked it
//! fourteen times. Apart: the API's (tests/api, run twice: on SQLite, then on PostgreSQL with
//! an object store) and the f64 ones (tests/f64: a process computes in one precision).
//!
//! Run one file's tests with its module name as the filter, e.g.
//! `cargo test --release -p graybox --test suite plan::`.

#[path = "../common/mod.rs"]
mod common;

mod architecture;
mod cli;
mod compat;
mod control;
mod data;
mod dircol;
mod formula_templates;
mod multibody;
mod multistep;
mod plan;
mod residual_periodic;
mod training;
mod urdf;
mod urdf_files;
