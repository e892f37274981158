#!/usr/bin/env bash
# The energy report's figures for models trained on the paper's double pendulum data
# (README "Energy and power"): W-B, MVB and MVF (and any model named in MODELS), trained with
# `graybox train` on the paper's sampling, the energy report each training wrote into its
# report (on its training rows), and a table of them in OUT/results.md. Resumable: a model
# whose report exists is not trained again. Usage:
#   scripts/energy_table.sh OUT [BUILD_DIR]
# (EPOCHS, default 500; MODELS, default "W-B MVB MVF"; SPEC_<NAME>: a JSON spec file for a
# model that is not a named one.)
set -euo pipefail
out=${1:?an output directory}
bin=${2:-target/release}
gb=$bin/graybox
epochs=${EPOCHS:-500}
models=${MODELS:-W-B MVB MVF}
mkdir -p "$out"
data=$out/data.json
# The paper's sampling (q ~ U(−π, π), q̇ ~ U(−10, 10), u ~ N(0, 120²)), 4096 transitions.
[ -f "$data" ] || "$gb" simulate --template double_pendulum --count 4096 --seed 0 --out "$data" > /dev/null
for name in $models; do
  file=$(echo "$name" | tr 'A-Z' 'a-z' | tr -d -)
  [ -f "$out/$file-report.json" ] && continue
  spec_var="SPEC_$(echo "$file" | tr 'a-z' 'A-Z')"
  model_args=(--model "$name")
  [ -n "${!spec_var:-}" ] && model_args=(--spec "${!spec_var}")
  # White-box values start off the truth (the template's defaults), as in the paper.
  init=()
  [ "$name" = W-B ] && init=(--init m1=8,m2=12,l1=0.8,l2=1.2,b1=0.8,b2=1.2,eta1=-0.3,eta2=-0.7)
  "$gb" train --data "$data" "${model_args[@]}" --template double_pendulum "${init[@]}" \
    --epochs "$epochs" --batch-size 256 --lr 1e-3 --seed 0 --out "$out/$file.gbx" \
    --report "$out/$file-report.json.part" 2> "$out/$file-train.log" > /dev/null
  mv "$out/$file-report.json.part" "$out/$file-report.json"
done
python3 - "$out" $models <<'PY'
import json, sys
from pathlib import Path
out, names = Path(sys.argv[1]), sys.argv[2:]
rows = ["| model | best val loss | drift 100 steps (median / max) | drift 1000 steps (median / max) | diverged | creates energy in | largest injected power |",
        "|---|---|---|---|---|---|---|"]
pct = lambda v: "–" if v is None else (f"{100 * v:.2g} %")
for name in names:
    f = name.lower().replace("-", "")
    if not (out / f"{f}-report.json").exists():
        continue
    r = json.loads((out / f"{f}-report.json").read_text())
    e = r["energy"]
    d100, d1000 = e["drift"]
    p = e["passivity"]
    rows.append(f"| {name} | {r['best_val_loss']:.3g} | {pct(d100['median'])} / {pct(d100['max'])} | "
                f"{pct(d1000['median'])} / {pct(d1000['max'])} | {d1000['diverged']} of {e['rollouts']} | "
                f"{100 * p['share']:.1f} % of {p['states']} | {p['max_power']:.3g} |")
(out / "results.md").write_text("# Energy reports on the paper's double pendulum\n\n" + "\n".join(rows) + "\n")
print("\n".join(rows))
PY
