#!/usr/bin/env bash
# The README's plan timings in one sitting (Control: the swing-ups and the UR5 reach, by iLQR
# and by direct collocation, in process and over gRPC), as JSON lines on stdout:
#   - `graybox-lab bench infer`: the paper's swing-up (T = 21 and 200) in process and over
#     gRPC, p50 of 10 calls, with iterations and cost;
#   - the README's own `graybox plan` commands, as a reader runs them (the UR5 reach's only
#     source): the median of five runs' solver seconds, and the iterations and the cost.
# Usage: scripts/plan_figures.sh [BUILD_DIR]   (BUILD_DIR: target/release)
set -euo pipefail
bin=${1:-target/release}
gb=$bin/graybox
lab=$bin/graybox-lab
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT

"$lab" bench infer | grep '_plan_'
"$gb" model --template tests/fixtures/urdf/robots/ur5.urdf --dt 0.01 --out "$dir/ur5.gbx" \
  > /dev/null
"$gb" model --template double_pendulum --dt 0.1 --out "$dir/dp-true.gbx" > /dev/null
for method in ilqr dircol; do
  for run in 1 2 3 4 5; do
    "$gb" plan --model "$dir/dp-true.gbx" --x0 0,0,0,0 --goal 3.14159,0,0,0 --horizon 21 \
      --u-min -120,-120 --u-max 120,120 --method "$method" --out "$dir/swing-up-$run.json" \
      > /dev/null
    "$gb" plan --model "$dir/ur5.gbx" --x0 0,0,0,0,0,0,0,0,0,0,0,0 \
      --goal 0.5,-1,1,0,0.5,0,0,0,0,0,0,0 --horizon 100 --method "$method" \
      --out "$dir/reach-$run.json" > /dev/null
  done
  for plan in swing-up reach; do
    python3 -c 'import json, statistics, sys
runs = [json.load(open(f)) for f in sys.argv[3:]]
p = runs[0]
print(json.dumps({"bench": "graybox_plan_" + sys.argv[1], "method": sys.argv[2],
      "runs": len(runs), "median_seconds": statistics.median(r["seconds"] for r in runs),
      "iterations": p["iterations"], "cost": p["cost"], "converged": p["converged"],
      "goal_error": p["goal_error"]}))' "$plan" "$method" "$dir/$plan"-?.json
  done
done
