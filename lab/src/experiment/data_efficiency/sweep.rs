//! The sweep: per model and seed, a ladder of growing training sets with one trained cell per
//! size. Each cell is saved as it finishes, so that a rerun trains only what is missing; and,
//! unless `--all-sizes`, a ladder stops at the first size that reaches the threshold, since
//! the larger sets cannot change its answer.

use std::sync::atomic::AtomicBool;
use std::time::Instant;

use super::{Cell, DataEfficiencySettings, MAX_BATCH, SeedData};
use crate::experiment::out::OutDir;
use crate::experiment::pool::{Progress, Status};
use graybox::backend::{self, Backend, Precision};
use graybox::error::Result;
use graybox::model::spec::ModelSpec;
use graybox::physics::templates::Template;
use graybox::rng::Rng;
use graybox::train::{TrainConfig, Trainer};

/// A model and seed over growing sizes, until one reaches the strict threshold (every size
/// with `all_sizes`). Finished cells come from the directory.
pub(super) fn ladder(
    s: &DataEfficiencySettings,
    out: &OutDir,
    model: &str,
    seed: u64,
    data: &SeedData,
    progress: &Progress,
    status: &Status,
) -> Result<Vec<Cell>> {
    let mut cells = vec![];
    for (i, &size) in s.sizes.iter().enumerate() {
        let key = format!("{model}/seed{seed}/{size}");
        let cell = match out.get::<Cell>(&key) {
            Some(c) => {
                progress.cells_done(1, &format!("{key}: done earlier"));
                c
            }
            None => {
                let c = train_cell(s, model, seed, size, data, status)?;
                out.put(&key, &c)?;
                let loss = c
                    .best_val_loss
                    .map_or_else(|| "failed".into(), |l| format!("{l:.3e}"));
                progress.cells_done(1, &format!("{key}: best val {loss} ({:.0} s)", c.seconds));
                c
            }
        };
        let reached = cell.reaches(s.thresholds[0]);
        cells.push(cell);
        if reached && !s.all_sizes {
            let skipped = s.sizes.len() - i - 1;
            if skipped > 0 {
                progress.cells_done(skipped, &format!("{model}/seed{seed}: reached at {size}"));
            }
            break;
        }
    }
    Ok(cells)
}

fn train_cell(
    s: &DataEfficiencySettings,
    model: &str,
    seed: u64,
    size: usize,
    data: &SeedData,
    status: &Status,
) -> Result<Cell> {
    let start = Instant::now();
    let idx: Vec<usize> = (0..size).collect();
    let train = data.pool.subset(&idx);
    let cfg = TrainConfig {
        epochs: s.epochs,
        batch_size: size.min(MAX_BATCH),
        lr: s.lr,
        val_fraction: 0.0,
        seed,
        patience: Some(s.patience),
        ..TrainConfig::default()
    };
    let spec = ModelSpec::named(model, Some(Template::DoublePendulum))?;
    let device = backend::device(Backend::Flex, Precision::F32)?.autodiff();
    let mut cell = Cell {
        model: model.to_string(),
        seed,
        size,
        best_val_loss: None,
        best_epoch: 0,
        epochs: 0,
        seconds: 0.0,
        error: None,
    };
    let init = if spec.template().is_some() {
        initial_physical(seed)
    } else {
        vec![]
    };
    let mut trainer = Trainer::new(model, spec, &init, &train, Some(&data.val), cfg, &device)?;
    let run = trainer.run(&AtomicBool::new(false), |m, t| {
        status.show(&format!(
            "{model} seed {seed} |D|={size}: epoch {}/{} best val {:.3e}",
            m.epoch,
            s.epochs,
            t.best_val_loss().unwrap_or(f64::NAN)
        ))
    });
    // A diverged training is a result of this cell (not reached), not the experiment's end.
    if let Err(e) = run {
        cell.error = Some(e.to_string());
    }
    let report = trainer.report();
    cell.best_val_loss = report.best_val_loss.filter(|l| l.is_finite());
    cell.best_epoch = report.best_epoch;
    cell.epochs = report.epochs;
    cell.seconds = start.elapsed().as_secs_f64();
    Ok(cell)
}

/// A seed's initial physical values: the true ones, each times a factor drawn
/// log-uniformly from [½, 2]. The paper's seeds vary the initialization; starting at the truth
/// (the template's defaults) would hand W-B its answer.
fn initial_physical(seed: u64) -> Vec<(String, f64)> {
    let mut rng = Rng::derive(seed, 0x1417_1A15);
    let ln2 = std::f64::consts::LN_2;
    Template::DoublePendulum
        .params()
        .iter()
        .map(|p| {
            (
                p.name.to_string(),
                p.default * rng.uniform_in(-ln2, ln2).exp(),
            )
        })
        .collect()
}
