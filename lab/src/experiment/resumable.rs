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
use graybox::sim::{Recording, double_pendulum_recorded};
use graybox::train::{TrainConfig, TrainState, Trainer};

/// Epochs between a cell's checkpoints.
const CHECKPOINT_EVERY: usize = 10;

/// `count` trajectories of `steps` transitions from stream `stream` of `seed` (streams keep a
/// seed's training, validation and test trajectories apart), recorded as `rec` says.
pub fn trajectories(
    count: usize,
    steps: usize,
    seed: u64,
    stream: u64,
    rec: Recording,
) -> Result<Dataset> {
    let seed = Rng::derive(seed, 0x7A7A_0000 + stream).next_u64();
    double_pendulum_recorded(count, steps, seed, rec)
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

/// `ds` as sensors would record it: each state of its trajectories with Gaussian noise of
/// standard deviation `std[0]` on q and `std[1]` on q̇ added, the same noisy state where one
/// row's next state is the following row's state (so windows still chain).
pub fn observed(ds: &Dataset, std: [f64; 2], seed: u64) -> Dataset {
    let mut rng = Rng::derive(seed, 0x0B5E_0000);
    let n = ds.nv; // the double pendulum's: q and q̇ of one width
    let mut out = ds.clone();
    // q's n values, then q̇'s.
    let mut noise = || -> Vec<f64> { (0..2 * n).map(|i| std[i / n] * rng.normal()).collect() };
    let add = |a: &mut [f64], row: usize, e: &[f64]| {
        a[row * n..(row + 1) * n]
            .iter_mut()
            .zip(e)
            .for_each(|(v, e)| *v += e);
    };
    for seg in ds.segments() {
        let mut here = noise();
        for row in seg.start..seg.start + seg.length {
            let next = noise();
            add(&mut out.q, row, &here[..n]);
            add(&mut out.qdot, row, &here[n..]);
            add(&mut out.q_next, row, &next[..n]);
            add(&mut out.qdot_next, row, &next[n..]);
            here = next;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn observed_states_are_noisy_and_still_chain() {
        let exact = trajectories(2, 20, 0, 0, Recording::default()).unwrap();
        let noisy = observed(&exact, [0.01, 0.1], 3);
        let n = exact.nv;
        let differs = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| x != y);
        assert!(differs(&exact.q, &noisy.q) && differs(&exact.qdot_next, &noisy.qdot_next));
        // The spread of the added noise is the one asked for (a seeded sample of 80: within 20%).
        let d: Vec<f64> = (noisy.qdot.iter().zip(&exact.qdot))
            .map(|(a, b)| a - b)
            .collect();
        let sd = (d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64).sqrt();
        assert!((sd - 0.1).abs() < 0.02, "{sd}");
        // Within a trajectory a row's next state is the following row's state, bit for bit.
        for row in 0..19 {
            let next = &noisy.q_next[row * n..(row + 1) * n];
            assert_eq!(next, &noisy.q[(row + 1) * n..(row + 2) * n]);
        }
        assert_eq!(noisy.segments().len(), 2);
    }
}
