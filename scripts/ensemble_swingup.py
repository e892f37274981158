"""The paper's swing-up planned on MVF x5 ensembles (members on bootstrap resamples, and on all
the data from their own seeds), on their mean dynamics and on their members' average cost
(`--ensemble-cost mean`), beside one MVF trained on the same 2048 random transitions; each plan tracked by its own TVLQR gains on an independent RK4 of the true system
(the closed form of tests/python/dp_reference.py), as scripts/dircol_learned.py does.

Usage (from the repository's root, after `cargo build --release`):
    .venv/bin/python scripts/ensemble_swingup.py [--out experiments/ensemble-swingup]
        [--epochs 3000] [--bin target/release/graybox]

The single MVF is experiments/dircol-learned's (the same data, seed and epochs). Steps whose
outputs exist in --out are not run again (a killed run resumes); results.json and results.md
are written at the end.
"""

import argparse
import json
from pathlib import Path

import numpy as np

from dircol_learned import DT, GOAL, HORIZON, U_MAX, plan, run, track, true_system

UPRIGHT_ANGLE, UPRIGHT_SPEED = 0.05, 0.2


def main():
    a = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    a.add_argument("--out", type=Path, default=Path("experiments/ensemble-swingup"))
    a.add_argument("--single", type=Path, default=Path("experiments/dircol-learned"))
    a.add_argument("--epochs", type=int, default=3000)
    a.add_argument("--bin", default="target/release/graybox")
    args = a.parse_args()
    out, gb = args.out, args.bin
    out.mkdir(parents=True, exist_ok=True)
    _, params = true_system(gb, out)
    data = out / "data.json"
    run([gb, "simulate", "--system", "double_pendulum", "--count", "2048", "--dt", str(DT),
         "--seed", "0", "--out", str(data)], data)
    cases = [(args.single / "mvf.gbx", "MVF", "")]
    for ens, name, flags in [(out / "mvf-x5.gbx", "MVF x5, bootstrap", []),
                             (out / "mvf-x5-nb.gbx", "MVF x5, all data", ["--no-bootstrap"])]:
        run([gb, "train", "--data", str(data), "--model", "MVF", "--epochs", str(args.epochs),
             "--batch-size", "256", "--lr", "1e-3", "--patience", "300", "--seed", "0",
             "--ensemble", "5", *flags, "--out", str(ens)], ens)
        cases += [(ens, name, cost) for cost in ("mean_dynamics", "mean")]
    rows = []
    for model, name, cost in cases:
        for method, restarts in [("ilqr", 0), ("ilqr", 8), ("dircol", 0), ("dircol", 8)]:
            tag = f"{model.stem}-{cost or 'single'}-{method}-{restarts}"
            extra = ["--ensemble-cost", cost] if cost else []
            p = plan(gb, model, method, restarts, out / f"plan-{tag}.json", extra)
            end = track(p, params)
            std_end = np.array(p["x_std"][-1]) if "x_std" in p else None
            rows.append({
                "model": name, "ensemble_cost": cost, "method": method, "restarts": restarts,
                "cost": p["cost"], "converged": p["converged"], "seconds": p["seconds"],
                "planned_end": p["x"][-1], "planned_end_std": None if std_end is None else
                std_end.tolist(), "tracked_end": end.tolist(),
                "tracked_angle_error": float(np.max(np.abs(end[:2] - GOAL[:2]))),
                "tracked_speed": float(np.max(np.abs(end[2:]))),
            })
    (out / "results.json").write_text(json.dumps(rows, indent=1))
    write_markdown(out, rows)


def write_markdown(out: Path, rows: list):
    lines = ["# Swing-up plans on an ensemble, tracked on the true system", "",
             f"T = {HORIZON}, Δt = {DT}, |u| ≤ {U_MAX}, from rest, u_init = 0; each plan tracked "
             "by its own TVLQR gains on the closed-form RK4 of the true double pendulum. "
             f"Upright: angle error < {UPRIGHT_ANGLE} rad and speed < {UPRIGHT_SPEED} rad/s. "
             "Planned σ at T: the members' largest standard deviation of an angle at the last "
             "step along the plan's inputs (rad).", "",
             "| model | plans on | method | restarts | plan cost | planned σ at T | plan s | "
             "tracked max angle error (rad) | tracked max speed (rad/s) | upright |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        up = r["tracked_angle_error"] < UPRIGHT_ANGLE and r["tracked_speed"] < UPRIGHT_SPEED
        sigma = "" if r["planned_end_std"] is None else f"{max(r['planned_end_std'][:2]):.3g}"
        on = {"": "its dynamics", "mean_dynamics": "mean dynamics",
              "mean": "members' mean cost"}[r["ensemble_cost"]]
        lines.append(f"| {r['model']} | {on} | {r['method']} | {r['restarts']} | "
                     f"{r['cost']:.2f} | {sigma} | {r['seconds']:.2f} | "
                     f"{r['tracked_angle_error']:.3g} | {r['tracked_speed']:.3g} | "
                     f"{'yes' if up else 'no'} |")
    (out / "results.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
