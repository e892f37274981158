"""Which swing-up the model-based RL loop's plans are, once the model is right along them.

Reads the `cells.jsonl` of `graybox-lab experiment mbrl` runs and prints, per model and seed:
the first episode whose model error along the plan (`detail.model_error`, RMS of
‖f_model − f_true‖ over the plan's steps) is below ACCURATE, and how the accurate episodes
split between the two swing-ups the planners find on the true model: the cheap one (iLQR's
reference, task cost ≈ 118, score ≈ 1.63 m) and the DIRCOL reference's (cost ≈ 141, score
≈ 1.36 m). With an accurate model the plan's cost on the model is its cost on the system, so
this tells the planner's choice apart from the model's error.

    python3 scripts/mbrl_optima.py experiments/mbrl-dircol experiments/mbrl-dircol-periodic
"""

import json
import sys
from collections import defaultdict
from pathlib import Path

# rad and rad/s together: far below the errors along the plans that fail (their means are
# 6–14 in the runs' "Where the plans part from the system" tables), ten times those of
# settled models (≈ 0.01).
ACCURATE = 0.1
# Between the two optima's costs (≈ 118 and ≈ 141, the true model's references).
SPLIT = 130.0


def cells(run: Path) -> dict:
    lines = (run / "cells.jsonl").read_text().splitlines()
    return {c["key"]: c["value"] for c in map(json.loads, lines)}


def main(runs: list[str]) -> None:
    print("| run | model | seed | first accurate episode | accurate | cheap (cost, score) | "
          "DIRCOL's (cost, score) |")
    print("|---|---|---|---|---|---|---|")
    for run in map(Path, runs):
        by_run = defaultdict(list)
        for key, v in cells(run).items():
            if "/episode" in key and v.get("detail") and v.get("plan_cost") is not None:
                by_run[(v["model"], v["seed"])].append(v)
        for (model, seed), eps in by_run.items():
            eps.sort(key=lambda e: e["episode"])
            good = [e for e in eps if (e["detail"]["model_error"] or 1e9) < ACCURATE]
            first = good[0]["episode"] if good else "none"

            def span(part: list) -> str:
                if not part:
                    return "–"
                cost = [e["plan_cost"] for e in part]
                score = [e["score"] for e in part]
                return (f"{len(part)}: {min(cost):.0f}–{max(cost):.0f}, "
                        f"{min(score):.2f}–{max(score):.2f} m")

            cheap = [e for e in good if e["plan_cost"] < SPLIT]
            dear = [e for e in good if e["plan_cost"] >= SPLIT]
            print(f"| {run.name} | {model} | {seed} | {first} | {len(good)} of {len(eps)} | "
                  f"{span(cheap)} | {span(dear)} |")


if __name__ == "__main__":
    main(sys.argv[1:])
