//! The gRPC half of `graybox-lab bench infer`: round trips on loopback against a real service,
//! one client at a time, then many while a training job runs.

use std::time::{Duration, Instant};

use serde_json::{Value, json};

use super::{BATCH, BenchInferArgs, HORIZON, Problem, ROLLOUT, summary, weights};
use graybox::api::grpc::pb::{self, dynamics_client::DynamicsClient};
use graybox::app::datasets::Upload;
use graybox::app::jobs::JobRequest;
use graybox::app::{App, WorkerSettings};
use graybox::error::{Error, Result};
use graybox::records::{Job, JobState};

pub(super) fn arr(shape: &[usize], data: &[f64]) -> Option<pb::Array> {
    Some(pb::Array {
        shape: shape.iter().map(|&d| d as u64).collect(),
        data: data.to_vec(),
    })
}

/// A closure making one unary call on a clone of the client (tonic clients are cheap handles).
macro_rules! unary {
    ($c:expr, $method:ident, $req:expr) => {
        || {
            let mut c = $c.clone();
            let r = $req.clone();
            async move { c.$method(r).await }
        }
    };
}

pub(super) async fn over_grpc(
    a: &BenchInferArgs,
    data: &graybox::data::Dataset,
    p: &Problem,
) -> Result<()> {
    let db = crate::bench::TempDb::new();
    let running = crate::bench::api_node(WorkerSettings {
        db: (a.db.clone()).unwrap_or_else(|| db.0.to_string_lossy().into_owned()),
        workers: 1,
        ..WorkerSettings::default()
    })
    .await?;
    let app = running.app.clone();
    let body: Value = serde_json::from_str(&data.to_json()).expect("datasets serialize to JSON");
    let ds = app
        .upload_dataset(
            None,
            Upload::Json {
                value: body,
                dt: None,
            },
        )
        .await?
        .dataset;
    let job = submit(&app, &ds.id, 1).await?;
    let model = wait_for(&app, &job.id, |s| s == JobState::Succeeded).await?;
    let model = model.model_id.expect("a succeeded job has a model");
    let url = format!("http://{}", running.grpc_addr);
    // The sequential calls come from their own thread and single-threaded runtime, as from a
    // controller's process: on the server's two worker threads the client's own wake-ups
    // would count as the service's latency.
    let (u, m, p2, calls) = (url.clone(), model.clone(), p.clone(), a.calls);
    tokio::task::spawn_blocking(move || {
        tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()?
            .block_on(sequential(&u, &m, calls, &p2))
    })
    .await
    .expect("client thread")?;
    let made = super::plan::true_double_pendulum().to_bytes()?;
    let true_dp = app.upload_model(Some("true-dp".into()), made).await?.item;
    super::plan::over_grpc(&url, &true_dp.id).await?;

    let train_job = submit(&app, &ds.id, 1_000_000).await?;
    wait_for(&app, &train_job.id, |s| s == JobState::Running).await?;
    let (lat, secs) = concurrent(&url, predict_one(&model, p), a).await?;
    let still_training = app.job(&train_job.id).await?.state == JobState::Running;
    let rps = lat.len() as f64 / secs;
    println!(
        "{}",
        summary(
            "grpc_predict_1_concurrent",
            lat,
            json!({"clients": a.clients, "requests_per_second": rps, "seconds": secs,
                   "training_job_running": still_training}),
        )
    );
    app.cancel_job(&train_job.id).await?;
    running.shutdown().await;
    Ok(())
}

/// An MVF job on the dataset for `epochs` epochs.
pub(super) async fn submit(app: &App, dataset: &str, epochs: usize) -> Result<Job> {
    let req: JobRequest = serde_json::from_value(json!({
        "dataset_id": dataset, "model": "MVF", "template": "double_pendulum",
        "training": {"epochs": epochs, "batch_size": 256}
    }))
    .expect("a valid job request");
    Ok(app.submit_job(req, None).await?.item)
}

/// Concurrent clients, each on its own connection, calling Predict for `a.seconds`: every
/// call's latency (µs) and the seconds it took.
async fn concurrent(
    url: &str,
    req: pb::PredictRequest,
    a: &BenchInferArgs,
) -> Result<(Vec<f64>, f64)> {
    let until = Instant::now() + Duration::from_secs_f64(a.seconds);
    let mut tasks = vec![];
    for _ in 0..a.clients {
        let mut c = connect(url).await?;
        let req = req.clone();
        tasks.push(tokio::spawn(async move {
            let mut lat = vec![];
            while Instant::now() < until {
                let t = Instant::now();
                c.predict(req.clone()).await?;
                lat.push(t.elapsed().as_secs_f64() * 1e6);
            }
            Ok::<_, tonic::Status>(lat)
        }));
    }
    let started = Instant::now();
    let mut all = vec![];
    for t in tasks {
        all.extend(t.await.expect("client task").map_err(status)?);
    }
    Ok((all, started.elapsed().as_secs_f64()))
}

pub(super) async fn connect(url: &str) -> Result<DynamicsClient<tonic::transport::Channel>> {
    DynamicsClient::connect(url.to_string())
        .await
        .map_err(|e| Error::invalid("grpc", e.to_string()))
}

/// Predict for one state: the figure a control loop cares about most.
fn predict_one(model: &str, p: &Problem) -> pb::PredictRequest {
    pb::PredictRequest {
        model_id: model.to_string(),
        x: arr(&[1, 4], &p.x1),
        u: arr(&[1, 2], &p.u1),
        ..Default::default()
    }
}

/// The one-client figures: each RPC timed call by call.
/// The sequential benchmark's requests.
struct Requests {
    predict1: pb::PredictRequest,
    predict_b: pb::PredictRequest,
    rollout: pb::RolloutRequest,
    linearize: pb::LinearizeRequest,
    tvlqr: pb::TvlqrRequest,
}

fn requests(model: &str, p: &Problem) -> Requests {
    let (q, r, qf) = weights();
    Requests {
        predict1: predict_one(model, p),
        predict_b: pb::PredictRequest {
            model_id: model.to_string(),
            x: arr(&[BATCH, 4], &p.xb),
            u: arr(&[BATCH, 2], &p.ub),
            ..Default::default()
        },
        rollout: pb::RolloutRequest {
            model_id: model.to_string(),
            x0: p.x1.clone(),
            inputs: Some(pb::rollout_request::Inputs::U(pb::Array {
                shape: vec![ROLLOUT as u64, 2],
                data: p.u500.clone(),
            })),
            chunk: ROLLOUT as u64 + 1,
            particles: None,
            ..Default::default()
        },
        linearize: pb::LinearizeRequest {
            model_id: model.to_string(),
            x: arr(&[1, 4], &p.x1),
            u: arr(&[1, 2], &p.u1),
            ..Default::default()
        },
        tvlqr: pb::TvlqrRequest {
            model_id: model.to_string(),
            x_bar: arr(&[HORIZON + 1, 4], &p.xbar),
            u_bar: arr(&[HORIZON, 2], &p.ubar),
            q: arr(&[4, 4], &q.data),
            r: arr(&[2, 2], &r.data),
            qf: arr(&[4, 4], &qf.data),
            ..Default::default()
        },
    }
}

async fn sequential(url: &str, model: &str, calls: usize, p: &Problem) -> Result<()> {
    let c = connect(url).await?;
    let Requests {
        predict1,
        predict_b,
        rollout,
        linearize,
        tvlqr: tv,
    } = requests(model, p);
    let few = (calls / 10).max(20);
    let note = json!({"transport": "gRPC round trip on loopback, one client"});
    let fig = |name: &str, v: Vec<f64>, target: f64| {
        let mut extra = note.clone();
        extra["target_us"] = json!(target);
        println!("{}", summary(name, v, extra));
    };
    fig(
        "grpc_predict_1",
        time_async(calls, unary!(c, predict, predict1)).await?,
        200.0,
    );
    fig(
        "grpc_predict_1024",
        time_async(few, unary!(c, predict, predict_b)).await?,
        3000.0,
    );
    fig(
        "grpc_rollout_500",
        time_async(few, || {
            let mut c = c.clone();
            let req = rollout.clone();
            async move {
                let mut s = c.rollout(req).await?.into_inner();
                while s.message().await?.is_some() {}
                Ok::<_, tonic::Status>(())
            }
        })
        .await?,
        10000.0,
    );
    fig(
        "grpc_linearize_1",
        time_async(calls, unary!(c, linearize, linearize)).await?,
        100.0,
    );
    fig(
        "grpc_tvlqr_200",
        time_async(few, unary!(c, tvlqr, tv)).await?,
        5000.0,
    );

    Ok(())
}

pub(super) fn status(s: tonic::Status) -> Error {
    Error::Training(format!("benchmark call failed: {s}"))
}

async fn time_async<F, Fut, T>(calls: usize, mut f: F) -> Result<Vec<f64>>
where
    F: FnMut() -> Fut,
    Fut: std::future::Future<Output = std::result::Result<T, tonic::Status>>,
{
    for _ in 0..calls.div_ceil(10) {
        f().await.map_err(status)?;
    }
    let mut out = Vec::with_capacity(calls);
    for _ in 0..calls {
        let t = Instant::now();
        f().await.map_err(status)?;
        out.push(t.elapsed().as_secs_f64() * 1e6);
    }
    Ok(out)
}

pub(super) async fn wait_for(
    app: &graybox::app::App,
    job: &str,
    ok: impl Fn(JobState) -> bool,
) -> Result<Job> {
    loop {
        let j = app.job(job).await?;
        if ok(j.state) {
            return Ok(j);
        }
        if matches!(j.state, JobState::Failed | JobState::Cancelled) {
            return Err(Error::Training(format!(
                "benchmark job ended {:?}: {:?}",
                j.state, j.error
            )));
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// `bench infer --model F`: Predict and Linearize of one state of that model as gRPC round
/// trips on loopback, from a client thread of its own, against a service that stores the file.
pub(super) fn model_round_trips(
    path: &std::path::Path,
    x: &[f64],
    u: &[f64],
    calls: usize,
) -> Result<Vec<Value>> {
    let bytes = std::fs::read(path)?;
    let (x, u) = (x.to_vec(), u.to_vec());
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    rt.block_on(async move {
        let db = crate::bench::TempDb::new();
        let running = crate::bench::api_node(WorkerSettings {
            db: db.0.to_string_lossy().into_owned(),
            workers: 0,
            ..WorkerSettings::default()
        })
        .await?;
        let model = running
            .app
            .upload_model(Some("bench".into()), bytes)
            .await?
            .item
            .id;
        let url = format!("http://{}", running.grpc_addr);
        let (nx, m) = (x.len(), u.len());
        let predict = pb::PredictRequest {
            model_id: model.clone(),
            x: arr(&[1, nx], &x),
            u: arr(&[1, m], &u),
            ..Default::default()
        };
        let linearize = pb::LinearizeRequest {
            model_id: model,
            x: arr(&[1, nx], &x),
            u: arr(&[1, m], &u),
            ..Default::default()
        };
        let figures = tokio::task::spawn_blocking(move || {
            tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()?
                .block_on(async {
                    let c = connect(&url).await?;
                    let note = json!({"transport": "gRPC round trip on loopback, one client"});
                    let p = time_async(calls, unary!(c, predict, predict)).await?;
                    let l = time_async(calls, unary!(c, linearize, linearize)).await?;
                    Ok::<_, Error>(vec![
                        summary("grpc_model_predict_1", p, note.clone()),
                        summary("grpc_model_linearize_1", l, note),
                    ])
                })
        })
        .await
        .expect("client thread")?;
        running.shutdown().await;
        Ok(figures)
    })
}
