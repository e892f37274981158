//! Large bytes in an object store (`--blobs`, here a local directory): written under their
//! content's key before a row points at them, read back verified, shared by rows with the same
//! bytes and deleted with the last of them; rows stored inline before keep being served.

use std::path::Path;
use std::time::Duration;

use graybox::error::Error;
use graybox::records::JobState;
use graybox::store::Store;
use graybox::store::blobs::Retry;

use super::rows::model;
use super::{TestStore, queued_job, small_dataset};

/// The objects under `dir/<kind>`, by name.
fn objects(dir: &Path, kind: &str) -> Vec<String> {
    let Ok(entries) = std::fs::read_dir(dir.join(kind)) else {
        return Vec::new();
    };
    let mut names: Vec<String> = entries
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

fn sha(bytes: &[u8]) -> String {
    graybox::store::sha256_hex(bytes)
}

async fn with_blobs(s: &TestStore, dir: &Path) -> Store {
    let url = format!("file://{}", dir.display());
    Store::open_with(&s.db, Some(&url)).await.unwrap()
}

#[tokio::test]
async fn rows_point_at_objects_that_two_rows_may_share_and_the_last_deletes() {
    let s = TestStore::new().await;
    let dir = tempfile::tempdir().unwrap();
    let b = with_blobs(&s, dir.path()).await;
    let file = b"one model file".to_vec();
    let (uploaded, _) = b.insert_model(model(&file)).await.unwrap();
    assert_eq!(objects(dir.path(), "models"), [sha(&file)]);
    // A trained model with the same bytes: a second row on the same object.
    queued_job(&b, 1, None).await;
    let c = b.claim_job("w", 600_000, 3).await.unwrap().unwrap();
    let trained = b.finish_job(&c, model(&file), &[]).await.unwrap().unwrap();
    assert_eq!(objects(dir.path(), "models"), [sha(&file)]);
    b.delete_model(&uploaded.id).await.unwrap();
    b.collect().await.unwrap();
    assert_eq!(b.model_file(&trained).await.unwrap(), Some(file.clone()));
    b.delete_model(&trained).await.unwrap();
    assert_eq!(
        objects(dir.path(), "models"),
        [sha(&file)],
        "deleted by the collector"
    );
    b.collect().await.unwrap();
    assert!(
        objects(dir.path(), "models").is_empty(),
        "the last row took it"
    );

    // A dataset: its arrays are one object; the same arrays again are the same row.
    let before = objects(dir.path(), "datasets");
    let ds = small_dataset(2);
    let (row, _) = b.insert_dataset(None, &ds).await.unwrap();
    let (again, created) = b.insert_dataset(None, &ds).await.unwrap();
    assert!(!created && again.id == row.id);
    assert_eq!(objects(dir.path(), "datasets").len(), before.len() + 1);
    assert_eq!(b.load_dataset(&row.id).await.unwrap(), Some(ds));
    b.delete_dataset(&row.id).await.unwrap();
    b.collect().await.unwrap();
    assert_eq!(objects(dir.path(), "datasets"), before);
}

/// A write the store refused gives its reference back even though the store also refuses
/// deletes then (before, the release was rolled back with the failed delete, and the object
/// written later for the same bytes outlived every row).
#[tokio::test]
async fn a_refused_write_leaves_no_reference_behind() {
    let s = TestStore::new().await;
    let dir = tempfile::tempdir().unwrap();
    let quick = Retry {
        timeout: Duration::from_secs(5),
        retry_for: Duration::ZERO,
    };
    let b = with_blobs(&s, dir.path()).await.with_retry(quick);
    // A file where the datasets' directory goes: every write and delete under it fails.
    let datasets = dir.path().join("datasets");
    std::fs::write(&datasets, b"in the way").unwrap();
    let ds = small_dataset(3);
    match b.insert_dataset(None, &ds).await {
        Err(Error::Storage(m)) => assert!(m.contains("object store"), "{m}"),
        other => panic!("{other:?}"),
    }
    assert!(b.collect().await.is_err(), "the store refuses deletes too");
    std::fs::remove_file(&datasets).unwrap();
    let (row, _) = b.insert_dataset(None, &ds).await.unwrap();
    assert_eq!(objects(dir.path(), "datasets").len(), 1);
    b.delete_dataset(&row.id).await.unwrap();
    assert_eq!(b.collect().await.unwrap(), 1);
    assert!(objects(dir.path(), "datasets").is_empty());
}

#[tokio::test]
async fn a_replaced_or_fenced_out_checkpoint_leaves_no_object_behind() {
    let s = TestStore::new().await;
    let dir = tempfile::tempdir().unwrap();
    let b = with_blobs(&s, dir.path()).await;
    let job = queued_job(&b, 1, None).await;
    let c = b.claim_job("a", 1, 3).await.unwrap().unwrap();
    for epoch in 1..=3u8 {
        assert!(
            b.save_checkpoint(&c, epoch.into(), &[epoch; 64])
                .await
                .unwrap()
        );
    }
    b.collect().await.unwrap();
    assert_eq!(objects(dir.path(), "checkpoints"), [sha(&[3; 64])]);
    // Its lease expires and another worker takes the job: the old holder's checkpoint is
    // refused and its object removed; the last committed one stays.
    tokio::time::sleep(std::time::Duration::from_millis(50)).await;
    let new = b.claim_job("b", 600_000, 3).await.unwrap().unwrap();
    assert!(!b.save_checkpoint(&c, 4, &[4; 64]).await.unwrap());
    b.collect().await.unwrap();
    assert_eq!(objects(dir.path(), "checkpoints"), [sha(&[3; 64])]);
    assert_eq!(
        b.load_checkpoint(&job.id).await.unwrap(),
        Some((3, vec![3; 64]))
    );
    // Once the job ends nothing resumes from its checkpoint: row and object go.
    assert!(b.end_job(&new, JobState::Succeeded, None).await.unwrap());
    assert_eq!(b.collect().await.unwrap(), 1);
    assert!(objects(dir.path(), "checkpoints").is_empty());
    assert_eq!(b.load_checkpoint(&job.id).await.unwrap(), None);
}

#[tokio::test]
async fn inline_rows_stay_served_beside_object_rows_and_need_the_store_they_name() {
    let s = TestStore::inline().await;
    let (inline, _) = s.insert_dataset(None, &small_dataset(1)).await.unwrap();
    let dir = tempfile::tempdir().unwrap();
    let b = with_blobs(&s, dir.path()).await;
    let (external, _) = b.insert_dataset(None, &small_dataset(2)).await.unwrap();
    assert_eq!(
        b.load_dataset(&inline.id).await.unwrap(),
        Some(small_dataset(1))
    );
    assert_eq!(
        b.load_dataset(&external.id).await.unwrap(),
        Some(small_dataset(2))
    );
    // A process without --blobs serves the inline row and says what the other needs.
    assert!(s.load_dataset(&inline.id).await.unwrap().is_some());
    match s.load_dataset(&external.id).await {
        Err(Error::FailedPrecondition(m)) => assert!(m.contains("--blobs"), "{m}"),
        other => panic!("{other:?}"),
    }
    // An object that went missing or changed is corrupt, not a wrong answer.
    let key = dir
        .path()
        .join("datasets")
        .join(&objects(dir.path(), "datasets")[0]);
    std::fs::write(&key, b"not the arrays").unwrap();
    match b.load_dataset(&external.id).await {
        Err(Error::Corrupt { .. }) => {}
        other => panic!("{other:?}"),
    }
    std::fs::remove_file(&key).unwrap();
    assert!(matches!(
        b.load_dataset(&external.id).await,
        Err(Error::Corrupt { .. })
    ));
}

/// Readiness asks the store for the marker every process writes at start, and writes it
/// anew when it is missing: a store that lost it is ready again; one that refuses the write
/// (a deleted bucket answers every read as a missing object) is not, and says so.
#[tokio::test]
async fn readiness_writes_a_missing_marker_anew() {
    let s = TestStore::new().await;
    let dir = tempfile::tempdir().unwrap();
    let b = with_blobs(&s, dir.path()).await;
    b.ping().await.unwrap();
    std::fs::remove_dir_all(dir.path().join("graybox")).unwrap();
    b.ping().await.unwrap();
    assert!(dir.path().join("graybox/ready").exists());
    std::fs::remove_dir_all(dir.path().join("graybox")).unwrap();
    std::fs::write(dir.path().join("graybox"), b"in the way").unwrap();
    match b.ping().await {
        Err(Error::Storage(m)) => {
            assert!(
                m.contains("object store") && m.contains("graybox/ready"),
                "{m}"
            )
        }
        other => panic!("{other:?}"),
    }
}

#[tokio::test]
async fn a_bad_blobs_url_is_refused_naming_the_flag() {
    let s = TestStore::new().await;
    for url in ["file://relative/dir", "s3://", "ftp://host/x"] {
        match Store::open_with(&s.db, Some(url)).await {
            Err(Error::Invalid { field, .. }) => assert_eq!(field, "blobs", "{url}"),
            other => panic!("{url}: {other:?}"),
        }
    }
}

/// The S3 endpoint of the run (`GRAYBOX_TEST_S3`, moto's server in `scripts/test.sh`) refuses
/// a second create of one key (412, which object_store reports as AlreadyExists): the
/// guarantee create-if-absent rests on, checked first so that an endpoint that regressed
/// (moto 5.2.0 answered 500) shows here by name. Without the endpoint (the SQLite run) there
/// is nothing to check.
#[tokio::test]
async fn the_s3_endpoint_refuses_a_second_create_of_a_key() {
    use object_store::aws::{AmazonS3Builder, S3ConditionalPut};
    use object_store::{ObjectStore, PutMode, PutOptions, PutPayload, path::Path};
    if std::env::var("GRAYBOX_TEST_S3").is_err() {
        return;
    }
    let s3 = AmazonS3Builder::from_env()
        .with_bucket_name("graybox-test")
        .with_conditional_put(S3ConditionalPut::ETagMatch)
        .build()
        .unwrap();
    let path = Path::from(format!("create-twice/{}", uuid::Uuid::new_v4().simple()));
    let create = || PutOptions {
        mode: PutMode::Create,
        ..PutOptions::default()
    };
    let once = s3
        .put_opts(&path, PutPayload::from_static(b"one"), create())
        .await;
    assert!(once.is_ok(), "{once:?}");
    let twice = s3
        .put_opts(&path, PutPayload::from_static(b"two"), create())
        .await;
    assert!(
        matches!(twice, Err(object_store::Error::AlreadyExists { .. })),
        "{twice:?}"
    );
}
