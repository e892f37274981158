#!/usr/bin/env bash
# Start-up of `graybox model` and `graybox eval` (one row) per URDF robot, against its number
# of coordinates: the time from reading the file to the first answer, which grows with the
# joints. Usage: scripts/urdf_startup.sh ROBOT.urdf… (default: the vendored real robots).
# Prints one markdown row per robot: coordinates, model s, eval s (median of 3 runs each).
set -euo pipefail
cd "$(dirname "$0")/.."
bin=target/release/graybox
[ -x "$bin" ] || cargo build --release --offline
files=("$@")
[ ${#files[@]} -gt 0 ] || files=(tests/fixtures/urdf/robots/*.urdf)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
median() { sort -n | sed -n 2p; }
seconds() {
  local s e
  s=$(date +%s.%N)
  "$@" >/dev/null 2>"$tmp/err" || { cat "$tmp/err" >&2; exit 1; }
  e=$(date +%s.%N)
  echo "scale=3; ($e - $s) / 1" | bc
}
echo "| robot | coordinates | graybox model (s) | graybox eval, 1 row (s) |"
echo "|---|---|---|---|"
for f in "${files[@]}"; do
  name=$(basename "$f" .urdf)
  "$bin" model --template "$f" --dt 0.01 --out "$tmp/m.gbx" >"$tmp/model.json"
  n=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['n'])" "$tmp/model.json")
  "$bin" simulate --template "$f" --count 1 --dt 0.01 --q-range 1 --qdot-range 1 --u-std 0.1 \
    --out "$tmp/d.json" >/dev/null
  model=$(for _ in 1 2 3; do seconds "$bin" model --template "$f" --dt 0.01 --out "$tmp/m.gbx"; done | median)
  eval=$(for _ in 1 2 3; do seconds "$bin" eval --model "$tmp/m.gbx" --data "$tmp/d.json"; done | median)
  echo "| $name | $n | $model | $eval |"
done
