//! Scale-out with the real binaries: one `graybox serve --workers 0` (the API node) and two
//! `graybox worker` processes on one database (PostgreSQL under `GRAYBOX_TEST_POSTGRES`),
//! started at once on an empty database; one worker is killed with `kill -9` mid-job.

use std::collections::HashMap;

use serde_json::{Value, json};

use crate::helpers::{dataset, final_state};
use crate::processes::{Proc, Server, fresh_db};

const EPOCHS: i64 = 16;
const JOBS: usize = 6;

/// The job every run here trains: the same request on the same data, so every run ends with
/// the same parameters, however it was interrupted.
fn submit(s: &Server) -> String {
    let d = s.post("/v1/datasets", &dataset(2048, 41));
    let v = s.post("/v1/datasets", &dataset(64, 42));
    let body = json!({"dataset_id": d["id"], "validation_dataset_id": v["id"], "model": "MVF",
                      "training": {"epochs": EPOCHS, "batch_size": 64, "lr": 0.003}});
    s.post("/v1/jobs", &body)["id"]
        .as_str()
        .unwrap()
        .to_string()
}

#[test]
fn workers_train_each_job_once_and_a_killed_workers_job_resumes_exactly() {
    let dir = tempfile::tempdir().unwrap();
    // The reference: one uninterrupted run on SQLite.
    let reference = dir.path().join("reference.db");
    let reference = Server::start(reference.to_str().unwrap(), 1);
    let rid = submit(&reference);
    let rjob = reference.wait(&rid, 300, final_state);
    assert_eq!(rjob["state"], "succeeded", "{rjob}");
    let want = reference.model_file(&rjob);
    reference.sigterm();

    // Three processes at once on an empty database: one migrates, the others wait for it.
    let db = fresh_db(&dir.path().join("cluster"));
    let api = Server::spawn(&db, 0);
    let workers = [Proc::worker(&db), Proc::worker(&db)];
    let api = Server::ready(api);
    let mut workers = workers.map(Proc::ready_worker);
    assert_eq!(applied_migrations(&db), migration_files(&db));

    let ids: Vec<String> = (0..JOBS).map(|_| submit(&api)).collect();
    // A job past its first checkpoint and well before its end; then its worker dies.
    let victim = ids[0].clone();
    let before = api.wait(&victim, 120, |j| j["checkpoint_epoch"].as_i64() >= Some(2));
    assert!(
        before["epoch"].as_i64() < Some(EPOCHS / 2),
        "too late to test a resume: {before}"
    );
    let claim = format!("job={victim}");
    let holder = (0..2)
        .find(|&i| {
            workers[i]
                .logs()
                .iter()
                .any(|l| claimed(l) && l.contains(&claim))
        })
        .expect("a worker logged its claim");
    let [first, second] = workers;
    let (killed, mut survivor) = if holder == 0 {
        (first, second)
    } else {
        (second, first)
    };
    let mut logs = killed.kill();

    let done: Vec<Value> = (ids.iter())
        .map(|id| api.wait(id, 600, final_state))
        .collect();
    logs.extend_from_slice(survivor.logs());
    let mut claims: HashMap<&str, usize> = HashMap::new();
    for line in logs.iter().filter(|l| claimed(l)) {
        let id = ids.iter().find(|id| line.contains(&format!("job={id}")));
        *claims
            .entry(id.expect("claims only these jobs"))
            .or_default() += 1;
    }
    for (id, job) in ids.iter().zip(&done) {
        assert_eq!(job["state"], "succeeded", "{job}");
        let (attempts, times) = if *id == victim { (2, 2) } else { (1, 1) };
        assert_eq!(job["attempt"], attempts, "{job}");
        assert_eq!(claims[id.as_str()], times, "{id}: {claims:?}");
        assert_eq!(api.metric_epochs(id), (1..=EPOCHS).collect::<Vec<_>>());
        let got = api.model_file(job);
        assert_eq!(
            got.params, want.params,
            "{id}: the parameters of the reference"
        );
    }
    let resumed = format!("job={victim} epoch=");
    assert!(
        logs.iter().any(|l| l.contains("resuming from checkpoint")
            && l.contains(&resumed)
            && !l.contains(&format!("{resumed}0"))),
        "the survivor resumed the victim from its checkpoint: {logs:#?}"
    );
    survivor.sigterm();
    api.sigterm();
}

fn claimed(line: &str) -> bool {
    line.contains("claimed a job")
}

/// The migrations the database records as applied.
fn applied_migrations(db: &str) -> usize {
    use sqlx::Connection;
    let count = async {
        let sql = "SELECT COUNT(*) FROM _sqlx_migrations WHERE success";
        let n: i64 = if graybox::store::is_postgres(db) {
            let mut c = sqlx::PgConnection::connect(db).await.unwrap();
            sqlx::query_scalar(sql).fetch_one(&mut c).await.unwrap()
        } else {
            let mut c = sqlx::SqliteConnection::connect(&format!("sqlite://{db}"))
                .await
                .unwrap();
            sqlx::query_scalar(sql).fetch_one(&mut c).await.unwrap()
        };
        n as usize
    };
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(count)
}

/// The migration files of `db`'s backend.
fn migration_files(db: &str) -> usize {
    let backend = if graybox::store::is_postgres(db) {
        "postgres"
    } else {
        "sqlite"
    };
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("migrations")
        .join(backend);
    (std::fs::read_dir(dir).unwrap())
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .path()
                .extension()
                .is_some_and(|x| x == "sql")
        })
        .count()
}

/// A worker's health signal: its probes on `--health` (no API there), `graybox health` against
/// it, exit 0 after SIGTERM; exit 1 when its database cannot be reached, 2 for a bad flag.
#[test]
fn a_worker_answers_its_probes_and_exits_by_its_status() {
    let dir = tempfile::tempdir().unwrap();
    let db = fresh_db(dir.path());
    let mut worker = Proc::spawn("worker", &db, &["--health", "127.0.0.1:0"]);
    let line = worker.wait_for("graybox worker: ");
    let addr = line.rsplit("http://").next().unwrap().to_string();
    let get = |path: &str| {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        rt.block_on(async {
            let r = reqwest::get(format!("http://{addr}{path}")).await.unwrap();
            (r.status().as_u16(), r.text().await.unwrap())
        })
    };
    assert_eq!(get("/healthz").0, 200);
    assert_eq!(get("/readyz"), (200, r#"{"status":"ready"}"#.to_string()));
    assert!(
        get("/metrics")
            .1
            .contains("graybox_jobs{state=\"queued\"} 0")
    );
    assert_eq!(get("/v1/jobs").0, 404, "a worker serves no API");
    let health = graybox(&["health", "--http", &addr]);
    assert!(health.status.success(), "{health:?}");
    worker.sigterm();

    // Nothing listens on port 1: refused at once, and said so.
    let out = graybox(&[
        "worker",
        "--db",
        "postgres://graybox:secret@127.0.0.1:1/graybox",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    assert!(
        stderr.contains("cannot connect to postgres://graybox:"),
        "{stderr}"
    );
    assert!(
        !stderr.contains("secret"),
        "the password stays out: {stderr}"
    );
    let bad = [
        ("workers", ["--db", &db, "--workers", "0"]),
        ("db", ["--db", "/no/such/dir/graybox.db", "--workers", "1"]),
    ];
    for (flag, args) in bad {
        let out = graybox(&[&["worker"][..], &args].concat());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{out:?}");
        assert!(stderr.contains(&format!("error: {flag}: ")), "{stderr}");
    }
}

fn graybox(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_graybox"))
        .args(args)
        .output()
        .unwrap()
}
