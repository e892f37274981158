//! graybox: structured Lagrangian (gray-box) dynamics models of mechanical systems, learned from
//! transition data and served to controllers.
//!
//! The model files, the mechanics, f64 inference and control are the inference core
//! (`graybox-core`, re-exported here under their own names); this crate adds training on
//! Burn, the store, the core `App` and its adapters.
//!
//! Layers (ARCHITECTURE.md, enforced by tests/suite/architecture.rs), bottom up: `error`, `rng`,
//! `names`, `array` (shaped f64 data), `backend`, `data` (the dataset type), `records` (what the store keeps); the
//! mechanics in `physics` (dynamics, templates, URDF robots; no Burn); the math in `model`
//! (the trainable model on Burn, its spec and file), `infer` (f64 evaluation), `control`
//! (TVLQR) and `sim`; `train` (the training loop); `store` (SQLite); `app` (the one core);
//! `worker` (training jobs from the queue); `api` (REST, gRPC); and at the top `cli` and `service`. The benchmarks
//! and the paper's experiments are the lab, a crate of their own (`lab/`, `graybox-lab`).

pub mod api;
pub mod app;
pub mod backend;
pub mod backoff;
pub mod cli;
pub mod model;
pub mod pem;
pub mod records;
pub mod service;
pub mod store;
pub mod train;
pub mod worker;

// The inference core's modules, under the paths the service has always used for them.
pub use graybox_core::{
    arena, array, control, data, error, infer, linalg, names, physics, rng, sim, simd,
};

pub use error::{Error, Result};
