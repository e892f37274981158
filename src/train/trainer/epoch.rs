//! One epoch, in the steps an ensemble's scheduler interleaves (`train::ensemble`): begin
//! (the shuffle), one batch at a time, end (validation and the best epoch). `run_epoch` runs
//! them in a row; whichever thread runs a step, the numbers are the same.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use super::Trainer;
use super::loss::{HostData, mean_loss};
use crate::error::{Error, Result};
use crate::model::report::EpochMetrics;
use crate::train::adam::Adam;
use crate::train::windows::Windows;

/// An epoch under way: its shuffled window starts and the batches done so far.
pub(in crate::train) struct EpochRun {
    start: Instant,
    order: Vec<usize>,
    batches: usize,
    total: f64,
}

impl Trainer {
    /// One pass over the shuffled training data, then validation. `cancel` is checked between
    /// batches.
    pub fn run_epoch(&mut self, cancel: &AtomicBool) -> Result<EpochMetrics> {
        let mut run = self.begin_epoch();
        while self.train_batch(&mut run, cancel)? {}
        self.end_epoch(run)
    }

    /// The epoch's order of the training windows.
    pub(in crate::train) fn begin_epoch(&mut self) -> EpochRun {
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
        EpochRun {
            start,
            order,
            batches: 0,
            total: 0.0,
        }
    }

    /// Trains the epoch's next batch; false when it had none left.
    pub(in crate::train) fn train_batch(
        &mut self,
        run: &mut EpochRun,
        cancel: &AtomicBool,
    ) -> Result<bool> {
        let size = self.state.train.batch_size;
        let Some(batch) = run.order.chunks(size).nth(run.batches) else {
            return Ok(false);
        };
        if cancel.load(Ordering::Relaxed) {
            return Err(Error::Cancelled);
        }
        let (value, grads) = self.loss_and_grads(batch);
        if !value.is_finite() {
            return Err(Error::Training(format!(
                "the loss became non-finite ({value}) at epoch {}, batch {}; try a smaller learning rate",
                self.state.epoch + 1,
                run.batches
            )));
        }
        run.total += value * batch.len() as f64;
        run.batches += 1;
        let lr = self.state.train.lr_at(self.state.epoch);
        self.model.params = self.adam.step(self.model.params.clone(), &grads, lr);
        if let Some(bounds) = &self.bounds {
            self.model.params = self.model.params.clone().projected(bounds);
        }
        Ok(true)
    }

    /// Validation, the best epoch so far, and the epoch's metrics.
    pub(in crate::train) fn end_epoch(&mut self, run: EpochRun) -> Result<EpochMetrics> {
        let (windows, horizon) = (self.windows().count(), self.windows().horizon());
        let epoch = self.state.epoch + 1;
        let s = &mut self.state;
        s.train_seconds += run.start.elapsed().as_secs_f64();
        s.samples_seen += (windows * horizon) as u64;
        let train_loss = run.total / windows as f64;
        let valid = self.model.valid();
        let pool = self.pool.as_deref();
        let loss = |v: &HostData, w: &Windows| mean_loss(&valid, v, w, s.shards, pool);
        let val = self.data.val.as_ref();
        let val_loss = val.map(|v| loss(&v.data, &v.one_step));
        let val_horizon_loss = val.and_then(|v| v.horizon.as_ref().map(|w| loss(&v.data, w)));
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
            seconds: run.start.elapsed().as_secs_f64(),
        };
        s.history.push(metrics);
        Ok(metrics)
    }
}
