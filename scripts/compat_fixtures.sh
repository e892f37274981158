#!/usr/bin/env bash
# Writes the missing files of tests/fixtures/compat: model files and a database written by the
# graybox that built $GRAYBOX_BIN (default target/release/graybox), which later versions must
# keep reading (tests/suite/compat.rs). Files already there are an earlier version's and are kept:
# delete one only to capture it again on purpose, never to make a test pass. Run it to capture
# a new format version (add its file below and to tests/suite/compat.rs's MODELS first). The files
# here predate the model file's checksum: they are what a reader loads with a warning.
#  - mvf.gbx, wb.gbx, naive.gbx: three trained models (2 epochs on simulated data);
#  - wb-x3.gbx: a W-B ensemble of 3 members (graybox.model/3);
#  - expected.json: their Predict and Linearize outputs at fixed points, written by
#    tests/suite/compat.rs in its generator mode (GRAYBOX_WRITE_COMPAT=1) with this version's code
#    for the models it has none for;
#  - running.db: a database whose MVF job was killed (-9) while running, after a checkpoint.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${GRAYBOX_BIN:-target/release/graybox}
out=tests/fixtures/compat
tmp=$(mktemp -d)
trap 'kill -9 "${pid:-0}" 2>/dev/null || true; rm -rf "$tmp"' EXIT

"$bin" simulate --system double_pendulum --count 256 --seed 0 --out "$tmp/train.json" > /dev/null
for spec in mvf:MVF:1 wb:W-B:1 naive:naive:1 wb-x3:W-B:3; do
  IFS=: read -r name model members <<< "$spec"
  [ -e "$out/$name.gbx" ] && continue
  "$bin" train --data "$tmp/train.json" --model "$model" --template double_pendulum \
    --epochs 2 --batch-size 64 --ensemble "$members" --out "$out/$name.gbx" > /dev/null 2>&1
done
GRAYBOX_WRITE_COMPAT=1 cargo test --release -p graybox --test suite -- --exact compat::models_predict_as_they_did > /dev/null

[ -e "$out/running.db" ] && { echo "kept $out/running.db"; exit 0; }

db="$tmp/running.db"
port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
http=$(port); grpc=$(port)
"$bin" serve --db "$db" --http "127.0.0.1:$http" --grpc "127.0.0.1:$grpc" --checkpoint-every 1 \
  --lease-secs 2 > "$tmp/serve.log" 2>&1 &
pid=$!
until curl -sf "localhost:$http/healthz" > /dev/null; do sleep 0.2; done
field() { python3 -c 'import json,sys; print(json.load(sys.stdin)[sys.argv[1]])' "$1"; }
ds=$(curl -sf -X POST "localhost:$http/v1/datasets?name=compat" -H 'content-type: application/json' \
  --data-binary @"$tmp/train.json" | field id)
job=$(curl -sf -X POST "localhost:$http/v1/jobs" -H 'content-type: application/json' \
  -d "{\"dataset_id\": \"$ds\", \"model\": \"MVF\", \"training\": {\"epochs\": 60, \"batch_size\": 64}}" | field id)
until [ "$(curl -sf "localhost:$http/v1/jobs/$job" | field checkpoint_epoch)" -ge 2 ]; do sleep 0.1; done
kill -9 "$pid"
wait "$pid" 2>/dev/null || true
# Fold the write-ahead log into the file so that one file is the whole database.
python3 -c 'import sqlite3, sys; c = sqlite3.connect(sys.argv[1]); c.execute("PRAGMA wal_checkpoint(TRUNCATE)"); c.close()' "$db"
cp "$db" "$out/running.db"
echo "$job" > "$out/running.job"
echo "wrote $out: $(ls "$out" | tr '\n' ' ')"
