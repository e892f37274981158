//! Following a job's progress: one store poller per followed job, shared by every subscriber
//! (800 SSE clients on one job once cost a full core, each polling the store itself). The
//! poller reads the store, so it follows jobs any process's workers run; it stops when its
//! last subscriber leaves or the job reaches a final state.

use std::collections::HashMap;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::sync::{broadcast, watch};

use super::App;
use crate::error::Result;
use crate::records::{Job, Metric};

/// How often a followed job is read from the store.
pub const POLL: Duration = Duration::from_millis(200);

/// A job as last read, with every epoch's metrics so far.
#[derive(Debug, Clone)]
pub struct JobProgress {
    pub job: Job,
    pub metrics: Arc<Vec<Metric>>,
}

/// The live pollers by job id (each entry a receiver kept to hand out clones).
#[derive(Default)]
pub struct Feeds {
    live: Mutex<HashMap<String, watch::Receiver<JobProgress>>>,
}

/// Every job's changes (GET /v1/events): one poller for all subscribers, started by the
/// first and stopped when the last has gone.
#[derive(Default)]
pub struct AllJobs {
    tx: Mutex<Option<broadcast::Sender<Job>>>,
}

/// Changes a subscriber may fall behind by before it is told to re-read the list.
const ALL_JOBS_BACKLOG: usize = 1024;

impl Feeds {
    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<String, watch::Receiver<JobProgress>>> {
        self.live.lock().expect("feeds lock")
    }
}

impl App {
    /// A receiver of every job's changes: each job as it is after a change of state, epoch
    /// or losses, and every job submitted after the call.
    pub async fn follow_all_jobs(&self) -> Result<broadcast::Receiver<Job>> {
        if let Some(tx) = self.all_jobs.tx.lock().expect("all-jobs lock").as_ref() {
            return Ok(tx.subscribe());
        }
        // The newest job is read before the call returns, not by the poller when it first
        // runs: a job submitted in between and finished before the first poll would have
        // been neither new nor active to it, and never sent.
        let after = self.store.max_job_seq().await?;
        let mut slot = self.all_jobs.tx.lock().expect("all-jobs lock");
        if let Some(tx) = slot.as_ref() {
            return Ok(tx.subscribe());
        }
        let (tx, rx) = broadcast::channel(ALL_JOBS_BACKLOG);
        *slot = Some(tx.clone());
        tokio::spawn(poll_all(self.clone(), tx, after));
        Ok(rx)
    }

    /// A receiver of `id`'s progress, joining the job's poller or starting it.
    pub async fn follow_job(&self, id: &str) -> Result<watch::Receiver<JobProgress>> {
        if let Some(rx) = self
            .feeds
            .lock()
            .get(id)
            .filter(|rx| rx.has_changed().is_ok())
        {
            return Ok(rx.clone());
        }
        let first = self.read_progress(id, None).await?;
        let mut live = self.feeds.lock();
        if let Some(rx) = live.get(id).filter(|rx| rx.has_changed().is_ok()) {
            return Ok(rx.clone());
        }
        let (tx, rx) = watch::channel(first);
        live.insert(id.to_string(), rx.clone());
        tokio::spawn(poll(self.clone(), id.to_string(), tx));
        Ok(rx)
    }

    /// The job and its metrics, appending to `prev`'s.
    async fn read_progress(&self, id: &str, prev: Option<&JobProgress>) -> Result<JobProgress> {
        self.telemetry.job_polls.fetch_add(1, Ordering::Relaxed);
        let job = self.job(id).await?;
        let last = prev.and_then(|p| p.metrics.last()).map_or(0, |m| m.epoch);
        let new = self.metrics_after(id, last).await?;
        let metrics = match prev {
            Some(p) if new.is_empty() => p.metrics.clone(),
            Some(p) => Arc::new(p.metrics.iter().cloned().chain(new).collect()),
            None => Arc::new(new),
        };
        Ok(JobProgress { job, metrics })
    }
}

async fn poll(app: App, id: String, tx: watch::Sender<JobProgress>) {
    loop {
        let done = tx.borrow().job.state.is_final();
        // One receiver is the map's own: with no other, nobody is listening.
        if done || tx.receiver_count() <= 1 {
            break;
        }
        tokio::time::sleep(POLL).await;
        let prev = tx.borrow().clone();
        match app.read_progress(&id, Some(&prev)).await {
            Ok(p) if p.job != prev.job || p.metrics.len() != prev.metrics.len() => {
                tx.send_replace(p);
            }
            Ok(_) => {}
            Err(e) => tracing::debug!(job = %id, error = %e, "reading job progress failed"),
        }
    }
    let mut live = app.feeds.lock();
    if live
        .get(&id)
        .is_some_and(|rx| rx.same_channel(&tx.subscribe()))
    {
        live.remove(&id);
    }
}

/// Reads what changed every `POLL` and sends it; stops when nobody listens (checked under the
/// lock subscribers take, so none joins a poller that is stopping).
async fn poll_all(app: App, tx: broadcast::Sender<Job>, mut after: i64) {
    let mut seen: HashMap<String, Job> = HashMap::new();
    loop {
        tokio::time::sleep(POLL).await;
        {
            let mut slot = app.all_jobs.tx.lock().expect("all-jobs lock");
            if tx.receiver_count() == 0 {
                *slot = None;
                return;
            }
        }
        app.telemetry.job_polls.fetch_add(1, Ordering::Relaxed);
        let rows = match app.store.watched_jobs(after).await {
            Ok(rows) => rows,
            Err(e) => {
                tracing::debug!(error = %e, "reading jobs for /v1/events failed");
                continue;
            }
        };
        let mut now: HashMap<String, Job> = HashMap::new();
        for r in rows {
            after = after.max(r.seq);
            let job = Job::from(r);
            if seen.get(&job.id) != Some(&job) {
                let _ = tx.send(job.clone());
            }
            now.insert(job.id.clone(), job);
        }
        // Jobs that were active and are no longer: read their final state.
        for (id, before) in seen.iter().filter(|(id, _)| !now.contains_key(*id)) {
            if let Ok(job) = app.job(id).await
                && job != *before
            {
                let _ = tx.send(job);
            }
        }
        seen = now
            .into_iter()
            .filter(|(_, j)| !j.state.is_final())
            .collect();
    }
}
