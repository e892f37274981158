"""Real robots' URDF files (tests/fixtures/urdf/robots: UR5, the Panda with its mimic finger,
Solo 12, a Kinova arm) served by graybox against Pinocchio: a white-box model with changed
masses, damping and friction is exported, the export loads in Pinocchio, and the service's
accelerations and RK4 steps are Pinocchio's dynamics of that export (with graybox's joint
force law written here)."""

import json
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from graybox_client import Client
from pinocchio_reference import DT, Reference

ROBOTS = Path(__file__).resolve().parents[2] / "tests" / "fixtures" / "urdf" / "robots"


def run(server, *args):
    r = subprocess.run([server.binary, *map(str, args)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return r.stdout


@pytest.mark.parametrize("robot", ["ur5", "panda", "solo12", "kinova", "iiwa"])
def test_a_real_robots_export_loads_in_pinocchio_and_is_what_graybox_serves(server, robot):
    urdf = ROBOTS / f"{robot}.urdf"
    gbx, out = server.tmp / f"{robot}.gbx", server.tmp / f"{robot}-export.urdf"
    plain = json.loads(run(server, "model", "--template", urdf, "--dt", DT, "--out", gbx))
    # Other values than the file's: 20 % heavier links, damping and Coulomb friction on every
    # joint (mimic joints included), so that the export has to write them.
    values = plain["physical_parameters"]
    changed = {k: 1.2 * v for k, v in values.items() if k.endswith(".mass") and v > 0}
    changed |= {k: 0.1 for k in values if k.endswith(".damping")}
    changed |= {k: 0.02 for k in values if k.endswith(".friction")}
    sets = ",".join(f"{k}={v!r}" for k, v in changed.items())
    run(server, "model", "--template", urdf, "--dt", DT, "--set", sets, "--out", gbx)
    run(server, "export-urdf", "--model", gbx, "--out", out)
    info = json.loads(run(server, "inspect", "--model", gbx))
    coords = info["coordinates"]
    kinds = {j.get("name"): j.get("type") for j in ET.fromstring(urdf.read_text()).findall("joint")}
    ref = Reference(out.read_text(), coords, [kinds[c] for c in coords])

    status, model = server.rest.post(f"/v1/models?name={robot}", raw=gbx.read_bytes())
    assert status in (200, 201), model
    n, m = info["n"], info["m"]
    rng = np.random.default_rng(28)
    x = np.concatenate([rng.uniform(-1, 1, (6, n)), rng.uniform(-1, 1, (6, n))], axis=1)
    u = rng.normal(0, 1, (6, m))
    with Client(server.grpc_target) as c:
        x_next, accel = c.predict(model["id"], x, u, want_accel=True)
    for k in range(len(x)):
        want = ref.accel(x[k, :n], x[k, n:], u[k])
        # Both are f64 evaluations of the same equations by different algorithms (ABA, or CRBA
        # and a Cholesky solve with mimic joints, in graybox; `crba` and `nonLinearEffects`
        # with numpy's solve in the reference): they agree to rounding,
        # ~1e-12 of the largest term for light wrist links; 1e-8 still catches a wrong mass,
        # frame, sign or friction term (each ≥ 1e-3 relative here).
        scale = max(1.0, np.abs(want).max())
        assert np.abs(accel[k] - want).max() < 1e-8 * scale, (robot, k, accel[k], want)
        step = ref.rk4(x[k], u[k])
        assert np.abs(x_next[k] - step).max() < 1e-8 * max(1.0, np.abs(step).max()), (robot, k)
