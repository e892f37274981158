//! The store's conformance suite: every public operation, on the backend the run uses (SQLite
//! by default, PostgreSQL under `GRAYBOX_TEST_POSTGRES`; `scripts/test.sh` runs both). The
//! API tests reach the store through the service; these call it directly, so that a backend
//! that differs in one statement fails here by name.

mod blobs;
mod queue;
mod rows;

use graybox::data::Dataset;
use graybox::physics::templates::Template;
use graybox::sim::{SimConfig, simulate};
use graybox::store::{NewJob, Store, Submitted};

use crate::helpers::{blobs_for, fresh_db};

/// A store on a new database (as `fresh_db` makes one).
pub struct TestStore {
    pub store: Store,
    pub db: String,
    _dir: tempfile::TempDir,
}

impl std::ops::Deref for TestStore {
    type Target = Store;
    fn deref(&self) -> &Store {
        &self.store
    }
}

impl TestStore {
    /// On the run's backends (large bytes in its object store, if it has one).
    pub async fn new() -> Self {
        Self::open(true).await
    }

    /// Large bytes inline in the rows, whatever the run's object store.
    pub async fn inline() -> Self {
        Self::open(false).await
    }

    async fn open(blobs: bool) -> Self {
        let dir = tempfile::tempdir().unwrap();
        let db = fresh_db(dir.path()).await;
        let blobs = blobs.then(|| blobs_for(&db)).flatten();
        let store = Store::open_with(&db, blobs.as_deref()).await.unwrap();
        Self {
            store,
            db,
            _dir: dir,
        }
    }

    /// A second connection pool on the same database, as another process opens it.
    pub async fn reopen(&self) -> Store {
        let blobs = blobs_for(&self.db);
        Store::open_with(&self.db, blobs.as_deref()).await.unwrap()
    }
}

pub fn small_dataset(seed: u64) -> Dataset {
    let t = Template::DoublePendulum;
    let cfg = SimConfig {
        count: 16,
        seed,
        ..SimConfig::default()
    };
    simulate(&t, t.defaults(), &cfg).unwrap()
}

/// A dataset in the store and a job on it (created), with an idempotency key if given.
pub async fn queued_job(store: &Store, seed: u64, key: Option<&str>) -> graybox::store::JobRow {
    let (ds, _) = store
        .insert_dataset(None, &small_dataset(seed))
        .await
        .unwrap();
    match store.submit_job(new_job(&ds.id, key)).await.unwrap() {
        Submitted::Created(job) => job,
        Submitted::Existing(job) => panic!("a new request found job {}", job.id),
    }
}

pub fn new_job(dataset_id: &str, key: Option<&str>) -> NewJob {
    NewJob {
        dataset_id: dataset_id.into(),
        validation_dataset_id: None,
        request: format!(r#"{{"model_name":"MVF","dataset_id":"{dataset_id}"}}"#),
        epochs: 4,
        idempotency_key: key.map(String::from),
        template_id: None,
    }
}
