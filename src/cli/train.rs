//! `graybox train`: train a model on a dataset file and write the best-validation model file,
//! with progress on stderr.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use clap::Args;

use crate::backend::{self, Backend, Precision};
use crate::data::Dataset;
use crate::error::{Error, Result};
use crate::model::file::write_atomic;
use crate::model::spec::ModelSpec;
use crate::physics::integrator::Integrator;
use crate::sim::parse_pairs;
use crate::train::objective::Objective;
use crate::train::{Ensemble, TrainConfig};

#[derive(Args, Debug)]
pub struct TrainArgs {
    /// Dataset: JSON transitions or trajectories, or CSV (README, "Dataset files").
    #[arg(long)]
    pub data: PathBuf,
    /// Δt in seconds, for data files without one (CSV, or JSON without "dt"); a file's own dt
    /// that disagrees is an error.
    #[arg(long)]
    pub dt: Option<f64>,
    /// One of MVF, MVB, MV, VB, MB, M, V, B, F, W-B, naive (default MVF unless --spec).
    #[arg(long)]
    pub model: Option<String>,
    /// The model's name in its file (and so in the service's lists when it is uploaded)
    /// [default: the model's, or "custom" for --spec].
    #[arg(long)]
    pub name: Option<String>,
    /// A JSON model spec file instead of a named model.
    #[arg(long, conflicts_with = "model")]
    pub spec: Option<PathBuf>,
    /// Template for the white-box parts: double_pendulum, pendulum, cartpole, planar_body, a robot's URDF
    /// file (.urdf), or a template document's JSON file (a formula template or a URDF's).
    #[arg(long)]
    pub template: Option<String>,
    /// Initial physical values, e.g. m1=13,l2=0.8.
    #[arg(long)]
    pub init: Option<String>,
    /// Where to write the trained model file (.gbx).
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
    /// Coordinates that are angles, one 1/0 (or true/false) per coordinate, e.g. 1,1: the
    /// networks see (sin q, cos q) and the loss compares them on the circle [default: the
    /// template's own `periodic`, else none].
    #[arg(long)]
    pub periodic: Option<String>,
    /// Transitions per training window: the loss compares the model's own rollout of this many
    /// steps with the recorded states (README "Multi-step training"); needs trajectory data.
    /// 1 is the one-step loss. --batch-size counts windows.
    #[arg(long, default_value_t = 1)]
    pub horizon: usize,
    /// Weight γ of each further step of a window (step k counts γ^(k−1)), in (0, 1].
    #[arg(long, default_value_t = 1.0)]
    pub discount: f64,
    /// Epochs of one-step training before the windows of --horizon take over (a curriculum;
    /// fewer than --epochs).
    #[arg(long, default_value_t = 0)]
    pub one_step_epochs: usize,
    /// Learning rate of the epochs on windows (--horizon > 1) [default: --lr].
    #[arg(long)]
    pub window_lr: Option<f64>,
    /// Members of an ensemble (1–32), each from its own seed (README "Ensembles and
    /// uncertainty"); the model file holds them all.
    #[arg(long, default_value_t = 1)]
    pub ensemble: usize,
    /// Train every member of an ensemble on all the training data instead of its own
    /// bootstrap resample.
    #[arg(long)]
    pub no_bootstrap: bool,
    /// What the loss compares: step (the predicted states), torque (the torques the
    /// manipulator equation asks for against the recorded inputs, docs/training.md) or both
    /// weighted, e.g. step=1,torque=0.01.
    #[arg(long, default_value = "step")]
    pub loss: String,
    /// Start from the least-squares solution of the torque equation on the training data,
    /// nearest --init (a URDF robot's M; docs/robots.md#least-squares).
    #[arg(long)]
    pub least_squares: bool,
    #[arg(long, value_enum, default_value_t = Backend::Flex)]
    pub backend: Backend,
    #[arg(long, value_enum, default_value_t = Precision::F32)]
    pub precision: Precision,
    /// Threads to train on [default: every core]. Each batch is split into this many shards
    /// (train/shards.rs): a run is reproducible for a given count.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Write the full training report (JSON, with the per-epoch history) here; stdout gets
    /// the report without the history.
    #[arg(long)]
    pub report: Option<PathBuf>,
}

/// `--periodic 1,0` or `true,false`.
fn parse_periodic(text: &str) -> Result<Vec<bool>> {
    text.split(',')
        .map(|v| match v.trim() {
            "1" | "true" => Ok(true),
            "0" | "false" => Ok(false),
            other => Err(Error::invalid(
                "periodic",
                format!("expected 1/0 or true/false per coordinate, got '{other}'"),
            )),
        })
        .collect()
}

pub(super) fn train(a: TrainArgs) -> Result<()> {
    let template = a.template.as_deref().map(super::template_arg).transpose()?;
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
    let name = match &a.name {
        Some(given) => {
            crate::names::check_name(given)?;
            given.clone()
        }
        None => name,
    };
    let init = parse_pairs(a.init.as_deref().unwrap_or(""), "init")?;
    let integrator = Integrator::parse(&a.integrator)?;
    let cfg = TrainConfig {
        epochs: a.epochs,
        batch_size: a.batch_size,
        lr: a.lr,
        lambda: a.lambda,
        val_fraction: a.val_fraction,
        seed: a.seed,
        integrator,
        patience: a.patience,
        periodic: a
            .periodic
            .as_deref()
            .map(parse_periodic)
            .transpose()?
            .unwrap_or_default(),
        horizon: a.horizon,
        discount: a.discount,
        one_step_epochs: a.one_step_epochs,
        window_lr: a.window_lr,
        ensemble: a.ensemble,
        bootstrap: !a.no_bootstrap,
        loss: Objective::parse(&a.loss)?,
        least_squares: a.least_squares,
    };
    let data = load(&a.data, a.dt)?;
    let val = a.val_data.as_deref().map(|p| load(p, a.dt)).transpose()?;
    let device = backend::device(a.backend, a.precision)?.autodiff();
    let threads = a.threads.unwrap_or_else(crate::train::shards::cores);
    let mut trainer = Ensemble::new(&name, spec, &init, &data, val.as_ref(), cfg, &device)?
        .with_threads(threads)?;
    if let Some(w) = trainer.stiffness_warning() {
        eprintln!("warning: {}", w.message);
    }
    let progress = EpochProgress::new(a.epochs as u64, a.horizon);
    let cancel = AtomicBool::new(false);
    while !trainer.finished() {
        progress.epoch(&trainer.run_epoch(&cancel)?.mean);
    }
    progress.finish();
    let file = trainer.model_file();
    file.save(&a.out)?;
    let report = file.report.as_ref().expect("trained files carry a report");
    if let Some(path) = &a.report {
        let full = serde_json::to_string_pretty(report).expect("reports serialize");
        write_atomic(path, full.as_bytes())?;
    }
    for w in &report.warnings {
        eprintln!("warning: {}", w.message);
    }
    let mut summary = serde_json::to_value(report).expect("reports serialize");
    if let Some(obj) = summary.as_object_mut() {
        obj.remove("history");
    }
    super::say(serde_json::to_string_pretty(&summary).expect("reports serialize"))?;
    Ok(())
}

/// A dataset file, with its sanity warnings on stderr.
fn load(path: &std::path::Path, dt: Option<f64>) -> Result<Dataset> {
    let ds = Dataset::load(path, dt)?;
    for w in ds.warnings() {
        eprintln!("warning: {}: {}", path.display(), w.message);
    }
    Ok(ds)
}

/// A progress bar on a terminal; otherwise one line per epoch, at most one a second.
struct EpochProgress {
    bar: Option<indicatif::ProgressBar>,
    last_line: std::cell::Cell<Option<Instant>>,
    total: u64,
    /// The run's horizon, which names the windowed validation loss.
    horizon: usize,
}

impl EpochProgress {
    fn new(total: u64, horizon: usize) -> Self {
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
            horizon,
        }
    }

    fn epoch(&self, m: &crate::model::report::EpochMetrics) {
        let mut msg = format!("train {:.4e}", m.train_loss);
        if let Some(v) = m.val_loss {
            msg += &format!(" val {v:.4e}");
        }
        // The loss that picks the kept epoch of a multi-step run.
        if let Some(v) = m.val_horizon_loss {
            msg += &format!(" val {}-step {v:.4e}", self.horizon);
        }
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

    fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish();
        }
    }
}
