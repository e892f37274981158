#!/usr/bin/env bash
# Before/after speed of the robots' paths in one sitting: `bench multibody` (beside Pinocchio's
# C++ when scripts/pinocchio_cpp/build.sh has built it; only the first binary named runs it),
# `bench infer --model` of a UR5 and an iiwa model file, and W-B training on the UR5 at batch
# 256 and 2048, each lab binary in turn round by round so that drift of this shared machine
# falls on all of them alike. Resumable: a run whose output exists is skipped. Prints each
# figure's per-round values, best round and median, and the ratio of each binary's best to
# the first's.
#
#   scripts/bench_robots.sh OUT_DIR ROUNDS NAME=LAB_BINARY [NAME=LAB_BINARY ...]
#   e.g. scripts/bench_robots.sh /tmp/robots 4 after=target/release/graybox-lab before=/tmp/lab-old
set -euo pipefail
cd "$(dirname "$0")/.."
out=$1 rounds=$2
shift 2
first=${1%%=*}
mkdir -p "$out"
graybox=${GRAYBOX_BIN:-target/release/graybox}
for r in ur5 iiwa; do
  [ -s "$out/$r.gbx" ] || "$graybox" model --template "tests/fixtures/urdf/robots/$r.urdf" \
    --dt 0.01 --out "$out/$r.gbx" > /dev/null
done
run() {
  local file=$out/$1.jsonl
  shift
  [ -s "$file" ] && return
  echo "== $(basename "$file")" >&2
  "$@" > "$file.part"
  mv "$file.part" "$file"
}
for round in $(seq 1 "$rounds"); do
  for pair in "$@"; do
    name=${pair%%=*} bin=${pair#*=}
    pin=()
    [ "$name" = "$first" ] || pin=(--pinocchio-bench /nonexistent)
    for r in ur5 iiwa; do
      run "multibody-$name-$r-$round" "$bin" bench multibody \
        --urdf "tests/fixtures/urdf/robots/$r.urdf" "${pin[@]}"
      run "infer-$name-$r-$round" "$bin" bench infer --model "$out/$r.gbx" --calls 5000 --rounds 1
    done
    run "train-$name-$round" "$bin" bench train --template tests/fixtures/urdf/robots/ur5.urdf \
      --models W-B --batch-sizes 256,2048 --time-limit 0
  done
done
python3 - "$out" "$@" <<'EOF'
import collections, glob, json, os, statistics, sys
out, names = sys.argv[1], [p.split("=", 1)[0] for p in sys.argv[2:]]
fig = collections.defaultdict(lambda: collections.defaultdict(list))
for path in sorted(glob.glob(os.path.join(out, "*.jsonl"))):
    kind, name, *rest = os.path.basename(path)[:-6].split("-")
    robot = rest[0] if kind != "train" else "ur5"
    for line in open(path):
        r = json.loads(line)
        if kind == "train" and "samples_per_second" in r:
            fig[("train W-B samples/s", robot, f"batch {r['batch_size']}")][name].append(
                r["samples_per_second"])
        elif "p50_us" in r and r.get("p50_us") is not None:
            fig[(f"{kind} µs (p50)", robot, r["bench"])][name].append(r["p50_us"])
# Interference from other load only ever adds time, so each binary's best round (least µs,
# most samples/s) is the figure compared; the median beside it shows the spread.
print("| figure | robot | what | " + " | ".join(f"{n}: rounds (best; median)" for n in names)
      + " | " + " | ".join(f"{n}/{names[0]} (best)" for n in names[1:]) + " |")
print("|---" * (3 + 2 * len(names) - 1) + "|")
for key in sorted(fig):
    per_second = key[0].startswith("train")
    cells, best = [], {}
    for n in names:
        v = fig[key].get(n, [])
        best[n] = (max(v) if per_second else min(v)) if v else None
        cells.append(", ".join(f"{x:.4g}" for x in v)
                     + (f" (**{best[n]:.4g}**; {statistics.median(v):.4g})" if v else ""))
    ratios = [f"{best[n] / best[names[0]]:.2f}" if best[n] and best[names[0]] else ""
              for n in names[1:]]
    print(f"| {key[0]} | {key[1]} | {key[2]} | " + " | ".join(cells) + " | "
          + " | ".join(ratios) + " |")
EOF
