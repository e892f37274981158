//! Datasets: canonical arrays stored once, identified by their sha256.

use sha2::{Digest, Sha256};

use super::blobs::Kind;
use super::dialect::{Dialect, begin_write};
use super::refs::Placed;
use super::{Store, new_id, now_rfc3339, row};
use crate::data::Dataset;
use crate::error::{Error, Result};
use crate::records;

/// A dataset as stored: the record and its listing key (its arrays are read separately).
#[derive(Debug, Clone, PartialEq, sqlx::FromRow)]
pub struct DatasetRow {
    #[sqlx(flatten)]
    pub info: records::DatasetInfo,
    pub seq: i64,
}

impl std::ops::Deref for DatasetRow {
    type Target = records::DatasetInfo;
    fn deref(&self) -> &records::DatasetInfo {
        &self.info
    }
}

impl From<DatasetRow> for records::DatasetInfo {
    fn from(r: DatasetRow) -> Self {
        r.info
    }
}

// `n` is the velocities' width; `nq` is NULL for a dataset stored before it (nq = n).
const COLUMNS: &str = "seq, id, name, COALESCE(nq, n) AS nq, n AS nv, n, m, dt, count, sha256, \
                       created_at, warnings";

/// Little-endian f64 of q | q̇ | u | q' | q̇', each row-major, then each transition's Δt when
/// they differ (`Dataset::steps`; the blob's length tells whether they are there).
pub fn encode(ds: &Dataset) -> Vec<u8> {
    let steps = ds.steps.iter().flatten();
    [&ds.q, &ds.qdot, &ds.u, &ds.q_next, &ds.qdot_next]
        .into_iter()
        .flatten()
        .chain(steps)
        .flat_map(|v| v.to_le_bytes())
        .collect()
}

fn decode(
    blob: &[u8],
    (nq, nv): (usize, usize),
    m: usize,
    dt: f64,
    count: usize,
) -> Result<Dataset> {
    let widths = [nq, nv, m, nq, nv];
    let values = count.checked_mul(widths.iter().sum::<usize>());
    let bytes = |v: Option<usize>| v.and_then(|v| v.checked_mul(8));
    let timed = bytes(values.and_then(|v| v.checked_add(count))) == Some(blob.len());
    if !timed && bytes(values) != Some(blob.len()) {
        return Err(Error::corrupt(
            "dataset",
            "stored arrays do not match their dimensions",
        ));
    }
    // Each array straight from its bytes: no copy of the whole in between.
    let mut rest = blob;
    let mut arrays: [Vec<f64>; 5] = Default::default();
    for (a, w) in arrays.iter_mut().zip(widths) {
        let (head, tail) = rest.split_at(8 * count * w);
        *a = (head.chunks_exact(8))
            .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect();
        rest = tail;
    }
    let data = Dataset::new(dt, (nq, nv), m, arrays)?;
    if !timed {
        return Ok(data);
    }
    let steps = rest.chunks_exact(8);
    let steps = steps.map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")));
    data.with_steps(steps.collect())
}

/// The identity of a dataset: its dimensions, Δt and every value (nq too where it is not nv,
/// so that a dataset of one width keeps the identity it always had).
pub fn sha256(ds: &Dataset, blob: &[u8]) -> String {
    let mut h = Sha256::new();
    for v in [
        ds.nv as u64,
        ds.m as u64,
        ds.count() as u64,
        ds.dt.to_bits(),
    ] {
        h.update(v.to_le_bytes());
    }
    if ds.nq != ds.nv {
        h.update((ds.nq as u64).to_le_bytes());
    }
    h.update(blob);
    hex::encode(h.finalize())
}

impl Store {
    /// Stores a dataset unless the same arrays are already stored; returns the row and whether
    /// it was created. The same arrays uploaded flat first gain the trajectories of an upload
    /// in trajectory form.
    pub async fn insert_dataset(
        &self,
        name: Option<&str>,
        ds: &Dataset,
    ) -> Result<(DatasetRow, bool)> {
        let blob = encode(ds);
        let placed = self.place(Kind::Dataset, &blob).await?;
        let stored = self.insert_dataset_row(name, ds, &blob, &placed).await;
        if !matches!(stored, Ok((_, true))) {
            self.unreference(placed.key.as_deref()).await;
        }
        stored
    }

    async fn insert_dataset_row(
        &self,
        name: Option<&str>,
        ds: &Dataset,
        blob: &[u8],
        placed: &Placed<'_>,
    ) -> Result<(DatasetRow, bool)> {
        on_db!(self, pool, D => {
            let lengths = (ds.trajectories.as_ref())
                .map(|t| serde_json::to_string(t).expect("lengths serialize"));
            let sha = sha256(ds, blob);
            // Computed before the write lock is taken: the checks read every value.
            let warnings = sqlx::types::Json(ds.warnings());
            let mut tx = begin_write(pool).await?;
            let existing = sqlx::query(sql::<D>("SELECT {COLUMNS} FROM datasets WHERE sha256 = $1"))
                .bind(&sha)
                .fetch_optional(&mut *tx)
                .await?;
            if let Some(r) = existing {
                let stored: Option<String> =
                    sqlx::query_scalar("SELECT trajectories FROM datasets WHERE sha256 = $1")
                        .bind(&sha)
                        .fetch_one(&mut *tx)
                        .await?;
                // The same rows with other boundaries are another reading of the data, and
                // the stored one cannot be changed under the jobs and replays that use it.
                if let (Some(stored), Some(new)) = (&stored, &lengths)
                    && stored != new
                {
                    let existing: DatasetRow = row(&r)?;
                    return Err(Error::Conflict(format!(
                        "these rows are stored already as dataset {} with other trajectory \
                         boundaries ({} trajectories); delete it first to store them with these",
                        existing.id,
                        trajectory_lengths(stored).map_or(0, |l| l.len())
                    )));
                }
                if lengths.is_some() {
                    sqlx::query(
                        "UPDATE datasets SET trajectories = $1 WHERE sha256 = $2 AND trajectories IS NULL",
                    )
                    .bind(&lengths)
                    .bind(&sha)
                    .execute(&mut *tx)
                    .await?;
                }
                tx.commit().await?;
                return Ok((row(&r)?, false));
            }
            let r = sqlx::query(sql::<D>(
                "INSERT INTO datasets (id, name, sha256, n, m, dt, count, data, created_at, warnings,
                                       trajectories, blob_key, nq)
                 VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13)
                 RETURNING {COLUMNS}",
            ))
            .bind(new_id("ds"))
            .bind(name)
            .bind(&sha)
            .bind(ds.nv as i64)
            .bind(ds.m as i64)
            .bind(ds.dt)
            .bind(ds.count() as i64)
            .bind(placed.inline)
            .bind(now_rfc3339())
            .bind(warnings)
            .bind(lengths)
            .bind(&placed.key)
            .bind(ds.nq as i64)
            .fetch_one(&mut *tx)
            .await?;
            tx.commit().await?;
            Ok((row(&r)?, true))
        })
    }

    pub async fn get_dataset(&self, id: &str) -> Result<Option<DatasetRow>> {
        if !super::could_be_id(id) {
            return Ok(None);
        }
        on_db!(self, pool, D => {
            let r = sqlx::query(sql::<D>("SELECT {COLUMNS} FROM datasets WHERE id = $1"))
                .bind(id)
                .fetch_optional(pool)
                .await?;
            r.as_ref().map(row).transpose()
        })
    }

    pub async fn load_dataset(&self, id: &str) -> Result<Option<Dataset>> {
        if !super::could_be_id(id) {
            return Ok(None);
        }
        type Stored = (
            i64,
            i64,
            i64,
            f64,
            i64,
            Vec<u8>,
            Option<String>,
            Option<String>,
        );
        let r: Option<Stored> = on_db!(self, pool, D => {
            sqlx::query_as(
                "SELECT COALESCE(nq, n), n, m, dt, count, data, blob_key, trajectories
                 FROM datasets WHERE id = $1",
            )
                .bind(id)
                .fetch_optional(pool)
                .await?
        });
        let Some((nq, nv, m, dt, count, inline, key, lengths)) = r else {
            return Ok(None);
        };
        let Some(blob) = self.fetch(inline, key, ("datasets", "id", id)).await? else {
            return Ok(None);
        };
        let ds = decode(
            &blob,
            (nq as usize, nv as usize),
            m as usize,
            dt,
            count as usize,
        )?;
        drop(blob);
        match lengths.as_deref().map(trajectory_lengths).transpose()? {
            Some(lengths) => (ds.with_trajectories(lengths))
                .map(Some)
                .map_err(|e| Error::corrupt("dataset", e)),
            None => Ok(Some(ds)),
        }
    }

    /// The trajectory lengths a dataset was uploaded with: None when there is no such
    /// dataset, Some(None) when it was uploaded flat.
    pub async fn dataset_trajectories(&self, id: &str) -> Result<Option<Option<Vec<usize>>>> {
        if !super::could_be_id(id) {
            return Ok(None);
        }
        on_db!(self, pool, D => {
            let r: Option<Option<String>> =
                sqlx::query_scalar("SELECT trajectories FROM datasets WHERE id = $1")
                    .bind(id)
                    .fetch_optional(pool)
                    .await?;
            r.map(|t| t.as_deref().map(trajectory_lengths).transpose()).transpose()
        })
    }

    /// Newest first; `before` is the `seq` of the last row of the previous page.
    pub async fn list_datasets(&self, before: Option<i64>, limit: i64) -> Result<Vec<DatasetRow>> {
        on_db!(self, pool, D => {
            let rows = sqlx::query(sql::<D>(
                "SELECT {COLUMNS} FROM datasets WHERE seq < $1 ORDER BY seq DESC LIMIT $2",
            ))
            .bind(before.unwrap_or(i64::MAX))
            .bind(limit)
            .fetch_all(pool)
            .await?;
            rows.iter().map(row).collect()
        })
    }

    /// Deletes a dataset unless a queued or running job uses it.
    pub async fn delete_dataset(&self, id: &str) -> Result<()> {
        let key = on_db!(self, pool, D => {
            delete_row!(pool, "datasets", "dataset", id, blob_key,
                users = "SELECT COUNT(*) FROM jobs WHERE state IN ('queued', 'running')
                         AND (dataset_id = $1 OR validation_dataset_id = $1)")
        })?;
        self.unreference(key.as_deref()).await;
        Ok(())
    }
}

fn sql<D: Dialect>(s: &'static str) -> sqlx::AssertSqlSafe<String> {
    super::dialect::sql::<D>(s, COLUMNS)
}

/// A row's `trajectories` column: the lengths as JSON.
fn trajectory_lengths(text: &str) -> Result<Vec<usize>> {
    serde_json::from_str(text).map_err(|e| Error::corrupt("dataset", format!("trajectories: {e}")))
}
