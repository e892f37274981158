"""Energy and power (README "Energy and power"): the white-box double pendulum's and UR5's
energies and every term of their dynamics against independent computations (the pendulum's
rods in numpy, Pinocchio for UR5), over gRPC, REST and the CLI; a naive model's refusal; bad
shapes; admission; and the energy report a finished job stores."""

import json
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from dp_reference import dp_energy, dp_inverse
from graybox_client import Client, GrayboxError
from pinocchio_reference import Reference

ROBOTS = Path(__file__).resolve().parents[2] / "tests" / "fixtures" / "urdf" / "robots"
# Other values than the template's defaults, every one of them used, damping included.
DP = {"m1": 2.0, "m2": 3.0, "l1": 0.7, "l2": 1.1, "g": 9.81, "b1": 1.5, "b2": 0.5,
      "eta1": -0.3, "eta2": -0.2}
TERMS = ("inertial", "coriolis", "gravity", "applied")


def run(server, *args):
    r = subprocess.run([server.binary, *map(str, args)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return r.stdout


def close(got, want):
    """Both sides are f64 evaluations of the same quantities by different formulas: they agree
    to rounding (~1e-13 of the largest term); 1e-9 of the reference's size (at least 1) still
    catches a wrong sign, factor or term, each ≥ 1e-3 relative here. Some terms are exactly 0
    (a vertical axis's gravity torque), hence the floor of 1."""
    got, want = np.asarray(got), np.asarray(want)
    return np.abs(got - want).max() <= 1e-9 * max(1.0, np.abs(want).max())


def upload(server, gbx, name):
    status, model = server.rest.post(f"/v1/models?name={name}", raw=gbx.read_bytes())
    assert status in (200, 201), model
    return model["id"]


def states(rng, b, n, m, qdot=3.0, u=5.0):
    x = np.column_stack([rng.uniform(-np.pi, np.pi, (b, n)), rng.uniform(-qdot, qdot, (b, n))])
    return x, rng.normal(0.0, u, (b, m))


@pytest.fixture(scope="module")
def dp_model(server):
    gbx = server.tmp / "dp-energy.gbx"
    sets = ",".join(f"{k}={v!r}" for k, v in DP.items())
    run(server, "model", "--template", "double_pendulum", "--dt", 0.01, "--set", sets, "--out", gbx)
    return gbx, upload(server, gbx, "dp-energy")


def test_the_double_pendulums_energy_and_terms_are_its_closed_form(server, client, dp_model):
    gbx, model = dp_model
    x, u = states(np.random.default_rng(54), 16, 2, 2)
    got = client.energy(model, x, u)
    want = dp_energy([DP[k] for k in DP], x[:, :2], x[:, 2:], u)
    for key in ("kinetic", "potential", "inertial", "coriolis", "gravity"):
        assert close(got[key], want[key]), key
    assert close(got["parts"]["input"], want["input"])
    assert close(got["parts"]["damping"], want["damping"])
    assert got["damping"] == ["damping"]
    applied = want["input"] + want["damping"]
    assert close(got["applied"], applied)
    assert close(got["total"], want["kinetic"] + want["potential"])
    assert close(got["power"], (x[:, 2:] * applied).sum(1))
    # The equation of motion, term by term.
    assert close(got["inertial"] + got["coriolis"] + got["gravity"], got["applied"])
    # One state alone is that state's row of a batch.
    one = client.energy(model, x[3], u[3])
    assert close(one["kinetic"], got["kinetic"][3]) and close(one["parts"]["input"], got["parts"]["input"][3])

    # REST answers the same numbers.
    status, rest = server.rest.post(f"/v1/models/{model}/energy", {"x": x.tolist(), "u": u.tolist()})
    assert status == 200, rest
    for key in ("kinetic", "potential", "total", "power", *TERMS):
        assert close(rest[key], got[key]), key
    assert [(p["name"], p["damping"]) for p in rest["parts"]] == [("input", False), ("damping", True)]
    assert close(rest["parts"][0]["values"], got["parts"]["input"])

    # And the CLI, from the model file and a dataset of these states.
    data = server.tmp / "dp-energy-states.json"
    q_next = np.zeros((16, 2))
    data.write_text(json.dumps({"dt": 0.01, "q": x[:, :2].tolist(), "qdot": x[:, 2:].tolist(),
                                "u": u.tolist(), "q_next": q_next.tolist(),
                                "qdot_next": q_next.tolist()}))
    lines = [json.loads(l) for l in run(server, "energy", "--model", gbx, "--data", data).splitlines()]
    assert len(lines) == 16
    assert close([l["kinetic"] for l in lines], want["kinetic"])
    assert close([l["parts"]["damping"] for l in lines], want["damping"])


@pytest.fixture(scope="module")
def ur5(server):
    """UR5 with its joints' rotors: `<dynamics armature>` in its file makes each joint's
    armature a parameter, set here to other values than the file's, which the export writes."""
    urdf = server.tmp / "ur5-armature.urdf"
    text = (ROBOTS / "ur5.urdf").read_text()
    urdf.write_text(text.replace('friction="0.0"/>', 'friction="0.0" armature="0.01"/>'))
    gbx = server.tmp / "ur5-energy.gbx"
    plain = json.loads(run(server, "model", "--template", urdf, "--dt", 0.01, "--out", gbx))
    values = plain["physical_parameters"]
    changed = {k: 1.2 * v for k, v in values.items() if k.endswith(".mass") and v > 0}
    changed |= {k: 0.1 for k in values if k.endswith(".damping")}
    changed |= {k: 0.02 for k in values if k.endswith(".friction")}
    rotors = [k for k in values if k.endswith(".armature")]
    assert len(rotors) == 6, values
    changed |= {k: 0.05 * (i + 1) for i, k in enumerate(rotors)}
    sets = ",".join(f"{k}={v!r}" for k, v in changed.items())
    run(server, "model", "--template", urdf, "--dt", 0.01, "--set", sets, "--out", gbx)
    export = server.tmp / "ur5-energy-export.urdf"
    run(server, "export-urdf", "--model", gbx, "--out", export)
    assert export.read_text().count(' armature="') == 6
    info = json.loads(run(server, "inspect", "--model", gbx))
    kinds = {j.get("name"): j.get("type") for j in ET.fromstring(urdf.read_text()).findall("joint")}
    coords = info["coordinates"]
    ref = Reference(export.read_text(), coords, [kinds[c] for c in coords])
    return upload(server, gbx, "ur5-energy"), ref, info["n"], info["m"]


def test_ur5s_energy_and_terms_are_pinocchios(client, ur5):
    model, ref, n, m = ur5
    x, u = states(np.random.default_rng(5), 8, n, m, qdot=1.0, u=1.0)
    got = client.energy(model, x, u)
    assert set(got["parts"]) == {"input", "friction"} and got["damping"] == ["friction"]
    for k in range(len(x)):
        want = ref.energy(x[k, :n], x[k, n:], u[k])
        for key in ("kinetic", "potential", "inertial", "coriolis", "gravity"):
            assert close(got[key][k], want[key]), (key, k, got[key][k], want[key])
        assert close(got["parts"]["friction"][k], want["friction"]), k
        assert close(got["parts"]["input"][k], u[k]), k
        terms = got["inertial"][k] + got["coriolis"][k] + got["gravity"][k]
        assert close(terms, got["applied"][k]), k


@pytest.fixture(scope="module")
def naive_model(server, models):
    status, job = server.rest.post("/v1/jobs", {
        "dataset_id": models.dataset_id, "model": "naive",
        "training": {"epochs": 1, "batch_size": 64}})
    assert status == 201, job
    done = server.rest.wait_job(job["id"])
    assert done["state"] == "succeeded", done
    return done["model_id"]


def test_a_naive_model_has_no_energy(server, client, naive_model):
    x, u = np.zeros(4), np.zeros(2)
    with pytest.raises(GrayboxError) as e:
        client.energy(naive_model, x, u)
    assert e.value.code == "FAILED_PRECONDITION" and "naive" in e.value.message, e.value
    status, body = server.rest.post(f"/v1/models/{naive_model}/energy", {"x": [x.tolist()], "u": [u.tolist()]})
    assert status == 409 and "naive" in body["error"]["message"], body
    status, model = server.rest.get(f"/v1/models/{naive_model}")
    assert status == 200 and model["metrics"]["energy"] is None, model


@pytest.mark.parametrize("x,u,field", [
    (np.zeros((2, 3)), np.zeros((2, 2)), "x"),
    (np.zeros((2, 4)), np.zeros((3, 2)), "u"),
    (np.zeros((0, 4)), np.zeros((0, 2)), "x"),
    (np.array([[0.0, np.nan, 0.0, 0.0]]), np.zeros((1, 2)), "x"),
])
def test_bad_shapes_are_invalid_arguments_naming_the_field(server, client, dp_model, x, u, field):
    _, model = dp_model
    with pytest.raises(GrayboxError) as e:
        client.energy(model, x, u)
    assert e.value.code == "INVALID_ARGUMENT" and field in e.value.message, e.value


def test_rest_names_ragged_rows_and_unknown_models(server, dp_model):
    _, model = dp_model
    status, body = server.rest.post(f"/v1/models/{model}/energy",
                                    {"x": [[0.0] * 4, [0.0] * 3], "u": [[0.0] * 2] * 2})
    assert status == 400 and body["error"]["field"] == "x" and "row 1" in body["error"]["message"], body
    status, body = server.rest.post(f"/v1/models/{model}/energy", {"x": [[0.0] * 4], "v": []})
    assert status == 422, body
    status, body = server.rest.post("/v1/models/mdl_nope/energy", {"x": [[0.0] * 4], "u": [[0.0] * 2]})
    assert status == 404, body


def test_a_batch_over_the_message_limit_is_refused_before_it_computes(client, dp_model):
    _, model = dp_model
    # 128 bytes of answer per state: 600 000 states answer 77 MB, over the 64 MB limit, in a
    # request of 29 MB that the limit admits.
    b = 600_000
    with pytest.raises(GrayboxError) as e:
        client.energy(model, np.zeros((b, 4)), np.zeros((b, 2)))
    assert e.value.code == "RESOURCE_EXHAUSTED" and "--grpc-max-message-mb" in e.value.message, e.value


def test_a_finished_job_stores_its_energy_report(server, models):
    status, wb = server.rest.get(f"/v1/models/{models.wb}")
    assert status == 200, wb
    report = wb["metrics"]["energy"]
    assert report is not None, wb["metrics"]
    # 256 transitions, a 0.8 split: the report's states are the training rows.
    assert report["rollouts"] == 64 and 0 < report["passivity"]["states"] <= 256
    assert [d["steps"] for d in report["drift"]] == [100, 1000]
    assert report["switched_off"] == ["damping"]
    # The white-box pendulum without its damping conserves E up to RK4's error at Δt = 0.01.
    for d in report["drift"]:
        assert d["diverged"] == 0 and d["median"] < 1e-3, d
    # η q̇ injects energy exactly where η > 0: none when both trained η are ≤ 0.
    eta = [wb["metrics"]["physical_parameters"][k] for k in ("eta1", "eta2")]
    injecting = report["passivity"]["injecting"]
    assert (injecting == 0) == all(e <= 0 for e in eta), (eta, report)
    assert ("never creates energy" in report["summary"]) == (injecting == 0), report
    status, mvf = server.rest.get(f"/v1/models/{models.mvf}")
    assert status == 200 and mvf["metrics"]["energy"]["switched_off"] == [], mvf["metrics"]


def test_an_uploaded_models_energy_report_is_measured_on_request_and_stored(server, models, dp_model, naive_model):
    _, model = dp_model
    status, before = server.rest.get(f"/v1/models/{model}")
    assert status == 200 and before["metrics"]["energy"] is None, before["metrics"]
    status, report = server.rest.post(f"/v1/models/{model}/energy-report",
                                      {"dataset_id": models.dataset_id})
    assert status == 200, report
    assert report["dataset_id"] == models.dataset_id and report["switched_off"] == ["damping"]
    # Its η are negative (DP above): it never injects; without them it keeps E to RK4's error.
    assert report["passivity"] == {"states": 256, "injecting": 0, "share": 0.0, "max_power": 0.0}
    assert all(d["median"] < 1e-3 for d in report["drift"]), report
    status, after = server.rest.get(f"/v1/models/{model}")
    assert status == 200 and after["metrics"]["energy"] == report, after["metrics"]
    with Client(server.grpc_target) as c:
        assert c.get_model(model).metrics["energy"] == report

    status, body = server.rest.post(f"/v1/models/{naive_model}/energy-report",
                                    {"dataset_id": models.dataset_id})
    assert status == 409 and "naive" in body["error"]["message"], body
    status, body = server.rest.post(f"/v1/models/{model}/energy-report", {"dataset_id": "ds_nope"})
    assert status == 404, body
    status, body = server.rest.post(f"/v1/models/{model}/energy-report",
                                    {"dataset_id": models.dataset_id, "timeout_seconds": 0})
    assert status == 400 and body["error"]["field"] == "timeout_seconds", body


def inverse_dynamics(server, gbx, x, qdd, n):
    """`graybox inverse-dynamics` of the model file at states x (q, q̇) and accelerations qdd."""
    states = server.tmp / f"{gbx.stem}-inverse.json"
    states.write_text(json.dumps({"q": x[:, :n].tolist(), "qdot": x[:, n:].tolist(),
                                  "qddot": qdd.tolist()}))
    out = run(server, "inverse-dynamics", "--model", gbx, "--states", states)
    return [json.loads(line) for line in out.splitlines()]


def within(got, want, rel=1e-10):
    """The issue's bound for inverse dynamics: 1e-10 of the reference's size (at least 1); the
    two sides agree to rounding (~1e-14), and a wrong term is of the terms' own size."""
    got, want = np.asarray(got), np.asarray(want)
    return np.abs(got - want).max() <= rel * max(1.0, np.abs(want).max())


def test_the_double_pendulums_inverse_dynamics_is_its_closed_form(server, dp_model):
    gbx, _ = dp_model
    rng = np.random.default_rng(80)
    x, _ = states(rng, 16, 2, 2)
    qdd = rng.normal(0.0, 10.0, (16, 2))
    lines = inverse_dynamics(server, gbx, x, qdd, 2)
    want = dp_inverse([DP[k] for k in DP], x[:, :2], x[:, 2:], qdd)
    assert within([l["tau"] for l in lines], want)
    damping = np.column_stack([DP["eta1"] * x[:, 2], DP["eta2"] * x[:, 3]])
    assert within([l["parts"]["damping"] for l in lines], damping)
    terms = [np.add.reduce([l["inertial"], l["coriolis"], l["gravity"]]) - l["passive"]
             for l in lines]
    assert within(terms, [l["tau"] for l in lines])


def test_ur5s_inverse_dynamics_is_pinocchios_rnea(server, client, ur5):
    """The CLI, gRPC and REST, each against Pinocchio's RNEA less the joints' force law."""
    model, ref, n, _ = ur5
    rng = np.random.default_rng(81)
    x, _ = states(rng, 8, n, n, qdot=1.0)
    qdd = rng.normal(0.0, 5.0, (8, n))
    want = np.array([ref.inverse(x[k, :n], x[k, n:], qdd[k]) for k in range(8)])
    lines = inverse_dynamics(server, server.tmp / "ur5-energy.gbx", x, qdd, n)
    assert within([line["tau"] for line in lines], want)
    assert set(lines[0]["parts"]) == {"friction"}
    got = client.inverse_dynamics(model, x, qdd)
    assert within(got["tau"], want) and set(got["parts"]) == {"friction"}
    assert within(got["inertial"] + got["coriolis"] + got["gravity"] - got["passive"], want)
    one = client.inverse_dynamics(model, x[2], qdd[2])
    assert within(one["tau"], want[2])
    status, rest = server.rest.post(f"/v1/models/{model}/inverse-dynamics",
                                    {"x": x.tolist(), "qdd": qdd.tolist()})
    assert status == 200, rest
    assert within(rest["tau"], want) and [p["name"] for p in rest["parts"]] == ["friction"]


def test_inverse_dynamics_names_bad_input(server, client, dp_model, naive_model):
    _, model = dp_model
    with pytest.raises(GrayboxError) as e:
        client.inverse_dynamics(model, np.zeros((2, 4)), np.zeros((3, 2)))
    assert e.value.code == "INVALID_ARGUMENT" and "qdd" in e.value.message, e.value
    status, body = server.rest.post(f"/v1/models/{model}/inverse-dynamics",
                                    {"x": [[0.0] * 4], "qdd": [[0.0] * 3]})
    assert status == 400 and body["error"]["field"] == "qdd", body
    with pytest.raises(GrayboxError) as e:
        client.inverse_dynamics(naive_model, np.zeros(4), np.zeros(2))
    assert e.value.code == "FAILED_PRECONDITION", e.value
