//! The queue's worker side: atomic claim (counting dead workers), leases with heartbeats,
//! fencing of every worker write by (job, attempt, owner), checkpoints, and the ends of a job.

use std::time::Duration;

use sqlx::Row;

use super::blobs::Kind;
use super::dialect::{Dialect, begin_write, owned_sql};
use super::jobs::{JobRow, row, sql};
use super::refs::Placed;
use super::{Store, now_rfc3339, sha256_hex, verified};
use crate::backoff::Backoff;
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
/// lease expired (and whose job was reclaimed) can no longer write. The condition, with its
/// parameters numbered after a statement's own `own`; bind them last, with [`fenced`].
pub(super) fn fence(own: usize) -> String {
    let p = |k: usize| own + k;
    format!(
        "id = ${} AND attempt = ${} AND lease_owner = ${} AND state = 'running'",
        p(1),
        p(2),
        p(3)
    )
}

/// Binds the [`fence`]'s parameters after the statement's own.
pub(super) fn fenced<'q, D: sqlx::Database>(
    q: sqlx::query::Query<'q, D, D::Arguments>,
    c: &Claimed,
) -> sqlx::query::Query<'q, D, D::Arguments>
where
    for<'t> String: sqlx::Encode<'t, D> + sqlx::Type<D>,
    for<'t> i64: sqlx::Encode<'t, D> + sqlx::Type<D>,
{
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
    /// one whose worker died `max_attempts` times fails, instead of running again. Leases are
    /// stamped and compared on the database's clock.
    pub async fn claim_job(
        &self,
        owner: &str,
        lease_ms: i64,
        max_attempts: i64,
    ) -> Result<Option<Claimed>> {
        on_db!(self, pool, D => {
            let mut tx = D::begin_claim(pool).await?;
            sqlx::query(sql::<D>(
                "UPDATE jobs SET state = 'cancelled', finished_at = $1, lease_owner = NULL,
                    lease_expires_ms = NULL WHERE state = 'running' AND lease_expires_ms < {NOW_MS} AND cancel_requested",
            ))
            .bind(now_rfc3339())
            .execute(&mut *tx)
            .await?;
            sqlx::query(sql::<D>(
                "UPDATE jobs SET state = 'failed', worker_deaths = worker_deaths + 1,
                    error = 'the worker died ' || (worker_deaths + 1) || ' times running this job',
                    finished_at = $1, lease_owner = NULL, lease_expires_ms = NULL
                 WHERE state = 'running' AND lease_expires_ms < {NOW_MS}
                    AND worker_deaths + 1 >= $2",
            ))
            .bind(now_rfc3339())
            .bind(max_attempts)
            .execute(&mut *tx)
            .await?;
            let r = sqlx::query(sql::<D>(
                "UPDATE jobs SET state = 'running', attempt = attempt + 1, lease_owner = $1,
                    worker_deaths = worker_deaths + CASE WHEN state = 'running' THEN 1 ELSE 0 END,
                    lease_expires_ms = {NOW_MS} + $2, heartbeat_ms = {NOW_MS},
                    started_at = COALESCE(started_at, $3)
                 WHERE id = (SELECT id FROM jobs
                             WHERE (state = 'queued' AND (not_before_ms IS NULL OR not_before_ms <= {NOW_MS}))
                                OR (state = 'running' AND lease_expires_ms < {NOW_MS})
                             ORDER BY seq LIMIT 1 {SKIP_LOCKED})
                 RETURNING {COLUMNS}",
            ))
            .bind(owner)
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
        })
    }

    pub async fn heartbeat(&self, c: &Claimed, lease_ms: i64) -> Result<Lease> {
        on_db!(self, pool, D => {
            let text = format!(
                "UPDATE jobs SET lease_expires_ms = {{NOW_MS}} + $1, heartbeat_ms = {{NOW_MS}}
                 WHERE {} RETURNING cancel_requested",
                fence(1)
            );
            let r = fenced(sqlx::query(owned_sql::<D>(text)).bind(lease_ms), c)
                .fetch_optional(pool)
                .await?;
            Ok(match r {
                Some(r) => Lease::Held {
                    cancel_requested: r.try_get("cancel_requested")?,
                },
                None => Lease::Lost,
            })
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
        on_db!(self, pool, D => {
            let mut tx = begin_write(pool).await?;
            let text = format!(
                "UPDATE jobs SET epoch = $1, train_loss = $2, val_loss = $3, best_val_loss = $4,
                    val_horizon_loss = $5
                 WHERE {}",
                fence(5)
            );
            let updated = fenced(
                sqlx::query(owned_sql::<D>(text))
                    .bind(m.epoch)
                    .bind(m.train_loss)
                    .bind(m.val_loss)
                    .bind(best_val_loss)
                    .bind(m.val_horizon_loss),
                c,
            )
            .execute(&mut *tx)
            .await?;
            if updated.rows_affected() == 0 {
                return Ok(false);
            }
            sqlx::query(
                "INSERT INTO metrics (job_id, epoch, train_loss, val_loss, seconds, val_horizon_loss,
                    train_loss_std, val_loss_std)
                 VALUES ($1, $2, $3, $4, $5, $6, $7, $8)
                 ON CONFLICT (job_id, epoch) DO UPDATE SET train_loss = excluded.train_loss,
                    val_loss = excluded.val_loss, seconds = excluded.seconds,
                    val_horizon_loss = excluded.val_horizon_loss,
                    train_loss_std = excluded.train_loss_std, val_loss_std = excluded.val_loss_std",
            )
            .bind(&c.job.id)
            .bind(m.epoch)
            .bind(m.train_loss)
            .bind(m.val_loss)
            .bind(m.seconds)
            .bind(m.val_horizon_loss)
            .bind(m.train_loss_std)
            .bind(m.val_loss_std)
            .execute(&mut *tx)
            .await?;
            tx.commit().await?;
            Ok(true)
        })
    }

    /// Replaces the job's checkpoint atomically (inside the transaction, so a crash leaves the
    /// previous one); false when the lease was lost.
    pub async fn save_checkpoint(&self, c: &Claimed, epoch: i64, state: &[u8]) -> Result<bool> {
        let placed = self.place(Kind::Checkpoint, state).await?;
        let saved = self.save_checkpoint_row(c, epoch, state, &placed).await;
        // The object no row points at: the new one when fenced out, else the replaced one.
        match &saved {
            Ok(Some(replaced)) => self.unreference(replaced.as_deref()).await,
            _ => self.unreference(placed.key.as_deref()).await,
        }
        saved.map(|s| s.is_some())
    }

    /// The fenced write of a checkpoint; None when the lease was lost, else the object key of
    /// the checkpoint it replaced (if that one was in the object store).
    async fn save_checkpoint_row(
        &self,
        c: &Claimed,
        epoch: i64,
        state: &[u8],
        placed: &Placed<'_>,
    ) -> Result<Option<Option<String>>> {
        on_db!(self, pool, D => {
            let mut tx = begin_write(pool).await?;
            // A stored checkpoint ends a run of storage failures (see `retry_later`).
            let text = format!(
                "UPDATE jobs SET checkpoint_epoch = $1, infra_since_ms = NULL WHERE {}",
                fence(1)
            );
            let updated = fenced(sqlx::query(owned_sql::<D>(text)).bind(epoch), c)
                .execute(&mut *tx)
                .await?;
            if updated.rows_affected() == 0 {
                return Ok(None);
            }
            let replaced: Option<Option<String>> =
                sqlx::query_scalar("SELECT blob_key FROM checkpoints WHERE job_id = $1")
                    .bind(&c.job.id)
                    .fetch_optional(&mut *tx)
                    .await?;
            sqlx::query(
                "INSERT INTO checkpoints (job_id, epoch, attempt, state, sha256, created_at, blob_key)
                 VALUES ($1, $2, $3, $4, $5, $6, $7)
                 ON CONFLICT (job_id) DO UPDATE SET epoch = excluded.epoch,
                    attempt = excluded.attempt, state = excluded.state,
                    sha256 = excluded.sha256, created_at = excluded.created_at,
                    blob_key = excluded.blob_key",
            )
            .bind(&c.job.id)
            .bind(epoch)
            .bind(c.attempt)
            .bind(placed.inline)
            .bind(sha256_hex(state))
            .bind(now_rfc3339())
            .bind(&placed.key)
            .execute(&mut *tx)
            .await
            .map_err(|e| too_big(e, state.len()))?;
            tx.commit().await?;
            Ok(Some(replaced.flatten()))
        })
    }

    /// The last committed checkpoint (epoch, bytes), verified against its checksum.
    pub async fn load_checkpoint(&self, job_id: &str) -> Result<Option<(i64, Vec<u8>)>> {
        if !super::could_be_id(job_id) {
            return Ok(None);
        }
        type Stored = (i64, Vec<u8>, String, Option<String>);
        let r: Option<Stored> = on_db!(self, pool, D => {
            sqlx::query_as("SELECT epoch, state, sha256, blob_key FROM checkpoints WHERE job_id = $1")
                .bind(job_id)
                .fetch_optional(pool)
                .await?
        });
        let Some((epoch, inline, sha, key)) = r else {
            return Ok(None);
        };
        let Some(state) = self
            .fetch(inline, key, ("checkpoints", "job_id", job_id))
            .await?
        else {
            return Ok(None);
        };
        Ok(Some((epoch, verified(state, &sha, "checkpoint", job_id)?)))
    }

    /// Ends a held job in a final state (with its error message, if any); false when the lease
    /// was lost.
    pub async fn end_job(&self, c: &Claimed, state: JobState, error: Option<&str>) -> Result<bool> {
        on_db!(self, pool, D => {
            let text = format!(
                "UPDATE jobs SET state = $1, error = $2, finished_at = $3, lease_owner = NULL,
                    lease_expires_ms = NULL WHERE {}",
                fence(3)
            );
            let r = fenced(
                sqlx::query(owned_sql::<D>(text))
                    .bind(state.as_str())
                    .bind(error)
                    .bind(now_rfc3339()),
                c,
            )
            .execute(pool)
            .await?;
            self.wake_collector();
            Ok(r.rows_affected() == 1)
        })
    }

    /// Gives a held job back to the queue (graceful shutdown).
    pub async fn release_job(&self, c: &Claimed) -> Result<bool> {
        on_db!(self, pool, D => {
            let text = format!(
                "UPDATE jobs SET state = 'queued', lease_owner = NULL, lease_expires_ms = NULL WHERE {}",
                fence(0)
            );
            let r = fenced(sqlx::query(owned_sql::<D>(text)), c).execute(pool).await?;
            Ok(r.rows_affected() == 1)
        })
    }

    /// Gives a held job back after a storage failure, to be claimed again after a backoff
    /// wait; or fails it when its storage has been failing for `patience` (counted from the
    /// first failure since it last stored a checkpoint), so that a long outage is measured in
    /// time, not in tries made in a burst. None when the lease was lost.
    pub async fn retry_later(
        &self,
        c: &Claimed,
        backoff: Backoff,
        patience: Duration,
        error: &str,
    ) -> Result<Option<JobState>> {
        on_db!(self, pool, D => {
            let mut tx = begin_write(pool).await?;
            let text = format!(
                "SELECT infra_failures, infra_since_ms, {{NOW_MS}} FROM jobs WHERE {}",
                fence(0)
            );
            let Some(r) = fenced(sqlx::query(owned_sql::<D>(text)), c)
                .fetch_optional(&mut *tx)
                .await?
            else {
                return Ok(None);
            };
            let (failures, since, now): (i64, Option<i64>, i64) =
                (r.try_get(0)?, r.try_get(1)?, r.try_get(2)?);
            let since = since.unwrap_or(now);
            let failing = Duration::from_millis((now - since).max(0) as u64);
            let state = if failing >= patience {
                let msg = format!(
                    "storage failed for {} s ({} times); last error: {error}",
                    failing.as_secs(),
                    failures + 1
                );
                let text = format!(
                    "UPDATE jobs SET state = 'failed', error = $1, finished_at = $2,
                        infra_failures = infra_failures + 1, lease_owner = NULL,
                        lease_expires_ms = NULL WHERE {}",
                    fence(2)
                );
                let q = sqlx::query(owned_sql::<D>(text)).bind(msg).bind(now_rfc3339());
                fenced(q, c).execute(&mut *tx).await?;
                JobState::Failed
            } else {
                let wait = backoff.delay(failures.clamp(0, 30) as u32).as_millis() as i64;
                let text = format!(
                    "UPDATE jobs SET state = 'queued', infra_failures = infra_failures + 1,
                        infra_since_ms = $1, not_before_ms = {{NOW_MS}} + $2,
                        lease_owner = NULL, lease_expires_ms = NULL WHERE {}",
                    fence(2)
                );
                let q = sqlx::query(owned_sql::<D>(text)).bind(since).bind(wait);
                fenced(q, c).execute(&mut *tx).await?;
                JobState::Queued
            };
            tx.commit().await?;
            if state == JobState::Failed {
                self.wake_collector();
            }
            Ok(Some(state))
        })
    }

    /// Gives back every job `owner` holds, without its fence's attempt: a process exiting
    /// before its training threads reached an epoch end (forced shutdown) cannot name their
    /// claims, and a job whose lease merely expired would wait out the lease and count as a
    /// dead worker. The abandoned threads' later writes fail their fence (the job is no longer
    /// running under this owner). Returns the jobs given back.
    pub async fn release_owned(&self, owner: &str) -> Result<u64> {
        on_db!(self, pool, D => {
            let r = sqlx::query(
                "UPDATE jobs SET state = 'queued', lease_owner = NULL, lease_expires_ms = NULL
                 WHERE state = 'running' AND lease_owner = $1",
            )
            .bind(owner)
            .execute(pool)
            .await?;
            Ok(r.rows_affected())
        })
    }
}
