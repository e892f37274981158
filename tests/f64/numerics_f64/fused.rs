//! The fused step against Burn's graph in f64 (`common::fused`): every gradient, and a
//! whole training run.

use super::f64_device;
use crate::common::fused::{best_val_loss, fused_matches_graph};

/// Both paths compute the same f64 mechanics in other orders (the tape sums a layer's
/// products row by row, Burn by matrix products): rounding separates them by ~1e-15
/// relative; a wrong rule anywhere moves a gradient by its own size.
#[test]
fn the_fused_step_has_burns_loss_and_gradients() {
    fused_matches_graph(&f64_device().autodiff(), 1e-12);
}

/// 300 epochs of Adam (600 steps) amplify the paths' 1e-15 rounding differences, but a
/// smooth optimizer keeps them far below 1e-6; a wrong gradient anywhere changes the
/// trajectory and its best loss at the percent level. Slow (tens of seconds): the
/// 300 epochs run on both paths, Burn's graph the slower.
#[test]
fn training_through_the_fused_step_follows_burns_trajectory() {
    let dev = f64_device().autodiff();
    let (fused, graph) = (
        best_val_loss(false, 0, 300, &dev),
        best_val_loss(true, 0, 300, &dev),
    );
    eprintln!("best validation loss: fused {fused:e}, graph {graph:e}");
    assert!(
        (fused - graph).abs() <= 1e-6 * graph,
        "fused {fused:e} vs graph {graph:e}"
    );
}
