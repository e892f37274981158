//! Jobs as submitted and read: submission (idempotent, checked against its datasets in the
//! same transaction), listing, cancellation, per-epoch metrics and counts. The worker's side
//! of the queue is in `queue.rs`.

use sqlx::{FromRow, Row};

use super::dialect::{Dialect, begin_write};
use super::{Store, new_id, now_rfc3339, sha256_hex};
use crate::error::{Error, Result};
use crate::records::JobState;
use crate::records::{Job, Metric};

/// A job as stored: the record and what only the queue reads.
#[derive(Debug, Clone, PartialEq, sqlx::FromRow)]
pub struct JobRow {
    #[sqlx(flatten)]
    pub info: Job,
    pub seq: i64,
    /// The normalized submission (JSON).
    pub request: String,
    pub cancel_requested: bool,
}

impl std::ops::Deref for JobRow {
    type Target = Job;
    fn deref(&self) -> &Job {
        &self.info
    }
}

impl From<JobRow> for Job {
    fn from(r: JobRow) -> Self {
        r.info
    }
}

const COLUMNS: &str = "seq, id, state, epoch, epochs, checkpoint_epoch, train_loss, val_loss, val_horizon_loss, best_val_loss, \
    attempt, error, model_id, dataset_id, validation_dataset_id, created_at, started_at, finished_at, \
    request, cancel_requested, warnings";

pub(super) fn sql<D: Dialect>(s: &'static str) -> sqlx::AssertSqlSafe<String> {
    super::dialect::sql::<D>(s, COLUMNS)
}

/// A job's row: its columns, then the fields the stored request holds (`name`, `model`,
/// `training`), read once here.
pub(super) fn row<R: sqlx::Row>(r: &R) -> Result<JobRow>
where
    JobRow: for<'r> FromRow<'r, R>,
{
    let mut job = JobRow::from_row(r)?;
    let submitted: serde_json::Value = serde_json::from_str(&job.request).unwrap_or_default();
    job.info.model = (submitted["model_name"].as_str())
        .unwrap_or("custom")
        .to_string();
    job.info.training = submitted["training"].clone();
    job.info.name = submitted["name"].as_str().map(String::from);
    // A multi-step job validates on windows of its horizon when its set has them, and then
    // reports their losses in val_horizon_loss beside the one-step val_loss.
    let steps = match job.info.val_horizon_loss {
        Some(_) => submitted["training"]["horizon"].as_i64().unwrap_or(1),
        None => 1,
    };
    job.info.best_val_loss_steps = job.info.best_val_loss.map(|_| steps);
    Ok(job)
}

pub struct NewJob {
    pub dataset_id: String,
    pub validation_dataset_id: Option<String>,
    /// The normalized request, JSON.
    pub request: String,
    pub epochs: i64,
    pub idempotency_key: Option<String>,
    /// The stored template the request named, kept from deletion while the job is queued or
    /// running.
    pub template_id: Option<String>,
}

#[derive(Debug)]
pub enum Submitted {
    Created(JobRow),
    /// Same idempotency key, same request: the job created the first time.
    Existing(JobRow),
}

const DATASETS_WITH_ID: &str = "SELECT COUNT(*) FROM datasets WHERE id = $1";
const TEMPLATES_WITH_ID: &str = "SELECT COUNT(*) FROM templates WHERE id = $1";

impl Store {
    pub async fn submit_job(&self, new: NewJob) -> Result<Submitted> {
        on_db!(self, pool, D => {
            let request_sha = sha256_hex(new.request.as_bytes());
            let mut tx = begin_write(pool).await?;
            if let Some(key) = &new.idempotency_key {
                let existing = sqlx::query(sql::<D>(
                    "SELECT {COLUMNS}, request_sha256 FROM jobs WHERE idempotency_key = $1",
                ))
                .bind(key)
                .fetch_optional(&mut *tx)
                .await?;
                if let Some(r) = existing {
                    let sha: Option<String> = r.try_get("request_sha256")?;
                    tx.commit().await?;
                    if sha.as_deref() != Some(request_sha.as_str()) {
                        return Err(Error::Unprocessable {
                            field: "Idempotency-Key".into(),
                            message: "this key was used with a different request".into(),
                        });
                    }
                    return Ok(Submitted::Existing(row(&r)?));
                }
            }
            // Inside the write transaction, so that a concurrent DELETE of a dataset or of the
            // template either runs first (and this submission fails) or sees this job and
            // refuses.
            for (field, what, count, id) in [
                ("dataset_id", "dataset", DATASETS_WITH_ID, Some(&new.dataset_id)),
                ("validation_dataset_id", "dataset", DATASETS_WITH_ID, new.validation_dataset_id.as_ref()),
                ("template", "template", TEMPLATES_WITH_ID, new.template_id.as_ref()),
            ] {
                let Some(id) = id else { continue };
                let found: i64 = if super::could_be_id(id) {
                    sqlx::query_scalar(count).bind(id).fetch_one(&mut *tx).await?
                } else {
                    0
                };
                if found == 0 {
                    return Err(Error::Unprocessable {
                        field: field.into(),
                        message: format!("{what} {} does not exist", id.escape_debug()),
                    });
                }
            }
            let r = sqlx::query(sql::<D>(
                "INSERT INTO jobs (id, state, dataset_id, validation_dataset_id, request, epochs,
                                   idempotency_key, request_sha256, created_at, template_id)
                 VALUES ($1, 'queued', $2, $3, $4, $5, $6, $7, $8, $9) RETURNING {COLUMNS}",
            ))
            .bind(new_id("job"))
            .bind(&new.dataset_id)
            .bind(&new.validation_dataset_id)
            .bind(&new.request)
            .bind(new.epochs)
            .bind(&new.idempotency_key)
            .bind(&request_sha)
            .bind(now_rfc3339())
            .bind(&new.template_id)
            .fetch_one(&mut *tx)
            .await?;
            tx.commit().await?;
            Ok(Submitted::Created(row(&r)?))
        })
    }

    pub async fn get_job(&self, id: &str) -> Result<Option<JobRow>> {
        if !super::could_be_id(id) {
            return Ok(None);
        }
        on_db!(self, pool, D => {
            let r = sqlx::query(sql::<D>("SELECT {COLUMNS} FROM jobs WHERE id = $1"))
                .bind(id)
                .fetch_optional(pool)
                .await?;
            r.as_ref().map(row).transpose()
        })
    }

    /// Newest first (a new job is on the first page); `before` is the `seq` of the last row
    /// of the previous page.
    pub async fn list_jobs(
        &self,
        state: Option<JobState>,
        before: Option<i64>,
        limit: i64,
    ) -> Result<Vec<JobRow>> {
        on_db!(self, pool, D => {
            let rows = sqlx::query(sql::<D>(
                "SELECT {COLUMNS} FROM jobs WHERE seq < $1 AND ($2 IS NULL OR state = $2) ORDER BY seq DESC LIMIT $3",
            ))
            .bind(before.unwrap_or(i64::MAX))
            .bind(state.map(JobState::as_str))
            .bind(limit)
            .fetch_all(pool)
            .await?;
            rows.iter().map(row).collect()
        })
    }

    /// The newest job's `seq` (0 with none).
    pub async fn max_job_seq(&self) -> Result<i64> {
        on_db!(self, pool, D => {
            let seq: Option<i64> = sqlx::query_scalar("SELECT MAX(seq) FROM jobs")
                .fetch_one(pool)
                .await?;
            Ok(seq.unwrap_or(0))
        })
    }

    /// What a watcher of every job reads each poll: the jobs submitted after `after` and
    /// every queued or running one.
    pub async fn watched_jobs(&self, after: i64) -> Result<Vec<JobRow>> {
        on_db!(self, pool, D => {
            let rows = sqlx::query(sql::<D>(
                "SELECT {COLUMNS} FROM jobs WHERE seq > $1 OR state IN ('queued', 'running') ORDER BY seq",
            ))
            .bind(after)
            .fetch_all(pool)
            .await?;
            rows.iter().map(row).collect()
        })
    }

    /// Queued, or running with an expired lease (its worker died) → cancelled at once; running
    /// → the cancel flag, which the worker sees at its next heartbeat. A finished job is a
    /// conflict.
    pub async fn cancel_job(&self, id: &str) -> Result<JobRow> {
        if !super::could_be_id(id) {
            return Err(Error::NotFound(format!("job {}", id.escape_debug())));
        }
        on_db!(self, pool, D => {
            let mut tx = begin_write(pool).await?;
            let r = sqlx::query(sql::<D>("UPDATE jobs SET
                    state = CASE WHEN state = 'queued' OR (state = 'running' AND lease_expires_ms < {NOW_MS})
                                 THEN 'cancelled' ELSE state END,
                    finished_at = CASE WHEN state = 'queued' OR (state = 'running' AND lease_expires_ms < {NOW_MS})
                                 THEN $2 ELSE finished_at END,
                    cancel_requested = CASE state WHEN 'running' THEN TRUE ELSE cancel_requested END
                 WHERE id = $1 RETURNING {COLUMNS}"))
            .bind(id)
            .bind(now_rfc3339())
            .fetch_optional(&mut *tx)
            .await?;
            tx.commit().await?;
            let job = r
                .as_ref()
                .map(row)
                .transpose()?
                .ok_or_else(|| Error::NotFound(format!("job {id}")))?;
            match job.state {
                JobState::Succeeded | JobState::Failed => Err(Error::Conflict(format!(
                    "job {id} already {}",
                    job.state.as_str()
                ))),
                _ => Ok(job),
            }
        })
    }

    pub async fn metrics(&self, job_id: &str, after_epoch: i64) -> Result<Vec<Metric>> {
        if !super::could_be_id(job_id) {
            return Ok(Vec::new());
        }
        on_db!(self, pool, D => {
            Ok(sqlx::query_as(
                "SELECT epoch, train_loss, val_loss, val_horizon_loss, seconds, train_loss_std,
                    val_loss_std FROM metrics
                 WHERE job_id = $1 AND epoch > $2 ORDER BY epoch",
            )
            .bind(job_id)
            .bind(after_epoch)
            .fetch_all(pool)
            .await?)
        })
    }

    pub async fn job_counts(&self) -> Result<Vec<(JobState, i64)>> {
        on_db!(self, pool, D => {
            let rows = sqlx::query("SELECT state, COUNT(*) AS c FROM jobs GROUP BY state")
                .fetch_all(pool)
                .await?;
            let mut out: Vec<(JobState, i64)> = JobState::ALL.iter().map(|s| (*s, 0)).collect();
            for r in rows {
                let s: String = r.try_get("state")?;
                if let Some(slot) = out.iter_mut().find(|(st, _)| st.as_str() == s) {
                    slot.1 = r.try_get("c")?;
                }
            }
            Ok(out)
        })
    }
}
