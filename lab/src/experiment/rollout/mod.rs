//! `graybox-lab experiment rollout`: the paper's §V-C. MVF and naive trained on the same data
//! predict 5-second trajectories open loop from the true system's initial states and inputs.
//! With `--horizon H` the table gains MVF trained on trajectories, with the one-step loss and
//! with windows of H (README "Multi-step training").

mod report;

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use clap::Args;
use serde::{Deserialize, Serialize};

use super::out::OutDir;
use super::paper_double_pendulum;
use super::pool::{self, Progress};
use super::resumable::{self, trajectories};
use graybox::backend::{self, Backend, Precision};
use graybox::error::Result;
use graybox::infer::Evaluator;
use graybox::model::file::ModelFile;
use graybox::model::spec::ModelSpec;
use graybox::physics::integrator::Integrator;
use graybox::physics::templates::Template;
use graybox::rng::Rng;
use graybox::sim::true_step;
use graybox::sim::{Recording, TemplateSystem};
use graybox::train::{TrainConfig, Trainer};

const MODELS: [&str; 2] = ["MVF", "naive"];
/// The trajectory rows' data: as `experiment multistep`'s (training, then validation).
const TRAIN_TRAJECTORIES: usize = 40;
const VAL_TRAJECTORIES: usize = 10;
const TRAJECTORY_STEPS: usize = 200;
const DT: f64 = 0.01;
/// 5 s at Δt = 0.01.
const STEPS: usize = 500;
/// Inputs are held for 0.1 s.
const HOLD: usize = 10;
const U_STD: f64 = 30.0;
const QDOT0: f64 = 2.0;

#[derive(Args, Debug)]
pub struct RolloutArgs {
    /// Directory for results.md, results.csv, rollouts.png, the two models and run.json;
    /// running again with the same settings reuses the trained models.
    #[arg(long)]
    pub out: PathBuf,
    /// True trajectories [default: 100; 4 with --quick].
    #[arg(long)]
    pub count: Option<usize>,
    /// Training samples [default: 4096; 256 with --quick].
    #[arg(long)]
    pub train_size: Option<usize>,
    /// Validation samples [default: 1024; 64 with --quick].
    #[arg(long)]
    pub val_size: Option<usize>,
    /// Training epochs (the best-validation parameters are kept) [default: 3000; 30 with
    /// --quick].
    #[arg(long)]
    pub epochs: Option<usize>,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Adds MVF trained on trajectories of the double pendulum (as `experiment multistep`'s)
    /// with the one-step loss and with windows of this many steps [default: none; 3 with
    /// --quick].
    #[arg(long)]
    pub horizon: Option<usize>,
    /// Epochs of the trajectory rows [default: 600; 3 with --quick].
    #[arg(long)]
    pub trajectory_epochs: Option<usize>,
    /// Epochs of one-step training before the windows take over in the --horizon row (a
    /// curriculum; fewer than --trajectory-epochs).
    #[arg(long, default_value_t = 0)]
    pub one_step_epochs: usize,
    #[command(flatten)]
    pub run: pool::RunArgs,
}

#[derive(Debug, Clone, Serialize)]
struct RolloutSettings {
    system: &'static str,
    models: [&'static str; 2],
    seed: u64,
    train_size: usize,
    val_size: usize,
    epochs: usize,
    batch_size: usize,
    lr: f64,
    count: usize,
    trajectory: &'static str,
    backend: &'static str,
    precision: &'static str,
    /// The trajectory rows (left out without --horizon, as before it was an option).
    #[serde(skip_serializing_if = "Option::is_none")]
    trajectories: Option<TrajectorySettings>,
}

#[derive(Debug, Clone, Serialize)]
struct TrajectorySettings {
    horizon: usize,
    train_trajectories: usize,
    val_trajectories: usize,
    steps: usize,
    epochs: usize,
    one_step_epochs: usize,
}

/// A row of the table: what its model trained on.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Row {
    /// The paper's independent samples.
    Samples(&'static str),
    /// MVF on trajectories, on windows of this many steps.
    Trajectories(usize),
}

impl Row {
    /// The row's cell key and file name.
    fn key(&self) -> String {
        match self {
            Row::Samples(m) => m.to_string(),
            Row::Trajectories(h) => format!("MVF-trajectories-h{h}"),
        }
    }

    fn label(&self) -> String {
        match self {
            Row::Samples(m) => m.to_string(),
            Row::Trajectories(h) => format!("MVF, trajectories, H = {h}"),
        }
    }
}

/// A trained model, saved as `<model>.gbx` in the directory.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Trained {
    model: String,
    best_val_loss: Option<f64>,
    best_epoch: usize,
    seconds: f64,
    file: String,
}

/// One true trajectory: x₀, inputs `[STEPS, m]` and positions `[STEPS + 1, n]`.
struct Trajectory {
    x0: Vec<f64>,
    u: Vec<f64>,
    q: Vec<f64>,
}

pub fn run(a: RolloutArgs) -> Result<()> {
    let q = a.run.quick;
    let s = RolloutSettings {
        system: "double_pendulum (paper values), dt 0.01, RK4; training data as in data-efficiency",
        models: MODELS,
        seed: a.seed,
        train_size: a.train_size.unwrap_or(if q { 256 } else { 4096 }).max(1),
        val_size: a.val_size.unwrap_or(if q { 64 } else { 1024 }).max(1),
        epochs: a.epochs.unwrap_or(if q { 30 } else { 3000 }),
        batch_size: 256,
        lr: 1e-3,
        count: a.count.unwrap_or(if q { 4 } else { 100 }).max(1),
        trajectory: "5 s (500 steps): q0 ~ U(-pi, pi), qdot0 ~ U(-2, 2), inputs held 0.1 s, ~ N(0, 30^2)",
        backend: "flex",
        precision: "f32",
        trajectories: a
            .horizon
            .or(q.then_some(3))
            .map(|horizon| TrajectorySettings {
                horizon,
                train_trajectories: if q { 4 } else { TRAIN_TRAJECTORIES },
                val_trajectories: if q { 2 } else { VAL_TRAJECTORIES },
                steps: if q { 30 } else { TRAJECTORY_STEPS },
                epochs: a.trajectory_epochs.unwrap_or(if q { 3 } else { 600 }),
                one_step_epochs: a.one_step_epochs,
            }),
    };
    let out = OutDir::open(&a.out, "rollout", &s)?;
    let mut rows: Vec<Row> = MODELS.iter().map(|&m| Row::Samples(m)).collect();
    if let Some(t) = &s.trajectories {
        rows.extend([Row::Trajectories(1), Row::Trajectories(t.horizon)]);
    }
    let progress = Progress::new(rows.len(), 0);
    let trained = pool::parallel(
        &rows,
        pool::threads(a.run.jobs),
        &progress,
        |row, status| {
            let name = row.key();
            if let Some(t) = out.get::<Trained>(&format!("train/{name}"))
                && let Ok(file) = ModelFile::load(&out.path(&t.file))
            {
                progress.cells_done(1, &format!("{name}: trained earlier"));
                return Ok((t, file));
            }
            let show = |e: usize, epochs: usize, best: f64| {
                status.show(&format!("{name}: epoch {e}/{epochs} best val {best:.3e}"))
            };
            let (t, file) = match row {
                Row::Samples(m) => train(&s, m, &|e, best| show(e, s.epochs, best))?,
                Row::Trajectories(h) => train_on_trajectories(&s, &out, *h, &show)?,
            };
            file.save(&out.path(&t.file))?;
            out.put(&format!("train/{name}"), &t)?;
            let _ = std::fs::remove_file(checkpoint(&out, *row));
            progress.cells_done(
                1,
                &format!(
                    "{name}: best val {:.3e} ({:.0} s)",
                    t.best_val_loss.unwrap_or(f64::NAN),
                    t.seconds
                ),
            );
            Ok((t, file))
        },
    );
    progress.finish();
    let trained: Vec<(Trained, ModelFile)> = trained.into_iter().collect::<Result<_>>()?;
    let evaluators: Vec<Evaluator> = trained
        .iter()
        .map(|(_, f)| Evaluator::from_file(f))
        .collect::<Result<_>>()?;
    let truth = true_trajectories(&s);
    let predicted: Vec<Vec<Vec<f64>>> = evaluators
        .iter()
        .map(|e| truth.iter().map(|t| predict(e, t)).collect())
        .collect();
    report::write(&s, &out, &trained, &truth, &predicted)?;
    out.finish()
}

fn train(
    s: &RolloutSettings,
    model: &str,
    show: &dyn Fn(usize, f64),
) -> Result<(Trained, ModelFile)> {
    let start = Instant::now();
    let data = paper_double_pendulum(s.train_size, s.seed, 0)?;
    let val = paper_double_pendulum(s.val_size, s.seed, 1)?;
    let cfg = TrainConfig {
        epochs: s.epochs,
        batch_size: s.batch_size,
        lr: s.lr,
        val_fraction: 0.0,
        seed: s.seed,
        ..TrainConfig::default()
    };
    let spec = ModelSpec::named(model, Some(Template::DoublePendulum))?;
    let device = backend::device(Backend::Flex, Precision::F32)?.autodiff();
    let mut trainer = Trainer::new(model, spec, &[], &data, Some(&val), cfg, &device)?;
    trainer.run(&AtomicBool::new(false), |m, t| {
        show(m.epoch, t.best_val_loss().unwrap_or(f64::NAN))
    })?;
    let report = trainer.report();
    Ok((
        Trained {
            model: model.to_string(),
            best_val_loss: report.best_val_loss,
            best_epoch: report.best_epoch,
            seconds: start.elapsed().as_secs_f64(),
            file: format!("{model}.gbx"),
        },
        trainer.model_file(),
    ))
}

fn checkpoint(out: &OutDir, row: Row) -> std::path::PathBuf {
    out.path(&format!("{}.ckpt.json", row.key()))
}

/// MVF on the settings' trajectories with windows of `horizon` (the one-step epochs first when
/// `horizon` > 1), checkpointing as it goes so that an interrupted run resumes mid-cell.
fn train_on_trajectories(
    s: &RolloutSettings,
    out: &OutDir,
    horizon: usize,
    show: &dyn Fn(usize, usize, f64),
) -> Result<(Trained, ModelFile)> {
    let t = s
        .trajectories
        .as_ref()
        .expect("trajectory rows have settings");
    let data = trajectories(
        t.train_trajectories,
        t.steps,
        s.seed,
        0,
        Recording::default(),
    )?;
    let val = trajectories(t.val_trajectories, t.steps, s.seed, 1, Recording::default())?;
    let cfg = TrainConfig {
        epochs: t.epochs,
        batch_size: s.batch_size,
        lr: s.lr,
        val_fraction: 0.0,
        seed: s.seed,
        horizon,
        one_step_epochs: if horizon > 1 { t.one_step_epochs } else { 0 },
        ..TrainConfig::default()
    };
    let row = Row::Trajectories(horizon);
    let ckpt = checkpoint(out, row);
    let trainer = resumable::train("MVF", cfg, &data, &val, &ckpt, 1, &|m| {
        show(
            m.epoch,
            t.epochs,
            m.val_horizon_loss.or(m.val_loss).unwrap_or(f64::NAN),
        )
    })?;
    let report = trainer.report();
    // The one-step validation loss of the kept epoch, comparable with the other rows' (the
    // multi-step run picks its epoch by the loss over its windows).
    let history = &trainer.checkpoint().history;
    let best = history.iter().find(|m| m.epoch == report.best_epoch);
    Ok((
        Trained {
            model: row.label(),
            best_val_loss: best.and_then(|m| m.val_loss),
            best_epoch: report.best_epoch,
            seconds: trainer.train_seconds(),
            file: format!("{}.gbx", row.key()),
        },
        trainer.model_file(),
    ))
}

/// The true system's trajectories (RK4 at Δt = 0.01 on the template, as the training data).
fn true_trajectories(s: &RolloutSettings) -> Vec<Trajectory> {
    let t = Template::DoublePendulum;
    let (n, m) = (t.n(), t.m());
    let sys = TemplateSystem::new(t.clone(), t.defaults());
    let mut rng = Rng::derive(s.seed, 0x0707_0001);
    (0..s.count)
        .map(|_| {
            let q0 = (0..n).map(|_| rng.uniform_in(-std::f64::consts::PI, std::f64::consts::PI));
            let q0: Vec<f64> = q0.collect();
            let qd0: Vec<f64> = (0..n).map(|_| rng.uniform_in(-QDOT0, QDOT0)).collect();
            let x0: Vec<f64> = q0.iter().chain(&qd0).copied().collect();
            let mut u = Vec::with_capacity(STEPS * m);
            for k in 0..STEPS {
                if k % HOLD == 0 {
                    u.extend((0..m).map(|_| U_STD * rng.normal()));
                } else {
                    u.extend_from_within(u.len() - m..);
                }
            }
            let mut x = x0.clone();
            let mut q = q0;
            for k in 0..STEPS {
                x = true_step(&sys, &x, &u[k * m..(k + 1) * m], DT, Integrator::Rk4);
                q.extend_from_slice(&x[..n]);
            }
            Trajectory { x0, u, q }
        })
        .collect()
}

/// A model's positions `[STEPS + 1, n]` from the trajectory's x₀ under its inputs.
fn predict(e: &Evaluator, t: &Trajectory) -> Vec<f64> {
    let (n, m) = (e.config.nq(), e.config.m);
    let mut q = t.x0[..n].to_vec();
    e.rollout(
        &t.x0,
        (STEPS, e.config.dt),
        |k, _| t.u[k * m..(k + 1) * m].to_vec(),
        |x, _| {
            q.extend_from_slice(&x[..n]);
            true
        },
    );
    q
}
