//! Training workers over the persistent queue (docs/storage.md#leases-and-heartbeats): claim a job, hold its lease
//! with heartbeats, train on a blocking thread, record each epoch, checkpoint at epoch ends,
//! and end the job (or give it back on shutdown). Every write is fenced by (job, attempt).

mod pool;

pub use pool::{Pool, Stopped};

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use tokio::runtime::Handle;
use tokio::sync::watch;
use tokio::task::JoinHandle;
use tracing::{info, warn};

use crate::app::App;
use crate::app::jobs::JobSpec;
use crate::backend::{self, Backend, Precision};
use crate::backoff::Backoff;
use crate::error::{Error, Result};
use crate::records::{JobState, Metric};
use crate::store::{Claimed, Lease, NewModel};
use crate::train::{TrainState, Trainer};

/// A job given back after a storage failure waits this long before it is claimed again,
/// doubling with each failure in a row (`--storage-patience-secs` says when it fails).
const JOB_BACKOFF: Backoff = Backoff::new(Duration::from_secs(2), Duration::from_secs(60));

/// How long a worker waits before asking an unreachable object store again, doubling.
const STORE_BACKOFF: Backoff = Backoff::new(Duration::from_millis(500), Duration::from_secs(15));

/// How a claimed job ended, as far as this worker is concerned.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    Succeeded(String),
    Failed(String),
    Cancelled,
    /// Checkpointed and given back to the queue (shutdown).
    Released,
    /// Another attempt owns the job now; this worker stopped without writing.
    LeaseLost,
    /// A storage failure; the job went back to the queue, to be claimed after a backoff wait.
    Retried,
}

/// Flags the blocking training thread reads.
#[derive(Default)]
struct Flags {
    cancel: AtomicBool,
    lost: AtomicBool,
    shutdown: AtomicBool,
}

/// Runs workers until `shutdown` turns true; each returns after its current job reached an
/// epoch end and was checkpointed and released.
pub async fn run_worker(app: App, owner: String, mut shutdown: watch::Receiver<bool>) {
    let mut store = StoreGate::default();
    loop {
        let mut poll = poll_interval();
        if *shutdown.borrow() {
            return;
        }
        // No job is claimed while the object store does not answer: it would only fail.
        if let Some(wait) = store.closed(&app, &owner).await {
            tokio::select! {
                _ = tokio::time::sleep(wait) => {}
                _ = shutdown.changed() => {}
            }
            continue;
        }
        match app
            .store
            .claim_job(
                &owner,
                lease_ms(&app),
                app.settings.worker.max_attempts as i64,
            )
            .await
        {
            Ok(Some(claimed)) => {
                let id = claimed.job.id.clone();
                info!(job = %id, attempt = claimed.attempt, worker = %owner, "claimed a job");
                match run_claimed(&app, claimed, shutdown.clone()).await {
                    Ok(outcome) => {
                        if outcome == Outcome::Retried {
                            store.recheck();
                        }
                        info!(job = %id, ?outcome, worker = %owner, "job left the worker")
                    }
                    Err(e) => {
                        warn!(job = %id, error = %e, worker = %owner, "worker failed to finish a job")
                    }
                }
            }
            Ok(None) => {
                tokio::select! {
                    _ = tokio::time::sleep(poll) => {}
                    _ = shutdown.changed() => {}
                }
            }
            Err(e) => {
                warn!(error = %e, "claiming a job failed");
                poll = STORE_BACKOFF.delay(0).max(poll);
                tokio::select! {
                    _ = tokio::time::sleep(poll) => {}
                    _ = shutdown.changed() => {}
                }
            }
        }
    }
}

/// How long a worker trusts the object store's last answer before it asks again: an idle
/// worker polls the queue five times a second, and need not ask the store each time.
const STORE_TRUSTED_FOR: Duration = Duration::from_secs(5);

/// Whether a worker may claim: the object store answered lately, or answers now.
#[derive(Default)]
struct StoreGate {
    answered: Option<std::time::Instant>,
    /// Pings in a row that failed.
    down: u32,
}

impl StoreGate {
    /// None when the store answers (lately or now); else how long to wait before asking it
    /// again.
    async fn closed(&mut self, app: &App, owner: &str) -> Option<Duration> {
        if self
            .answered
            .is_some_and(|t| t.elapsed() < STORE_TRUSTED_FOR)
        {
            return None;
        }
        match app.store.ping_blobs().await {
            Ok(()) => {
                if self.down > 0 {
                    info!(worker = %owner, "the object store answers again");
                }
                (self.answered, self.down) = (Some(std::time::Instant::now()), 0);
                None
            }
            Err(e) => {
                if self.down == 0 {
                    warn!(error = %e, worker = %owner, "the object store is unreachable; claiming no job until it answers");
                }
                self.answered = None;
                self.down = self.down.saturating_add(1);
                Some(STORE_BACKOFF.delay(self.down - 1))
            }
        }
    }

    /// A job just failed on storage: ask the store before the next claim.
    fn recheck(&mut self) {
        self.answered = None;
    }
}

/// How long an idle worker waits before asking the queue again: 200 ms on average, varied by
/// ±25% so that workers started together drift apart and an idle fleet answers a new job
/// sooner than one worker would (see `graybox-lab bench queue`).
fn poll_interval() -> Duration {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.subsec_nanos());
    Duration::from_millis(150 + u64::from(nanos % 101))
}

fn lease_ms(app: &App) -> i64 {
    app.settings.worker.lease_secs as i64 * 1000
}

/// Trains one claimed job to its end (or until shutdown, cancellation or a lost lease).
pub async fn run_claimed(
    app: &App,
    claimed: Claimed,
    shutdown: watch::Receiver<bool>,
) -> Result<Outcome> {
    let flags = Arc::new(Flags::default());
    let heartbeat = spawn_heartbeat(app, &claimed, &flags);
    let shutdown_watch = spawn_shutdown_watch(shutdown, &flags);
    let result = {
        let (app, claimed, flags) = (app.clone(), claimed.clone(), flags.clone());
        let handle = Handle::current();
        tokio::task::spawn_blocking(move || train_job(&app, &claimed, &flags, &handle))
            .await
            .unwrap_or_else(|e| {
                Err(Error::Training(format!(
                    "the training thread panicked: {e}"
                )))
            })
    };
    heartbeat.abort();
    shutdown_watch.abort();
    if flags.lost.load(Ordering::Relaxed) {
        return Ok(Outcome::LeaseLost);
    }
    match result {
        Ok(outcome) => Ok(outcome),
        Err(e) => end_with_error(app, &claimed, e).await,
    }
}

/// Renews the lease every lease/6; delivers cancellation, and notices a lost lease.
fn spawn_heartbeat(app: &App, claimed: &Claimed, flags: &Arc<Flags>) -> JoinHandle<()> {
    let (app, claimed, flags) = (app.clone(), claimed.clone(), flags.clone());
    let every = Duration::from_millis((lease_ms(&app) / 6).max(50) as u64);
    tokio::spawn(async move {
        loop {
            tokio::time::sleep(every).await;
            match app.store.heartbeat(&claimed, lease_ms(&app)).await {
                Ok(Lease::Held { cancel_requested }) => {
                    if cancel_requested {
                        flags.cancel.store(true, Ordering::Relaxed);
                    }
                }
                Ok(Lease::Lost) => {
                    flags.lost.store(true, Ordering::Relaxed);
                    flags.cancel.store(true, Ordering::Relaxed);
                    return;
                }
                Err(e) => warn!(job = %claimed.job.id, error = %e, "heartbeat failed"),
            }
        }
    })
}

/// Raises the shutdown flag the training thread reads at epoch ends.
fn spawn_shutdown_watch(mut shutdown: watch::Receiver<bool>, flags: &Arc<Flags>) -> JoinHandle<()> {
    let flags = flags.clone();
    tokio::spawn(async move {
        while !*shutdown.borrow() {
            if shutdown.changed().await.is_err() {
                return;
            }
        }
        flags.shutdown.store(true, Ordering::Relaxed);
    })
}

/// Ends a job whose training returned an error: cancelled, given back after a storage fault
/// (claimed again after a backoff wait, or failed once storage has failed it for
/// `--storage-patience-secs`), or failed with the error's message.
async fn end_with_error(app: &App, claimed: &Claimed, e: Error) -> Result<Outcome> {
    let store = &app.store;
    Ok(match e {
        Error::Cancelled => {
            store.end_job(claimed, JobState::Cancelled, None).await?;
            Outcome::Cancelled
        }
        Error::Storage(msg) => {
            let patience = app.settings.worker.storage_patience();
            warn!(job = %claimed.job.id, error = %msg, "storage failed; the job goes back to the queue");
            // The job's error is shown to users: which service failed, not its address.
            let public = Error::Storage(msg.clone()).public_message();
            match store
                .retry_later(claimed, JOB_BACKOFF, patience, &public)
                .await?
            {
                Some(JobState::Failed) => Outcome::Failed(msg),
                Some(_) => Outcome::Retried,
                None => Outcome::LeaseLost,
            }
        }
        e => {
            let msg = e.to_string();
            store.end_job(claimed, JobState::Failed, Some(&msg)).await?;
            Outcome::Failed(msg)
        }
    })
}

/// The blocking part: build or resume the trainer, run epochs (recording each, with a
/// checkpoint every `--checkpoint-every`), then store the model; progress goes through the
/// runtime handle. Every write is fenced: a lost lease ends it without writing.
fn train_job(app: &App, c: &Claimed, flags: &Flags, rt: &Handle) -> Result<Outcome> {
    let spec = JobSpec::from_json(&c.job.request)?;
    let mut trainer = build_trainer(app, c, &spec, rt)?;
    if trainer.epoch() == 0
        && let Some(w) = trainer.stiffness_warning()
    {
        warn!(job = %c.job.id, code = %w.code, "{}", w.message);
    }
    let every = app.settings.worker.checkpoint_epochs();
    let mut checkpointed = trainer.epoch();
    let lost = || {
        flags.lost.store(true, Ordering::Relaxed);
        Ok(Outcome::LeaseLost)
    };
    while !trainer.finished() {
        if flags.shutdown.load(Ordering::Relaxed) {
            return release(app, c, &trainer, checkpointed, rt);
        }
        let m = trainer.run_epoch(&flags.cancel)?;
        app.telemetry.epochs_trained.fetch_add(1, Ordering::Relaxed);
        let row = Metric {
            epoch: m.epoch as i64,
            train_loss: m.train_loss,
            val_loss: m.val_loss,
            val_horizon_loss: m.val_horizon_loss,
            seconds: m.seconds,
        };
        if !rt.block_on(app.store.record_epoch(c, &row, trainer.best_val_loss()))? {
            return lost();
        }
        if trainer.epoch() % every == 0 && !trainer.finished() {
            let bytes = trainer.checkpoint().to_bytes();
            let epoch = trainer.epoch() as i64;
            if !rt.block_on(app.store.save_checkpoint(c, epoch, &bytes))? {
                return lost();
            }
            checkpointed = trainer.epoch();
        }
    }
    match rt.block_on(store_model(app, c, &spec, &trainer))? {
        Some(id) => Ok(Outcome::Succeeded(id)),
        None => lost(),
    }
}

/// A new trainer for the job, or the one its last checkpoint holds (refused as corrupt when
/// the checkpoint claims an epoch past the job's last).
fn build_trainer(app: &App, c: &Claimed, spec: &JobSpec, rt: &Handle) -> Result<Trainer> {
    let load = |id: &str| -> Result<crate::data::Dataset> {
        rt.block_on(app.store.load_dataset(id))?
            .ok_or_else(|| Error::invalid("dataset_id", format!("dataset {id} was deleted")))
    };
    let data = load(&spec.dataset_id)?;
    let val = spec
        .validation_dataset_id
        .as_deref()
        .map(load)
        .transpose()?;
    let device = backend::device(Backend::Flex, Precision::F32)?.autodiff();
    let trainer = match rt.block_on(app.store.load_checkpoint(&c.job.id))? {
        Some((epoch, _)) if epoch > c.job.epochs => Err(Error::corrupt(
            "checkpoint",
            format!(
                "its epoch {epoch} is past the job's {} epochs",
                c.job.epochs
            ),
        )),
        Some((epoch, bytes)) => {
            info!(job = %c.job.id, epoch, "resuming from checkpoint");
            let state = TrainState::from_bytes(&bytes)?;
            Trainer::resume(state, &data, val.as_ref(), &device)
        }
        None => Trainer::new(
            &spec.model_name,
            spec.spec.clone(),
            &spec.init,
            &data,
            val.as_ref(),
            spec.training.clone(),
            &device,
        ),
    }?;
    trainer.with_threads(app.settings.worker.job_threads())
}

/// The trained model and the job's success in one fenced transaction; None when the lease
/// was lost. A model file with a non-finite number is an error instead.
async fn store_model(
    app: &App,
    c: &Claimed,
    spec: &JobSpec,
    trainer: &Trainer,
) -> Result<Option<String>> {
    let file = trainer.model_file();
    let report = file.report.as_ref().expect("trained files carry a report");
    let warnings = report.warnings.clone();
    let report = serde_json::to_string(report).expect("json");
    let spec_json = serde_json::to_string(&file.config.spec).expect("json");
    let model = NewModel {
        name: spec.display_name(),
        n: file.config.n as i64,
        m: file.config.m as i64,
        dt: file.config.dt,
        spec: &spec_json,
        report: &report,
        file: &file.to_bytes()?,
    };
    app.store.finish_job(c, model, &warnings).await
}

/// Shutdown: checkpoint at this epoch end (unless just taken) and give the job back.
fn release(
    app: &App,
    c: &Claimed,
    trainer: &Trainer,
    checkpointed: usize,
    rt: &Handle,
) -> Result<Outcome> {
    if trainer.epoch() > checkpointed {
        rt.block_on(app.store.save_checkpoint(
            c,
            trainer.epoch() as i64,
            &trainer.checkpoint().to_bytes(),
        ))?;
    }
    rt.block_on(app.store.release_job(c))?;
    Ok(Outcome::Released)
}
