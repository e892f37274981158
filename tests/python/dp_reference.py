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


def dp_energy(p, q, qd, u):
    """The double pendulum's energies from its rods' kinematics (centres of mass and angular
    velocities, not its mass matrix), zero potential at the pivot's height, and the terms of
    M q̈ + c + ∇V = F from the closed form above; batched."""
    m1, m2, l1, l2, g, b1, b2, e1, e2 = p
    q1, q12 = q[:, 0], q[:, 0] + q[:, 1]
    w1, w12 = qd[:, 0], qd[:, 0] + qd[:, 1]
    # Rod centres' velocities: d/dt of (l/2)(sin, −cos) chained down the pendulum.
    v1 = 0.5 * l1 * w1[:, None] * np.column_stack([np.cos(q1), np.sin(q1)])
    v2 = (l1 * w1[:, None] * np.column_stack([np.cos(q1), np.sin(q1)])
          + 0.5 * l2 * w12[:, None] * np.column_stack([np.cos(q12), np.sin(q12)]))
    kinetic = (0.5 * m1 * (v1 ** 2).sum(1) + 0.5 * m1 * l1 ** 2 / 12 * w1 ** 2
               + 0.5 * m2 * (v2 ** 2).sum(1) + 0.5 * m2 * l2 ** 2 / 12 * w12 ** 2)
    potential = -g * (m1 * 0.5 * l1 * np.cos(q1) + m2 * (l1 * np.cos(q1) + 0.5 * l2 * np.cos(q12)))
    i1, i2 = m1 * l1 * l1 / 3, m2 * l2 * l2 / 3
    c2 = np.cos(q[:, 1])
    m11 = i1 + i2 + m2 * l1 * l1 + m2 * l1 * l2 * c2
    m12 = i2 + 0.5 * m2 * l1 * l2 * c2
    qdd = dp_accel(p, q, qd, u)
    inertial = np.column_stack([m11 * qdd[:, 0] + m12 * qdd[:, 1], m12 * qdd[:, 0] + i2 * qdd[:, 1]])
    h = m2 * l1 * l2 * np.sin(q[:, 1])
    coriolis = np.column_stack([-h * qd[:, 0] * qd[:, 1] - 0.5 * h * qd[:, 1] ** 2,
                                0.5 * h * qd[:, 0] ** 2])
    s1, s12 = np.sin(q1), np.sin(q12)
    gravity = np.column_stack([0.5 * m1 * g * l1 * s1 + m2 * g * (l1 * s1 + 0.5 * l2 * s12),
                               0.5 * m2 * g * l2 * s12])
    bu = np.column_stack([b1 * u[:, 0], b2 * u[:, 1]])
    damping = np.column_stack([e1 * qd[:, 0], e2 * qd[:, 1]])
    return {"kinetic": kinetic, "potential": potential, "inertial": inertial,
            "coriolis": coriolis, "gravity": gravity, "input": bu, "damping": damping}


def dp_inverse(p, q, qd, qdd):
    """The generalized force that gives accelerations qdd: M q̈ + c + ∇V less the damping η q̇
    (F at u = 0), from the closed form's terms; batched."""
    m1, m2, l1, l2, g, b1, b2, e1, e2 = p
    i1, i2 = m1 * l1 * l1 / 3, m2 * l2 * l2 / 3
    c2 = np.cos(q[:, 1])
    m11 = i1 + i2 + m2 * l1 * l1 + m2 * l1 * l2 * c2
    m12 = i2 + 0.5 * m2 * l1 * l2 * c2
    h = m2 * l1 * l2 * np.sin(q[:, 1])
    s1, s12 = np.sin(q[:, 0]), np.sin(q[:, 0] + q[:, 1])
    tau1 = (m11 * qdd[:, 0] + m12 * qdd[:, 1] - h * qd[:, 0] * qd[:, 1] - 0.5 * h * qd[:, 1] ** 2
            + 0.5 * m1 * g * l1 * s1 + m2 * g * (l1 * s1 + 0.5 * l2 * s12) - e1 * qd[:, 0])
    tau2 = (m12 * qdd[:, 0] + i2 * qdd[:, 1] + 0.5 * h * qd[:, 0] ** 2
            + 0.5 * m2 * g * l2 * s12 - e2 * qd[:, 1])
    return np.column_stack([tau1, tau2])
