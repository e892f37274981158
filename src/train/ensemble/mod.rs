//! Ensembles (README "Ensembles and uncertainty"): K members of one model configuration,
//! each with its own seed and bootstrap resample of the training windows, trained in lockstep
//! one epoch at a time on one data split, checkpointed and stored together. One member is a
//! single model's run, byte for byte: its checkpoints and its model file are a `Trainer`'s.
//!
//! Members, not a batch's rows, are the unit of parallelism when there are at least as many
//! members as threads (`Parallelism`): each member then runs on one thread with one shard,
//! and what a member computes never depends on which thread runs it.

use std::collections::BTreeMap;
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use burn::tensor::Device;
use serde::{Deserialize, Serialize};

use super::setup::{TrainConfig, split_data};
use super::shards;
use super::trainer::{EpochRun, RunData, TrainState, Trainer};
use crate::data::Dataset;
use crate::error::{Error, Result};
use crate::model::file::ModelFile;
use crate::model::report::{EpochMetrics, TrainReport};
use crate::model::spec::ModelSpec;
use crate::records::Warning;

mod report;

use report::{ensemble_report, mean, summary};

/// What runs on a job's threads: whole members side by side, or one member's batch split
/// into shards, the members one after another.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Parallelism {
    Members,
    Rows,
}

impl Parallelism {
    /// Members when there are at least as many as threads (`graybox-lab bench ensemble`).
    pub fn default_for(members: usize, threads: usize) -> Self {
        if members > 1 && members >= threads {
            Self::Members
        } else {
            Self::Rows
        }
    }
}

pub struct Ensemble {
    members: Vec<Trainer>,
    /// The threads members run on side by side (`Parallelism::Members`).
    pool: Option<Arc<rayon::ThreadPool>>,
    /// Each epoch's wall time, by epoch: what the run took, which the members' own times,
    /// overlapping when they run side by side, do not say.
    wall: BTreeMap<usize, f64>,
}

/// An ensemble's checkpoint: every member's (one member's is a `TrainState` alone).
#[derive(Serialize, Deserialize)]
struct EnsembleState {
    /// First, so that a checkpoint's bytes say what they are by their first field.
    members: Vec<TrainState>,
    /// `Ensemble::wall`; absent from earlier checkpoints.
    #[serde(
        rename = "seconds",
        default,
        skip_serializing_if = "BTreeMap::is_empty"
    )]
    wall: BTreeMap<usize, f64>,
}

/// How an ensemble checkpoint's JSON starts (`EnsembleState`'s first field).
const ENSEMBLE_CHECKPOINT: &[u8] = b"{\"members\":";

/// An epoch of the ensemble: the members' mean losses and their standard deviations (None
/// for one member).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnsembleEpoch {
    pub mean: EpochMetrics,
    pub std: Option<LossSpread>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LossSpread {
    pub train_loss: f64,
    pub val_loss: Option<f64>,
    pub val_horizon_loss: Option<f64>,
}

impl Ensemble {
    /// A new run of `cfg.ensemble` members (see `Trainer::new`).
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
        let members = (0..cfg.ensemble)
            .map(|k| {
                let (start, run) = (start.clone(), run.clone());
                Trainer::member(model_name, start, run, cfg.clone(), k, device)
            })
            .collect::<Result<_>>()?;
        Ok(Self {
            members,
            pool: None,
            wall: BTreeMap::new(),
        })
    }

    /// Continues a run from its checkpoint's bytes, on the data it started with.
    pub fn resume(
        bytes: &[u8],
        data: &Dataset,
        val: Option<&Dataset>,
        device: &Device,
    ) -> Result<Self> {
        let state = if bytes.starts_with(ENSEMBLE_CHECKPOINT) {
            serde_json::from_slice(bytes).map_err(|e| Error::corrupt("checkpoint", e))?
        } else {
            EnsembleState {
                members: vec![TrainState::from_bytes(bytes)?],
                wall: BTreeMap::new(),
            }
        };
        let mut resumed = Self::resume_states(state.members, data, val, device)?;
        resumed.wall = state.wall;
        Ok(resumed)
    }

    /// Continues a run from its members' states (`Ensemble::states`).
    pub fn resume_states(
        states: Vec<TrainState>,
        data: &Dataset,
        val: Option<&Dataset>,
        device: &Device,
    ) -> Result<Self> {
        let Some(first) = states.first() else {
            return Err(Error::corrupt("checkpoint", "it has no members"));
        };
        if states.len() != first.train.ensemble
            || states.iter().enumerate().any(|(k, s)| s.member != k)
        {
            return Err(Error::corrupt(
                "checkpoint",
                "its members do not match its ensemble size",
            ));
        }
        let (train_ds, val_ds) = split_data(data, val, (&first.train, &first.config.spec))?;
        let run = Arc::new(RunData::new(
            &train_ds,
            val_ds.as_ref(),
            &first.train,
            &first.config,
        ));
        let members = (states.into_iter())
            .map(|s| Trainer::resume_on(s, run.clone(), device))
            .collect::<Result<_>>()?;
        Ok(Self {
            members,
            pool: None,
            wall: BTreeMap::new(),
        })
    }

    /// Runs on `threads` threads, members or rows side by side as `Parallelism::default_for`.
    pub fn with_threads(self, threads: usize) -> Result<Self> {
        let unit = Parallelism::default_for(self.members.len(), threads);
        self.with_parallelism(threads, unit)
    }

    /// Runs on `threads` threads, `unit` side by side. A resumed run keeps its checkpoint's
    /// shards (what its results depend on) whichever unit it runs by.
    pub fn with_parallelism(mut self, threads: usize, unit: Parallelism) -> Result<Self> {
        let pool = shards::pool(threads)?;
        match unit {
            Parallelism::Members => {
                self.members.iter_mut().for_each(|m| m.use_pool(None, 1));
                self.pool = pool;
            }
            Parallelism::Rows => {
                (self.members.iter_mut()).for_each(|m| m.use_pool(pool.clone(), threads));
                self.pool = None;
            }
        }
        Ok(self)
    }

    /// Goes on training every member on `data` for `epochs` more epochs (`Trainer::extend`):
    /// the members share the grown data, each on its own resample of it.
    pub fn extend(&mut self, data: &Dataset, epochs: usize, batch_size: usize) -> Result<()> {
        // Each member's own: one that stopped early has trained fewer epochs.
        let cfgs: Vec<TrainConfig> = (self.members.iter())
            .map(|m| m.extended(data, epochs, batch_size))
            .collect::<Result<_>>()?;
        let first = &self.members[0];
        let run = Arc::new(RunData::new(data, None, &cfgs[0], &first.model().config));
        for (m, cfg) in self.members.iter_mut().zip(cfgs) {
            m.extend_on(run.clone(), cfg);
        }
        Ok(())
    }

    pub fn members(&self) -> &[Trainer] {
        &self.members
    }

    /// Epochs completed (the most any member has: one that stopped early waits for the rest).
    pub fn epoch(&self) -> usize {
        self.members.iter().map(Trainer::epoch).max().unwrap_or(0)
    }

    pub fn finished(&self) -> bool {
        self.members.iter().all(Trainer::finished)
    }

    /// The members' mean best validation loss (None without a validation set).
    pub fn best_val_loss(&self) -> Option<f64> {
        mean(self.members.iter().map(Trainer::best_val_loss))
    }

    /// One epoch of every member not yet finished. A member's failure fails the ensemble,
    /// naming the member; `cancel` stops every member at its next batch.
    pub fn run_epoch(&mut self, cancel: &AtomicBool) -> Result<EnsembleEpoch> {
        let start = std::time::Instant::now();
        let run = |t: &mut Trainer| match t.finished() {
            true => Ok(None),
            false => t.run_epoch(cancel).map(Some),
        };
        let results: Vec<Result<Option<EpochMetrics>>> = match &self.pool {
            Some(pool) => interleaved(pool, &mut self.members, cancel),
            None => self.members.iter_mut().map(run).collect(),
        };
        let single = self.members.len() == 1;
        let mut ran = vec![];
        for (k, r) in results.into_iter().enumerate() {
            match r {
                Ok(m) => ran.extend(m),
                Err(Error::Training(why)) if !single => {
                    return Err(Error::Training(format!("member {k}: {why}")));
                }
                Err(e) => return Err(e),
            }
        }
        if ran.is_empty() {
            return Err(Error::FailedPrecondition(
                "the run has finished: every member has trained its epochs".into(),
            ));
        }
        if single {
            return Ok(EnsembleEpoch {
                mean: ran[0],
                std: None,
            });
        }
        let mut epoch = summary(&ran);
        epoch.mean.epoch = self.epoch();
        epoch.mean.seconds = start.elapsed().as_secs_f64();
        self.wall.insert(epoch.mean.epoch, epoch.mean.seconds);
        Ok(epoch)
    }

    /// Every member's state, in order: what `checkpoint` holds.
    pub fn states(&self) -> Vec<TrainState> {
        self.members.iter().map(Trainer::checkpoint).collect()
    }

    /// The checkpoint's bytes: one member's are its `TrainState`'s.
    pub fn checkpoint(&self) -> Vec<u8> {
        if let [one] = self.members.as_slice() {
            return one.checkpoint().to_bytes();
        }
        serde_json::to_vec(&EnsembleState {
            members: self.states(),
            wall: self.wall.clone(),
        })
        .expect("train states serialize")
    }

    /// The stiffness warning of member 0's template forces (the members start alike).
    pub fn stiffness_warning(&self) -> Option<Warning> {
        self.members[0].stiffness_warning()
    }

    /// Every member's best parameters in one file, with the ensemble's report.
    pub fn model_file(&self) -> ModelFile {
        if let [one] = self.members.as_slice() {
            return one.model_file();
        }
        let files: Vec<ModelFile> = self.members.iter().map(Trainer::best_file).collect();
        let reports: Vec<&TrainReport> = (files.iter())
            .map(|f| f.report.as_ref().expect("trained files carry a report"))
            .collect();
        let report = ensemble_report(&reports, &self.wall);
        let mut file = ModelFile::ensemble(files, Some(report));
        self.members[0].add_horizon_errors(&mut file);
        self.members[0].add_energy_report(&mut file);
        file
    }
}

/// One epoch of every unfinished member on the pool's threads, batch by batch: a thread
/// takes the member that has waited longest, trains one batch of it (or ends its epoch) and
/// puts it back. Whole member-epochs would leave a thread idle at the end of every epoch
/// (5 members on 2 threads: 3 member-epochs long instead of 2.5). A member's steps still run
/// one at a time, in order, so its numbers do not depend on the threads.
fn interleaved(
    pool: &rayon::ThreadPool,
    members: &mut [Trainer],
    cancel: &AtomicBool,
) -> Vec<Result<Option<EpochMetrics>>> {
    type Slot<'a> = Mutex<(&'a mut Trainer, Option<EpochRun>)>;
    let waiting: VecDeque<usize> = (0..members.len())
        .filter(|&k| !members[k].finished())
        .collect();
    let results: Vec<Mutex<Result<Option<EpochMetrics>>>> =
        (0..members.len()).map(|_| Mutex::new(Ok(None))).collect();
    let slots: Vec<Slot> = members.iter_mut().map(|t| Mutex::new((t, None))).collect();
    let (queue, failed) = (Mutex::new(waiting), AtomicBool::new(false));
    pool.scope(|s| {
        for _ in 0..pool.current_num_threads() {
            s.spawn(|_| {
                // A thread that finds no member waiting leaves: the members left are held
                // by other threads, and there are never more of them later.
                loop {
                    // Its own statement: the queue's guard must not live through the batch.
                    let next = lock(&queue).pop_front();
                    let Some(k) = next.filter(|_| !failed.load(Ordering::Relaxed)) else {
                        return;
                    };
                    let mut slot = lock(&slots[k]);
                    let (t, run) = &mut *slot;
                    let epoch = run.get_or_insert_with(|| t.begin_epoch());
                    let outcome = match t.train_batch(epoch, cancel) {
                        Ok(true) => {
                            drop(slot);
                            lock(&queue).push_back(k);
                            continue;
                        }
                        Ok(false) => t.end_epoch(run.take().expect("begun")).map(Some),
                        Err(e) => Err(e),
                    };
                    failed.fetch_or(outcome.is_err(), Ordering::Relaxed);
                    *lock(&results[k]) = outcome;
                }
            });
        }
    });
    results
        .into_iter()
        .map(|r| r.into_inner().unwrap_or_else(|e| e.into_inner()))
        .collect()
}

/// The value behind `m`, whether or not a thread panicked holding it (the panic itself
/// reaches the caller through the pool's scope).
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}
