"""Writes pendulum.csv, the log the README's "Robot logs" example imports: a pendulum (the
built-in template at its default values) driven by inputs held for 0.3 s, recorded as a robot's
logger records it: positions only, every 4, 5 or 6 ms (jittered by 20 %), every 41st position
missing, the logger paused for 0.3 s after t = 2 s, and a text column beside the numbers.

    python3 examples/logs/make_pendulum_log.py target/release/graybox

The motion comes from `graybox simulate` at 1 ms (RK4 at 0.1 ms); the log samples its states.
"""

import json
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main(graybox: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        fine = Path(tmp) / "fine.json"
        subprocess.run([graybox, "simulate", "--template", "pendulum", "--trajectories", "1",
                        "--steps", "4000", "--dt", "0.001", "--hold", "300", "--substeps", "10",
                        "--u-std", "3", "--q-range", "1", "--qdot-range", "1", "--seed", "7",
                        "--out", str(fine)], check=True, capture_output=True)
        traj = json.loads(fine.read_text())["trajectories"][0]
    q, u = traj["q"], traj["u"]
    lines, k, rows = ["time,mode,theta,tau"], 0, 0
    while k < len(u):
        t = k * 1e-3
        if not 2.0 <= t < 2.3:
            theta = "" if rows % 41 == 20 else f"{q[k][0]:.9f}"
            lines.append(f"{t:.3f},run,{theta},{u[k][0]:.6f}")
            rows += 1
        k += 4 + rows % 3
    (HERE / "pendulum.csv").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main(sys.argv[1])
