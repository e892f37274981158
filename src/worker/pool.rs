//! A process's training workers, started and stopped together: `graybox serve` and `graybox
//! worker` both run one pool. Each worker holds leases under its own id, logged at start, so
//! that a job's holder can be found among many processes and machines.

use std::future::Future;
use std::time::Duration;

use tokio::sync::watch;
use tokio::task::JoinSet;
use tracing::{info, warn};

use crate::app::App;

/// How a pool's stop ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stopped {
    /// Every worker gave its job back at an epoch end, checkpointed.
    Clean,
    /// The grace ran out first: `released` jobs went back to the queue from their last
    /// checkpoint, and whatever was still computing was abandoned.
    Forced { released: u64 },
}

/// Giving held jobs back on a forced stop waits this long for the database at most; past it
/// their leases expire instead (and the jobs are reclaimed then).
const RELEASE_TIMEOUT: Duration = Duration::from_secs(5);

pub struct Pool {
    tasks: JoinSet<()>,
    /// The workers' lease owners: a forced stop gives back what they hold.
    owners: Vec<String>,
}

impl Pool {
    /// `--workers` workers claiming from `app`'s store until `stop` turns true.
    pub fn spawn(app: &App, stop: &watch::Receiver<bool>) -> Self {
        let process = crate::store::new_id("proc");
        let owners: Vec<String> = (0..app.settings.worker.workers)
            .map(|i| format!("{process}-w{i}"))
            .collect();
        let mut tasks = JoinSet::new();
        for owner in &owners {
            tasks.spawn(super::run_worker(app.clone(), owner.clone(), stop.clone()));
        }
        if !owners.is_empty() {
            info!(worker_ids = ?owners, pid = std::process::id(), "training workers started");
        }
        Self { tasks, owners }
    }

    /// Resolves when a worker ended on its own (only a panic does: a worker returns when
    /// stopped); never for an empty pool.
    pub async fn died(&mut self) -> String {
        match self.tasks.join_next().await {
            Some(Err(e)) => format!("a training worker failed: {e}"),
            Some(Ok(())) => "a training worker stopped".into(),
            None => std::future::pending().await,
        }
    }

    /// Waits for the workers (told to stop by the pool's `stop` channel) to give their jobs
    /// back at epoch ends, checkpointed; when `force` resolves first, drops them and gives
    /// what they hold back at once, from the last checkpoint.
    pub async fn stop_by<F: Future<Output = ()> + Unpin>(
        mut self,
        app: &App,
        force: &mut F,
    ) -> Stopped {
        let forced = tokio::select! {
            biased;
            () = force => true,
            () = async { while self.tasks.join_next().await.is_some() {} } => false,
        };
        if !forced {
            return Stopped::Clean;
        }
        self.tasks.abort_all();
        Stopped::Forced {
            released: self.release(app).await,
        }
    }

    /// Gives back the jobs these workers hold, at once and from their last checkpoint (see
    /// `Store::release_owned`); how many.
    async fn release(&self, app: &App) -> u64 {
        let held = async {
            let mut released = 0;
            for owner in &self.owners {
                released += app.store.release_owned(owner).await?;
            }
            Ok::<u64, crate::error::Error>(released)
        };
        match tokio::time::timeout(RELEASE_TIMEOUT, held).await {
            Ok(Ok(n)) => n,
            Ok(Err(e)) => {
                warn!(error = %e, "giving jobs back failed; their leases will expire");
                0
            }
            Err(_) => {
                warn!("giving jobs back timed out; their leases will expire");
                0
            }
        }
    }
}
