//! `graybox-lab bench ensemble`: what an ensemble costs to train. MVF on the paper's double
//! pendulum (1024 samples, batch 256) for a few epochs: one member, then K members with the
//! job's threads running whole members side by side and with them splitting each member's
//! batches into shards (members one after another); wall time and its ratio to one member's.

use std::sync::atomic::AtomicBool;
use std::time::Instant;

use clap::Args;
use serde_json::json;

use graybox::backend::{self, Backend, Precision};
use graybox::error::Result;
use graybox::model::spec::ModelSpec;
use graybox::physics::templates::Template;
use graybox::sim::{SimConfig, simulate};
use graybox::train::{Ensemble, Parallelism, TrainConfig};

#[derive(Args, Debug)]
pub struct BenchEnsembleArgs {
    /// Members of the ensemble measured against one member.
    #[arg(long, default_value_t = 5)]
    pub members: usize,
    /// Epochs per run (the first one included: a job pays for it too).
    #[arg(long, default_value_t = 10)]
    pub epochs: usize,
    #[arg(long, default_value_t = 1024)]
    pub samples: usize,
    #[arg(long, default_value_t = 256)]
    pub batch_size: usize,
    /// The job's threads (`--job-threads`).
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
}

pub fn run(a: BenchEnsembleArgs) -> Result<()> {
    let t = Template::DoublePendulum;
    let cfg = SimConfig {
        count: a.samples,
        ..SimConfig::default()
    };
    let data = simulate(&t, t.defaults(), &cfg)?;
    let device = backend::device(Backend::Flex, Precision::F32)?.autodiff();
    let wall = |members: usize, unit: Parallelism| -> Result<f64> {
        let tc = TrainConfig {
            epochs: a.epochs,
            batch_size: a.batch_size,
            ensemble: members,
            ..TrainConfig::default()
        };
        let spec = ModelSpec::named("MVF", Some(t.clone()))?;
        let start = Instant::now();
        let mut e = Ensemble::new("MVF", spec, &[], &data, None, tc, &device)?
            .with_parallelism(a.threads, unit)?;
        let never = AtomicBool::new(false);
        while !e.finished() {
            e.run_epoch(&never)?;
        }
        Ok(start.elapsed().as_secs_f64())
    };
    let one = wall(1, Parallelism::Rows)?;
    let base = json!({"bench": "ensemble_training", "samples": a.samples, "epochs": a.epochs,
                      "batch_size": a.batch_size, "threads": a.threads});
    let line = |members: usize, unit: &str, seconds: f64| {
        let mut v = base.clone();
        v["members"] = json!(members);
        v["parallel_over"] = json!(unit);
        v["seconds"] = json!(seconds);
        v["over_one_member"] = json!(seconds / one);
        println!("{v}");
    };
    line(1, "rows", one);
    line(a.members, "members", wall(a.members, Parallelism::Members)?);
    line(a.members, "rows", wall(a.members, Parallelism::Rows)?);
    Ok(())
}
