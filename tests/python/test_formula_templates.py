"""A job whose template is a formula document (README "Your own mechanism") trains over REST
and its model serves Predict, Linearize, Tvlqr and Plan over gRPC; bad documents are 422s
naming the field and the offset."""

import copy
import json
import subprocess
from pathlib import Path

import numpy as np

from graybox_client import Client

ROOT = Path(__file__).resolve().parents[2]
# The README's example, as shipped in examples/templates/.
CARTPOLE = json.loads((ROOT / "examples" / "templates" / "cartpole.json").read_text())


def cartpole(mc, mp, l, g, eta, x):
    """The cart-pole's q̈ written out independently: M q̈ = F − c − ∇V."""
    th, xd, thd, f = x[1], x[2], x[3], x[4]
    m = np.array([[mc + mp, mp * l * np.cos(th)], [mp * l * np.cos(th), mp * l * l]])
    c = np.array([-mp * l * np.sin(th) * thd * thd, 0.0])
    grad_v = np.array([0.0, mp * g * l * np.sin(th)])
    forces = np.array([f + eta * xd, 0.0])
    return np.linalg.solve(m, forces - c - grad_v)


def test_a_job_on_a_formula_template_trains_and_serves(server):
    doc_file = server.tmp / "cartpole.json"
    doc_file.write_text(json.dumps(CARTPOLE))
    data = server.tmp / "cartpole-data.json"
    subprocess.run([server.binary, "simulate", "--template", str(doc_file), "--count", "256",
                    "--seed", "4", "--q-range", "1", "--qdot-range", "1", "--u-std", "5",
                    "--out", str(data)], check=True, capture_output=True)
    status, ds = server.rest.post("/v1/datasets?name=cartpole", raw=data.read_bytes())
    assert status == 201, ds
    status, job = server.rest.post("/v1/jobs", {
        "dataset_id": ds["id"], "model": "W-B", "template": CARTPOLE,
        "init": {"l": 0.5, "mp": 0.6},
        "training": {"epochs": 3, "batch_size": 64, "lr": 0.01}})
    assert status == 201, job
    done = server.rest.wait_job(job["id"])
    assert done["state"] == "succeeded", done
    model_id = done["model_id"]
    status, model = server.rest.get(f"/v1/models/{model_id}")
    assert status == 200 and set(model["metrics"]["physical_parameters"]) == set(CARTPOLE["parameters"])
    values = model["metrics"]["physical_parameters"]

    with Client(server.grpc_target) as c:
        x = np.array([[0.1, 0.3, -0.2, 0.5]])
        u = np.array([[2.0]])
        # One RK4 step with the learned values against the equations written out here; the
        # service computes in f64 (1e-9 covers the different operation order).
        p = c.predict(model_id, x, u)
        dt = ds["dt"]
        args = [values[k] for k in ("mc", "mp", "l", "g", "eta")]
        f = lambda s: np.concatenate([s[2:], cartpole(*args, np.concatenate([s, u[0]]))])
        s0 = x[0]
        k1 = f(s0); k2 = f(s0 + dt / 2 * k1); k3 = f(s0 + dt / 2 * k2); k4 = f(s0 + dt * k3)
        expected = s0 + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        assert np.allclose(p, expected, rtol=1e-9, atol=1e-12), (p, expected)
        a, b = c.linearize(model_id, x, u)
        assert a.shape == (1, 4, 4) and b.shape == (1, 4, 1) and np.isfinite(a).all()
        xbar = np.zeros((11, 4)); ubar = np.zeros((10, 1))
        k, s = c.tvlqr(model_id, xbar, ubar, np.eye(4), np.eye(1), np.eye(4))
        assert k.shape == (10, 1, 4) and np.isfinite(k).all()
        plan = c.plan(model_id, np.zeros(4), [0.2, 0, 0, 0], 100, np.eye(4), 1e-3 * np.eye(1),
                      1e4 * np.eye(4))
        assert plan.x.shape == (101, 4) and np.isfinite(plan.x).all()
        assert plan.cost < plan.costs[0] and plan.goal_error < 0.05, plan.goal_error


def test_bad_formula_templates_are_422s_naming_field_and_offset(server, models):
    def submit(template):
        return server.rest.post("/v1/jobs", {"dataset_id": models.dataset_id, "model": "W-B",
                                             "template": template})
    bad = copy.deepcopy(CARTPOLE)
    bad["mass"][1][1] = "mp*l^2 + theta_dot"
    status, body = submit(bad)
    assert status == 422 and "template.mass[1][1]" in json.dumps(body) and "offset 9" in json.dumps(body), body
    bad = copy.deepcopy(CARTPOLE)
    del bad["forces"]
    status, body = submit(bad)
    assert status == 422 and "forces" in json.dumps(body), body
    status, body = submit(["not", "a", "template"])
    assert status == 422 and "template" in json.dumps(body), body
    # A valid document whose dimensions do not fit the dataset (n = 2, m = 1 vs the double
    # pendulum's m = 2).
    status, body = submit(CARTPOLE)
    assert status == 422, body
