#!/usr/bin/env python3
"""Issue 28, item 5 end to end: a UR5 identified on data whose best fit has negative damping
(the joints give energy: τ = u + 0.2 q̇) exports a URDF that Pinocchio loads, with every
`<dynamics>` value ≥ 0 (bench-results/2026-11-26-coulomb-stiffness.md).

The data is written by Pinocchio (ABA, RK4 in 10 substeps per Δt = 0.01 s, 1024 transitions
from q ~ U(−1, 1), q̇ ~ U(−2, 2), u ~ N(0, 1)); graybox trains W-B on it from the file's values
(damping and friction 0), exports the URDF, and `scripts/pinocchio_load.py` loads it. Before
damping and friction were kept ≥ 0 the identified values came out negative and Pinocchio
refused the export. Offline, with Pinocchio and a release build:

    python scripts/negative_damping_export.py [--graybox target/release/graybox] [--epochs 20]
"""

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pinocchio as pin

HERE = Path(__file__).resolve().parent
GIVEN = -0.2  # the "true" damping: energy in, which no physical damping explains


def ur5() -> str:
    prefix = next(p for p in Path(pin.__file__).resolve().parents if p.name == "cmeel.prefix")
    return str(prefix / "share/example-robot-data/robots/ur_description/urdf/ur5_robot.urdf")


def data(urdf: Path, count=1024, dt=0.01, sub=10, seed=0) -> dict:
    model = pin.buildModelFromUrdf(str(urdf))
    d = model.createData()
    rng = np.random.default_rng(seed)
    acc = lambda q, v, u: pin.aba(model, d, q, v, u - GIVEN * v)
    out = {k: [] for k in ("q", "qdot", "u", "q_next", "qdot_next")}
    for _ in range(count):
        q0, v0 = rng.uniform(-1, 1, model.nq), rng.uniform(-2, 2, model.nv)
        u = rng.normal(0, 1, model.nv)
        q, v, h = q0.copy(), v0.copy(), dt / sub
        for _ in range(sub):
            k1q, k1v = v, acc(q, v, u)
            k2q, k2v = v + h / 2 * k1v, acc(q + h / 2 * k1q, v + h / 2 * k1v, u)
            k3q, k3v = v + h / 2 * k2v, acc(q + h / 2 * k2q, v + h / 2 * k2v, u)
            k4q, k4v = v + h * k3v, acc(q + h * k3q, v + h * k3v, u)
            q = q + h / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
            v = v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        for k, x in zip(out, (q0, v0, u, q, v)):
            out[k].append(x.tolist())
    return {"dt": dt, **out}


def run(*args) -> str:
    r = subprocess.run([str(a) for a in args], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"{' '.join(map(str, args))} failed: {r.stderr}")
    return r.stdout


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--graybox", default=str(HERE.parent / "target/release/graybox"))
    ap.add_argument("--urdf", default=ur5())
    ap.add_argument("--epochs", type=int, default=20)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "d.json").write_text(json.dumps(data(Path(a.urdf))))
        report = json.loads(run(a.graybox, "train", "--data", tmp / "d.json", "--template", a.urdf,
                                "--model", "W-B", "--epochs", a.epochs, "--batch-size", 256,
                                "--lr", "1e-2", "--out", tmp / "m.gbx"))
        joint = {k: v for k, v in report["physical_parameters"].items()
                 if k.endswith((".damping", ".friction"))}
        print(json.dumps({"learned": joint, "best_val_loss": report["best_val_loss"]}))
        run(a.graybox, "export-urdf", "--model", tmp / "m.gbx", "--out", tmp / "identified.urdf")
        check = subprocess.run([sys.executable, HERE / "pinocchio_load.py", tmp / "identified.urdf"],
                               capture_output=True, text=True)
        print(check.stdout.strip())
        ok = check.returncode == 0 and all(v >= 0 for v in joint.values())
        print("ok" if ok else "FAILED")
        sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
