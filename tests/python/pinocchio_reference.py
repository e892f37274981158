"""Pinocchio's forward dynamics of a URDF in graybox's coordinates, with graybox's joint force
law (docs/robots.md#joint-forces): the reference of test_robots.py and scripts/urdf_survey.py."""

import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin

COULOMB_EPS = 0.01
DT = 0.01


def joint_forces(urdf, coords):
    """q̇ ↦ F(q̇) per coordinate: each movable joint's −d v − f tanh(v/ε) at its velocity v =
    k q̇_c (k = 1, or a mimic joint's multiplier for the coordinate c it follows), entering c
    times k."""
    terms = []
    for j in ET.fromstring(urdf).findall("joint"):
        if j.get("type") == "fixed":
            continue
        dyn, mimic = j.find("dynamics"), j.find("mimic")
        d = float(dyn.get("damping", 0)) if dyn is not None else 0.0
        f = float(dyn.get("friction", 0)) if dyn is not None else 0.0
        source, k = (mimic.get("joint"), float(mimic.get("multiplier", 1))) if mimic is not None \
            else (j.get("name"), 1.0)
        terms.append((coords.index(source), k, d, f))

    def forces(qd):
        out = np.zeros(len(coords))
        for c, k, d, f in terms:
            v = k * qd[c]
            out[c] += k * (-d * v - f * np.tanh(v / COULOMB_EPS))
        return out
    return forces


class Reference:
    """Pinocchio's forward dynamics of a URDF in graybox's coordinates (mapped by joint name;
    a continuous joint is (cos, sin) in Pinocchio). Its `aba` does not take mimic joints, so
    q̈ = M⁻¹(τ − h) from `crba` and `nonLinearEffects`."""

    def __init__(self, urdf, coords, kinds):
        self.model = pin.buildModelFromXML(urdf, mimic=True)
        # graybox's `<dynamics armature>` (Pinocchio's reader skips the attribute): the
        # rotor inertia Pinocchio adds to M's diagonal, RNEA, ABA and the kinetic energy.
        for j in ET.fromstring(urdf).findall("joint"):
            dyn = j.find("dynamics")
            if dyn is not None and dyn.get("armature") is not None:
                idx = self.model.joints[self.model.getJointId(j.get("name"))].idx_v
                self.model.armature[idx] = float(dyn.get("armature"))
        self.data = self.model.createData()
        self.coords, self.kinds = coords, kinds
        self.forces = joint_forces(urdf, coords)
        assert self.model.nv == len(coords)

    def state(self, q, qd):
        """Pinocchio's configuration and velocity for graybox's q and q̇, and the order that
        maps Pinocchio's velocity coordinates back to graybox's."""
        qp, vp = np.zeros(self.model.nq), np.zeros(self.model.nv)
        for name, kind, qi, vi in zip(self.coords, self.kinds, q, qd):
            j = self.model.joints[self.model.getJointId(name)]
            if kind == "continuous":
                qp[j.idx_q], qp[j.idx_q + 1] = np.cos(qi), np.sin(qi)
            else:
                qp[j.idx_q] = qi
            vp[j.idx_v] = vi
        order = [self.model.joints[self.model.getJointId(n)].idx_v for n in self.coords]
        return qp, vp, order

    def mass(self, qp):
        m = pin.crba(self.model, self.data, qp)
        return np.triu(m) + np.triu(m, 1).T

    def accel(self, q, qd, u):
        qp, vp, order = self.state(q, qd)
        h = pin.nonLinearEffects(self.model, self.data, qp, vp)
        tau = np.zeros(self.model.nv)
        tau[order] = u + self.forces(qd)
        return np.linalg.solve(self.mass(qp), tau - h)[order]

    def inverse(self, q, qd, qdd):
        """The force graybox's inverse dynamics gives: Pinocchio's `rnea` (M q̈ + c + g) less
        the joints' passive forces, in graybox's coordinates."""
        qp, vp, order = self.state(q, qd)
        ap = np.zeros(self.model.nv)
        ap[order] = qdd
        tau = pin.rnea(self.model, self.data, qp, vp, ap)
        return tau[order] - self.forces(qd)

    def energy(self, q, qd, u):
        """T, V and the terms of M q̈ + c + g = τ in graybox's coordinates, from Pinocchio's
        `computeKineticEnergy`, `computePotentialEnergy`, `crba`, `nonLinearEffects` and
        `computeGeneralizedGravity` (c is nonLinearEffects less gravity)."""
        qp, vp, order = self.state(q, qd)
        gravity = pin.computeGeneralizedGravity(self.model, self.data, qp)
        qdd = np.zeros(self.model.nv)
        qdd[order] = self.accel(q, qd, u)
        return {
            "kinetic": pin.computeKineticEnergy(self.model, self.data, qp, vp),
            "potential": pin.computePotentialEnergy(self.model, self.data, qp),
            "inertial": (self.mass(qp) @ qdd)[order],
            "coriolis": (pin.nonLinearEffects(self.model, self.data, qp, vp) - gravity)[order],
            "gravity": gravity[order],
            "friction": self.forces(qd),
        }

    def rk4(self, x, u):
        n = len(self.coords)

        def f(x):
            return np.concatenate([x[n:], self.accel(x[:n], x[n:], u)])
        k1 = f(x)
        k2 = f(x + 0.5 * DT * k1)
        k3 = f(x + 0.5 * DT * k2)
        k4 = f(x + DT * k3)
        return x + DT / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
