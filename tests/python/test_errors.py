"""Bad requests reach the server and come back as GrayboxError with the right status code and
a message naming what is wrong."""

import numpy as np
import pytest

from conftest import MAX_ROLLOUT_STEPS
from graybox_client import GrayboxError, pb, to_array

X, U = np.array([0.3, -0.6, 2.0, -1.0]), np.array([15.0, -40.0])
I2, I4 = np.eye(2), np.eye(4)
NAN, INF = float("nan"), float("inf")


XBAR, UBAR = np.zeros((3, 4)), np.zeros((2, 2))


def tvlqr(c, model, xbar=XBAR, ubar=UBAR, Q=I4, R=I2, Qf=I4):
    return c.tvlqr(model, xbar, ubar, Q, R, Qf)


def raw_predict(c, model, x: pb.Array | None, u: pb.Array | None):
    """A request the numpy helpers cannot produce (a missing array, data not matching shape)."""
    return c._call(c.stub.Predict, pb.PredictRequest(model_id=model, x=x, u=u))


def policy(T=3, xbar_rows=None, k=None):
    return (np.zeros((xbar_rows or T + 1, 4)), np.zeros((T, 2)),
            np.zeros((T, 2, 4)) if k is None else k)


# (name, call(client, models), code, a piece of the message)
CASES = [
    ("unknown model", lambda c, m: c.predict("mdl_does_not_exist", X, U),
     "NOT_FOUND", "mdl_does_not_exist"),
    ("unknown job", lambda c, m: c.get_model("job_does_not_exist"),
     "NOT_FOUND", "job_does_not_exist"),
    ("unknown model, rollout", lambda c, m: c.rollout("mdl_nope", X, u=[U]), "NOT_FOUND", "mdl_nope"),
    ("unknown model, linearize", lambda c, m: c.linearize("mdl_nope", X, U), "NOT_FOUND", "mdl_nope"),
    ("unknown model, tvlqr", lambda c, m: tvlqr(c, "mdl_nope"), "NOT_FOUND", "mdl_nope"),
    ("x has 3 columns", lambda c, m: c.predict(m.wb, X[:3], U), "INVALID_ARGUMENT", "x"),
    ("u has 3 columns", lambda c, m: c.predict(m.wb, X, [1.0, 2.0, 3.0]), "INVALID_ARGUMENT", "u"),
    ("x is 3-d", lambda c, m: c.predict(m.wb, X.reshape(1, 1, 4), U.reshape(1, 2)),
     "INVALID_ARGUMENT", "x"),
    ("x data does not fill its shape", lambda c, m: raw_predict(
        c, m.wb, pb.Array(shape=[2, 4], data=X.tolist()), to_array(np.zeros((2, 2)))),
     "INVALID_ARGUMENT", "x"),
    ("x missing", lambda c, m: raw_predict(c, m.wb, None, to_array([U])), "INVALID_ARGUMENT", "x"),
    ("empty batch", lambda c, m: c.predict(m.wb, np.zeros((0, 4)), np.zeros((0, 2))),
     "INVALID_ARGUMENT", "x"),
    ("NaN in x", lambda c, m: c.predict(m.wb, [0.0, NAN, 0.0, 0.0], U), "INVALID_ARGUMENT", "x"),
    ("Inf in u", lambda c, m: c.predict(m.mvf, X, [INF, 0.0]), "INVALID_ARGUMENT", "u"),
    ("batch lengths differ", lambda c, m: c.predict(m.wb, np.zeros((2, 4)), np.zeros((3, 2))),
     "INVALID_ARGUMENT", "rows"),
    ("linearize: NaN in x", lambda c, m: c.linearize(m.mvf, [NAN, 0.0, 0.0, 0.0], U),
     "INVALID_ARGUMENT", "x"),
    ("linearize: batch lengths differ", lambda c, m: c.linearize(m.wb, np.zeros((3, 4)), np.zeros((1, 2))),
     "INVALID_ARGUMENT", "rows"),
    ("Q not symmetric", lambda c, m: tvlqr(c, m.wb, Q=I4 + np.triu(np.full((4, 4), 0.1), 1)),
     "INVALID_ARGUMENT", "Q"),
    ("R singular", lambda c, m: tvlqr(c, m.wb, R=np.diag([1.0, 0.0])), "INVALID_ARGUMENT", "R"),
    ("R negative definite", lambda c, m: tvlqr(c, m.mvf, R=-I2), "INVALID_ARGUMENT", "R"),
    ("Qf has a negative eigenvalue", lambda c, m: tvlqr(c, m.wb, Qf=np.diag([1.0, 1.0, 1.0, -1e-3])),
     "INVALID_ARGUMENT", "Qf"),
    ("Q is 2x2", lambda c, m: tvlqr(c, m.wb, Q=I2), "INVALID_ARGUMENT", "Q"),
    ("Inf in Q", lambda c, m: tvlqr(c, m.wb, Q=np.diag([1.0, INF, 1.0, 1.0])), "INVALID_ARGUMENT", "Q"),
    ("x_bar rows != T+1", lambda c, m: tvlqr(c, m.wb, xbar=np.zeros((2, 4))), "INVALID_ARGUMENT", "x_bar"),
    ("tvlqr with T = 0", lambda c, m: tvlqr(c, m.wb, xbar=np.zeros((1, 4)), ubar=np.zeros((0, 2))),
     "INVALID_ARGUMENT", "u_bar"),
    ("tvlqr horizon over the limit", lambda c, m: tvlqr(
        c, m.wb, xbar=np.zeros((MAX_ROLLOUT_STEPS + 2, 4)), ubar=np.zeros((MAX_ROLLOUT_STEPS + 1, 2))),
     "RESOURCE_EXHAUSTED", "limit"),
    ("rollout over the step limit", lambda c, m: c.rollout(m.wb, X, u=np.zeros((MAX_ROLLOUT_STEPS + 1, 2))),
     "RESOURCE_EXHAUSTED", "limit"),
    ("rollout: x0 has 3 values", lambda c, m: c.rollout(m.wb, X[:3], u=[U]), "INVALID_ARGUMENT", "x0"),
    ("rollout: NaN in x0", lambda c, m: c.rollout(m.wb, [NAN, 0.0, 0.0, 0.0], u=[U]),
     "INVALID_ARGUMENT", "x0"),
    ("rollout: neither u nor policy", lambda c, m: c.rollout(m.wb, X), "INVALID_ARGUMENT", "inputs"),
    ("rollout: T = 0", lambda c, m: c.rollout(m.wb, X, u=np.zeros((0, 2))), "INVALID_ARGUMENT", "u"),
    ("rollout: Inf in u", lambda c, m: c.rollout(m.wb, X, u=[[0.0, INF]]), "INVALID_ARGUMENT", "u"),
    ("policy: K has the wrong shape", lambda c, m: c.rollout(m.wb, X, policy=policy(k=np.zeros((3, 4, 2)))),
     "INVALID_ARGUMENT", "policy.k"),
    ("policy: NaN in K", lambda c, m: c.rollout(m.wb, X, policy=policy(k=np.full((3, 2, 4), NAN))),
     "INVALID_ARGUMENT", "policy.k"),
    ("policy: x_bar has T+2 rows", lambda c, m: c.rollout(m.wb, X, policy=policy(xbar_rows=5)),
     "INVALID_ARGUMENT", "policy.x_bar"),
    ("list: page_size over 1000", lambda c, m: c.list_models(page_size=5000),
     "INVALID_ARGUMENT", "page_size"),
    ("list: a forged page_token", lambda c, m: c.list_models(page_token="not-a-token"),
     "INVALID_ARGUMENT", "page_token"),
]


@pytest.mark.parametrize("call,code,needle", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_request(client, models, call, code, needle):
    with pytest.raises(GrayboxError) as e:
        call(client, models)
    assert e.value.code == code, e.value
    assert e.value.message and needle in e.value.message, e.value
    assert str(e.value) == f"{code}: {e.value.message}"


@pytest.mark.parametrize("rpc", ["predict", "get_model"])
def test_empty_model_id_is_invalid_argument(client, rpc):
    with pytest.raises(GrayboxError) as e:
        client.predict("", X, U) if rpc == "predict" else client.get_model("")
    assert e.value.code == "INVALID_ARGUMENT" and "model_id" in e.value.message


def test_outputs_outside_the_models_range_are_errors_not_numbers(client, models):
    """Finite but absurd inputs make the dynamics overflow: the caller must get an error
    naming the field, never NaN states with an OK status."""
    huge_x, huge_u = [1e300, 0.0, 1e300, 0.0], [1e300, 0.0]
    for call in (lambda: client.predict(models.wb, huge_x, huge_u),
                 lambda: client.linearize(models.wb, huge_x, huge_u)):
        with pytest.raises(GrayboxError) as e:
            call()
        assert e.value.code == "INVALID_ARGUMENT" and "x" in e.value.message, e.value
    xbar = np.full((3, 4), 1e200)
    with pytest.raises(GrayboxError) as e:
        client.tvlqr(models.wb, xbar, np.zeros((2, 2)), np.eye(4), np.eye(2), np.eye(4))
    assert e.value.code == "INVALID_ARGUMENT" and "x_bar" in e.value.message, e.value
    # A rollout whose state blows up stops with an error at the step where it happened.
    with pytest.raises(GrayboxError) as e:
        client.rollout(models.wb, [0.1, 0.0, 0.0, 0.0], np.full((2000, 2), 1e6))
    assert e.value.code == "INVALID_ARGUMENT" and "non-finite at step" in e.value.message, e.value


def test_client_refuses_both_u_and_policy(client, models):
    with pytest.raises(ValueError):
        client.rollout(models.wb, X, u=[U], policy=policy())


def test_a_job_that_has_not_succeeded_is_failed_precondition(server, client, models):
    # With one worker the models' jobs are done, so this one is queued or running: either
    # way it has no model. Submitted here, cancelled before the test ends.
    status, job = server.rest.post("/v1/jobs", {
        "dataset_id": models.dataset_id, "model": "MVF",
        "training": {"epochs": 100_000, "batch_size": 64}})
    assert status == 201, job
    jid = job["id"]
    calls = {
        "predict": lambda: client.predict(jid, X, U),
        "linearize": lambda: client.linearize(jid, X, U),
        "rollout": lambda: client.rollout(jid, X, u=[U]),
        "tvlqr": lambda: tvlqr(client, jid),
        "get_model": lambda: client.get_model(jid),
    }
    try:
        for name, call in calls.items():
            with pytest.raises(GrayboxError) as e:
                call()
            assert e.value.code == "FAILED_PRECONDITION", (name, e.value)
            assert jid in e.value.message, (name, e.value)
    finally:
        status, body = server.rest.post(f"/v1/jobs/{jid}/cancel")
    assert status == 200, body
    assert server.rest.wait_job(jid)["state"] == "cancelled"
    with pytest.raises(GrayboxError) as e:
        client.predict(jid, X, U)
    assert e.value.code == "FAILED_PRECONDITION" and "cancelled" in e.value.message
