"""`graybox simulate --trajectories --substeps K`: the true system integrated by RK4 at Δt/K
and recorded every Δt, as a sensor samples a system that evolves continuously. One substep
(the default) is the data graybox always made, bit for bit (tests/fixtures/sim, written by the
graybox before the option existed: scripts/sim_fixtures.sh); K substeps are K steps of an
independent RK4 (dp_reference, numpy) at Δt/K under the held input."""

import json
import subprocess
from pathlib import Path

import numpy as np

from dp_reference import dp_rk4

ROOT = Path(__file__).resolve().parents[2]
FIXTURE = ROOT / "tests/fixtures/sim/dp-trajectories-seed7.json"


def _simulate(graybox_bin, out, *args):
    done = subprocess.run([graybox_bin, "simulate", "--template", "double_pendulum",
                           "--out", str(out), *map(str, args)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_one_substep_is_the_data_graybox_always_made(graybox_bin, tmp_path):
    for extra in ([], ["--substeps", 1]):
        out = tmp_path / "d.json"
        summary = _simulate(graybox_bin, out, "--trajectories", 3, "--steps", 20, "--seed", 7,
                            *extra)
        assert summary["substeps"] == 1
        assert out.read_bytes() == FIXTURE.read_bytes(), extra


def test_substeps_are_the_true_system_at_the_finer_step(graybox_bin, tmp_path):
    # Parameters set here, so the reference does not depend on the template's defaults.
    p = [1.2, 0.8, 1.0, 0.7, 9.81, 1.0, 0.9, -0.1, -0.05]
    names = ["m1", "m2", "l1", "l2", "g", "b1", "b2", "eta1", "eta2"]
    assignments = ",".join(f"{k}={v}" for k, v in zip(names, p))
    out = tmp_path / "d.json"
    dt, k = 0.05, 50
    _simulate(graybox_bin, out, "--trajectories", 2, "--steps", 10, "--hold", 2, "--dt", dt,
              "--substeps", k, "--qdot-range", 2, "--u-std", 5, "--set", assignments,
              "--seed", 3)
    doc = json.loads(out.read_text())
    assert doc["dt"] == dt
    for t in doc["trajectories"]:
        x = np.hstack([np.array(t["q"]), np.array(t["qdot"])])
        u = np.array(t["u"])
        ref = x[:-1]
        for _ in range(k):
            ref = dp_rk4(p, ref, u, dt / k)
        # Two RK4s of the same equations in another order of operations: rounding apart (here
        # 2e-15 on states of order 1–20 after 50 substeps of 1 ms). 1e-9 is loose for that
        # and far below the ~2e-3 by which one RK4 step of Δt differs (checked next, so that
        # this test tells the two apart).
        np.testing.assert_allclose(x[1:], ref, rtol=0, atol=1e-9)
        coarse = dp_rk4(p, x[:-1], u, dt)
        assert np.abs(coarse - x[1:]).max() > 1e-6
