#!/usr/bin/env python3
"""Every URDF under a folder (by default example-robot-data's robots, as `pip install
example-robot-data` puts them) through graybox and Pinocchio: does graybox load it, and on the
ones it loads, how far is one RK4 step of graybox's white-box model (`graybox simulate`, the
file's own values) from one RK4 step of Pinocchio's dynamics of the same file with graybox's
joint force law F = u − d q̇ − f tanh(q̇/0.01) (mimic joints by the chain rule)?

Prints a markdown table: robot, coordinates, load error or the one-step mean squared error over
the state and the largest relative difference. Run with Pinocchio installed (`pip install
pin==4.1.0 numpy==2.4.6 example-robot-data==6.0.0`) and a release build:

    python scripts/urdf_survey.py [FOLDER]
"""

import json
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "python"))
from pinocchio_reference import DT, Reference  # noqa: E402  (the tests' reference)

BIN = ROOT / "target" / "release" / "graybox"


def default_folder() -> Path:
    prefix = Path(sys.prefix) / "lib"
    found = sorted(prefix.glob("python3*/site-packages/cmeel.prefix/share/example-robot-data/robots"))
    return found[0]


def survey(path: Path, tmp: Path) -> str:
    text = path.read_text()
    gbx, data = tmp / "m.gbx", tmp / "d.json"
    r = subprocess.run([BIN, "model", "--template", path, "--dt", str(DT), "--out", gbx],
                       capture_output=True, text=True)
    if r.returncode != 0:
        why = r.stderr.strip().split("urdf: ", 1)[-1][:160]
        return f"| {path.stem} | – | refused: {why} |"
    info = json.loads(subprocess.run([BIN, "inspect", "--model", gbx], capture_output=True,
                                     text=True, check=True).stdout)
    subprocess.run([BIN, "simulate", "--template", path, "--count", "8", "--seed", "1",
                    "--dt", str(DT), "--q-range", "1", "--qdot-range", "1", "--u-std", "0.5",
                    "--out", data], capture_output=True, check=True)
    d = json.loads(data.read_text())
    coords = info["coordinates"]
    kinds = {j.get("name"): j.get("type") for j in ET.fromstring(text).findall("joint")}
    # Only the actuated joints take an input; graybox's inputs are in coordinate order.
    inputs = [coords.index(j) for j in info["inputs"]]
    try:
        ref = Reference(text, coords, [kinds[c] for c in coords])
    except Exception as e:  # Pinocchio refuses the file
        return f"| {path.stem} | {len(coords)} | Pinocchio refuses it: {str(e)[:120]} |"
    errs, rel = [], 0.0
    for q, qd, u, qn, qdn in zip(d["q"], d["qdot"], d["u"], d["q_next"], d["qdot_next"]):
        full = np.zeros(len(coords))
        full[inputs] = u
        want = ref.rk4(np.array(q + qd), full)
        got = np.array(qn + qdn)
        errs.append(np.mean((got - want) ** 2))
        rel = max(rel, np.abs(got - want).max() / max(1.0, np.abs(want).max()))
    return f"| {path.stem} | {len(coords)} | one-step MSE {max(errs):.1e}, max relative {rel:.1e} |"


def main():
    folder = Path(sys.argv[1]) if len(sys.argv) > 1 else default_folder()
    print("| robot | coordinates | graybox vs Pinocchio |\n|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for path in sorted(folder.rglob("*.urdf")):
            print(survey(path, Path(tmp)), flush=True)


if __name__ == "__main__":
    main()
