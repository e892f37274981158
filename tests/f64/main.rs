//! The integration tests that compute with Burn's tensors in f64. Burn fixes a device's float
//! type once per process, so these cannot share a binary with the f32 tests (tests/suite).
//!
//! Run one file's tests with its module name as the filter, e.g.
//! `cargo test --release -p graybox --test f64 infer_f64::`.

#[path = "../common/mod.rs"]
mod common;

mod infer_f64;
mod numerics_f64;
