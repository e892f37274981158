//! The training step in f64 against what Burn's op-by-op graph computed before it was
//! retired (`common::fused`): every gradient, and a whole training run.

use std::path::Path;

use super::f64_device;
use crate::common::fused::{TRAINED, best_val_loss, recorded_runs, step_matches_graph};

const RECORD: &str = "tests/fixtures/gradients/graph-f64.json";
const TRAINING: &str = "tests/fixtures/gradients/graph-training-f64.json";

/// Both compute the same f64 mechanics in other orders (the tape sums a layer's products row
/// by row, Burn by matrix products): rounding separates them by ~1e-15 relative; a wrong
/// rule anywhere moves a gradient by its own size.
#[test]
fn the_step_has_the_graphs_loss_and_gradients() {
    step_matches_graph(&f64_device().autodiff(), 1e-12, Path::new(RECORD));
}

/// 300 epochs of Adam (600 steps) amplify the two's 1e-15 rounding differences, but a
/// smooth optimizer keeps them far below 1e-6; a wrong gradient anywhere changes the
/// trajectory and its best loss at the percent level. Tens of seconds.
#[test]
fn training_follows_the_graphs_trajectory() {
    let dev = f64_device().autodiff();
    for model in TRAINED {
        for run in recorded_runs(Path::new(TRAINING), model) {
            let now = best_val_loss(model, run.seed, run.epochs, &dev);
            let graph = run.best_val_loss;
            eprintln!("{model}: best validation loss: {now:e}, graph {graph:e}");
            assert!(
                (now - graph).abs() <= 1e-6 * graph,
                "{model}: {now:e} vs graph {graph:e}"
            );
        }
    }
}
