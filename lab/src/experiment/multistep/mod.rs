//! `graybox-lab experiment multistep`: MVF trained on windows of H transitions of the double
//! pendulum's trajectories (H = 1 is the paper's one-step loss) against the open-loop error of
//! its rollouts on held-out trajectories, per seed, paired across H (same data, same epochs),
//! and H = 1 once more for the wall time H = 10 took. The data are recorded every Δt from RK4
//! at Δt (the paper's) or, with `--substeps`, at a finer step. Cells checkpoint every few
//! epochs, so an interrupted run resumes mid-cell.

mod report;

use std::path::PathBuf;

use clap::Args;
use serde::{Deserialize, Serialize};

use super::out::OutDir;
use super::pool::{self, Progress};
use super::resumable::{self, trajectories};
use graybox::data::Dataset;
use graybox::error::Result;
use graybox::infer::Evaluator;
use graybox::infer::horizons::{HorizonError, horizon_errors};
use graybox::model::file::ModelFile;
use graybox::sim::{MAX_SUBSTEPS, Recording};
use graybox::train::TrainConfig;

/// When the error is read, in seconds (the plot's points, those that are a step or more at
/// the run's Δt); the tables show `TABLE_SECONDS`.
const EVAL_SECONDS: [f64; 10] = [0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 0.75, 1.0, 1.5, 2.0];
const TABLE_SECONDS: [f64; 3] = [0.5, 1.0, 2.0];
/// The paper's recording: every 0.01 s, of RK4 at 0.01 s.
const PAPER_DT: f64 = 0.01;

#[derive(Args, Debug)]
pub struct MultistepArgs {
    /// Directory for results.md, results.csv, the models, checkpoints and run.json; running
    /// again with the same settings continues where it stopped.
    #[arg(long)]
    pub out: PathBuf,
    /// Horizons to train with, comma-separated [default: 1,10,5,20; 1,3 with --quick].
    #[arg(long, value_delimiter = ',')]
    pub horizons: Option<Vec<usize>>,
    /// Seeds (each its own training data and initialization) [default: 3; 1 with --quick].
    #[arg(long)]
    pub seeds: Option<u64>,
    /// Epochs of every training [default: 200; 3 with --quick].
    #[arg(long)]
    pub epochs: Option<usize>,
    /// Epochs of one-step training before the windows take over, in every H > 1 cell (a
    /// curriculum; fewer than --epochs).
    #[arg(long, default_value_t = 0)]
    pub one_step_epochs: usize,
    /// Learning rate of the window epochs in H > 1 cells [default: the run's lr].
    #[arg(long)]
    pub window_lr: Option<f64>,
    /// Standard deviations of Gaussian noise added to the training and validation states, on
    /// q and on q̇ (e.g. 0.01,0.1), as sensors would record them; the held-out trajectories
    /// stay exact [default: none].
    #[arg(long, value_delimiter = ',')]
    pub noise: Option<Vec<f64>>,
    /// Training threads per cell [default: every core divided by --jobs]. Burn records a
    /// process's ops under one lock, so two runs side by side go faster as two processes
    /// (different --horizons and --out) than as --jobs 2.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Trainings at once [default: 1].
    #[arg(long, default_value_t = 1)]
    pub jobs: usize,
    /// The recording's (and the model's) time step, seconds: trajectories keep their
    /// length in seconds (2 s to train on, 3 s held out) and their inputs' hold (0.1 s).
    #[arg(long, default_value_t = PAPER_DT)]
    pub dt: f64,
    /// RK4 steps of the true system per recorded step (1: the data the model's own RK4 step
    /// can match exactly; e.g. 50 at --dt 0.05: a continuous system sampled every 0.05 s).
    #[arg(long, default_value_t = 1)]
    pub substeps: usize,
    /// A small run for tests (well under a minute).
    #[arg(long)]
    pub quick: bool,
}

#[derive(Debug, Clone, Serialize)]
pub(super) struct MultistepSettings {
    system: String,
    /// The recording's step and RK4 steps per recorded step (left out at the paper's 0.01
    /// and 1, as before they were options).
    #[serde(skip_serializing_if = "is_paper_dt")]
    dt: f64,
    #[serde(skip_serializing_if = "is_one")]
    substeps: usize,
    model: &'static str,
    horizons: Vec<usize>,
    seeds: Vec<u64>,
    epochs: usize,
    batch_size: usize,
    lr: f64,
    discount: f64,
    /// One-step epochs before the windows in H > 1 cells (left out when 0, as before it was
    /// an option).
    #[serde(skip_serializing_if = "is_zero")]
    one_step_epochs: usize,
    /// The window epochs' learning rate (left out when it is `lr`).
    #[serde(skip_serializing_if = "Option::is_none")]
    window_lr: Option<f64>,
    /// Noise on the training and validation states, [q, q̇] standard deviations (left out
    /// when there is none).
    #[serde(skip_serializing_if = "Option::is_none")]
    noise: Option<[f64; 2]>,
    train_trajectories: usize,
    val_trajectories: usize,
    test_trajectories: usize,
    steps: usize,
    test_steps: usize,
    trajectory: &'static str,
}

/// One training: its horizon, seed and epochs (more than the settings' for the H = 1 run at
/// H = 10's wall time).
#[derive(Debug, Clone, Copy, PartialEq)]
struct CellKey {
    horizon: usize,
    seed: u64,
    equal_time: bool,
}

impl CellKey {
    fn name(&self) -> String {
        let tag = if self.equal_time { "-equal-time" } else { "" };
        format!("h{}-seed{}{tag}", self.horizon, self.seed)
    }
}

/// A finished cell.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(super) struct Cell {
    horizon: usize,
    seed: u64,
    equal_time: bool,
    epochs: usize,
    best_epoch: usize,
    best_val_loss: Option<f64>,
    best_val_horizon_loss: Option<f64>,
    /// Seconds in training steps, and per epoch.
    train_seconds: f64,
    seconds_per_epoch: f64,
    samples_per_second: f64,
    /// Held-out open-loop errors at `EVAL_SECONDS`.
    errors: Vec<HorizonError>,
}

pub fn run(a: MultistepArgs) -> Result<()> {
    let q = a.quick;
    let rec = recording(a.dt, a.substeps)?;
    // Trajectories as long in seconds as at the paper's step.
    let steps = |seconds: f64| ((seconds / rec.dt).round() as usize).max(1);
    let s = MultistepSettings {
        system: system(rec),
        dt: rec.dt,
        substeps: rec.substeps,
        model: "MVF",
        horizons: a
            .horizons
            .unwrap_or(if q { vec![1, 3] } else { vec![1, 10, 5, 20] }),
        seeds: super::seeds_arg(a.seeds, if q { 1 } else { 3 })?,
        epochs: a.epochs.unwrap_or(if q { 3 } else { 200 }),
        batch_size: 256,
        lr: 1e-3,
        discount: 1.0,
        one_step_epochs: a.one_step_epochs,
        window_lr: a.window_lr,
        noise: noise_arg(a.noise.as_deref())?,
        train_trajectories: if q { 4 } else { 40 },
        val_trajectories: if q { 2 } else { 10 },
        test_trajectories: if q { 2 } else { 20 },
        steps: steps(if q { 0.3 } else { 2.0 }),
        test_steps: steps(if q { 0.6 } else { 3.0 }),
        trajectory: "q0 ~ U(-pi, pi), qdot0 ~ U(-2, 2), inputs ~ N(0, 30^2) held 0.1 s",
    };
    let out = OutDir::open(&a.out, "multistep", &s)?;
    let jobs = a.jobs.max(1);
    let threads = a.threads.unwrap_or((pool::threads(0) / jobs).max(1));
    let test = trajectories(s.test_trajectories, s.test_steps, 1000, 2, rec)?;
    let keys = cell_keys(&s);
    let done = keys
        .iter()
        .filter(|k| out.get::<Cell>(&k.name()).is_some())
        .count();
    if done > 0 {
        eprintln!("{done} of {} cells finished earlier", keys.len());
    }
    let progress = Progress::new(keys.len(), done);
    // The equal-time cells last: they need their seed's H = 1 and H = 10 times.
    for equal_time in [false, true] {
        let phase: Vec<CellKey> = keys
            .iter()
            .filter(|k| k.equal_time == equal_time)
            .copied()
            .collect();
        let results = pool::parallel(&phase, jobs, &progress, |k, status| {
            if let Some(c) = out.get::<Cell>(&k.name()) {
                return Ok(c);
            }
            let c = train_cell(&s, &out, *k, threads, &test, &|what| status.show(what))?;
            out.put(&k.name(), &c)?;
            progress.cells_done(1, &format!("{}: {:.0} s", k.name(), c.train_seconds));
            Ok(c)
        });
        results.into_iter().collect::<Result<Vec<Cell>>>()?;
    }
    progress.finish();
    let cells: Vec<Cell> = keys.iter().filter_map(|k| out.get(&k.name())).collect();
    report::write(&s, &out, &cells)?;
    out.finish()
}

/// Each horizon with every seed, in the order given, then H = 1 at H = 10's wall time per
/// seed when both are trained.
fn cell_keys(s: &MultistepSettings) -> Vec<CellKey> {
    let key = |horizon, seed, equal_time| CellKey {
        horizon,
        seed,
        equal_time,
    };
    let own =
        (s.horizons.iter()).flat_map(|&h| s.seeds.iter().map(move |&seed| key(h, seed, false)));
    let equal = s.horizons.contains(&1) && s.horizons.contains(&10);
    let extra = (s.seeds.iter())
        .filter(|_| equal)
        .map(|&seed| key(1, seed, true));
    own.chain(extra).collect()
}

/// `--noise`: two finite standard deviations ≥ 0.
fn noise_arg(noise: Option<&[f64]>) -> Result<Option<[f64; 2]>> {
    match noise {
        None => Ok(None),
        Some(&[q, qdot]) if [q, qdot].iter().all(|v| v.is_finite() && *v >= 0.0) => {
            Ok(Some([q, qdot]))
        }
        Some(_) => Err(graybox::error::Error::invalid(
            "noise",
            "expected two standard deviations ≥ 0: on q, then on q̇",
        )),
    }
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

fn is_one(n: &usize) -> bool {
    *n == 1
}

fn is_paper_dt(dt: &f64) -> bool {
    *dt == PAPER_DT
}

/// `--dt` and `--substeps`, checked.
fn recording(dt: f64, substeps: usize) -> Result<Recording> {
    if !(dt.is_finite() && dt > 0.0 && dt <= 0.1) {
        return Err(graybox::error::Error::invalid(
            "dt",
            "expected a step in (0, 0.1] seconds",
        ));
    }
    if !(1..=MAX_SUBSTEPS).contains(&substeps) {
        return Err(graybox::error::Error::invalid(
            "substeps",
            format!("expected 1 to {MAX_SUBSTEPS}"),
        ));
    }
    Ok(Recording { dt, substeps })
}

/// The system as run.json names it (the paper's recording as it always was).
fn system(rec: Recording) -> String {
    if rec.dt == PAPER_DT && rec.substeps == 1 {
        return "double_pendulum (paper values), dt 0.01, RK4".into();
    }
    format!(
        "double_pendulum (paper values), recorded every {} s of RK4 at {} s ({} substeps)",
        rec.dt,
        rec.dt / rec.substeps as f64,
        rec.substeps
    )
}

/// The steps at which the errors are read: `EVAL_SECONDS` at the run's step.
fn eval_steps(dt: f64) -> Vec<usize> {
    let mut steps: Vec<usize> = EVAL_SECONDS
        .iter()
        .map(|t| (t / dt).round() as usize)
        .filter(|&k| k >= 1)
        .collect();
    steps.dedup();
    steps
}

/// Trains one cell (resuming from its checkpoint when there is one), saves its model and
/// measures its held-out errors.
fn train_cell(
    s: &MultistepSettings,
    out: &OutDir,
    k: CellKey,
    threads: usize,
    test: &Dataset,
    show: &dyn Fn(&str),
) -> Result<Cell> {
    let rec = Recording {
        dt: s.dt,
        substeps: s.substeps,
    };
    let mut data = trajectories(s.train_trajectories, s.steps, k.seed, 0, rec)?;
    let mut val = trajectories(s.val_trajectories, s.steps, k.seed, 1, rec)?;
    if let Some(std) = s.noise {
        data = resumable::observed(&data, std, k.seed);
        val = resumable::observed(&val, std, k.seed + 1_000_000);
    }
    let epochs = if k.equal_time {
        equal_time_epochs(s, out, k.seed)
    } else {
        s.epochs
    };
    let cfg = TrainConfig {
        epochs,
        batch_size: s.batch_size,
        lr: s.lr,
        val_fraction: 0.0,
        seed: k.seed,
        horizon: k.horizon,
        discount: s.discount,
        one_step_epochs: if k.horizon > 1 { s.one_step_epochs } else { 0 },
        window_lr: s.window_lr.filter(|_| k.horizon > 1),
        ..TrainConfig::default()
    };
    let ckpt = out.path(&format!("{}.ckpt.json", k.name()));
    let trainer = resumable::train(s.model, cfg, &data, &val, &ckpt, threads, &|m| {
        show(&format!(
            "{}: epoch {}/{epochs} val {:.3e}",
            k.name(),
            m.epoch,
            m.val_horizon_loss.or(m.val_loss).unwrap_or(f64::NAN)
        ))
    })?;
    let file = trainer.model_file();
    file.save(&out.path(&format!("{}.gbx", k.name())))?;
    let report = trainer.report();
    let history = &trainer.checkpoint().history;
    let best = history.iter().find(|m| m.epoch == report.best_epoch);
    let errors = held_out_errors(&file, test, s.dt)?;
    let _ = std::fs::remove_file(&ckpt);
    Ok(Cell {
        horizon: k.horizon,
        seed: k.seed,
        equal_time: k.equal_time,
        epochs: report.epochs,
        best_epoch: report.best_epoch,
        best_val_loss: best.and_then(|m| m.val_loss),
        best_val_horizon_loss: best.and_then(|m| m.val_horizon_loss),
        train_seconds: trainer.train_seconds(),
        seconds_per_epoch: trainer.train_seconds() / report.epochs.max(1) as f64,
        samples_per_second: report.samples_per_second,
        errors,
    })
}

/// H = 1's epochs in the training time H = 10 took on this seed (the settings' epochs when
/// either is missing).
fn equal_time_epochs(s: &MultistepSettings, out: &OutDir, seed: u64) -> usize {
    let cell = |h: usize| {
        out.get::<Cell>(
            &CellKey {
                horizon: h,
                seed,
                equal_time: false,
            }
            .name(),
        )
    };
    match (cell(1), cell(10)) {
        (Some(one), Some(ten)) => {
            ((ten.train_seconds / one.seconds_per_epoch).round() as usize).max(s.epochs)
        }
        _ => s.epochs,
    }
}

fn held_out_errors(file: &ModelFile, test: &Dataset, dt: f64) -> Result<Vec<HorizonError>> {
    let e = Evaluator::from_file(file)?;
    Ok(horizon_errors(&e, test, &eval_steps(dt), &|| false).expect("never stopped"))
}
