#!/usr/bin/env python3
"""Your own robot, end to end: identify the 4-DoF arm of `arm.urdf` through graybox's REST API.

The "true" arm differs from the file the way a real one differs from its CAD export: heavier
links whose centres of mass sit further out, and Coulomb friction the file does not have.
This script

1. simulates transitions of the true arm with `graybox simulate` (train and validation sets),
2. uploads them and the nominal URDF as a template,
3. trains W-B (the URDF's rigid-body physics, inertia and friction trainable), W-B with a
   learned residual force, and MVF (no physics) on the same data,
4. prints the validation table and the identified masses beside the true and nominal ones,
5. writes the identified robot as URDF (`GET /v1/models/{id}/urdf`).

Run the service first (`cargo run --release -- serve`), then, from the repository, with the
Python client installed (`bash scripts/test.sh` makes `.venv` with it; README "Python client"
for your own):

    .venv/bin/python examples/urdf_arm/run.py                 # ~10 min on 2 cores
    .venv/bin/python examples/urdf_arm/run.py --epochs 20     # a quick look (or EPOCHS=20)

It simulates the data with `graybox`: the one on PATH, else the repository's build
(target/release/graybox), or --graybox.
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from graybox_client import GrayboxError, RestClient

HERE = Path(__file__).resolve().parent
BUILT = HERE.parents[1] / "target" / "release" / "graybox"

# How the true arm differs from arm.urdf (parameter names as in the template): these masses
# and centres of mass are this many times the file's, and these joints have Coulomb friction.
SCALED = {"upper_arm.mass": 1.3, "upper_arm.com_z": 1.25, "forearm.mass": 1.35,
          "forearm.com_z": 1.3, "hand.mass": 1.25}
FRICTION = {"turret.friction": 0.2, "shoulder.friction": 0.3, "elbow.friction": 0.2}
# Input noise per joint (N·m): about what moves each joint as much as the others.
U_STD = "8,8,3,0.2"


def follow(g: RestClient, job_id: str, label: str) -> dict:
    """Waits for a job, showing its epochs on one line; exits unless it succeeds."""
    def show(m):
        print(f"  {label}: epoch {m['epoch']}, val {m.get('val_loss')}", end="\r", file=sys.stderr)
    job = g.wait(job_id, progress=show)
    print(f"  {label}: {job['state']} after {job['epoch']} epochs", file=sys.stderr)
    for w in job.get("warnings") or []:
        print(f"  {label}: warning: {w['message']}", file=sys.stderr)
    if job["state"] != "succeeded":
        sys.exit(f"{label} did not succeed: {job.get('error')}")
    return job


def simulate(graybox: str, urdf: Path, truth: dict, count: int, seed: int, out: Path):
    setting = ",".join(f"{k}={v!r}" for k, v in truth.items())
    subprocess.run([graybox, "simulate", "--template", str(urdf), "--count", str(count),
                    "--seed", str(seed), "--q-range", "3.14", "--qdot-range", "3",
                    "--u-std", U_STD, "--set", setting, "--out", str(out)],
                   check=True, stdout=subprocess.DEVNULL)


def zero_acceleration_loss(data: dict) -> float:
    """The loss of predicting q̇′ = q̇ and q′ = q + Δt·q̇: the scale a model's loss is read on."""
    n, dt = len(data["q"][0]), data["dt"]
    total = 0.0
    for q, qd, qn, qdn in zip(data["q"], data["qdot"], data["q_next"], data["qdot_next"]):
        total += sum((qn[i] - q[i] - dt * qd[i]) ** 2 + (qdn[i] - qd[i]) ** 2 for i in range(n))
    return total / len(data["q"])


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--api", default=os.environ.get("GRAYBOX_HTTP", "127.0.0.1:8080"))
    p.add_argument("--graybox", default=shutil.which("graybox") or str(BUILT),
                   help="the graybox command (default: on PATH, else target/release/graybox)")
    p.add_argument("--epochs", type=int, default=int(os.environ.get("EPOCHS", "600")))
    p.add_argument("--count", type=int, default=1024, help="training transitions")
    p.add_argument("--out", type=Path, default=Path("identified_arm.urdf"))
    a = p.parse_args()
    if not (shutil.which(a.graybox) or Path(a.graybox).is_file()):
        sys.exit(f"no graybox command at {a.graybox}: build it (cargo build --release) or pass "
                 "--graybox PATH")
    try:
        run(RestClient(a.api), a)
    except GrayboxError as e:
        sys.exit(f"graybox at {a.api}: {e}")


def run(g: RestClient, a: argparse.Namespace):
    urdf = HERE / "arm.urdf"
    template = g.upload_template(urdf)
    print(f"template {template['id']}: {template['n']} joints {template['coordinates']}, "
          f"{len(template['parameters'])} trainable values", file=sys.stderr)
    nominal = {q["name"]: q["value"] for q in template["parameters"]}
    truth = {name: k * nominal[name] for name, k in SCALED.items()} | FRICTION

    work = Path(tempfile.mkdtemp(prefix="urdf_arm-"))
    print(f"simulating the true arm into {work}", file=sys.stderr)
    simulate(a.graybox, urdf, truth, a.count, 0, work / "train.json")
    simulate(a.graybox, urdf, truth, 1024, 1, work / "val.json")
    train = g.upload_dataset_file(work / "train.json", name="urdf-arm-train")
    val = g.upload_dataset_file(work / "val.json", name="urdf-arm-val")

    residual_force = {"kind": "structured", "mass": "template", "potential": "template",
                      "forces": {"type": "template", "residual": {"type": "mlp",
                                                                  "hidden": [32, 32]}}}
    # The URDF models' step costs nearly the same at any batch up to a few thousand rows, so
    # they take the whole set per step (exact gradients); MVF takes the usual mini-batches.
    runs = [("W-B", "W-B", a.count, 1e-2), ("W-B + residual force", residual_force, a.count, 1e-2),
            ("MVF", "MVF", 128, 3e-3)]
    jobs = {}
    for label, model, batch, lr in runs:
        jobs[label] = g.submit_job(
            train["id"], model, template=template["id"] if model != "MVF" else None,
            name=f"urdf arm: {label}", validation_dataset_id=val["id"],
            training={"epochs": a.epochs, "batch_size": batch, "lr": lr})["id"]
    done = {label: follow(g, job, label) for label, job in jobs.items()}

    baseline = zero_acceleration_loss(json.loads((work / "val.json").read_text()))
    print(f"\nvalidation loss (1024 transitions; predicting q̇′ = q̇ scores {baseline:.3e})\n")
    print("| model | best val loss | ÷ zero-acceleration | epochs | seconds |")
    print("|---|---|---|---|---|")
    for label, job in done.items():
        secs = _seconds(job)
        print(f"| {label} | {job['best_val_loss']:.3e} | {job['best_val_loss'] / baseline:.1e} | "
              f"{job['epoch']} | {secs:.0f} |")

    wb = g.model(done["W-B"]["model_id"])
    print("\n| parameter | nominal (arm.urdf) | true | identified (W-B) |")
    print("|---|---|---|---|")
    for name in sorted(truth):
        print(f"| {name} | {nominal[name]:.3f} | {truth[name]:.3f} | "
              f"{wb['physical_parameters'][name]:.3f} |")
    print(f"\n{wb['identifiability']}")

    a.out.write_text(g.model_urdf(wb["id"]))
    print(f"\nwrote the identified arm to {a.out}")


def _seconds(job: dict) -> float:
    from datetime import datetime
    start, end = job.get("started_at"), job.get("finished_at")
    if not (start and end):
        return float("nan")
    parse = lambda s: datetime.fromisoformat(s.replace("Z", "+00:00"))  # noqa: E731
    return (parse(end) - parse(start)).total_seconds()


if __name__ == "__main__":
    main()
