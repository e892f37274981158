//! All SQL (docs/storage.md#sqlite-settings): SQLite in WAL mode with synchronous=FULL, a busy timeout, and
//! `BEGIN IMMEDIATE` for every write transaction, so that concurrent writers queue on the lock
//! instead of failing with SQLITE_BUSY. Queries are checked at run time (no offline data).

// First: their macros (`on_db!`, `page!`, `delete_row!`) are used by every module after them.
#[macro_use]
mod dialect;
#[macro_use]
mod page;
mod postgres;
#[macro_use]
mod delete;
pub mod blobs;
mod datasets;
mod jobs;
mod models;
mod queue;
mod refs;
mod templates;

pub use datasets::DatasetRow;
pub use jobs::{JobRow, NewJob, Submitted};
pub use models::{ModelRow, NewModel};
pub use queue::{Claimed, Lease};
pub use refs::COLLECT_EVERY;
pub use templates::{NewTemplate, TemplateRow};

use std::str::FromStr;
use std::time::Duration;

use sqlx::sqlite::{SqliteConnectOptions, SqliteJournalMode, SqlitePoolOptions, SqliteSynchronous};

use dialect::Db;

use crate::error::{Error, Result};

#[derive(Debug, Clone)]
pub struct Store {
    db: Db,
    /// Where large bytes go (`--blobs`); None: inline in their rows.
    blobs: Option<blobs::Blobs>,
    /// Wakes this process's collector (`refs.rs`): an object's last reference went.
    collect_soon: std::sync::Arc<tokio::sync::Notify>,
}

pub fn now_rfc3339() -> String {
    chrono::Utc::now().to_rfc3339_opts(chrono::SecondsFormat::Millis, true)
}

pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    hex::encode(sha2::Sha256::digest(bytes))
}

/// Stored bytes back, if they still match the checksum taken when they were written.
pub fn verified(bytes: Vec<u8>, sha256: &str, what: &str, id: &str) -> Result<Vec<u8>> {
    if sha256_hex(&bytes) != sha256 {
        return Err(Error::corrupt(what, format!("checksum mismatch for {id}")));
    }
    Ok(bytes)
}

/// Bytes a page of a list may carry: rows whose documents are large (a model's spec embeds
/// its template, up to `--max-template-mb`) fill a page before its count does.
pub const PAGE_BYTES: i64 = 8 << 20;

/// A row as its record (`#[derive(sqlx::FromRow)]`).
fn row<R: sqlx::Row, T: for<'r> sqlx::FromRow<'r, R>>(r: &R) -> Result<T> {
    Ok(T::from_row(r)?)
}

/// Whether `id` could name a row. Ids are graybox's own (`prefix_hex`), so one that is empty,
/// very long or holds a control character names none, and is answered as missing before the
/// database is asked (PostgreSQL refuses a NUL in text with an error, not "no row").
pub(crate) fn could_be_id(id: &str) -> bool {
    !id.is_empty() && id.len() <= 256 && !id.chars().any(char::is_control)
}

pub fn new_id(prefix: &str) -> String {
    format!("{prefix}_{}", uuid::Uuid::new_v4().simple())
}

/// An exclusive lock on `<db>.lock` while a process opens and migrates the database: two
/// processes that start at once on a new database would otherwise both create its tables,
/// and one fails ("table datasets already exists", or "database is locked" while the other
/// switches the new file to WAL). A lock file beside the database, not the database file
/// itself: closing any other descriptor of the database would drop SQLite's own locks.
async fn migration_lock(db: &str) -> Result<Option<std::fs::File>> {
    if db == ":memory:" || db.starts_with("file:") {
        return Ok(None);
    }
    let path = format!("{db}.lock");
    tokio::task::spawn_blocking(move || {
        let file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(|e| Error::invalid("db", format!("cannot open {path}: {e}")))?;
        file.lock()
            .map_err(|e| Error::invalid("db", format!("cannot lock {path}: {e}")))?;
        Ok(Some(file))
    })
    .await
    .map_err(|e| Error::Internal(format!("migration lock: {e}")))?
}

/// Whether `db` names a PostgreSQL database (else it is an SQLite file's path).
pub fn is_postgres(db: &str) -> bool {
    db.starts_with("postgres://") || db.starts_with("postgresql://")
}

/// `db` as logs may show it: a URL's password replaced by `***`.
pub fn redacted(db: &str) -> String {
    let Some((scheme, rest)) = db.split_once("://") else {
        return db.to_string();
    };
    match rest.rsplit_once('@') {
        Some((user, host)) => match user.split_once(':') {
            Some((name, _password)) => format!("{scheme}://{name}:***@{host}"),
            None => db.to_string(),
        },
        None => db.to_string(),
    }
}

impl Store {
    /// Opens the database `db` names and applies its migrations: a `postgres://` URL, or the
    /// path of an SQLite file (created if needed).
    pub async fn open(db: &str) -> Result<Self> {
        let db = if is_postgres(db) {
            postgres::open(db).await?
        } else {
            Self::open_sqlite(db).await?
        };
        Ok(Self {
            db,
            blobs: None,
            collect_soon: Default::default(),
        })
    }

    /// [`Store::open`], with new rows' large bytes in the object store `blobs` names (see
    /// `blobs.rs`); rows stored inline before keep their bytes and are served as they are.
    pub async fn open_with(db: &str, blobs: Option<&str>) -> Result<Self> {
        // The cheap check first: a bad URL stops the start-up before the database is opened.
        let blobs = blobs.map(blobs::Blobs::open).transpose()?;
        let store = Self::open(db).await?;
        if let Some(b) = &blobs {
            b.mark().await?;
        }
        Ok(Self { blobs, ..store })
    }

    /// The same store, its object store's calls timed out and retried as `retry` says.
    pub fn with_retry(self, retry: blobs::Retry) -> Self {
        let blobs = self.blobs.map(|b| b.with_retry(retry));
        Self { blobs, ..self }
    }

    /// Opens (creating if needed) the database file and applies the migrations.
    async fn open_sqlite(path: &str) -> Result<Db> {
        let opts = SqliteConnectOptions::from_str(&format!("sqlite://{path}"))
            .map_err(|e| Error::invalid("db", e))?
            .create_if_missing(true)
            .journal_mode(SqliteJournalMode::Wal)
            .synchronous(SqliteSynchronous::Full)
            .busy_timeout(Duration::from_secs(30))
            .foreign_keys(true);
        // Held from creating the file (and switching it to WAL, which takes an exclusive lock
        // that SQLite's busy handler does not wait for) through the migrations.
        let lock = migration_lock(path).await?;
        let pool = SqlitePoolOptions::new()
            .max_connections(8)
            .connect_with(opts)
            .await?;
        let migrated = sqlx::migrate!("./migrations/sqlite").run(&pool).await;
        drop(lock);
        migrated?;
        Ok(Db::Sqlite(pool))
    }

    /// Ready when the database (and the object store, with `--blobs`) answer, each asked
    /// once and for [`blobs::PING_TIMEOUT`] at most: a probe answers while either hangs, and
    /// its error names the one that did not answer.
    pub async fn ping(&self) -> Result<()> {
        let db = async {
            on_db!(self, pool, D => {
                sqlx::query("SELECT 1").execute(pool).await?;
            });
            Ok::<(), Error>(())
        };
        match tokio::time::timeout(blobs::PING_TIMEOUT, db).await {
            Ok(Ok(())) => {}
            Ok(Err(e)) => return Err(Error::Storage(format!("database: {e}"))),
            Err(_) => {
                return Err(Error::Storage(format!(
                    "database: no answer within {} s",
                    blobs::PING_TIMEOUT.as_secs()
                )));
            }
        }
        self.ping_blobs().await
    }

    /// Ready when the object store answers (always, without `--blobs`): a worker asks before
    /// it claims a job, so that an outage of the store leaves queued jobs queued.
    pub async fn ping_blobs(&self) -> Result<()> {
        match &self.blobs {
            Some(b) => b.ping().await,
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{is_postgres, redacted};

    #[test]
    fn logs_show_a_database_url_without_its_password() {
        let url = "postgres://graybox:s3cr:et@db.internal:5432/graybox?sslmode=require";
        let shown = redacted(url);
        assert!(!shown.contains("s3cr"), "{shown}");
        assert_eq!(
            shown,
            "postgres://graybox:***@db.internal:5432/graybox?sslmode=require"
        );
        // Nothing to hide: shown as given.
        for db in ["./graybox.db", "postgres://graybox@127.0.0.1/graybox"] {
            assert_eq!(redacted(db), db);
        }
        assert!(is_postgres(url) && is_postgres("postgresql://h/d"));
        assert!(!is_postgres("./postgres://.db") && !is_postgres("graybox.db"));
    }
}
