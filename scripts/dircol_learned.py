"""The paper's swing-up planned by iLQR and by direct collocation, on the true double pendulum
and on an MVF model learned from 2048 random transitions, each plan tracked by its own TVLQR
gains on an independent RK4 of the true system (the closed form of tests/python/dp_reference.py).

Usage (from the repository's root, after `cargo build --release`):
    .venv/bin/python scripts/dircol_learned.py [--out experiments/dircol-learned]
        [--epochs 3000] [--bin target/release/graybox]

Steps whose outputs exist in --out are not run again (a killed run resumes); results.json and
results.md are written at the end.
"""

import argparse
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "python"))
from dp_reference import PARAMS, dp_rk4  # noqa: E402

GOAL = [math.pi, 0.0, 0.0, 0.0]
HORIZON, DT, U_MAX = 21, 0.1, 120.0


def run(cmd, out: Path):
    """`cmd`, which writes `out`, unless `out` exists."""
    if not out.exists():
        subprocess.run(cmd, check=True, capture_output=True, text=True)


def plan(gb, model: Path, method: str, restarts: int, out: Path, extra=()) -> dict:
    """The swing-up planned on `model` (`extra`: more `graybox plan` flags), kept in `out`."""
    run([gb, "plan", "--model", str(model), "--x0", "0,0,0,0",
         "--goal", ",".join(map(str, GOAL)), "--horizon", str(HORIZON),
         "--u-min", f"-{U_MAX},-{U_MAX}", "--u-max", f"{U_MAX},{U_MAX}",
         "--restarts", str(restarts), "--method", method, "--out", str(out), *extra], out)
    return json.loads(out.read_text())


def true_system(gb, out: Path) -> tuple[Path, list]:
    """The true double pendulum's model file in `out`, and its physical values in PARAMS order."""
    true = out / "true.gbx"
    made = subprocess.run([gb, "model", "--template", "double_pendulum", "--dt", str(DT),
                           "--out", str(true)], check=True, capture_output=True, text=True)
    values = json.loads(made.stdout.strip().splitlines()[-1])["physical_parameters"]
    return true, [values[k] for k in PARAMS]


def track(p: dict, params) -> np.ndarray:
    """The plan's law u = ū − K(x − x̄), clipped to the bounds, on the true system's RK4."""
    xbar, ubar, K = np.array(p["x"]), np.array(p["u"]), np.array(p["K"])
    x = xbar[0].copy()
    for t in range(HORIZON):
        u = np.clip(ubar[t] - K[t] @ (x - xbar[t]), -U_MAX, U_MAX)
        x = dp_rk4(params, x[None, :], u[None, :], DT)[0]
    return x


def main():
    a = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    a.add_argument("--out", type=Path, default=Path("experiments/dircol-learned"))
    a.add_argument("--epochs", type=int, default=3000)
    a.add_argument("--bin", default="target/release/graybox")
    args = a.parse_args()
    out, gb = args.out, args.bin
    out.mkdir(parents=True, exist_ok=True)
    true, params = true_system(gb, out)
    data, mvf = out / "data.json", out / "mvf.gbx"
    run([gb, "simulate", "--system", "double_pendulum", "--count", "2048", "--dt", str(DT),
         "--seed", "0", "--out", str(data)], data)
    run([gb, "train", "--data", str(data), "--model", "MVF", "--epochs", str(args.epochs),
         "--batch-size", "256", "--lr", "1e-3", "--patience", "300", "--seed", "0",
         "--out", str(mvf)], mvf)
    rows = []
    for model, name in [(true, "true"), (mvf, "MVF, 2048 transitions")]:
        for method, restarts in [("ilqr", 0), ("ilqr", 8), ("dircol", 0), ("dircol", 8)]:
            p = plan(gb, model, method, restarts, out / f"plan-{model.stem}-{method}-{restarts}.json")
            end = track(p, params)
            rows.append({
                "model": name, "method": method, "restarts": restarts, "cost": p["cost"],
                "converged": p["converged"], "iterations": p["iterations"],
                "seconds": p["seconds"], "planned_goal_error": p["goal_error"],
                "constraint_violation": p["constraint_violation"],
                "rollout_deviation": p["rollout_deviation"],
                "tracked_end": end.tolist(),
                "tracked_angle_error": float(np.max(np.abs(end[:2] - GOAL[:2]))),
                "tracked_speed": float(np.max(np.abs(end[2:]))),
            })
    (out / "results.json").write_text(json.dumps(rows, indent=1))
    lines = ["# Swing-up plans tracked on the true system", "",
             f"T = {HORIZON}, Δt = {DT}, |u| ≤ {U_MAX}, from rest, u_init = 0; each plan tracked "
             "by its own TVLQR gains on the closed-form RK4 of the true double pendulum. "
             "Upright: angle error < 0.05 rad and speed < 0.2 rad/s.", "",
             "| model | method | restarts | plan cost | converged | plan s | tracked max angle "
             "error (rad) | tracked max speed (rad/s) | upright |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        up = r["tracked_angle_error"] < 0.05 and r["tracked_speed"] < 0.2
        lines.append(f"| {r['model']} | {r['method']} | {r['restarts']} | {r['cost']:.2f} | "
                     f"{r['converged']} | {r['seconds']:.2f} | {r['tracked_angle_error']:.3g} | "
                     f"{r['tracked_speed']:.3g} | {'yes' if up else 'no'} |")
    (out / "results.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
