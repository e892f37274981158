//! The fused step against Burn's graph in f64 (`common::fused`): every gradient, and a
//! whole training run.

use std::path::Path;

use super::f64_device;
use crate::common::fused::{
    TRAINED, best_val_loss, fused_matches_graph, record_graph, record_graph_training, recorded_runs,
};

const RECORD: &str = "tests/fixtures/gradients/graph-f64.json";
const TRAINING: &str = "tests/fixtures/gradients/graph-training-f64.json";

/// Records the graph's losses and gradients (`scripts/gradient_fixtures.sh`).
#[test]
#[ignore = "writes tests/fixtures/gradients/graph-f64.json; scripts/gradient_fixtures.sh"]
fn record_the_graphs_gradients() {
    let dev = f64_device().autodiff();
    record_graph(&dev, Path::new(RECORD));
    record_graph_training(&dev, &[0], Path::new(TRAINING));
}

/// Both paths compute the same f64 mechanics in other orders (the tape sums a layer's
/// products row by row, Burn by matrix products): rounding separates them by ~1e-15
/// relative; a wrong rule anywhere moves a gradient by its own size.
#[test]
fn the_fused_step_has_burns_loss_and_gradients() {
    fused_matches_graph(&f64_device().autodiff(), 1e-12, Path::new(RECORD));
}

/// 300 epochs of Adam (600 steps) amplify the paths' 1e-15 rounding differences, but a
/// smooth optimizer keeps them far below 1e-6; a wrong gradient anywhere changes the
/// trajectory and its best loss at the percent level. Against the graph's runs as recorded
/// (`record_the_graphs_gradients`); tens of seconds.
#[test]
fn training_through_the_fused_step_follows_burns_trajectory() {
    let dev = f64_device().autodiff();
    for model in TRAINED {
        for run in recorded_runs(Path::new(TRAINING), model) {
            let fused = best_val_loss(model, false, run.seed, run.epochs, &dev);
            let graph = run.best_val_loss;
            eprintln!("{model}: best validation loss: fused {fused:e}, graph {graph:e}");
            assert!(
                (fused - graph).abs() <= 1e-6 * graph,
                "{model}: fused {fused:e} vs graph {graph:e}"
            );
        }
    }
}
