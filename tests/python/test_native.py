"""graybox_native, the model inside a Python process (clients/native): the service's recorded
answers (tests/fixtures/inference/answers.json) bit for bit from every recorded model file,
its errors as GrayboxError with the service's code and the field named, and one model shared
by threads that compute at once (the GIL is released) with the answers of one thread."""

import json
import re
import subprocess
import threading
import warnings
from pathlib import Path

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
        model = _load(source)
        assert (model.info["n"], model.info["m"]) == (entry["n"], entry["m"])
        for call in entry["calls"]:
            got = ia.answer(_AsClient(model), "", call)
            where = ia.first_difference(got, call["answer"])
            assert not where, f"{name} {call['rpc']} {call.get('method', '')}{where}"


def _load(source):
    """A committed fixture: written before model files carried a checksum, so it loads with an
    UncheckedModelWarning (test_a_file_from_before_checksums_loads_with_a_warning checks it)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", graybox_native.UncheckedModelWarning)
        return graybox_native.load(source)


def _model(name="dp-mvf"):
    return _load(str(ia.ROOT / ia.MODELS[name]))


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


def test_a_file_from_before_checksums_loads_with_a_warning(graybox_bin, tmp_path):
    old = ia.ROOT / ia.MODELS["ensemble-wb-x3"]
    with pytest.warns(graybox_native.UncheckedModelWarning, match="no checksum"):
        graybox_native.load(old.read_bytes())
    # A file this graybox writes carries its checksum and loads without a warning.
    made = tmp_path / "dp.gbx"
    subprocess.run([graybox_bin, "model", "--template", "double_pendulum", "--dt", "0.01",
                    "--out", str(made)], check=True, capture_output=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        graybox_native.load(str(made))


def test_an_edited_model_file_is_refused(graybox_bin, tmp_path):
    """One weight changed in a file graybox wrote, a member removed, or an ensemble's members
    deleted (which would leave one model answering with no spread, as if certain): each
    raises GrayboxError, where before they loaded and were served."""
    made = tmp_path / "dp.gbx"
    subprocess.run([graybox_bin, "model", "--template", "double_pendulum", "--dt", "0.01",
                    "--out", str(made)], check=True, capture_output=True)
    doc = json.loads(made.read_bytes())
    assert doc["checksum"].startswith("sha256:"), doc.get("checksum")
    doc["params"][0]["values"][0] *= 1.001
    e = _refused(lambda: graybox_native.load(json.dumps(doc).encode()), "INVALID_ARGUMENT",
                 "source")
    assert "checksum" in e.message, e.message

    ensemble = json.loads((ia.ROOT / ia.MODELS["ensemble-wb-x3"]).read_bytes())
    fewer = dict(ensemble, members=ensemble["members"][:1])
    e = _refused(lambda: _load(json.dumps(fewer).encode()), "INVALID_ARGUMENT", "source")
    assert "members" in e.message and "lists 3" in e.message, e.message
    gone = {k: v for k, v in ensemble.items() if k != "members"}
    e = _refused(lambda: _load(json.dumps(gone).encode()), "INVALID_ARGUMENT", "source")
    assert "members" in e.message, e.message


# --- The package's surface: info, and one GrayboxError and PlanResult ---------------------------

INFO_KEYS = ["nq", "nv", "n", "m", "dt", "members", "integrator", "joints", "coordinates",
             "inputs"]


def test_info_has_attributes_and_reads_as_the_dict_it_was():
    info = _model("ensemble-wb-x3").info
    assert (info.n, info.m, info.members, info.integrator) == (2, 2, 3, "rk4"), info
    assert (info.nq, info.nv, info.joints) == (2, 2, ["real", "real"]), info
    assert info.coordinates == ["q1", "q2"] and info.inputs == ["u1", "u2"], info
    # Item access, the keys in the dict's order, and comparison with a dict, as before.
    assert list(info) == INFO_KEYS and list(info.keys()) == INFO_KEYS
    assert [info[k] for k in INFO_KEYS] == [getattr(info, k) for k in INFO_KEYS]
    assert info == dict(info) and len(info) == len(INFO_KEYS) and "dt" in info
    assert info.get("absent") is None
    with pytest.raises(KeyError):
        info["absent"]
    # What a model file says is not the caller's to change.
    with pytest.raises(AttributeError):
        info.n = 3


def test_graybox_error_and_plan_result_are_defined_once():
    graybox_client = pytest.importorskip("graybox_client")
    import graybox_client._shared as client_shared
    import graybox_native._shared as native_shared
    assert graybox_native.GrayboxError is graybox_client.GrayboxError
    assert graybox_native.PlanResult is graybox_client.PlanResult
    with pytest.raises(graybox_client.GrayboxError):
        _model().predict(np.zeros(3), np.zeros(2))
    # One class statement each in the packages' sources (a symbolic link is the file it
    # names), which both packages install: their copies are the same bytes.
    found = {"GrayboxError": set(), "PlanResult": set()}
    for path in (ia.ROOT / "clients").rglob("*.py"):
        parts = path.relative_to(ia.ROOT).parts
        if {"build", "__pycache__"} & set(parts) or any(p.endswith(".egg-info") for p in parts):
            continue
        text = path.read_text()
        for name, files in found.items():
            if re.search(rf"^\s*class {name}\b", text, re.M):
                files.add(path.resolve())
    assert all(len(files) == 1 for files in found.values()), found
    assert Path(native_shared.__file__).read_bytes() == Path(client_shared.__file__).read_bytes()


# Without graybox_client (importing it fails, as when it is not installed), the module's
# errors and plans are its own copy's classes.
_WITHOUT_CLIENT = """
import sys
sys.modules["graybox_client"] = None
import warnings
import numpy as np
import graybox_native
warnings.simplefilter("ignore")
m = graybox_native.load(sys.argv[1])
try:
    m.predict(np.zeros(3), np.zeros(2))
except graybox_native.GrayboxError as e:
    print(type(e).__module__, e.code, e.field)
p = m.plan(np.zeros(4), np.zeros(4), 5, np.eye(4), np.eye(2), np.eye(4), max_iterations=1)
print(type(p).__module__, type(p).__name__, p.x.shape)
"""


def test_the_module_works_without_graybox_client():
    import sys
    out = subprocess.run([sys.executable, "-c", _WITHOUT_CLIENT, str(ia.ROOT / ia.MODELS["dp-mvf"])],
                         capture_output=True, text=True, check=True).stdout
    assert out.split("\n")[:2] == ["graybox_native._shared INVALID_ARGUMENT x",
                                   "graybox_native._shared PlanResult (6, 4)"], out


# --- Any array layout answers as its C-ordered copy -------------------------------------------

def _layouts(a):
    """`a` as C, Fortran (float64 and float32, which NumPy converts keeping the order), strided
    (a view of every other column or row of a bigger array) and reversed views."""
    a = np.ascontiguousarray(a, dtype=float)
    yield "C", a
    yield "Fortran", np.asfortranarray(a)
    yield "Fortran float32", np.asfortranarray(a.astype(np.float32))
    wide = np.zeros(a.shape[:-1] + (2 * a.shape[-1],))
    wide[..., ::2] = a
    yield "every other column", wide[..., ::2]
    tall = np.zeros((2 * a.shape[0],) + a.shape[1:])
    tall[::2] = a
    yield "every other row", tall[::2]
    yield "reversed", a[::-1]
    if a.ndim > 1:
        yield "both axes reversed", a[::-1, ::-1]


def _same(got, want, where):
    if isinstance(want, (tuple, list)):
        assert len(got) == len(want), where
        for k, (g, w) in enumerate(zip(got, want)):
            _same(g, w, f"{where}[{k}]")
    elif hasattr(want, "__dataclass_fields__"):
        for name in want.__dataclass_fields__:
            _same(getattr(got, name), getattr(want, name), f"{where}.{name}")
    elif isinstance(want, np.ndarray):
        assert got.shape == want.shape and np.array_equal(got, want, equal_nan=True), where
    else:
        assert got == want, where


def _answer(call, **kwargs):
    """The call's answer, or its error's code, field and message (a reversed weight matrix
    is not positive definite: the copy must be refused alike)."""
    try:
        return call(**kwargs)
    except GrayboxError as e:
        return (e.code, e.field, e.message)


def _every_layout(call, arrays, **kwargs):
    """Each array argument in each layout answers exactly as its C-ordered copy does."""
    for name, a in arrays.items():
        for layout, view in _layouts(a):
            args = dict(arrays, **{name: view}, **kwargs)
            copies = dict(arrays, **{name: np.ascontiguousarray(view)}, **kwargs)
            _same(_answer(call, **args), _answer(call, **copies), f"{name} {layout}")


def test_every_entry_point_reads_any_layout_as_its_c_ordered_copy():
    m = _model()
    rng = np.random.default_rng(3)
    x, u = rng.uniform(-1, 1, (5, 4)), rng.uniform(-1, 1, (5, 2))
    _every_layout(m.predict, {"x": x, "u": u})
    _every_layout(m.predict, {"x": x, "u": u}, want_accel=True)
    _every_layout(m.step, {"x": x, "u": u})
    _every_layout(m.linearize, {"x": x, "u": u})
    x0, us = np.array([0.1, -0.2, 0.3, 0.05]), rng.uniform(-1, 1, (8, 2))
    _every_layout(m.rollout, {"x0": x0, "u": us}, with_inputs=True)
    xbar = m.rollout(x0, us)
    K = rng.uniform(-0.5, 0.5, (8, 2, 4))

    def by_policy(x0, x_bar, u_bar, K):
        return m.rollout(x0, policy=(x_bar, u_bar, K), with_inputs=True)

    _every_layout(by_policy, {"x0": x0, "x_bar": xbar + 0.01, "u_bar": us, "K": K})
    Q, R = np.diag([1.0, 2.0, 0.1, 0.2]), np.array([[0.02, 0.005], [0.005, 0.01]])
    _every_layout(m.tvlqr, {"xbar": xbar, "ubar": us, "Q": Q, "R": R, "Qf": 10 * Q})
    goal = np.array([0.5, 0.0, 0.0, 0.0])
    plan = {"x0": x0, "goal": goal, "Q": Q, "R": R, "Qf": 10 * Q, "u_init": us}
    _every_layout(m.plan, plan, horizon=8, max_iterations=5)
    _every_layout(m.plan, dict(plan, x_init=xbar), horizon=8, max_iterations=3,
                  method="dircol")


# --- Integers: a negative one is refused naming it ----------------------------------------------

def test_negative_counts_and_limits_of_a_plan_name_their_argument():
    m = _model()
    args = (np.zeros(4), np.zeros(4), 10, np.eye(4), np.eye(2), np.eye(4))
    for name in ("time_limit_ms", "restarts", "max_iterations", "seed"):
        e = _refused(lambda: m.plan(*args, **{name: -1}), "INVALID_ARGUMENT", name)
        assert "-1" in e.message, e
    e = _refused(lambda: m.plan(*args[:2], -5, *args[3:]), "INVALID_ARGUMENT", "horizon")
    assert "-5" in e.message, e
    _refused(lambda: m.plan(*args, restarts=10**30), "INVALID_ARGUMENT", "restarts")
    _refused(lambda: m.plan(*args[:2], 10**9, *args[3:]), "RESOURCE_EXHAUSTED", "horizon")
    # The largest seed is still a seed.
    assert m.plan(*args, seed=2**64 - 1, max_iterations=1).x.shape == (11, 4)


# --- The memory budget -------------------------------------------------------------------------

def test_calls_over_the_memory_budget_are_refused_naming_the_field_and_the_way_out():
    # The service's default --max-call-memory-mb.
    assert graybox_native.memory_budget_mb() == 512
    for bad in (0, -1):
        _refused(lambda: graybox_native.set_memory_budget_mb(bad), "INVALID_ARGUMENT", "mb")
    m = _model("ensemble-wb-x3")
    x0, goal = np.zeros(4), np.array([0.5, 0.0, 0.0, 0.0])
    plan = (x0, goal, 10, np.eye(4), 0.01 * np.eye(2), 10 * np.eye(4))
    graybox_native.set_memory_budget_mb(1)
    try:
        assert graybox_native.memory_budget_mb() == 1
        # The members' average cost plans all three members' states at once: about 2.7 MB
        # at this horizon, where the mean dynamics' plan fits.
        e = _refused(lambda: m.plan(*plan, method="dircol", ensemble_cost="mean"),
                     "RESOURCE_EXHAUSTED", "horizon")
        for words in ("set_memory_budget_mb", "shorter horizon", "ensemble_cost",
                      "mean_dynamics", "3 members"):
            assert words in e.message, e
        assert "fewer states" not in e.message, e
        p = m.plan(*plan, method="dircol", ensemble_cost="mean_dynamics", max_iterations=2)
        assert p.x.shape == (11, 4)
        e = _refused(lambda: m.predict(np.zeros((20_000, 4)), np.zeros((20_000, 2))),
                     "RESOURCE_EXHAUSTED", "x")
        assert "fewer states" in e.message, e
        _refused(lambda: m.linearize(np.zeros((5_000, 4)), np.zeros((5_000, 2))),
                 "RESOURCE_EXHAUSTED", "x")
        _refused(lambda: m.rollout(x0, np.zeros((40_000, 2))), "RESOURCE_EXHAUSTED", "u")
        xbar, ubar = np.zeros((5_001, 4)), np.zeros((5_000, 2))
        _refused(lambda: m.tvlqr(xbar, ubar, np.eye(4), np.eye(2), np.eye(4)),
                 "RESOURCE_EXHAUSTED", "ubar")
    finally:
        graybox_native.set_memory_budget_mb(512)


# --- Ctrl-C --------------------------------------------------------------------------------------

# Runs one long call in a child process and says how many of them completed when
# KeyboardInterrupt arrived. The call runs under map() inside deque(), all C code, so nothing
# between the call's return and `done.append` checks for signals: a call that ignored Ctrl-C
# completes and is counted before the interrupt is raised.
_INTERRUPTED_CALL = """
import collections, functools, itertools, signal, sys
import numpy as np
import graybox_native

# Python leaves SIGINT ignored when its parent ignored it (a job started in the background by
# a non-interactive shell, as a CI runner may be): put back the handler a terminal's Python has.
signal.signal(signal.SIGINT, signal.default_int_handler)

m = graybox_native.load(sys.argv[1])
graybox_native.set_memory_budget_mb(8192)
rows, steps = int(sys.argv[3]), int(sys.argv[4])
x, u = np.full((rows, 4), 0.1), np.full((rows, 2), 0.1)
x0, us = np.array([0.1, 0.2, 0.0, 0.0]), np.full((steps, 2), 0.1)
Q, R = np.eye(4), 1e-4 * np.eye(2)
calls = {
    "predict": (m.predict, (x, u)),
    "linearize": (m.linearize, (x, u)),
    "rollout": (m.rollout, (x0, us)),
    "tvlqr": (m.tvlqr, (np.full((steps + 1, 4), 0.1), us, Q, R, Q)),
    "plan": (functools.partial(m.plan, tolerance=0.0, max_iterations=10**6),
             (x0, np.array([np.pi, 0.0, 0.0, 0.0]), steps, Q, R, 1000 * Q)),
}
call, args = calls[sys.argv[2]]
done = []
print("ready", flush=True)
try:
    collections.deque(map(done.append, itertools.starmap(call, [args])), maxlen=0)
except KeyboardInterrupt:
    print("KeyboardInterrupt", len(done), flush=True)
else:
    print("no interrupt", len(done), flush=True)
"""


@pytest.mark.parametrize("name,rows,steps", [
    # Each call takes 10 s or more uninterrupted on this project's 2-core machine (the plan,
    # which never meets a tolerance of 0, minutes).
    ("predict", 1_000_000, 1),
    ("linearize", 300_000, 1),
    ("rollout", 1, 1_000_000),
    ("tvlqr", 1, 300_000),
    ("plan", 1, 300),
])
def test_ctrl_c_interrupts_a_long_call(tmp_path, name, rows, steps):
    import signal
    import subprocess
    import sys
    import time

    script = tmp_path / "call.py"
    script.write_text(_INTERRUPTED_CALL)
    model = str(ia.ROOT / ia.MODELS["dp-mvf"])
    child = subprocess.Popen([sys.executable, str(script), model, name, str(rows), str(steps)],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "ready", child.stderr.read()
        time.sleep(1.0)  # into the call
        child.send_signal(signal.SIGINT)
        out, err = child.communicate(timeout=600)
    finally:
        child.kill()
    # Interrupted, and the call never completed.
    assert out.split() == ["KeyboardInterrupt", "0"], (out, err)
