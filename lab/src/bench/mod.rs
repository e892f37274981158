//! `graybox-lab bench …`: the figures the issues ask for, printed as JSON lines on stdout.

mod ensemble;
mod events;
mod flops;
mod horizon;
mod infer;
mod multibody;
mod pinocchio;
mod process;
mod queue;
mod reads;
mod scale;
mod uploads;

use std::sync::atomic::AtomicBool;
use std::time::Instant;

use clap::{Args, Subcommand};
use serde_json::json;

use burn::tensor::Device;

use graybox::backend::{self, Backend, Precision};
use graybox::data::Dataset;
use graybox::error::Result;
use graybox::model::spec::ModelSpec;
use graybox::physics::templates::Template;
use graybox::sim::{SimConfig, simulate};
use graybox::train::{TrainConfig, Trainer};

#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Training throughput (samples/s) for MVF and naive at batch 256 and 4096, and the wall
    /// time for MVF to reach the paper's validation loss, on the paper's double pendulum.
    Train(BenchTrainArgs),
    /// Where one training step's time goes: forward, backward, optimizer (milliseconds).
    Step(BenchStepArgs),
    /// Inference latency for controllers (double pendulum MVF 3×32): in process and as gRPC
    /// round trips on loopback, idle and with 64 concurrent clients while a job trains.
    Infer(infer::BenchInferArgs),
    /// A controller's 16-state Predict (p50, p99) while a job trains, alone and beside two
    /// long plans holding the long-call class.
    ShortCalls(infer::classes::BenchShortCallsArgs),
    /// µs per call of a URDF robot's dynamics: the assembled path vs the multibody algorithms
    /// (`rigid` is its former name).
    #[command(alias = "rigid")]
    Multibody(multibody::BenchMultibodyArgs),
    /// The database load of one API node's event streams (polls and statements per second)
    /// with many subscribers, on SQLite or PostgreSQL.
    Events(events::BenchEventsArgs),
    /// How long a submitted job waits for an idle worker (queued → running), p50 and p99.
    Queue(queue::BenchQueueArgs),
    /// The wall time of a batch of jobs on one worker and on two, one thread each.
    Scale(scale::BenchScaleArgs),
    /// An ensemble's training wall time against one member's, its threads running whole
    /// members or each member's shards.
    Ensemble(ensemble::BenchEnsembleArgs),
    /// Multi-step training's cost: samples/s and seconds per epoch at each horizon.
    Horizon(horizon::BenchHorizonArgs),
    /// The memory of a `graybox serve` process answering many concurrent replays of one
    /// large dataset: resident set at idle and at its peak.
    Reads(reads::BenchReadsArgs),
    /// The memory one dataset upload takes per body byte, for each JSON form, its bytes in
    /// the database's rows and in an object store, beside what the admission reserves.
    Uploads(uploads::BenchUploadsArgs),
}

#[derive(Args, Debug)]
pub struct BenchStepArgs {
    #[arg(long, default_value = "MVF")]
    pub model: String,
    #[arg(long, default_value_t = 256)]
    pub batch_size: usize,
    #[arg(long, default_value_t = 50)]
    pub steps: usize,
    #[arg(long, value_enum, default_value_t = Backend::Flex)]
    pub backend: Backend,
}

#[derive(Args, Debug)]
pub struct BenchTrainArgs {
    #[arg(long, default_value_t = 4096)]
    pub train: usize,
    #[arg(long, default_value_t = 1024)]
    pub val: usize,
    /// Timed epochs per throughput figure (after one warm-up epoch), at least enough for
    /// `--min-steps` training steps: at batch 4096 an epoch is one step, and three steps are
    /// too few to average out page faults and the scheduler.
    #[arg(long, default_value_t = 3)]
    pub epochs: usize,
    /// The fewest timed training steps per figure (see --epochs).
    #[arg(long, default_value_t = 30)]
    pub min_steps: usize,
    /// Models to measure, comma-separated.
    #[arg(long, default_value = "MVF,naive")]
    pub models: String,
    /// The system the data comes from and the white-box parts use: a built-in template's
    /// name or a formula template's JSON file (e.g. examples/templates/double_pendulum.json,
    /// to compare a formula's throughput with the built-in's).
    #[arg(long, default_value = "double_pendulum")]
    pub template: String,
    #[arg(long, default_value = "256,4096")]
    pub batch_sizes: String,
    /// log10 of the validation loss MVF must reach.
    #[arg(long, default_value_t = -2.5)]
    pub target_log10: f64,
    /// Give up on the time-to-target run after this many seconds (0 skips it).
    #[arg(long, default_value_t = 300.0)]
    pub time_limit: f64,
    /// Training settings of the time-to-target run.
    #[arg(long, default_value_t = 256)]
    pub target_batch_size: usize,
    #[arg(long, default_value_t = 1e-3)]
    pub target_lr: f64,
    #[arg(long, value_enum, default_value_t = Backend::Flex)]
    pub backend: Backend,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Threads per training (default: every core).
    #[arg(long, default_value_t = graybox::train::shards::cores())]
    pub threads: usize,
}

/// A temporary SQLite database file, removed (with its WAL files) on drop.
pub(crate) struct TempDb(pub std::path::PathBuf);

impl TempDb {
    pub fn new() -> Self {
        let name = format!("graybox-bench-{}.db", graybox::store::new_id("b"));
        Self(std::env::temp_dir().join(name))
    }
}

impl Drop for TempDb {
    fn drop(&mut self) {
        for ext in ["", "-wal", "-shm", ".lock"] {
            let mut p = self.0.clone().into_os_string();
            p.push(ext);
            let _ = std::fs::remove_file(p);
        }
    }
}

/// An API node (no workers of its own unless `worker` says) on `worker.db`, on free ports.
pub(crate) async fn api_node(
    worker: graybox::app::WorkerSettings,
) -> Result<graybox::service::Running> {
    graybox::service::start(graybox::app::Settings {
        http: "127.0.0.1:0".into(),
        grpc: "127.0.0.1:0".into(),
        worker,
        ..graybox::app::Settings::default()
    })
    .await
}

/// Uploads `count` transitions of the double pendulum (seed 0); the dataset's id.
pub(crate) async fn upload_double_pendulum(
    app: &graybox::app::App,
    count: usize,
) -> Result<String> {
    let t = Template::DoublePendulum;
    let cfg = SimConfig {
        count,
        ..SimConfig::default()
    };
    let data = simulate(&t, t.defaults(), &cfg)?;
    let value = serde_json::from_str(&data.to_json()).expect("datasets serialize to JSON");
    let upload = graybox::app::datasets::Upload::Json { value, dt: None };
    Ok(app.upload_dataset(None, upload).await?.dataset.id)
}

pub fn run(cmd: BenchCommand) -> Result<()> {
    match cmd {
        BenchCommand::Train(a) => bench_train(a),
        BenchCommand::Step(a) => bench_step(a),
        BenchCommand::Infer(a) => infer::run(a),
        BenchCommand::ShortCalls(a) => infer::classes::run(a),
        BenchCommand::Multibody(a) => multibody::run(a),
        BenchCommand::Events(a) => events::run(a),
        BenchCommand::Queue(a) => queue::run(a),
        BenchCommand::Scale(a) => scale::run(a),
        BenchCommand::Horizon(a) => horizon::run(a),
        BenchCommand::Ensemble(a) => ensemble::run(a),
        BenchCommand::Reads(a) => reads::run(a),
        BenchCommand::Uploads(a) => uploads::run(a),
    }
}

fn bench_train(a: BenchTrainArgs) -> Result<()> {
    let t = graybox::cli::template_arg(&a.template)?;
    let cfg = |count, seed| SimConfig {
        count,
        seed,
        ..SimConfig::default()
    };
    let train = simulate(&t, t.defaults(), &cfg(a.train, a.seed))?;
    let val = simulate(&t, t.defaults(), &cfg(a.val, a.seed + 1))?;
    let device = backend::device(a.backend, Precision::F32)?.autodiff();
    for model in a.models.split(',').map(str::trim) {
        for bs in a
            .batch_sizes
            .split(',')
            .filter_map(|s| s.trim().parse::<usize>().ok())
        {
            throughput(&a, model, &t, bs, (&train, &val), &device)?;
        }
    }
    if a.time_limit > 0.0 {
        time_to_target(&a, &t, (&train, &val), &device)?;
    }
    Ok(())
}

/// Training samples per second of `model` at batch size `bs`, after a warm-up epoch.
fn throughput(
    a: &BenchTrainArgs,
    model: &str,
    t: &Template,
    bs: usize,
    (train, val): (&Dataset, &Dataset),
    device: &Device,
) -> Result<()> {
    let spec = ModelSpec::named(model, Some(t.clone()))?;
    let epochs = a.epochs.max(a.min_steps.div_ceil(a.train.div_ceil(bs)));
    let tc = TrainConfig {
        epochs: epochs + 1,
        batch_size: bs,
        seed: a.seed,
        ..TrainConfig::default()
    };
    let never = AtomicBool::new(false);
    let mut trainer =
        Trainer::new(model, spec, &[], train, Some(val), tc, device)?.with_threads(a.threads)?;
    trainer.run_epoch(&never)?; // warm-up: allocations, first-touch
    let (wall, cpu, steps) = (Instant::now(), cpu_seconds(), trainer.train_seconds());
    for _ in 0..epochs {
        trainer.run_epoch(&never)?;
    }
    let (wall, cpu) = (wall.elapsed().as_secs_f64(), cpu_seconds() - cpu);
    let steps = trainer.train_seconds() - steps;
    let samples = (epochs * a.train) as f64;
    println!(
        "{}",
        json!({"bench": "train_throughput", "model": model, "template": t.name(),
               "batch_size": bs, "backend": a.backend, "epochs": epochs,
               "samples_per_second": samples / steps,
               "samples_per_second_with_validation": samples / wall,
               "cpu_per_wall": cpu / wall,
               "threads": a.threads,
               "shards": trainer.shards_of(bs),
               "cores": graybox::train::shards::cores(),
               "note": "samples_per_second: training steps only (forward, backward, Adam), as \
                        the PyTorch reference is measured; cpu_per_wall: process CPU time over \
                        wall time across the timed epochs (1.0 = one core busy)"})
    );
    Ok(())
}

/// This process's user + system CPU time, in seconds.
fn cpu_seconds() -> f64 {
    // SAFETY: getrusage writes into the zeroed struct it is given and reads nothing else.
    let usage = unsafe {
        let mut u: libc::rusage = std::mem::zeroed();
        libc::getrusage(libc::RUSAGE_SELF, &mut u);
        u
    };
    let secs = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    secs(usage.ru_utime) + secs(usage.ru_stime)
}

/// Wall time for MVF to reach the target validation loss, within `a.time_limit` seconds.
fn time_to_target(
    a: &BenchTrainArgs,
    t: &Template,
    (train, val): (&Dataset, &Dataset),
    device: &Device,
) -> Result<()> {
    let spec = ModelSpec::named("MVF", Some(t.clone()))?;
    let tc = TrainConfig {
        epochs: 1_000_000,
        batch_size: a.target_batch_size,
        lr: a.target_lr,
        seed: a.seed,
        ..TrainConfig::default()
    };
    let target = 10f64.powf(a.target_log10);
    let never = AtomicBool::new(false);
    let mut trainer =
        Trainer::new("MVF", spec, &[], train, Some(val), tc, device)?.with_threads(a.threads)?;
    let start = Instant::now();
    let mut reached = None;
    let mut best = f64::INFINITY;
    while start.elapsed().as_secs_f64() < a.time_limit {
        let m = trainer.run_epoch(&never)?;
        let v = m.val_loss.unwrap_or(f64::INFINITY);
        best = best.min(v);
        if v <= target {
            reached = Some((m.epoch, start.elapsed().as_secs_f64()));
            break;
        }
    }
    println!(
        "{}",
        json!({"bench": "time_to_target", "model": "MVF", "target_val_loss": target,
               "batch_size": a.target_batch_size, "lr": a.target_lr,
               "reached": reached.is_some(), "seconds": reached.map(|r| r.1),
               "epochs": reached.map_or(trainer.epoch(), |r| r.0), "best_val_loss": best,
               "time_limit": a.time_limit})
    );
    Ok(())
}

fn bench_step(a: BenchStepArgs) -> Result<()> {
    use burn::tensor::{Tensor, TensorData};
    use graybox::train::adam::Adam;
    let t = Template::DoublePendulum;
    let data = simulate(
        &t,
        t.defaults(),
        &SimConfig {
            count: a.batch_size,
            ..SimConfig::default()
        },
    )?;
    let device = backend::device(a.backend, Precision::F32)?.autodiff();
    let spec = ModelSpec::named(&a.model, Some(t))?;
    let trainer = Trainer::new(
        &a.model,
        spec,
        &[],
        &data,
        None,
        TrainConfig {
            val_fraction: 0.0,
            ..TrainConfig::default()
        },
        &device,
    )?;
    let mut model = trainer.model().clone();
    let (x, y) = data.states();
    let b = a.batch_size;
    let tensor =
        |v: Vec<f64>, w: usize| Tensor::<2>::from_data(TensorData::new(v, [b, w]), &device);
    let (xt, ut, yt) = (tensor(x, 4), tensor(data.u.clone(), 2), tensor(y, 4));
    let mut adam = Adam::default();
    let (mut fwd, mut bwd, mut opt) = (0.0, 0.0, 0.0);
    for i in 0..a.steps + 5 {
        let t0 = Instant::now();
        let loss = model
            .loss_sum(xt.clone(), ut.clone(), yt.clone())
            .div_scalar(b as f64);
        let _ = loss.clone().into_data();
        let t1 = Instant::now();
        let grads = loss.backward();
        let t2 = Instant::now();
        let grads = graybox::train::shards::param_grads(&model.params, &grads);
        model.params = adam.step(model.params.clone(), &grads, 1e-3);
        let _ = model.params.export();
        let t3 = Instant::now();
        if i >= 5 {
            fwd += (t1 - t0).as_secs_f64();
            bwd += (t2 - t1).as_secs_f64();
            opt += (t3 - t2).as_secs_f64();
        }
    }
    let k = 1e3 / a.steps as f64;
    let rate = (a.steps * b) as f64 / (fwd + bwd + opt);
    let (flops, peak) = (flops::per_sample(&model), flops::sgemm_per_core());
    println!(
        "{}",
        json!({"bench": "train_step", "model": a.model, "batch_size": b, "forward_ms": fwd * k,
               "backward_ms": bwd * k, "optimizer_ms": opt * k, "samples_per_second": rate,
               "network_mflop_per_sample": flops / 1e6, "network_gflops": rate * flops / 1e9,
               "sgemm_gflops_per_core": peak / 1e9, "share_of_sgemm": rate * flops / peak,
               "note": "network_gflops: the networks' forward and backward FLOPs at this rate (elementwise work left out); share_of_sgemm: of one core's f32 sgemm rate on 256 × 256 matrices"})
    );
    Ok(())
}
