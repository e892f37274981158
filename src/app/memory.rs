//! One memory budget (`--max-inflight-body-mb`) for what requests hold while they are served:
//! request bodies being read and parsed (REST's admission reserves each before reading it)
//! and datasets loaded for reads (replays and evaluations, `inference/reads.rs`). A request
//! whose share is not free now is refused with 503 and `Retry-After`, never queued: memory is
//! bounded under any concurrency, not only per request.

use std::sync::Arc;

use tokio::sync::{OwnedSemaphorePermit, Semaphore};

/// Budget units: 1 MiB each (a semaphore counts in u32).
const UNIT: usize = 1 << 20;

pub struct MemoryBudget {
    permits: Arc<Semaphore>,
}

impl MemoryBudget {
    pub fn new(bytes: usize) -> Self {
        let units = (bytes / UNIT).clamp(1, Semaphore::MAX_PERMITS);
        Self {
            permits: Arc::new(Semaphore::new(units)),
        }
    }

    /// `cost` bytes of the budget until the permit drops, if they are free now.
    pub fn try_reserve(&self, cost: usize) -> Option<OwnedSemaphorePermit> {
        let units = u32::try_from(cost.div_ceil(UNIT).max(1)).unwrap_or(u32::MAX);
        self.permits.clone().try_acquire_many_owned(units).ok()
    }
}
