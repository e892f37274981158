"""Ensembles through the service and graybox_client: a W-B ensemble's Predict against the
closed-form double pendulum at each member's own learned parameters (the members' mean and
their spread), and a single model asked for its members."""

import numpy as np
import pytest

from conftest import rel
from dp_reference import PARAMS, dp_rk4
from graybox_client import GrayboxError


@pytest.fixture(scope="module")
def ensemble(server, models):
    status, job = server.rest.post("/v1/jobs", {
        "dataset_id": models.dataset_id, "model": "W-B", "template": "double_pendulum",
        "training": {"epochs": 2, "batch_size": 64, "lr": 0.01, "ensemble": 3}})
    assert status == 201, job
    done = server.rest.wait_job(job["id"])
    assert done["state"] == "succeeded", done
    return done["model_id"]


def test_an_ensembles_predict_is_its_members_mean_with_their_spread(client, ensemble):
    info = client.get_model(ensemble)
    members = info.metrics["ensemble"]["members"]
    assert len(members) == 3
    rng = np.random.default_rng(2)
    x = np.column_stack([rng.uniform(-np.pi, np.pi, (8, 2)), rng.uniform(-10, 10, (8, 2))])
    u = rng.normal(0.0, 50.0, (8, 2))
    # Each member is the closed form at its own parameters (bootstrap resamples differ).
    want = np.array([dp_rk4([m["physical_parameters"][k] for k in PARAMS], x, u, info.dt)
                     for m in members])
    assert rel(want[0], want[1]) > 1e-6, "the members differ"
    mean, std, each = client.predict(ensemble, x, u, return_std=True, members=True)
    assert each.shape == (3, 8, 4) and std.shape == (8, 4)
    assert rel(each, want) < 1e-9
    assert rel(mean, want.mean(axis=0)) < 1e-9
    assert rel(std, want.std(axis=0, ddof=1)) < 1e-6
    # One state: the batch's first row, and plain predict is the same mean.
    m0, s0, e0 = client.predict(ensemble, x[0], u[0], return_std=True, members=True)
    assert e0.shape == (3, 4) and rel(m0, mean[0]) < 1e-12 and rel(s0, std[0]) < 1e-12
    assert np.array_equal(client.predict(ensemble, x, u), mean)
    # The report gives each parameter's mean and spread across the members.
    spread = info.metrics["ensemble"]["physical_parameters"]
    for k in PARAMS:
        values = [m["physical_parameters"][k] for m in members]
        assert rel(spread[k]["mean"], np.mean(values)) < 1e-12
        assert rel(spread[k]["std"], np.std(values, ddof=1)) < 1e-9


def test_a_single_model_is_one_member_with_no_spread(client, models):
    x, u = np.array([0.3, -0.6, 2.0, -1.0]), np.array([15.0, -40.0])
    alone = client.predict(models.mvf, x, u)
    mean, std, each = client.predict(models.mvf, x, u, return_std=True, members=True)
    assert np.array_equal(mean, alone) and np.array_equal(each, alone[None, :])
    assert np.array_equal(std, np.zeros(4))


def test_particles_follow_the_members_round_robin(client, ensemble, models):
    info = client.get_model(ensemble)
    params = [[m["physical_parameters"][k] for k in PARAMS]
              for m in info.metrics["ensemble"]["members"]]
    rng = np.random.default_rng(3)
    x0, u = np.array([0.3, -0.6, 1.0, -0.5]), rng.normal(0.0, 20.0, (20, 2))

    def closed_form(p):
        xs = [x0]
        for t in range(len(u)):
            xs.append(dp_rk4(p, xs[-1][None, :], u[t][None, :], info.dt)[0])
        return np.array(xs)

    each = [closed_form(p) for p in params]
    # Six particles, two per member (particle p follows member p mod 3).
    particles = np.array([each[p % 3] for p in range(6)])
    mean, std, applied = client.rollout(ensemble, x0, u=u, particles=6, with_inputs=True)
    assert mean.shape == std.shape == (21, 4)
    assert rel(mean, particles.mean(axis=0)) < 1e-9
    assert rel(std, particles.std(axis=0, ddof=1)) < 1e-6 and std[-1].min() > 0
    # The particles share the open-loop inputs: their mean is u to rounding.
    assert np.array_equal(std[0], np.zeros(4)) and rel(applied, u) < 1e-14
    # Small chunks stream the same particles.
    chunked, _ = client.rollout(ensemble, x0, u=u, particles=6, chunk=3)
    assert np.array_equal(chunked, mean)
    # A single model's particles all follow it: its own rollout, no spread.
    alone = client.rollout(models.mvf, x0, u=u)
    same, spread = client.rollout(models.mvf, x0, u=u, particles=4)
    assert rel(same, alone) < 1e-12 and np.abs(spread).max() <= 1e-12 * np.abs(alone).max()
    for bad in (0, 1025):
        with pytest.raises(GrayboxError) as e:
            client.rollout(ensemble, x0, u=u, particles=bad)
        assert e.value.code == "INVALID_ARGUMENT" and "particles" in str(e.value), e.value


def test_a_plan_minimizes_the_members_mean_cost_when_asked(client, ensemble):
    info = client.get_model(ensemble)
    params = [[m["physical_parameters"][k] for k in PARAMS]
              for m in info.metrics["ensemble"]["members"]]
    T, goal = 10, np.array([np.pi, 0.0, 0.0, 0.0])
    Q, R, Qf = np.diag([1, 1, 0.1, 0.1]), 1e-4 * np.eye(2), np.diag([1000, 1000, 100, 100])
    x0 = np.zeros(4)

    def rollouts(u):
        """Every member's closed-form rollout of u from x0: [K, T+1, 4]."""
        out = []
        for p in params:
            xs = [x0]
            for t in range(T):
                xs.append(dp_rk4(p, xs[-1][None, :], u[t][None, :], info.dt)[0])
            out.append(xs)
        return np.array(out)

    def cost(x, u):
        d = x - goal
        return (np.einsum("ti,ij,tj->", d[:-1], Q, d[:-1]) + np.einsum("ti,ij,tj->", u, R, u)
                + d[-1] @ Qf @ d[-1])

    kw = dict(x0=x0, goal=goal, horizon=T, Q=Q, R=R, Qf=Qf, u_min=[-120, -120],
              u_max=[120, 120], max_iterations=30)
    plans = {c: client.plan(ensemble, **kw, ensemble_cost=c) for c in ("mean_dynamics", "mean")}
    for c, p in plans.items():
        xs = rollouts(p.u)
        # σ of the members' own rollouts of the plan's inputs (relative 1e-6: the closed form
        # and the service's evaluator differ in rounding, which σ's differences amplify).
        assert p.x_std.shape == (T + 1, 4)
        assert rel(p.x_std, xs.std(axis=0, ddof=1)) < 1e-6, c
    mean = plans["mean"]
    xs = rollouts(mean.u)
    assert rel(mean.x, xs.mean(axis=0)) < 1e-9
    # Its cost is the members' average cost; the mean dynamics' plan does no better on it, to
    # the planner's relative tolerance (1e-6: it stops when an iteration gains less).
    avg = lambda u: np.mean([cost(x, u) for x in rollouts(u)])
    assert abs(mean.cost - avg(mean.u)) <= 1e-7 * avg(mean.u)
    assert avg(mean.u) <= avg(plans["mean_dynamics"].u) * (1 + 1e-6)
    assert mean.K.shape == (T, 2, 4)
    with pytest.raises(GrayboxError) as e:
        client.plan(ensemble, **kw, ensemble_cost="median")
    assert e.value.code == "INVALID_ARGUMENT" and "ensemble_cost" in str(e.value), e.value
