//! `graybox-lab bench events`: the database load of one API node's event streams. Every
//! stream polls the store (a job's stream every 200 ms, `/v1/events` likewise), and streams
//! share pollers; this measures what that costs a node with many subscribers, on SQLite or on
//! PostgreSQL, where the statements the node sent are counted by the database itself.

use std::time::{Duration, Instant};

use clap::Args;
use serde_json::json;
use sqlx::Connection;

use graybox::app::jobs::JobRequest;
use graybox::app::{App, WorkerSettings};
use graybox::error::{Error, Result};

#[derive(Args, Debug)]
pub struct BenchEventsArgs {
    /// The node's database: an empty PostgreSQL database's URL (statements per second are
    /// read from its pg_stat_database row), or an SQLite file [default: a temporary one, and
    /// polls per second only].
    #[arg(long)]
    pub db: Option<String>,
    /// Subscribers per phase.
    #[arg(long, default_value_t = 50)]
    pub subscribers: usize,
    /// How long each phase is measured. PostgreSQL reports a busy connection's statements up
    /// to a second late: at 20 s that is 5% of a phase at most.
    #[arg(long, default_value_t = 20.0)]
    pub seconds: f64,
}

/// Who subscribes in a phase.
#[derive(Clone, Copy, Debug)]
enum Phase {
    /// Nobody: the node's own background reads (its model cache sweep).
    Idle,
    /// Every subscriber on `/v1/events`.
    AllJobs,
    /// Every subscriber on one job's stream.
    OneJob,
    /// Each subscriber on its own job's stream.
    OwnJob,
}

pub fn run(a: BenchEventsArgs) -> Result<()> {
    tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?
        .block_on(measure(a))
}

async fn measure(a: BenchEventsArgs) -> Result<()> {
    let temp = super::TempDb::new();
    let db = (a.db.clone()).unwrap_or_else(|| temp.0.display().to_string());
    // An API node: no workers, so the jobs stay queued and their streams keep polling.
    let running = super::api_node(WorkerSettings {
        db: db.clone(),
        workers: 0,
        ..WorkerSettings::default()
    })
    .await?;
    let app = running.app.clone();
    let jobs = queued_jobs(&app, a.subscribers).await?;
    let mut counter = Statements::connect(&db).await?;
    for phase in [Phase::Idle, Phase::AllJobs, Phase::OneJob, Phase::OwnJob] {
        let subscribed = subscribe(&app, phase, &jobs, a.subscribers).await?;
        // Let the pollers start before the window opens; before the first, let PostgreSQL
        // report the set-up's statements (an idle connection's counts arrive 10 s late).
        let first = matches!(phase, Phase::Idle) && graybox::store::is_postgres(&db);
        let settle = if first { 11 } else { 1 };
        tokio::time::sleep(Duration::from_secs(settle)).await;
        let (polls, statements, t0) = (polls(&app), counter.read().await?, Instant::now());
        tokio::time::sleep(Duration::from_secs_f64(a.seconds)).await;
        let secs = t0.elapsed().as_secs_f64();
        let polls = (self::polls(&app) - polls) as f64 / secs;
        let statements = match (statements, counter.read().await?) {
            (Some(before), Some(after)) => Some((after - before) as f64 / secs),
            _ => None,
        };
        println!(
            "{}",
            json!({"bench": "event_stream_load", "phase": format!("{phase:?}"),
                   "subscribers": if matches!(phase, Phase::Idle) { 0 } else { a.subscribers },
                   "backend": if graybox::store::is_postgres(&db) { "postgres" } else { "sqlite" },
                   "polls_per_second": polls, "statements_per_second": statements,
                   "seconds": secs})
        );
        drop(subscribed);
        // The pollers notice at their next read that nobody listens, and stop.
        tokio::time::sleep(Duration::from_millis(500)).await;
    }
    running.shutdown().await;
    Ok(())
}

/// `n` queued jobs on a small dataset.
async fn queued_jobs(app: &App, n: usize) -> Result<Vec<String>> {
    let ds = super::upload_double_pendulum(app, 64).await?;
    let mut ids = Vec::with_capacity(n);
    for _ in 0..n.max(1) {
        let req: JobRequest = serde_json::from_value(json!({
            "dataset_id": ds, "model": "MVF", "template": "double_pendulum"
        }))
        .expect("a valid job request");
        ids.push(app.submit_job(req, None).await?.item.id);
    }
    Ok(ids)
}

/// What keeps a phase's subscriptions alive (dropped: unsubscribed).
#[derive(Default)]
struct Subscribed {
    _all_jobs: Vec<tokio::sync::broadcast::Receiver<graybox::records::Job>>,
    _jobs: Vec<tokio::sync::watch::Receiver<graybox::app::events::JobProgress>>,
}

/// Subscribes as the SSE handlers do (a stream holds one of these receivers).
async fn subscribe(app: &App, phase: Phase, jobs: &[String], n: usize) -> Result<Subscribed> {
    let mut s = Subscribed::default();
    match phase {
        Phase::Idle => {}
        Phase::AllJobs => {
            for _ in 0..n {
                s._all_jobs.push(app.follow_all_jobs().await?);
            }
        }
        Phase::OneJob | Phase::OwnJob => {
            for i in 0..n {
                let job = if matches!(phase, Phase::OneJob) { 0 } else { i };
                s._jobs.push(app.follow_job(&jobs[job]).await?);
            }
        }
    }
    Ok(s)
}

fn polls(app: &App) -> u64 {
    app.telemetry
        .job_polls
        .load(std::sync::atomic::Ordering::Relaxed)
}

/// PostgreSQL's count of the transactions on the database (each of the node's statements is
/// one); nothing on SQLite.
struct Statements(Option<sqlx::PgConnection>);

impl Statements {
    async fn connect(db: &str) -> Result<Self> {
        if !graybox::store::is_postgres(db) {
            return Ok(Self(None));
        }
        let c = sqlx::PgConnection::connect(db).await;
        Ok(Self(Some(c.map_err(|e| Error::Storage(e.to_string()))?)))
    }

    async fn read(&mut self) -> Result<Option<i64>> {
        let Some(c) = self.0.as_mut() else {
            return Ok(None);
        };
        // A fresh snapshot: statistics are otherwise cached for the transaction.
        let sql = "SELECT pg_stat_clear_snapshot()::text, (SELECT xact_commit + xact_rollback \
                   FROM pg_stat_database WHERE datname = current_database())";
        let (_, n): (Option<String>, i64) = sqlx::query_as(sql)
            .fetch_one(c)
            .await
            .map_err(|e| Error::Storage(e.to_string()))?;
        Ok(Some(n))
    }
}
