//! Chaos with the real binaries: one API node and three `graybox worker` processes on one
//! database (PostgreSQL and the S3 endpoint in `scripts/test.sh`'s second run), a 2 s lease
//! and `--max-attempts 100`; twelve small jobs of four models; a driver kills a random worker
//! with `kill -9` every ~1.5 s and starts a new one. Every job succeeds once, its metrics hold
//! epochs 1..E once each, and each model's parameters equal the same job trained
//! uninterrupted on SQLite. One seeded schedule runs here (`GRAYBOX_CHAOS_SEED`,
//! `GRAYBOX_CHAOS_KILLS` choose another); the test prints it.

use std::time::{Duration, Instant};

use serde_json::Value;

use crate::helpers::final_state;
use crate::processes::{Proc, Server, fresh_db, undisturbed};

const JOBS: usize = 12;
const EPOCHS: i64 = 20;
const MODELS: [&str; 4] = ["MVF", "MV", "naive", "W-B"];

/// The twelve jobs (four models, three seeds), submitted in order; their ids.
fn submit_all(s: &Server) -> Vec<String> {
    s.submit_batch(&MODELS, JOBS, EPOCHS, (1024, 51))
}

/// A small deterministic generator for the kill schedule (xorshift64*).
struct Schedule(u64);

impl Schedule {
    fn below(&mut self, n: usize) -> usize {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 33) as usize % n
    }
}

fn env_or(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

#[test]
fn killed_workers_lose_no_job_and_change_no_result() {
    let dir = tempfile::tempdir().unwrap();
    let reference = dir.path().join("reference.db");
    let want = undisturbed(reference.to_str().unwrap(), submit_all);

    let db = fresh_db(&dir.path().join("chaos"));
    let worker = || Proc::spawn("worker", &db, &["--workers", "1", "--max-attempts", "100"]);
    let api = Server::ready(Server::spawn(&db, 0));
    let mut workers: Vec<Proc> = (0..3).map(|_| worker().ready_worker()).collect();
    let ids = submit_all(&api);

    let seed = env_or("GRAYBOX_CHAOS_SEED", 7);
    let kills = env_or("GRAYBOX_CHAOS_KILLS", 6) as usize;
    let mut schedule = Schedule(seed.max(1));
    let t0 = Instant::now();
    let done = |api: &Server| {
        ids.iter()
            .all(|id| final_state(&api.get(&format!("/v1/jobs/{id}"))))
    };
    let mut killed = Vec::new();
    while killed.len() < kills && !done(&api) {
        std::thread::sleep(Duration::from_millis(
            1000 + 100 * schedule.below(10) as u64,
        ));
        let victim = workers.remove(schedule.below(workers.len()));
        let logs = victim.kill();
        let held: Vec<&String> = (ids.iter())
            .filter(|id| {
                logs.iter()
                    .rev()
                    .find(|l| l.contains(&format!("job={id}")))
                    .is_some_and(|l| l.contains("claimed a job"))
            })
            .collect();
        killed.push(format!(
            "{:.1} s: a worker holding {held:?}",
            t0.elapsed().as_secs_f64()
        ));
        workers.push(worker().ready_worker());
    }
    println!(
        "chaos seed {seed}: {} kill(s)\n{}",
        killed.len(),
        killed.join("\n")
    );

    let jobs: Vec<Value> = (ids.iter())
        .map(|id| api.wait(id, 600, final_state))
        .collect();
    for ((id, job), want) in ids.iter().zip(&jobs).zip(&want) {
        assert_eq!(job["state"], "succeeded", "{job}");
        assert_eq!(
            api.metric_epochs(id),
            (1..=EPOCHS).collect::<Vec<_>>(),
            "{id}"
        );
        assert_eq!(&api.model_file(job).params, want, "{id}: {}", job["model"]);
    }
    let models = api.get("/v1/models?page_size=100");
    let models = models["items"].as_array().unwrap();
    assert_eq!(
        models.len(),
        JOBS,
        "one model per job, no second from a fenced-out worker"
    );
    for w in workers {
        w.sigterm();
    }
    api.sigterm();
}
