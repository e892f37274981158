//! What a submitted job would cost to train (parameters, checkpoint, peak memory) against
//! the service's limits, checked before it is queued.

use super::App;
use super::jobs::JobSpec;
use crate::error::{Error, Result};
use crate::records::DatasetInfo;
use crate::train::budget;

impl App {
    /// The job's size, memory and checkpoint against the service's limits, before it is
    /// queued: each refusal a 422 naming the field to change and the estimate.
    pub(super) fn check_job_cost(
        &self,
        job: &JobSpec,
        data: &DatasetInfo,
        val_count: usize,
    ) -> Result<()> {
        let s = &self.settings;
        let n = data.nv();
        let refuse = |field: &str, message: String| {
            Err(Error::Unprocessable {
                field: field.into(),
                message,
            })
        };
        if n > s.max_dof {
            return refuse(
                "dataset_id",
                format!(
                    "the dataset has nv = {n} velocities; this service trains at most {} (--max-dof)",
                    s.max_dof
                ),
            );
        }
        let (est, batch) = job_estimate(job, data, val_count);
        if est.params > s.max_model_params {
            return refuse(
                "model",
                format!(
                    "the model would have {} trainable parameters, over the limit of {} \
                     (--max-model-params); use narrower or fewer hidden layers",
                    est.params, s.max_model_params
                ),
            );
        }
        if est.checkpoint_bytes > budget::STORE_MAX_BLOB {
            return refuse(
                "model",
                format!(
                    "the model's checkpoint would take about {} MB{}, more than the store holds ({} MB)",
                    est.checkpoint_bytes >> 20,
                    members_note(job.training.ensemble),
                    budget::STORE_MAX_BLOB >> 20
                ),
            );
        }
        if est.peak_bytes > s.max_job_memory_bytes() {
            return refuse(
                "training.batch_size",
                format!(
                    "training would take about {} MB at its peak (batch {batch}{}{}), over the \
                     limit of {} MB (--max-job-memory-mb); lower batch_size{} or the network widths",
                    est.peak_bytes >> 20,
                    horizon_note(job.training.horizon, " windows of horizon "),
                    members_note(job.training.ensemble),
                    s.max_job_memory_bytes() >> 20,
                    horizon_note(job.training.horizon, ", horizon ")
                ),
            );
        }
        Ok(())
    }
}

/// The job's estimated cost and its effective batch: a batch larger than the training set is
/// the whole set.
fn job_estimate(
    job: &JobSpec,
    data: &DatasetInfo,
    val_count: usize,
) -> (budget::JobEstimate, usize) {
    let (n, m) = (data.nv(), data.m as usize);
    let count = data.count as usize;
    let train = if job.validation_dataset_id.is_some() {
        count
    } else {
        count - (count as f64 * job.training.val_fraction) as usize
    };
    let batch = job.training.batch_size.min(train.max(1));
    // Physical parameters exist only when some part is white-box (`Model::init`).
    let physical = match job.spec.template() {
        Some(t) if !job.spec.white_box_parts().is_empty() => t.params().len(),
        _ => 0,
    };
    // A bad `periodic` is refused by the data check; here it counts as no angles.
    let angles = crate::train::setup::run_space(&job.spec, &job.training, (data.nq(), n))
        .map_or(0, |s| s.q_features() - s.nv());
    let dims = budget::Dims { n, m, angles };
    // A window keeps every step's integrator stages for the backward pass.
    let steps = batch.saturating_mul(job.training.horizon);
    let est = budget::estimate(&job.spec, dims, steps, count + val_count, physical);
    (est.of_members(job.training.ensemble), batch)
}

/// The members an estimate counts, when more than one.
fn members_note(members: usize) -> String {
    if members > 1 {
        format!(", {members} ensemble members")
    } else {
        String::new()
    }
}

/// `prefix` and the horizon when it is over 1, else nothing.
fn horizon_note(horizon: usize, prefix: &str) -> String {
    if horizon > 1 {
        format!("{prefix}{horizon}")
    } else {
        String::new()
    }
}
