"""Train a model from Python over REST: double-pendulum swings as numpy arrays, MVF trained on
10-step windows, its progress as it trains, its error against horizon, and its model file."""
import json
import os
import subprocess
import sys
from typing import Any

import numpy as np
from graybox_client import GrayboxError, RestClient

api = os.environ.get("GRAYBOX_HTTP", "127.0.0.1:8080")
epochs = int(os.environ.get("EPOCHS", "30"))
horizon, one_step = 10, epochs // 2


def progress(m: dict[str, Any]) -> None:
    """A line per epoch on stderr, each loss named by what it is over: the train loss is the
    one-step loss until the curriculum switches to 10-step windows, then a larger number."""
    if m["epoch"] == one_step + 1:
        print(f"-- epoch {one_step + 1}: the train loss is now over {horizon}-step windows",
              file=sys.stderr)
    over = "1-step" if m["epoch"] <= one_step else f"{horizon}-step windows"
    windows = m.get("val_horizon_loss")
    print(f"epoch {m['epoch']}: train ({over}) {m['train_loss']:.4e}, val (1-step) "
          f"{m['val_loss']:.4e}" + (f", val ({horizon}-step windows) {windows:.4e}"
                                     if windows is not None else ""), file=sys.stderr)


# 20 swings of 2 s (inputs held 0.1 s); any arrays of this shape would do.
subprocess.run(["graybox", "simulate", "--system", "double_pendulum", "--trajectories", "20",
                "--steps", "200", "--u-std", "30", "--out", "swings.json"],
               check=True, stdout=subprocess.DEVNULL)
doc = json.load(open("swings.json"))
swings = [{k: np.array(t[k]) for k in ("q", "qdot", "u")} for t in doc["trajectories"]]

with RestClient(api) as g:
    train = g.upload_trajectories(swings[:16], dt=doc["dt"], name="swings")
    val = g.upload_trajectories(swings[16:], dt=doc["dt"], name="swings-val")
    for w in train["warnings"]:  # angles in degrees, a wrong dt, …: read them before training
        print("warning:", w["message"])

    job = g.submit_job(train["id"], "MVF", name="MVF, 10-step windows",
                       validation_dataset_id=val["id"],
                       training={"epochs": epochs, "horizon": horizon, "one_step_epochs": one_step})
    job = g.wait(job["id"], progress=progress)  # a line per epoch on stderr
    # The loss that picked the kept epoch: over 10-step windows of the validation swings.
    print(f"{job['name']}: {job['state']}, best val loss {job['best_val_loss']:.4f} "
          f"over {job['best_val_loss_steps']}-step windows")
    for w in job["warnings"]:  # the training checks' findings (README "Training warnings")
        print("warning:", w["message"])

    for e in g.evaluate(job["model_id"], val["id"], horizons=[10, 50, 100]):
        print(f"after {e['seconds']:.1f} s: median |q̂ − q| {e['position_median']:.4f} rad")
    g.download_model(job["model_id"], "mvf-windows.gbx")

    try:
        g.submit_job(train["id"], "MVF", training={"epochs": 0})
    except GrayboxError as e:
        print("refused:", e.status, e.field, e.message)
