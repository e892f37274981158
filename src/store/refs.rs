//! Counted references to the object store's objects (docs/storage.md#object-store-faults):
//! a row that points at an object holds one, and an object whose count reached 0 is deleted
//! by the collector, after and outside the transaction that released it. No call to the
//! object store runs while a database transaction is open, so a store that hangs can stall
//! the collector, never the database's write lock.

use std::time::Duration;

use super::blobs::{Blobs, DeleteFailed, Kind};
use super::dialect::{begin_write, owned_sql};
use crate::error::{Error, Result};

/// A row that points at an object: its table, the column that identifies it, and its id.
pub(super) type Row<'a> = (&'static str, &'static str, &'a str);

/// Bytes as a new row keeps them: inline in its column, or under `key` in the object store
/// (the column then empty).
pub(super) struct Placed<'a> {
    pub inline: &'a [u8],
    pub key: Option<String>,
}

/// How often each process collects when nothing wakes its collector sooner (on average:
/// each wait is drawn between this and twice this).
pub const COLLECT_EVERY: Duration = Duration::from_secs(30);

/// Objects the collector deletes in one batch.
const BATCH: i64 = 64;

/// How often a write waits to see a deletion of its object end (see [`super::Store::place`]).
const CLAIM_POLL: Duration = Duration::from_millis(100);

impl super::Store {
    /// Puts `bytes` where a new row of `kind` keeps them. With `--blobs`: first counted as
    /// referenced (so that the collector leaves the object this row will point at), then
    /// written; the caller gives the reference back with [`Store::unreference`] if no row ends
    /// up pointing at it. A crash in between leaves a count too high: an object kept, never a
    /// row pointing at a missing one.
    pub(super) async fn place<'a>(&self, kind: Kind, bytes: &'a [u8]) -> Result<Placed<'a>> {
        let Some(blobs) = &self.blobs else {
            return Ok(Placed {
                inline: bytes,
                key: None,
            });
        };
        let key = Blobs::key(kind, bytes);
        let deleting: bool = on_db!(self, pool, D => {
            let mut tx = begin_write(pool).await?;
            let claimed: i64 = sqlx::query_scalar(owned_sql::<D>(
                "INSERT INTO blob_refs (key, refs) VALUES ($1, 1)
                 ON CONFLICT (key) DO UPDATE SET refs = blob_refs.refs + 1
                 RETURNING CAST(CASE WHEN deleting_until_ms > {NOW_MS} THEN 1 ELSE 0 END AS BIGINT)"
                    .to_string(),
            ))
            .bind(&key)
            .fetch_one(&mut *tx)
            .await?;
            tx.commit().await?;
            claimed == 1
        });
        // The collector is deleting this very object (its count was 0 a moment ago): write
        // it once that deletion is over, or it could remove what this write finds in place.
        if deleting && let Err(e) = self.until_not_deleting(&key).await {
            self.unreference(Some(&key)).await;
            return Err(e);
        }
        if let Err(e) = blobs.put(&key, bytes).await {
            self.unreference(Some(&key)).await;
            return Err(e);
        }
        Ok(Placed {
            inline: &[],
            key: Some(key),
        })
    }

    /// Wakes this process's collector: a job ended (its checkpoint can go) or an object lost
    /// its last reference.
    pub(super) fn wake_collector(&self) {
        self.collect_soon.notify_one();
    }

    /// Waits until no collector claims `key` (its deletion finished, or its claim expired).
    async fn until_not_deleting(&self, key: &str) -> Result<()> {
        loop {
            let claimed: i64 = on_db!(self, pool, D => {
                sqlx::query_scalar(owned_sql::<D>(
                    "SELECT COUNT(*) FROM blob_refs WHERE key = $1 AND deleting_until_ms > {NOW_MS}"
                        .to_string(),
                ))
                .bind(key)
                .fetch_one(pool)
                .await?
            });
            if claimed == 0 {
                return Ok(());
            }
            tokio::time::sleep(CLAIM_POLL).await;
        }
    }

    /// Gives back one reference to `key`'s object (a row deleted or replaced, or a write that
    /// made none); at zero the collector deletes it. A failure is logged, not returned: the
    /// row's change has happened, and the object is merely kept.
    pub(super) async fn unreference(&self, key: Option<&str>) {
        let (Some(key), Some(_)) = (key, &self.blobs) else {
            return;
        };
        let released: Result<i64> = on_db!(self, pool, D => async {
            let mut tx = begin_write(pool).await?;
            let left: Option<i64> =
                sqlx::query_scalar("UPDATE blob_refs SET refs = refs - 1 WHERE key = $1 RETURNING refs")
                    .bind(key)
                    .fetch_optional(&mut *tx)
                    .await?;
            tx.commit().await?;
            Ok(left.unwrap_or(0))
        }.await);
        match released {
            Ok(left) if left <= 0 => self.wake_collector(),
            Ok(_) => {}
            Err(e) => tracing::warn!(key, error = %e, "releasing an object failed; it is kept"),
        }
    }

    /// A row's bytes: its inline column, or its object (verified against the key). None when
    /// the object is gone because the row was deleted or replaced after it was read (the
    /// deletion won the race: as if the row had not been found); a row that still points at a
    /// missing object is corrupt.
    pub(super) async fn fetch(
        &self,
        inline: Vec<u8>,
        key: Option<String>,
        row: Row<'_>,
    ) -> Result<Option<Vec<u8>>> {
        let Some(key) = key else {
            return Ok(Some(inline));
        };
        let Some(blobs) = &self.blobs else {
            return Err(Error::FailedPrecondition(format!(
                "{key} is in the object store: start graybox with the --blobs it was stored with"
            )));
        };
        if let Some(bytes) = blobs.get(&key).await? {
            return Ok(Some(bytes));
        }
        let (table, column, id) = row;
        let text = format!("SELECT COUNT(*) FROM {table} WHERE {column} = $1 AND blob_key = $2");
        let still: i64 = on_db!(self, pool, D => {
            sqlx::query_scalar(sqlx::AssertSqlSafe(text))
                .bind(id)
                .bind(&key)
                .fetch_one(pool)
                .await?
        });
        if still > 0 {
            return Err(Error::corrupt("object store", format!("{key} is missing")));
        }
        Ok(None)
    }

    /// One collection: drops the checkpoints of ended jobs (nothing resumes from them), then
    /// deletes every object no row points at, a batch at a time. Each deletion is claimed in
    /// one transaction, made outside any, and its row removed in another; one that fails keeps
    /// its row, and a later collection (in this process or another, after the claim expires)
    /// tries again. Returns how many objects it deleted.
    pub async fn collect(&self) -> Result<usize> {
        self.drop_ended_checkpoints().await?;
        let Some(blobs) = &self.blobs else {
            return Ok(0);
        };
        let me = super::new_id("gc");
        // Longer than a deletion's try may take: a claim outlives the call it covers.
        let claim_ms = 2 * blobs.timeout().as_millis() as i64 + 10_000;
        let mut deleted = 0;
        loop {
            let keys = self.claim_unreferenced(&me, claim_ms).await?;
            if keys.is_empty() {
                return Ok(deleted);
            }
            let mut failed = None;
            for key in &keys {
                match blobs.delete_once(key).await {
                    Ok(()) => {
                        self.end_claim(&me, key, true).await?;
                        deleted += 1;
                    }
                    Err(DeleteFailed::Refused(e)) => {
                        self.end_claim(&me, key, false).await?;
                        failed = Some(e);
                    }
                    // The store may still delete it: the claim stands until it expires.
                    Err(DeleteFailed::Unanswered(e)) => failed = Some(e),
                }
            }
            if let Some(e) = failed {
                return Err(e);
            }
        }
    }

    /// Claims up to a batch of objects whose count is 0 and that no live claim covers.
    async fn claim_unreferenced(&self, me: &str, claim_ms: i64) -> Result<Vec<String>> {
        on_db!(self, pool, D => {
            let mut tx = begin_write(pool).await?;
            let keys: Vec<String> = sqlx::query_scalar(owned_sql::<D>(
                "UPDATE blob_refs SET deleting_by = $1, deleting_until_ms = {NOW_MS} + $2
                 WHERE key IN (SELECT key FROM blob_refs WHERE refs <= 0
                     AND (deleting_until_ms IS NULL OR deleting_until_ms <= {NOW_MS})
                     ORDER BY key LIMIT $3)
                 RETURNING key"
                    .to_string(),
            ))
            .bind(me)
            .bind(claim_ms)
            .bind(BATCH)
            .fetch_all(&mut *tx)
            .await?;
            tx.commit().await?;
            Ok(keys)
        })
    }

    /// Ends `me`'s claim on `key`. When its object was `deleted`, the row goes too, unless a
    /// write referenced the key meanwhile (that write waits for this claim to end, then
    /// writes the object anew).
    async fn end_claim(&self, me: &str, key: &str, deleted: bool) -> Result<()> {
        on_db!(self, pool, D => {
            let mut tx = begin_write(pool).await?;
            if deleted {
                sqlx::query("DELETE FROM blob_refs WHERE key = $1 AND deleting_by = $2 AND refs <= 0")
                    .bind(key)
                    .bind(me)
                    .execute(&mut *tx)
                    .await?;
            }
            sqlx::query(
                "UPDATE blob_refs SET deleting_by = NULL, deleting_until_ms = NULL
                 WHERE key = $1 AND deleting_by = $2",
            )
            .bind(key)
            .bind(me)
            .execute(&mut *tx)
            .await?;
            tx.commit().await?;
            Ok(())
        })
    }

    /// Deletes the checkpoints of jobs that ended (succeeded, failed or cancelled: none is
    /// resumed) and gives back their objects' references, in one transaction.
    async fn drop_ended_checkpoints(&self) -> Result<()> {
        on_db!(self, pool, D => {
            let mut tx = begin_write(pool).await?;
            let keys: Vec<Option<String>> = sqlx::query_scalar(
                "DELETE FROM checkpoints WHERE job_id IN
                    (SELECT id FROM jobs WHERE state IN ('succeeded', 'failed', 'cancelled'))
                 RETURNING blob_key",
            )
            .fetch_all(&mut *tx)
            .await?;
            for key in keys.iter().flatten() {
                sqlx::query("UPDATE blob_refs SET refs = refs - 1 WHERE key = $1")
                    .bind(key)
                    .execute(&mut *tx)
                    .await?;
            }
            tx.commit().await?;
            Ok(())
        })
    }

    /// Runs [`Store::collect`] when a reference was given back or a job ended, and every
    /// `every` to 2 × `every` (varied, so that processes started together sweep apart), until
    /// `stop` resolves.
    pub async fn run_collector(
        &self,
        every: Duration,
        stop: impl std::future::Future<Output = ()>,
    ) {
        tokio::pin!(stop);
        let wait = crate::backoff::Backoff::new(2 * every, 2 * every);
        loop {
            tokio::select! {
                () = tokio::time::sleep(wait.delay(0)) => {}
                () = self.collect_soon.notified() => {}
                () = &mut stop => return,
            }
            if let Err(e) = self.collect().await {
                tracing::warn!(error = %e, "collecting unreferenced objects failed; trying again later");
            }
        }
    }
}
