//! Datasets loaded for reads (replays, evaluations): their memory admitted under the in-flight
//! budget before they are loaded, and loaded once however many requests read one at the same
//! time. Before, a hundred replays of one 100 MB dataset each loaded it first and were refused
//! by their cost only afterwards.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, Weak};

use tokio::sync::OwnedSemaphorePermit;

use crate::app::App;
use crate::data::Dataset;
use crate::error::{Error, Result};
use crate::records::DatasetInfo;

/// A dataset loaded for reads; it holds its share of the memory budget while any request
/// reads it.
pub struct Loaded {
    pub ds: Dataset,
    _memory: OwnedSemaphorePermit,
}

/// One per dataset being read: the request that loads it holds the lock while it loads, and
/// the requests behind it find it loaded.
type Slot = Arc<tokio::sync::Mutex<Weak<Loaded>>>;

#[derive(Default)]
pub struct SharedReads {
    slots: Mutex<HashMap<String, Slot>>,
}

impl SharedReads {
    fn slot(&self, id: &str) -> Slot {
        let mut slots = self.slots.lock().expect("reads lock");
        // A slot nobody waits on and whose dataset nobody reads goes.
        slots.retain(|_, s| {
            Arc::strong_count(s) > 1 || s.try_lock().is_ok_and(|w| w.strong_count() > 0)
        });
        slots.entry(id.to_string()).or_default().clone()
    }
}

/// Bytes loading a dataset takes: its arrays twice (the stored bytes and the arrays decoded
/// from them are both alive while it loads).
pub fn load_cost(info: &DatasetInfo) -> usize {
    let (n, m) = (info.n.max(0) as usize, info.m.max(0) as usize);
    let values = (info.count.max(0) as usize).saturating_mul(4 * n + m);
    values.saturating_mul(2 * 8)
}

impl App {
    /// The arrays of the dataset `info` describes, for a read: the copy other requests are
    /// reading already, or loaded now under the memory budget (503 with `Retry-After` while
    /// its share is not free; 413 for a dataset that could never fit it).
    pub(crate) async fn read_dataset(&self, info: &DatasetInfo) -> Result<Arc<Loaded>> {
        let cost = load_cost(info);
        let budget = self.settings.max_inflight_body_mb;
        if cost > self.settings.max_inflight_body_bytes() {
            return Err(Error::ResourceExhausted(format!(
                "reading dataset {} takes {} MiB, more than the in-flight budget \
                 (--max-inflight-body-mb {budget})",
                info.id,
                cost >> 20
            )));
        }
        let slot = self.reads.slot(&info.id);
        let mut held = slot.lock().await;
        if let Some(loaded) = held.upgrade() {
            return Ok(loaded);
        }
        let memory = self.memory.try_reserve(cost).ok_or_else(|| {
            Error::Busy(format!(
                "reading dataset {} takes {} MiB and the in-flight budget \
                 (--max-inflight-body-mb {budget}) is in use: retry in a moment",
                info.id,
                cost >> 20
            ))
        })?;
        let ds = (self.store.load_dataset(&info.id).await?)
            .ok_or_else(|| Error::NotFound(format!("dataset {}", info.id)))?;
        let loaded = Arc::new(Loaded {
            ds,
            _memory: memory,
        });
        *held = Arc::downgrade(&loaded);
        Ok(loaded)
    }
}
