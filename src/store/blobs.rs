//! Large bytes (dataset arrays, checkpoints, model files) in an object store (`--blobs`): a
//! local directory (`file:///path`) or S3 and S3-compatible stores (`s3://bucket/prefix`,
//! configured by the usual `AWS_*` environment variables). Keys are the bytes' sha256, so an
//! object never changes once written; objects are written create-if-absent before any row
//! points at them, and read back verified against their key.

use std::sync::Arc;

use object_store::aws::{AmazonS3Builder, S3ConditionalPut};
use object_store::local::LocalFileSystem;
use object_store::path::Path;
use object_store::{ObjectStore, ObjectStoreExt, PutMode, PutOptions, PutPayload};

use super::sha256_hex;
use crate::error::{Error, Result};

/// The object every graybox process writes at start and readiness checks for.
const MARKER: &str = "graybox/ready";

/// What a row's bytes are: the key's directory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Dataset,
    Checkpoint,
    Model,
}

impl Kind {
    fn dir(self) -> &'static str {
        match self {
            Kind::Dataset => "datasets",
            Kind::Checkpoint => "checkpoints",
            Kind::Model => "models",
        }
    }
}

/// An object store under a prefix. Cheap to clone.
#[derive(Clone)]
pub struct Blobs {
    store: Arc<dyn ObjectStore>,
    prefix: Path,
}

impl std::fmt::Debug for Blobs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Blobs({}, {})", self.store, self.prefix)
    }
}

/// An object store failure: the store is unavailable, not the request wrong.
fn storage(e: object_store::Error) -> Error {
    Error::Storage(format!("object store: {e}"))
}

impl Blobs {
    /// The store `url` names: `file:///absolute/dir` (created if missing) or
    /// `s3://bucket[/prefix]`.
    pub fn open(url: &str) -> Result<Self> {
        let bad = |why: &str| Error::invalid("blobs", format!("{url}: {why}"));
        if let Some(dir) = url.strip_prefix("file://") {
            if !dir.starts_with('/') {
                return Err(bad("a file:// URL needs an absolute path (file:///dir)"));
            }
            std::fs::create_dir_all(dir).map_err(|e| bad(&e.to_string()))?;
            let local = LocalFileSystem::new_with_prefix(dir).map_err(|e| bad(&e.to_string()))?;
            return Ok(Self {
                store: Arc::new(local),
                prefix: Path::default(),
            });
        }
        let Some(rest) = url.strip_prefix("s3://") else {
            return Err(bad("expected file:///dir or s3://bucket/prefix"));
        };
        let (bucket, prefix) = rest.split_once('/').unwrap_or((rest, ""));
        if bucket.is_empty() {
            return Err(bad("no bucket"));
        }
        // HTTPS on ring, as the service's own TLS (the client is built without a provider of
        // its own); a provider installed already is as good.
        let _ = tokio_rustls::rustls::crypto::ring::default_provider().install_default();
        // Create-if-absent through If-None-Match, which S3 and the S3-compatible stores
        // answer; without it the crate refuses PutMode::Create on S3.
        let s3 = AmazonS3Builder::from_env()
            .with_bucket_name(bucket)
            .with_conditional_put(S3ConditionalPut::ETagMatch)
            .build()
            .map_err(|e| bad(&e.to_string()))?;
        Ok(Self {
            store: Arc::new(s3),
            prefix: Path::from(prefix),
        })
    }

    /// The key of `bytes` of this kind: its directory and sha256.
    pub fn key(kind: Kind, bytes: &[u8]) -> String {
        format!("{}/{}", kind.dir(), sha256_hex(bytes))
    }

    fn path(&self, key: &str) -> Path {
        key.split('/')
            .fold(self.prefix.clone(), |p, part| p.join(part))
    }

    /// Writes `bytes` under `key` unless an object is there already (then it holds the same
    /// bytes: the key is their hash).
    pub async fn put(&self, key: &str, bytes: &[u8]) -> Result<()> {
        let opts = PutOptions {
            mode: PutMode::Create,
            ..PutOptions::default()
        };
        let payload = PutPayload::from(bytes.to_vec());
        match self.store.put_opts(&self.path(key), payload, opts).await {
            Ok(_) | Err(object_store::Error::AlreadyExists { .. }) => Ok(()),
            Err(e) => Err(storage(e)),
        }
    }

    /// The bytes under `key`, checked against the hash the key names; None when there is no
    /// object there.
    pub async fn get(&self, key: &str) -> Result<Option<Vec<u8>>> {
        let got = match self.store.get(&self.path(key)).await {
            Ok(got) => got,
            Err(object_store::Error::NotFound { .. }) => return Ok(None),
            Err(e) => return Err(storage(e)),
        };
        let bytes = got.bytes().await.map_err(storage)?.to_vec();
        let want = key.rsplit('/').next().unwrap_or_default();
        if sha256_hex(&bytes) != want {
            let why = format!("checksum mismatch for {key}");
            return Err(Error::corrupt("object store", why));
        }
        Ok(Some(bytes))
    }

    /// Deletes the object under `key` (gone already is fine).
    pub async fn delete(&self, key: &str) -> Result<()> {
        match self.store.delete(&self.path(key)).await {
            Ok(()) | Err(object_store::Error::NotFound { .. }) => Ok(()),
            Err(e) => Err(storage(e)),
        }
    }

    /// Whether `key` has an object.
    pub async fn exists(&self, key: &str) -> Result<bool> {
        match self.store.head(&self.path(key)).await {
            Ok(_) => Ok(true),
            Err(object_store::Error::NotFound { .. }) => Ok(false),
            Err(e) => Err(storage(e)),
        }
    }

    /// Writes the marker [`Blobs::ping`] looks for: at start, the store is writable (bucket,
    /// credentials, permissions), or the process does not start.
    pub async fn mark(&self) -> Result<()> {
        let marker = PutPayload::from_static(b"graybox");
        self.store
            .put(&self.path(MARKER), marker)
            .await
            .map_err(storage)?;
        Ok(())
    }

    /// Ready when the store answers with the marker: a missing bucket answers a read of any
    /// key as a missing object, so the marker's absence is what tells it apart.
    pub async fn ping(&self) -> Result<()> {
        if self.exists(MARKER).await? {
            return Ok(());
        }
        Err(Error::Storage(format!(
            "object store: {MARKER} is missing (the bucket or prefix was deleted or changed)"
        )))
    }
}

/// A row that points at an object: its table, the column that identifies it, and its id.
pub(super) type Row<'a> = (&'static str, &'static str, &'a str);

/// Bytes as a new row keeps them: inline in its column, or under `key` in the object store
/// (the column then empty).
pub(super) struct Placed<'a> {
    pub inline: &'a [u8],
    pub key: Option<String>,
}

impl super::Store {
    /// Puts `bytes` where a new row of `kind` keeps them. With `--blobs`: first counted as
    /// referenced (so that a concurrent delete of the same content cannot remove the object
    /// this row will point at), then written; the caller gives the reference back with
    /// [`Store::unreference`] if no row ends up pointing at it. A crash in between leaves a
    /// count too high: an object kept, never a row pointing at a missing one.
    pub(super) async fn place<'a>(&self, kind: Kind, bytes: &'a [u8]) -> Result<Placed<'a>> {
        let Some(blobs) = &self.blobs else {
            return Ok(Placed {
                inline: bytes,
                key: None,
            });
        };
        let key = Blobs::key(kind, bytes);
        on_db!(self, pool, D => {
            let mut tx = super::dialect::begin_write(pool).await?;
            sqlx::query(
                "INSERT INTO blob_refs (key, refs) VALUES ($1, 1)
                 ON CONFLICT (key) DO UPDATE SET refs = blob_refs.refs + 1",
            )
            .bind(&key)
            .execute(&mut *tx)
            .await?;
            tx.commit().await?;
        });
        if let Err(e) = blobs.put(&key, bytes).await {
            self.unreference(Some(&key)).await;
            return Err(e);
        }
        Ok(Placed {
            inline: &[],
            key: Some(key),
        })
    }

    /// Gives back one reference to `key`'s object (a row deleted or replaced, or a write that
    /// made none); at zero the object is deleted, inside the write transaction, so that a
    /// [`Store::place`] of the same bytes comes wholly before (and is counted) or wholly
    /// after (and writes the object anew). A failure is logged, not returned: the row's
    /// change has happened, and the object is merely kept.
    pub(super) async fn unreference(&self, key: Option<&str>) {
        let (Some(key), Some(blobs)) = (key, &self.blobs) else {
            return;
        };
        let released: Result<()> = on_db!(self, pool, D => async {
            let mut tx = super::dialect::begin_write(pool).await?;
            let left: Option<i64> =
                sqlx::query_scalar("UPDATE blob_refs SET refs = refs - 1 WHERE key = $1 RETURNING refs")
                    .bind(key)
                    .fetch_optional(&mut *tx)
                    .await?;
            if left.is_some_and(|n| n <= 0) {
                sqlx::query("DELETE FROM blob_refs WHERE key = $1")
                    .bind(key)
                    .execute(&mut *tx)
                    .await?;
                blobs.delete(key).await?;
            }
            tx.commit().await?;
            Ok(())
        }.await);
        if let Err(e) = released {
            tracing::warn!(key, error = %e, "releasing an object failed; it is kept");
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
}
