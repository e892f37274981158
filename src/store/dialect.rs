//! The SQL dialects the store speaks. Its SQL is written once, with numbered parameters (`$1`,
//! which SQLite reads by number too), and what differs between databases is here: how a
//! write transaction starts and the database's clock. Every operation runs on the pool the
//! store opened through [`on_db!`], which compiles its body once per backend.

use sqlx::{AssertSqlSafe, Pool, Sqlite, Transaction};

use crate::error::Result;

/// What an SQL dialect fills in of the store's shared SQL.
pub(super) trait Dialect: sqlx::Database {
    /// Starts a transaction that writes.
    const BEGIN_WRITE: &'static str;
    /// The database's clock in milliseconds since the Unix epoch, as an SQL expression: leases
    /// are stamped and expired on it, never on a worker's clock, so that workers on machines
    /// whose clocks disagree cannot expire each other's live leases.
    const NOW_MS: &'static str;
}

impl Dialect for Sqlite {
    // Takes the write lock up front: a deferred transaction that reads and then writes fails
    // with SQLITE_BUSY instead of waiting, whatever the busy timeout.
    const BEGIN_WRITE: &'static str = "BEGIN IMMEDIATE";
    // julianday('now') has millisecond resolution and works on every SQLite version.
    const NOW_MS: &'static str = "CAST((julianday('now') - 2440587.5) * 86400000.0 AS INTEGER)";
}

/// The pool of the database the store opened.
#[derive(Debug, Clone)]
pub(super) enum Db {
    Sqlite(Pool<Sqlite>),
}

/// Runs `$body` on the store's pool, bound to `$pool`, with `$D` naming its database type
/// (for [`sql`] and [`Dialect`]'s constants).
macro_rules! on_db {
    ($store:expr, $pool:ident, $D:ident => $body:expr) => {
        match &$store.db {
            $crate::store::dialect::Db::Sqlite($pool) => {
                #[allow(dead_code)]
                type $D = sqlx::Sqlite;
                $body
            }
        }
    };
}

/// A transaction that writes (see [`Dialect::BEGIN_WRITE`]).
pub(super) async fn begin_write<D: Dialect>(pool: &Pool<D>) -> Result<Transaction<'static, D>> {
    Ok(pool.begin_with(D::BEGIN_WRITE).await?)
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
            .replace("{NOW_MS}", D::NOW_MS),
    )
}
