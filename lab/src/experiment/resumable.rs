//! Trainings on the double pendulum's trajectories that checkpoint every few epochs, so that
//! an interrupted cell resumes mid-cell (the multistep and rollout experiments, whose
//! multi-step cells take many minutes).

use std::path::Path;
use std::sync::atomic::AtomicBool;

use graybox::backend::{self, Backend, Precision};
use graybox::data::Dataset;
use graybox::error::Result;
use graybox::model::file::write_atomic;
use graybox::model::report::EpochMetrics;
use graybox::model::spec::ModelSpec;
use graybox::physics::templates::Template;
use graybox::rng::Rng;
use graybox::sim::double_pendulum_trajectories;
use graybox::train::{TrainConfig, TrainState, Trainer};

/// Epochs between a cell's checkpoints.
const CHECKPOINT_EVERY: usize = 10;

/// `count` trajectories of `steps` transitions from stream `stream` of `seed` (streams keep a
/// seed's training, validation and test trajectories apart).
pub fn trajectories(count: usize, steps: usize, seed: u64, stream: u64) -> Result<Dataset> {
    let seed = Rng::derive(seed, 0x7A7A_0000 + stream).next_u64();
    double_pendulum_trajectories(count, steps, seed)
}

/// Trains `model` with `cfg` on `data` (validated on `val`) to the end, resuming from the
/// checkpoint at `ckpt` when there is one and writing one every few epochs. The caller
/// removes `ckpt` once it has saved what it needs of the trained model.
pub fn train(
    model: &str,
    cfg: TrainConfig,
    data: &Dataset,
    val: &Dataset,
    ckpt: &Path,
    threads: usize,
    show: &dyn Fn(&EpochMetrics),
) -> Result<Trainer> {
    let device = backend::device(Backend::Flex, Precision::F32)?.autodiff();
    let mut trainer = match std::fs::read(ckpt) {
        Ok(bytes) => Trainer::resume(TrainState::from_bytes(&bytes)?, data, Some(val), &device)?,
        Err(_) => {
            let spec = ModelSpec::named(model, Some(Template::DoublePendulum))?;
            Trainer::new(model, spec, &[], data, Some(val), cfg, &device)?
        }
    }
    .with_threads(threads)?;
    let never = AtomicBool::new(false);
    while !trainer.finished() {
        let m = trainer.run_epoch(&never)?;
        show(&m);
        if m.epoch % CHECKPOINT_EVERY == 0 {
            write_atomic(ckpt, &trainer.checkpoint().to_bytes())?;
        }
    }
    Ok(trainer)
}
