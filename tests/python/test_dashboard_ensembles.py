"""An ensemble in the dashboard, in headless Chromium: its job's loss curves drawn with a band
of ± one standard deviation across the members (read from the chart's series and seen in its
pixels, against a single model's chart that has none), and its model page's physical
parameters with their bootstrap error bars and its members' validation losses."""

import io

import pytest
from PIL import Image

from conftest import serve
from test_dashboard import browser, series, watch_csp  # noqa: F401  (a fixture, used by name)

MEMBERS, EPOCHS = 3, 6
# The train band's fill: PALETTE[0] (#2457c5) at alpha 0x33 over the white chart.
BAND = tuple(round(255 - 0x33 / 255 * (255 - c)) for c in (0x24, 0x57, 0xC5))


@pytest.fixture(scope="module")
def service(tmp_path_factory, graybox_bin):
    tmp = tmp_path_factory.mktemp("dashboard-ensembles")
    with serve(graybox_bin, tmp, "--workers", "1", name="dashboard ensembles serve") as s:
        yield s


@pytest.fixture(scope="module")
def jobs(service, graybox_bin, tmp_path_factory):
    """A W-B ensemble of three and one W-B model, on the same transitions."""
    import subprocess
    out = tmp_path_factory.mktemp("data") / "dp.json"
    subprocess.run([graybox_bin, "simulate", "--template", "double_pendulum", "--count", "256",
                    "--out", str(out)], check=True, capture_output=True)
    status, ds = service.rest.post("/v1/datasets?name=dp", raw=out.read_bytes())
    assert status == 201, ds
    done = {}
    for name, k in (("ensemble", MEMBERS), ("single", 1)):
        status, job = service.rest.post("/v1/jobs", {
            "dataset_id": ds["id"], "model": "W-B", "template": "double_pendulum", "name": name,
            "training": {"epochs": EPOCHS, "batch_size": 32, "lr": 0.01, "ensemble": k}})
        assert status == 201, job
        done[name] = service.rest.wait_job(job["id"])
        assert done[name]["state"] == "succeeded", done[name]
    return done


@pytest.fixture
def page(browser, service):  # noqa: F811
    p = browser.new_page(viewport={"width": 1280, "height": 900})
    errors = []
    p.on("pageerror", lambda e: errors.append(str(e)))
    violations = watch_csp(p)
    p.goto(service.rest.base + "/")
    yield p
    p.close()
    assert errors == [] and violations == [], (errors, violations)


def band_pixels(page) -> int:
    """Pixels of the chart's canvas in the train band's fill colour (±3 per channel)."""
    png = page.locator("#loss-chart canvas").first.screenshot()
    img = Image.open(io.BytesIO(png)).convert("RGB")
    return sum(1 for px in img.get_flattened_data() if all(abs(a - b) <= 3 for a, b in zip(px, BAND)))


def test_an_ensembles_loss_curves_have_a_spread_band(service, jobs, page):
    job = jobs["ensemble"]
    status, metrics = service.rest.get(f"/v1/jobs/{job['id']}/metrics")
    assert status == 200
    rows = metrics["items"]
    assert len(rows) == EPOCHS and all(r["train_loss_std"] > 0 for r in rows), rows
    page.goto(service.rest.base + f"/#/jobs/{job['id']}")
    page.wait_for_selector("#loss-chart canvas")
    page.fill("#smoothing", "0")
    drawn = series(page, "#loss-chart")
    assert {"of": "train", "upper": "train + σ", "lower": "train − σ"} in drawn["bands"]
    for sign, name in ((1, "train + σ"), (-1, "train − σ")):
        want = [r["train_loss"] + sign * r["train_loss_std"] for r in rows]
        assert drawn["series"][name] == pytest.approx(want, rel=1e-12), name
    # Measured: ~10 000 pixels of the fill; a curve's antialiased edge gives tens.
    assert band_pixels(page) > 1000
    # A single model's chart has no band, in its series or its pixels.
    page.goto(service.rest.base + f"/#/jobs/{jobs['single']['id']}")
    page.wait_for_selector("#loss-chart canvas")
    single = series(page, "#loss-chart")
    assert single["bands"] == [] and "train + σ" not in single["series"]
    assert band_pixels(page) < 300


def test_an_ensembles_model_page_shows_error_bars_and_members(service, jobs, page):
    model_id = jobs["ensemble"]["model_id"]
    status, model = service.rest.get(f"/v1/models/{model_id}")
    assert status == 200
    ensemble = model["metrics"]["ensemble"]
    page.goto(service.rest.base + f"/#/models/{model_id}")
    page.wait_for_selector("#physical-table")
    heads = page.locator("#physical-table thead th").all_inner_texts()
    assert heads[:4] == ["parameter", "mean", "± σ", "σ / |mean|"], heads
    spread = ensemble["physical_parameters"]
    rows = page.locator("#physical-table tbody tr")
    assert rows.count() == len(spread) == 9
    # The bars share one scale on which the widest ± 3σ fills its cell.
    rel = {k: v["std"] / abs(v["mean"]) for k, v in spread.items()}
    scale = 3 * max(rel.values())
    for i in range(rows.count()):
        cells = rows.nth(i).locator("td").all_inner_texts()
        s = spread[cells[0]]
        assert float(cells[1]) == pytest.approx(s["mean"], rel=1e-5), cells
        assert float(cells[2]) == pytest.approx(s["std"], rel=1e-2), cells
        bar = rows.nth(i).locator(".errorbar .errorbar-1")
        width = bar.evaluate("e => parseFloat(e.style.width)")
        # The browser keeps a style length to 6 significant digits.
        assert width == pytest.approx(100 * rel[cells[0]] / scale, rel=1e-4), cells
    members = page.locator("#members-table tbody tr")
    assert members.count() == MEMBERS
    shown = [members.nth(k).locator("td").nth(2).inner_text() for k in range(MEMBERS)]
    assert all(s not in ("", "–") for s in shown), shown
    # A single model's page keeps one value per parameter and lists no members.
    page.goto(service.rest.base + f"/#/models/{jobs['single']['model_id']}")
    page.wait_for_selector("#physical-table")
    assert page.locator("#physical-table thead th").all_inner_texts() == ["parameter", "value"]
    assert page.locator("#members-table").count() == 0
