#!/usr/bin/env bash
# Training throughput beside the paper's PyTorch code in one sitting: per round, the harness's
# bench_train.py (MVF and naive at batch 256 and 4096, 2 threads, 6 epochs, tensor loader)
# and `graybox-lab bench train --time-limit 0`, then `bench step` (one thread, one piece).
# Rounds alternate the two so that drift of the machine falls on both alike. Resumable:
# a run whose output file exists is skipped. Prints the medians and ratios at the end.
#
#   scripts/pytorch_sitting.sh OUT_DIR ROUNDS HARNESS_DIR
#   e.g. scripts/pytorch_sitting.sh experiments/fused-step/sitting 2 /work/mml
# HARNESS_DIR holds bench_train.py (../shared/bench/mml-harness), the paper's repository in
# repo/ and a venv with torch in venv/ (see that harness's README).
set -euo pipefail
out=$(realpath -m "$1") rounds=$2 harness=$(realpath "$3")
lab=${GRAYBOX_LAB_BIN:-target/release/graybox-lab}
mkdir -p "$out"
run() { # file command...
  local file=$1; shift
  [ -s "$file" ] && return 0
  echo "== $(basename "$file")" >&2
  "$@" > "$file.part"
  mv "$file.part" "$file"
}
for round in $(seq 1 "$rounds"); do
  for model in mvf naive; do
    for batch in 256 4096; do
      file="$out/torch-$model-$batch-$round.json"
      [ -s "$file" ] && continue
      echo "== $(basename "$file")" >&2
      env -C "$harness" PYTHONPATH="$harness/repo:$harness" "$harness/venv/bin/python" -W ignore \
        bench_train.py --wait-idle --threads 2 --model "$model" --batch-size "$batch" --epochs 6 \
        --loader tensor --out "$file.part" > "$out/torch-$model-$batch-$round.log"
      mv "$file.part" "$file"
    done
  done
  run "$out/graybox-train-$round.jsonl" "$lab" bench train --time-limit 0 --epochs 3
  for batch in 256 4096; do
    run "$out/step-$batch-$round.json" "$lab" bench step --batch-size "$batch"
  done
done
python3 - "$out" <<'PY'
import json, re, statistics, sys
from pathlib import Path
out = Path(sys.argv[1])
def last_json(path):
    for line in reversed(path.read_text().splitlines()):
        line = line.strip()
        if line.startswith("{"):
            return json.loads(line)
    raise SystemExit(f"no JSON in {path}")
torch, ours = {}, {}
for f in out.glob("torch-*.json"):
    _, model, batch, _ = f.stem.split("-")
    v = json.loads(f.read_text())["samples_per_sec"]
    torch.setdefault((model.upper() if model == "mvf" else model, int(batch)), []).append(v)
for f in out.glob("graybox-train-*.jsonl"):
    for line in f.read_text().splitlines():
        r = json.loads(line)
        if r.get("bench") == "train_throughput":
            ours.setdefault((r["model"], r["batch_size"]), []).append(r["samples_per_second"])
print("| model, batch | PyTorch (samples/s) | graybox, 2 threads | ratio |")
print("|---|---|---|---|")
for key in sorted(ours):
    t, g = statistics.median(torch.get(key, [float("nan")])), statistics.median(ours[key])
    print(f"| {key[0]}, {key[1]} | {t:,.0f} | {g:,.0f} | {g / t:.1f}× |")
print()
print("| bench step (1 thread) | forward ms | backward ms | optimizer ms | samples/s |")
print("|---|---|---|---|---|")
for f in sorted(out.glob("step-*.json")):
    r = last_json(f)
    print(f"| {f.stem} | {r['forward_ms']:.2f} | {r['backward_ms']:.2f} | {r['optimizer_ms']:.2f} | {r['samples_per_second']:,.0f} |")
PY
