//! `graybox-lab bench infer`: inference latency for controllers on the double pendulum MVF 3×32
//! and Plan swing-ups. In process (the evaluator alone) and as gRPC round trips on loopback
//! against a real service: idle, then with concurrent clients while a training job runs. With
//! `--model`, any model file's figures, in process, through the C library and over gRPC.

use std::sync::Arc;
use std::time::Instant;

use clap::Args;
use serde_json::{Value, json};

use graybox::control::linalg::Mat;
use graybox::error::{Error, Result};
use graybox::infer::Evaluator;
use graybox::physics::templates::Template;
use graybox::sim::{SimConfig, simulate};

pub mod classes;
mod grpc;
mod model;
mod native;
mod plan;

#[derive(Args, Debug)]
pub struct BenchInferArgs {
    /// Timed calls per sequential figure (after warm-up).
    #[arg(long, default_value_t = 2000)]
    pub calls: usize,
    /// Concurrent gRPC clients calling Predict while a training job runs.
    #[arg(long, default_value_t = 64)]
    pub clients: usize,
    /// How long the concurrent phase lasts.
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    /// The service's database for the gRPC figures: an empty PostgreSQL database's URL, to
    /// compare with the default [a temporary SQLite file] (Predict never reads the database).
    #[arg(long)]
    pub db: Option<String>,
    /// Skip the gRPC figures (in process only).
    #[arg(long)]
    pub in_process_only: bool,
    /// Instead, Predict, Linearize and Plan of this model file (any n, m; e.g. a URDF
    /// robot's from `graybox model --template arm.urdf`), in process.
    #[arg(long)]
    pub model: Option<std::path::PathBuf>,
    /// With --model: also the C library's Predict and Linearize of the same state, through
    /// this build of it (`cargo build --release --workspace` leaves
    /// target/release/libgraybox_c.so), built into examples/c/latency.c with `cc`.
    #[arg(long, requires = "model")]
    pub c_library: Option<std::path::PathBuf>,
    /// With --model: also graybox_native's Predict and Linearize of the same state, and its
    /// throughput from 8 threads, run by this Python (whose environment has the module:
    /// `pip install ./clients/native`).
    #[arg(long, requires = "model")]
    pub python: Option<std::path::PathBuf>,
    /// With --model: rounds of the one-state figures (in process, C, Python), each library's
    /// ratio taken to its own round's Rust figure.
    #[arg(long, default_value_t = 3)]
    pub rounds: usize,
    /// Run the in-process figures inside a rayon pool of this many threads, as the service
    /// runs its calls (a batch splits over the pool's idle threads); 1: the caller's thread
    /// alone, as an embedding program without a pool.
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
}

/// Latency percentiles of a set of samples, in microseconds.
fn summary(name: &str, mut us: Vec<f64>, extra: Value) -> Value {
    us.sort_by(f64::total_cmp);
    let pct = |p: f64| us[((us.len() - 1) as f64 * p).round() as usize];
    let mut v = json!({"bench": name, "calls": us.len(), "p50_us": pct(0.5), "p99_us": pct(0.99),
                       "mean_us": us.iter().sum::<f64>() / us.len() as f64});
    if let (Value::Object(o), Value::Object(e)) = (&mut v, extra) {
        o.extend(e);
    }
    v
}

fn time_calls(calls: usize, mut f: impl FnMut()) -> Vec<f64> {
    for _ in 0..calls.div_ceil(10) {
        f(); // warm-up: caches, allocator
    }
    (0..calls)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e6
        })
        .collect()
}

/// The problem every figure uses: states, inputs and a nominal trajectory of the double
/// pendulum (n = 2, m = 2), and TVLQR weights.
#[derive(Clone)]
struct Problem {
    x1: Vec<f64>,
    u1: Vec<f64>,
    xb: Vec<f64>,
    ub: Vec<f64>,
    u500: Vec<f64>,
    xbar: Vec<f64>,
    ubar: Vec<f64>,
}

const BATCH: usize = 1024;
const ROLLOUT: usize = 500;
const HORIZON: usize = 200;

fn problem(data: &graybox::data::Dataset) -> Problem {
    let (x, _) = data.states();
    let u500: Vec<f64> = (0..ROLLOUT)
        .flat_map(|t| [5.0 * (t as f64 * 0.05).sin(), -3.0])
        .collect();
    Problem {
        x1: x[..4].to_vec(),
        u1: data.u[..2].to_vec(),
        xb: x[..4 * BATCH].to_vec(),
        ub: data.u[..2 * BATCH].to_vec(),
        xbar: x[..4 * (HORIZON + 1)].to_vec(),
        ubar: data.u[..2 * HORIZON].to_vec(),
        u500,
    }
}

fn weights() -> (Mat, Mat, Mat) {
    let eye = |d: usize, s: f64| {
        let mut m = Mat::zeros(d, d);
        for i in 0..d {
            m.data[i * d + i] = s;
        }
        m
    };
    (eye(4, 10.0), eye(2, 0.1), eye(4, 100.0))
}

pub fn run(a: BenchInferArgs) -> Result<()> {
    let pool = match a.threads {
        0 => return Err(Error::invalid("--threads", "must be at least 1")),
        1 => None,
        k => Some(
            rayon::ThreadPoolBuilder::new()
                .num_threads(k)
                .build()
                .map_err(|e| Error::invalid("--threads", format!("could not start {k}: {e}")))?,
        ),
    };
    let in_pool = |f: &(dyn Fn() -> Result<()> + Sync)| match &pool {
        Some(pool) => pool.install(f),
        None => f(),
    };
    if let Some(path) = &a.model {
        return in_pool(&|| model::figures(&a, path));
    }
    let t = Template::DoublePendulum;
    let data = simulate(
        &t,
        t.defaults(),
        &SimConfig {
            count: 2048,
            seed: 0,
            ..SimConfig::default()
        },
    )?;
    let p = problem(&data);
    let eval = Arc::new(trained_mvf(&data)?);
    in_pool(&|| {
        in_process(&eval, &p, a.calls);
        plan::in_process()
    })?;
    if !a.in_process_only {
        let rt = tokio::runtime::Builder::new_multi_thread()
            .enable_all()
            .build()?;
        rt.block_on(grpc::over_grpc(&a, &data, &p))?;
    }
    Ok(())
}

/// An MVF model after one epoch (the weights' values do not change the work done).
fn trained_mvf(data: &graybox::data::Dataset) -> Result<Evaluator> {
    use graybox::backend::{self, Backend, Precision};
    use graybox::model::spec::ModelSpec;
    use graybox::train::{TrainConfig, Trainer};
    let device = backend::device(Backend::Flex, Precision::F32)?.autodiff();
    let spec = ModelSpec::named("MVF", Some(Template::DoublePendulum))?;
    let tc = TrainConfig {
        epochs: 1,
        ..TrainConfig::default()
    };
    let mut trainer = Trainer::new("MVF", spec, &[], data, None, tc, &device)?;
    trainer.run_epoch(&std::sync::atomic::AtomicBool::new(false))?;
    Evaluator::from_file(&trainer.model_file())
}

fn in_process(eval: &Evaluator, p: &Problem, calls: usize) {
    let (q, r, qf) = weights();
    let few = (calls / 10).max(20);
    let figures = [
        summary(
            "evaluator_predict_1",
            time_calls(calls, || {
                std::hint::black_box(eval.predict(&p.x1, &p.u1, false));
            }),
            json!({"target_us": 200.0}),
        ),
        summary(
            "evaluator_predict_64",
            time_calls(calls, || {
                std::hint::black_box(eval.predict(&p.xb[..64 * 4], &p.ub[..64 * 2], false));
            }),
            json!({}),
        ),
        summary(
            "evaluator_predict_1024",
            time_calls(few, || {
                std::hint::black_box(eval.predict(&p.xb, &p.ub, false));
            }),
            json!({"target_us": 3000.0}),
        ),
        summary(
            "evaluator_rollout_500",
            time_calls(few, || {
                let mut last = 0.0;
                eval.rollout(
                    &p.x1,
                    (ROLLOUT, eval.config.dt),
                    |t, _| p.u500[2 * t..2 * t + 2].to_vec(),
                    |x, _| {
                        last = x[0];
                        true
                    },
                );
                std::hint::black_box(last);
            }),
            json!({"target_us": 10000.0}),
        ),
        summary(
            "evaluator_linearize_1",
            time_calls(calls, || {
                std::hint::black_box(eval.linearize_batch(&p.x1, &p.u1));
            }),
            json!({"target_us": 100.0}),
        ),
        summary(
            "evaluator_tvlqr_200",
            time_calls(few, || {
                std::hint::black_box(eval.tvlqr(&p.xbar, &p.ubar, &q, &r, &qf).unwrap());
            }),
            json!({"target_us": 5000.0}),
        ),
    ];
    for f in figures {
        println!("{f}");
    }
}
