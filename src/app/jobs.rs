//! Job submission: the whole request is validated here, at submission, so that a job that
//! cannot train never enters the queue.

use crate::physics::templates::Template;
use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::App;
use super::views::Stored;
use crate::error::{Error, Result};
use crate::model::spec::ModelSpec;
use crate::records::{DatasetInfo, Job, JobState, Metric};
use crate::store::{NewJob, Submitted};
use crate::train::TrainConfig;
use crate::train::setup::physical_init;

/// The body of POST /v1/jobs.
#[derive(Debug, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct JobRequest {
    /// A name for the job and the model it trains (shown in every list) [default: the
    /// model's name].
    #[serde(default)]
    pub name: Option<String>,
    pub dataset_id: String,
    #[serde(default)]
    pub validation_dataset_id: Option<String>,
    /// A paper name ("MVF", …, "W-B", "naive") or a JSON model spec.
    #[schema(value_type = Object)]
    pub model: Value,
    /// A built-in template's name, a stored template's id (POST /v1/templates), or a formula
    /// template's document (README "Your own mechanism").
    #[serde(default)]
    #[schema(value_type = Option<Object>)]
    pub template: Option<Value>,
    #[serde(default)]
    pub init: Option<BTreeMap<String, f64>>,
    /// Which coordinates are angles (README "Periodic coordinates") [default: the
    /// template's own `periodic`, else none].
    #[serde(default)]
    pub periodic: Option<Vec<bool>>,
    #[serde(default)]
    #[schema(value_type = Option<Object>)]
    pub training: Option<TrainConfig>,
}

/// The validated job as stored (and as the worker reads it back).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobSpec {
    /// The name the job was given (its model takes it), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    pub model_name: String,
    pub spec: ModelSpec,
    pub init: Vec<(String, f64)>,
    pub training: TrainConfig,
    pub dataset_id: String,
    pub validation_dataset_id: Option<String>,
}

impl JobSpec {
    /// The trained model's name: the job's, else its model's.
    pub fn display_name(&self) -> &str {
        self.name.as_deref().unwrap_or(&self.model_name)
    }

    pub fn from_json(s: &str) -> Result<Self> {
        serde_json::from_str(s).map_err(|e| Error::corrupt("job request", e))
    }
}

/// A job's name, trimmed: not empty, and a name by the one rule for names (`crate::names`).
fn check_name(name: &str) -> Result<String> {
    let name = name.trim();
    if name.is_empty() {
        return Err(Error::Unprocessable {
            field: "name".into(),
            message: "must not be empty (leave it out for the model's name)".into(),
        });
    }
    crate::names::check_name_at("name", name)?;
    Ok(name.to_string())
}

/// A request's template document (errors name `template.<field>`).
fn parse_template(t: &Value, max_dof: usize) -> Result<Template> {
    Template::from_document_within(t, max_dof).map_err(|e| match e {
        Error::Unprocessable { field, message } => Error::Unprocessable {
            field: if field == "template" {
                field
            } else {
                format!("template.{field}")
            },
            message: super::requests::in_words(&message),
        },
        other => other,
    })
}

/// The model of a request: a paper name ("MVF", …) or a spec object, with an optional
/// template for its white-box parts.
fn parse_model(model: &Value, template: Option<Template>) -> Result<(String, ModelSpec)> {
    let (name, spec) = match model {
        Value::String(name) => (name.clone(), ModelSpec::named(name, template)),
        Value::Object(_) => (
            "custom".to_string(),
            ModelSpec::parse(&model.to_string(), template),
        ),
        _ => {
            return Err(Error::Unprocessable {
                field: "model".into(),
                message: "must be a model name or a spec object".into(),
            });
        }
    };
    Ok((name, spec.map_err(Error::unprocessable)?))
}

impl App {
    /// Validates a request against its datasets and queues it (or returns the job an earlier
    /// request with the same idempotency key created).
    pub async fn submit_job(
        &self,
        req: JobRequest,
        idempotency_key: Option<String>,
    ) -> Result<Stored<Job>> {
        let (spec, template_id) = self.validate_job(req).await?;
        let new = NewJob {
            dataset_id: spec.dataset_id.clone(),
            validation_dataset_id: spec.validation_dataset_id.clone(),
            request: serde_json::to_string(&spec).expect("job specs serialize"),
            epochs: spec.training.epochs as i64,
            idempotency_key,
            template_id,
        };
        let (job, created) = match self.store.submit_job(new).await? {
            Submitted::Created(job) => (job, true),
            Submitted::Existing(job) => (job, false),
        };
        Ok(Stored {
            item: job.into(),
            created,
        })
    }

    /// A request's template and, when it names a stored one, that template's id.
    async fn request_template(&self, t: Value) -> Result<(Template, Option<String>)> {
        let Value::String(name) = t else {
            let max_dof = self.settings.max_dof;
            let parsed = super::templates::off_executor(move || parse_template(&t, max_dof));
            return Ok((parsed.await?, None));
        };
        if let Some(builtin) = Template::from_name(&name) {
            return Ok((builtin, None));
        }
        match self.stored_template(&name).await? {
            Some(stored) => Ok((stored, Some(name))),
            None => Err(Error::Unprocessable {
                field: "template".into(),
                message: format!(
                    "{name:?} is neither a built-in template ({}) nor a stored template's id",
                    Template::ALL.map(|t| t.name().to_string()).join(", ")
                ),
            }),
        }
    }

    async fn validate_job(&self, req: JobRequest) -> Result<(JobSpec, Option<String>)> {
        let name = req.name.as_deref().map(check_name).transpose()?;
        let mut training = req.training.unwrap_or_default();
        if !training.periodic.is_empty() {
            return Err(Error::Unprocessable {
                field: "training.periodic".into(),
                message: "give it as the job's own \"periodic\"".into(),
            });
        }
        training.periodic = req.periodic.unwrap_or_default();
        training.validate().map_err(Error::unprocessable)?;
        let (template, template_id) = match req.template {
            None => (None, None),
            Some(t) => {
                let (t, id) = self.request_template(t).await?;
                (Some(t), id)
            }
        };
        let (model_name, spec) = parse_model(&req.model, template)?;
        spec.check_trainable().map_err(Error::unprocessable)?;
        training.check_for(&spec).map_err(Error::unprocessable)?;
        let init: Vec<(String, f64)> = req.init.unwrap_or_default().into_iter().collect();
        physical_init(&spec, &init).map_err(Error::unprocessable)?;
        let job = JobSpec {
            name,
            model_name,
            spec,
            init,
            training,
            dataset_id: req.dataset_id,
            validation_dataset_id: req.validation_dataset_id,
        };
        let (data, val_count) = self.check_datasets(&job).await?;
        self.check_horizon_fits(&job, &data).await?;
        self.check_job_cost(&job, &data, val_count)?;
        self.check_job_data(&job).await?;
        Ok((job, template_id))
    }

    /// A multi-step job's horizon against its data's longest trajectory as far as the row
    /// tells without the rows (uploaded boundaries, else the row count): first, so that a
    /// horizon no trajectory holds is refused as such, not by the memory its windows would
    /// take. The rows' own check (chains, the training split) comes with the data checks.
    async fn check_horizon_fits(&self, job: &JobSpec, data: &DatasetInfo) -> Result<()> {
        let horizon = job.training.horizon;
        if horizon <= 1 {
            return Ok(());
        }
        let stored = self.store.dataset_trajectories(&data.id).await?.flatten();
        let longest = match stored {
            Some(lengths) => lengths.into_iter().max().unwrap_or(0),
            None => data.count.max(0) as usize,
        };
        crate::train::windows::check_longest(longest, horizon).map_err(Error::unprocessable)
    }

    /// The job's datasets exist and fit its model and each other; the training dataset and
    /// the validation dataset's size.
    async fn check_datasets(&self, job: &JobSpec) -> Result<(DatasetInfo, usize)> {
        let find = |field: &'static str, id: String| async move {
            self.store
                .get_dataset(&id)
                .await?
                .map(DatasetInfo::from)
                .ok_or_else(|| Error::Unprocessable {
                    field: field.into(),
                    message: format!("dataset {id} does not exist"),
                })
        };
        let data = find("dataset_id", job.dataset_id.clone()).await?;
        let space =
            crate::train::setup::run_space(&job.spec, &job.training, (data.nq(), data.nv()))
                .map_err(Error::unprocessable)?;
        job.spec
            .check_dims(&space, data.m as usize)
            .map_err(Error::unprocessable)?;
        let Some(vid) = &job.validation_dataset_id else {
            if job.training.val_fraction > 0.0 && data.count < 2 {
                return Err(Error::Unprocessable {
                    field: "training.val_fraction".into(),
                    message: "a dataset of one transition cannot be split; set it to 0 or give validation_dataset_id".into(),
                });
            }
            return Ok((data, 0));
        };
        let v = find("validation_dataset_id", vid.clone()).await?;
        if (v.nq, v.nv, v.m) != (data.nq, data.nv, data.m)
            || (v.dt - data.dt).abs() > 1e-12 * data.dt
        {
            return Err(Error::Unprocessable {
                field: "validation_dataset_id".into(),
                message: format!(
                    "has nq = {}, nv = {}, m = {}, dt = {} but the training dataset has nq = {}, \
                     nv = {}, m = {}, dt = {}",
                    v.nq, v.nv, v.m, v.dt, data.nq, data.nv, data.m, data.dt
                ),
            });
        }
        Ok((data, v.count as usize))
    }

    /// The scalings training derives from the data must be finite (values near the f64
    /// range overflow them), else the job would "succeed" with a model that cannot answer.
    async fn check_job_data(&self, job: &JobSpec) -> Result<()> {
        let data = self
            .store
            .load_dataset(&job.dataset_id)
            .await?
            .ok_or_else(|| Error::Unprocessable {
                field: "dataset_id".into(),
                message: format!("dataset {} does not exist", job.dataset_id),
            })?;
        let job = job.clone();
        tokio::task::spawn_blocking(move || {
            let physical = physical_init(&job.spec, &job.init)?;
            crate::train::setup::run_space(&job.spec, &job.training, (data.nq, data.nv))?;
            crate::train::setup::scaling(&job.spec, physical.as_deref(), &data)?;
            check_windows(&job, &data)
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

    pub async fn job(&self, id: &str) -> Result<Job> {
        self.store
            .get_job(id)
            .await?
            .map(Job::from)
            .ok_or_else(|| Error::NotFound(format!("job {id}")))
    }

    pub async fn job_metrics(&self, id: &str) -> Result<Vec<Metric>> {
        self.job(id).await?;
        self.metrics_after(id, 0).await
    }

    /// A job's metrics after `epoch`, in order.
    pub(super) async fn metrics_after(&self, id: &str, epoch: i64) -> Result<Vec<Metric>> {
        self.store.metrics(id, epoch).await
    }

    pub async fn cancel_job(&self, id: &str) -> Result<Job> {
        self.store.cancel_job(id).await.map(Job::from)
    }

    pub async fn list_jobs(
        &self,
        state: Option<&str>,
        size: Option<i64>,
        token: Option<&str>,
    ) -> Result<(Vec<Job>, Option<String>)> {
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
        let before = super::paging::decode("jobs", token)?;
        let items = self.store.list_jobs(state, before, size).await?;
        let next = super::paging::next("jobs", &items, size, |j| j.seq);
        Ok((items.into_iter().map(Job::from).collect(), next))
    }
}

/// A multi-step job's training data (what is left after the validation split) has a
/// trajectory as long as its horizon.
fn check_windows(job: &JobSpec, data: &crate::data::Dataset) -> Result<()> {
    let t = &job.training;
    if t.horizon == 1 {
        return Ok(());
    }
    if job.validation_dataset_id.is_some() || t.val_fraction == 0.0 || data.count() < 2 {
        return crate::train::windows::check(data, t.horizon);
    }
    let (train, _) = data.split_by_trajectories(t.val_fraction, t.seed);
    crate::train::windows::check(&train, t.horizon)
}
