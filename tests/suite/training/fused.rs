//! The fused step against Burn's graph in f32 (`common::fused`), the precision service jobs
//! train in: every gradient, and training runs over three seeds.

use std::path::Path;

use super::flex;
use crate::common::fused::{
    TRAINED, best_val_loss, fused_matches_graph, record_graph, record_graph_training, recorded_runs,
};

const RECORD: &str = "tests/fixtures/gradients/graph-f32.json";
const TRAINING: &str = "tests/fixtures/gradients/graph-training-f32.json";

/// Records the graph's losses and gradients (`scripts/gradient_fixtures.sh`).
#[test]
#[ignore = "writes tests/fixtures/gradients/graph-f32.json; scripts/gradient_fixtures.sh"]
fn record_the_graphs_gradients() {
    record_graph(&flex(), Path::new(RECORD));
    record_graph_training(&flex(), &[1, 2, 3], Path::new(TRAINING));
}

/// Both paths round every product to f32 (~6e-8) in different orders, through a few hundred
/// operations per row, so gradients differ by ~1e-6 relative; a wrong rule moves a gradient
/// by its own size.
#[test]
fn the_fused_step_has_burns_loss_and_gradients_in_f32() {
    fused_matches_graph(&flex(), 1e-5, Path::new(RECORD));
}

/// In f32 rounding differences grow through training into a different trajectory, as
/// another seed's would: the fused runs' mean best validation loss over three seeds lies
/// within the graph runs' seed-to-seed spread of theirs (as recorded). A wrong gradient
/// trains worse by far more than that spread.
#[test]
fn training_through_the_fused_step_matches_burns_within_the_seeds_spread() {
    let dev = flex();
    for model in TRAINED {
        let runs = recorded_runs(Path::new(TRAINING), model);
        let graph: Vec<f64> = runs.iter().map(|r| r.best_val_loss).collect();
        let fused: Vec<f64> = runs
            .iter()
            .map(|r| best_val_loss(model, false, r.seed, r.epochs, &dev))
            .collect();
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let spread = graph.iter().fold(f64::MIN, |a, &b| a.max(b))
            - graph.iter().fold(f64::MAX, |a, &b| a.min(b));
        eprintln!("{model}: best validation losses: fused {fused:?}, graph {graph:?}");
        assert!(
            (mean(&fused) - mean(&graph)).abs() <= spread,
            "{model}: fused {fused:?} vs graph {graph:?}"
        );
    }
}
