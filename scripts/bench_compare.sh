#!/usr/bin/env bash
# Before/after benchmarks in one sitting: `bench train --time-limit 0` and `bench infer` of
# each lab binary (graybox-lab; a build from before the lab was its own crate: graybox), alternated round by round so that drift of the machine (heat,
# other load) falls on all of them alike; then `bench step` under callgrind (instruction
# counts, which do not drift). Resumable: a run whose output file exists is skipped, so an
# interrupted sitting continues where it stopped. Prints the medians table at the end.
#
#   scripts/bench_compare.sh OUT_DIR ROUNDS NAME=BINARY [NAME=BINARY ...]
#   e.g. scripts/bench_compare.sh /tmp/cmp 3 before=/tmp/lab-before after=target/release/graybox-lab
set -euo pipefail
out=$1 rounds=$2
shift 2
mkdir -p "$out"
for round in $(seq 1 "$rounds"); do
  for pair in "$@"; do
    name=${pair%%=*} bin=${pair#*=}
    for kind in train infer; do
      file="$out/$kind-$name-$round.jsonl"
      [ -s "$file" ] && continue
      args=()
      [ "$kind" = train ] && args=(--time-limit 0)
      echo "== round $round: $name bench $kind" >&2
      "$bin" bench "$kind" "${args[@]}" > "$file.part"
      mv "$file.part" "$file"
    done
  done
done
if command -v valgrind > /dev/null; then
  for pair in "$@"; do
    name=${pair%%=*} bin=${pair#*=}
    file="$out/step-callgrind-$name.txt"
    [ -s "$file" ] && continue
    echo "== $name bench step under callgrind" >&2
    valgrind --tool=callgrind --callgrind-out-file="$out/callgrind.$name" \
      "$bin" bench step --steps 20 > /dev/null 2> "$file.part"
    mv "$file.part" "$file"
  done
fi
python3 - "$out" "$@" <<'EOF'
import json, re, statistics, sys
from pathlib import Path
out, names = Path(sys.argv[1]), [p.split("=", 1)[0] for p in sys.argv[2:]]
def figures(name):
    per = {}
    for f in sorted(out.glob(f"*-{name}-*.jsonl")):
        for line in f.read_text().splitlines():
            r = json.loads(line)
            if "samples_per_second" in r and "batch_size" in r:
                key, v = f"train {r['model']} batch {r['batch_size']} (samples/s)", r["samples_per_second"]
            elif "requests_per_second" in r:
                key, v = f"{r['bench']} (req/s)", r["requests_per_second"]
            elif "p50_us" in r:
                key, v = f"{r['bench']} p50 µs", r["p50_us"]
            else:
                continue
            per.setdefault(key, []).append(v)
    return per
cols = {n: figures(n) for n in names}
keys = list(dict.fromkeys(k for n in names for k in cols[n]))
print("| figure | " + " | ".join(f"{n} (median of {len(next(iter(cols[n].values()), []))})" for n in names)
      + (f" | {names[-1]}/{names[0]} |" if len(names) > 1 else " |"))
print("|---" * (len(names) + 1 + (len(names) > 1)) + "|")
for k in keys:
    meds = [statistics.median(cols[n][k]) if k in cols[n] else float("nan") for n in names]
    ratio = f" | {meds[-1] / meds[0]:.3f}" if len(names) > 1 and meds[0] else ""
    print(f"| {k} | " + " | ".join(f"{m:,.1f}" for m in meds) + ratio + " |")
for n in names:
    f = out / f"step-callgrind-{n}.txt"
    if f.exists():
        m = re.search(r"Collected : (\d+)", f.read_text())
        print(f"callgrind bench step --steps 20, {n}: {int(m.group(1)):,} instructions" if m else f"{n}: no count")
EOF
