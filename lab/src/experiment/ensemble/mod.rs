//! `graybox-lab experiment ensemble`: what an ensemble's spread is worth (README "Ensembles and
//! uncertainty"). Calibration: MVF ×5 (bootstrap) on the paper's double pendulum, its
//! members' σ against the true one-step error on held-out samples of the training
//! distribution and out of it (faster velocities). Error bars: W-B ×5 on few noisy samples
//! from a wrong start, its bootstrap σ of each physical value against the truth. Both
//! ensembles checkpoint as they train and are kept as model files, so a rerun only evaluates.

mod calibration;
mod errorbars;
mod report;

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use clap::Args;
use serde::{Deserialize, Serialize};

use super::out::OutDir;
use super::pool::{self, Progress, Status};
use graybox::backend::{self, Backend, Precision};
use graybox::data::Dataset;
use graybox::error::Result;
use graybox::model::file::{ModelFile, write_atomic};
use graybox::model::spec::ModelSpec;
use graybox::physics::templates::Template;
use graybox::rng::Rng;
use graybox::sim::{SimConfig, simulate};
use graybox::train::{Ensemble, TrainConfig};

/// Epochs between an ensemble's checkpoints.
const CHECKPOINT_EVERY: usize = 50;

#[derive(Args, Debug)]
pub struct EnsembleArgs {
    /// Directory for results.md, results.json, results.csv, sigma_vs_error.png, the two
    /// ensembles' model files and run.json; running again with the same settings reuses the
    /// trained ensembles (and resumes one cut short from its checkpoint).
    #[arg(long)]
    pub out: PathBuf,
    /// Epochs of the MVF ensemble (the best-validation epoch of each member is kept)
    /// [default: 2000; 20 with --quick].
    #[arg(long)]
    pub epochs: Option<usize>,
    /// Epochs of the W-B ensemble [default: 3000; 20 with --quick].
    #[arg(long)]
    pub wb_epochs: Option<usize>,
    /// Seed of the data, the noise and the members' seeds.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Training threads [default: every core].
    #[arg(long)]
    pub threads: Option<usize>,
    /// A small run for tests (well under a minute).
    #[arg(long)]
    pub quick: bool,
}

#[derive(Debug, Clone, Serialize)]
pub(super) struct EnsembleSettings {
    system: &'static str,
    members: usize,
    bootstrap: bool,
    seed: u64,
    backend: &'static str,
    precision: &'static str,
    calibration: CalibrationSettings,
    error_bars: ErrorBarSettings,
}

#[derive(Debug, Clone, Serialize)]
pub(super) struct CalibrationSettings {
    model: &'static str,
    train_size: usize,
    val_size: usize,
    epochs: usize,
    batch_size: usize,
    lr: f64,
    /// Held-out samples of the training distribution, and as many out of it.
    test_size: usize,
    qdot_range: f64,
    ood_qdot_range: f64,
}

#[derive(Debug, Clone, Serialize)]
pub(super) struct ErrorBarSettings {
    model: &'static str,
    train_size: usize,
    val_size: usize,
    /// σ of the Gaussian noise added to q̇' of the training and validation samples.
    qdot_next_noise: f64,
    /// Each parameter's start: its true value times this factor.
    init_factors: Vec<(String, f64)>,
    epochs: usize,
    batch_size: usize,
    lr: f64,
}

/// A trained ensemble, saved as `file` in the directory.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(super) struct Trained {
    model: String,
    file: String,
    epochs: usize,
    best_epochs: Vec<usize>,
    /// The members' mean best validation loss, and each member's.
    best_val_loss: Option<f64>,
    member_best_val_loss: Vec<Option<f64>>,
    /// The members' training seconds summed (they run side by side), and the wall time of the
    /// invocation that finished the training (from its checkpoint when it resumed one).
    member_seconds: f64,
    wall_seconds: f64,
}

/// One of the two ensembles.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Cell {
    Calibration,
    ErrorBars,
}

impl Cell {
    fn key(self) -> &'static str {
        match self {
            Cell::Calibration => "mvf-x5",
            Cell::ErrorBars => "wb-x5",
        }
    }
}

pub fn run(a: EnsembleArgs) -> Result<()> {
    let q = a.quick;
    let t = Template::DoublePendulum;
    let factors = errorbars::init_factors(&t);
    let s = EnsembleSettings {
        system: "double_pendulum (paper values), dt 0.01, RK4, u ~ N(0, 120^2)",
        members: 5,
        bootstrap: true,
        seed: a.seed,
        backend: "flex",
        precision: "f32",
        calibration: CalibrationSettings {
            model: "MVF",
            train_size: if q { 256 } else { 1024 },
            val_size: if q { 64 } else { 256 },
            epochs: a.epochs.unwrap_or(if q { 20 } else { 2000 }),
            batch_size: 256,
            lr: 1e-3,
            test_size: if q { 256 } else { 4096 },
            qdot_range: 10.0,
            ood_qdot_range: 20.0,
        },
        error_bars: ErrorBarSettings {
            model: "W-B",
            train_size: 256,
            val_size: 64,
            qdot_next_noise: 0.01,
            init_factors: factors,
            epochs: a.wb_epochs.unwrap_or(if q { 20 } else { 3000 }),
            batch_size: 32,
            lr: 1e-3,
        },
    };
    let out = OutDir::open(&a.out, "ensemble", &s)?;
    let threads = a.threads.unwrap_or(pool::threads(0)).max(1);
    let cells = [Cell::Calibration, Cell::ErrorBars];
    let done = (cells.iter())
        .filter(|&&c| trained_earlier(&out, c).is_some())
        .count();
    if done > 0 {
        eprintln!("{done} of {} cells finished earlier", cells.len());
    }
    let progress = Progress::new(cells.len(), done);
    // One ensemble at a time, each on every thread (its members side by side).
    let trained = pool::parallel(&cells, 1, &progress, |&cell, status| {
        if let Some(done) = trained_earlier(&out, cell) {
            return Ok(done);
        }
        let r = train_cell(&s, &out, cell, threads, status)?;
        let what = format!(
            "{}: best val {:.3e} ({:.0} s)",
            cell.key(),
            r.0.best_val_loss.unwrap_or(f64::NAN),
            r.0.wall_seconds
        );
        progress.cells_done(1, &what);
        Ok(r)
    });
    progress.finish();
    let trained: Vec<(Trained, ModelFile)> = trained.into_iter().collect::<Result<_>>()?;
    let c = &s.calibration;
    let seed = s.seed;
    let in_dist = samples(c.test_size, seed, 2, c.qdot_range, 0.0)?;
    let ood = samples(c.test_size, seed, 3, c.ood_qdot_range, 0.0)?;
    let cal = calibration::evaluate(&trained[0].1, &in_dist, &ood, c.qdot_range)?;
    let bars = errorbars::table(&trained[1].1, &s.error_bars)?;
    let trained: Vec<Trained> = trained.into_iter().map(|(t, _)| t).collect();
    report::write(&s, &out, &trained, &cal, &bars)?;
    out.finish()
}

/// `count` transitions of the paper's double pendulum with q̇ ~ U(−`qdot_range`, `qdot_range`)
/// from stream `stream` of `seed`, with Gaussian noise of σ `noise` added to q̇' (seeded by
/// the same stream).
fn samples(count: usize, seed: u64, stream: u64, qdot_range: f64, noise: f64) -> Result<Dataset> {
    let t = Template::DoublePendulum;
    let cfg = SimConfig {
        count,
        seed: Rng::derive(seed, 0xE5E0_0000 + stream).next_u64(),
        qdot_range,
        ..SimConfig::default()
    };
    let mut ds = simulate(&t, t.defaults(), &cfg)?;
    if noise > 0.0 {
        let mut rng = Rng::derive(seed, 0x0B5E_E500 + stream);
        (ds.qdot_next.iter_mut()).for_each(|v| *v += noise * rng.normal());
    }
    Ok(ds)
}

/// The cell's ensemble when an earlier invocation trained and saved it.
fn trained_earlier(out: &OutDir, cell: Cell) -> Option<(Trained, ModelFile)> {
    let t = out.get::<Trained>(&format!("train/{}", cell.key()))?;
    let file = ModelFile::load(&out.path(&t.file)).ok()?;
    Some((t, file))
}

/// Trains the cell's ensemble (from its checkpoint when there is one) and saves it.
fn train_cell(
    s: &EnsembleSettings,
    out: &OutDir,
    cell: Cell,
    threads: usize,
    status: &Status,
) -> Result<(Trained, ModelFile)> {
    let key = cell.key();
    let t = Template::DoublePendulum;
    let (model, data, val, init, cfg) = match cell {
        Cell::Calibration => {
            let c = &s.calibration;
            let cfg = TrainConfig {
                epochs: c.epochs,
                batch_size: c.batch_size,
                lr: c.lr,
                ..TrainConfig::default()
            };
            let data = samples(c.train_size, s.seed, 0, c.qdot_range, 0.0)?;
            let val = samples(c.val_size, s.seed, 1, c.qdot_range, 0.0)?;
            (c.model, data, val, vec![], cfg)
        }
        Cell::ErrorBars => {
            let e = &s.error_bars;
            let cfg = TrainConfig {
                epochs: e.epochs,
                batch_size: e.batch_size,
                lr: e.lr,
                ..TrainConfig::default()
            };
            let noise = e.qdot_next_noise;
            let data = samples(e.train_size, s.seed, 4, 10.0, noise)?;
            let val = samples(e.val_size, s.seed, 5, 10.0, noise)?;
            (e.model, data, val, errorbars::init(&t, e), cfg)
        }
    };
    let cfg = TrainConfig {
        seed: s.seed,
        ensemble: s.members,
        bootstrap: s.bootstrap,
        ..cfg
    };
    let epochs = cfg.epochs;
    let ckpt = out.path(&format!("{key}.ckpt.json"));
    let device = backend::device(Backend::Flex, Precision::F32)?.autodiff();
    let start = Instant::now();
    let mut e = match std::fs::read(&ckpt) {
        Ok(bytes) => Ensemble::resume(&bytes, &data, Some(&val), &device)?,
        Err(_) => {
            let spec = ModelSpec::named(model, Some(t))?;
            Ensemble::new(model, spec, &init, &data, Some(&val), cfg, &device)?
        }
    }
    .with_threads(threads)?;
    let never = AtomicBool::new(false);
    while !e.finished() {
        let m = e.run_epoch(&never)?;
        status.show(&format!(
            "{key}: epoch {}/{epochs} val {:.3e} best {:.3e}",
            e.epoch(),
            m.mean.val_loss.unwrap_or(f64::NAN),
            e.best_val_loss().unwrap_or(f64::NAN)
        ));
        if e.epoch() % CHECKPOINT_EVERY == 0 {
            write_atomic(&ckpt, &e.checkpoint())?;
        }
    }
    let file = e.model_file();
    let report = file.report.as_ref().expect("a trained file has a report");
    let members = report.ensemble.as_ref().map(|r| r.members.as_slice());
    let trained = Trained {
        model: model.to_string(),
        file: format!("{key}.gbx"),
        epochs: report.epochs,
        best_epochs: members.map_or(vec![report.best_epoch], |m| {
            m.iter().map(|m| m.best_epoch).collect()
        }),
        best_val_loss: report.best_val_loss,
        member_best_val_loss: members.map_or(vec![report.best_val_loss], |m| {
            m.iter().map(|m| m.best_val_loss).collect()
        }),
        member_seconds: (report.ensemble.as_ref())
            .and_then(|e| e.member_seconds)
            .unwrap_or(report.seconds),
        wall_seconds: start.elapsed().as_secs_f64(),
    };
    file.save(&out.path(&trained.file))?;
    out.put(&format!("train/{key}"), &trained)?;
    let _ = std::fs::remove_file(&ckpt);
    Ok((trained, file))
}
