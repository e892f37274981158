//! Faults of the object store, with the real binaries on PostgreSQL and the S3 endpoint of
//! `scripts/test.sh`'s second run, through the tests' fault proxy (`faults.rs`): an outage
//! longer than any one call's retries fails no job, and a store that hangs on a delete stalls
//! no other node. Without the endpoint (the SQLite run) there is nothing to put a proxy in
//! front of, and these return at once.

use std::time::{Duration, Instant};

use reqwest::Method;
use serde_json::{Value, json};

use crate::faults::{FaultProxy, Mode, ONE_REQUEST_PER_CONNECTION, endpoint_addr};
use crate::helpers::{blobs_for, dataset, final_state};
use crate::processes::{Proc, Server, fresh_db, undisturbed};

const JOBS: usize = 6;
const EPOCHS: i64 = 24;
const MODELS: [&str; 3] = ["MVF", "MV", "W-B"];
/// How long the store refuses every connection: many times what a call's retries last here
/// (`--blobs-retry-secs 3`) and what they lasted before jobs waited outages out (three tries
/// of about 2 s each).
const OUTAGE: Duration = Duration::from_secs(25);

/// The S3 endpoint's address, and a proxy in front of it on a runtime of its own.
fn proxied_store() -> Option<(tokio::runtime::Runtime, FaultProxy)> {
    let s3 = std::env::var("GRAYBOX_TEST_S3").ok()?;
    let rt = tokio::runtime::Runtime::new().unwrap();
    let proxy = rt.block_on(FaultProxy::start(endpoint_addr(&s3)));
    Some((rt, proxy))
}

/// `graybox <command>` whose object store is reached through `proxy`.
fn through(proxy: &FaultProxy, command: &str, db: &str, args: &[&str]) -> Proc {
    let endpoint = format!("http://{}", proxy.addr);
    let env = [
        ("AWS_ENDPOINT", endpoint.as_str()),
        ONE_REQUEST_PER_CONNECTION,
    ];
    Proc::spawn_env(command, db, args, &env)
}

fn api_node(proxy: &FaultProxy, db: &str, args: &[&str]) -> Server {
    let listen = [
        "--http",
        "127.0.0.1:0",
        "--grpc",
        "127.0.0.1:0",
        "--workers",
        "0",
    ];
    Server::ready(through(proxy, "serve", db, &[&listen[..], args].concat()))
}

/// The jobs (three models, two seeds), submitted in order; their ids.
fn submit_all(s: &Server) -> Vec<String> {
    s.submit_batch(&MODELS, JOBS, EPOCHS, (512, 61))
}

/// The keys of the objects under `db`'s prefix whose kind is `kind` (read straight from the
/// endpoint, not through the proxy).
fn objects(rt: &tokio::runtime::Runtime, db: &str, kind: &str) -> Vec<String> {
    use futures_util::TryStreamExt;
    use object_store::ObjectStore;
    // object_store's HTTP client has no TLS provider of its own (see `store/blobs.rs`).
    let _ = tokio_rustls::rustls::crypto::ring::default_provider().install_default();
    let url = blobs_for(db).unwrap();
    let prefix = url.trim_start_matches("s3://graybox-test/");
    let s3 = object_store::aws::AmazonS3Builder::from_env()
        .with_bucket_name("graybox-test")
        .build()
        .unwrap();
    let path = object_store::path::Path::from(format!("{prefix}/{kind}"));
    let listed: Vec<_> = rt.block_on(s3.list(Some(&path)).try_collect()).unwrap();
    listed.into_iter().map(|o| o.location.to_string()).collect()
}

#[test]
fn an_object_store_outage_fails_no_job_and_changes_no_result() {
    let Some((rt, proxy)) = proxied_store() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let want = undisturbed(&fresh_db(&dir.path().join("reference")), submit_all);

    let db = fresh_db(&dir.path().join("outage"));
    let api = api_node(&proxy, &db, &["--blobs-retry-secs", "3"]);
    let worker_args = [
        "--workers",
        "1",
        "--blobs-retry-secs",
        "3",
        "--blobs-timeout-secs",
        "5",
    ];
    let workers: Vec<Proc> = (0..2)
        .map(|_| through(&proxy, "worker", &db, &worker_args).ready_worker())
        .collect();
    let ids = submit_all(&api);
    // The outage begins once two jobs are past their first checkpoint, the rest queued.
    let t0 = Instant::now();
    let job = |id: &String| api.get(&format!("/v1/jobs/{id}"));
    while (ids.iter().map(job))
        .filter(|j| j["checkpoint_epoch"].as_i64() >= Some(2))
        .count()
        < 2
    {
        assert!(t0.elapsed() < Duration::from_secs(300), "no job got going");
        std::thread::sleep(Duration::from_millis(50));
    }
    let before: Vec<Value> = ids.iter().map(job).collect();
    proxy.set(Mode::Refuse);
    std::thread::sleep(OUTAGE / 2);
    let (status, body) = api.call(Method::GET, "/readyz", None, Duration::from_secs(10));
    assert_eq!(status, 503, "{body}");
    let message = body["error"]["message"].as_str().unwrap_or_default();
    assert!(message.contains("object store"), "{body}");
    // An upload meanwhile is refused after its retries, naming the store, not its address.
    let upload = dataset(16, 63);
    let (status, body) = api.call(Method::POST, "/v1/datasets", Some(&upload), OUTAGE);
    assert_eq!(status, 503, "{body}");
    let message = body["error"]["message"].as_str().unwrap_or_default();
    assert!(
        message.contains("object store") && !message.contains("127.0.0.1"),
        "{body}"
    );
    std::thread::sleep(OUTAGE / 2);
    let during: Vec<Value> = ids.iter().map(job).collect();
    proxy.set(Mode::Pass);

    let jobs: Vec<Value> = (ids.iter())
        .map(|id| api.wait(id, 600, final_state))
        .collect();
    println!(
        "outage of {} s while jobs ran and queued:",
        OUTAGE.as_secs()
    );
    for (((id, job), before), during) in ids.iter().zip(&jobs).zip(&before).zip(&during) {
        println!(
            "  {id} {}: {} at epoch {} → {} during → {} after {} attempt(s)",
            job["model"],
            before["state"],
            before["epoch"],
            during["state"],
            job["state"],
            job["attempt"]
        );
    }
    for ((id, job), want) in ids.iter().zip(&jobs).zip(&want) {
        assert_eq!(job["state"], "succeeded", "{job}");
        assert_ne!(
            during_state(&during, id),
            "failed",
            "failed during the outage"
        );
        assert_eq!(
            api.metric_epochs(id),
            (1..=EPOCHS).collect::<Vec<_>>(),
            "{id}"
        );
        assert_eq!(&api.model_file(job).params, want, "{id}: {}", job["model"]);
    }
    // Ended jobs keep no checkpoint: the collector takes each once its job ends.
    let t1 = Instant::now();
    while !objects(&rt, &db, "checkpoints").is_empty() {
        assert!(
            t1.elapsed() < Duration::from_secs(120),
            "checkpoints outlived their jobs"
        );
        std::thread::sleep(Duration::from_millis(200));
    }
    for w in workers {
        w.sigterm();
    }
    api.sigterm();
}

fn during_state<'a>(during: &'a [Value], id: &str) -> &'a str {
    (during.iter())
        .find(|j| j["id"] == id)
        .and_then(|j| j["state"].as_str())
        .unwrap_or_default()
}

/// Node A deletes a dataset while the store holds every DELETE without an answer: its
/// collector's delete hangs, outside any transaction, and a job submitted on node B is
/// answered while it still hangs (before, the delete held the database's write lock).
#[test]
fn a_hung_delete_on_one_node_stalls_no_submission_on_another() {
    let Some((_rt, proxy)) = proxied_store() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let db = fresh_db(&dir.path().join("hung"));
    let a = api_node(&proxy, &db, &[]);
    let b = api_node(&proxy, &db, &[]);
    let gone = a.post("/v1/datasets", &dataset(64, 71));
    let kept = b.post("/v1/datasets", &dataset(64, 72));
    proxy.set(Mode::HangDeletes);
    let within = Duration::from_secs(10);
    let path = format!("/v1/datasets/{}", gone["id"].as_str().unwrap());
    let (status, body) = a.call(Method::DELETE, &path, None, within);
    assert!((200..300).contains(&status), "{status} {body}");
    let t0 = Instant::now();
    while proxy.held() == 0 {
        assert!(
            t0.elapsed() < Duration::from_secs(30),
            "node A never deleted the object"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let body = json!({"dataset_id": kept["id"], "model": "W-B", "template": "double_pendulum",
                      "training": {"epochs": 2}});
    let sent = Instant::now();
    let (status, job) = b.call(Method::POST, "/v1/jobs", Some(&body), within);
    let took = sent.elapsed();
    assert_eq!(status, 201, "{job}");
    assert!(
        proxy.held() > 0,
        "the delete was still hanging when B answered"
    );
    println!("a submission on B during A's hung delete took {took:?}");
    proxy.set(Mode::Pass);
    a.sigterm();
    b.sigterm();
}
