//! graybox: structured Lagrangian (gray-box) dynamics models of mechanical systems, learned from
//! transition data and served to controllers.
//!
//! Layers (ARCHITECTURE.md, enforced by tests/architecture.rs), bottom up: `error`, `rng`,
//! `names`, `array` (shaped f64 data), `backend`, `data` (the dataset type), `records` (what the store keeps); the
//! mechanics in `physics` (dynamics, templates, URDF robots; no Burn); the math in `model`
//! (the trainable model on Burn, its spec and file), `infer` (f64 evaluation), `control`
//! (TVLQR) and `sim`; `train` (the training loop); `store` (SQLite); `app` (the one core);
//! `worker` (training jobs from the queue); `api` (REST, gRPC); and at the top `cli` and `service`. The benchmarks
//! and the paper's experiments are the lab, a crate of their own (`lab/`, `graybox-lab`).

pub mod api;
pub mod app;
pub mod array;
pub mod backend;
pub mod backoff;
pub mod cli;
pub mod control;
pub mod data;
pub mod error;
pub mod infer;
pub mod model;
pub mod names;
pub mod pem;
pub mod physics;
pub mod records;
pub mod rng;
pub mod service;
pub mod sim;
pub mod simd;
pub mod store;
pub mod train;
pub mod worker;

pub use error::{Error, Result};
