"""UR5 identification against Pinocchio (bench-results/*-urdf-training.md): data from a copy of
the UR5 file with every link's mass x 1.3 and no joint friction, simulated by Pinocchio 4.1
(ABA and an RK4 step in numpy, dt 0.01), and W-B trained by `graybox train` from the original
file; the identified model is exported as URDF (`graybox export-urdf`), loaded by Pinocchio and
compared with the true robot at 100 held-out states: the largest ||dM||_F / ||M||_F and
||dg|| / ||g||, and the validation loss against the zero-acceleration loss.

    /work/pinvenv/bin/python scripts/ur5_identification.py [--graybox target/release/graybox]

Prints one JSON line; writes its files under --dir (kept, so a run can be looked at).
"""

import argparse
import json
import os
import re
import subprocess
import time

import numpy as np
import pinocchio as pin

HERE = os.path.dirname(os.path.abspath(__file__))
UR5 = os.path.join(HERE, "..", "tests", "fixtures", "urdf", "robots", "ur5.urdf")


def heavier(text, factor):
    """The URDF with every <mass value> times `factor` and every joint's friction 0."""
    text = re.sub(
        r'<mass value="([^"]+)"',
        lambda m: '<mass value="%r"' % (float(m.group(1)) * factor),
        text,
    )
    return re.sub(r'friction="[^"]+"', 'friction="0.0"', text)


def model_of(text):
    return pin.buildModelFromXML(text)


def rk4(model, data, q, v, u, dt):
    def f(q, v):
        return v, pin.aba(model, data, q, v, u).copy()

    k1 = f(q, v)
    k2 = f(q + 0.5 * dt * k1[0], v + 0.5 * dt * k1[1])
    k3 = f(q + 0.5 * dt * k2[0], v + 0.5 * dt * k2[1])
    k4 = f(q + dt * k3[0], v + dt * k3[1])
    q1 = q + dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
    v1 = v + dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
    return q1, v1


def transitions(model, count, rng, dt):
    """q ~ U(-pi, pi), qd ~ U(-3, 3), and each joint's input scaled to its own inertia,
    u_i = 20 M_ii(q) xi, xi ~ N(0, 1): the wrist is hundreds of times lighter than the
    shoulder, and one input scale for all would make the loss the wrist's alone."""
    data = model.createData()
    out = {k: [] for k in ("q", "qdot", "u", "q_next", "qdot_next")}
    for _ in range(count):
        q = rng.uniform(-np.pi, np.pi, model.nq)
        v = rng.uniform(-3, 3, model.nv)
        m = pin.crba(model, data, q)
        u = 20 * np.diag(m) * rng.standard_normal(model.nv)
        q1, v1 = rk4(model, data, q, v, u, dt)
        for k, x in zip(out, (q, v, u, q1, v1)):
            out[k].append(x.tolist())
    return {"dt": dt, **out}


def zero_acceleration_loss(d, lam=1.0):
    q, v = np.array(d["q"]), np.array(d["qdot"])
    q1, v1 = np.array(d["q_next"]), np.array(d["qdot_next"])
    dq = q1 - (q + d["dt"] * v)
    return float(np.mean(np.sum(dq**2, 1) + lam * np.sum((v1 - v) ** 2, 1)))


def mass_and_gravity(model, q):
    data = model.createData()
    m = pin.crba(model, data, q)
    m = np.triu(m) + np.triu(m, 1).T
    return m, pin.computeGeneralizedGravity(model, data, q).copy()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--graybox", default=os.path.join(HERE, "..", "target", "release", "graybox"))
    ap.add_argument("--dir", default="/tmp/ur5-identification")
    ap.add_argument("--train", type=int, default=8192)
    ap.add_argument("--val", type=int, default=2048)
    ap.add_argument("--epochs", default="300,100")
    ap.add_argument("--lr", default="1e-2,1e-3")
    ap.add_argument("--batch-size", type=int, default=2048)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    os.makedirs(a.dir, exist_ok=True)
    path = lambda name: os.path.join(a.dir, name)
    original = open(UR5).read()
    truth = model_of(heavier(original, 1.3))
    rng = np.random.default_rng(a.seed)
    train, val = transitions(truth, a.train, rng, 0.01), transitions(truth, a.val, rng, 0.01)
    for name, d in (("train.json", train), ("val.json", val)):
        json.dump(d, open(path(name), "w"))
    # Adam at a constant rate ends in a ball whose size scales with the rate: a second run at
    # a tenth of it starts from the first one's values, as a user would with `--init`.
    start, init = time.time(), None
    for k, (epochs, lr) in enumerate(zip(a.epochs.split(","), a.lr.split(","))):
        out = path("stage%d.gbx" % k)
        cmd = [a.graybox, "train", "--data", path("train.json"), "--val-data", path("val.json"),
               "--model", "W-B", "--template", UR5, "--out", out, "--epochs", epochs,
               "--batch-size", str(a.batch_size), "--lr", lr, "--seed", str(a.seed),
               "--report", path("report%d.json" % k)]
        if init:
            cmd += ["--init", init]
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        report = json.load(open(path("report%d.json" % k)))
        init = ",".join("%s=%r" % kv for kv in report["physical_parameters"].items())
    seconds = time.time() - start
    subprocess.run([a.graybox, "export-urdf", "--model", out, "--out", path("identified.urdf")],
                   check=True, stdout=subprocess.DEVNULL)
    identified, nominal = model_of(open(path("identified.urdf")).read()), model_of(original)
    worst = {"identified": [0.0, 0.0], "nominal": [0.0, 0.0]}
    for _ in range(100):
        q = rng.uniform(-np.pi, np.pi, truth.nq)
        m, g = mass_and_gravity(truth, q)
        for name, model in (("identified", identified), ("nominal", nominal)):
            mi, gi = mass_and_gravity(model, q)
            w = worst[name]
            w[0] = max(w[0], np.linalg.norm(mi - m) / np.linalg.norm(m))
            w[1] = max(w[1], np.linalg.norm(gi - g) / np.linalg.norm(g))
    print(json.dumps({
        "bench": "ur5_identification", "train": a.train, "val": a.val, "epochs": a.epochs,
        "lr": a.lr, "batch_size": a.batch_size, "train_seconds": seconds,
        "best_val_loss": report.get("best_val_loss"),
        "zero_acceleration_loss": zero_acceleration_loss(val),
        "max_rel_M_error": worst["identified"][0], "max_rel_g_error": worst["identified"][1],
        "nominal_max_rel_M_error": worst["nominal"][0],
        "nominal_max_rel_g_error": worst["nominal"][1],
    }))


if __name__ == "__main__":
    main()
