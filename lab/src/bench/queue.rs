//! `graybox-lab bench queue`: how long a submitted job waits for an idle worker (queued →
//! running). Workers poll the queue (every 150–250 ms each, so their phases drift) rather than
//! wait on LISTEN/NOTIFY: PgBouncer in transaction mode drops LISTEN, SQLite has no such thing,
//! and one code path serves both; this measures what polling costs in latency.

use std::time::{Duration, Instant};

use clap::Args;
use serde_json::json;

use graybox::app::WorkerSettings;
use graybox::app::jobs::JobRequest;
use graybox::error::Result;
use graybox::records::JobState;
use graybox::service::start_worker;

#[derive(Args, Debug)]
pub struct BenchQueueArgs {
    /// The database: an empty PostgreSQL database's URL, or an SQLite file [default: a
    /// temporary one].
    #[arg(long)]
    pub db: Option<String>,
    /// Idle worker processes' worth of workers (each its own pool and poller, as separate
    /// `graybox worker` processes run).
    #[arg(long, default_value_t = 3)]
    pub workers: usize,
    /// Jobs submitted, one at a time, to idle workers.
    #[arg(long, default_value_t = 50)]
    pub jobs: usize,
}

pub fn run(a: BenchQueueArgs) -> Result<()> {
    tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?
        .block_on(measure(a))
}

async fn measure(a: BenchQueueArgs) -> Result<()> {
    let temp = super::TempDb::new();
    let db = (a.db.clone()).unwrap_or_else(|| temp.0.display().to_string());
    let worker = WorkerSettings {
        db: db.clone(),
        workers: 0,
        ..WorkerSettings::default()
    };
    let api = super::api_node(worker.clone()).await?;
    let mut workers = Vec::new();
    for _ in 0..a.workers {
        let one = WorkerSettings {
            workers: 1,
            job_threads: Some(1),
            ..worker.clone()
        };
        workers.push(start_worker(one, None).await?);
    }
    let app = api.app.clone();
    let ds = super::upload_double_pendulum(&app, 32).await?;
    let mut waits = Vec::with_capacity(a.jobs);
    for i in 0..a.jobs {
        // Submissions at varying phases of the workers' polls.
        tokio::time::sleep(Duration::from_millis(37 * (i as u64 % 7))).await;
        let req: JobRequest = serde_json::from_value(json!({
            "dataset_id": ds, "model": "W-B", "template": "double_pendulum",
            "training": {"epochs": 1, "batch_size": 32}
        }))
        .expect("a valid job request");
        let id = app.submit_job(req, None).await?.item.id;
        let t0 = Instant::now();
        while app.job(&id).await?.state == JobState::Queued {
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
        waits.push(t0.elapsed().as_secs_f64() * 1e3);
        while !app.job(&id).await?.state.is_final() {
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    }
    waits.sort_by(f64::total_cmp);
    let at = |q: f64| waits[((waits.len() - 1) as f64 * q).round() as usize];
    println!(
        "{}",
        json!({"bench": "claim_latency", "workers": a.workers, "jobs": a.jobs,
               "backend": if graybox::store::is_postgres(&db) { "postgres" } else { "sqlite" },
               "p50_ms": at(0.5), "p99_ms": at(0.99), "max_ms": at(1.0),
               "mean_ms": waits.iter().sum::<f64>() / waits.len() as f64,
               "poll_ms": "150-250", "wakeup": "polling"})
    );
    for w in workers {
        w.shutdown_by(async {}).await;
    }
    api.shutdown().await;
    Ok(())
}
