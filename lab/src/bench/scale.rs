//! `graybox-lab bench scale`: the wall time of a batch of jobs on one worker and on two, each
//! training on one thread (`--job-threads 1`): what adding a worker buys on a machine with a
//! core to spare, as separate `graybox worker` processes and as workers in one process.

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use clap::{Args, ValueEnum};
use serde_json::json;

use graybox::app::WorkerSettings;
use graybox::app::jobs::JobRequest;
use graybox::error::{Error, Result};
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
    /// Where the workers run: `processes` (one `graybox worker` process each, found next to
    /// this binary) and/or `threads` (all in one process, as `serve --workers N`).
    #[arg(long, value_delimiter = ',', default_value = "processes,threads")]
    pub placement: Vec<Placement>,
}

#[derive(Clone, Copy, Debug, PartialEq, ValueEnum)]
pub enum Placement {
    Processes,
    Threads,
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
        for &p in &a.placement {
            // One worker is the same thing in either placement: measure it once.
            if w == 1 && p != a.placement[0] {
                continue;
            }
            let secs = rt.block_on(batch(&a, w, p))?;
            let base = *first.get_or_insert(secs);
            println!(
                "{}",
                json!({"bench": "worker_scaling", "workers": w, "placement": format!("{p:?}").to_lowercase(),
                       "jobs": a.jobs, "epochs": a.epochs, "job_threads": 1, "seconds": secs,
                       "ratio_to_first": secs / base})
            );
        }
    }
    Ok(())
}

/// Seconds from submitting the batch until every job has ended, with `workers` workers placed
/// as `placement` says, on a new database.
async fn batch(a: &BenchScaleArgs, workers: usize, placement: Placement) -> Result<f64> {
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
    let mut in_process = None;
    let mut children = Vec::new();
    match placement {
        Placement::Threads => {
            let all = WorkerSettings {
                workers,
                ..worker.clone()
            };
            in_process = Some(start_worker(all, None).await?);
        }
        Placement::Processes => {
            for _ in 0..workers {
                children.push(spawn_worker(&worker.db)?);
            }
        }
    }
    for id in &ids {
        while !app.job(id).await?.state.is_final() {
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }
    let secs = t0.elapsed().as_secs_f64();
    if let Some(w) = in_process {
        w.shutdown_by(async {}).await;
    }
    for child in children {
        stop(child)?;
    }
    api.shutdown().await;
    Ok(secs)
}

/// The `graybox` binary built beside this one.
fn graybox_binary() -> Result<PathBuf> {
    let exe = std::env::current_exe()?;
    let bin = exe.with_file_name("graybox");
    if !bin.exists() {
        return Err(Error::FailedPrecondition(format!(
            "{} not found: build it first (cargo build --release --workspace)",
            bin.display()
        )));
    }
    Ok(bin)
}

fn spawn_worker(db: &str) -> Result<Child> {
    Ok(Command::new(graybox_binary()?)
        .args(["worker", "--db", db, "--workers", "1", "--job-threads", "1"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()?)
}

/// SIGTERM, as an orchestrator stops a worker, and wait for it to exit.
fn stop(mut child: Child) -> Result<()> {
    let pid = libc::pid_t::try_from(child.id()).expect("a pid fits pid_t");
    // SAFETY: kill(2) with a pid this process spawned and has not yet reaped.
    unsafe { libc::kill(pid, libc::SIGTERM) };
    child.wait()?;
    Ok(())
}
