#!/usr/bin/env bash
# The speed figures of URDF models in one sitting (bench-results/*-featherstone.md): graybox's
# `bench infer --model` (the multibody path, and the template assembly it replaced, printed
# beside), the UR5 reach plan as `graybox plan` reports it, and Pinocchio's figures from
# scripts/pinocchio_bench.py. Usage:
#   scripts/urdf_speed.sh PYTHON_WITH_PIN [BUILD_DIR]
# (PYTHON_WITH_PIN: a Python with `pin` installed; BUILD_DIR: where graybox and graybox-lab
# are, target/release.)
set -euo pipefail
py=${1:?a python with pin installed}
bin=${2:-target/release}
gb=$bin/graybox
lab=$bin/graybox-lab
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
robots=tests/fixtures/urdf/robots
for r in ur5 iiwa; do
  # The iiwa's damped light wrist is too stiff for RK4 at 0.01 s (graybox model says so and
  # names 3.5e-3 s): its model steps 0.003 s, which changes no cost per call.
  dt=0.01; [ "$r" = iiwa ] && dt=0.003
  "$gb" model --template "$robots/$r.urdf" --dt "$dt" --out "$dir/$r.gbx" > /dev/null 2>&1
  "$lab" bench infer --model "$dir/$r.gbx"
done
# The reach: q = 0 at rest to (0.5, −1, 1, 0, 0.5, 0) at rest, T = 100, Δt = 0.01,
# Q = diag(1, 0.1), R = 1e-4 I, Q_f = 1000 Q (graybox plan's defaults), u within the URDF's
# effort limits (its default with no bounds given), u_init = 0.
"$gb" plan --model "$dir/ur5.gbx" --x0 0,0,0,0,0,0,0,0,0,0,0,0 \
  --goal 0.5,-1,1,0,0.5,0,0,0,0,0,0,0 --horizon 100 --out "$dir/plan.json" > /dev/null
"$py" -c 'import json, sys; p = json.load(open(sys.argv[1]))
u = max(abs(v) / m for r in p["u"] for v, m in zip(r, p["u_max"]))
print(json.dumps({"bench": "ur5_plan_reach_100", "converged": p["converged"],
      "iterations": p["iterations"], "seconds": p["seconds"], "goal_error": p["goal_error"],
      "max_u_over_effort": u}))' "$dir/plan.json"
"$py" scripts/pinocchio_bench.py "$robots/ur5.urdf" "$robots/iiwa.urdf"
