//! graybox processes for the tests that kill them: `serve` and `worker` on a database, their
//! logs, and a blocking HTTP client to talk to them.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use graybox::model::file::ModelFile;
use graybox::model::params_io::NamedArray;
use serde_json::Value;

/// A running `graybox` command; its stderr is collected line by line.
pub struct Proc {
    pub child: Child,
    logs: mpsc::Receiver<String>,
    lines: Vec<String>,
}

impl Proc {
    /// `graybox <command> --db <db>` (and the run's object store, see `blobs_for`) with a 2 s
    /// lease and checkpoints every 2 epochs, so that a killed worker's job is reclaimed soon
    /// and resumes from a recent checkpoint.
    pub fn spawn(command: &str, db: &str, args: &[&str]) -> Proc {
        Proc::spawn_env(command, db, args, &[])
    }

    /// [`Proc::spawn`] with these environment variables set too.
    pub fn spawn_env(command: &str, db: &str, args: &[&str], env: &[(&str, &str)]) -> Proc {
        let blobs = crate::helpers::blobs_for(db).map(|b| ["--blobs".to_string(), b]);
        let common = ["--db", db, "--lease-secs", "2", "--checkpoint-every", "2"];
        let mut child = Command::new(env!("CARGO_BIN_EXE_graybox"))
            .arg(command)
            .args(common)
            .args(blobs.iter().flatten())
            .args(args)
            .env("RUST_LOG", "warn,graybox=info")
            .envs(env.iter().copied())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let (tx, logs) = mpsc::channel();
        let stderr = child.stderr.take().unwrap();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                let _ = tx.send(line);
            }
        });
        Proc {
            child,
            logs,
            lines: Vec::new(),
        }
    }

    /// A training worker process (not waited for: see [`Proc::ready_worker`]).
    pub fn worker(db: &str) -> Proc {
        Proc::spawn("worker", db, &["--workers", "1"])
    }

    /// Waits until the worker says it runs.
    pub fn ready_worker(mut self) -> Proc {
        self.wait_for("graybox worker: ");
        self
    }

    /// Waits (30 s at most) for a log line starting with `prefix`; the rest of it.
    pub fn wait_for(&mut self, prefix: &str) -> String {
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let line = self
                .logs
                .recv_timeout(left)
                .unwrap_or_else(|_| panic!("no line {prefix:?}; so far: {:?}", self.lines));
            self.lines.push(line.clone());
            if let Some(rest) = line.strip_prefix(prefix) {
                return rest.to_string();
            }
        }
    }

    /// Every log line so far.
    pub fn logs(&mut self) -> &[String] {
        self.lines.extend(self.logs.try_iter());
        &self.lines
    }

    /// `kill -9`; its log lines.
    pub fn kill(mut self) -> Vec<String> {
        self.child.kill().unwrap();
        self.child.wait().unwrap();
        // The reader thread ends at EOF: every line written before the kill is in.
        std::thread::sleep(Duration::from_millis(100));
        self.logs().to_vec()
    }

    /// SIGTERM, and a clean exit.
    pub fn sigterm(mut self) {
        Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status()
            .unwrap();
        let status = self.child.wait().unwrap();
        assert!(status.success(), "graceful shutdown exits 0: {status}");
    }
}

/// A test that fails leaves no process behind (the processes of one that passes have exited
/// already: killing a waited-for child sends nothing).
impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `graybox serve` and a client of its REST API.
pub struct Server {
    pub proc: Proc,
    pub base: String,
    client: http::Client,
}

impl Server {
    /// `graybox serve` with `workers` training workers, not waited for.
    pub fn spawn(db: &str, workers: usize) -> Proc {
        let workers = workers.to_string();
        let args = ["--http", "127.0.0.1:0", "--grpc", "127.0.0.1:0"];
        Proc::spawn("serve", db, &[&args[..], &["--workers", &workers]].concat())
    }

    /// Waits until `proc` (from [`Server::spawn`]) serves.
    pub fn ready(mut proc: Proc) -> Server {
        let rest = proc.wait_for("graybox: REST on ");
        Server {
            proc,
            base: rest.split(',').next().unwrap().to_string(),
            client: http::Client::new(),
        }
    }

    pub fn start(db: &str, workers: usize) -> Server {
        Server::ready(Server::spawn(db, workers))
    }

    pub fn get(&self, path: &str) -> Value {
        self.client.get(&format!("{}{path}", self.base))
    }

    pub fn post(&self, path: &str, body: &Value) -> Value {
        self.client.post(&format!("{}{path}", self.base), body)
    }

    /// A request that must be answered within `timeout`: its status and JSON body.
    pub fn call(
        &self,
        method: reqwest::Method,
        path: &str,
        body: Option<&Value>,
        timeout: Duration,
    ) -> (u16, Value) {
        let url = format!("{}{path}", self.base);
        self.client.call(method, &url, body, timeout)
    }

    /// Polls job `id` until `done` holds (or panics after `secs`).
    pub fn wait(&self, id: &str, secs: u64, done: impl Fn(&Value) -> bool) -> Value {
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

    /// A batch of jobs on one dataset of `rows` (seed `seed`) with a validation dataset of
    /// 128 (seed `seed + 1`): `jobs` of `epochs`, their models in turn from `models`, seed 0
    /// for the first round of models, 1 for the next, …; their ids, in submission order.
    pub fn submit_batch(
        &self,
        models: &[&str],
        jobs: usize,
        epochs: i64,
        (rows, seed): (usize, u64),
    ) -> Vec<String> {
        let d = self.post("/v1/datasets", &crate::helpers::dataset(rows, seed));
        let v = self.post("/v1/datasets", &crate::helpers::dataset(128, seed + 1));
        (0..jobs)
            .map(|i| {
                let body = serde_json::json!({"dataset_id": d["id"],
                    "validation_dataset_id": v["id"], "model": models[i % models.len()],
                    "template": "double_pendulum",
                    "training": {"epochs": epochs, "batch_size": 64, "lr": 0.003,
                                 "seed": i / models.len()}});
                let job = self.post("/v1/jobs", &body);
                job["id"]
                    .as_str()
                    .unwrap_or_else(|| panic!("{job}"))
                    .to_string()
            })
            .collect()
    }

    /// The model file a finished job made.
    pub fn model_file(&self, job: &Value) -> ModelFile {
        let id = job["model_id"].as_str().unwrap();
        let bytes = self
            .client
            .bytes(&format!("{}/v1/models/{id}/checkpoint", self.base));
        ModelFile::from_bytes(&bytes).unwrap()
    }

    /// The epochs of job `id`'s metrics rows, in order.
    pub fn metric_epochs(&self, id: &str) -> Vec<i64> {
        self.get(&format!("/v1/jobs/{id}/metrics"))["items"]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| m["epoch"].as_i64().unwrap())
            .collect()
    }

    /// The body of a GET of `url`.
    pub fn bytes(&self, url: &str) -> Vec<u8> {
        self.client.bytes(url)
    }

    pub fn sigterm(self) {
        self.proc.sigterm();
    }
}

/// The parameters of the models of `submit`'s jobs trained undisturbed: `graybox serve` with
/// two workers on a new database `db`, every job waited for and checked succeeded.
pub fn undisturbed(db: &str, submit: impl Fn(&Server) -> Vec<String>) -> Vec<Vec<NamedArray>> {
    let reference = Server::start(db, 2);
    let want = (submit(&reference).iter())
        .map(|id| reference.wait(id, 600, crate::helpers::final_state))
        .map(|job| {
            assert_eq!(job["state"], "succeeded", "{job}");
            reference.model_file(&job).params
        })
        .collect();
    reference.sigterm();
    want
}

/// A new database for a test that drives processes (see `helpers::fresh_db`); `dir` is
/// created for an SQLite file.
pub fn fresh_db(dir: &std::path::Path) -> String {
    std::fs::create_dir_all(dir).unwrap();
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(crate::helpers::fresh_db(dir))
}

/// A tiny blocking HTTP client over reqwest's async one.
mod http {
    pub struct Client {
        rt: tokio::runtime::Runtime,
        inner: reqwest::Client,
    }

    impl Client {
        pub fn new() -> Self {
            let rt = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .unwrap();
            Self {
                rt,
                inner: reqwest::Client::new(),
            }
        }

        fn send(&self, request: reqwest::RequestBuilder) -> reqwest::Response {
            self.rt.block_on(request.send()).unwrap()
        }

        pub fn get(&self, url: &str) -> serde_json::Value {
            let r = self.send(self.inner.get(url));
            self.rt.block_on(r.json()).unwrap()
        }

        pub fn bytes(&self, url: &str) -> Vec<u8> {
            let r = self.send(self.inner.get(url));
            self.rt.block_on(r.bytes()).unwrap().to_vec()
        }

        /// A request answered within `timeout` (or panics): its status and JSON body (null
        /// when it has none).
        pub fn call(
            &self,
            method: reqwest::Method,
            url: &str,
            body: Option<&serde_json::Value>,
            timeout: std::time::Duration,
        ) -> (u16, serde_json::Value) {
            let mut request = self.inner.request(method, url).timeout(timeout);
            if let Some(body) = body {
                request = request.json(body);
            }
            // Sent inside the runtime: a request's timeout starts its timer when sent.
            let r = self.rt.block_on(async { request.send().await });
            let r = r.unwrap_or_else(|e| panic!("{url}: no answer within {timeout:?}: {e}"));
            let status = r.status().as_u16();
            let text = self.rt.block_on(r.text()).unwrap();
            (status, serde_json::from_str(&text).unwrap_or_default())
        }

        pub fn post(&self, url: &str, body: &serde_json::Value) -> serde_json::Value {
            let r = self.send(self.inner.post(url).json(body));
            self.rt.block_on(r.json()).unwrap()
        }
    }
}
