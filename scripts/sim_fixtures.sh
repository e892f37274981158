#!/usr/bin/env bash
# The simulated trajectories tests/python/test_simulate.py holds `graybox simulate` to, bit for
# bit: written by the graybox before `--substeps` existed, so that one substep (the default)
# stays the data it always made. Keeps the file that is there (delete it to record again,
# which makes the check compare a build with itself).
#   GRAYBOX=target/release/graybox bash scripts/sim_fixtures.sh
set -euo pipefail
cd "$(dirname "$0")/.."
graybox=${GRAYBOX:-target/release/graybox}
out=tests/fixtures/sim/dp-trajectories-seed7.json
if [ -e "$out" ]; then
  echo "$out exists; delete it to record it again" >&2
  exit 0
fi
mkdir -p "$(dirname "$out")"
"$graybox" simulate --template double_pendulum --trajectories 3 --steps 20 --seed 7 --out "$out"
