//! Training: the training loop with Adam, checkpoints, and what a job will cost. Returns
//! bytes (checkpoints, model files); knows no database.

pub mod adam;
pub mod budget;
pub mod ensemble;
pub mod objective;
pub mod setup;
pub mod shards;
pub mod trainer;
pub mod warnings;
pub mod windows;

pub use ensemble::{Ensemble, Parallelism};
pub use setup::TrainConfig;
pub use trainer::{TrainState, Trainer, member_seed};
