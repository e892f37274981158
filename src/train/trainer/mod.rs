//! The training loop (docs/training.md#training-loop): mean one-step prediction loss, Adam, per-epoch
//! validation, early stopping that keeps the best-validation parameters, and checkpoints at
//! epoch boundaries from which a resumed run equals an uninterrupted one.

mod epoch;
mod loss;
mod report;
mod state;

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use burn::tensor::Device;

use super::adam::{Adam, AdamState};
use super::objective::{Objective, least_squares_start};
use super::setup::{TrainConfig, prepare};
use super::shards;
use super::warnings::zero_acceleration_window_loss;
use super::windows::Windows;
use crate::data::Dataset;
use crate::error::{Error, Result};
use crate::model::report::EpochMetrics;
use crate::model::spec::ModelSpec;
use crate::model::{Model, ModelConfig};
use crate::physics::params::bounds;
use crate::rng::Rng;

pub(in crate::train) use epoch::EpochRun;
use loss::HostData;
pub use loss::{EnsembleEval, evaluate, evaluate_members};
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
    /// The sets every member of the run trains and validates on, shared by an ensemble's.
    data: Arc<RunData>,
    /// The training windows of the run's horizon (every row, for the one-step loss), an
    /// ensemble member's bootstrap resample of them.
    train_windows: Windows,
    /// Every row on its own, for the one-step epochs of a curriculum
    /// (`TrainConfig::one_step_epochs`), or a member's resample of the rows.
    train_rows: Windows,
    /// The threads that run a batch's shards (`TrainState::shards`).
    pool: Option<Arc<rayon::ThreadPool>>,
    /// The physical parameters' raw bounds, kept after every step (`Params::projected`):
    /// minimums, and fixed parameters held at their values.
    bounds: Option<(Vec<f64>, Vec<f64>)>,
}

/// What a run trains and validates on, built once however many members train on it.
pub(super) struct RunData {
    train: HostData,
    /// The training set's windows of the run's horizon, and its row count.
    windows: Windows,
    rows: usize,
    val: Option<Validation>,
    /// The zero-acceleration loss on the set and windows that pick the best epoch
    /// (validation, else training), and the windows' steps, for the training checks; none
    /// for a loss with a torque term, which a state's loss does not measure.
    baseline: Option<(f64, usize)>,
    /// `fingerprint` of the training and validation sets.
    fingerprint: u64,
}

/// What a new member starts from: the model configuration and initial physical values.
pub(super) type Start = (ModelConfig, Option<Vec<f64>>);

impl RunData {
    /// A new run checked and prepared (`setup::prepare`): its members' start, and the data
    /// they share.
    pub(super) fn prepare(
        spec: &ModelSpec,
        init: &[(String, f64)],
        data: &Dataset,
        val: Option<&Dataset>,
        cfg: &TrainConfig,
    ) -> Result<(Start, Arc<Self>)> {
        let (config, mut physical, train_ds, val_ds) = prepare(spec, init, data, val, cfg)?;
        if cfg.least_squares {
            physical = Some(least_squares_start(&config, physical, &train_ds)?);
        }
        let run = Self::new(&train_ds, val_ds.as_ref(), cfg, &config);
        Ok(((config, physical), Arc::new(run)))
    }

    pub(super) fn new(
        train: &Dataset,
        val: Option<&Dataset>,
        cfg: &TrainConfig,
        model: &ModelConfig,
    ) -> Self {
        let (horizon, discount) = (cfg.horizon, cfg.discount);
        let windows = Windows::of(train, horizon, discount);
        let validation = val.map(|v| Validation::new(v, (horizon, discount), model, cfg.loss));
        let baseline = match &validation {
            Some(v) => baseline(&v.ds, v.horizon.as_ref().unwrap_or(&v.one_step), model),
            None => baseline(train, &windows, model),
        };
        let step = cfg.loss.step;
        let baseline = (cfg.loss.torque == 0.0).then_some((step * baseline.0, baseline.1));
        Self {
            train: HostData::new(train, model.dt).with_objective(train, model, cfg.loss),
            windows,
            rows: train.count(),
            val: validation,
            baseline,
            fingerprint: fingerprint(train, val),
        }
    }
}

/// The stream of a member's bootstrap resamples (derived from its seed).
const BOOTSTRAP_STREAM: u64 = 0xB0_075;

/// The seed of ensemble member `k`: the job's own for member 0 (so that one member is the
/// single model the same job would train), an independent stream of it for the others.
pub fn member_seed(seed: u64, k: usize) -> u64 {
    if k == 0 {
        return seed;
    }
    Rng::derive(seed, 0xE_5E3B_0000 + k as u64).next_u64()
}

/// The windows and rows a run at `state` trains on: `data`'s, or in an ensemble with
/// bootstrap the member's resample of them. Re-derived from the seed on every start and
/// every `extend`, so a resumed member trains on the resample it had and a checkpoint never
/// stores it.
fn train_sets(state: &TrainState, data: &RunData) -> (Windows, Windows) {
    let (windows, rows) = (data.windows.clone(), Windows::one_step(data.rows));
    let t = &state.train;
    if t.ensemble > 1 && t.bootstrap {
        let mut rng = Rng::derive(member_seed(t.seed, state.member), BOOTSTRAP_STREAM);
        let rows = rows.resample(&mut rng);
        return (windows.resample(&mut rng), rows);
    }
    (windows, rows)
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
        let (start, run) = RunData::prepare(&spec, init, data, val, &cfg)?;
        Self::member(model_name, start, run, cfg, 0, device)
    }

    /// Member `k` of a new run on `data`: its own initialization and data order from
    /// [`member_seed`], and in an ensemble its own bootstrap resample.
    pub(super) fn member(
        model_name: &str,
        (config, physical): Start,
        data: Arc<RunData>,
        cfg: TrainConfig,
        k: usize,
        device: &Device,
    ) -> Result<Self> {
        let seed = member_seed(cfg.seed, k);
        let model = Model::init(config, physical, seed, device)?;
        model.check_learns()?;
        let state = TrainState {
            model_name: model_name.to_string(),
            config: model.config.clone(),
            epoch: 0,
            params: vec![],
            adam: AdamState::default(),
            rng: Rng::derive(seed, 0x05_40F),
            train: cfg,
            best_epoch: 0,
            best_loss: f64::INFINITY,
            best_params: model.params.export(),
            history: vec![],
            stale_epochs: 0,
            train_seconds: 0.0,
            samples_seen: 0,
            data_fingerprint: data.fingerprint,
            initial_physical: used_physical_values(&model),
            shards: 1,
            member: k,
        };
        Ok(Self::start(state, model, Adam::default(), data))
    }

    /// A run at `state` with its live parameters and moments, on its data.
    fn start(state: TrainState, model: Model, adam: Adam, data: Arc<RunData>) -> Self {
        let c = &model.config;
        // A fixed parameter's value now is its start: it never moves (a resumed run's too).
        let bounds =
            (c.template().zip(model.raw_physical())).and_then(|(t, raw)| bounds(t.params(), &raw));
        let (train_windows, train_rows) = train_sets(&state, &data);
        Self {
            state,
            model,
            adam,
            data,
            train_windows,
            train_rows,
            pool: None,
            bounds,
        }
    }

    /// Runs on `threads` threads (1, the default, runs on the caller's thread). A new run
    /// splits each batch into that many shards; a resumed one keeps its checkpoint's split.
    pub fn with_threads(mut self, threads: usize) -> Result<Self> {
        let pool = shards::pool(threads)?;
        self.use_pool(pool, threads);
        Ok(self)
    }

    /// Runs its shards on `pool` (None: the caller's thread), splitting a new run's batches
    /// into `shards`.
    pub(super) fn use_pool(&mut self, pool: Option<Arc<rayon::ThreadPool>>, shards: usize) {
        if self.state.samples_seen == 0 {
            self.state.shards = shards;
        }
        self.pool = pool;
    }

    /// Shards per batch (what the results depend on, see `TrainState::shards`).
    pub fn shards(&self) -> usize {
        self.state.shards
    }

    /// The pieces a batch of `rows` is split into (fewer for small batches, more on the
    /// fused step for large ones: `shards::piece_count`).
    pub fn shards_of(&self, rows: usize) -> usize {
        shards::piece_count(self.state.shards, rows, &self.model)
    }

    /// Goes on training the same model on `data` (no validation set) for `epochs` more
    /// epochs in batches of `batch_size`: the parameters, Adam's moments and the shuffling RNG
    /// carry on, the scalings stay those of the first data, and the best-epoch tracking starts
    /// over (losses on other data do not compare). Model-based RL grows its dataset this way
    /// after every episode; a checkpoint taken afterwards resumes with `data`.
    pub fn extend(&mut self, data: &Dataset, epochs: usize, batch_size: usize) -> Result<()> {
        let run = self.extended(data, epochs, batch_size)?;
        self.extend_on(
            Arc::new(RunData::new(data, None, &run, &self.model.config)),
            run,
        );
        Ok(())
    }

    /// The training settings of `extend`, checked against the model.
    pub(super) fn extended(
        &self,
        data: &Dataset,
        epochs: usize,
        batch_size: usize,
    ) -> Result<TrainConfig> {
        let c = &self.model.config;
        c.check_data("data", (data.nq(), data.nv(), data.m))?;
        if data.dt != c.dt {
            return Err(Error::invalid(
                "data",
                format!("has dt = {} but the model has dt = {}", data.dt, c.dt),
            ));
        }
        let cfg = TrainConfig {
            epochs: self.state.epoch + epochs,
            batch_size,
            val_fraction: 0.0,
            ..self.state.train.clone()
        };
        cfg.validate()?;
        Ok(cfg)
    }

    /// `extend` onto prepared data (an ensemble's members share theirs). A member keeps
    /// training on its own resample, drawn anew from the grown data as a resumed run would.
    pub(super) fn extend_on(&mut self, data: Arc<RunData>, cfg: TrainConfig) {
        let s = &mut self.state;
        s.train = cfg;
        s.data_fingerprint = data.fingerprint;
        s.best_loss = f64::INFINITY;
        s.best_params = self.model.params.export();
        s.stale_epochs = 0;
        (self.train_windows, self.train_rows) = train_sets(&self.state, &data);
        self.data = data;
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
        (self.data.val.is_some() && self.state.epoch > 0).then_some(self.state.best_loss)
    }

    /// The steps of the windows [`Trainer::best_val_loss`] is taken over (1: one-step).
    pub fn best_val_loss_steps(&self) -> Option<usize> {
        (self.best_val_loss().and(self.data.val.as_ref()))
            .map(|v| v.horizon.as_ref().map_or(1, Windows::horizon))
    }

    pub fn stopped_early(&self) -> bool {
        let s = &self.state;
        s.train.patience.is_some_and(|p| s.stale_epochs >= p)
    }

    pub fn finished(&self) -> bool {
        self.state.epoch >= self.state.train.epochs || self.stopped_early()
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

/// The zero-acceleration loss of `ds` over `windows` with `model`'s loss weights, and the
/// windows' steps.
fn baseline(ds: &Dataset, windows: &Windows, c: &ModelConfig) -> (f64, usize) {
    let loss = zero_acceleration_window_loss(ds, windows, c.lambda, &c.space);
    (loss, windows.horizon())
}

/// The validation set: its one-step loss (comparable across every job), and for a multi-step
/// run the loss over its windows of the run's horizon when it has any.
struct Validation {
    /// The set itself, for the error against horizon at the end (`model_file`).
    ds: Dataset,
    data: HostData,
    one_step: Windows,
    horizon: Option<Windows>,
}

impl Validation {
    fn new(
        ds: &Dataset,
        (horizon, discount): (usize, f64),
        model: &ModelConfig,
        objective: Objective,
    ) -> Self {
        let windows = (horizon > 1).then(|| Windows::of(ds, horizon, discount));
        let data = HostData::new(ds, model.dt).with_objective(ds, model, objective);
        Self {
            ds: ds.clone(),
            data,
            one_step: Windows::one_step(ds.count()),
            horizon: windows.filter(|w| w.count() > 0),
        }
    }
}
