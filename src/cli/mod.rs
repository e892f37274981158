//! The `graybox` command line: simulate datasets, train, evaluate and inspect models, and run
//! benchmarks. Results go to stdout (JSON), progress and logs to stderr.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use clap::{Args, Parser, Subcommand};
use serde_json::json;

mod serve;

pub use serve::ServeArgs;

use crate::backend::{self, Backend, Precision};
use crate::data::Dataset;
use crate::error::{Error, Result};
use crate::model::file::{ModelFile, write_atomic};
use crate::model::integrator::Integrator;
use crate::model::report::{identifiable, used_physical};
use crate::model::spec::ModelSpec;
use crate::model::templates::Template;
use crate::sim::{self, SimConfig, parse_assignments, parse_pairs};
use crate::train::trainer::evaluate;
use crate::train::{TrainConfig, Trainer};

#[derive(Parser, Debug)]
#[command(
    name = "graybox",
    version,
    about = "Structured Lagrangian dynamics models: learn, evaluate, serve"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Sample a transition dataset from a white-box template (the paper's sampling).
    Simulate(SimulateArgs),
    /// Train a model on a dataset and write the best-validation model file.
    Train(TrainArgs),
    /// The training loss of a model file on a dataset.
    Eval(EvalArgs),
    /// Print a model file's spec, dimensions, scalings and physical parameters.
    Inspect(InspectArgs),
    /// Run the service: REST, gRPC and training workers over one SQLite file.
    Serve(ServeArgs),
    /// Benchmarks (figures for the issues' targets).
    #[command(subcommand)]
    Bench(crate::bench::BenchCommand),
}

#[derive(Args, Debug)]
pub struct SimulateArgs {
    /// Template: double_pendulum, pendulum or cartpole.
    #[arg(long)]
    pub system: String,
    #[arg(long, default_value_t = 1024)]
    pub count: usize,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    #[arg(long, default_value_t = 0.01)]
    pub dt: f64,
    #[arg(long)]
    pub out: PathBuf,
    /// Physical parameters, e.g. m1=10,l2=0.8 (others keep their defaults).
    #[arg(long)]
    pub set: Option<String>,
    /// q ~ U(−r, r).
    #[arg(long, default_value_t = std::f64::consts::PI)]
    pub q_range: f64,
    /// q̇ ~ U(−r, r).
    #[arg(long, default_value_t = 10.0)]
    pub qdot_range: f64,
    /// u ~ N(0, σ²).
    #[arg(long, default_value_t = 120.0)]
    pub u_std: f64,
}

#[derive(Args, Debug)]
pub struct TrainArgs {
    /// Dataset (JSON, or CSV with --dt).
    #[arg(long)]
    pub data: PathBuf,
    /// Δt of a CSV dataset.
    #[arg(long)]
    pub dt: Option<f64>,
    /// One of MVF, MVB, MV, VB, MB, M, V, B, F, W-B, naive (default MVF unless --spec).
    #[arg(long)]
    pub model: Option<String>,
    /// A JSON model spec file instead of a named model.
    #[arg(long, conflicts_with = "model")]
    pub spec: Option<PathBuf>,
    /// Template for the white-box parts: double_pendulum, pendulum, cartpole.
    #[arg(long)]
    pub template: Option<String>,
    /// Initial physical values, e.g. m1=13,l2=0.8.
    #[arg(long)]
    pub init: Option<String>,
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value_t = 500)]
    pub epochs: usize,
    #[arg(long, default_value_t = 256)]
    pub batch_size: usize,
    #[arg(long, default_value_t = 1e-3)]
    pub lr: f64,
    #[arg(long, default_value_t = 1.0)]
    pub lambda: f64,
    /// Validation dataset (else --val-fraction of --data is held out).
    #[arg(long)]
    pub val_data: Option<PathBuf>,
    #[arg(long, default_value_t = 0.2)]
    pub val_fraction: f64,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// rk4, euler or midpoint.
    #[arg(long, default_value = "rk4")]
    pub integrator: String,
    /// Early stopping after this many epochs without improvement.
    #[arg(long)]
    pub patience: Option<usize>,
    #[arg(long, value_enum, default_value_t = Backend::Flex)]
    pub backend: Backend,
    #[arg(long, value_enum, default_value_t = Precision::F32)]
    pub precision: Precision,
    /// Write the training report (JSON) here as well as to stdout.
    #[arg(long)]
    pub report: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct EvalArgs {
    #[arg(long)]
    pub model: PathBuf,
    #[arg(long)]
    pub data: PathBuf,
    #[arg(long)]
    pub dt: Option<f64>,
    #[arg(long, value_enum, default_value_t = Backend::Flex)]
    pub backend: Backend,
    #[arg(long, value_enum, default_value_t = Precision::F32)]
    pub precision: Precision,
}

#[derive(Args, Debug)]
pub struct InspectArgs {
    #[arg(long)]
    pub model: PathBuf,
}

pub fn main() -> ExitCode {
    let cli = Cli::parse();
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        // Colour only on a terminal: logs redirected to files stay plain text.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| "warn,graybox=info".into()),
        )
        .init();
    match run(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(match e {
                Error::Invalid { .. }
                | Error::Unprocessable { .. }
                | Error::NotFound(_)
                | Error::Conflict(_)
                | Error::FailedPrecondition(_)
                | Error::ResourceExhausted(_)
                | Error::Corrupt { .. } => 2,
                Error::Training(_)
                | Error::Cancelled
                | Error::Io(_)
                | Error::Storage(_)
                | Error::DeadlineExceeded(_)
                | Error::Internal(_) => 1,
            })
        }
    }
}

pub fn run(command: Command) -> Result<()> {
    match command {
        Command::Simulate(a) => simulate(a),
        Command::Train(a) => train(a),
        Command::Eval(a) => eval(a),
        Command::Inspect(a) => inspect(a),
        Command::Serve(a) => serve::serve(a),
        Command::Bench(b) => crate::bench::run(b),
    }
}

fn simulate(a: SimulateArgs) -> Result<()> {
    let t = Template::parse(&a.system)?;
    let params = parse_assignments(t, a.set.as_deref(), "set")?;
    let cfg = SimConfig {
        count: a.count,
        seed: a.seed,
        dt: a.dt,
        q_range: a.q_range,
        qdot_range: a.qdot_range,
        u_std: a.u_std,
    };
    let ds = sim::simulate(t, params, &cfg)?;
    write_atomic(&a.out, ds.to_json().as_bytes())?;
    println!(
        "{}",
        json!({"out": a.out, "system": t.name(), "count": ds.count(), "n": ds.n, "m": ds.m, "dt": ds.dt})
    );
    Ok(())
}

fn train(a: TrainArgs) -> Result<()> {
    let template = a.template.as_deref().map(Template::parse).transpose()?;
    let (name, spec) = match &a.spec {
        Some(path) => {
            let text = std::fs::read_to_string(path).map_err(|e| {
                Error::invalid("spec", format!("cannot read {}: {e}", path.display()))
            })?;
            ("custom".to_string(), ModelSpec::parse(&text, template)?)
        }
        None => {
            let name = a.model.clone().unwrap_or_else(|| "MVF".into());
            let spec = ModelSpec::named(&name, template)?;
            (name, spec)
        }
    };
    let init = parse_pairs(a.init.as_deref().unwrap_or(""), "init")?;
    let integrator = Integrator::from_name(&a.integrator).ok_or_else(|| {
        Error::invalid(
            "integrator",
            format!(
                "unknown integrator '{}'; expected rk4, euler or midpoint",
                a.integrator
            ),
        )
    })?;
    let cfg = TrainConfig {
        epochs: a.epochs,
        batch_size: a.batch_size,
        lr: a.lr,
        lambda: a.lambda,
        val_fraction: a.val_fraction,
        seed: a.seed,
        integrator,
        patience: a.patience,
    };
    let data = Dataset::load(&a.data, a.dt)?;
    let val = a
        .val_data
        .as_deref()
        .map(|p| Dataset::load(p, a.dt))
        .transpose()?;
    let device = backend::device(a.backend, a.precision)?.autodiff();
    let mut trainer = Trainer::new(&name, spec, &init, &data, val.as_ref(), cfg, &device)?;
    let progress = Progress::new(a.epochs as u64);
    trainer.run(&AtomicBool::new(false), |m, _| progress.epoch(m))?;
    progress.finish();
    let file = trainer.model_file();
    file.save(&a.out)?;
    let report =
        serde_json::to_string_pretty(file.report.as_ref().expect("trained files carry a report"))
            .expect("reports serialize");
    if let Some(path) = &a.report {
        write_atomic(path, report.as_bytes())?;
    }
    println!("{report}");
    Ok(())
}

fn eval(a: EvalArgs) -> Result<()> {
    let file = ModelFile::load(&a.model)?;
    let data = Dataset::load(&a.data, a.dt)?;
    let device = backend::device(a.backend, a.precision)?;
    let model = file.model(&device)?;
    let loss = evaluate(&model, &data)?;
    println!("{}", json!({"loss": loss, "count": data.count()}));
    Ok(())
}

fn inspect(a: InspectArgs) -> Result<()> {
    let file = ModelFile::load(&a.model)?;
    let c = &file.config;
    let mut out = json!({
        "spec": c.spec,
        "n": c.n,
        "m": c.m,
        "dt": c.dt,
        "integrator": c.integrator,
        "lambda": c.lambda,
        "scaling": c.scaling,
        "parameters": file.params.iter().map(|p| p.values.len()).sum::<usize>(),
    });
    if let Some(t) = c.template() {
        let device = backend::device(Backend::Flex, Precision::F32)?;
        let values = file.model(&device)?.physical_values().unwrap_or_default();
        let parts = c.spec.white_box_parts();
        out["template"] = json!(t.name());
        out["physical_parameters"] = json!(used_physical(t, &parts, &values));
        out["identifiable"] = json!(identifiable(t, &parts, &values));
    }
    if let Some(r) = &file.report {
        out["training"] = json!({
            "model": r.model, "epochs": r.epochs, "best_epoch": r.best_epoch,
            "train_loss": r.train_loss, "val_loss": r.val_loss, "best_val_loss": r.best_val_loss,
            "seconds": r.seconds,
        });
    }
    println!("{}", serde_json::to_string_pretty(&out).expect("json"));
    Ok(())
}

/// A progress bar on a terminal; otherwise one line per epoch, at most one a second.
pub struct Progress {
    bar: Option<indicatif::ProgressBar>,
    last_line: std::cell::Cell<Option<Instant>>,
    total: u64,
}

impl Progress {
    pub fn new(total: u64) -> Self {
        let bar = std::io::stderr().is_terminal().then(|| {
            let b = indicatif::ProgressBar::new(total);
            b.set_style(
                indicatif::ProgressStyle::with_template(
                    "{elapsed_precise} [{bar:30}] epoch {pos}/{len} {msg}",
                )
                .expect("valid template")
                .progress_chars("=> "),
            );
            b
        });
        Self {
            bar,
            last_line: std::cell::Cell::new(None),
            total,
        }
    }

    pub fn epoch(&self, m: &crate::model::report::EpochMetrics) {
        let msg = match m.val_loss {
            Some(v) => format!("train {:.4e} val {:.4e}", m.train_loss, v),
            None => format!("train {:.4e}", m.train_loss),
        };
        match &self.bar {
            Some(b) => {
                b.set_position(m.epoch as u64);
                b.set_message(msg);
            }
            None => {
                let due = self
                    .last_line
                    .get()
                    .is_none_or(|t| t.elapsed().as_secs_f64() >= 1.0);
                if due || m.epoch as u64 == self.total {
                    eprintln!("epoch {}/{} {msg} ({:.2}s)", m.epoch, self.total, m.seconds);
                    self.last_line.set(Some(Instant::now()));
                }
            }
        }
    }

    pub fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish();
        }
    }
}
