//! graybox: structured Lagrangian (gray-box) dynamics models of mechanical systems, learned from
//! transition data and served to controllers.
//!
//! Layout (design.md §3): `model` holds the math (components, dynamics, integrators, specs),
//! `train` the datasets and the training loop, `sim` the simulated datasets, `cli` the
//! command-line front end. The service and gRPC layers call the same pieces.

pub mod api;
pub mod app;
pub mod backend;
pub mod bench;
pub mod cli;
pub mod control;
pub mod error;
pub mod infer;
pub mod jobs;
pub mod model;
pub mod rng;
pub mod service;
pub mod sim;
pub mod store;
pub mod train;

pub use error::{Error, Result};
