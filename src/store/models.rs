//! Models: a finished job's best parameters as a model file with its report, or a model
//! file uploaded as it is.

use serde::Serialize;

use super::blobs::Kind;
use super::dialect::{Dialect, begin_write};
use super::queue::{Claimed, fence, fenced};
use super::refs::Placed;
use super::{Store, new_id, now_rfc3339, row, sha256_hex, verified};
use crate::error::{Error, Result};
use crate::records::Warning;

#[derive(Debug, Clone, PartialEq, Serialize, sqlx::FromRow)]
pub struct ModelRow {
    pub id: String,
    /// The job that trained it; `None` for an uploaded model.
    pub job_id: Option<String>,
    /// "trained" or "uploaded".
    pub origin: String,
    pub name: String,
    /// Velocities nv.
    pub n: i64,
    /// Configuration values nq; NULL for a model stored before the column (nq = n).
    pub nq: Option<i64>,
    pub m: i64,
    pub dt: f64,
    /// JSON of the model spec.
    pub spec: String,
    /// JSON of the training report.
    pub report: String,
    pub sha256: String,
    pub created_at: String,
    pub seq: i64,
    /// JSON of the energy report last measured on request against a dataset (the training
    /// report carries the one measured on the training data).
    pub energy: Option<String>,
}

const COLUMNS: &str =
    "seq, id, job_id, origin, name, n, nq, m, dt, spec, report, sha256, created_at, energy";

fn sql<D: Dialect>(s: &'static str) -> sqlx::AssertSqlSafe<String> {
    super::dialect::sql::<D>(s, COLUMNS)
}

/// A model's record and file, as `finish_job` (trained) and `insert_model` (uploaded) store it.
pub struct NewModel<'a> {
    pub name: &'a str,
    /// Velocities nv and configuration values nq.
    pub n: i64,
    pub nq: i64,
    pub m: i64,
    pub dt: f64,
    /// The spec (JSON).
    pub spec: &'a str,
    /// The report (JSON; `null` for an uploaded file without one).
    pub report: &'a str,
    pub file: &'a [u8],
}

/// Inserts a model in the transaction `$tx` of database `$D`: trained when it has a job,
/// uploaded when not; the stored row. (A macro: it runs in either backend's transaction.)
macro_rules! insert_row {
    ($D:ty, $tx:expr, $id:expr, $job_id:expr, $m:expr, $placed:expr) => {{
        let (id, job_id, m): (&str, Option<&str>, &NewModel<'_>) = ($id, $job_id, $m);
        let placed: &Placed<'_> = $placed;
        let origin = if job_id.is_some() {
            "trained"
        } else {
            "uploaded"
        };
        let r = sqlx::query(sql::<$D>(
            "INSERT INTO models (id, job_id, origin, name, n, m, dt, spec, report, file, sha256,
                 created_at, blob_key, nq)
             VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14)
             RETURNING {COLUMNS}",
        ))
        .bind(id)
        .bind(job_id)
        .bind(origin)
        .bind(m.name)
        .bind(m.n)
        .bind(m.m)
        .bind(m.dt)
        .bind(m.spec)
        .bind(m.report)
        .bind(placed.inline)
        .bind(sha256_hex(m.file))
        .bind(now_rfc3339())
        .bind(&placed.key)
        .bind(m.nq)
        .fetch_one(&mut *$tx)
        .await?;
        row::<_, ModelRow>(&r)
    }};
}

impl Store {
    /// Stores the model and marks the job succeeded in one transaction, fenced by the lease:
    /// either both happen or neither. Returns the model id, or None when the lease was lost.
    /// `warnings` are the training checks' findings, recorded on the job.
    pub async fn finish_job(
        &self,
        c: &Claimed,
        m: NewModel<'_>,
        warnings: &[Warning],
    ) -> Result<Option<String>> {
        let placed = self.place(Kind::Model, m.file).await?;
        let finished = self.finish_job_row(c, &m, warnings, &placed).await;
        if !matches!(finished, Ok(Some(_))) {
            self.unreference(placed.key.as_deref()).await;
        }
        finished
    }

    async fn finish_job_row(
        &self,
        c: &Claimed,
        m: &NewModel<'_>,
        warnings: &[Warning],
        placed: &Placed<'_>,
    ) -> Result<Option<String>> {
        on_db!(self, pool, D => {
            let mut tx = begin_write(pool).await?;
            let model_id = new_id("mdl");
            let updated = fenced(
                sqlx::query(sqlx::AssertSqlSafe(format!(
                    "UPDATE jobs SET state = 'succeeded', model_id = $1, finished_at = $2, warnings = $3,
                        lease_owner = NULL, lease_expires_ms = NULL WHERE {}",
                    fence(3)
                )))
                .bind(&model_id)
                .bind(now_rfc3339())
                .bind(sqlx::types::Json(warnings)),
                c,
            )
            .execute(&mut *tx)
            .await?;
            if updated.rows_affected() == 0 {
                return Ok(None);
            }
            insert_row!(D, tx, &model_id, Some(&c.job.id), m, placed)?;
            tx.commit().await?;
            self.wake_collector();
            Ok(Some(model_id))
        })
    }

    /// Stores an uploaded model unless the same file is stored already; the row and whether
    /// it was created.
    pub async fn insert_model(&self, m: NewModel<'_>) -> Result<(ModelRow, bool)> {
        let placed = self.place(Kind::Model, m.file).await?;
        let stored = self.insert_model_row(&m, &placed).await;
        if !matches!(stored, Ok((_, true))) {
            self.unreference(placed.key.as_deref()).await;
        }
        stored
    }

    async fn insert_model_row(
        &self,
        m: &NewModel<'_>,
        placed: &Placed<'_>,
    ) -> Result<(ModelRow, bool)> {
        on_db!(self, pool, D => {
            let sha = sha256_hex(m.file);
            let mut tx = begin_write(pool).await?;
            let existing = sqlx::query(sql::<D>(
                "SELECT {COLUMNS} FROM models WHERE origin = 'uploaded' AND sha256 = $1",
            ))
            .bind(&sha)
            .fetch_optional(&mut *tx)
            .await?;
            if let Some(r) = existing {
                tx.commit().await?;
                return Ok((row(&r)?, false));
            }
            let stored = insert_row!(D, tx, &new_id("mdl"), None, m, placed)?;
            tx.commit().await?;
            Ok((stored, true))
        })
    }

    /// Stores a model's energy report (JSON) measured on request; false when the model is gone.
    pub async fn set_model_energy(&self, id: &str, energy: &str) -> Result<bool> {
        on_db!(self, pool, D => {
            let mut tx = begin_write(pool).await?;
            let updated = sqlx::query("UPDATE models SET energy = $1 WHERE id = $2")
                .bind(energy)
                .bind(id)
                .execute(&mut *tx)
                .await?;
            tx.commit().await?;
            Ok(updated.rows_affected() == 1)
        })
    }

    pub async fn get_model(&self, id: &str) -> Result<Option<ModelRow>> {
        if !super::could_be_id(id) {
            return Ok(None);
        }
        on_db!(self, pool, D => {
            let r = sqlx::query(sql::<D>("SELECT {COLUMNS} FROM models WHERE id = $1"))
                .bind(id)
                .fetch_optional(pool)
                .await?;
            r.as_ref().map(row).transpose()
        })
    }

    /// The model file (`.gbx` bytes), verified against its checksum.
    pub async fn model_file(&self, id: &str) -> Result<Option<Vec<u8>>> {
        if !super::could_be_id(id) {
            return Ok(None);
        }
        let r: Option<(Vec<u8>, String, Option<String>)> = on_db!(self, pool, D => {
            sqlx::query_as("SELECT file, sha256, blob_key FROM models WHERE id = $1")
                .bind(id)
                .fetch_optional(pool)
                .await?
        });
        let Some((inline, sha, key)) = r else {
            return Ok(None);
        };
        let Some(file) = self.fetch(inline, key, ("models", "id", id)).await? else {
            return Ok(None);
        };
        Ok(Some(verified(file, &sha, "model file", id)?))
    }

    /// Newest first, at most `limit` rows and [`super::PAGE_BYTES`] of specs and reports;
    /// whether more rows follow.
    pub async fn list_models(
        &self,
        before: Option<i64>,
        limit: i64,
    ) -> Result<(Vec<ModelRow>, bool)> {
        let before = before.unwrap_or(i64::MAX);
        on_db!(self, pool, D => {
            Ok(page!(pool, D, ModelRow, "models", COLUMNS, "length(spec) + coalesce(length(report), 0)", before, limit))
        })
    }

    /// Which of `ids` are still stored.
    pub async fn existing_models(
        &self,
        ids: &[String],
    ) -> Result<std::collections::HashSet<String>> {
        on_db!(self, pool, D => {
            let mut found = std::collections::HashSet::new();
            for chunk in ids.chunks(500) {
                let marks: Vec<String> = (1..=chunk.len()).map(|i| format!("${i}")).collect();
                let marks = marks.join(", ");
                let sql = format!("SELECT id FROM models WHERE id IN ({marks})");
                let mut q = sqlx::query_scalar::<_, String>(sqlx::AssertSqlSafe(sql));
                for id in chunk {
                    q = q.bind(id);
                }
                found.extend(q.fetch_all(pool).await?);
            }
            Ok(found)
        })
    }

    pub async fn delete_model(&self, id: &str) -> Result<()> {
        let key = on_db!(self, pool, D => {
            delete_row!(pool, "models", "model", id, blob_key)
        })?;
        self.unreference(key.as_deref()).await;
        Ok(())
    }
}
