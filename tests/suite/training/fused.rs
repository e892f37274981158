//! The fused step against Burn's graph in f32 (`common::fused`), the precision service jobs
//! train in: every gradient, and training runs over three seeds.

use super::flex;
use crate::common::fused::{best_val_loss, fused_matches_graph};

/// Both paths round every product to f32 (~6e-8) in different orders, through a few hundred
/// operations per row, so gradients differ by ~1e-6 relative; a wrong rule moves a gradient
/// by its own size.
#[test]
fn the_fused_step_has_burns_loss_and_gradients_in_f32() {
    fused_matches_graph(&flex(), 1e-5);
}

/// In f32 rounding differences grow through training into a different trajectory, as
/// another seed's would: the fused runs' mean best validation loss over three seeds lies
/// within the graph runs' seed-to-seed spread of theirs. A wrong gradient trains worse by far
/// more than that spread.
#[test]
fn training_through_the_fused_step_matches_burns_within_the_seeds_spread() {
    let dev = flex();
    let runs = |graph: bool| -> Vec<f64> {
        (1..=3)
            .map(|seed| best_val_loss(graph, seed, 300, &dev))
            .collect()
    };
    let (fused, graph) = (runs(false), runs(true));
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let spread = graph.iter().fold(f64::MIN, |a, &b| a.max(b))
        - graph.iter().fold(f64::MAX, |a, &b| a.min(b));
    eprintln!("best validation losses: fused {fused:?}, graph {graph:?}");
    assert!(
        (mean(&fused) - mean(&graph)).abs() <= spread,
        "fused {fused:?} vs graph {graph:?}"
    );
}
