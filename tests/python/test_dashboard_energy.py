"""The dashboard's energy panels in headless Chromium, as a person reads them: a model's
stored energy report in a sentence and a table equal to the API's, and along a replay the
energy chart (T, V, E and E(0) plus the work of F) and, per coordinate, the terms of
M q̈ + c + ∇V = F, each the API's numbers; a naive model's replay says it has no energy; a
model whose heading is a rotation (nq = 4, nv = 3) replays q's four values by name."""

import subprocess

import numpy as np
import pytest

from conftest import serve
from test_dashboard import browser, expect, series  # noqa: F401  (a fixture, used by name)
from test_dashboard_pages import page  # noqa: F401  (a fixture, used by name)


@pytest.fixture(scope="module")
def service(tmp_path_factory, graybox_bin):
    tmp = tmp_path_factory.mktemp("dashboard-energy")
    with serve(graybox_bin, tmp, "--workers", "1", name="dashboard energy serve") as s:
        yield s, tmp


@pytest.fixture(scope="module")
def trained(service, graybox_bin):
    """W-B and naive jobs on 3 calm swings of the double pendulum, 40 steps each."""
    s, tmp = service
    data = tmp / "swings.json"
    subprocess.run([graybox_bin, "simulate", "--template", "double_pendulum", "--out", str(data),
                    "--trajectories", "3", "--steps", "40", "--qdot-range", "2", "--u-std", "30"],
                   check=True, capture_output=True)
    status, ds = s.rest.post("/v1/datasets?name=swings", raw=data.read_bytes())
    assert status == 201, ds
    models = {}
    for name in ("W-B", "naive"):
        status, job = s.rest.post("/v1/jobs", {
            "dataset_id": ds["id"], "model": name, "template": "double_pendulum",
            "training": {"epochs": 2, "batch_size": 32, "lr": 1e-9}})
        assert status == 201, job
        job = s.rest.wait_job(job["id"])
        assert job["state"] == "succeeded", job
        status, models[name] = s.rest.get(f"/v1/models/{job['model_id']}")
        assert status == 200
    return ds, models


def replay(page, base, model, ds):
    page.goto(base + f"/#/models/{model['id']}")
    page.wait_for_selector("#replay-dataset")
    page.select_option("#replay-dataset", ds["id"])
    # Playwright's own wait: a string predicate is eval'd in the page, which its policy forbids.
    expect(page.locator("#replay-index")).to_have_value("0")
    page.click("#replay-button")


def test_the_model_page_shows_the_stored_energy_report(service, trained, page):
    s, _ = service
    _, models = trained
    wb = models["W-B"]
    report = wb["metrics"]["energy"]
    page.goto(s.rest.base + f"/#/models/{wb['id']}")
    page.wait_for_selector("#model-energy-summary")
    # The sentence gives the worst rollout's drift beside the median's, in the table's figures.
    sentence = page.inner_text("#model-energy-summary")
    drift = report["drift"][-1]
    def pct(v):  # one decimal, or a power of ten for the tiny and the huge
        p = 100 * v
        return f"{p:.1f}" if 0.1 <= p < 1000 else f"{p:.1e}".replace("e+0", "e+").replace("e-0", "e-")
    assert sentence.startswith("The model "), sentence
    assert f"drift by {pct(drift['median'])} % (median) and up to {pct(drift['max'])} %" in sentence, sentence
    assert f"(the worst of {report['rollouts']})" in sentence and f"in {drift['steps']} steps" in sentence
    cells = page.locator("#model-energy-table td").all_inner_texts()
    assert len(cells) == 4, cells
    median = report["drift"][1]["median"]
    assert cells[1].startswith(f"{100 * median:.2g}"[:3]), (cells, median)
    assert cells[2].startswith(f"{100 * report['passivity']['share']:.2g}"), cells
    assert cells[3] == "damping", cells
    # A naive model has no report, and no energy card.
    page.goto(s.rest.base + f"/#/models/{models['naive']['id']}")
    page.wait_for_selector("#replay-dataset")
    assert page.locator("#model-energy").count() == 0


def test_a_replay_draws_the_energy_and_the_terms_of_the_dynamics(service, trained, page):
    s, _ = service
    ds, models = trained
    wb = models["W-B"]
    replay(page, s.rest.base, wb, ds)
    page.wait_for_selector("#energy-chart canvas")
    page.wait_for_selector('.split-chart[data-coordinate="1"] canvas')
    drawn = series(page, "#energy-chart")
    status, r = s.rest.get(f"/v1/models/{wb['id']}/rollout?dataset_id={ds['id']}&index=0")
    assert status == 200, r
    x = np.hstack([np.array(r["predicted"]["q"]), np.array(r["predicted"]["qdot"])])
    u = np.array(r["u"])
    assert len(drawn["x"]) == len(x) == len(u) + 1
    # T, V, E: the API's at every predicted state (the last one under the last input).
    status, e = s.rest.post(f"/v1/models/{wb['id']}/energy",
                            {"x": x.tolist(), "u": np.vstack([u, u[-1:]]).tolist()})
    assert status == 200, e
    for key, name in (("kinetic", "T"), ("potential", "V"), ("total", "E")):
        assert np.allclose(drawn["series"][name], e[key], rtol=1e-12, atol=1e-9), name
    # The white-box model's E follows E(0) plus the work of its forces: the trapezoid rule
    # over steps of 0.01 s is off by O(Δt²) of the work, far below the energy's swing.
    balance = np.array(drawn["series"]["E(0) + work of F"])
    total = np.array(drawn["series"]["E"])
    swing = np.ptp(total)
    assert swing > 1.0 and np.abs(balance - total).max() < 0.05 * swing, (swing, balance - total)
    # Per coordinate, the terms at each step's start under its input: M q̈ + c + ∇V = F.
    for i in range(2):
        split = series(page, f'.split-chart[data-coordinate="{i}"]')["series"]
        assert set(split) == {"M q̈", "c (Coriolis)", "∇V (gravity)", "F: input", "F: damping"}, split
        lhs = np.add(np.add(split["M q̈"], split["c (Coriolis)"]), split["∇V (gravity)"])
        rhs = np.add(split["F: input"], split["F: damping"])
        assert np.allclose(lhs, rhs, rtol=1e-9, atol=1e-9), i
        assert np.allclose(split["F: input"], [row[i] for row in e["parts"][0]["values"][:-1]]), i


def test_a_naive_models_replay_says_it_has_no_energy(service, trained, page):
    s, _ = service
    ds, models = trained
    replay(page, s.rest.base, models["naive"], ds)
    page.wait_for_selector("#energy-note")
    assert "no mass matrix" in page.inner_text("#energy-note")
    assert page.locator("#energy-chart").count() == 0


@pytest.fixture(scope="module")
def planar(service, graybox_bin):
    """A W-B model of the planar body (q = (x, y, cos θ, sin θ), v = (ẋ, ẏ, ω)) and its data."""
    s, tmp = service
    data = tmp / "planar.json"
    subprocess.run([graybox_bin, "simulate", "--template", "planar_body", "--out", str(data),
                    "--trajectories", "2", "--steps", "30"], check=True, capture_output=True)
    status, ds = s.rest.post("/v1/datasets?name=planar", raw=data.read_bytes())
    assert status == 201, ds
    status, job = s.rest.post("/v1/jobs", {
        "dataset_id": ds["id"], "model": "W-B", "template": "planar_body",
        "training": {"epochs": 1, "batch_size": 16, "lr": 1e-9}})
    assert status == 201, job
    job = s.rest.wait_job(job["id"])
    assert job["state"] == "succeeded", job
    status, model = s.rest.get(f"/v1/models/{job['model_id']}")
    assert status == 200 and (model["nq"], model["nv"]) == (4, 3), model
    return ds, model


def test_a_rotation_replays_as_its_cos_and_sin(service, planar, page):
    """Four charts of q (the heading's cos and sin by name, without a unit), three of the
    rates, three of the terms of the dynamics: each the API's numbers."""
    s, _ = service
    ds, model = planar
    assert model["configuration"] == ["x", "y", "cos(theta)", "sin(theta)"], model
    replay(page, s.rest.base, model, ds)
    page.wait_for_selector('.split-chart[data-coordinate="2"] canvas')
    status, r = s.rest.get(f"/v1/models/{model['id']}/rollout?dataset_id={ds['id']}&index=0")
    assert status == 200, r
    charts = page.locator(".replay-chart")
    variables = [charts.nth(i).get_attribute("data-variable") for i in range(charts.count())]
    assert variables == ["q0", "q1", "q2", "q3", "qdot0", "qdot1", "qdot2"], variables
    captions = page.locator(".replay-chart").locator("xpath=..").locator("figcaption").all_inner_texts()
    assert captions[:4] == ["x", "y", "cos(theta)", "sin(theta)"], captions
    assert captions[6] == "theta rate", captions
    for i, key in ((3, "q"), (2, "qdot")):
        drawn = series(page, f'.replay-chart[data-variable="{key}{i}"]')["series"]
        assert np.allclose(drawn["recorded"], [row[i] for row in r["recorded"][key]]), key
        assert np.allclose(drawn["predicted"], [row[i] for row in r["predicted"][key]]), key
    # The heading's recorded values stay on the unit circle.
    heading = np.array(r["recorded"]["q"])[:, 2:4]
    assert np.allclose(np.hypot(heading[:, 0], heading[:, 1]), 1.0)
    assert page.locator('.split-chart[data-coordinate="3"]').count() == 0
