#!/usr/bin/env bash
# Writes what is missing of tests/fixtures/gradients: Burn's op-by-op graph's one-step loss
# and every parameter tensor's gradient, at the parameters it ran at, for each case of
# tests/common/fused.rs (graph-f64.json, graph-f32.json), and its best validation loss after
# 300 epochs of MVF and W-B on the paper's double pendulum data (graph-training-f64.json: seed
# 0; graph-training-f32.json: seeds 1–3). They are the fused step's independent reference
# (tests/f64/numerics_f64/fused.rs, tests/suite/training/fused.rs), recorded while the graph
# exists; files already there are kept: delete one only to record it again on purpose,
# never to make a test pass. Takes a few minutes after the build.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo test --release --locked -p graybox --test f64 numerics_f64::fused::record_the_graphs_gradients \
  -- --ignored --exact --nocapture
cargo test --release --locked -p graybox --test suite training::fused::record_the_graphs_gradients \
  -- --ignored --exact --nocapture
