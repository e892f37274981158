#!/usr/bin/env bash
# Writes what is missing of tests/fixtures/inference: model files trained by the graybox that
# built $GRAYBOX_BIN (default target/release/graybox), and answers.json, the service's answers
# to a fixed set of inference calls on them and on two compatibility fixtures (the oldest
# format's MVF and a W-B ensemble, tests/fixtures/compat), which every evaluator of a model
# file must reproduce bit for bit (tests/python/test_inference_answers.py). Files and records
# already there are kept: delete one only to record it again on purpose, never to make a test
# pass. A recorded Predict, Rollout or Linearize without its max_abs_z gets the service's, once
# the rest of its answer is checked to be the record's. The files recorded before model files
# carried a checksum have none and load with a warning (docs/model-file.md); a file recorded
# now gets one from the CLI that writes it.
#  - dp-mvf.gbx: MVF on the double pendulum;
#  - cartpole-wb.gbx: W-B on the cart-pole;
#  - formula-dp-wb.gbx: W-B on the double pendulum as a formula template
#    (examples/templates/double_pendulum.json);
#  - ur5-residual.gbx: the UR5 (a URDF) with a residual force network beside its joints'
#    damping and friction;
# each 2 epochs on 256 simulated transitions.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=$(realpath "${GRAYBOX_BIN:-target/release/graybox}")
python=${PYTHON:-.venv/bin/python}
out=tests/fixtures/inference
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mkdir -p "$out"

# train NAME TEMPLATE --model NAME | --spec FILE
train() {
  local name=$1 template=$2
  shift 2
  [ -e "$out/$name.gbx" ] && return
  "$bin" simulate --template "$template" --count 256 --seed 0 --out "$tmp/$name.json" > /dev/null
  "$bin" train --data "$tmp/$name.json" "$@" --template "$template" \
    --epochs 2 --batch-size 64 --out "$out/$name.gbx" > "$tmp/$name.log" 2>&1 ||
    { cat "$tmp/$name.log" >&2; exit 1; }
}
train dp-mvf double_pendulum --model MVF
train cartpole-wb cartpole --model W-B
train formula-dp-wb examples/templates/double_pendulum.json --model W-B
echo '{"mass": "template", "potential": "template",
  "forces": {"type": "template", "residual": {"type": "mlp", "hidden": [16]}}}' > "$tmp/residual.json"
train ur5-residual tests/fixtures/urdf/robots/ur5.urdf --spec "$tmp/residual.json"

GRAYBOX_WRITE_INFERENCE=1 GRAYBOX_BIN="$bin" "$python" -m pytest -q -rs \
  tests/python/test_inference_answers.py
echo "wrote $out: $(ls "$out" | tr '\n' ' ')"
