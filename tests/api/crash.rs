//! Durability with the real binary: `kill -9` mid-training and SIGTERM. A job resumes from
//! its last checkpoint and ends with exactly the parameters of an uninterrupted run.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use graybox::model::file::ModelFile;
use serde_json::{Value, json};

use crate::helpers::{dataset, final_state};

struct Server {
    child: Child,
    base: String,
    logs: mpsc::Receiver<String>,
    client: reqwest::blocking_free::Client,
}

/// A tiny blocking HTTP client over reqwest's async one (the tests here drive processes).
mod reqwest {
    pub mod blocking_free {
        pub struct Client {
            rt: tokio::runtime::Runtime,
            inner: ::reqwest::Client,
        }
        impl Client {
            pub fn new() -> Self {
                let rt = tokio::runtime::Builder::new_current_thread()
                    .enable_all()
                    .build()
                    .unwrap();
                Self {
                    rt,
                    inner: ::reqwest::Client::new(),
                }
            }
            pub fn get(&self, url: &str) -> serde_json::Value {
                self.rt.block_on(async {
                    self.inner
                        .get(url)
                        .send()
                        .await
                        .unwrap()
                        .json()
                        .await
                        .unwrap()
                })
            }
            pub fn bytes(&self, url: &str) -> Vec<u8> {
                self.rt.block_on(async {
                    self.inner
                        .get(url)
                        .send()
                        .await
                        .unwrap()
                        .bytes()
                        .await
                        .unwrap()
                        .to_vec()
                })
            }
            pub fn post(&self, url: &str, body: &serde_json::Value) -> serde_json::Value {
                self.rt.block_on(async {
                    self.inner
                        .post(url)
                        .json(body)
                        .send()
                        .await
                        .unwrap()
                        .json()
                        .await
                        .unwrap()
                })
            }
        }
    }
}

impl Server {
    fn start(db: &std::path::Path, workers: usize) -> Server {
        let mut child = Command::new(env!("CARGO_BIN_EXE_graybox"))
            .args([
                "serve",
                "--http",
                "127.0.0.1:0",
                "--grpc",
                "127.0.0.1:0",
                "--lease-secs",
                "2",
                "--checkpoint-every",
                "2",
            ])
            .args([
                "--workers",
                &workers.to_string(),
                "--db",
                db.to_str().unwrap(),
            ])
            .env("RUST_LOG", "warn,graybox=info")
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let (tx, rx) = mpsc::channel();
        let stderr = child.stderr.take().unwrap();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                let _ = tx.send(line);
            }
        });
        let deadline = Instant::now() + Duration::from_secs(30);
        let base = loop {
            let line = rx
                .recv_timeout(deadline - Instant::now())
                .expect("the server prints its address");
            if let Some(rest) = line.strip_prefix("graybox: REST on ") {
                break rest.split(',').next().unwrap().to_string();
            }
        };
        Server {
            child,
            base,
            logs: rx,
            client: reqwest::blocking_free::Client::new(),
        }
    }

    fn get(&self, path: &str) -> Value {
        self.client.get(&format!("{}{path}", self.base))
    }

    fn post(&self, path: &str, body: &Value) -> Value {
        self.client.post(&format!("{}{path}", self.base), body)
    }

    fn wait(&self, id: &str, secs: u64, done: impl Fn(&Value) -> bool) -> Value {
        let deadline = Instant::now() + Duration::from_secs(secs);
        loop {
            let job = self.get(&format!("/v1/jobs/{id}"));
            if done(&job) {
                return job;
            }
            assert!(Instant::now() < deadline, "job did not get there: {job}");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Every log line so far.
    fn drain_logs(&self) -> Vec<String> {
        self.logs.try_iter().collect()
    }

    fn sigterm(mut self) {
        Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status()
            .unwrap();
        let status = self.child.wait().unwrap();
        assert!(status.success(), "graceful shutdown exits 0: {status}");
    }
}

fn setup(s: &Server) -> String {
    let d = s.post("/v1/datasets", &dataset(1024, 21));
    let v = s.post("/v1/datasets", &dataset(128, 22));
    let body = json!({"dataset_id": d["id"], "validation_dataset_id": v["id"], "model": "MVF",
                      "training": {"epochs": 24, "batch_size": 64, "lr": 0.003}});
    s.post("/v1/jobs", &body)["id"]
        .as_str()
        .unwrap()
        .to_string()
}

fn model_params(s: &Server, job: &Value) -> ModelFile {
    let bytes = s.client.bytes(&format!(
        "{}/v1/models/{}/checkpoint",
        s.base,
        job["model_id"].as_str().unwrap()
    ));
    ModelFile::from_bytes(&bytes).unwrap()
}

fn metric_epochs(s: &Server, id: &str) -> Vec<i64> {
    s.get(&format!("/v1/jobs/{id}/metrics"))["items"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["epoch"].as_i64().unwrap())
        .collect()
}

#[test]
fn kill_and_sigterm_resume_from_checkpoints_and_match_an_uninterrupted_run() {
    let dir = tempfile::tempdir().unwrap();

    // Reference: one uninterrupted run.
    let reference = Server::start(&dir.path().join("ref.db"), 1);
    let rid = setup(&reference);
    let rjob = reference.wait(&rid, 300, final_state);
    assert_eq!(rjob["state"], "succeeded", "{rjob}");
    let want = model_params(&reference, &rjob);
    reference.sigterm();

    // kill -9 after the first checkpoints, then restart on the same database.
    let db = dir.path().join("crash.db");
    let mut first = Server::start(&db, 1);
    let id = setup(&first);
    let before = first.wait(&id, 120, |j| j["checkpoint_epoch"].as_i64() >= Some(2));
    assert_ne!(
        before["state"], "succeeded",
        "killed too late to test anything"
    );
    first.child.kill().unwrap();
    first.child.wait().unwrap();
    let second = Server::start(&db, 1);
    let done = second.wait(&id, 300, final_state);
    assert_eq!(done["state"], "succeeded", "{done}");
    assert_eq!(done["attempt"], 2, "reclaimed once after the lease expired");
    let resumed: Vec<String> = second
        .drain_logs()
        .into_iter()
        .filter(|l| l.contains("resuming from checkpoint"))
        .collect();
    assert_eq!(resumed.len(), 1, "{resumed:?}");
    assert!(
        !resumed[0].contains("epoch=0"),
        "resumed at a checkpoint, not epoch 0: {}",
        resumed[0]
    );
    let got = model_params(&second, &done);
    assert_eq!(
        got.params, want.params,
        "final parameters equal the uninterrupted run's"
    );
    assert_eq!(
        got.report.as_ref().unwrap().best_epoch,
        want.report.as_ref().unwrap().best_epoch
    );
    assert_eq!(
        metric_epochs(&second, &id),
        (1..=24).collect::<Vec<_>>(),
        "one metrics row per epoch"
    );
    assert_eq!(
        second.get("/v1/datasets")["items"]
            .as_array()
            .unwrap()
            .len(),
        2,
        "no row lost"
    );
    assert_eq!(second.get("/v1/jobs")["items"].as_array().unwrap().len(), 1);
    second.sigterm();

    // SIGTERM: the running job is checkpointed at its next epoch end and released as queued.
    let db = dir.path().join("term.db");
    let third = Server::start(&db, 1);
    let id = setup(&third);
    third.wait(&id, 120, |j| j["epoch"].as_i64() >= Some(3));
    third.sigterm();
    let idle = Server::start(&db, 0);
    let released = idle.get(&format!("/v1/jobs/{id}"));
    assert_eq!(released["state"], "queued", "{released}");
    let ck = released["checkpoint_epoch"].as_i64().unwrap();
    assert!(
        ck >= 3 && ck == released["epoch"].as_i64().unwrap(),
        "checkpointed at the epoch it stopped: {released}"
    );
    idle.sigterm();
    let last = Server::start(&db, 1);
    let done = last.wait(&id, 300, final_state);
    assert_eq!(done["state"], "succeeded", "{done}");
    assert_eq!(model_params(&last, &done).params, want.params);
    assert_eq!(metric_epochs(&last, &id), (1..=24).collect::<Vec<_>>());
    last.sigterm();
}
