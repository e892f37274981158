"""The service's answers to a fixed set of inference calls (Predict, Rollout, Linearize,
Tvlqr, Plan by both methods) for a set of model files: the record that every evaluator of a
model file (the service, the inference core, the C library) must reproduce bit for bit.

`scripts/inference_fixtures.sh` writes the models and, through `record`, the requests and
the service's answers to tests/fixtures/inference/answers.json; `test_inference_answers.py`
replays the requests against the service and compares. The requests live in the JSON, not in
code, so that a reader in any language replays exactly what was recorded.
"""

import json
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
ANSWERS = ROOT / "tests/fixtures/inference/answers.json"

# name → model file (relative to the repository). The oldest format and the ensemble are the
# compatibility fixtures an earlier graybox wrote (tests/fixtures/compat).
MODELS = {
    "dp-mvf": "tests/fixtures/inference/dp-mvf.gbx",
    "cartpole-wb": "tests/fixtures/inference/cartpole-wb.gbx",
    "formula-dp-wb": "tests/fixtures/inference/formula-dp-wb.gbx",
    "ur5-residual": "tests/fixtures/inference/ur5-residual.gbx",
    "ensemble-wb-x3": "tests/fixtures/compat/wb-x3.gbx",
    "oldest-format-mvf": "tests/fixtures/compat/mvf.gbx",
}

HORIZON = 10


def requests(n: int, m: int, seed: int) -> list[dict]:
    """The calls for a model with n coordinates and m inputs: states within ±1 (angles and
    rates alike), inputs within ±1, a horizon of HORIZON steps, and the cost
    Q = 𝟙, R = 0.1·𝟙, Qf = 10·𝟙 toward the origin."""
    rng = np.random.default_rng(seed)
    x = lambda *shape: rng.uniform(-1.0, 1.0, (*shape, 2 * n)).tolist()
    u = lambda *shape: rng.uniform(-1.0, 1.0, (*shape, m)).tolist()
    cost = {"Q": np.eye(2 * n).tolist(), "R": (0.1 * np.eye(m)).tolist(),
            "Qf": (10.0 * np.eye(2 * n)).tolist()}
    x0, us = x(), u(HORIZON)
    plan = {"x0": x0, "goal": [0.0] * (2 * n), "horizon": HORIZON, "u_init": us,
            "max_iterations": 3, **cost}
    return [
        {"rpc": "predict", "x": x(), "u": u()},
        {"rpc": "predict", "x": x(4), "u": u(4)},
        {"rpc": "rollout", "x0": x0, "u": us},
        {"rpc": "linearize", "x": x(), "u": u()},
        {"rpc": "linearize", "x": x(3), "u": u(3)},
        {"rpc": "tvlqr", "x0": x0, "u": us, **cost},
        {"rpc": "plan", "method": "ilqr", **plan},
        {"rpc": "plan", "method": "dircol", **plan},
    ]


def _list(a) -> list:
    return np.asarray(a, dtype=np.float64).tolist()


# The calls that answer max_abs_z, how far their states and inputs lie from the training data.
Z_RPCS = ("predict", "rollout", "linearize")


def answer(client, model_id: str, call: dict, z: bool | None = None) -> dict:
    """The service's answer to one recorded call, as plain lists of floats; with `z` also its
    max_abs_z (by default when the record holds it, or when there is no record yet)."""
    rpc = call["rpc"]
    if z is None:
        z = rpc in Z_RPCS and "max_abs_z" in call.get("answer", {"max_abs_z": None})
    if rpc == "predict":
        out = client.predict(model_id, call["x"], call["u"], want_accel=True, return_z=z)
        got = {"x_next": _list(out[0]), "accel": _list(out[1])}
        return {**got, "max_abs_z": _list(out[2])} if z else got
    if rpc == "rollout":
        out = client.rollout(model_id, call["x0"], call["u"], return_z=z)
        return {"xs": _list(out[0]), "max_abs_z": _list(out[1])} if z else {"xs": _list(out)}
    if rpc == "linearize":
        out = client.linearize(model_id, call["x"], call["u"], return_z=z)
        got = {"A": _list(out[0]), "B": _list(out[1])}
        return {**got, "max_abs_z": _list(out[2])} if z else got
    if rpc == "tvlqr":
        # Along the model's own rollout of the inputs, as a controller tracking it would.
        xbar = client.rollout(model_id, call["x0"], call["u"])
        k, s = client.tvlqr(model_id, xbar, call["u"], call["Q"], call["R"], call["Qf"])
        return {"K": _list(k), "S": _list(s)}
    if rpc == "plan":
        p = client.plan(model_id, call["x0"], call["goal"], call["horizon"], call["Q"],
                        call["R"], call["Qf"], u_init=call["u_init"],
                        max_iterations=call["max_iterations"], method=call["method"])
        return {"x": _list(p.x), "u": _list(p.u), "K": _list(p.K), "cost": p.cost,
                "costs": _list(p.costs), "iterations": p.iterations,
                "converged": p.converged}
    raise ValueError(f"unknown rpc {rpc}")


def record(client, upload, skip=frozenset()) -> dict:
    """Every model's calls and the service's answers (but those in `skip`); `upload(path)`
    returns a model id."""
    out = {}
    for seed, (name, path) in enumerate(MODELS.items()):
        if name in skip:
            continue
        model_id = upload(ROOT / path)
        info = client.get_model(model_id)
        calls = requests(info.n, info.m, seed)
        out[name] = {"file": path, "n": info.n, "m": info.m,
                     "calls": [{**c, "answer": answer(client, model_id, c)} for c in calls]}
    return out


def complete(client, upload, record: dict) -> list[str]:
    """Adds the service's max_abs_z to the recorded Predict, Rollout and Linearize answers
    that lack it (z joined the record after their first answers), each once the rest of its
    answer is checked to be the recorded one; the names of the models it completed."""
    done = []
    for name, entry in record.items():
        calls = [c for c in entry["calls"]
                 if c["rpc"] in Z_RPCS and "max_abs_z" not in c["answer"]]
        if not calls:
            continue
        model_id = upload(ROOT / entry["file"])
        for call in calls:
            got = answer(client, model_id, call, z=True)
            where = first_difference(got, call["answer"])
            assert not where, f"{name} {call['rpc']}{where}: the record is not this service's"
            call["answer"]["max_abs_z"] = got["max_abs_z"]
        done.append(name)
    return done


def first_difference(got, want, at="") -> str:
    """Where `got` first differs from the recorded `want` ("" when nowhere): json.dumps prints
    each float in its shortest round-trip form, so equal text is equal bits (and tells −0.0
    from 0.0)."""
    if isinstance(want, dict):
        for k in want:
            d = first_difference(got.get(k), want[k], f"{at}.{k}")
            if d:
                return d
        return ""
    if isinstance(want, list):
        if not isinstance(got, list) or len(got) != len(want):
            return f"{at}: shape differs"
        for i, (g, w) in enumerate(zip(got, want)):
            d = first_difference(g, w, f"{at}[{i}]")
            if d:
                return d
        return ""
    return "" if json.dumps(got) == json.dumps(want) else f"{at}: {got!r} != {want!r}"


def load() -> dict:
    return json.loads(ANSWERS.read_text())


def write(answers: dict) -> None:
    ANSWERS.parent.mkdir(parents=True, exist_ok=True)
    ANSWERS.write_text(json.dumps(answers, indent=1) + "\n")
