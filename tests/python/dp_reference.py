"""The paper's double pendulum in closed form, independent of graybox: the reference the
Dynamics tests and scripts/dircol_learned.py compare with."""

import numpy as np

PARAMS = ["m1", "m2", "l1", "l2", "g", "b1", "b2", "eta1", "eta2"]


def dp_accel(p, q, qd, u):
    """The paper's double pendulum (rods), written out as in tests/common/mod.rs; batched."""
    m1, m2, l1, l2, g, b1, b2, e1, e2 = p
    i1, i2 = m1 * l1 * l1 / 3, m2 * l2 * l2 / 3
    c2 = np.cos(q[:, 1])
    m11 = i1 + i2 + m2 * l1 * l1 + m2 * l1 * l2 * c2
    m12 = i2 + 0.5 * m2 * l1 * l2 * c2
    m22 = i2
    h = m2 * l1 * l2 * np.sin(q[:, 1])
    cor1 = -h * qd[:, 0] * qd[:, 1] - 0.5 * h * qd[:, 1] ** 2
    cor2 = 0.5 * h * qd[:, 0] ** 2
    s1, s12 = np.sin(q[:, 0]), np.sin(q[:, 0] + q[:, 1])
    dv1 = 0.5 * m1 * g * l1 * s1 + m2 * g * (l1 * s1 + 0.5 * l2 * s12)
    dv2 = 0.5 * m2 * g * l2 * s12
    r1 = b1 * u[:, 0] + e1 * qd[:, 0] - cor1 - dv1
    r2 = b2 * u[:, 1] + e2 * qd[:, 1] - cor2 - dv2
    det = m11 * m22 - m12 * m12
    return np.column_stack([(m22 * r1 - m12 * r2) / det, (-m12 * r1 + m11 * r2) / det])


def dp_rk4(p, x, u, dt):
    def f(x):
        return np.hstack([x[:, 2:], dp_accel(p, x[:, :2], x[:, 2:], u)])
    k1 = f(x)
    k2 = f(x + dt / 2 * k1)
    k3 = f(x + dt / 2 * k2)
    k4 = f(x + dt * k3)
    return x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
