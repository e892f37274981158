//! graybox's inference core: everything a trained model needs to answer, with no Burn, async
//! runtime, database or RPC framework (ARCHITECTURE.md). The service (`graybox`) and the C
//! library (`graybox-c`) are built on it.
//!
//! Layers, bottom up: `error`, `rng`, `names`, `simd`, `array` (shaped f64 data), `records`
//! (a warning), `data` (the dataset type); the mechanics in `physics`, and `linalg` (the one
//! Cholesky factorisation and its triangular solves) written over their `Scalar` for the
//! mechanics and control alike; then `model` (a model as its file describes it), `infer`
//! (f64 evaluation), `control` (TVLQR, planning) and `sim` (simulated data, a template's true
//! system). Training (in the service) records the same mechanics on the tape of
//! `physics::tape`; the core links no Burn.

pub mod arena;
pub mod array;
pub mod control;
pub mod data;
pub mod error;
pub mod infer;
pub mod linalg;
pub mod model;
pub mod names;
pub mod physics;
pub mod records;
pub mod rng;
pub mod sim;
pub mod simd;

pub use error::{Error, Result};
