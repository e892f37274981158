//! Training workers over the persistent queue (docs/storage.md#leases-and-heartbeats): claim a job, hold its lease
//! with heartbeats, train on a blocking thread, record each epoch, checkpoint at epoch ends,
//! and end the job (or give it back on shutdown). Every write is fenced by (job, attempt).

mod pool;
mod train;

pub use pool::{Pool, Stopped};

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use tokio::runtime::Handle;
use tokio::sync::watch;
use tokio::task::JoinHandle;
use tracing::{info, warn};

use crate::app::App;
use crate::backoff::Backoff;
use crate::error::{Error, Result};
use crate::records::JobState;
use crate::store::{Claimed, Lease};

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
        tokio::task::spawn_blocking(move || train::train_job(&app, &claimed, &flags, &handle))
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
