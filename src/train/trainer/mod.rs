//! The training loop (docs/training.md#training-loop): mean one-step prediction loss, Adam, per-epoch
//! validation, early stopping that keeps the best-validation parameters, and checkpoints at
//! epoch boundaries from which a resumed run equals an uninterrupted one.

mod loss;
mod report;
mod state;

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use burn::tensor::Device;

use super::adam::{Adam, AdamState};
use super::setup::{TrainConfig, prepare};
use super::shards;
use super::warnings::zero_acceleration_window_loss;
use super::windows::Windows;
use crate::data::Dataset;
use crate::error::{Error, Result};
use crate::model::Model;
use crate::model::report::EpochMetrics;
use crate::model::spec::ModelSpec;
use crate::physics::params::bounds;
use crate::rng::Rng;

pub use loss::evaluate;
use loss::{HostData, mean_loss};
use report::used_physical_values;
pub use state::TrainState;
use state::fingerprint;

pub struct Trainer {
    /// What a checkpoint holds, the run's progress included. Its `params` and `adam` stay
    /// empty here: the live values are `model`'s tensors and `adam`'s, which `checkpoint`
    /// writes in their place.
    state: TrainState,
    model: Model,
    adam: Adam,
    train: HostData,
    /// The training windows of the run's horizon (every row, for the one-step loss).
    train_windows: Windows,
    /// Every row on its own, for the one-step epochs of a curriculum
    /// (`TrainConfig::one_step_epochs`).
    train_rows: Windows,
    val: Option<Validation>,
    /// The zero-acceleration loss on the set and windows that pick the best epoch
    /// (validation, else training), and the windows' steps, for the training checks.
    baseline: (f64, usize),
    /// The threads that run a batch's shards (`TrainState::shards`).
    pool: Option<rayon::ThreadPool>,
    /// The physical parameters' raw bounds, kept after every step (`Params::projected`):
    /// minimums, and fixed parameters held at their values.
    bounds: Option<(Vec<f64>, Vec<f64>)>,
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
        let state = TrainState {
            model_name: model_name.to_string(),
            config: model.config.clone(),
            epoch: 0,
            params: vec![],
            adam: AdamState::default(),
            rng: Rng::derive(cfg.seed, 0x05_40F),
            train: cfg,
            best_epoch: 0,
            best_loss: f64::INFINITY,
            best_params: model.params.export(),
            history: vec![],
            stale_epochs: 0,
            train_seconds: 0.0,
            samples_seen: 0,
            data_fingerprint: fingerprint(&train_ds, val_ds.as_ref()),
            initial_physical: used_physical_values(&model),
            shards: 1,
        };
        Ok(Self::start(
            state,
            model,
            Adam::default(),
            &train_ds,
            val_ds.as_ref(),
        ))
    }

    /// A run at `state` with its live parameters and moments, on its data.
    fn start(
        state: TrainState,
        model: Model,
        adam: Adam,
        train: &Dataset,
        val: Option<&Dataset>,
    ) -> Self {
        let c = &model.config;
        // A fixed parameter's value now is its start: it never moves (a resumed run's too).
        let bounds =
            (c.template().zip(model.raw_physical())).and_then(|(t, raw)| bounds(t.params(), &raw));
        let (horizon, discount) = (state.train.horizon, state.train.discount);
        let train_windows = Windows::of(train, horizon, discount);
        let val = val.map(|v| Validation::new(v, horizon, discount));
        let baseline = match &val {
            Some(v) => baseline(&v.ds, v.horizon.as_ref().unwrap_or(&v.one_step), &model),
            None => baseline(train, &train_windows, &model),
        };
        Self {
            state,
            model,
            adam,
            train: HostData::new(train),
            train_windows,
            train_rows: Windows::one_step(train.count()),
            val,
            baseline,
            pool: None,
            bounds,
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
        if self.state.samples_seen == 0 {
            self.state.shards = threads;
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
        self.state.shards
    }

    /// The shards a batch of `rows` gets (fewer for small batches, see `shards::MIN_SHARD_ROWS`).
    pub fn shards_of(&self, rows: usize) -> usize {
        shards::shard_count(self.state.shards, rows, self.min_shard_rows())
    }

    fn min_shard_rows(&self) -> usize {
        shards::min_shard_rows(&self.model.config.spec)
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
            epochs: self.state.epoch + epochs,
            batch_size,
            val_fraction: 0.0,
            ..self.state.train.clone()
        };
        cfg.validate()?;
        self.train = HostData::new(data);
        self.train_windows = Windows::of(data, cfg.horizon, cfg.discount);
        self.baseline = baseline(data, &self.train_windows, &self.model);
        self.train_rows = Windows::one_step(data.count());
        self.val = None;
        let s = &mut self.state;
        s.train = cfg;
        s.data_fingerprint = fingerprint(data, None);
        s.best_loss = f64::INFINITY;
        s.best_params = self.model.params.export();
        s.stale_epochs = 0;
        Ok(())
    }

    pub fn epoch(&self) -> usize {
        self.state.epoch
    }

    /// Seconds spent in training steps so far (validation excluded).
    pub fn train_seconds(&self) -> f64 {
        self.state.train_seconds
    }

    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The best validation loss so far (`None` without a validation set or before epoch 1).
    pub fn best_val_loss(&self) -> Option<f64> {
        (self.val.is_some() && self.state.epoch > 0).then_some(self.state.best_loss)
    }

    /// The steps of the windows [`Trainer::best_val_loss`] is taken over (1: one-step).
    pub fn best_val_loss_steps(&self) -> Option<usize> {
        (self.best_val_loss().and(self.val.as_ref()))
            .map(|v| v.horizon.as_ref().map_or(1, Windows::horizon))
    }

    pub fn stopped_early(&self) -> bool {
        let s = &self.state;
        s.train.patience.is_some_and(|p| s.stale_epochs >= p)
    }

    pub fn finished(&self) -> bool {
        self.state.epoch >= self.state.train.epochs || self.stopped_early()
    }

    /// One pass over the shuffled training data, then validation. `cancel` is checked between
    /// batches.
    pub fn run_epoch(&mut self, cancel: &AtomicBool) -> Result<EpochMetrics> {
        let start = Instant::now();
        let t = &self.state.train;
        if t.one_step_epochs > 0 && self.state.epoch == t.one_step_epochs && t.horizon > 1 {
            // The window loss's gradients are larger than the one-step loss's; Adam's second
            // moments (β₂ = 0.999, ~1000 steps to adapt) would scale the first window steps
            // by the old, small gradients and overshoot. Fresh moments restart the bias
            // correction at the new scale.
            self.adam = Adam::default();
        }
        let mut order = self.windows().starts.clone();
        self.state.rng.shuffle(&mut order);
        let epoch = self.state.epoch + 1;
        let mut total = 0.0;
        for (b, batch) in order.chunks(self.state.train.batch_size).enumerate() {
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
            let lr = self.state.train.lr_at(self.state.epoch);
            self.model.params = self.adam.step(self.model.params.clone(), &grads, lr);
            if let Some(bounds) = &self.bounds {
                self.model.params = self.model.params.clone().projected(bounds);
            }
        }
        let (windows, horizon) = (self.windows().count(), self.windows().horizon());
        let s = &mut self.state;
        s.train_seconds += start.elapsed().as_secs_f64();
        s.samples_seen += (windows * horizon) as u64;
        let train_loss = total / windows as f64;
        let valid = self.model.valid();
        let loss =
            |v: &HostData, w: &Windows| mean_loss(&valid, v, w, s.shards, self.pool.as_ref());
        let val_loss = (self.val.as_ref()).map(|v| loss(&v.data, &v.one_step));
        let val_horizon_loss =
            (self.val.as_ref()).and_then(|v| v.horizon.as_ref().map(|w| loss(&v.data, w)));
        if let Some(v) = (val_loss.iter().chain(&val_horizon_loss)).find(|v| !v.is_finite()) {
            return Err(Error::Training(format!(
                "the validation loss became non-finite ({v}) at epoch {epoch}"
            )));
        }
        s.epoch = epoch;
        // A multi-step run keeps the epoch whose rollouts validate best.
        let criterion = val_horizon_loss.or(val_loss).unwrap_or(train_loss);
        if criterion < s.best_loss {
            s.best_loss = criterion;
            s.best_epoch = epoch;
            s.best_params = self.model.params.export();
            s.stale_epochs = 0;
        } else {
            s.stale_epochs += 1;
        }
        let metrics = EpochMetrics {
            epoch,
            train_loss,
            val_loss,
            val_horizon_loss,
            seconds: start.elapsed().as_secs_f64(),
        };
        s.history.push(metrics);
        Ok(metrics)
    }

    /// The windows the next epoch trains on.
    fn windows(&self) -> &Windows {
        if self.state.train.horizon_at(self.state.epoch) == 1 {
            &self.train_rows
        } else {
            &self.train_windows
        }
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

/// The validation set: its one-step loss (comparable across every job), and for a multi-step
/// run the loss over its windows of the run's horizon when it has any.
/// The zero-acceleration loss of `ds` over `windows` with `model`'s loss weights, and the
/// windows' steps.
fn baseline(ds: &Dataset, windows: &Windows, model: &Model) -> (f64, usize) {
    let c = &model.config;
    let loss = zero_acceleration_window_loss(ds, windows, c.lambda, &c.periodic);
    (loss, windows.horizon())
}

struct Validation {
    /// The set itself, for the error against horizon at the end (`model_file`).
    ds: Dataset,
    data: HostData,
    one_step: Windows,
    horizon: Option<Windows>,
}

impl Validation {
    fn new(ds: &Dataset, horizon: usize, discount: f64) -> Self {
        let windows = (horizon > 1).then(|| Windows::of(ds, horizon, discount));
        Self {
            ds: ds.clone(),
            data: HostData::new(ds),
            one_step: Windows::one_step(ds.count()),
            horizon: windows.filter(|w| w.count() > 0),
        }
    }
}
