"""Ensembles counted right, as a person meets them: an ensemble job's model reports the time
the job took (its members train side by side, so their own times overlap), `graybox inspect`
says how many members a file holds, the dashboard's Jobs list says "MVF ×4", and the
dashboard's replay of an ensemble draws the members' spread as a band (read from the chart's
series and seen in its pixels, against a single model's replay that has none)."""

import io
import json
import subprocess
from datetime import datetime
from pathlib import Path

import pytest
from PIL import Image

from conftest import serve
from test_dashboard import browser, expect, series  # noqa: F401  (a fixture, used by name)
from test_dashboard_pages import page  # noqa: F401  (a fixture, used by name)

ROOT = Path(__file__).resolve().parents[2]
MEMBERS = 4
# The band's fill: the third curve's colour (PALETTE[2], #2b8a3e: recorded and predicted
# take the first two) at alpha 0x33 over the page's background (#f6f7fa: replays are not on
# a card).
BAND = tuple(round(bg - 0x33 / 255 * (bg - c)) for c, bg in zip((0x2B, 0x8A, 0x3E), (0xF6, 0xF7, 0xFA)))


@pytest.fixture(scope="module")
def service(tmp_path_factory, graybox_bin):
    tmp = tmp_path_factory.mktemp("ensemble-counts")
    # Two threads for four members: the members train side by side, batch by batch.
    with serve(graybox_bin, tmp, "--workers", "1", "--job-threads", "2",
               name="ensemble counts serve") as s:
        yield s, tmp


@pytest.fixture(scope="module")
def trained(service, graybox_bin):
    """MVF ×4 for long enough that training is most of the job, and one W-B model, on eight
    recorded swings of the double pendulum (trajectories: the replay needs them)."""
    s, tmp = service
    data = tmp / "swings.json"
    subprocess.run([graybox_bin, "simulate", "--template", "double_pendulum", "--trajectories",
                    "8", "--steps", "100", "--u-std", "10", "--out", str(data)],
                   check=True, capture_output=True)
    status, ds = s.rest.post("/v1/datasets?name=swings", raw=data.read_bytes())
    assert status == 201, ds
    jobs = {}
    for name, model, k, epochs in (("ensemble", "MVF", MEMBERS, 60), ("single", "W-B", 1, 2)):
        status, job = s.rest.post("/v1/jobs", {
            "dataset_id": ds["id"], "model": model, "template": "double_pendulum", "name": name,
            "training": {"epochs": epochs, "batch_size": 64, "ensemble": k}})
        assert status == 201, job
        jobs[name] = s.rest.wait_job(job["id"])
        assert jobs[name]["state"] == "succeeded", jobs[name]
    return ds, jobs


def test_an_ensembles_seconds_are_within_its_jobs_wall_time(service, trained):
    """An accounting invariant, not a speed: every epoch ran between the job's start and its
    end, so the time the model reports cannot exceed the time between them."""
    s, _ = service
    _, jobs = trained
    job = jobs["ensemble"]
    wall = (datetime.fromisoformat(job["finished_at"])
            - datetime.fromisoformat(job["started_at"])).total_seconds()
    status, model = s.rest.get(f"/v1/models/{job['model_id']}")
    assert status == 200, model
    metrics = model["metrics"]
    assert 0 < metrics["seconds"] <= wall, (metrics["seconds"], wall)
    # The members' own times, overlapping, are kept under their own name.
    assert metrics["ensemble"]["member_seconds"] > 0, metrics["ensemble"]
    assert len(metrics["ensemble"]["members"]) == MEMBERS


def test_inspect_says_how_many_members_a_file_holds(graybox_bin):
    fixtures = ROOT / "tests" / "fixtures" / "compat"
    for name, members in (("wb-x3", 3), ("wb", 1)):
        out = subprocess.run([graybox_bin, "inspect", "--model", str(fixtures / f"{name}.gbx")],
                             check=True, capture_output=True, text=True)
        info = json.loads(out.stdout)
        assert info["members"] == members, (name, info)
        # An ensemble's physical values are its members' mean, with their spread beside them.
        assert ("physical_parameters_std" in info) == (members > 1), (name, info)


def test_the_jobs_list_names_an_ensemble_with_its_members(service, trained, page):
    s, _ = service
    _, jobs = trained
    page.goto(s.rest.base + "/#/jobs")
    row = page.locator(f'tr[data-job="{jobs["ensemble"]["id"]}"]')
    row.wait_for()
    assert f"MVF ×{MEMBERS}" in row.inner_text(), row.inner_text()
    single = page.locator(f'tr[data-job="{jobs["single"]["id"]}"]').inner_text()
    assert "W-B" in single and "×" not in single, single
    page.click(f'a[href="#/jobs/{jobs["ensemble"]["id"]}"]')
    page.wait_for_selector("#loss-chart canvas")
    assert f"MVF ×{MEMBERS}" in page.inner_text("#view dl"), page.inner_text("#view dl")


def band_pixels(page, selector) -> int:
    """Pixels of the chart's canvas in the band's fill colour (±3 per channel)."""
    png = page.locator(f"{selector} canvas").first.screenshot()
    img = Image.open(io.BytesIO(png)).convert("RGB")
    return sum(1 for px in img.get_flattened_data() if all(abs(a - b) <= 3 for a, b in zip(px, BAND)))


def replay(page, base, model_id, ds):
    page.goto(base + f"/#/models/{model_id}")
    page.wait_for_selector("#replay-dataset")
    page.select_option("#replay-dataset", ds["id"])
    # Playwright's own wait: a string predicate is eval'd in the page, which its policy forbids.
    expect(page.locator("#replay-index")).to_have_value("0")
    page.click("#replay-button")
    page.wait_for_selector('.replay-chart[data-variable="q0"] canvas')


def test_an_ensembles_replay_draws_the_members_spread_as_a_band(service, trained, page):
    s, _ = service
    ds, jobs = trained
    model_id = jobs["ensemble"]["model_id"]
    replay(page, s.rest.base, model_id, ds)
    expect(page.locator("#replay-spread-note")).not_to_have_text("")
    assert f"{MEMBERS} particles" in page.inner_text("#replay-spread-note")
    status, r = s.rest.get(f"/v1/models/{model_id}/rollout?dataset_id={ds['id']}&index=0"
                           f"&particles={MEMBERS}")
    assert status == 200, r
    spread = r["particles"]
    assert spread["count"] == MEMBERS
    for key, i, name in (("q", 0, "q0"), ("qdot", 1, "qdot1")):
        drawn = series(page, f'.replay-chart[data-variable="{name}"]')
        assert drawn["bands"] == [{"of": "members' mean", "upper": "members' mean + σ",
                                   "lower": "members' mean − σ"}], drawn["bands"]
        mean = [row[i] for row in spread["mean"][key]]
        std = [row[i] for row in spread["std"][key]]
        assert drawn["series"]["members' mean"] == mean
        assert drawn["series"]["members' mean + σ"] == pytest.approx([a + b for a, b in zip(mean, std)])
        assert drawn["series"]["members' mean − σ"] == pytest.approx([a - b for a, b in zip(mean, std)])
        assert max(std) > 0, "the members differ"
    # Angles in radians, time in seconds, on the axes.
    q0 = series(page, '.replay-chart[data-variable="q0"]')
    assert (q0["x_label"], q0["y_label"]) == ("time (s)", "q1 (rad)"), q0
    assert series(page, '.replay-chart[data-variable="qdot0"]')["y_label"] == "q1 rate (rad/s)"
    # Seen: the band's fill on the canvas (a curve's antialiased edge gives tens of pixels), on
    # q2's chart, where the members part most against the swing's range (measured: ~20 000).
    assert band_pixels(page, '.replay-chart[data-variable="q1"]') > 1000
    # A single model's replay asks for no particles and draws no band.
    replay(page, s.rest.base, jobs["single"]["model_id"], ds)
    single = series(page, '.replay-chart[data-variable="q0"]')
    assert single["bands"] == [] and set(single["series"]) == {"recorded", "predicted"}, single
    assert page.inner_text("#replay-spread-note") == ""
    assert band_pixels(page, '.replay-chart[data-variable="q1"]') < 300
