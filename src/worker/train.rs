//! A claimed job's training on its blocking thread: build or resume the trainer, run and
//! record its epochs, checkpoint, and store the model or give the job back, every write
//! fenced by (job, attempt).

use std::sync::atomic::Ordering;

use tokio::runtime::Handle;
use tracing::{info, warn};

use super::{Flags, Outcome};
use crate::app::App;
use crate::app::jobs::JobSpec;
use crate::backend::{self, Backend, Precision};
use crate::error::{Error, Result};
use crate::records::Metric;
use crate::store::{Claimed, NewModel};
use crate::train::Ensemble;
use crate::train::ensemble::EnsembleEpoch;

/// The blocking part: build or resume the trainer, run epochs (recording each, with a
/// checkpoint every `--checkpoint-every`), then store the model; progress goes through the
/// runtime handle. Every write is fenced: a lost lease ends it without writing.
pub(super) fn train_job(app: &App, c: &Claimed, flags: &Flags, rt: &Handle) -> Result<Outcome> {
    let spec = JobSpec::from_json(&c.job.request)?;
    let mut trainer = build_trainer(app, c, &spec, rt)?;
    if trainer.epoch() == 0
        && let Some(w) = trainer.stiffness_warning()
    {
        warn!(job = %c.job.id, code = %w.code, "{}", w.message);
    }
    let every = app.settings.worker.checkpoint_epochs();
    let mut checkpointed = trainer.epoch();
    let lost = || {
        flags.lost.store(true, Ordering::Relaxed);
        Ok(Outcome::LeaseLost)
    };
    while !trainer.finished() {
        if flags.shutdown.load(Ordering::Relaxed) {
            return release(app, c, &trainer, checkpointed, rt);
        }
        let EnsembleEpoch { mean: m, std } = trainer.run_epoch(&flags.cancel)?;
        app.telemetry.epochs_trained.fetch_add(1, Ordering::Relaxed);
        let row = Metric {
            epoch: m.epoch as i64,
            train_loss: m.train_loss,
            val_loss: m.val_loss,
            val_horizon_loss: m.val_horizon_loss,
            seconds: m.seconds,
            train_loss_std: std.map(|s| s.train_loss),
            val_loss_std: std.and_then(|s| s.val_loss),
        };
        if !rt.block_on(app.store.record_epoch(c, &row, trainer.best_val_loss()))? {
            return lost();
        }
        if trainer.epoch() % every == 0 && !trainer.finished() {
            let bytes = trainer.checkpoint();
            let epoch = trainer.epoch() as i64;
            if !rt.block_on(app.store.save_checkpoint(c, epoch, &bytes))? {
                return lost();
            }
            checkpointed = trainer.epoch();
        }
    }
    match rt.block_on(store_model(app, c, &spec, &trainer))? {
        Some(id) => Ok(Outcome::Succeeded(id)),
        None => lost(),
    }
}

/// A new trainer for the job, or the one its last checkpoint holds (refused as corrupt when
/// the checkpoint claims an epoch past the job's last).
fn build_trainer(app: &App, c: &Claimed, spec: &JobSpec, rt: &Handle) -> Result<Ensemble> {
    let load = |id: &str| -> Result<crate::data::Dataset> {
        rt.block_on(app.store.load_dataset(id))?
            .ok_or_else(|| Error::invalid("dataset_id", format!("dataset {id} was deleted")))
    };
    let data = load(&spec.dataset_id)?;
    let val = spec
        .validation_dataset_id
        .as_deref()
        .map(load)
        .transpose()?;
    let device = backend::device(Backend::Flex, Precision::F32)?.autodiff();
    let trainer = match rt.block_on(app.store.load_checkpoint(&c.job.id))? {
        Some((epoch, _)) if epoch > c.job.epochs => Err(Error::corrupt(
            "checkpoint",
            format!(
                "its epoch {epoch} is past the job's {} epochs",
                c.job.epochs
            ),
        )),
        Some((epoch, bytes)) => {
            info!(job = %c.job.id, epoch, "resuming from checkpoint");
            Ensemble::resume(&bytes, &data, val.as_ref(), &device)
        }
        None => Ensemble::new(
            &spec.model_name,
            spec.spec.clone(),
            &spec.init,
            &data,
            val.as_ref(),
            spec.training.clone(),
            &device,
        ),
    }?;
    trainer.with_threads(app.settings.worker.job_threads())
}

/// The trained model and the job's success in one fenced transaction; None when the lease
/// was lost. A model file with a non-finite number is an error instead.
async fn store_model(
    app: &App,
    c: &Claimed,
    spec: &JobSpec,
    trainer: &Ensemble,
) -> Result<Option<String>> {
    let file = trainer.model_file();
    let report = file.report.as_ref().expect("trained files carry a report");
    let warnings = report.warnings.clone();
    let report = serde_json::to_string(report).expect("json");
    let spec_json = serde_json::to_string(&file.config.spec).expect("json");
    let model = NewModel {
        name: spec.display_name(),
        n: file.config.nv() as i64,
        nq: file.config.nq() as i64,
        m: file.config.m as i64,
        dt: file.config.dt,
        spec: &spec_json,
        report: &report,
        file: &file.to_bytes()?,
    };
    app.store.finish_job(c, model, &warnings).await
}

/// Shutdown: checkpoint at this epoch end (unless just taken) and give the job back.
fn release(
    app: &App,
    c: &Claimed,
    trainer: &Ensemble,
    checkpointed: usize,
    rt: &Handle,
) -> Result<Outcome> {
    if trainer.epoch() > checkpointed {
        rt.block_on(
            app.store
                .save_checkpoint(c, trainer.epoch() as i64, &trainer.checkpoint()),
        )?;
    }
    rt.block_on(app.store.release_job(c))?;
    Ok(Outcome::Released)
}
