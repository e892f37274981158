#!/usr/bin/env bash
# Before/after of `bench multibody` (Predict, Linearize, q̈ and its derivatives, the adjoint, the
# f64 passes) for the UR5 and the iiwa in many short rounds, the binaries alternating within
# each round. On a shared machine whose neighbours now and then slow a whole run by up to 2×,
# the least of many short rounds is a steadier figure than the best of three long ones
# (scripts/bench_robots.sh, which also covers `bench infer` and training). Resumable: a run
# whose output exists is skipped. Prints, per figure, each binary's least and lower-quartile
# p50 over the rounds and their ratios to the first binary's.
#
#   scripts/bench_multibody_ab.sh OUT_DIR ROUNDS NAME=LAB_BINARY [NAME=LAB_BINARY ...]
#   e.g. scripts/bench_multibody_ab.sh /tmp/ab 16 before=/tmp/lab-old after=target/release/graybox-lab
set -euo pipefail
cd "$(dirname "$0")/.."
out=$1 rounds=$2
shift 2
mkdir -p "$out"
for round in $(seq 1 "$rounds"); do
  for r in ur5 iiwa; do
    for pair in "$@"; do
      name=${pair%%=*} bin=${pair#*=} file=$out/$name-$r-$round.jsonl
      [ -s "$file" ] && continue
      "$bin" bench multibody --urdf "tests/fixtures/urdf/robots/$r.urdf" --calls 4000 \
        --pinocchio-bench /nonexistent > "$file.part"
      mv "$file.part" "$file"
    done
  done
done
python3 - "$out" "$@" <<'EOF'
import collections, glob, json, os, sys
out, names = sys.argv[1], [p.split("=", 1)[0] for p in sys.argv[2:]]
fig = collections.defaultdict(lambda: collections.defaultdict(list))
for path in glob.glob(os.path.join(out, "*.jsonl")):
    name, robot, _ = os.path.basename(path)[:-6].rsplit("-", 2)
    for line in open(path):
        r = json.loads(line)
        if r.get("p50_us") is not None:
            fig[(robot, r["bench"])][name].append(r["p50_us"])
print("| robot | figure (p50 µs) | " + " | ".join(f"{n}: least; lower quartile" for n in names)
      + " | " + " | ".join(f"{n}/{names[0]}: least; lower quartile" for n in names[1:]) + " |")
print("|---" * (2 + 2 * len(names) - 1) + "|")
for key in sorted(fig):
    q = {}
    for n in names:
        v = sorted(fig[key].get(n, []))
        q[n] = (v[0], v[len(v) // 4]) if v else None
    cells = [f"{q[n][0]:.4g}; {q[n][1]:.4g}" if q[n] else "" for n in names]
    ratios = [f"{q[n][0] / q[names[0]][0]:.3f}; {q[n][1] / q[names[0]][1]:.3f}"
              if q[n] and q[names[0]] else "" for n in names[1:]]
    print(f"| {key[0]} | {key[1]} | " + " | ".join(cells) + " | " + " | ".join(ratios) + " |")
EOF
