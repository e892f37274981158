//! Checkpoints: the state a run keeps at an epoch boundary, taking it and resuming from it.
//! Kept side by side because a resumed run must equal an uninterrupted one: what `checkpoint`
//! writes, `resume` must restore in full; and the data fingerprint makes a resume on other
//! data fail instead of quietly training on something else.

use std::collections::BTreeMap;

use burn::tensor::Device;
use serde::{Deserialize, Serialize};

use std::sync::Arc;

use super::{RunData, Trainer};
use crate::data::Dataset;
use crate::error::{Error, Result};
use crate::model::params_io::{NamedArray, import};
use crate::model::report::EpochMetrics;
use crate::model::{Model, ModelConfig};
use crate::rng::Rng;
use crate::train::adam::{Adam, AdamState};
use crate::train::setup::{TrainConfig, split_data};

/// Everything needed to continue a run from an epoch boundary.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TrainState {
    pub model_name: String,
    pub config: ModelConfig,
    pub train: TrainConfig,
    /// Epochs completed.
    pub epoch: usize,
    pub params: Vec<NamedArray>,
    pub adam: AdamState,
    pub rng: Rng,
    pub best_epoch: usize,
    pub best_loss: f64,
    pub best_params: Vec<NamedArray>,
    pub history: Vec<EpochMetrics>,
    pub stale_epochs: usize,
    pub train_seconds: f64,
    pub samples_seen: u64,
    /// Identifies the training and validation data, so that a resume on other data fails.
    pub data_fingerprint: u64,
    /// The used physical values at the start, for the training checks (absent in
    /// checkpoints of earlier versions: that check is then skipped).
    #[serde(default)]
    pub initial_physical: Option<BTreeMap<String, f64>>,
    /// Shards per batch (train/shards.rs): the thread count the run started with. A resumed
    /// run splits its batches the same way, whatever threads it has (1 in checkpoints of
    /// earlier versions, which trained on one thread).
    #[serde(default = "one")]
    pub shards: usize,
    /// Which member of an ensemble this is (`train::ensemble`): its seed and bootstrap
    /// resample derive from it. 0, a single model's, is left out.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub member: usize,
}

fn is_zero(k: &usize) -> bool {
    *k == 0
}

fn one() -> usize {
    1
}

impl TrainState {
    pub fn to_bytes(&self) -> Vec<u8> {
        serde_json::to_vec(self).expect("train state serializes")
    }

    pub fn from_bytes(bytes: &[u8]) -> Result<Self> {
        serde_json::from_slice(bytes).map_err(|e| Error::corrupt("checkpoint", e))
    }
}

/// FNV-1a over the bits of every value, train then validation.
pub(super) fn fingerprint(train: &Dataset, val: Option<&Dataset>) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for ds in std::iter::once(train).chain(val) {
        let arrays = [&ds.q, &ds.qdot, &ds.u, &ds.q_next, &ds.qdot_next];
        let steps = ds.steps.iter().flatten();
        for v in arrays.into_iter().flatten().chain([&ds.dt]).chain(steps) {
            for b in v.to_bits().to_le_bytes() {
                h = (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01B3);
            }
        }
    }
    h
}

impl Trainer {
    /// Continues a run from a checkpoint, with the same data as the original run.
    pub fn resume(
        state: TrainState,
        data: &Dataset,
        val: Option<&Dataset>,
        device: &Device,
    ) -> Result<Self> {
        let (train_ds, val_ds) = split_data(data, val, (&state.train, &state.config.spec))?;
        let run = RunData::new(&train_ds, val_ds.as_ref(), &state.train, &state.config);
        Self::resume_on(state, Arc::new(run), device)
    }

    /// Continues member `state.member` of a run on `data`, the run's sets.
    pub(in crate::train) fn resume_on(
        state: TrainState,
        data: Arc<RunData>,
        device: &Device,
    ) -> Result<Self> {
        if data.fingerprint != state.data_fingerprint {
            return Err(Error::invalid(
                "checkpoint",
                "was taken on other data than the data given",
            ));
        }
        let skeleton = Model::init(state.config.clone(), None, state.train.seed, device)?;
        let params = import(skeleton.params, &state.params, device)?;
        let model = Model::from_parts(state.config.clone(), params, device);
        let adam = Adam::from_state(&state.adam, &device.clone().without_autodiff());
        // The live values are the model's and Adam's from here on (see `Trainer::state`).
        let state = TrainState {
            params: vec![],
            adam: AdamState::default(),
            shards: state.shards.max(1),
            ..state
        };
        Ok(Self::start(state, model, adam, data))
    }

    pub fn checkpoint(&self) -> TrainState {
        TrainState {
            params: self.model.params.export(),
            adam: self.adam.state(),
            ..self.state.clone()
        }
    }
}
