"""graybox_native against the running service, call for call and bit for bit, where the
recorded answers (test_native.py) say nothing: max_abs_z from Predict, Linearize and Rollout,
Rollout's particles (the service streams them in pieces, the module answers whole) and
Energy, each through graybox_client.Client with the same keyword arguments, on every recorded
model file (an ensemble among them) and two models the session's service trained."""

import warnings

import numpy as np
import pytest

import inference_answers as ia
from graybox_client import GrayboxError, RestClient

graybox_native = pytest.importorskip("graybox_native")


def _load(data: bytes):
    with warnings.catch_warnings():
        # The committed fixtures predate checksums (test_native.py checks the warning).
        warnings.simplefilter("ignore", graybox_native.UncheckedModelWarning)
        return graybox_native.load(data)


@pytest.fixture(scope="module")
def pairs(server, models):
    """name → (the service's id of a model, the same file loaded in this process)."""
    rest = RestClient(server.rest.base)
    out = {}
    for name, path in ia.MODELS.items():
        data = (ia.ROOT / path).read_bytes()
        out[name] = (rest.upload_model(data)["id"], _load(data))
    for name, model_id in (("trained-wb", models.wb), ("trained-mvf", models.mvf)):
        out[name] = (model_id, _load(rest.download_model(model_id)))
    return out


@pytest.fixture(scope="module")
def naive(server, models):
    status, job = server.rest.post("/v1/jobs", {
        "dataset_id": models.dataset_id, "model": "naive",
        "training": {"epochs": 1, "batch_size": 64}})
    assert status == 201, job
    done = server.rest.wait_job(job["id"])
    assert done["state"] == "succeeded", done
    model_id = done["model_id"]
    return model_id, _load(RestClient(server.rest.base).download_model(model_id))


def _same(got, want, where=""):
    """Equal values of equal types: arrays of one dtype and shape with the same bytes (which
    tells −0.0 from 0.0), a float for a float, equal dicts and sequences."""
    assert type(got) is type(want), f"{where}: {type(got).__name__} for {type(want).__name__}"
    if isinstance(want, np.ndarray):
        assert got.dtype == want.dtype and got.shape == want.shape, (where, got.shape, want.shape)
        assert got.tobytes() == want.tobytes(), f"{where}: values differ"
    elif isinstance(want, dict):
        assert list(got) == list(want), (where, list(got), list(want))
        for k in want:
            _same(got[k], want[k], f"{where}.{k}")
    elif isinstance(want, (tuple, list)):
        assert len(got) == len(want), (where, len(got), len(want))
        for k, (g, w) in enumerate(zip(got, want)):
            _same(g, w, f"{where}[{k}]")
    else:
        assert got == want, (where, got, want)


def _states(model, rng, rows, scale=1.0):
    """States and inputs within ±scale: ±1 is inside the recorded models' data, ±20 far out."""
    n, m = model.info.n, model.info.m
    return rng.uniform(-scale, scale, (rows, 2 * n)), rng.uniform(-scale, scale, (rows, m))


# Predict's extras in the combinations a caller would ask for (z last in every tuple).
PREDICT_EXTRAS = [
    {"return_z": True},
    {"want_accel": True, "return_z": True},
    {"return_std": True, "return_z": True},
    {"want_accel": True, "return_std": True, "members": True, "return_z": True},
]


def test_predict_and_linearize_answer_z_as_the_client_does(client, pairs):
    rng = np.random.default_rng(7)
    for name, (model_id, model) in pairs.items():
        for scale in (1.0, 20.0):
            x, u = _states(model, rng, 5, scale)
            for one in (False, True):
                xs, us = (x[0], u[0]) if one else (x, u)
                for extras in PREDICT_EXTRAS:
                    where = f"{name} predict ±{scale} {'one' if one else 'batch'} {extras}"
                    want = client.predict(model_id, xs, us, **extras)
                    _same(model.predict(xs, us, **extras), want, where)
                where = f"{name} linearize ±{scale} {'one' if one else 'batch'}"
                want = client.linearize(model_id, xs, us, return_z=True)
                _same(model.linearize(xs, us, return_z=True), want, where)
                z = want[-1]
                assert isinstance(z, float) if one else z.shape == (5,), where


def test_rollouts_answer_z_and_particles_as_the_service(client, pairs):
    rng = np.random.default_rng(8)
    steps = 30
    for name, (model_id, model) in pairs.items():
        n, m, k = model.info.n, model.info.m, model.info.members
        x0, us = rng.uniform(-0.5, 0.5, 2 * n), rng.uniform(-1, 1, (steps, m))
        xbar = model.rollout(x0, us)
        gains = rng.uniform(-0.2, 0.2, (steps, m, 2 * n))
        policy = (xbar + 0.01, us, gains)
        # Chunks of 7 states: the service computes and streams the rollout in pieces.
        for particles in (None, 1, 2 * k + 1):
            for inputs in ({"u": us}, {"policy": policy}):
                for extras in ({}, {"with_inputs": True}, {"with_inputs": True, "return_z": True},
                               {"return_z": True}):
                    kw = dict(inputs, particles=particles, **extras)
                    want = client.rollout(model_id, x0, chunk=7, **kw)
                    where = f"{name} particles={particles} {sorted(kw)}"
                    _same(model.rollout(x0, **kw), want, where)
            if particles is not None:
                xs, std = model.rollout(x0, us, particles=particles)
                if k > 1 and particles > 1:
                    assert std[-1].max() > 1e-6, (name, particles)
                else:
                    # One member's particles are one trajectory: their spread is the rounding
                    # of a mean of equal values, a few ulps of the state.
                    assert std.max() <= 1e-12 * max(1.0, np.abs(xs).max()), (name, particles)


def test_a_callers_step_answers_as_the_service_and_chains(client, pairs):
    """`dt` on Predict and Rollout: the module and the client agree bit for bit (an ensemble's
    members and particles too); the model's own Δt changes nothing; a rollout of steps of h is
    the chain of predictions at h; two steps of Δt/2 land near one of Δt (RK4's error, far
    below the states' scale) without being it; a Δt out of range is refused naming dt."""
    rng = np.random.default_rng(9)
    for name, (model_id, model) in pairs.items():
        dt = model.info.dt
        x, u = _states(model, rng, 3, 0.5)
        _same(model.predict(x, u, dt=dt), model.predict(x, u), f"{name} own dt")
        h = 0.5 * dt
        for extras in PREDICT_EXTRAS:
            want = client.predict(model_id, x, u, dt=h, **extras)
            _same(model.predict(x, u, dt=h, **extras), want, f"{name} dt/2 {extras}")
        us = np.repeat(u[:1], 2, axis=0)
        for particles in (None, 3):
            want = client.rollout(model_id, x[0], us, chunk=2, particles=particles, dt=h)
            _same(model.rollout(x[0], us, particles=particles, dt=h), want, f"{name} {particles}")
        xs = model.rollout(x[0], us, dt=h)
        _same(xs[1], model.predict(x[0], u[0], dt=h), f"{name} chain")
        one = model.predict(x[0], u[0])
        gap = np.abs(xs[2] - one).max()
        assert 0 < gap < 1e-3 * max(1.0, np.abs(one).max()), (name, gap)
        for bad in (0.0, -dt, 20.0, float("nan")):
            for call in (lambda: model.predict(x, u, dt=bad),
                         lambda: client.predict(model_id, x, u, dt=bad),
                         lambda: model.rollout(x[0], us, dt=bad),
                         lambda: client.rollout(model_id, x[0], us, dt=bad)):
                with pytest.raises(GrayboxError) as e:
                    call()
                assert e.value.code == "INVALID_ARGUMENT" and "dt" in str(e.value), (name, bad)


def test_a_long_rollout_from_rest_says_where_it_left_the_data(client, pairs):
    """The README's C example: the UR5 from rest with no torque for 1000 steps falls, and its
    state leaves the training data; z says so, as the service's does."""
    model_id, model = pairs["ur5-residual"]
    x0, us = np.zeros(2 * model.info.n), np.zeros((1000, model.info.m))
    want = client.rollout(model_id, x0, u=us, return_z=True)
    got = model.rollout(x0, us, return_z=True)
    _same(got, want, "ur5")
    z = got[1]
    assert z[0] < 4 < z[-1], (z[0], z[-1])


def test_energy_is_the_services(client, pairs, naive):
    rng = np.random.default_rng(9)
    for name, (model_id, model) in pairs.items():
        x, u = _states(model, rng, 4)
        for one in (False, True):
            xs, us = (x[0], u[0]) if one else (x, u)
            _same(model.energy(xs, us), client.energy(model_id, xs, us), f"{name} {one}")
        e = model.energy(x, u)
        assert set(e["damping"]) <= set(e["parts"]), name
    model_id, model = naive
    for call in (lambda: client.energy(model_id, np.zeros(4), np.zeros(2)),
                 lambda: model.energy(np.zeros(4), np.zeros(2))):
        with pytest.raises(GrayboxError) as e:
            call()
        assert e.value.code == "FAILED_PRECONDITION" and "naive" in e.value.message, e.value


def test_inverse_dynamics_is_the_services(client, pairs, naive):
    rng = np.random.default_rng(10)
    for name, (model_id, model) in pairs.items():
        x, _ = _states(model, rng, 4)
        qdd = rng.normal(0.0, 3.0, (4, model.info.nv))
        for one in (False, True):
            xs, qs = (x[0], qdd[0]) if one else (x, qdd)
            got = model.inverse_dynamics(xs, qs)
            _same(got, client.inverse_dynamics(model_id, xs, qs), f"{name} {one}")
            assert "input" not in got["parts"], name
    model_id, model = naive
    for call in (lambda: client.inverse_dynamics(model_id, np.zeros(4), np.zeros(2)),
                 lambda: model.inverse_dynamics(np.zeros(4), np.zeros(2))):
        with pytest.raises(GrayboxError) as e:
            call()
        assert e.value.code == "FAILED_PRECONDITION" and "naive" in e.value.message, e.value


def test_what_the_service_refuses_the_module_refuses_alike(client, pairs):
    """The same code (gRPC names no field; the module names it as well), and for the particle
    count, which the core checks for both, the same message."""
    model_id, model = pairs["ensemble-wb-x3"]
    x0, us = np.zeros(4), np.zeros((5, 2))
    calls = [
        ("particles", {"particles": 0}),
        ("particles", {"particles": 1025}),
        ("x0", {"x0": np.zeros(3)}),
    ]
    for field, kw in calls:
        args = dict({"x0": x0, "u": us}, **kw)
        with pytest.raises(GrayboxError) as want:
            client.rollout(model_id, **args)
        with pytest.raises(GrayboxError) as got:
            model.rollout(**args)
        assert (got.value.code, got.value.field) == (want.value.code, field), got.value
        if field == "particles":
            assert got.value.message == want.value.message, (got.value, want.value)
    for x, u, field in ((np.zeros(3), np.zeros(2), "x"), (np.zeros((2, 4)), np.zeros((3, 2)), "u")):
        with pytest.raises(GrayboxError) as want:
            client.energy(model_id, x, u)
        with pytest.raises(GrayboxError) as got:
            model.energy(x, u)
        assert (got.value.code, got.value.field) == (want.value.code, field), got.value
