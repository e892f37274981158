//! Large bytes (dataset arrays, checkpoints, model files) in an object store (`--blobs`): a
//! local directory (`file:///path`) or S3 and S3-compatible stores (`s3://bucket/prefix`,
//! configured by the usual `AWS_*` environment variables). Keys are the bytes' sha256, so an
//! object never changes once written; objects are written create-if-absent before any row
//! points at them, and read back verified against their key.
//!
//! Every call has a timeout and is retried with backoff (docs/storage.md#object-store-faults):
//! an unreachable store is the cluster's fault, not the request's, so a call gives up only
//! after `--blobs-retry-secs` of failures. The object store's own client does not retry, so
//! that one policy, this one, bounds how long a call can take.

use std::future::Future;
use std::sync::Arc;
use std::time::{Duration, Instant};

use object_store::aws::{AmazonS3Builder, AmazonS3ConfigKey, S3ConditionalPut};
use object_store::local::LocalFileSystem;
use object_store::path::Path;
use object_store::{
    ClientConfigKey, ObjectStore, ObjectStoreExt, PutMode, PutOptions, PutPayload, RetryConfig,
};

use super::sha256_hex;
use crate::backoff::Backoff;
use crate::error::{Error, Result};

/// The object every graybox process writes at start and readiness checks for.
const MARKER: &str = "graybox/ready";

/// Readiness asks the store once, this long at most: a probe must answer while the store
/// hangs.
pub const PING_TIMEOUT: Duration = Duration::from_secs(2);

/// The waits between tries of one call.
const RETRY_BACKOFF: Backoff = Backoff::new(Duration::from_millis(200), Duration::from_secs(5));

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

/// How long one call to the store may take, and how long a failing call is tried again.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Retry {
    /// One try that has not answered by then is abandoned (and counts as a failure).
    pub timeout: Duration,
    /// Tries go on, with backoff, until this long after the first; then the error is returned.
    pub retry_for: Duration,
}

impl Default for Retry {
    fn default() -> Self {
        Self {
            timeout: Duration::from_secs(30),
            retry_for: Duration::from_secs(30),
        }
    }
}

/// An object store under a prefix. Cheap to clone.
#[derive(Clone)]
pub struct Blobs {
    store: Arc<dyn ObjectStore>,
    prefix: Path,
    retry: Retry,
}

impl std::fmt::Debug for Blobs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Blobs({}, {})", self.store, self.prefix)
    }
}

/// How a deletion's one try failed.
#[derive(Debug)]
pub enum DeleteFailed {
    /// The store answered with an error: the object is still there.
    Refused(Error),
    /// No answer in time: the store may still carry the deletion out.
    Unanswered(Error),
}

/// An object store failure: the store is unavailable, not the request wrong.
fn storage(e: object_store::Error) -> Error {
    Error::Storage(format!("object store: {e}"))
}

/// What one try of a call came to: done, or failed in a way another try may not repeat.
/// Why the client would refuse the endpoint the environment names: a plain `http://` one
/// (a MinIO or moto in a private network) needs `AWS_ALLOW_HTTP`, and without it every call
/// fails with the HTTP client's bare "builder error".
fn plain_http_refused(s3: &AmazonS3Builder) -> Option<String> {
    let endpoint = s3.get_config_value(&AmazonS3ConfigKey::Endpoint)?;
    let allowed = s3
        .get_config_value(&AmazonS3ConfigKey::Client(ClientConfigKey::AllowHttp))
        .is_some_and(|v| {
            ["1", "true", "on", "yes", "y"].contains(&v.to_ascii_lowercase().as_str())
        });
    (endpoint.starts_with("http://") && !allowed).then(|| {
        format!(
            "the endpoint {endpoint} (AWS_ENDPOINT) is plain HTTP, which the client refuses \
             unless AWS_ALLOW_HTTP=true is set too (or use an https:// endpoint)"
        )
    })
}

enum Try<T> {
    Done(T),
    Again(Error),
}

impl Blobs {
    /// The store `url` names: `file:///absolute/dir` (created if missing) or
    /// `s3://bucket[/prefix]`; calls retried as [`Retry::default`].
    pub fn open(url: &str) -> Result<Self> {
        let bad = |why: &str| Error::invalid("blobs", format!("{url}: {why}"));
        if let Some(dir) = url.strip_prefix("file://") {
            if !dir.starts_with('/') {
                return Err(bad("a file:// URL needs an absolute path (file:///dir)"));
            }
            std::fs::create_dir_all(dir).map_err(|e| bad(&e.to_string()))?;
            let local = LocalFileSystem::new_with_prefix(dir).map_err(|e| bad(&e.to_string()))?;
            return Ok(Self::new(Arc::new(local), Path::default()));
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
        let s3 = AmazonS3Builder::from_env();
        if let Some(why) = plain_http_refused(&s3) {
            return Err(bad(&why));
        }
        let s3 = s3
            .with_bucket_name(bucket)
            .with_conditional_put(S3ConditionalPut::ETagMatch)
            .with_retry(RetryConfig {
                max_retries: 0,
                ..RetryConfig::default()
            })
            .build()
            .map_err(|e| bad(&e.to_string()))?;
        Ok(Self::new(Arc::new(s3), Path::from(prefix)))
    }

    fn new(store: Arc<dyn ObjectStore>, prefix: Path) -> Self {
        Self {
            store,
            prefix,
            retry: Retry::default(),
        }
    }

    /// The same store, its calls timed out and retried as `retry` says.
    pub fn with_retry(self, retry: Retry) -> Self {
        Self { retry, ..self }
    }

    /// How long one try of a call may take.
    pub fn timeout(&self) -> Duration {
        self.retry.timeout
    }

    /// The key of `bytes` of this kind: its directory and sha256.
    pub fn key(kind: Kind, bytes: &[u8]) -> String {
        format!("{}/{}", kind.dir(), sha256_hex(bytes))
    }

    fn path(&self, key: &str) -> Path {
        key.split('/')
            .fold(self.prefix.clone(), |p, part| p.join(part))
    }

    /// Runs `call` until it is done, a try times out or fails again after `retry_for`
    /// (then its last error), with backoff between tries.
    async fn retried<T, F, Fut>(&self, what: &str, mut call: F) -> Result<T>
    where
        F: FnMut() -> Fut,
        Fut: Future<Output = Result<Try<T>>>,
    {
        let start = Instant::now();
        let mut retry = 0;
        loop {
            let error = match self.once(what, self.retry.timeout, call()).await {
                Ok(Try::Done(t)) => return Ok(t),
                Ok(Try::Again(e)) | Err(e) => e,
            };
            let wait = RETRY_BACKOFF.delay(retry);
            if start.elapsed() + wait > self.retry.retry_for {
                return Err(error);
            }
            tracing::debug!(what, error = %error, ?wait, "object store call failed; retrying");
            tokio::time::sleep(wait).await;
            retry = retry.saturating_add(1);
        }
    }

    /// One try of `call`, abandoned after `timeout`.
    async fn once<T>(
        &self,
        what: &str,
        timeout: Duration,
        call: impl Future<Output = Result<T>>,
    ) -> Result<T> {
        match tokio::time::timeout(timeout, call).await {
            Ok(done) => done,
            Err(_) => Err(Error::Storage(format!(
                "object store: {what} did not answer within {} s",
                timeout.as_secs_f64()
            ))),
        }
    }

    /// Writes `bytes` under `key` unless an object is there already (then it holds the same
    /// bytes: the key is their hash).
    pub async fn put(&self, key: &str, bytes: &[u8]) -> Result<()> {
        let path = self.path(key);
        let payload = PutPayload::from(bytes.to_vec());
        self.retried(&format!("writing {key}"), || async {
            let opts = PutOptions {
                mode: PutMode::Create,
                ..PutOptions::default()
            };
            match self.store.put_opts(&path, payload.clone(), opts).await {
                Ok(_) | Err(object_store::Error::AlreadyExists { .. }) => Ok(Try::Done(())),
                Err(e) => Ok(Try::Again(storage(e))),
            }
        })
        .await
    }

    /// The bytes under `key`, checked against the hash the key names; None when there is no
    /// object there. A read that does not match its key is tried again (a transfer cut
    /// short), and is corrupt when it still does not.
    pub async fn get(&self, key: &str) -> Result<Option<Vec<u8>>> {
        let path = self.path(key);
        let want = key.rsplit('/').next().unwrap_or_default();
        self.retried(&format!("reading {key}"), || async {
            let got = match self.store.get(&path).await {
                Ok(got) => got,
                Err(object_store::Error::NotFound { .. }) => return Ok(Try::Done(None)),
                Err(e) => return Ok(Try::Again(storage(e))),
            };
            // Into a Vec without a copy when the bytes own their buffer alone.
            let bytes: Vec<u8> = match got.bytes().await {
                Ok(b) => b.into(),
                Err(e) => return Ok(Try::Again(storage(e))),
            };
            if sha256_hex(&bytes) != want {
                let why = format!("checksum mismatch for {key}");
                return Ok(Try::Again(Error::corrupt("object store", why)));
            }
            Ok(Try::Done(Some(bytes)))
        })
        .await
    }

    /// Deletes the object under `key` (gone already is fine): one try, as the collector
    /// makes it (it tries again on a later sweep).
    pub async fn delete_once(&self, key: &str) -> std::result::Result<(), DeleteFailed> {
        let path = self.path(key);
        match tokio::time::timeout(self.retry.timeout, self.store.delete(&path)).await {
            Ok(Ok(()) | Err(object_store::Error::NotFound { .. })) => Ok(()),
            Ok(Err(e)) => Err(DeleteFailed::Refused(storage(e))),
            Err(_) => Err(DeleteFailed::Unanswered(Error::Storage(format!(
                "object store: deleting {key} did not answer within {} s",
                self.retry.timeout.as_secs_f64()
            )))),
        }
    }

    /// Whether `key` has an object.
    pub async fn exists(&self, key: &str) -> Result<bool> {
        let path = self.path(key);
        self.retried(&format!("looking up {key}"), || async {
            match self.store.head(&path).await {
                Ok(_) => Ok(Try::Done(true)),
                Err(object_store::Error::NotFound { .. }) => Ok(Try::Done(false)),
                Err(e) => Ok(Try::Again(storage(e))),
            }
        })
        .await
    }

    /// Writes the marker [`Blobs::ping`] looks for: at start, the store is writable (bucket,
    /// credentials, permissions), or the process does not start.
    pub async fn mark(&self) -> Result<()> {
        let marker = PutPayload::from_static(b"graybox");
        self.retried("writing the readiness marker", || async {
            match self.store.put(&self.path(MARKER), marker.clone()).await {
                Ok(_) => Ok(Try::Done(())),
                Err(e) => Ok(Try::Again(storage(e))),
            }
        })
        .await
    }

    /// Ready when the store answers with the marker, asked once within [`PING_TIMEOUT`]. A
    /// missing marker is written anew: a deleted bucket refuses that write (not ready), while
    /// a store that merely lost the marker is ready again (and the loss is logged).
    pub async fn ping(&self) -> Result<()> {
        let path = self.path(MARKER);
        let found = self.once("readiness", PING_TIMEOUT, async {
            match self.store.head(&path).await {
                Ok(_) => Ok(true),
                Err(object_store::Error::NotFound { .. }) => Ok(false),
                Err(e) => Err(storage(e)),
            }
        });
        if found.await? {
            return Ok(());
        }
        tracing::warn!(
            marker = MARKER,
            "the object store's marker was missing; writing it anew"
        );
        let marker = PutPayload::from_static(b"graybox");
        let written = self.once("readiness", PING_TIMEOUT, async {
            self.store.put(&path, marker).await.map_err(storage)
        });
        written.await.map(|_| ()).map_err(|e| {
            Error::Storage(format!(
                "{e} ({MARKER} was missing and cannot be written: was the bucket or prefix \
                 deleted or changed?)"
            ))
        })
    }
}
