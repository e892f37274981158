//! `spawn_app()`: the service on port 0 with a temporary database.
#![allow(dead_code)]

use std::time::Duration;

use graybox::api::grpc::pb::{self, dynamics_client::DynamicsClient};
use graybox::app::{Settings, WorkerSettings};
use graybox::physics::templates::Template;
use graybox::service::{Running, start};
use graybox::sim::{SimConfig, simulate};
use serde_json::{Value, json};

pub struct TestApp {
    pub running: Option<Running>,
    pub base: String,
    pub client: reqwest::Client,
    /// The database it runs on (`--db`).
    pub db: String,
    pub _dir: tempfile::TempDir,
}

/// A new, empty database for one test: an SQLite file in `dir`, or, when
/// `GRAYBOX_TEST_POSTGRES` names a PostgreSQL server (`postgres://user@host:port`, as
/// `scripts/test.sh` starts one), a new database on it. The suite runs once on each.
pub async fn fresh_db(dir: &std::path::Path) -> String {
    let Ok(server) = std::env::var("GRAYBOX_TEST_POSTGRES") else {
        return dir.join("test.db").to_string_lossy().into_owned();
    };
    use sqlx::Connection;
    let mut admin = sqlx::PgConnection::connect(&format!("{server}/postgres"))
        .await
        .expect("the test PostgreSQL server answers");
    let name = format!("t_{}", uuid::Uuid::new_v4().simple());
    sqlx::raw_sql(sqlx::AssertSqlSafe(format!("CREATE DATABASE {name}")))
        .execute(&mut admin)
        .await
        .unwrap();
    format!("{server}/{name}")
}

/// The object store of `db`'s large bytes: with `GRAYBOX_TEST_BLOBS` (an S3 bucket, as
/// `scripts/test.sh` starts one), a prefix of its own for each database, so that every node on
/// one database shares it; else none (inline in the rows).
pub fn blobs_for(db: &str) -> Option<String> {
    let bucket = std::env::var("GRAYBOX_TEST_BLOBS").ok()?;
    let name: String = (db.chars())
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    Some(format!("{bucket}/{name}"))
}

pub async fn spawn_app(workers: usize) -> TestApp {
    let mut settings = test_settings();
    settings.worker.workers = workers;
    spawn_configured(settings).await
}

/// What the tests run with unless they say otherwise: checkpoints every 2 epochs, 64 MB
/// bodies.
pub fn test_settings() -> Settings {
    Settings {
        worker: WorkerSettings {
            checkpoint_every: 2,
            lease_secs: 30,
            ..WorkerSettings::default()
        },
        max_body_mb: 64,
        ..Settings::default()
    }
}

/// The service with these settings on a new database (their addresses and database are
/// replaced: port 0 and a temporary file).
pub async fn spawn_configured(settings: Settings) -> TestApp {
    let dir = tempfile::tempdir().unwrap();
    let db = fresh_db(dir.path()).await;
    spawn_on(db, settings, dir).await
}

/// A second service process (its own App, cache and workers) on `app`'s database.
pub async fn spawn_app_on(app: &TestApp, workers: usize) -> TestApp {
    let mut settings = Settings::default();
    settings.worker.workers = workers;
    spawn_on(app.db.clone(), settings, tempfile::tempdir().unwrap()).await
}

/// The service with these settings on `db` (its addresses replaced by port 0), keeping `dir`.
pub async fn spawn_on(db: String, mut settings: Settings, dir: tempfile::TempDir) -> TestApp {
    settings.worker.db = db.clone();
    settings.worker.blobs = settings.worker.blobs.or_else(|| blobs_for(&db));
    let running = start(Settings {
        http: "127.0.0.1:0".into(),
        grpc: "127.0.0.1:0".into(),
        ..settings
    })
    .await
    .expect("service starts");
    let base = format!("http://{}", running.http_addr);
    TestApp {
        running: Some(running),
        base,
        client: reqwest::Client::new(),
        db,
        _dir: dir,
    }
}

impl TestApp {
    /// Another connection pool on the service's database, as a second process would open it.
    pub async fn open_store(&self) -> graybox::store::Store {
        let blobs = blobs_for(&self.db);
        (graybox::store::Store::open_with(&self.db, blobs.as_deref()).await).unwrap()
    }

    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }

    pub async fn get(&self, path: &str) -> (u16, Value) {
        let r = self.client.get(self.url(path)).send().await.unwrap();
        let status = r.status().as_u16();
        (status, r.json().await.unwrap_or(Value::Null))
    }

    pub async fn post(&self, path: &str, body: &Value) -> (u16, Value) {
        let r = self
            .client
            .post(self.url(path))
            .json(body)
            .send()
            .await
            .unwrap();
        let status = r.status().as_u16();
        (status, r.json().await.unwrap_or(Value::Null))
    }

    /// A model file uploaded (`POST /v1/models`, new); its id.
    pub async fn upload_model(&self, file: &graybox::model::file::ModelFile) -> String {
        let r = (self.client.post(self.url("/v1/models")))
            .body(file.to_bytes().unwrap())
            .send()
            .await
            .unwrap();
        assert_eq!(r.status().as_u16(), 201);
        let body: Value = r.json().await.unwrap();
        body["id"].as_str().unwrap().to_string()
    }

    /// A model's file as `GET /v1/models/{id}/checkpoint` serves it.
    pub async fn model_file(&self, id: &str) -> Vec<u8> {
        let r = self
            .client
            .get(self.url(&format!("/v1/models/{id}/checkpoint")))
            .send()
            .await
            .unwrap();
        r.bytes().await.unwrap().to_vec()
    }

    pub async fn upload(&self, body: &Value) -> String {
        let (status, v) = self.post("/v1/datasets", body).await;
        assert!(status == 201 || status == 200, "{status} {v}");
        v["id"].as_str().unwrap().to_string()
    }

    /// Polls a job until `done` holds (or panics after `secs`).
    pub async fn wait_job(&self, id: &str, secs: u64, done: impl Fn(&Value) -> bool) -> Value {
        let deadline = tokio::time::Instant::now() + Duration::from_secs(secs);
        loop {
            let (_, job) = self.get(&format!("/v1/jobs/{id}")).await;
            if done(&job) {
                return job;
            }
            assert!(
                tokio::time::Instant::now() < deadline,
                "job {id} did not get there: {job}"
            );
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }

    pub async fn stop(mut self) {
        if let Some(r) = self.running.take() {
            r.shutdown().await;
        }
    }
}

pub fn final_state(job: &Value) -> bool {
    matches!(
        job["state"].as_str(),
        Some("succeeded" | "failed" | "cancelled")
    )
}

/// The CLI/REST dataset JSON of a simulated double pendulum.
pub fn dataset(count: usize, seed: u64) -> Value {
    let t = Template::DoublePendulum;
    let ds = simulate(
        &t,
        t.defaults(),
        &SimConfig {
            count,
            seed,
            ..SimConfig::default()
        },
    )
    .unwrap();
    serde_json::from_str(&ds.to_json()).unwrap()
}

pub fn job_body(dataset_id: &str, model: &str, epochs: usize) -> Value {
    json!({"dataset_id": dataset_id, "model": model, "template": "double_pendulum",
           "training": {"epochs": epochs, "batch_size": 64}})
}

/// s·I, n × n, as an array message.
pub fn eye(n: usize, s: f64) -> Option<pb::Array> {
    let mut d = vec![0.0; n * n];
    (0..n).for_each(|i| d[i * n + i] = s);
    arr(&[n as u64, n as u64], d)
}

/// An array message of this shape.
pub fn arr(shape: &[u64], data: Vec<f64>) -> Option<pb::Array> {
    Some(pb::Array {
        shape: shape.to_vec(),
        data,
    })
}

/// A model of the double pendulum trained for one epoch on 128 transitions.
pub async fn trained(app: &TestApp, model: &str) -> String {
    let ds = app.upload(&dataset(128, 5)).await;
    let (_, job) = app.post("/v1/jobs", &job_body(&ds, model, 1)).await;
    let done = app
        .wait_job(job["id"].as_str().unwrap(), 120, final_state)
        .await;
    assert_eq!(done["state"], "succeeded", "{done}");
    done["model_id"].as_str().unwrap().to_string()
}

/// A gRPC Dynamics client of the service.
pub async fn client(app: &TestApp) -> DynamicsClient<tonic::transport::Channel> {
    let addr = format!("http://{}", app.running.as_ref().unwrap().grpc_addr);
    DynamicsClient::connect(addr).await.unwrap()
}

/// A Predict of `b` double-pendulum states.
pub fn predict_req(model: &str, b: usize) -> pb::PredictRequest {
    pb::PredictRequest {
        id: String::new(),
        model_id: model.into(),
        x: arr(&[b as u64, 4], vec![0.1; 4 * b]),
        u: arr(&[b as u64, 2], vec![1.0; 2 * b]),
        want_accel: false,
        members: false,
        dt: None,
    }
}
