//! The training loop (design.md §2): mean one-step prediction loss, Adam, per-epoch
//! validation, early stopping that keeps the best-validation parameters, and checkpoints at
//! epoch boundaries from which a resumed run equals an uninterrupted one.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use burn::tensor::{Device, Tensor, TensorData};
use serde::{Deserialize, Serialize};

use super::adam::{Adam, AdamState};
use super::setup::{TrainConfig, prepare, split_data};
use super::shards::{self, ParamGrads};
use super::warnings::{RunSummary, training_warnings, zero_acceleration_loss};
use crate::data::Dataset;
use crate::error::{Error, Result};
use crate::model::file::ModelFile;
use crate::model::params_io::{NamedArray, import};
use crate::model::report::{EpochMetrics, TrainReport, identifiable, used_physical};
use crate::model::spec::ModelSpec;
use crate::model::{Model, ModelConfig};
use crate::rng::Rng;

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

/// One set of transitions as host arrays: x = [q, q̇], u, target x'.
struct HostData {
    x: Vec<f64>,
    u: Vec<f64>,
    y: Vec<f64>,
    count: usize,
    n2: usize,
    m: usize,
}

impl HostData {
    fn new(ds: &Dataset) -> Self {
        let (x, y) = ds.states();
        Self {
            x,
            u: ds.u.clone(),
            y,
            count: ds.count(),
            n2: 2 * ds.n,
            m: ds.m,
        }
    }

    fn gather(&self, idx: &[usize], device: &Device) -> (Tensor<2>, Tensor<2>, Tensor<2>) {
        let take = |a: &[f64], w: usize| -> Tensor<2> {
            let v: Vec<f64> = idx
                .iter()
                .flat_map(|&i| a[i * w..(i + 1) * w].iter().copied())
                .collect();
            Tensor::from_data(TensorData::new(v, [idx.len(), w]), device)
        };
        (
            take(&self.x, self.n2),
            take(&self.u, self.m),
            take(&self.y, self.n2),
        )
    }
}

/// Mean loss of `model` over `data`, in chunks of at most 4096 rows, each split into
/// `shards` pieces run on `pool`, without autodiff.
fn mean_loss(
    model: &Model,
    data: &HostData,
    shards: usize,
    pool: Option<&rayon::ThreadPool>,
) -> f64 {
    let device = model.device();
    let min_rows = shards::min_shard_rows(&model.config.spec);
    let idx: Vec<usize> = (0..data.count).collect();
    let total: f64 = idx
        .chunks(4096)
        .flat_map(|c| {
            let pieces = shards::split(c, shards::shard_count(shards, c.len(), min_rows));
            shards::map_pieces(&pieces, pool, |p| {
                let (x, u, y) = data.gather(p, &device);
                scalar(model.loss_sum(x, u, y))
            })
        })
        .sum();
    total / data.count as f64
}

fn scalar(t: Tensor<1>) -> f64 {
    t.into_data().iter::<f64>().next().unwrap_or(f64::NAN)
}

/// The mean loss of a trained model on a dataset (the `eval` command).
pub fn evaluate(model: &Model, ds: &Dataset) -> Result<f64> {
    if ds.n != model.config.n || ds.m != model.config.m {
        return Err(Error::invalid(
            "data",
            format!(
                "dataset has n = {}, m = {} but the model has n = {}, m = {}",
                ds.n, ds.m, model.config.n, model.config.m
            ),
        ));
    }
    Ok(mean_loss(&model.valid(), &HostData::new(ds), 1, None))
}

pub struct Trainer {
    model_name: String,
    model: Model,
    adam: Adam,
    cfg: TrainConfig,
    rng: Rng,
    epoch: usize,
    train: HostData,
    val: Option<HostData>,
    best_epoch: usize,
    best_loss: f64,
    best_params: Vec<NamedArray>,
    history: Vec<EpochMetrics>,
    stale_epochs: usize,
    train_seconds: f64,
    samples_seen: u64,
    fingerprint: u64,
    /// The zero-acceleration loss on the set that picks the best epoch (validation, else
    /// training), for the training checks.
    baseline: f64,
    initial_physical: Option<BTreeMap<String, f64>>,
    /// Shards per batch (see `TrainState::shards`) and the threads that run them.
    shards: usize,
    pool: Option<rayon::ThreadPool>,
}

/// The physical values the model's white-box parts use, by name.
fn used_physical_values(model: &Model) -> Option<BTreeMap<String, f64>> {
    let t = model.config.template()?;
    Some(used_physical(
        t,
        &model.white_box_parts(),
        &model.physical_values()?,
    ))
}

/// FNV-1a over the bits of every value, train then validation.
fn fingerprint(train: &Dataset, val: Option<&Dataset>) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for ds in std::iter::once(train).chain(val) {
        let arrays = [&ds.q, &ds.qdot, &ds.u, &ds.q_next, &ds.qdot_next];
        for v in arrays.into_iter().flatten().chain([&ds.dt]) {
            for b in v.to_bits().to_le_bytes() {
                h = (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01B3);
            }
        }
    }
    h
}

impl Trainer {
    /// A new run. Without `val`, `cfg.val_fraction` of `data` is held out (seeded).
    /// `device` must be an autodiff device.
    pub fn new(
        model_name: &str,
        spec: ModelSpec,
        init: &[(String, f64)],
        data: &Dataset,
        val: Option<&Dataset>,
        cfg: TrainConfig,
        device: &Device,
    ) -> Result<Self> {
        let (config, physical, train_ds, val_ds) = prepare(&spec, init, data, val, &cfg)?;
        let model = Model::init(config, physical, cfg.seed, device)?;
        Ok(Self::start(
            model_name,
            model,
            cfg,
            &train_ds,
            val_ds.as_ref(),
        ))
    }

    fn start(
        model_name: &str,
        model: Model,
        cfg: TrainConfig,
        train: &Dataset,
        val: Option<&Dataset>,
    ) -> Self {
        let best_params = model.params.export();
        let c = &model.config;
        let baseline = zero_acceleration_loss(val.unwrap_or(train), c.lambda, &c.periodic);
        let initial_physical = used_physical_values(&model);
        Self {
            model_name: model_name.to_string(),
            model,
            adam: Adam::default(),
            rng: Rng::derive(cfg.seed, 0x05_40F),
            cfg,
            epoch: 0,
            fingerprint: fingerprint(train, val),
            train: HostData::new(train),
            val: val.map(HostData::new),
            best_epoch: 0,
            best_loss: f64::INFINITY,
            best_params,
            history: vec![],
            stale_epochs: 0,
            train_seconds: 0.0,
            samples_seen: 0,
            baseline,
            initial_physical,
            shards: 1,
            pool: None,
        }
    }

    /// Runs on `threads` threads (1, the default, runs on the caller's thread). A new run
    /// splits each batch into that many shards; a resumed one keeps its checkpoint's split.
    pub fn with_threads(mut self, threads: usize) -> Result<Self> {
        if !(1..=shards::MAX_THREADS).contains(&threads) {
            return Err(Error::invalid(
                "threads",
                format!("must be between 1 and {}", shards::MAX_THREADS),
            ));
        }
        if self.samples_seen == 0 {
            self.shards = threads;
        }
        self.pool = if threads > 1 {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .thread_name(|i| format!("graybox-train-{i}"))
                .build()
                .map_err(|e| Error::Training(format!("could not start {threads} threads: {e}")))?;
            Some(pool)
        } else {
            None
        };
        Ok(self)
    }

    /// Shards per batch (what the results depend on, see `TrainState::shards`).
    pub fn shards(&self) -> usize {
        self.shards
    }

    /// The shards a batch of `rows` gets (fewer for small batches, see `shards::MIN_SHARD_ROWS`).
    pub fn shards_of(&self, rows: usize) -> usize {
        shards::shard_count(self.shards, rows, self.min_shard_rows())
    }

    fn min_shard_rows(&self) -> usize {
        shards::min_shard_rows(&self.model.config.spec)
    }

    /// The mean loss over the training rows `batch` and its gradient (the parameters' visiting
    /// order), the batch split into shards as a training step splits it.
    pub fn loss_and_grads(&self, batch: &[usize]) -> (f64, ParamGrads) {
        let rows = batch.len() as f64;
        let k = self.shards_of(batch.len());
        let shard = |idx: &[usize], model: &Model| {
            let (x, u, y) = self.train.gather(idx, &model.device());
            let loss = model.loss_sum(x, u, y).div_scalar(rows);
            let value = scalar(loss.clone());
            (value, shards::gradients(&model.params, &loss))
        };
        if k == 1 {
            return shard(batch, &self.model);
        }
        let results = shards::map_pieces(&shards::split(batch, k), self.pool.as_ref(), |idx| {
            let model = self
                .model
                .with_params(shards::fresh_leaves(self.model.params.clone()));
            shard(idx, &model)
        });
        let value = results.iter().map(|r| r.0).sum();
        (
            value,
            shards::sum_grads(results.into_iter().map(|r| r.1).collect()),
        )
    }

    /// Continues a run from a checkpoint, with the same data as the original run.
    pub fn resume(
        state: TrainState,
        data: &Dataset,
        val: Option<&Dataset>,
        device: &Device,
    ) -> Result<Self> {
        let (train_ds, val_ds) = split_data(data, val, &state.train)?;
        if fingerprint(&train_ds, val_ds.as_ref()) != state.data_fingerprint {
            return Err(Error::invalid(
                "checkpoint",
                "was taken on other data than the data given",
            ));
        }
        let skeleton = Model::init(state.config.clone(), None, state.train.seed, device)?;
        let params = import(skeleton.params, &state.params, device)?;
        let model = Model::from_parts(state.config, params, device);
        let mut t = Self::start(
            &state.model_name,
            model,
            state.train,
            &train_ds,
            val_ds.as_ref(),
        );
        t.adam = Adam::from_state(&state.adam, &device.clone().without_autodiff());
        t.rng = state.rng;
        t.epoch = state.epoch;
        t.best_epoch = state.best_epoch;
        t.best_loss = state.best_loss;
        t.best_params = state.best_params;
        t.history = state.history;
        t.stale_epochs = state.stale_epochs;
        t.train_seconds = state.train_seconds;
        t.samples_seen = state.samples_seen;
        t.initial_physical = state.initial_physical;
        t.shards = state.shards.max(1);
        Ok(t)
    }

    /// Goes on training the same model on `data` (no validation set) for `epochs` more
    /// epochs in batches of `batch_size`: the parameters, Adam's moments and the shuffling RNG
    /// carry on, the scalings stay those of the first data, and the best-epoch tracking starts
    /// over (losses on other data do not compare). Model-based RL grows its dataset this way
    /// after every episode; a checkpoint taken afterwards resumes with `data`.
    pub fn extend(&mut self, data: &Dataset, epochs: usize, batch_size: usize) -> Result<()> {
        let c = &self.model.config;
        if (data.n, data.m) != (c.n, c.m) || data.dt != c.dt {
            return Err(Error::invalid(
                "data",
                format!(
                    "has n = {}, m = {}, dt = {} but the model has n = {}, m = {}, dt = {}",
                    data.n, data.m, data.dt, c.n, c.m, c.dt
                ),
            ));
        }
        let cfg = TrainConfig {
            epochs: self.epoch + epochs,
            batch_size,
            val_fraction: 0.0,
            ..self.cfg.clone()
        };
        cfg.validate()?;
        self.cfg = cfg;
        self.train = HostData::new(data);
        self.val = None;
        self.fingerprint = fingerprint(data, None);
        self.baseline = zero_acceleration_loss(data, c.lambda, &c.periodic);
        self.best_loss = f64::INFINITY;
        self.best_params = self.model.params.export();
        self.stale_epochs = 0;
        Ok(())
    }

    pub fn checkpoint(&self) -> TrainState {
        TrainState {
            model_name: self.model_name.clone(),
            config: self.model.config.clone(),
            train: self.cfg.clone(),
            epoch: self.epoch,
            params: self.model.params.export(),
            adam: self.adam.state(),
            rng: self.rng,
            best_epoch: self.best_epoch,
            best_loss: self.best_loss,
            best_params: self.best_params.clone(),
            history: self.history.clone(),
            stale_epochs: self.stale_epochs,
            train_seconds: self.train_seconds,
            samples_seen: self.samples_seen,
            data_fingerprint: self.fingerprint,
            initial_physical: self.initial_physical.clone(),
            shards: self.shards,
        }
    }

    pub fn epoch(&self) -> usize {
        self.epoch
    }

    /// Seconds spent in training steps so far (validation excluded).
    pub fn train_seconds(&self) -> f64 {
        self.train_seconds
    }

    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The best validation loss so far (`None` without a validation set or before epoch 1).
    pub fn best_val_loss(&self) -> Option<f64> {
        (self.val.is_some() && self.epoch > 0).then_some(self.best_loss)
    }

    pub fn stopped_early(&self) -> bool {
        self.cfg.patience.is_some_and(|p| self.stale_epochs >= p)
    }

    pub fn finished(&self) -> bool {
        self.epoch >= self.cfg.epochs || self.stopped_early()
    }

    /// One pass over the shuffled training data, then validation. `cancel` is checked between
    /// batches.
    pub fn run_epoch(&mut self, cancel: &AtomicBool) -> Result<EpochMetrics> {
        let start = Instant::now();
        let mut order: Vec<usize> = (0..self.train.count).collect();
        self.rng.shuffle(&mut order);
        let epoch = self.epoch + 1;
        let mut total = 0.0;
        for (b, batch) in order.chunks(self.cfg.batch_size).enumerate() {
            if cancel.load(Ordering::Relaxed) {
                return Err(Error::Cancelled);
            }
            let (value, grads) = self.loss_and_grads(batch);
            shards::check_learns(&grads)?;
            if !value.is_finite() {
                return Err(Error::Training(format!(
                    "the loss became non-finite ({value}) at epoch {epoch}, batch {b}; try a smaller learning rate"
                )));
            }
            total += value * batch.len() as f64;
            self.model.params = self
                .adam
                .step(self.model.params.clone(), &grads, self.cfg.lr);
        }
        self.train_seconds += start.elapsed().as_secs_f64();
        self.samples_seen += self.train.count as u64;
        let train_loss = total / self.train.count as f64;
        let val_loss = self
            .val
            .as_ref()
            .map(|v| mean_loss(&self.model.valid(), v, self.shards, self.pool.as_ref()));
        if let Some(v) = val_loss.filter(|v| !v.is_finite()) {
            return Err(Error::Training(format!(
                "the validation loss became non-finite ({v}) at epoch {epoch}"
            )));
        }
        self.epoch = epoch;
        let criterion = val_loss.unwrap_or(train_loss);
        if criterion < self.best_loss {
            self.best_loss = criterion;
            self.best_epoch = epoch;
            self.best_params = self.model.params.export();
            self.stale_epochs = 0;
        } else {
            self.stale_epochs += 1;
        }
        let metrics = EpochMetrics {
            epoch,
            train_loss,
            val_loss,
            seconds: start.elapsed().as_secs_f64(),
        };
        self.history.push(metrics);
        Ok(metrics)
    }

    /// The report for the run so far.
    pub fn report(&self) -> TrainReport {
        let last = self.history.last();
        let seconds: f64 = self.history.iter().map(|h| h.seconds).sum();
        let parts = self.model.white_box_parts();
        let best = Model::from_parts(
            self.model.config.clone(),
            import(
                self.model.params.clone(),
                &self.best_params,
                &self.model.device(),
            )
            .expect("same structure"),
            &self.model.device(),
        );
        let (physical_parameters, ident) =
            match (self.model.config.template(), best.physical_values()) {
                (Some(t), Some(values)) => (
                    used_physical(t, &parts, &values),
                    identifiable(t, &parts, &values),
                ),
                _ => Default::default(),
            };
        TrainReport {
            model: self.model_name.clone(),
            spec: self.model.config.spec.clone(),
            epochs: self.epoch,
            train_loss: last.map_or(f64::NAN, |h| h.train_loss),
            val_loss: last.and_then(|h| h.val_loss),
            best_epoch: self.best_epoch,
            best_val_loss: self.best_val_loss(),
            stopped_early: self.stopped_early(),
            seconds,
            samples_per_second: if self.train_seconds > 0.0 {
                self.samples_seen as f64 / self.train_seconds
            } else {
                0.0
            },
            physical_parameters,
            identifiable: ident,
            identifiability: self
                .model
                .config
                .template()
                .filter(|_| !self.model.white_box_parts().is_empty())
                .and_then(|t| t.identifiability_note())
                .map(str::to_string),
            history: self.history.clone(),
            warnings: self.warnings(),
        }
    }

    /// The training checks on the run so far.
    fn warnings(&self) -> Vec<crate::records::Warning> {
        let physical = used_physical_values(&self.model).unwrap_or_default();
        training_warnings(&RunSummary {
            history: &self.history,
            best_loss: self.best_loss,
            baseline: self.baseline,
            initial_physical: self.initial_physical.as_ref(),
            physical: &physical,
        })
    }

    /// The best parameters as a model file, with the report.
    pub fn model_file(&self) -> ModelFile {
        ModelFile::new(
            self.model.config.clone(),
            self.best_params.clone(),
            Some(self.report()),
        )
    }

    /// Runs to the end, calling `on_epoch` after each epoch.
    pub fn run(
        &mut self,
        cancel: &AtomicBool,
        mut on_epoch: impl FnMut(&EpochMetrics, &Trainer),
    ) -> Result<()> {
        while !self.finished() {
            let m = self.run_epoch(cancel)?;
            on_epoch(&m, self);
        }
        Ok(())
    }
}
