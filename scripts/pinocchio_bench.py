"""Pinocchio's figures beside `graybox-lab bench infer --model` (run both in one sitting; the
figures in README and bench-results were measured so):

    /path/to/venv-with-pin/bin/python scripts/pinocchio_bench.py tests/fixtures/urdf/robots/ur5.urdf ...

Per robot, the median µs of: `aba` (one forward dynamics), `computeABADerivatives`, one RK4
step of Δt = 0.01 written in numpy over `aba` with graybox's joint forces (the Python-side
counterpart of Predict 1 state), 1024 such steps (Predict 1024) and a 500-step rollout, and
the step's Jacobian from `computeABADerivatives` at each RK4 stage chained in numpy (the
counterpart of Linearize 1 state). Every call includes the Python binding's overhead, as a
Python controller would pay it. The Pinocchio version is printed with the figures.
"""

import json
import sys
import time

import numpy as np
import pinocchio as pin

DT = 0.01
COULOMB_EPS = 0.01


def median_us(f, calls):
    for _ in range(max(calls // 10, 1)):
        f()
    times = []
    for _ in range(calls):
        t = time.perf_counter_ns()
        f()
        times.append((time.perf_counter_ns() - t) / 1e3)
    return float(np.median(times))


def bench(path, calls):
    model = pin.buildModelFromUrdf(path)
    data = model.createData()
    assert model.nq == model.nv, "a robot without continuous joints (q is then not (cos, sin))"
    n = model.nv
    damping, friction = np.array(model.damping), np.array(model.friction)
    rng = np.random.default_rng(0)
    q, v, u = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)

    def accel(q, v, u):
        tau = u - damping * v - friction * np.tanh(v / COULOMB_EPS)
        return pin.aba(model, data, q, v, tau)

    def step(q, v, u):
        k1q, k1v = v, accel(q, v, u)
        k2q, k2v = v + 0.5 * DT * k1v, accel(q + 0.5 * DT * k1q, v + 0.5 * DT * k1v, u)
        k3q, k3v = v + 0.5 * DT * k2v, accel(q + 0.5 * DT * k2q, v + 0.5 * DT * k2v, u)
        k4q, k4v = v + DT * k3v, accel(q + DT * k3q, v + DT * k3v, u)
        return (q + DT / 6 * (k1q + 2 * k2q + 2 * k3q + k4q),
                v + DT / 6 * (k1v + 2 * k2v + 2 * k3v + k4v))

    def stage_jacobian(q, v, u):
        """∂q̈/∂(q, q̇, u) at one stage: Pinocchio's ABA derivatives with the joint forces'."""
        tau = u - damping * v - friction * np.tanh(v / COULOMB_EPS)
        pin.computeABADerivatives(model, data, q, v, tau)
        minv = data.Minv.copy()
        minv = np.triu(minv) + np.triu(minv, 1).T
        dtau_dv = -np.diag(damping + friction / COULOMB_EPS * (1 - np.tanh(v / COULOMB_EPS) ** 2))
        return np.hstack([data.ddq_dq, data.ddq_dv + minv @ dtau_dv, minv])

    def linearize(q, v, u):
        """The RK4 step's [∂x'/∂x, ∂x'/∂u] by the chain rule through the four stages."""
        z = np.hstack([np.eye(2 * n), np.zeros((2 * n, n))])  # ∂x/∂(x, u)
        du = np.hstack([np.zeros((n, 2 * n)), np.eye(n)])
        ks, x0, x = [], np.concatenate([q, v]), np.concatenate([q, v])
        dx = z
        for c in (0.5, 0.5, 1.0, None):
            j = stage_jacobian(x[:n], x[n:], u)
            a = accel(x[:n], x[n:], u)
            dk = np.vstack([dx[n:], j @ np.vstack([dx, du])])
            ks.append((np.concatenate([x[n:], a]), dk))
            if c is not None:
                x = x0 + c * DT * ks[-1][0]
                dx = z + c * DT * dk
        w = (1, 2, 2, 1)
        return z + DT / 6 * sum(wi * k[1] for wi, k in zip(w, ks))

    def predict_1024():
        for _ in range(1024):
            step(q, v, u)

    def rollout_500():
        s = (q, v)
        for _ in range(500):
            s = step(*s, u)

    # The reference must be right before it is timed: its Jacobian against central differences.
    h, x = 1e-6, np.concatenate([q, v, u])
    fd = np.zeros((2 * n, 3 * n))
    for k in range(3 * n):
        e = np.zeros(3 * n)
        e[k] = h
        p, m = step(*np.split(x + e, 3)), step(*np.split(x - e, 3))
        fd[:, k] = (np.concatenate(p) - np.concatenate(m)) / (2 * h)
    assert np.abs(linearize(q, v, u) - fd).max() < 1e-6 * max(1, np.abs(fd).max())

    def aba_derivatives():
        tau = u - damping * v - friction * np.tanh(v / COULOMB_EPS)
        pin.computeABADerivatives(model, data, q, v, tau)

    few = max(calls // 100, 5)
    return {
        "robot": model.name, "n": n, "pinocchio": pin.__version__,
        "aba_us": median_us(lambda: accel(q, v, u), calls),
        "aba_derivatives_us": median_us(aba_derivatives, calls),
        "predict_1_us": median_us(lambda: step(q, v, u), calls),
        "predict_1024_us": median_us(predict_1024, few),
        "rollout_500_us": median_us(rollout_500, few),
        "linearize_1_us": median_us(lambda: linearize(q, v, u), calls),
    }


if __name__ == "__main__":
    for path in sys.argv[1:]:
        print(json.dumps(bench(path, 2000)), flush=True)
