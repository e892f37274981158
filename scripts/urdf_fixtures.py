#!/usr/bin/env python3
"""Writes the rigid-body fixtures in tests/fixtures/urdf/*.json from the URDFs beside them,
with Pinocchio as the reference (read by tests/suite/urdf.rs).

For each URDF and 50 random states (q, q̇): M(q) (`crba`, which fills the upper triangle
only: symmetrised here), g(q) = ∂V/∂q (`computeGeneralizedGravity`) and C(q, q̇)q̇
(`nonLinearEffects` − g), in graybox's coordinate order: the movable joints depth-first from
the root, children in document order (mimic joints, which follow another joint, are not
coordinates: Pinocchio is built with its mimic support). Pinocchio orders siblings by name and gives a
continuous joint two position coordinates (cos θ, sin θ) and one velocity, so coordinates are
mapped by joint name (`getJointId`, `idx_q`, `idx_v`). Gravity is each file's (below). Each
state also has the kinetic energy T (from the bodies' velocities) and the potential energy V
(Σ −m g·c from the bodies' placements; `computePotentialEnergy` refuses mimic joints).

Every value is checked by a second method before it is written: M against the kinetic energy
½ q̇ᵀMq̇ from Pinocchio's body velocities (`forwardKinematics` with q̇, Σ ½ vᵀ𝕀v), and g
against central differences of that potential energy.

Floats are written with repr, so the f64 values round-trip. Deterministic (fixed seed). Run
with Pinocchio installed (`pip install pin==4.1.0 numpy==2.4.6`):

    python scripts/urdf_fixtures.py
"""

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin

ROOT = Path(__file__).resolve().parents[1]
DIR = ROOT / "tests" / "fixtures" / "urdf"
# point_masses has links without mass (a massless gimbal, a link without <inertial>, point
# masses): tests/suite/urdf_files/exact.rs holds it at rest with these g(q).
GRAVITY = {"arm4": [0.0, 0.0, -9.81], "tree": [0.3, -0.2, -9.81], "point_masses": [0.0, 0.0, -9.81]}
# Real robots' files (robots/README.md says where each comes from), fewer states: they are
# larger, and their joints are what is new, not the draws.
ROBOTS = ["ur5", "panda", "solo12", "kinova", "iiwa"]
STATES = 50
ROBOT_STATES = 20


def coordinates(urdf: str) -> list[tuple[str, str]]:
    """(name, type) of the movable joints, depth-first from the root, children in document
    order, as graybox numbers them."""
    robot = ET.fromstring(urdf)
    joints = robot.findall("joint")
    children = {j.find("child").get("link") for j in joints}
    roots = [l.get("name") for l in robot.findall("link") if l.get("name") not in children]
    assert len(roots) == 1, roots
    out = []

    def visit(link):
        for j in joints:
            if j.find("parent").get("link") == link:
                # A mimic joint follows another: not a coordinate.
                if j.get("type") != "fixed" and j.find("mimic") is None:
                    out.append((j.get("name"), j.get("type")))
                visit(j.find("child").get("link"))

    visit(roots[0])
    return out


def pin_state(model, coords, q, qd):
    qp, vp = np.zeros(model.nq), np.zeros(model.nv)
    for (name, kind), qi, vi in zip(coords, q, qd):
        j = model.joints[model.getJointId(name)]
        if kind == "continuous":
            qp[j.idx_q], qp[j.idx_q + 1] = np.cos(qi), np.sin(qi)
        else:
            qp[j.idx_q] = qi
        vp[j.idx_v] = vi
    return qp, vp


def potential(model, data, qp):
    """−Σ mᵢ gᵀ cᵢ over the bodies, from Pinocchio's placements (its `computePotentialEnergy`
    does not take mimic joints)."""
    pin.forwardKinematics(model, data, qp)
    return -sum(model.inertias[i].mass * model.gravity.linear @ data.oMi[i].act(model.inertias[i].lever)
                for i in range(1, model.njoints))


def main():
    rng = np.random.default_rng(20261124)
    cases = [(name, gravity, STATES) for name, gravity in GRAVITY.items()]
    cases += [(f"robots/{r}", [0.0, 0.0, -9.81], ROBOT_STATES) for r in ROBOTS]
    for name, gravity, count in cases:
        urdf = (DIR / f"{name}.urdf").read_text()
        model = pin.buildModelFromXML(urdf, mimic=True)
        model.gravity.linear = np.array(gravity)
        data = model.createData()
        coords = coordinates(urdf)
        assert len(coords) == model.nv
        order = [model.joints[model.getJointId(n)].idx_v for n, _ in coords]
        states = []
        for _ in range(count):
            q = rng.uniform(-np.pi, np.pi, len(coords))
            q = np.array([qi * 0.1 if k == "prismatic" else qi for qi, (_, k) in zip(q, coords)])
            qd = rng.uniform(-2.0, 2.0, len(coords))
            qp, vp = pin_state(model, coords, q, qd)
            m = pin.crba(model, data, qp)
            m = np.triu(m) + np.triu(m, 1).T
            g = pin.computeGeneralizedGravity(model, data, qp).copy()
            c = pin.nonLinearEffects(model, data, qp, vp) - g
            # Ours in graybox's order.
            M = m[np.ix_(order, order)]
            G, C = g[order], c[order]
            # Check M by the kinetic energy of the bodies' velocities.
            pin.forwardKinematics(model, data, qp, vp)
            ke = sum(0.5 * data.v[i].vector @ model.inertias[i].matrix() @ data.v[i].vector
                     for i in range(1, model.njoints))
            assert abs(ke - 0.5 * qd @ M @ qd) < 1e-10 * max(1.0, ke), (ke, qd @ M @ qd / 2)
            # Check g by central differences of the potential energy.
            h = 1e-6
            fd = []
            for k in range(len(coords)):
                e = np.zeros(len(coords)); e[k] = h
                vp_, vm_ = (potential(model, data, pin_state(model, coords, q + s * e, qd)[0])
                            for s in (1, -1))
                fd.append((vp_ - vm_) / (2 * h))
            assert np.allclose(fd, G, atol=1e-6 * max(1.0, np.abs(G).max())), (fd, G)
            states.append({"q": list(q), "qd": list(qd), "M": M.tolist(), "g": list(G), "c": list(C),
                           "T": ke, "V": potential(model, data, qp)})
        out = {"urdf": f"{Path(name).name}.urdf", "gravity": gravity, "coordinates": [n for n, _ in coords],
               "pinocchio": pin.__version__, "states": states}
        (DIR / f"{name}.json").write_text(json.dumps(out, indent=1) + "\n")
        print(f"wrote {name}.json: {len(coords)} coordinates, {count} states")


if __name__ == "__main__":
    main()
