//! Job submission: the whole request is validated here, at submission, so that a job that
//! cannot train never enters the queue.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::App;
use crate::error::{Error, Result};
use crate::model::spec::ModelSpec;
use crate::store::{DatasetRow, JobRow, JobState, MetricRow, NewJob, Submitted};
use crate::train::trainer::physical_init;
use crate::train::{TrainConfig, budget};

/// The body of POST /v1/jobs.
#[derive(Debug, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct JobRequest {
    pub dataset_id: String,
    #[serde(default)]
    pub validation_dataset_id: Option<String>,
    /// A paper name ("MVF", …, "W-B", "naive") or a JSON model spec.
    #[schema(value_type = Object)]
    pub model: Value,
    #[serde(default)]
    pub template: Option<String>,
    #[serde(default)]
    pub init: Option<BTreeMap<String, f64>>,
    #[serde(default)]
    #[schema(value_type = Option<Object>)]
    pub training: Option<TrainConfig>,
}

/// The validated job as stored (and as the worker reads it back).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobSpec {
    pub model_name: String,
    pub spec: ModelSpec,
    pub init: Vec<(String, f64)>,
    pub training: TrainConfig,
    pub dataset_id: String,
    pub validation_dataset_id: Option<String>,
}

impl JobSpec {
    pub fn from_json(s: &str) -> Result<Self> {
        serde_json::from_str(s).map_err(|e| Error::corrupt("job request", e))
    }
}

/// Parses a JSON body into `T`, naming the field at fault in the error.
pub fn parse_body<T: serde::de::DeserializeOwned>(value: Value) -> Result<T> {
    serde_path_to_error::deserialize(value).map_err(|e| {
        let path = e.path().to_string();
        let message = e.into_inner().to_string();
        // serde reports a missing field at its parent: name the field itself.
        let missing = message
            .strip_prefix("missing field `")
            .and_then(|m| m.split('`').next());
        let root = !path.chars().any(|c| c.is_alphanumeric());
        let field = match (root, missing) {
            (true, Some(m)) => m.to_string(),
            (false, Some(m)) => format!("{path}.{m}"),
            (true, None) => "body".to_string(),
            (false, None) => path,
        };
        Error::Unprocessable { field, message }
    })
}

impl App {
    /// Validates a request against its datasets and queues it (or returns the job an earlier
    /// request with the same idempotency key created).
    pub async fn submit_job(
        &self,
        req: JobRequest,
        idempotency_key: Option<String>,
    ) -> Result<(JobRow, bool)> {
        let spec = self.validate_job(req).await?;
        let new = NewJob {
            dataset_id: spec.dataset_id.clone(),
            validation_dataset_id: spec.validation_dataset_id.clone(),
            request: serde_json::to_string(&spec).expect("job specs serialize"),
            epochs: spec.training.epochs as i64,
            idempotency_key,
        };
        Ok(match self.store.submit_job(new).await? {
            Submitted::Created(job) => (job, true),
            Submitted::Existing(job) => (job, false),
        })
    }

    async fn validate_job(&self, req: JobRequest) -> Result<JobSpec> {
        let training = req.training.unwrap_or_default();
        training.validate().map_err(Error::unprocessable)?;
        let template = req
            .template
            .as_deref()
            .map(crate::cli::parse_template)
            .transpose()
            .map_err(Error::unprocessable)?;
        let (model_name, spec) = match &req.model {
            Value::String(name) => (name.clone(), ModelSpec::named(name, template)),
            Value::Object(_) => (
                "custom".to_string(),
                ModelSpec::parse(&req.model.to_string(), template),
            ),
            _ => {
                return Err(Error::Unprocessable {
                    field: "model".into(),
                    message: "must be a model name or a spec object".into(),
                });
            }
        };
        let spec = spec.map_err(Error::unprocessable)?;
        let init: Vec<(String, f64)> = req.init.unwrap_or_default().into_iter().collect();
        physical_init(&spec, &init).map_err(Error::unprocessable)?;
        let missing = |field: &str, id: &str| Error::Unprocessable {
            field: field.into(),
            message: format!("dataset {id} does not exist"),
        };
        let data = self
            .store
            .get_dataset(&req.dataset_id)
            .await?
            .ok_or_else(|| missing("dataset_id", &req.dataset_id))?;
        spec.check_dims(data.n as usize, data.m as usize)
            .map_err(Error::unprocessable)?;
        if let Some(vid) = &req.validation_dataset_id {
            let v = self
                .store
                .get_dataset(vid)
                .await?
                .ok_or_else(|| missing("validation_dataset_id", vid))?;
            if (v.n, v.m) != (data.n, data.m) || (v.dt - data.dt).abs() > 1e-12 * data.dt {
                return Err(Error::Unprocessable {
                    field: "validation_dataset_id".into(),
                    message: format!(
                        "has n = {}, m = {}, dt = {} but the training dataset has n = {}, m = {}, dt = {}",
                        v.n, v.m, v.dt, data.n, data.m, data.dt
                    ),
                });
            }
        } else if training.val_fraction > 0.0 && data.count < 2 {
            return Err(Error::Unprocessable {
                field: "training.val_fraction".into(),
                message: "a dataset of one transition cannot be split; set it to 0 or give validation_dataset_id".into(),
            });
        }
        let val_count = match &req.validation_dataset_id {
            Some(vid) => self
                .dataset(vid)
                .await
                .map(|v| v.count as usize)
                .unwrap_or(0),
            None => 0,
        };
        let job = JobSpec {
            model_name,
            spec,
            init,
            training,
            dataset_id: req.dataset_id,
            validation_dataset_id: req.validation_dataset_id,
        };
        self.check_job_cost(&job, &data, val_count)?;
        self.check_job_data(&job).await?;
        Ok(job)
    }

    /// Refuses a job over the service's limits (422 naming the field and the estimate),
    /// before it is queued.
    fn check_job_cost(&self, job: &JobSpec, data: &DatasetRow, val_count: usize) -> Result<()> {
        let s = &self.settings;
        let (n, m) = (data.n as usize, data.m as usize);
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
                    "the dataset has n = {n} coordinates; this service trains at most {} (--max-dof)",
                    s.max_dof
                ),
            );
        }
        let count = data.count as usize;
        // Training samples: a batch larger than the training set is the whole set.
        let train = if job.validation_dataset_id.is_some() {
            count
        } else {
            count - (count as f64 * job.training.val_fraction) as usize
        };
        let batch = job.training.batch_size.min(train.max(1));
        let physical = job.spec.template().map_or(0, |t| t.params().len());
        let est = budget::estimate(&job.spec, n, m, batch, count + val_count, physical);
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
                    "the model's checkpoint would take about {} MB, more than the store holds ({} MB)",
                    est.checkpoint_bytes >> 20,
                    budget::STORE_MAX_BLOB >> 20
                ),
            );
        }
        if est.peak_bytes > s.max_job_memory_bytes {
            return refuse(
                "training.batch_size",
                format!(
                    "training would take about {} MB at its peak (batch {batch}), over the limit of \
                     {} MB (--max-job-memory-mb); lower batch_size or the network widths",
                    est.peak_bytes >> 20,
                    s.max_job_memory_bytes >> 20
                ),
            );
        }
        Ok(())
    }

    /// The scalings training derives from the data must be finite (values near the f64
    /// range overflow them), else the job would "succeed" with a model that cannot answer.
    async fn check_job_data(&self, job: &JobSpec) -> Result<()> {
        let load = |field: &'static str, id: String| async move {
            self.store
                .load_dataset(&id)
                .await?
                .ok_or_else(|| Error::Unprocessable {
                    field: field.into(),
                    message: format!("dataset {id} does not exist"),
                })
        };
        let data = load("dataset_id", job.dataset_id.clone()).await?;
        let val = match &job.validation_dataset_id {
            Some(id) => Some(load("validation_dataset_id", id.clone()).await?),
            None => None,
        };
        let job = job.clone();
        tokio::task::spawn_blocking(move || {
            crate::train::trainer::prepare(&job.spec, &job.init, &data, val.as_ref(), &job.training)
                .map(|_| ())
        })
        .await
        .map_err(|e| Error::Internal(format!("checking the data failed: {e}")))?
        .map_err(|e| match e {
            Error::Invalid { field, message } if field == "data" => Error::Unprocessable {
                field: "dataset_id".into(),
                message,
            },
            e => e.unprocessable(),
        })
    }

    pub async fn job(&self, id: &str) -> Result<JobRow> {
        self.store
            .get_job(id)
            .await?
            .ok_or_else(|| Error::NotFound(format!("job {id}")))
    }

    pub async fn job_metrics(&self, id: &str) -> Result<Vec<MetricRow>> {
        self.job(id).await?;
        self.store.metrics(id, 0).await
    }

    pub async fn cancel_job(&self, id: &str) -> Result<JobRow> {
        self.store.cancel_job(id).await
    }

    pub async fn list_jobs(
        &self,
        state: Option<&str>,
        size: Option<i64>,
        token: Option<&str>,
    ) -> Result<(Vec<JobRow>, Option<String>)> {
        let state = match state {
            None | Some("") => None,
            Some(s) => Some(JobState::parse(s).ok_or_else(|| {
                Error::invalid(
                    "state",
                    "must be one of queued, running, succeeded, failed, cancelled",
                )
            })?),
        };
        let size = super::paging::size(size)?;
        let after = super::paging::decode("jobs", token)?;
        let items = self.store.list_jobs(state, after, size).await?;
        let next = super::paging::next("jobs", &items, size, |j| j.seq);
        Ok((items, next))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn body_errors_name_the_field() {
        let field = |v: Value| match parse_body::<JobRequest>(v) {
            Err(Error::Unprocessable { field, .. }) => field,
            other => panic!("{other:?}"),
        };
        assert_eq!(field(serde_json::json!({"model": "MVF"})), "dataset_id");
        assert_eq!(
            field(
                serde_json::json!({"dataset_id": "d", "model": "MVF", "training": {"epochs": "x"}})
            ),
            "training.epochs"
        );
    }
}
