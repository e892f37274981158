#!/usr/bin/env python3
"""What a Coulomb ε costs: graybox at Δt against Pinocchio with the same friction law at a fine
step (bench-results/2026-11-26-coulomb-stiffness.md, docs/robots.md#joint-forces).

The robot is the UR5 of example-robot-data with `<dynamics damping="0" friction="1"/>` on every
joint (its light wrist makes tanh(q̇/0.01) far too stiff for Δt = 0.01 s). The truth is
Pinocchio's ABA with τ = u − d∘q̇ − f∘tanh(q̇/ε₀), ε₀ = 0.01 (graybox's default), integrated by
RK4 at Δt/100 (1e-4 s: λΔt ≤ 0.64 for the stiffest mode, where RK4 is accurate). graybox runs
at Δt = 0.01 s with ε₀ and with the ε that put the fastest mode's λΔt at 6 (unstable), 2.785
(RK4's edge), 2 (the recommended ε, graybox's limit for RK4), 1.6 and 1 (without damping λ is
f/ε times the inertia term, so ε = ε₀ · λ₀Δt / (λΔt)):

1. one step: `graybox simulate` (1024 states, q ~ U(−1, 1), q̇ ~ U(−2, 2), u ~ N(0, 1)) against
   the truth from the same (q, q̇, u), and against Pinocchio with graybox's own ε (the error
   of stepping alone);
2. a rollout: zero gravity, u = 0, every joint coasting from 1–2 rad/s until friction stops it,
   1 s (100 steps): `graybox model` then `graybox plan --max-iterations 0` (the rollout of its
   initial guess u = 0) against the truth;
3. the law itself: `graybox simulate` at Δt = 1e-4 s with ε₀ against the truth stepped at
   1e-6 s, so that both sides are the same law (not only similar ones).

Prints a markdown report. Offline, with Pinocchio (`pip install pin==4.1.0 numpy==2.4.6`) and
a release build:

    python scripts/coulomb_stiffness.py [--graybox target/release/graybox] [--urdf ur5_robot.urdf]
"""

import argparse
import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pinocchio as pin

EPS0 = 0.01
DT = 0.01
FINE = 100  # truth substeps per Δt
# λΔt of the fastest mode: beyond RK4's edge, at it (2.785), at graybox's limit for RK4 (2, the
# recommended ε), where RK4's amplification R(−λΔt) is smallest (0.27 at 1.6), and at 1.
RATES = (6.0, 2.785, 2.0, 1.6, 1.0)


def default_urdf() -> str:
    # pip's Pinocchio (cmeel) ships example-robot-data beside it.
    prefix = next(p for p in Path(pin.__file__).resolve().parents if p.name == "cmeel.prefix")
    return str(prefix / "share/example-robot-data/robots/ur_description/urdf/ur5_robot.urdf")


def graybox(exe, *args) -> tuple[dict, str]:
    r = subprocess.run([exe, *map(str, args)], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"graybox {' '.join(map(str, args))} failed: {r.stderr}")
    return json.loads(r.stdout), r.stderr


class Truth:
    """Pinocchio's ABA with graybox's joint forces, stepped by RK4."""

    def __init__(self, urdf: str, coords: list[str], gravity):
        self.model = pin.buildModelFromXML(urdf)
        self.model.gravity.linear = np.array(gravity, dtype=float)
        self.data = self.model.createData()
        # graybox's coordinate order → Pinocchio's (a serial arm: the same, checked by name).
        self.idx = [self.model.joints[self.model.getJointId(c)].idx_v for c in coords]
        assert self.model.nq == self.model.nv == len(coords)
        self.d = np.zeros(len(coords))
        self.f = np.ones(len(coords))

    def accel(self, q, v, u, eps):
        tau = u - self.d * v - self.f * np.tanh(v / eps)
        order = self.idx
        qp, vp, tp = np.empty_like(q), np.empty_like(v), np.empty_like(tau)
        qp[order], vp[order], tp[order] = q, v, tau
        a = pin.aba(self.model, self.data, qp, vp, tp)
        return a[order]

    def step(self, q, v, u, eps, h, steps):
        for _ in range(steps):
            k1q, k1v = v, self.accel(q, v, u, eps)
            k2q, k2v = v + h / 2 * k1v, self.accel(q + h / 2 * k1q, v + h / 2 * k1v, u, eps)
            k3q, k3v = v + h / 2 * k2v, self.accel(q + h / 2 * k2q, v + h / 2 * k2v, u, eps)
            k4q, k4v = v + h * k3v, self.accel(q + h * k3q, v + h * k3v, u, eps)
            q = q + h / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
            v = v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        return q, v


def one_step(exe, tmp, doc, truth, eps, dt=DT, fine=FINE, count=1024):
    path = tmp / f"doc-{eps}-{dt}.json"
    path.write_text(json.dumps(doc))
    data = tmp / f"data-{eps}-{dt}.json"
    out, stderr = graybox(exe, "simulate", "--template", path, "--dt", dt, "--count", count,
                          "--seed", 0, "--q-range", 1, "--qdot-range", 2, "--u-std", 1,
                          "--out", data)
    ds = json.loads(data.read_text())
    q, v, u = (np.array(ds[k]) for k in ("q", "qdot", "u"))
    gq, gv = np.array(ds["q_next"]), np.array(ds["qdot_next"])
    res = {"warned": "coulomb_eps" in stderr or "too stiff" in stderr}
    for name, law in (("truth", EPS0), ("own", eps)):
        tq, tv = zip(*(truth.step(q[k], v[k], u[k], law, dt / fine, fine) for k in range(len(q))))
        ev, eq = np.abs(gv - np.array(tv)), np.abs(gq - np.array(tq))
        res[name] = {"v_rms": float(np.sqrt((ev ** 2).mean())), "v_max": float(ev.max()),
                     "q_max": float(eq.max()), "wrist3_v_max": float(ev[:, -1].max())}
    res["v_max_graybox"] = float(np.abs(gv).max())
    return res


def rollout(exe, tmp, urdf, truth, eps, x0):
    doc = {"kind": "urdf", "urdf": urdf, "gravity": [0, 0, 0], "coulomb_eps": eps}
    path, model, plan = tmp / f"roll-{eps}.json", tmp / f"roll-{eps}.gbx", tmp / f"plan-{eps}.json"
    path.write_text(json.dumps(doc))
    graybox(exe, "model", "--template", path, "--dt", DT, "--out", model)
    steps = 100
    xs = ",".join(repr(float(x)) for x in x0)
    graybox(exe, "plan", "--model", model, "--x0", xs, "--goal", xs, "--horizon", steps,
            "--max-iterations", 0, "--out", plan)
    x = np.array(json.loads(plan.read_text())["x"])
    n = len(x0) // 2
    q, v = np.array(x0[:n]), np.array(x0[n:])
    tq, tv = [q], [v]
    for _ in range(steps):
        q, v = truth.step(q, v, np.zeros(n), EPS0, DT / FINE, FINE)
        tq.append(q)
        tv.append(v)
    tq, tv = np.array(tq), np.array(tv)
    stop = lambda vs: [next((k * DT for k in range(len(vs)) if np.all(np.abs(vs[k:, j]) < 0.05)), None)
                       for j in range(n)]
    return {"v_max": float(np.abs(x[:, n:] - tv).max()), "q_final": float(np.abs(x[-1, :n] - tq[-1]).max()),
            "v_final_max": float(np.abs(x[-1, n:]).max()), "stops": stop(x[:, n:]), "truth_stops": stop(tv)}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--graybox", default=str(Path(__file__).resolve().parents[1] / "target/release/graybox"))
    ap.add_argument("--urdf", default=default_urdf())
    a = ap.parse_args()
    urdf = Path(a.urdf).read_text()
    urdf, k = re.subn(r'<dynamics damping="[^"]*" friction="[^"]*"\s*/>',
                      '<dynamics damping="0" friction="1"/>', urdf)
    assert k == 6, k
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        base = {"kind": "urdf", "urdf": urdf}
        (tmp / "base.json").write_text(json.dumps(base))
        out, stderr = graybox(a.graybox, "model", "--template", tmp / "base.json", "--dt", DT,
                              "--out", tmp / "base.gbx")
        rec = float(re.search(r'"coulomb_eps" to at least ([0-9.e-]+)', stderr).group(1))
        rate0 = float(re.search(r"([0-9.]+) times shorter than the step", stderr).group(1))
        info, _ = graybox(a.graybox, "inspect", "--model", tmp / "base.gbx")
        coords = info["coordinates"]
        truth = Truth(urdf, coords, [0, 0, -9.81])
        print(f"# Coulomb ε on a UR5 with friction 1 on every joint, Δt = {DT} s\n")
        print(f"graybox's warning at ε = {EPS0}: {stderr.strip()}\n")
        print(f"Recommended ε = {rec}; the fastest mode's λΔt at ε = {EPS0} is {rate0}.\n")
        print("## One step from 1024 states (q ~ U(−1, 1), q̇ ~ U(−2, 2), u ~ N(0, 1))\n")
        print("| ε | λΔt | graybox warns | max \\|q̇′\\| graybox | vs truth (ε = 0.01, Δt/100): q̇′ RMS | q̇′ max | wrist_3 q̇′ max | q′ max | vs Pinocchio with the same ε: q̇′ RMS | q̇′ max |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        sweep = [EPS0] + [float(f"{EPS0 * rate0 / k:.2g}") for k in RATES]
        for eps in sweep:
            r = one_step(a.graybox, tmp, {**base, "coulomb_eps": eps}, truth, eps)
            t, o = r["truth"], r["own"]
            print(f"| {eps} | {EPS0 * rate0 / eps:.3g} | {'yes' if r['warned'] else 'no'} | {r['v_max_graybox']:.3g} | {t['v_rms']:.3g} | {t['v_max']:.3g} | "
                  f"{t['wrist3_v_max']:.3g} | {t['q_max']:.3g} | {o['v_rms']:.3g} | {o['v_max']:.3g} |")
        fine = one_step(a.graybox, tmp, {**base}, truth, EPS0, dt=1e-4, fine=100, count=256)
        print(f"\nThe law itself: graybox at Δt = 1e-4 s with ε = 0.01 against Pinocchio at 1e-6 s, 256 states: "
              f"q̇′ max difference {fine['truth']['v_max']:.3g} rad/s (warned: {fine['warned']}).\n")
        print("## Rollout: zero gravity, u = 0, 1 s from q = 0.3·(1…6) rad, q̇ = (1, −1, 1.5, −2, 2, −2) rad/s\n")
        x0 = [0.3 * (k + 1) for k in range(6)] + [1.0, -1.0, 1.5, -2.0, 2.0, -2.0]
        zero_g = Truth(urdf, coords, [0, 0, 0])
        print("| ε | λΔt | max \\|q̇ − q̇_truth\\| over 1 s | \\|q − q_truth\\| at 1 s | max \\|q̇\\| at 1 s | stopped (\\|q̇\\| < 0.05 for good), s | truth stopped, s |")
        print("|---|---|---|---|---|---|---|")
        for eps in sweep:
            r = rollout(a.graybox, tmp, urdf, zero_g, eps, x0)
            fmt = lambda s: ", ".join("–" if x is None else f"{x:.2f}" for x in s)
            print(f"| {eps} | {EPS0 * rate0 / eps:.3g} | {r['v_max']:.3g} | {r['q_final']:.3g} | {r['v_final_max']:.3g} | {fmt(r['stops'])} | {fmt(r['truth_stops'])} |")


if __name__ == "__main__":
    main()
