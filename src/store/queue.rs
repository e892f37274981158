//! The queue's worker side: atomic claim (counting dead workers), leases with heartbeats,
//! fencing of every worker write by (job, attempt, owner), checkpoints, and the ends of a job.

use sqlx::Row;

use super::jobs::{JobRow, row, sql};
use super::{Store, now_ms, now_rfc3339, sha256_hex, verified};
use crate::error::{Error, Result};
use crate::records::JobState;
use crate::records::Metric;

/// A job a worker holds: fenced writes name this attempt and owner.
#[derive(Debug, Clone)]
pub struct Claimed {
    pub job: JobRow,
    pub attempt: i64,
    pub owner: String,
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
        m: &Metric,
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

    /// Gives back every job `owner` holds, without its fence's attempt: a process exiting
    /// before its training threads reached an epoch end (forced shutdown) cannot name their
    /// claims, and a job whose lease merely expired would wait out the lease and count as a
    /// dead worker. The abandoned threads' later writes fail their fence (the job is no longer
    /// running under this owner). Returns the jobs given back.
    pub async fn release_owned(&self, owner: &str) -> Result<u64> {
        let r = sqlx::query(
            "UPDATE jobs SET state = 'queued', lease_owner = NULL, lease_expires_ms = NULL
             WHERE state = 'running' AND lease_owner = ?",
        )
        .bind(owner)
        .execute(&self.pool)
        .await?;
        Ok(r.rows_affected())
    }

    pub async fn infra_failures(&self, job_id: &str) -> Result<i64> {
        Ok(
            sqlx::query_scalar("SELECT infra_failures FROM jobs WHERE id = ?")
                .bind(job_id)
                .fetch_one(&self.pool)
                .await?,
        )
    }
}
