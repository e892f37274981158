//! Training: datasets, the training loop with Adam, checkpoints, reports.

pub mod adam;
pub mod artifact;
pub mod budget;
pub mod data;
pub mod report;
pub mod trainer;

pub use trainer::{TrainConfig, TrainState, Trainer};
