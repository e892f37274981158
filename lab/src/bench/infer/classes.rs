//! `graybox-lab bench short-calls`: a controller's batched Predict while the service plans
//! and trains. Sixteen-state Predicts from one client, as a control loop sends them, timed
//! against a service that trains a job: first with nothing else running, then while two
//! direct-collocation plans hold the long class (`--max-heavy-calls`, 2). With one pool for
//! both, every such Predict waited for a plan to end.

use std::time::{Duration, Instant};

use clap::Args;
use serde_json::json;

use super::grpc::{arr, connect, status, submit, wait_for};
use super::summary;
use graybox::api::grpc::pb;
use graybox::app::WorkerSettings;
use graybox::app::datasets::Upload;
use graybox::error::{Error, Result};
use graybox::physics::templates::Template;
use graybox::records::JobState;
use graybox::sim::{SimConfig, simulate};

#[derive(Args, Debug)]
pub struct BenchShortCallsArgs {
    /// States per Predict.
    #[arg(long, default_value_t = 16)]
    pub states: usize,
    /// How long each phase lasts.
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    /// Plans running at once in the second phase.
    #[arg(long, default_value_t = 2)]
    pub plans: usize,
}

pub fn run(a: BenchShortCallsArgs) -> Result<()> {
    tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?
        .block_on(phases(&a))
}

async fn phases(a: &BenchShortCallsArgs) -> Result<()> {
    let t = Template::DoublePendulum;
    let config = SimConfig {
        count: 2048,
        seed: 0,
        ..SimConfig::default()
    };
    let data = simulate(&t, t.defaults(), &config)?;
    let db = crate::bench::TempDb::new();
    let running = crate::bench::api_node(WorkerSettings {
        db: db.0.to_string_lossy().into_owned(),
        workers: 1,
        ..WorkerSettings::default()
    })
    .await?;
    let app = running.app.clone();
    let body = serde_json::from_str(&data.to_json()).expect("datasets serialize to JSON");
    let upload = Upload::Json {
        value: body,
        dt: None,
    };
    let ds = app.upload_dataset(None, upload).await?.dataset;
    let job = submit(&app, &ds.id, 1).await?;
    let model = wait_for(&app, &job.id, |s| s == JobState::Succeeded).await?;
    let model = model.model_id.expect("a succeeded job has a model");
    let url = format!("http://{}", running.grpc_addr);
    let (x, _) = data.states();
    let b = a.states;
    let predict = pb::PredictRequest {
        model_id: model.clone(),
        x: arr(&[b, 4], &x[..4 * b]),
        u: arr(&[b, 2], &data.u[..2 * b]),
        ..Default::default()
    };
    let training = submit(&app, &ds.id, 1_000_000).await?;
    wait_for(&app, &training.id, |s| s == JobState::Running).await?;

    let quiet = timed(&url, &predict, a.seconds).await?;
    let note = |plans: usize| {
        json!({"states": b, "plans_running": plans, "training_job_running": true,
               "transport": "gRPC round trip on loopback, one client"})
    };
    println!(
        "{}",
        summary("grpc_predict_beside_training", quiet, note(0))
    );

    let long = app.long_calls.clone();
    let mut plans = Vec::new();
    for _ in 0..a.plans {
        let mut c = connect(&url).await?;
        let req = long_plan(&model);
        plans.push(tokio::spawn(async move { c.plan(req).await }));
    }
    while long.busy() < a.plans.min(app.settings.max_heavy_calls) {
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let beside = timed(&url, &predict, a.seconds).await?;
    let held = long.busy();
    let mut extra = note(a.plans);
    extra["long_calls_computing_at_end"] = json!(held);
    println!("{}", summary("grpc_predict_beside_plans", beside, extra));
    for p in plans {
        p.abort();
    }
    app.cancel_job(&training.id).await?;
    running.shutdown().await;
    Ok(())
}

/// A swing-up by collocation that runs far longer than a phase (2000 steps, 1000 restarts):
/// it holds its long-call permit until it is dropped.
fn long_plan(model: &str) -> pb::PlanRequest {
    let eye = |d: usize, s: f64| {
        let data = (0..d * d)
            .map(|i| if i % (d + 1) == 0 { s } else { 0.0 })
            .collect::<Vec<_>>();
        arr(&[d, d], &data)
    };
    pb::PlanRequest {
        model_id: model.into(),
        method: "dircol".into(),
        x0: vec![0.0; 4],
        goal: vec![std::f64::consts::PI, 0.0, 0.0, 0.0],
        horizon: 2000,
        q: eye(4, 1.0),
        r: eye(2, 1e-4),
        qf: eye(4, 1000.0),
        u_min: vec![-120.0; 2],
        u_max: vec![120.0; 2],
        max_iterations: Some(200),
        restarts: 1000,
        ..Default::default()
    }
}

/// Back-to-back Predicts for `seconds` from one client: each one's latency (µs). A call that
/// fails ends the benchmark: a refusal is a finding, not a sample.
async fn timed(url: &str, req: &pb::PredictRequest, seconds: f64) -> Result<Vec<f64>> {
    let mut c = connect(url).await?;
    for _ in 0..20 {
        c.predict(req.clone()).await.map_err(status)?;
    }
    let until = Instant::now() + Duration::from_secs_f64(seconds);
    let mut lat = vec![];
    while Instant::now() < until {
        let t = Instant::now();
        c.predict(req.clone()).await.map_err(status)?;
        lat.push(t.elapsed().as_secs_f64() * 1e6);
    }
    if lat.is_empty() {
        return Err(Error::invalid("seconds", "no call finished in the phase"));
    }
    Ok(lat)
}
