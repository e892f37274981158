//! The training step in f32, the precision service jobs train in, against what Burn's
//! op-by-op graph computed before it was retired (`common::fused`): every gradient, and
//! training runs over three seeds.

use std::path::Path;

use super::flex;
use crate::common::fused::{TRAINED, best_val_loss, recorded_runs, step_matches_graph};

const RECORD: &str = "tests/fixtures/gradients/graph-f32.json";
const TRAINING: &str = "tests/fixtures/gradients/graph-training-f32.json";

/// Both round every product to f32 (~6e-8) in different orders, through a few hundred
/// operations per row, so gradients differ by ~1e-6 relative; a wrong rule moves a gradient
/// by its own size.
#[test]
fn the_step_has_the_graphs_loss_and_gradients_in_f32() {
    step_matches_graph(&flex(), 1e-5, Path::new(RECORD));
}

/// In f32 rounding differences grow through training into a different trajectory, as
/// another seed's would: the runs' mean best validation loss over three seeds lies within
/// the graph runs' seed-to-seed spread of theirs. A wrong gradient trains worse by far more
/// than that spread.
#[test]
fn training_matches_the_graphs_within_the_seeds_spread() {
    let dev = flex();
    for model in TRAINED {
        let runs = recorded_runs(Path::new(TRAINING), model);
        let graph: Vec<f64> = runs.iter().map(|r| r.best_val_loss).collect();
        let now: Vec<f64> = (runs.iter())
            .map(|r| best_val_loss(model, r.seed, r.epochs, &dev))
            .collect();
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let spread = graph.iter().fold(f64::MIN, |a, &b| a.max(b))
            - graph.iter().fold(f64::MAX, |a, &b| a.min(b));
        eprintln!("{model}: best validation losses: {now:?}, graph {graph:?}");
        assert!(
            (mean(&now) - mean(&graph)).abs() <= spread,
            "{model}: {now:?} vs graph {graph:?}"
        );
    }
}
