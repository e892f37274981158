//! Issue 25: a shutdown that cannot wait for an epoch end. Past its grace (here: at once) the
//! jobs still held go back to the queue immediately, from their last checkpoint: not after
//! their lease expires, and not counted as a dead worker. The process-level bound (SIGTERM
//! with Plans and training running) is in tests/python/test_hostile.py.

use graybox::records::JobState;
use graybox::service::Stopped;
use serde_json::json;

use crate::helpers::*;

#[tokio::test]
async fn a_forced_shutdown_gives_held_jobs_back_at_once() {
    // A lease far longer than the test: only an explicit release makes the job claimable.
    let mut settings = test_settings();
    settings.worker.workers = 1;
    settings.worker.lease_secs = 600;
    let mut app = spawn_configured(settings).await;
    let ds = app.upload(&dataset(1024, 3)).await;
    let body = json!({"dataset_id": ds, "model": "MVF", "template": "double_pendulum",
                      "training": {"epochs": 100_000, "batch_size": 1024}});
    let (status, job) = app.post("/v1/jobs", &body).await;
    assert_eq!(status, 201, "{job}");
    let id = job["id"].as_str().unwrap().to_string();
    let running = app
        .wait_job(&id, 120, |j| {
            j["state"] == "running" && j["epoch"].as_i64() >= Some(1)
        })
        .await;

    let stopped = app
        .running
        .take()
        .unwrap()
        .shutdown_by(std::future::ready(()))
        .await;
    assert!(matches!(stopped, Stopped::Forced { .. }), "{stopped:?}");

    let store = app.open_store().await;
    let row = store.get_job(&id).await.unwrap().unwrap();
    assert_eq!(row.state, JobState::Queued, "{row:?}");
    let again = store
        .claim_job("another-process", 60_000, 3)
        .await
        .unwrap()
        .expect("claimable at once, long before the lease would expire");
    assert_eq!(again.job.id, id);
    assert_eq!(again.attempt, running["attempt"].as_i64().unwrap() + 1);
    assert_eq!(
        worker_deaths(&app, &id).await,
        0,
        "a release is not a dead worker"
    );
}

/// The job's count of dead workers, read from its database as it stands.
async fn worker_deaths(app: &TestApp, id: &str) -> i64 {
    const SQL: &str = "SELECT worker_deaths FROM jobs WHERE id = $1";
    if graybox::store::is_postgres(&app.db) {
        let pool = sqlx::PgPool::connect(&app.db).await.unwrap();
        sqlx::query_scalar(SQL)
            .bind(id)
            .fetch_one(&pool)
            .await
            .unwrap()
    } else {
        let pool = sqlx::SqlitePool::connect(&format!("sqlite://{}", app.db))
            .await
            .unwrap();
        sqlx::query_scalar(SQL)
            .bind(id)
            .fetch_one(&pool)
            .await
            .unwrap()
    }
}
