"""graybox_native, the model inside a Python process (clients/native): the service's recorded
answers (tests/fixtures/inference/answers.json) bit for bit from every recorded model file,
its errors as GrayboxError with the service's code and the field named, and one model shared
by threads that compute at once (the GIL is released) with the answers of one thread."""

import threading

import numpy as np
import pytest

import inference_answers as ia

graybox_native = pytest.importorskip("graybox_native")
from graybox_native import GrayboxError  # noqa: E402


class _AsClient:
    """A loaded model behind the gRPC client's signatures (the model id is ignored), so the
    recorded calls replay through the same code as against the service."""

    def __init__(self, model):
        self.model = model

    def __getattr__(self, name):
        method = getattr(self.model, name)
        return lambda _model_id, *args, **kwargs: method(*args, **kwargs)


@pytest.mark.parametrize("name", sorted(ia.MODELS))
def test_the_recorded_answers_bit_for_bit(name):
    entry = ia.load()[name]
    path = ia.ROOT / entry["file"]
    # From the path and from the bytes alike.
    for source in (str(path), path.read_bytes()):
        model = graybox_native.load(source)
        assert (model.info["n"], model.info["m"]) == (entry["n"], entry["m"])
        for call in entry["calls"]:
            got = ia.answer(_AsClient(model), "", call)
            where = ia.first_difference(got, call["answer"])
            assert not where, f"{name} {call['rpc']} {call.get('method', '')}{where}"


def _model(name="dp-mvf"):
    return graybox_native.load(str(ia.ROOT / ia.MODELS[name]))


def _refused(call, code, field):
    with pytest.raises(GrayboxError) as e:
        call()
    assert (e.value.code, e.value.field) == (code, field), e.value
    return e.value


def test_bad_input_is_refused_naming_the_argument():
    m = _model()
    _refused(lambda: m.predict(np.zeros(3), np.zeros(2)), "INVALID_ARGUMENT", "x")
    _refused(lambda: m.predict(np.zeros((2, 4)), np.zeros((3, 2))), "INVALID_ARGUMENT", "u")
    _refused(lambda: m.predict(np.zeros(4)), "INVALID_ARGUMENT", "u")
    _refused(lambda: m.linearize(np.zeros((0, 4)), np.zeros((0, 2))), "INVALID_ARGUMENT", "x")
    e = _refused(lambda: m.predict([0.0, np.nan, 0.0, 0.0], [0.0, 0.0]), "INVALID_ARGUMENT", "x")
    assert "non-finite" in e.message
    # Finite inputs the model cannot evaluate: its outputs would not be finite.
    e = _refused(lambda: m.predict([0, 0, 1e200, 1e200], np.zeros(2)), "INVALID_ARGUMENT", "x")
    assert "not finite" in e.message
    xbar, ubar = np.zeros((11, 4)), np.zeros((10, 2))
    _refused(lambda: m.tvlqr(xbar[:10], ubar, np.eye(4), np.eye(2), np.eye(4)),
             "INVALID_ARGUMENT", "xbar")
    _refused(lambda: m.tvlqr(xbar, ubar, np.eye(3), np.eye(2), np.eye(4)),
             "INVALID_ARGUMENT", "Q")
    _refused(lambda: m.plan(np.zeros(4), np.zeros(4), 10, np.eye(4), np.eye(2), np.eye(4),
                            method="shooting"), "INVALID_ARGUMENT", "method")
    _refused(lambda: m.rollout(np.zeros(4)), "INVALID_ARGUMENT", "u")
    for source in (str(ia.ROOT / "README.md"), b"not a model", "/nonexistent.gbx"):
        _refused(lambda: graybox_native.load(source), "INVALID_ARGUMENT", "source")


def test_an_ensemble_gives_its_mean_its_spread_and_its_members():
    m = _model("ensemble-wb-x3")
    x, u = np.array([[0.3, -0.2, 0.1, 0.0], [0.1, 0.2, -0.1, 0.3]]), np.ones((2, 2))
    mean, std, each = m.predict(x, u, return_std=True, members=True)
    assert each.shape == (3, 2, 4)
    # The members' mean and sample standard deviation (what the service reports).
    np.testing.assert_allclose(mean, each.mean(axis=0), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(std, each.std(axis=0, ddof=1), rtol=1e-9, atol=1e-15)
    assert (std > 0).any()
    assert np.array_equal(m.predict(x, u), mean)


def test_threads_sharing_a_model_get_the_answers_of_one():
    m = _model("ur5-residual")
    rng = np.random.default_rng(0)
    xs, us = rng.uniform(-1, 1, (8, 200, 12)), rng.uniform(-1, 1, (8, 200, 6))
    want = [[m.predict(x, u) for x, u in zip(xs[k], us[k])] for k in range(8)]
    got = [None] * 8

    def work(k):
        got[k] = [m.predict(x, u) for x, u in zip(xs[k], us[k])]

    threads = [threading.Thread(target=work, args=(k,)) for k in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for k in range(8):
        assert all(np.array_equal(g, w) for g, w in zip(got[k], want[k])), k
