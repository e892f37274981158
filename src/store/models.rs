//! Models: a finished job's best parameters as a model file with its report, or a model
//! file uploaded as it is.

use serde::Serialize;
use sqlx::{Row, Sqlite, Transaction};

use super::queue::{Claimed, FENCE, fenced};
use super::{Store, new_id, now_rfc3339, row, sha256_hex, verified};
use crate::error::{Error, Result};

#[derive(Debug, Clone, PartialEq, Serialize, sqlx::FromRow)]
pub struct ModelRow {
    pub id: String,
    /// The job that trained it; `None` for an uploaded model.
    pub job_id: Option<String>,
    /// "trained" or "uploaded".
    pub origin: String,
    pub name: String,
    pub n: i64,
    pub m: i64,
    pub dt: f64,
    /// JSON of the model spec.
    pub spec: String,
    /// JSON of the training report.
    pub report: String,
    pub sha256: String,
    pub created_at: String,
    pub seq: i64,
}

const COLUMNS: &str = "seq, id, job_id, origin, name, n, m, dt, spec, report, sha256, created_at";

fn sql(s: &'static str) -> sqlx::AssertSqlSafe<String> {
    super::with_columns(s, COLUMNS)
}

/// A model's record and file, as `finish_job` (trained) and `insert_model` (uploaded) store it.
pub struct NewModel<'a> {
    pub name: &'a str,
    pub n: i64,
    pub m: i64,
    pub dt: f64,
    /// The spec (JSON).
    pub spec: &'a str,
    /// The report (JSON; `null` for an uploaded file without one).
    pub report: &'a str,
    pub file: &'a [u8],
}

/// Inserts a model in `tx`: trained when it has a job, uploaded when not.
async fn insert_row(
    tx: &mut Transaction<'static, Sqlite>,
    id: &str,
    job_id: Option<&str>,
    m: &NewModel<'_>,
) -> Result<ModelRow> {
    let origin = if job_id.is_some() {
        "trained"
    } else {
        "uploaded"
    };
    let r = sqlx::query(sql(
        "INSERT INTO models (id, job_id, origin, name, n, m, dt, spec, report, file, sha256,
             created_at)
         VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?) RETURNING {COLUMNS}",
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
    .bind(m.file)
    .bind(sha256_hex(m.file))
    .bind(now_rfc3339())
    .fetch_one(&mut **tx)
    .await?;
    row(&r)
}

impl Store {
    /// Stores the model and marks the job succeeded in one transaction, fenced by the lease:
    /// either both happen or neither. Returns the model id, or None when the lease was lost.
    /// `warnings` (JSON) are the training checks' findings, recorded on the job.
    pub async fn finish_job(
        &self,
        c: &Claimed,
        m: NewModel<'_>,
        warnings: &str,
    ) -> Result<Option<String>> {
        let mut tx = self.write().await?;
        let model_id = new_id("mdl");
        let updated = fenced(
            sqlx::query(sqlx::AssertSqlSafe(format!(
                "UPDATE jobs SET state = 'succeeded', model_id = ?, finished_at = ?, warnings = ?,
                    lease_owner = NULL, lease_expires_ms = NULL WHERE {FENCE}"
            )))
            .bind(&model_id)
            .bind(now_rfc3339())
            .bind(warnings),
            c,
        )
        .execute(&mut *tx)
        .await?;
        if updated.rows_affected() == 0 {
            return Ok(None);
        }
        insert_row(&mut tx, &model_id, Some(&c.job.id), &m).await?;
        tx.commit().await?;
        Ok(Some(model_id))
    }

    /// Stores an uploaded model unless the same file is stored already; the row and whether
    /// it was created.
    pub async fn insert_model(&self, m: NewModel<'_>) -> Result<(ModelRow, bool)> {
        let sha = sha256_hex(m.file);
        let mut tx = self.write().await?;
        let existing = sqlx::query(sql(
            "SELECT {COLUMNS} FROM models WHERE origin = 'uploaded' AND sha256 = ?",
        ))
        .bind(&sha)
        .fetch_optional(&mut *tx)
        .await?;
        if let Some(r) = existing {
            tx.commit().await?;
            return Ok((row(&r)?, false));
        }
        let stored = insert_row(&mut tx, &new_id("mdl"), None, &m).await?;
        tx.commit().await?;
        Ok((stored, true))
    }

    pub async fn get_model(&self, id: &str) -> Result<Option<ModelRow>> {
        let r = sqlx::query(sql("SELECT {COLUMNS} FROM models WHERE id = ?"))
            .bind(id)
            .fetch_optional(&self.pool)
            .await?;
        r.as_ref().map(row).transpose()
    }

    /// The model file (`.gbx` bytes), verified against its checksum.
    pub async fn model_file(&self, id: &str) -> Result<Option<Vec<u8>>> {
        let r = sqlx::query("SELECT file, sha256 FROM models WHERE id = ?")
            .bind(id)
            .fetch_optional(&self.pool)
            .await?;
        let Some(r) = r else { return Ok(None) };
        let sha: String = r.try_get("sha256")?;
        Ok(Some(verified(r.try_get("file")?, &sha, "model file", id)?))
    }

    /// Newest first.
    /// Newest first, at most `limit` rows and [`super::PAGE_BYTES`] of specs and reports;
    /// whether more rows follow.
    pub async fn list_models(
        &self,
        before: Option<i64>,
        limit: i64,
    ) -> Result<(Vec<ModelRow>, bool)> {
        let before = before.unwrap_or(i64::MAX);
        let size = "length(spec) + coalesce(length(report), 0)";
        let (fit, more) = super::fitting(&self.pool, "models", size, before, limit).await?;
        let rows = sqlx::query(sql(
            "SELECT {COLUMNS} FROM models WHERE seq < ? ORDER BY seq DESC LIMIT ?",
        ))
        .bind(before)
        .bind(fit)
        .fetch_all(&self.pool)
        .await?;
        Ok((rows.iter().map(row).collect::<Result<_>>()?, more))
    }

    /// Which of `ids` are still stored.
    pub async fn existing_models(
        &self,
        ids: &[String],
    ) -> Result<std::collections::HashSet<String>> {
        let mut found = std::collections::HashSet::new();
        for chunk in ids.chunks(500) {
            let marks = vec!["?"; chunk.len()].join(", ");
            let sql = format!("SELECT id FROM models WHERE id IN ({marks})");
            let mut q = sqlx::query_scalar::<_, String>(sqlx::AssertSqlSafe(sql));
            for id in chunk {
                q = q.bind(id);
            }
            found.extend(q.fetch_all(&self.pool).await?);
        }
        Ok(found)
    }

    pub async fn delete_model(&self, id: &str) -> Result<()> {
        let mut tx = self.write().await?;
        let r = sqlx::query("DELETE FROM models WHERE id = ?")
            .bind(id)
            .execute(&mut *tx)
            .await?;
        if r.rows_affected() == 0 {
            return Err(Error::NotFound(format!("model {id}")));
        }
        tx.commit().await?;
        Ok(())
    }
}
