"""Regenerates README's dashboard screenshots (assets/dashboard-*.png) from a fresh service:
three named jobs on recorded double-pendulum trajectories (one an ensemble of five), then the
jobs list, a multi-step job's loss curves, the new-job form, a model replaying a trajectory
with its energy along it, and the ensemble's replay with its members' spread, at 1280 px in
Debian's Chromium.

    GRAYBOX_BIN=target/release/graybox .venv/bin/python scripts/dashboard_screenshots.py
"""

import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "python"))

from conftest import serve  # noqa: E402
from playwright.sync_api import sync_playwright  # noqa: E402


def main():
    binary = os.environ.get("GRAYBOX_BIN", str(ROOT / "target" / "release" / "graybox"))
    tmp = Path(tempfile.mkdtemp(prefix="graybox-shots-"))
    data = tmp / "swings.json"
    subprocess.run([binary, "simulate", "--template", "double_pendulum", "--trajectories", "8",
                    "--steps", "150", "--u-std", "10", "--out", str(data)], check=True)
    with serve(binary, tmp, "--workers", "1", name="screenshots") as s:
        status, ds = s.rest.post("/v1/datasets?name=double-pendulum-swings", raw=data.read_bytes())
        assert status == 201, ds
        jobs = []
        for name, model, training in [("white-box, paper values", "W-B", {"epochs": 40}),
                                      ("MVF, 10-step windows", "MVF",
                                       {"epochs": 150, "batch_size": 64, "horizon": 10,
                                        "one_step_epochs": 100}),
                                      ("MVB, five members", "MVB",
                                       {"epochs": 100, "batch_size": 64, "ensemble": 5})]:
            status, job = s.rest.post("/v1/jobs", {"dataset_id": ds["id"], "model": model,
                                                   "template": "double_pendulum", "name": name,
                                                   "training": training})
            assert status == 201, job
            jobs.append(s.rest.wait_job(job["id"]))
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path="/usr/bin/chromium",
                                        args=["--no-sandbox", "--disable-gpu"])
            page = browser.new_page(viewport={"width": 1280, "height": 800})
            shots = [("jobs", "#/jobs", "#jobs-table tbody tr"),
                     ("job", f"#/jobs/{jobs[1]['id']}", "#loss-chart canvas"),
                     ("new-job", "#/new", "#job-form"),
                     ("model", f"#/models/{jobs[0]['model_id']}",
                      '.split-chart[data-coordinate="1"] canvas'),
                     ("ensemble", f"#/models/{jobs[2]['model_id']}",
                      '.split-chart[data-coordinate="1"] canvas')]
            for name, view, ready in shots:
                page.goto(s.rest.base + "/" + view)
                page.wait_for_selector(ready)
                page.wait_for_timeout(500)
                out = ROOT / "assets" / f"dashboard-{name}.png"
                page.screenshot(path=str(out), full_page=True)
                print(out)
            browser.close()


if __name__ == "__main__":
    main()
