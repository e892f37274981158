//! Templates: a user's mechanism as its canonical JSON document, stored once per document.

use super::dialect::{Dialect, begin_write};
use super::{Store, new_id, now_rfc3339, row, sha256_hex};
use crate::error::{Error, Result};

#[derive(Debug, Clone, PartialEq, sqlx::FromRow)]
pub struct TemplateRow {
    pub id: String,
    pub kind: String,
    pub name: String,
    pub n: i64,
    pub m: i64,
    /// The canonical JSON document (sorted keys, no spaces); lists leave it out when the row
    /// has its summary.
    pub document: Option<String>,
    /// What a list shows of the template (JSON); None for rows stored before summaries.
    pub summary: Option<String>,
    pub sha256: String,
    pub created_at: String,
    pub seq: i64,
}

/// What `insert_template` stores.
pub struct NewTemplate<'a> {
    pub kind: &'a str,
    pub name: &'a str,
    pub n: i64,
    pub m: i64,
    pub document: &'a str,
    pub summary: &'a str,
}

const COLUMNS: &str = "seq, id, kind, name, n, m, document, summary, sha256, created_at";

/// A list's columns: the document only where no summary stands for it.
const LIST_COLUMNS: &str = "seq, id, kind, name, n, m, summary, sha256, created_at, \
     CASE WHEN summary IS NULL THEN document END AS document";

fn sql<D: Dialect>(s: &'static str) -> sqlx::AssertSqlSafe<String> {
    super::dialect::sql::<D>(s, COLUMNS)
}

impl Store {
    /// Stores a template unless the same document is stored already; the row and whether it
    /// was created.
    pub async fn insert_template(&self, t: NewTemplate<'_>) -> Result<(TemplateRow, bool)> {
        on_db!(self, pool, D => {
            let sha = sha256_hex(t.document.as_bytes());
            let mut tx = begin_write(pool).await?;
            let existing = sqlx::query(sql::<D>("SELECT {COLUMNS} FROM templates WHERE sha256 = $1"))
                .bind(&sha)
                .fetch_optional(&mut *tx)
                .await?;
            if let Some(r) = existing {
                tx.commit().await?;
                return Ok((row(&r)?, false));
            }
            let r = sqlx::query(sql::<D>(
                "INSERT INTO templates (id, kind, name, n, m, document, summary, sha256, created_at)
                 VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9) RETURNING {COLUMNS}",
            ))
            .bind(new_id("tpl"))
            .bind(t.kind)
            .bind(t.name)
            .bind(t.n)
            .bind(t.m)
            .bind(t.document)
            .bind(t.summary)
            .bind(&sha)
            .bind(now_rfc3339())
            .fetch_one(&mut *tx)
            .await?;
            tx.commit().await?;
            Ok((row(&r)?, true))
        })
    }

    pub async fn get_template(&self, id: &str) -> Result<Option<TemplateRow>> {
        if !super::could_be_id(id) {
            return Ok(None);
        }
        on_db!(self, pool, D => {
            let r = sqlx::query(sql::<D>("SELECT {COLUMNS} FROM templates WHERE id = $1"))
                .bind(id)
                .fetch_optional(pool)
                .await?;
            r.as_ref().map(row).transpose()
        })
    }

    /// Newest first, at most `limit` rows and [`super::PAGE_BYTES`] of summaries (documents
    /// for rows without one); `before` is the `seq` of the last row of the previous page;
    /// whether more rows follow.
    pub async fn list_templates(
        &self,
        before: Option<i64>,
        limit: i64,
    ) -> Result<(Vec<TemplateRow>, bool)> {
        let before = before.unwrap_or(i64::MAX);
        on_db!(self, pool, D => {
            Ok(page!(pool, D, TemplateRow, "templates", LIST_COLUMNS, "coalesce(length(summary), length(document))", before, limit))
        })
    }

    /// Deletes a template unless a queued or running job uses it.
    pub async fn delete_template(&self, id: &str) -> Result<()> {
        on_db!(self, pool, D => {
            delete_row!(pool, "templates", "template", id,
                users = "SELECT COUNT(*) FROM jobs WHERE state IN ('queued', 'running')
                         AND template_id = $1")
        })
    }
}
