"""Every Dynamics RPC through graybox_client, against independent references: a closed-form
double pendulum with RK4 (the W-B model), Predict itself (Rollout), central differences
(Linearize), a numpy Riccati recursion and python-control's dlqr (Tvlqr)."""

import json
import math
import subprocess

import control
import numpy as np
import pytest

from conftest import rel
from dp_reference import PARAMS, dp_accel, dp_rk4
from graybox_client import Client, GrayboxError

X = np.array([[0.3, -0.6, 2.0, -1.0], [1.2, 0.4, -3.0, 0.5], [-2.0, 2.5, 0.1, 4.0]])
U = np.array([[15.0, -40.0], [0.0, 0.0], [-60.0, 25.0]])


def relp(a, b) -> float:
    """max|a − b| / max|b| (purely relative, for gains and cost-to-go)."""
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape, (a.shape, b.shape)
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def riccati(A, B, Q, R, Qf):
    """Standard form: K_t = (R + BᵀS_{t+1}B)⁻¹BᵀS_{t+1}A, S_t = Q + AᵀS_{t+1}(A − BK_t)."""
    T = len(A)
    K, S = [None] * T, [None] * (T + 1)
    S[T] = Qf
    for t in reversed(range(T)):
        a, b, s = A[t], B[t], S[t + 1]
        K[t] = np.linalg.solve(R + b.T @ s @ b, b.T @ s @ a)
        S[t] = Q + a.T @ s @ (a - b @ K[t])
    return np.array(K), np.array(S)


def nominal(T):
    """An arbitrary nominal (x̄, ū) of T steps: Tvlqr ignores defects."""
    t = np.arange(T + 1)
    xbar = np.column_stack([0.1 * t, -0.05 * t, 0.3 + 0 * t, -0.2 + 0 * t])
    ubar = np.column_stack([5.0 + t[:-1], -3.0 + 0 * t[:-1]])
    return xbar, ubar


@pytest.fixture(params=["wb", "mvf"])
def model(request, models):
    return getattr(models, request.param)


def test_get_model_by_model_and_by_job_id(client, models):
    for mid, job, name, mass in [(models.wb, models.wb_job, "W-B", "template"),
                                 (models.mvf, models.mvf_job, "MVF", "mlp")]:
        info = client.get_model(mid)
        assert (info.id, info.job_id, info.name, info.n, info.m, info.dt) == (mid, job, name, 2, 2, 0.01)
        assert info.spec["kind"] == "structured" and info.spec["mass"]["type"] == mass
        assert info.metrics["epochs"] == 2 and math.isfinite(info.metrics["best_val_loss"])
        assert info.created_at
        assert client.get_model(job) == info, "a succeeded job's id names its model"
    physical = client.get_model(models.wb).metrics["physical_parameters"]
    assert set(PARAMS) <= set(physical)


def test_list_models_follows_page_tokens_newest_first(client, models):
    page, token = client.list_models(page_size=1)
    assert len(page) == 1 and token
    ids = [m.id for m in client.iter_models(page_size=1)]
    assert len(ids) == len(set(ids)) and {models.wb, models.mvf} <= set(ids)
    assert ids.index(models.mvf) < ids.index(models.wb), "MVF was trained after W-B"
    everything, token = client.list_models()
    assert token == "" and [m.id for m in everything] == ids


def test_wb_predict_and_accel_equal_the_closed_form_with_learned_parameters(client, models):
    info = client.get_model(models.wb)
    p = [info.metrics["physical_parameters"][k] for k in PARAMS]
    rng = np.random.default_rng(1)
    x = np.column_stack([rng.uniform(-np.pi, np.pi, (16, 2)), rng.uniform(-10, 10, (16, 2))])
    u = rng.normal(0.0, 50.0, (16, 2))
    x_next, accel = client.predict(models.wb, x, u, want_accel=True)
    assert x_next.shape == (16, 4) and accel.shape == (16, 2)
    assert rel(accel, dp_accel(p, x[:, :2], x[:, 2:], u)) < 1e-9
    assert rel(x_next, dp_rk4(p, x, u, info.dt)) < 1e-9
    # q = 0, q̇ = 0, u = 0 is the hanging equilibrium.
    assert np.array_equal(client.predict(models.wb, np.zeros(4), np.zeros(2)), np.zeros(4))


def test_predict_single_points_equal_the_batch(client, model):
    x_next, accel = client.predict(model, X, U, want_accel=True)
    assert x_next.shape == (3, 4) and accel.shape == (3, 2) and np.isfinite(x_next).all()
    assert np.array_equal(client.predict(model, X, U), x_next), "want_accel does not change x'"
    for i in range(len(X)):
        xi, ai = client.predict(model, X[i], U[i], want_accel=True)
        assert xi.shape == (4,) and ai.shape == (2,)
        assert rel(xi, x_next[i]) <= 1e-12 and rel(ai, accel[i]) <= 1e-12


def test_predict_by_job_id_equals_by_model_id(client, models):
    assert np.array_equal(client.predict(models.wb_job, X, U), client.predict(models.wb, X, U))


def test_rollout_equals_repeated_predict(client, model):
    T = 60
    t = np.arange(T)
    u = np.column_stack([20 * np.sin(0.1 * t), -10 + 0 * t])
    x0 = np.array([0.4, -0.2, 1.0, 0.5])
    xs, us = client.rollout(model, x0, u=u, chunk=7, with_inputs=True)
    assert xs.shape == (T + 1, 4) and us.shape == (T, 2)
    assert np.array_equal(xs[0], x0) and np.array_equal(us, u)
    x = x0
    for k in range(T):
        x = client.predict(model, x, u[k])
        assert rel(x, xs[k + 1]) <= 1e-12, k
    assert np.array_equal(client.rollout(model, x0, u=u), xs), "chunking does not change states"


def test_rollout_under_a_tvlqr_policy(client, model):
    T = 40
    t = np.arange(T)
    ubar = np.column_stack([10 * np.sin(0.2 * t), 5 * np.cos(0.1 * t)])
    xbar = client.rollout(model, [0.5, -0.3, 0.2, 0.1], u=ubar)  # a feasible nominal
    Q, R, Qf = np.eye(4), 0.01 * np.eye(2), 10 * np.eye(4)
    K, S = client.tvlqr(model, xbar, ubar, Q, R, Qf)
    x0 = xbar[0] + np.array([1e-4, -1e-4, 2e-4, 0.0])
    xs, us = client.rollout(model, x0, policy=(xbar, ubar, K), chunk=16, with_inputs=True)
    assert xs.shape == (T + 1, 4) and us.shape == (T, 2)
    dx, du = xs - xbar, us - ubar
    assert rel(du, -np.einsum("tij,tj->ti", K, dx[:-1])) <= 1e-12, "u_t = ū_t − K_t(x_t − x̄_t)"
    assert rel(client.predict(model, xs[:-1], us), xs[1:]) <= 1e-12
    assert np.array_equal(client.rollout(model, x0, policy=(xbar[:-1], ubar, K)), xs), \
        "x̄ may have T rows"
    # Near the nominal, the closed-loop cost is the quadratic form TVLQR predicts.
    cost = sum(dx[k] @ Q @ dx[k] + du[k] @ R @ du[k] for k in range(T)) + dx[T] @ Qf @ dx[T]
    assert abs(cost - dx[0] @ S[0] @ dx[0]) <= 1e-3 * cost


def test_linearize_matches_central_differences_of_predict(client, model):
    A, B = client.linearize(model, X, U)
    assert A.shape == (3, 4, 4) and B.shape == (3, 4, 2)
    for i in range(len(X)):
        a, b = client.linearize(model, X[i], U[i])
        assert rel(a, A[i]) <= 1e-12 and rel(b, B[i]) <= 1e-12
    h = 1e-6
    z = np.hstack([X, U])  # [3, 6]: every perturbed point in one Predict batch
    plus = (z[:, None, :] + h * np.eye(6)).reshape(-1, 6)
    minus = (z[:, None, :] - h * np.eye(6)).reshape(-1, 6)
    fp = client.predict(model, plus[:, :4], plus[:, 4:]).reshape(3, 6, 4)
    fm = client.predict(model, minus[:, :4], minus[:, 4:]).reshape(3, 6, 4)
    fd = ((fp - fm) / (2 * h)).transpose(0, 2, 1)  # [3, 4 outputs, 6 inputs]
    ours = np.concatenate([A, B], axis=2)
    for i in range(len(X)):
        assert rel(ours[i], fd[i]) < 1e-6, i


@pytest.mark.parametrize("q", ["identity", "singular"])
def test_tvlqr_equals_riccati_on_the_services_linearization(client, model, q):
    T = 25
    xbar, ubar = nominal(T)
    Q = np.eye(4) if q == "identity" else np.diag([1.0, 1.0, 0.0, 0.0])
    R, Qf = np.diag([0.01, 0.02]), 10 * np.eye(4)
    K, S = client.tvlqr(model, xbar, ubar, Q, R, Qf)
    assert K.shape == (T, 2, 4) and S.shape == (T + 1, 4, 4)
    assert np.array_equal(S[T], Qf) and np.array_equal(S, S.transpose(0, 2, 1))
    A, B = client.linearize(model, xbar[:-1], ubar)
    K_ref, S_ref = riccati(A, B, Q, R, Qf)
    assert relp(K, K_ref) < 1e-8
    assert relp(S, S_ref) < 1e-8
    # The linearized closed loop's cost from any δx0 is δx0ᵀS_0δx0.
    dx0 = np.array([0.3, -0.1, 0.5, 0.2])
    x, cost = dx0, 0.0
    for t in range(T):
        du = -K[t] @ x
        cost += x @ Q @ x + du @ R @ du
        x = A[t] @ x + B[t] @ du
    cost += x @ Qf @ x
    assert abs(cost - dx0 @ S[0] @ dx0) <= 1e-9 * cost


def test_tvlqr_over_a_long_constant_horizon_converges_to_dlqr(client, models):
    A, B = client.linearize(models.wb, np.zeros(4), np.zeros(2))  # at the equilibrium
    Q, R = np.diag([1e3, 1e3, 1.0, 1.0]), 1e-5 * np.eye(2)
    T = 300
    K, S = client.tvlqr(models.wb, np.zeros((T + 1, 4)), np.zeros((T, 2)), Q, R, np.zeros((4, 4)))
    K_inf, S_inf, _ = control.dlqr(A, B, Q, R)
    assert relp(K[0], K_inf) < 1e-9
    assert relp(S[0], S_inf) < 1e-9


def test_plan_end_to_end(client, models):
    """Client.plan on a served model: shapes, bounds, non-increasing costs, the goal error as
    defined, gains equal to Tvlqr's along the returned plan, and a policy rollout that follows
    the plan from its own start."""
    Q, R, Qf = np.diag([1, 1, 0.1, 0.1]), 1e-4 * np.eye(2), np.diag([1000, 1000, 100, 100.0])
    goal = np.array([np.pi, 0, 0, 0])
    p = client.plan(models.wb, np.zeros(4), goal, 21, Q, R, Qf, u_min=[-120, -120],
                    u_max=[120, 120])
    assert p.x.shape == (22, 4) and p.u.shape == (21, 2) and p.K.shape == (21, 2, 4)
    assert np.all(np.abs(p.u) <= 120)
    assert np.all(np.diff(p.costs) <= 0) and p.costs[-1] == p.cost
    assert p.iterations == len(p.costs) - 1
    assert p.goal_error == pytest.approx(np.linalg.norm(p.x[-1] - goal), rel=1e-12)
    K, _ = client.tvlqr(models.wb, p.x, p.u, Q, R, Qf)
    assert rel(p.K, K) < 1e-12
    xs = client.rollout(models.wb, p.x[0], policy=(p.x, p.u, p.K))
    assert rel(xs, p.x) < 1e-9, "the plan is a rollout of the model"
    with pytest.raises(GrayboxError) as e:
        client.plan(models.wb, np.zeros(4), goal, 21, Q, R, Qf, u_min=[1, 1], u_max=[0, 0])
    assert e.value.code == "INVALID_ARGUMENT" and "u_min" in e.value.message
    with pytest.raises(GrayboxError) as e:
        client.plan(models.wb, np.zeros(4), goal, 10_001, Q, R, Qf)
    assert e.value.code == "RESOURCE_EXHAUSTED" and "--max-plan-horizon" in e.value.message
    with pytest.raises(GrayboxError) as e:
        client.plan("mdl_nonexistent", np.zeros(4), goal, 21, Q, R, Qf)
    assert e.value.code == "NOT_FOUND", e.value
    with pytest.raises(GrayboxError) as e:
        client.plan(models.wb, np.zeros(4), goal, 21, -Q, R, Qf)
    assert e.value.code == "INVALID_ARGUMENT" and "Q" in e.value.message


def test_plan_by_direct_collocation(server, client, models):
    """method="dircol" on a served model: the swing-up converges with its defects met, within
    the bounds, with Tvlqr's gains along it, and tracked by them on the model it ends where
    the plan ends; the default method is iLQR's answer; bad methods and initial states are
    INVALID_ARGUMENT naming the field; the caller's deadline ends a long one. (This model,
    trained for two epochs, cannot swing up within the bounds by either method: both plans
    end ~3 away from the goal at the same cost.)"""
    Q, R, Qf = np.diag([1, 1, 0.1, 0.1]), 1e-4 * np.eye(2), np.diag([1000, 1000, 100, 100.0])
    goal = np.array([np.pi, 0, 0, 0])
    bounds = dict(u_min=[-120, -120], u_max=[120, 120])
    line = np.linspace(np.zeros(4), goal, 22)
    p = client.plan(models.wb, np.zeros(4), goal, 21, Q, R, Qf, method="dircol", x_init=line,
                    **bounds)
    assert p.method == "dircol" and p.converged, p
    assert p.x.shape == (22, 4) and p.u.shape == (21, 2) and p.K.shape == (21, 2, 4)
    assert p.constraint_violation < 1e-6 and np.all(np.abs(p.u) <= 120)
    assert p.goal_error == pytest.approx(np.linalg.norm(p.x[-1] - goal), rel=1e-12)
    K, _ = client.tvlqr(models.wb, p.x, p.u, Q, R, Qf)
    assert rel(p.K, K) < 1e-12
    xs = client.rollout(models.wb, p.x[0], policy=(p.x, p.u, p.K))
    # TVLQR absorbs collocation's departure from the one-step map (rollout_deviation):
    # 0.05 rad and 0.2 rad/s, the bounds on a tracked end.
    end = xs[-1] - p.x[-1]
    assert np.all(np.abs(end[:2]) < 0.05) and np.all(np.abs(end[2:]) < 0.2), end
    assert p.rollout_deviation > 0

    default = client.plan(models.wb, np.zeros(4), goal, 21, Q, R, Qf, **bounds)
    ilqr = client.plan(models.wb, np.zeros(4), goal, 21, Q, R, Qf, method="ilqr", **bounds)
    assert default.method == "ilqr" and np.array_equal(default.u, ilqr.u)
    assert default.constraint_violation == 0 and default.rollout_deviation == 0
    for kwargs, field in [(dict(method="shooting"), "method"),
                          (dict(method="dircol", x_init=np.zeros((21, 4))), "x_init"),
                          (dict(x_init=np.zeros((22, 4))), "x_init"),
                          (dict(x_min=-np.ones(4), x_max=np.ones(4)), "x_min"),
                          (dict(method="dircol", x_min=np.ones(4)), "x0")]:
        with pytest.raises(GrayboxError) as e:
            client.plan(models.wb, np.zeros(4), goal, 21, Q, R, Qf, **kwargs)
        assert e.value.code == "INVALID_ARGUMENT" and field in e.value.message, e.value
    with Client(server.grpc_target, timeout=0.2) as c:
        with pytest.raises(GrayboxError) as e:
            c.plan(models.wb, np.zeros(4), goal, 2000, Q, R, Qf, restarts=50, method="dircol")
        assert e.value.code == "DEADLINE_EXCEEDED", e.value


def test_plan_time_limit_and_deadline(server, models):
    Q, R, Qf = np.diag([1, 1, 0.1, 0.1]), 1e-4 * np.eye(2), np.diag([1000, 1000, 100, 100.0])
    goal = [np.pi, 0, 0, 0]
    with Client(server.grpc_target, timeout=300) as c:
        p = c.plan(models.wb, np.zeros(4), goal, 200, Q, R, Qf, restarts=50, time_limit_ms=50)
        assert not p.converged and np.isfinite(p.x).all() and p.x.shape == (201, 4)
    with Client(server.grpc_target, timeout=0.05) as c:
        with pytest.raises(GrayboxError) as e:
            c.plan(models.wb, np.zeros(4), goal, 2000, Q, R, Qf, restarts=50)
        assert e.value.code == "DEADLINE_EXCEEDED", e.value


def test_evaluate_against_horizon_equals_a_numpy_rollout(server, client, models):
    """POST /v1/models/{id}/evaluate: from every window start of the dataset's trajectories,
    the W-B model's open-loop rollout under the recorded inputs, its errors after h steps,
    against the closed-form double pendulum rolled out in numpy with the learned values."""
    data = server.tmp / "trajectories.json"
    subprocess.run([server.binary, "simulate", "--template", "double_pendulum",
                    "--trajectories", "3", "--steps", "40", "--qdot-range", "2",
                    "--u-std", "30", "--seed", "5", "--out", str(data)],
                   check=True, capture_output=True)
    status, ds = server.rest.post("/v1/datasets", raw=data.read_bytes())
    assert status == 201, ds
    horizons = [20, 1, 5]
    status, ev = server.rest.post(f"/v1/models/{models.wb}/evaluate",
                                  {"dataset_id": ds["id"], "horizons": horizons})
    assert status == 200, ev
    assert [e["horizon"] for e in ev["items"]] == [1, 5, 20]

    info = client.get_model(models.wb)
    p = [info.metrics["physical_parameters"][k] for k in PARAMS]
    trajs = json.loads(data.read_text())["trajectories"]
    for item in ev["items"]:
        h = item["horizon"]
        pos, vel = [], []
        for t in trajs:
            q, qd, u = (np.array(t[k]) for k in ("q", "qdot", "u"))
            starts = np.arange(len(u) - h + 1)
            x = np.column_stack([q[starts], qd[starts]])
            for k in range(h):
                x = dp_rk4(p, x, u[starts + k], info.dt)
            dq = x[:, :2] - q[starts + h]
            dq = np.arctan2(np.sin(dq), np.cos(dq))  # both coordinates are angles
            pos.extend(np.linalg.norm(dq, axis=1))
            vel.extend(np.linalg.norm(x[:, 2:] - qd[starts + h], axis=1))
        assert item["windows"] == len(pos) == 3 * (40 - h + 1) and item["diverged"] == 0
        assert item["seconds"] == pytest.approx(h * info.dt, rel=1e-12)
        # Both f64; the service steps the windows as one SIMD batch: last-bit differences.
        for key, ref in [("position_median", np.median(pos)), ("position_mean", np.mean(pos)),
                         ("velocity_median", np.median(vel)), ("velocity_mean", np.mean(vel))]:
            assert item[key] == pytest.approx(ref, rel=1e-9), (h, key)
