//! The SQL dialects the store speaks. Its SQL is written once, with numbered parameters (`$1`,
//! which SQLite reads by number too), and what differs between databases is here: how a
//! write transaction starts, the database's clock, how a claim passes over locked rows. Every operation runs on the pool the
//! store opened through [`on_db!`], which compiles its body once per backend.

use std::future::Future;

use sqlx::{AssertSqlSafe, Pool, Postgres, Sqlite, Transaction};

use crate::error::Result;

/// What differs between the databases the store speaks.
pub(super) trait Dialect: sqlx::Database {
    /// The database's clock in milliseconds since the Unix epoch, as an SQL expression: leases
    /// are stamped and expired on it, never on a worker's clock, so that workers on machines
    /// whose clocks disagree cannot expire each other's live leases.
    const NOW_MS: &'static str;
    /// What the claim's choice of a job ends with: rows other claimers hold are passed over.
    const SKIP_LOCKED: &'static str;

    /// Starts a transaction that writes, serialized with every other such transaction: a
    /// read-then-write (an upload's "stored already?", a delete's "still used?") sees the
    /// writes before it and none beside it.
    fn begin_write(
        pool: &Pool<Self>,
    ) -> impl Future<Output = Result<Transaction<'static, Self>>> + Send;

    /// Starts the claim's transaction: on a database with row locks it need not wait for
    /// other writers, only skip the rows other claimers hold.
    fn begin_claim(
        pool: &Pool<Self>,
    ) -> impl Future<Output = Result<Transaction<'static, Self>>> + Send;
}

impl Dialect for Sqlite {
    // julianday('now') has millisecond resolution and works on every SQLite version.
    const NOW_MS: &'static str = "CAST((julianday('now') - 2440587.5) * 86400000.0 AS INTEGER)";
    // One writer at a time already: nothing to skip.
    const SKIP_LOCKED: &'static str = "";

    // Takes the write lock up front: a deferred transaction that reads and then writes fails
    // with SQLITE_BUSY instead of waiting, whatever the busy timeout.
    async fn begin_write(pool: &Pool<Self>) -> Result<Transaction<'static, Self>> {
        Ok(pool.begin_with("BEGIN IMMEDIATE").await?)
    }

    async fn begin_claim(pool: &Pool<Self>) -> Result<Transaction<'static, Self>> {
        Self::begin_write(pool).await
    }
}

/// The transaction-scoped advisory lock every write transaction on Postgres takes first (any
/// number: graybox's database is its own).
const WRITE_LOCK: i64 = 0x6772_6179;

impl Dialect for Postgres {
    const NOW_MS: &'static str = "CAST(EXTRACT(EPOCH FROM clock_timestamp()) * 1000 AS BIGINT)";
    const SKIP_LOCKED: &'static str = "FOR UPDATE SKIP LOCKED";

    // READ COMMITTED plus one advisory lock: writes are serialized as SQLite's are (they are
    // small; the training between them is not), so every check-then-write keeps its meaning.
    async fn begin_write(pool: &Pool<Self>) -> Result<Transaction<'static, Self>> {
        let mut tx = pool.begin().await?;
        sqlx::query("SELECT pg_advisory_xact_lock($1)")
            .bind(WRITE_LOCK)
            .execute(&mut *tx)
            .await?;
        Ok(tx)
    }

    async fn begin_claim(pool: &Pool<Self>) -> Result<Transaction<'static, Self>> {
        Ok(pool.begin().await?)
    }
}

/// The pool of the database the store opened.
#[derive(Debug, Clone)]
pub(super) enum Db {
    Sqlite(Pool<Sqlite>),
    Postgres(Pool<Postgres>),
}

/// Runs `$body` on the store's pool, bound to `$pool`, with `$D` naming its database type
/// (for [`sql`] and [`Dialect`]): the body is compiled once per backend.
macro_rules! on_db {
    ($store:expr, $pool:ident, $D:ident => $body:expr) => {
        match &$store.db {
            $crate::store::dialect::Db::Sqlite($pool) => {
                #[allow(dead_code)]
                type $D = sqlx::Sqlite;
                $body
            }
            $crate::store::dialect::Db::Postgres($pool) => {
                #[allow(dead_code)]
                type $D = sqlx::Postgres;
                $body
            }
        }
    };
}

/// A transaction that writes (see [`Dialect::begin_write`]).
pub(super) async fn begin_write<D: Dialect>(pool: &Pool<D>) -> Result<Transaction<'static, D>> {
    D::begin_write(pool).await
}

/// [`sql`] of a statement built at run time (no table columns in it).
pub(super) fn owned_sql<D: Dialect>(sql: String) -> AssertSqlSafe<String> {
    AssertSqlSafe(sql.replace("{NOW_MS}", D::NOW_MS))
}

/// `sql` with its placeholders filled: `{COLUMNS}` by a table's column list and `{NOW_MS}` by
/// the dialect's clock. The SQL stays static and parameterized (no value is ever formatted
/// into it).
pub(super) fn sql<D: Dialect>(sql: &'static str, columns: &'static str) -> AssertSqlSafe<String> {
    AssertSqlSafe(
        sql.replace("{COLUMNS}", columns)
            .replace("{NOW_MS}", D::NOW_MS)
            .replace("{SKIP_LOCKED}", D::SKIP_LOCKED),
    )
}
