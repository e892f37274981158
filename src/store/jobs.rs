//! The persistent job queue: atomic claim, leases with heartbeats, fencing by (job, attempt),
//! cancellation, per-epoch metrics (upserted) and checkpoints.

use serde::Serialize;
use sqlx::Row;
use sqlx::sqlite::SqliteRow;

use super::{Store, new_id, now_ms, now_rfc3339, sha256_hex, verified};
use crate::error::{Error, Result};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum JobState {
    Queued,
    Running,
    Succeeded,
    Failed,
    Cancelled,
}

impl JobState {
    pub const ALL: [JobState; 5] = [
        JobState::Queued,
        JobState::Running,
        JobState::Succeeded,
        JobState::Failed,
        JobState::Cancelled,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            JobState::Queued => "queued",
            JobState::Running => "running",
            JobState::Succeeded => "succeeded",
            JobState::Failed => "failed",
            JobState::Cancelled => "cancelled",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|j| j.as_str() == s)
    }

    pub fn is_final(self) -> bool {
        matches!(
            self,
            JobState::Succeeded | JobState::Failed | JobState::Cancelled
        )
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct JobRow {
    pub id: String,
    pub state: JobState,
    /// Last completed epoch, counting from 1 (0 before the first).
    pub epoch: i64,
    pub epochs: i64,
    pub checkpoint_epoch: i64,
    pub train_loss: Option<f64>,
    pub val_loss: Option<f64>,
    pub best_val_loss: Option<f64>,
    pub attempt: i64,
    pub error: Option<String>,
    pub model_id: Option<String>,
    pub dataset_id: String,
    pub validation_dataset_id: Option<String>,
    pub created_at: String,
    pub started_at: Option<String>,
    pub finished_at: Option<String>,
    #[serde(skip)]
    pub seq: i64,
    /// The normalized submission (JSON).
    #[serde(skip)]
    pub request: String,
    #[serde(skip)]
    pub cancel_requested: bool,
}

const COLUMNS: &str = "seq, id, state, epoch, epochs, checkpoint_epoch, train_loss, val_loss, best_val_loss, \
    attempt, error, model_id, dataset_id, validation_dataset_id, created_at, started_at, finished_at, \
    request, cancel_requested";

fn sql(s: &'static str) -> sqlx::AssertSqlSafe<String> {
    sqlx::AssertSqlSafe(s.replace("{COLUMNS}", COLUMNS))
}

fn row(r: &SqliteRow) -> Result<JobRow> {
    let state: String = r.try_get("state")?;
    Ok(JobRow {
        seq: r.try_get("seq")?,
        id: r.try_get("id")?,
        state: JobState::parse(&state)
            .ok_or_else(|| Error::Storage(format!("unknown job state {state}")))?,
        epoch: r.try_get("epoch")?,
        epochs: r.try_get("epochs")?,
        checkpoint_epoch: r.try_get("checkpoint_epoch")?,
        train_loss: r.try_get("train_loss")?,
        val_loss: r.try_get("val_loss")?,
        best_val_loss: r.try_get("best_val_loss")?,
        attempt: r.try_get("attempt")?,
        error: r.try_get("error")?,
        model_id: r.try_get("model_id")?,
        dataset_id: r.try_get("dataset_id")?,
        validation_dataset_id: r.try_get("validation_dataset_id")?,
        created_at: r.try_get("created_at")?,
        started_at: r.try_get("started_at")?,
        finished_at: r.try_get("finished_at")?,
        request: r.try_get("request")?,
        cancel_requested: r.try_get::<i64, _>("cancel_requested")? != 0,
    })
}

pub struct NewJob {
    pub dataset_id: String,
    pub validation_dataset_id: Option<String>,
    /// The normalized request, JSON.
    pub request: String,
    pub epochs: i64,
    pub idempotency_key: Option<String>,
}

pub enum Submitted {
    Created(JobRow),
    /// Same idempotency key, same request: the job created the first time.
    Existing(JobRow),
}

/// A job a worker holds: fenced writes name this attempt and owner.
#[derive(Debug, Clone)]
pub struct Claimed {
    pub job: JobRow,
    pub attempt: i64,
    pub owner: String,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, utoipa::ToSchema)]
pub struct MetricRow {
    pub epoch: i64,
    pub train_loss: f64,
    pub val_loss: Option<f64>,
    pub seconds: f64,
}

/// What a heartbeat learned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lease {
    Held {
        cancel_requested: bool,
    },
    /// Another attempt owns the job (our lease expired and it was reclaimed) or it ended.
    Lost,
}

/// Every worker write names the job, the attempt and the owner it claimed with: a worker whose
/// lease expired (and whose job was reclaimed) can no longer write. Bind with [`fenced`].
pub(super) const FENCE: &str = "id = ? AND attempt = ? AND lease_owner = ? AND state = 'running'";

pub(super) type SqliteQuery<'q> =
    sqlx::query::Query<'q, sqlx::Sqlite, <sqlx::Sqlite as sqlx::Database>::Arguments>;

/// Binds the [`FENCE`] parameters after the statement's own.
pub(super) fn fenced<'q>(q: SqliteQuery<'q>, c: &Claimed) -> SqliteQuery<'q> {
    q.bind(c.job.id.clone())
        .bind(c.attempt)
        .bind(c.owner.clone())
}

/// SQLite refuses a blob over its length limit (SQLITE_TOOBIG): no retry can store it, so
/// it is not a storage fault but a job that cannot be checkpointed.
fn too_big(e: sqlx::Error, len: usize) -> Error {
    match &e {
        sqlx::Error::Database(db)
            if db.code().as_deref() == Some("18") || db.message().contains("too big") =>
        {
            Error::ResourceExhausted(format!(
                "the checkpoint ({} MB) is larger than the store can hold",
                len >> 20
            ))
        }
        _ => e.into(),
    }
}

impl Store {
    pub async fn submit_job(&self, new: NewJob) -> Result<Submitted> {
        let request_sha = sha256_hex(new.request.as_bytes());
        let mut tx = self.write().await?;
        if let Some(key) = &new.idempotency_key {
            let existing = sqlx::query(sql(
                "SELECT {COLUMNS}, request_sha256 FROM jobs WHERE idempotency_key = ?",
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
        // Inside the write transaction, so that a concurrent DELETE of a dataset either runs
        // first (and this submission fails) or sees this job and refuses.
        for (field, id) in [
            ("dataset_id", Some(&new.dataset_id)),
            ("validation_dataset_id", new.validation_dataset_id.as_ref()),
        ] {
            let Some(id) = id else { continue };
            let found: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM datasets WHERE id = ?")
                .bind(id)
                .fetch_one(&mut *tx)
                .await?;
            if found == 0 {
                return Err(Error::Unprocessable {
                    field: field.into(),
                    message: format!("dataset {id} does not exist"),
                });
            }
        }
        let r = sqlx::query(sql(
            "INSERT INTO jobs (id, state, dataset_id, validation_dataset_id, request, epochs,
                               idempotency_key, request_sha256, created_at)
             VALUES (?, 'queued', ?, ?, ?, ?, ?, ?, ?) RETURNING {COLUMNS}",
        ))
        .bind(new_id("job"))
        .bind(&new.dataset_id)
        .bind(&new.validation_dataset_id)
        .bind(&new.request)
        .bind(new.epochs)
        .bind(&new.idempotency_key)
        .bind(&request_sha)
        .bind(now_rfc3339())
        .fetch_one(&mut *tx)
        .await?;
        tx.commit().await?;
        Ok(Submitted::Created(row(&r)?))
    }

    pub async fn get_job(&self, id: &str) -> Result<Option<JobRow>> {
        let r = sqlx::query(sql("SELECT {COLUMNS} FROM jobs WHERE id = ?"))
            .bind(id)
            .fetch_optional(&self.pool)
            .await?;
        r.as_ref().map(row).transpose()
    }

    /// Oldest first; `after` is the `seq` of the last row of the previous page.
    pub async fn list_jobs(
        &self,
        state: Option<JobState>,
        after: Option<i64>,
        limit: i64,
    ) -> Result<Vec<JobRow>> {
        let rows = sqlx::query(sql(
            "SELECT {COLUMNS} FROM jobs WHERE seq > ?1 AND (?2 IS NULL OR state = ?2) ORDER BY seq LIMIT ?3",
        ))
        .bind(after.unwrap_or(0))
        .bind(state.map(JobState::as_str))
        .bind(limit)
        .fetch_all(&self.pool)
        .await?;
        rows.iter().map(row).collect()
    }

    /// Queued, or running with an expired lease (its worker died) → cancelled at once; running
    /// → the cancel flag, which the worker sees at its next heartbeat. A finished job is a
    /// conflict.
    pub async fn cancel_job(&self, id: &str) -> Result<JobRow> {
        let mut tx = self.write().await?;
        let r = sqlx::query(sql("UPDATE jobs SET
                state = CASE WHEN state = 'queued' OR (state = 'running' AND lease_expires_ms < ?3)
                             THEN 'cancelled' ELSE state END,
                finished_at = CASE WHEN state = 'queued' OR (state = 'running' AND lease_expires_ms < ?3)
                             THEN ?2 ELSE finished_at END,
                cancel_requested = CASE state WHEN 'running' THEN 1 ELSE cancel_requested END
             WHERE id = ?1 RETURNING {COLUMNS}"))
        .bind(id)
        .bind(now_rfc3339())
        .bind(now_ms())
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
    }

    /// Claims the oldest queued job, or a running one whose lease expired (its worker died:
    /// counted), in one transaction. An expired job that was asked to cancel is cancelled, and
    /// one whose worker died `max_attempts` times fails, instead of running again.
    pub async fn claim_job(
        &self,
        owner: &str,
        lease_ms: i64,
        max_attempts: i64,
    ) -> Result<Option<Claimed>> {
        let now = now_ms();
        let mut tx = self.write().await?;
        const EXPIRED: &str = "state = 'running' AND lease_expires_ms < ?1";
        sqlx::query(sqlx::AssertSqlSafe(format!(
            "UPDATE jobs SET state = 'cancelled', finished_at = ?2, lease_owner = NULL,
                lease_expires_ms = NULL WHERE {EXPIRED} AND cancel_requested = 1"
        )))
        .bind(now)
        .bind(now_rfc3339())
        .execute(&mut *tx)
        .await?;
        sqlx::query(sqlx::AssertSqlSafe(format!(
            "UPDATE jobs SET state = 'failed', worker_deaths = worker_deaths + 1,
                error = 'the worker died ' || (worker_deaths + 1) || ' times running this job',
                finished_at = ?2, lease_owner = NULL, lease_expires_ms = NULL
             WHERE {EXPIRED} AND worker_deaths + 1 >= ?3"
        )))
        .bind(now)
        .bind(now_rfc3339())
        .bind(max_attempts)
        .execute(&mut *tx)
        .await?;
        let r = sqlx::query(sql(
            "UPDATE jobs SET state = 'running', attempt = attempt + 1, lease_owner = ?1,
                worker_deaths = worker_deaths + (state = 'running'),
                lease_expires_ms = ?2 + ?3, heartbeat_ms = ?2, started_at = COALESCE(started_at, ?4)
             WHERE id = (SELECT id FROM jobs
                         WHERE state = 'queued' OR (state = 'running' AND lease_expires_ms < ?2)
                         ORDER BY seq LIMIT 1)
             RETURNING {COLUMNS}",
        ))
        .bind(owner)
        .bind(now)
        .bind(lease_ms)
        .bind(now_rfc3339())
        .fetch_optional(&mut *tx)
        .await?;
        tx.commit().await?;
        Ok(match r {
            Some(r) => {
                let job = row(&r)?;
                Some(Claimed {
                    attempt: job.attempt,
                    owner: owner.to_string(),
                    job,
                })
            }
            None => None,
        })
    }

    pub async fn heartbeat(&self, c: &Claimed, lease_ms: i64) -> Result<Lease> {
        let now = now_ms();
        let r = fenced(
        sqlx::query(sqlx::AssertSqlSafe(format!(
            "UPDATE jobs SET lease_expires_ms = ? + ?, heartbeat_ms = ? WHERE {FENCE} RETURNING cancel_requested"
        )))
        .bind(now)
        .bind(lease_ms)
        .bind(now),
        c,
    )
        .fetch_optional(&self.pool)
        .await?;
        Ok(match r {
            Some(r) => Lease::Held {
                cancel_requested: r.try_get::<i64, _>("cancel_requested")? != 0,
            },
            None => Lease::Lost,
        })
    }

    /// Records one finished epoch (metrics upserted by (job, epoch)) and the job's progress, in
    /// one transaction; false when the lease was lost.
    pub async fn record_epoch(
        &self,
        c: &Claimed,
        m: &MetricRow,
        best_val_loss: Option<f64>,
    ) -> Result<bool> {
        let mut tx = self.write().await?;
        let updated = fenced(
        sqlx::query(sqlx::AssertSqlSafe(format!(
            "UPDATE jobs SET epoch = ?, train_loss = ?, val_loss = ?, best_val_loss = ? WHERE {FENCE}"
        )))
        .bind(m.epoch)
        .bind(m.train_loss)
        .bind(m.val_loss)
        .bind(best_val_loss),
        c,
    )
        .execute(&mut *tx)
        .await?;
        if updated.rows_affected() == 0 {
            return Ok(false);
        }
        sqlx::query(
            "INSERT INTO metrics (job_id, epoch, train_loss, val_loss, seconds) VALUES (?, ?, ?, ?, ?)
             ON CONFLICT (job_id, epoch) DO UPDATE SET
                train_loss = excluded.train_loss, val_loss = excluded.val_loss, seconds = excluded.seconds",
        )
        .bind(&c.job.id)
        .bind(m.epoch)
        .bind(m.train_loss)
        .bind(m.val_loss)
        .bind(m.seconds)
        .execute(&mut *tx)
        .await?;
        tx.commit().await?;
        Ok(true)
    }

    /// Replaces the job's checkpoint atomically (inside the transaction, so a crash leaves the
    /// previous one); false when the lease was lost.
    pub async fn save_checkpoint(&self, c: &Claimed, epoch: i64, state: &[u8]) -> Result<bool> {
        let mut tx = self.write().await?;
        let updated = fenced(
            sqlx::query(sqlx::AssertSqlSafe(format!(
                "UPDATE jobs SET checkpoint_epoch = ? WHERE {FENCE}"
            )))
            .bind(epoch),
            c,
        )
        .execute(&mut *tx)
        .await?;
        if updated.rows_affected() == 0 {
            return Ok(false);
        }
        sqlx::query(
            "INSERT INTO checkpoints (job_id, epoch, attempt, state, sha256, created_at) VALUES (?, ?, ?, ?, ?, ?)
             ON CONFLICT (job_id) DO UPDATE SET epoch = excluded.epoch, attempt = excluded.attempt,
                state = excluded.state, sha256 = excluded.sha256, created_at = excluded.created_at",
        )
        .bind(&c.job.id)
        .bind(epoch)
        .bind(c.attempt)
        .bind(state)
        .bind(sha256_hex(state))
        .bind(now_rfc3339())
        .execute(&mut *tx)
        .await
        .map_err(|e| too_big(e, state.len()))?;
        tx.commit().await?;
        Ok(true)
    }

    /// The last committed checkpoint (epoch, bytes), verified against its checksum.
    pub async fn load_checkpoint(&self, job_id: &str) -> Result<Option<(i64, Vec<u8>)>> {
        let r = sqlx::query("SELECT epoch, state, sha256 FROM checkpoints WHERE job_id = ?")
            .bind(job_id)
            .fetch_optional(&self.pool)
            .await?;
        let Some(r) = r else { return Ok(None) };
        let sha: String = r.try_get("sha256")?;
        let state = verified(r.try_get("state")?, &sha, "checkpoint", job_id)?;
        Ok(Some((r.try_get("epoch")?, state)))
    }

    /// Ends a held job in a final state (with its error message, if any); false when the lease
    /// was lost.
    pub async fn end_job(&self, c: &Claimed, state: JobState, error: Option<&str>) -> Result<bool> {
        let r = fenced(
        sqlx::query(sqlx::AssertSqlSafe(format!(
            "UPDATE jobs SET state = ?, error = ?, finished_at = ?, lease_owner = NULL, lease_expires_ms = NULL
             WHERE {FENCE}"
        )))
        .bind(state.as_str())
        .bind(error)
        .bind(now_rfc3339()),
        c,
    )
        .execute(&self.pool)
        .await?;
        Ok(r.rows_affected() == 1)
    }

    /// Gives a held job back to the queue (graceful shutdown, or an infrastructure failure
    /// that may succeed on retry).
    pub async fn release_job(&self, c: &Claimed, infra_failure: bool) -> Result<bool> {
        let r = fenced(
            sqlx::query(sqlx::AssertSqlSafe(format!(
                "UPDATE jobs SET state = 'queued', lease_owner = NULL, lease_expires_ms = NULL,
                infra_failures = infra_failures + ? WHERE {FENCE}"
            )))
            .bind(infra_failure as i64),
            c,
        )
        .execute(&self.pool)
        .await?;
        Ok(r.rows_affected() == 1)
    }

    pub async fn infra_failures(&self, job_id: &str) -> Result<i64> {
        Ok(
            sqlx::query_scalar("SELECT infra_failures FROM jobs WHERE id = ?")
                .bind(job_id)
                .fetch_one(&self.pool)
                .await?,
        )
    }

    pub async fn metrics(&self, job_id: &str, after_epoch: i64) -> Result<Vec<MetricRow>> {
        let rows = sqlx::query(
            "SELECT epoch, train_loss, val_loss, seconds FROM metrics WHERE job_id = ? AND epoch > ? ORDER BY epoch",
        )
        .bind(job_id)
        .bind(after_epoch)
        .fetch_all(&self.pool)
        .await?;
        rows.iter()
            .map(|r| {
                Ok(MetricRow {
                    epoch: r.try_get("epoch")?,
                    train_loss: r.try_get("train_loss")?,
                    val_loss: r.try_get("val_loss")?,
                    seconds: r.try_get("seconds")?,
                })
            })
            .collect()
    }

    pub async fn job_counts(&self) -> Result<Vec<(JobState, i64)>> {
        let rows = sqlx::query("SELECT state, COUNT(*) AS c FROM jobs GROUP BY state")
            .fetch_all(&self.pool)
            .await?;
        let mut out: Vec<(JobState, i64)> = JobState::ALL.iter().map(|s| (*s, 0)).collect();
        for r in rows {
            let s: String = r.try_get("state")?;
            if let Some(slot) = out.iter_mut().find(|(st, _)| st.as_str() == s) {
                slot.1 = r.try_get("c")?;
            }
        }
        Ok(out)
    }
}
