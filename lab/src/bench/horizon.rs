//! `graybox-lab bench horizon`: what multi-step training costs. MVF on 40 trajectories of 200
//! steps of the double pendulum, batch 256 windows, one thread: samples/s (one sample = one
//! transition of a window) and seconds per epoch at each horizon, against H = 1's.

use std::sync::atomic::AtomicBool;

use clap::Args;
use serde_json::json;

use graybox::backend::{self, Backend, Precision};
use graybox::error::Result;
use graybox::model::spec::ModelSpec;
use graybox::physics::templates::Template;
use graybox::sim::double_pendulum_trajectories;
use graybox::train::{TrainConfig, Trainer};

#[derive(Args, Debug)]
pub struct BenchHorizonArgs {
    /// Horizons to measure, comma-separated (the first is the reference).
    #[arg(long, value_delimiter = ',', default_value = "1,5,10,20")]
    pub horizons: Vec<usize>,
    /// Timed epochs per horizon, after one warm-up epoch.
    #[arg(long, default_value_t = 2)]
    pub epochs: usize,
    /// Trajectories of 200 steps to train on.
    #[arg(long, default_value_t = 40)]
    pub trajectories: usize,
    #[arg(long, default_value_t = 256)]
    pub batch_size: usize,
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
}

pub fn run(a: BenchHorizonArgs) -> Result<()> {
    let t = Template::DoublePendulum;
    let data = double_pendulum_trajectories(a.trajectories, 200, 0)?;
    let device = backend::device(Backend::Flex, Precision::F32)?.autodiff();
    let never = AtomicBool::new(false);
    let mut first: Option<f64> = None;
    for &h in &a.horizons {
        let tc = TrainConfig {
            epochs: a.epochs + 1,
            batch_size: a.batch_size,
            val_fraction: 0.0,
            horizon: h,
            ..TrainConfig::default()
        };
        let spec = ModelSpec::named("MVF", Some(t.clone()))?;
        let mut trainer =
            Trainer::new("MVF", spec, &[], &data, None, tc, &device)?.with_threads(a.threads)?;
        trainer.run_epoch(&never)?; // warm-up: allocations, first-touch
        let before = trainer.train_seconds();
        for _ in 0..a.epochs {
            trainer.run_epoch(&never)?;
        }
        let per_epoch = (trainer.train_seconds() - before) / a.epochs as f64;
        let windows = a.trajectories * (200 - h + 1);
        let base = *first.get_or_insert(per_epoch);
        println!(
            "{}",
            json!({"bench": "multistep_throughput", "horizon": h, "windows": windows,
                   "batch_size": a.batch_size, "threads": a.threads,
                   "samples_per_second": (windows * h) as f64 / per_epoch,
                   "seconds_per_epoch": per_epoch,
                   "epoch_time_over_first": per_epoch / base,
                   "note": "one sample = one transition of a window; an epoch passes over every window once"})
        );
    }
    Ok(())
}
