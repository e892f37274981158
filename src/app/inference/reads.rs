//! Datasets loaded for reads (replays, evaluations): their memory admitted under the in-flight
//! budget before they are loaded, and loaded once for all the requests that read one at the
//! same time. Before, a hundred replays of one 100 MB dataset each loaded it first and were
//! refused by their cost only afterwards.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use tokio::sync::{OnceCell, OwnedSemaphorePermit};

use crate::app::App;
use crate::data::Dataset;
use crate::error::{Error, Result};
use crate::model::ModelConfig;
use crate::records::DatasetInfo;

/// A dataset loaded for reads, holding its share of the memory budget while it is loaded.
struct Loaded {
    ds: Dataset,
    _memory: OwnedSemaphorePermit,
}

/// One per dataset being read: the first request loads it, the ones that join before the
/// last of them is done read the same copy.
type Slot = Arc<OnceCell<Loaded>>;

#[derive(Default)]
pub struct SharedReads {
    slots: Mutex<HashMap<String, Slot>>,
}

/// A request's hold on a dataset it reads; the last hold of a dataset frees it.
pub struct Reading {
    slot: Option<Slot>,
    id: String,
    reads: Arc<SharedReads>,
}

impl Reading {
    fn join(reads: &Arc<SharedReads>, id: &str) -> Self {
        let mut slots = reads.slots.lock().expect("reads lock");
        let slot = slots.entry(id.to_string()).or_default().clone();
        Self {
            slot: Some(slot),
            id: id.to_string(),
            reads: reads.clone(),
        }
    }

    fn cell(&self) -> &Slot {
        self.slot.as_ref().expect("held until dropped")
    }

    /// The dataset (only a loaded `Reading` is handed out).
    pub fn ds(&self) -> &Dataset {
        &self.cell().get().expect("loaded before handed out").ds
    }
}

impl Drop for Reading {
    fn drop(&mut self) {
        let mut slots = self.reads.slots.lock().expect("reads lock");
        // Let go under the lock that joining takes: the count read next is exact.
        drop(self.slot.take());
        if slots
            .get(&self.id)
            .is_some_and(|s| Arc::strong_count(s) == 1)
        {
            slots.remove(&self.id);
        }
    }
}

/// Bytes loading a dataset takes: its arrays three times (the bytes as the store hands them
/// over, their copy, and the arrays decoded from them are alive together while it loads),
/// counting a step per transition, which a dataset of its own Δt's carries (the row does not
/// say whether it does).
pub fn load_cost(info: &DatasetInfo) -> usize {
    let (nq, nv, m) = (info.nq(), info.nv(), info.m.max(0) as usize);
    let values = (info.count.max(0) as usize).saturating_mul(2 * (nq + nv) + m + 1);
    values.saturating_mul(3 * 8)
}

impl App {
    /// The row of a dataset a model is to read (a replay, an evaluation): 404 when it does
    /// not exist, 400 naming `dataset_id` when its shape is not the model's (n, m).
    pub(crate) async fn dataset_for_model(
        &self,
        id: &str,
        model: &ModelConfig,
    ) -> Result<DatasetInfo> {
        let info: DatasetInfo = (self.store.get_dataset(id).await?)
            .ok_or_else(|| Error::NotFound(format!("dataset {id}")))?
            .into();
        let (nq, nv, m) = (model.nq(), model.nv(), model.m);
        let (dq, dv, dm) = (info.nq(), info.nv(), info.m as usize);
        if (dq, dv, dm) != (nq, nv, m) {
            return Err(Error::invalid(
                "dataset_id",
                format!(
                    "dataset {id} has nq = {dq}, nv = {dv}, m = {dm}; the model has nq = {nq}, \
                     nv = {nv}, m = {m}"
                ),
            ));
        }
        Ok(info)
    }

    /// The arrays of the dataset `info` describes, for a read: the copy other requests are
    /// reading already, or loaded now under the memory budget (503 with `Retry-After` while
    /// its share is not free; 413 for a dataset that could never fit the budget).
    pub(crate) async fn read_dataset(&self, info: &DatasetInfo) -> Result<Reading> {
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
        let reading = Reading::join(&self.reads, &info.id);
        let load = async {
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
            Ok::<_, Error>(Loaded {
                ds,
                _memory: memory,
            })
        };
        reading.cell().get_or_try_init(|| load).await?;
        Ok(reading)
    }
}
