//! `graybox-lab bench scale`: the wall time of a batch of jobs on one worker and on two, each
//! training on one thread (`--job-threads 1`): what adding a worker process buys on a machine
//! with a core to spare.

use std::time::{Duration, Instant};

use clap::Args;
use serde_json::json;

use graybox::app::WorkerSettings;
use graybox::app::jobs::JobRequest;
use graybox::error::Result;
use graybox::service::start_worker;

#[derive(Args, Debug)]
pub struct BenchScaleArgs {
    /// Jobs in the batch.
    #[arg(long, default_value_t = 8)]
    pub jobs: usize,
    /// Epochs per job (MVF on the double pendulum, 1024 transitions, batch 64: ~30 s on one
    /// thread of the 2-core sandbox).
    #[arg(long, default_value_t = 600)]
    pub epochs: usize,
    /// Worker counts to measure, comma-separated.
    #[arg(long, default_value = "1,2")]
    pub workers: String,
}

pub fn run(a: BenchScaleArgs) -> Result<()> {
    let counts: Vec<usize> = (a.workers.split(','))
        .map(|w| w.trim().parse().expect("--workers: numbers"))
        .collect();
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    let mut first = None;
    for w in counts {
        let secs = rt.block_on(batch(&a, w))?;
        let base = *first.get_or_insert(secs);
        println!(
            "{}",
            json!({"bench": "worker_scaling", "workers": w, "jobs": a.jobs, "epochs": a.epochs,
                   "job_threads": 1, "seconds": secs, "ratio_to_first": secs / base})
        );
    }
    Ok(())
}

/// Seconds from submitting the batch until every job has ended, with `workers` workers (each
/// its own pool, as separate `graybox worker` processes) on a new database.
async fn batch(a: &BenchScaleArgs, workers: usize) -> Result<f64> {
    let temp = super::TempDb::new();
    let worker = WorkerSettings {
        db: temp.0.display().to_string(),
        workers: 0,
        job_threads: Some(1),
        ..WorkerSettings::default()
    };
    let api = super::api_node(worker.clone()).await?;
    let app = api.app.clone();
    let ds = super::upload_double_pendulum(&app, 1024).await?;
    let mut ids = Vec::new();
    for seed in 0..a.jobs {
        let req: JobRequest = serde_json::from_value(json!({
            "dataset_id": ds, "model": "MVF", "template": "double_pendulum",
            "training": {"epochs": a.epochs, "batch_size": 64, "seed": seed}
        }))
        .expect("a valid job request");
        ids.push(app.submit_job(req, None).await?.item.id);
    }
    let t0 = Instant::now();
    let mut running = Vec::new();
    for _ in 0..workers {
        let one = WorkerSettings {
            workers: 1,
            ..worker.clone()
        };
        running.push(start_worker(one, None).await?);
    }
    for id in &ids {
        while !app.job(id).await?.state.is_final() {
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }
    let secs = t0.elapsed().as_secs_f64();
    for w in running {
        w.shutdown_by(async {}).await;
    }
    api.shutdown().await;
    Ok(secs)
}
