//! The core the adapters call (REST, gRPC, workers, CLI): datasets, jobs, models.
//! Handlers translate; every rule lives here or below.

pub mod datasets;
pub mod events;
pub mod inference;
mod job_cost;
pub mod jobs;
pub mod memory;
pub mod models;
pub mod requests;
pub mod settings;
pub mod telemetry;
pub mod templates;
pub mod uploads;
pub mod views;

use std::sync::Arc;

pub use settings::{Settings, WorkerSettings};

use crate::error::Result;
use crate::store::Store;

/// How long a `/metrics` scrape waits for the database's job counts.
pub const JOB_COUNTS_WAIT: std::time::Duration = std::time::Duration::from_secs(1);

/// The shared core. Cheap to clone.
#[derive(Clone)]
pub struct App {
    /// The store is the core's own: adapters go through `App` (ARCHITECTURE.md).
    pub(crate) store: Store,
    pub settings: Arc<Settings>,
    pub telemetry: Arc<telemetry::Telemetry>,
    /// Trained models loaded for inference, by model id.
    pub models: Arc<inference::ModelCache>,
    /// Shared progress pollers of followed jobs.
    pub feeds: Arc<events::Feeds>,
    pub all_jobs: Arc<events::AllJobs>,
    /// Admission of short inference calls (see `Settings::max_short_calls`).
    pub short_calls: Arc<inference::Heavy>,
    /// Admission of long inference calls (see `Settings::max_heavy_calls`).
    pub long_calls: Arc<inference::Heavy>,
    /// Admission of rollout chunks, a share of its own.
    pub streaming: Arc<inference::Heavy>,
    /// Memory for request bodies and datasets being read (`--max-inflight-body-mb`).
    pub memory: Arc<memory::MemoryBudget>,
    /// Datasets loaded for reads, shared by the requests reading each at once.
    pub reads: Arc<inference::reads::SharedReads>,
}

impl App {
    /// Ready when the database (and the object store, with `--blobs`) answer, within seconds.
    pub async fn ready(&self) -> Result<()> {
        self.store.ping().await
    }

    /// The Prometheus exposition text: this process's counters and the jobs by state. The
    /// counts are read anew for [`JOB_COUNTS_WAIT`] at most (one read in flight per process,
    /// not cancelled by a scrape that stops waiting); past it, the last counts read are shown
    /// with their age, so that a scrape answers while the database does not.
    pub async fn metrics_text(&self) -> String {
        let app = self.clone();
        let read = tokio::spawn(async move {
            let telemetry = &app.telemetry;
            let Ok(_reading) = telemetry.counting.try_lock() else {
                return;
            };
            match app.store.job_counts().await {
                Ok(jobs) => telemetry.set_job_counts(jobs),
                Err(e) => tracing::warn!(error = %e, "reading the job counts failed"),
            }
        });
        let _ = tokio::time::timeout(JOB_COUNTS_WAIT, read).await;
        self.telemetry.render()
    }

    pub fn new(store: Store, settings: Settings) -> Self {
        Self {
            store,
            telemetry: Arc::default(),
            models: Arc::default(),
            feeds: Arc::default(),
            all_jobs: Arc::default(),
            short_calls: Arc::new(inference::Heavy::new(
                settings.max_short_calls,
                "--max-short-calls",
                "short",
            )),
            long_calls: Arc::new(inference::Heavy::new(
                settings.max_heavy_calls,
                "--max-heavy-calls",
                "long",
            )),
            streaming: Arc::new(inference::Heavy::streaming(
                settings.max_heavy_calls,
                "--max-heavy-calls",
            )),
            memory: Arc::new(memory::MemoryBudget::new(
                settings.max_inflight_body_bytes(),
            )),
            reads: Arc::default(),
            settings: Arc::new(settings),
        }
    }
}

/// Runs a store write to its end even if the request that started it goes away: a write of
/// large bytes counts a reference to their object before it writes the row, and a future
/// dropped in between would leave the count too high (the object never collected).
async fn detached<T: Send + 'static>(
    write: impl std::future::Future<Output = Result<T>> + Send + 'static,
) -> Result<T> {
    tokio::spawn(write)
        .await
        .map_err(|e| crate::error::Error::Internal(format!("a store write failed: {e}")))?
}

/// Keyset pagination: an opaque token carrying the last row's position.
pub mod paging {
    use base64::Engine;
    use base64::engine::general_purpose::URL_SAFE_NO_PAD;

    use crate::error::{Error, Result};

    pub const DEFAULT_SIZE: i64 = 50;
    pub const MAX_SIZE: i64 = 1000;

    pub fn size(page_size: Option<i64>) -> Result<i64> {
        match page_size {
            None => Ok(DEFAULT_SIZE),
            Some(s) if (1..=MAX_SIZE).contains(&s) => Ok(s),
            Some(s) => Err(Error::invalid(
                "page_size",
                format!("must be between 1 and {MAX_SIZE}, got {s}"),
            )),
        }
    }

    pub fn encode(kind: &str, seq: i64) -> String {
        URL_SAFE_NO_PAD.encode(format!("{kind}:{seq}"))
    }

    /// The position in a token made by `encode` for the same kind of listing.
    pub fn decode(kind: &str, token: Option<&str>) -> Result<Option<i64>> {
        let Some(token) = token.filter(|t| !t.is_empty()) else {
            return Ok(None);
        };
        let bad = || Error::invalid("page_token", "is not a token from this listing");
        let bytes = URL_SAFE_NO_PAD.decode(token).map_err(|_| bad())?;
        let text = String::from_utf8(bytes).map_err(|_| bad())?;
        let (k, seq) = text.split_once(':').ok_or_else(bad)?;
        if k != kind {
            return Err(bad());
        }
        seq.parse::<i64>().map(Some).map_err(|_| bad())
    }

    /// The token for the next page when rows remain after `items` (a page may end before
    /// its count at the store's byte limit).
    pub fn after<T>(
        kind: &str,
        items: &[T],
        more: bool,
        seq: impl Fn(&T) -> i64,
    ) -> Option<String> {
        more.then(|| items.last().map(|x| encode(kind, seq(x))))
            .flatten()
    }

    /// The token for the next page, when this page was full.
    pub fn next<T>(kind: &str, items: &[T], size: i64, seq: impl Fn(&T) -> i64) -> Option<String> {
        (items.len() as i64 == size)
            .then(|| items.last().map(|x| encode(kind, seq(x))))
            .flatten()
    }
}
