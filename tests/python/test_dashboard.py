"""The dashboard as a person sees it: headless Chromium (Debian's, driven by Playwright) on a
fresh service. Two jobs submitted while the page is open appear and finish without a reload;
a job's chart has a point per epoch; the compare view draws both; a model replays a recorded
trajectory; the upload form adds a dataset and shows the API's error for a bad one. Charts
are read through their `data-series` attribute, not their pixels. Throughout, the page runs
under the service's Content-Security-Policy without a single violation."""

import json
import os
import shutil
import subprocess
import urllib.request

import numpy as np
import pytest

from conftest import serve
from graybox_client import Client

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
EPOCHS = {"W-B": 12, "MVF": 8}

playwright = pytest.importorskip("playwright.sync_api")
expect = playwright.expect


def series(page, selector):
    return json.loads(page.get_attribute(selector, "data-series"))


def watch_csp(page) -> list:
    """The Content-Security-Policy violations of every document the page loads, as
    "directive blocked-uri source:line" (reported to Python, so a reload loses none)."""
    seen = []
    page.expose_function("__reportCspViolation", lambda v: seen.append(v))
    page.add_init_script("""
        document.addEventListener("securitypolicyviolation", (e) => window.__reportCspViolation(
            `${e.violatedDirective} ${e.blockedURI} ${e.sourceFile}:${e.lineNumber}`));
    """)
    return seen


def assert_secure_headers(headers: dict, what: str):
    assert "default-src 'self'" in headers.get("content-security-policy", ""), (what, headers)
    assert "frame-ancestors 'none'" in headers["content-security-policy"], (what, headers)
    assert headers.get("x-content-type-options") == "nosniff", (what, headers)
    assert headers.get("x-frame-options") == "DENY", (what, headers)


@pytest.fixture(scope="module")
def fresh(tmp_path_factory, graybox_bin):
    tmp = tmp_path_factory.mktemp("dashboard")
    with serve(graybox_bin, tmp, "--workers", "1", name="dashboard serve") as s:
        yield s, tmp


@pytest.fixture(scope="module")
def browser():
    if not os.path.exists(CHROMIUM):
        pytest.fail("chromium is not installed (scripts/test.sh installs Debian's package)")
    with playwright.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=[
            "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
            "--disable-background-networking", "--disable-component-update", "--disable-sync"])
        yield b
        b.close()


def recorded_trajectories(s, tmp, binary):
    """Two trajectories of the true double pendulum (a white-box model file served by the same
    service, rolled out over gRPC), uploaded in trajectory form."""
    gbx = tmp / "truth.gbx"
    subprocess.run([binary, "model", "--template", "double_pendulum", "--dt", "0.01", "--out",
                    str(gbx)], check=True, capture_output=True)
    status, truth = s.rest.post("/v1/models?name=truth", raw=gbx.read_bytes())
    assert status == 201, truth
    rng = np.random.default_rng(0)
    trajectories = []
    with Client(s.grpc_target) as c:
        for length in (60, 40):
            u = rng.normal(0.0, 20.0, size=(length, 2))
            x = c.rollout(truth["id"], [0.5, -0.3, 0.0, 0.0], u)
            trajectories.append({"q": x[:, :2].tolist(), "qdot": x[:, 2:].tolist(),
                                 "u": u.tolist()})
    status, ds = s.rest.post("/v1/datasets?name=recorded", {"dt": 0.01,
                                                             "trajectories": trajectories})
    assert status == 201, ds
    return ds


def test_dashboard_in_a_real_browser(fresh, browser, graybox_bin, tmp_path):
    s, tmp = fresh
    base = s.rest.base
    ds = recorded_trajectories(s, tmp, graybox_bin)
    page = browser.new_page(viewport={"width": 1280, "height": 900})
    page_errors, console_errors = [], []
    page.on("pageerror", lambda e: page_errors.append(str(e)))
    page.on("console", lambda m: console_errors.append(m.text) if m.type == "error" else None)
    violations = watch_csp(page)

    # Jobs submitted while the page is open appear and finish without a reload.
    assert_secure_headers(page.goto(base + "/").headers, "the page")
    assert_secure_headers(page.request.get(base + "/v1/jobs").headers, "the API")
    page.wait_for_selector("#jobs-table")
    jobs = {}
    for model, epochs in EPOCHS.items():
        # MVF trains on windows of 2 steps (its chart shows that loss too); W-B starts at the
        # true values and, at a learning rate of 1e-9, stays there (its replay follows the
        # recording, and its training warnings show).
        extra = {"horizon": 2} if model == "MVF" else {"lr": 1e-9}
        training = {"epochs": epochs, "batch_size": 32, **extra}
        status, job = s.rest.post("/v1/jobs", {
            "dataset_id": ds["id"], "model": model, "template": "double_pendulum",
            "name": f"{model} at lr {training.get('lr', 'default')}", "training": training})
        assert status == 201, job
        jobs[model] = job["id"]
    for job_id in jobs.values():
        page.wait_for_selector(f'tr[data-job="{job_id}"][data-state="succeeded"]', timeout=180_000)
    rows = page.locator("#jobs-table tbody tr")
    assert rows.count() == 2
    # Newest first; each job by its name, its dataset by the dataset's.
    assert rows.nth(0).get_attribute("data-job") == jobs["MVF"]
    wb = page.locator(f'tr[data-job="{jobs["W-B"]}"]').inner_text()
    assert "W-B at lr 1e-09" in wb and "recorded" in wb and ds["id"] not in wb, wb
    # Loaded afresh, the page lists them newest first too (its rows came reversed from the
    # second one on: the list's index was taken for "put it at the top").
    page.reload()
    page.wait_for_selector(f'tr[data-job="{jobs["W-B"]}"]')
    order = [rows.nth(i).get_attribute("data-job") for i in range(rows.count())]
    assert order == [jobs["MVF"], jobs["W-B"]], order
    page.screenshot(path=str(tmp_path / "jobs.png"), full_page=True)

    # A job's loss chart: one point per epoch.
    page.click(f'a[href="#/jobs/{jobs["W-B"]}"]')
    page.wait_for_selector("#loss-chart canvas")
    drawn = series(page, "#loss-chart")
    assert drawn["x"] == list(range(1, EPOCHS["W-B"] + 1)), drawn["x"]
    assert len(drawn["series"]["train"]) == EPOCHS["W-B"]
    assert len(drawn["series"]["validation"]) == EPOCHS["W-B"]
    # Smoothing changes the drawn curve, not the number of points.
    raw = json.loads(page.get_attribute("#loss-chart", "data-raw"))["train"]
    page.fill("#smoothing", "0")
    assert series(page, "#loss-chart")["series"]["train"] == raw
    page.select_option("#x-axis", "time")
    assert series(page, "#loss-chart")["x_label"] == "wall time (s)"
    # W-B learns nothing at its tiny learning rate: its page says so.
    warned = page.inner_text("#job-warnings")
    assert "loss_not_decreasing" in warned and "physical_parameters_unmoved" in warned, warned
    page.screenshot(path=str(tmp_path / "job.png"), full_page=True)
    # The multi-step job's chart: its 2-step validation loss beside the one-step one.
    page.goto(base + f'/#/jobs/{jobs["MVF"]}')
    page.wait_for_selector("#loss-chart canvas")
    multi = series(page, "#loss-chart")["series"]
    # Its train loss is over 2-step windows from the first epoch: the legend says so.
    assert set(multi) == {"train (2-step windows)", "validation", "validation, 2 steps"}, multi.keys()
    assert all(v is not None and v > 0 for v in multi["validation, 2 steps"])

    # Compare: both jobs' validation curves on one chart.
    page.goto(base + "/#/jobs")
    for job_id in jobs.values():
        page.check(f'tr[data-job="{job_id}"] input[type="checkbox"]')
    page.click("text=Compare selected")
    page.wait_for_selector("#compare-chart canvas")
    compared = series(page, "#compare-chart")
    assert len(compared["series"]) == 2, compared["series"].keys()
    assert len(compared["x"]) == max(EPOCHS.values())
    assert page.locator("#compare-table th", has_text=jobs["MVF"]).count() == 1
    # Their models' error against horizon on the training trajectories: a line each.
    assert page.input_value("#compare-dataset") == ds["id"]
    page.click("#horizon-button")
    page.wait_for_selector("#horizon-chart canvas")
    against = series(page, "#horizon-chart")
    assert set(against["series"]) == {f"{jobs[m]} ({m})" for m in jobs}, against["series"].keys()
    assert all(len(v) == len(against["x"]) == 6 for v in against["series"].values()), against
    page.screenshot(path=str(tmp_path / "compare.png"), full_page=True)

    # A model replays a recorded trajectory: recorded and predicted, T + 1 points each.
    status, job = s.rest.get(f'/v1/jobs/{jobs["W-B"]}')
    page.goto(base + f'/#/models/{job["model_id"]}')
    page.wait_for_selector(".replay-chart canvas")
    page.select_option("#replay-dataset", ds["id"])
    # Playwright's own wait: a string predicate is eval'd in the page, which its policy forbids.
    expect(page.locator("#replay-index")).to_have_value("0")
    page.click("#replay-button")
    page.wait_for_selector('.replay-chart[data-variable="q0"] canvas')
    replay = series(page, '.replay-chart[data-variable="q0"]')
    assert len(replay["x"]) == 61, len(replay["x"])  # trajectory 0: 60 steps
    assert len(replay["series"]["recorded"]) == len(replay["series"]["predicted"]) == 61
    # W-B starts at the true values: its replay follows the recording.
    gap = np.max(np.abs(np.array(replay["series"]["recorded"]) -
                        np.array(replay["series"]["predicted"])))
    assert gap < 0.1, gap
    assert page.locator("#physical-table tbody tr").count() == 9  # m1 m2 l1 l2 g b1 b2 eta1 eta2
    assert "physical_parameters_unmoved" in page.inner_text("#model-warnings")
    # Error against horizon on the same trajectories: the horizons they are long enough for.
    page.click("#horizon-button")
    page.wait_for_selector("#horizon-chart canvas")
    curve = series(page, "#horizon-chart")
    assert curve["x"] == pytest.approx([0.01, 0.02, 0.05, 0.1, 0.2, 0.5]), curve["x"]
    assert all(v > 0 for v in curve["series"]["median"]), curve
    # The download button saves the model file through a blob: link.
    with page.expect_download() as download:
        page.click("text=Download model (.gbx)")
    with urllib.request.urlopen(base + f'/v1/models/{job["model_id"]}/checkpoint') as r:
        assert open(download.value.path(), "rb").read() == r.read()
    page.screenshot(path=str(tmp_path / "model.png"), full_page=True)

    # The upload form adds a dataset; a bad file shows the API's message.
    good = tmp_path / "upload.json"
    good.write_text(json.dumps({"dt": 0.01, "q": [[0.1]], "qdot": [[0.0]], "u": [[1.0]],
                                "q_next": [[0.1005]], "qdot_next": [[0.1]]}))
    page.goto(base + "/#/datasets")
    page.wait_for_selector("#datasets-table tbody tr")
    before = page.locator("#datasets-table tbody tr").count()
    page.set_input_files("#upload-file", str(good))
    page.fill("#upload-name", "from-the-form")
    page.click('#upload-form button[type="submit"]')
    page.wait_for_selector('#datasets-table .dataset-name:text-is("from-the-form")')
    assert page.locator("#datasets-table tbody tr").count() == before + 1
    assert page.inner_text("#upload-status").startswith("Uploaded ds_"), "a 201 is a new dataset"
    bad = tmp_path / "bad.json"
    bad.write_text('{"dt": 0.01, "q": [[0.1], [0.2]], "qdot": [[0.0]], "u": [[1.0]], '
                   '"q_next": [[0.1]], "qdot_next": [[0.1]]}')
    page.set_input_files("#upload-file", str(bad))
    page.click('#upload-form button[type="submit"]')
    page.wait_for_selector("#upload-alert:not(:empty)")
    message = page.inner_text("#upload-alert")
    status, api_error = s.rest.post("/v1/datasets", raw=bad.read_bytes())
    assert status == 400 and api_error["error"]["message"] in message, (message, api_error)
    # A swing recorded in degrees uploads, and says plainly that angles must be in radians.
    t = np.arange(300) * 0.01
    deg = {"dt": 0.01, "q": (60 * np.sin(3 * t))[:-1, None].tolist(),
           "qdot": (180 * np.cos(3 * t))[:-1, None].tolist(), "u": np.zeros((299, 1)).tolist(),
           "q_next": (60 * np.sin(3 * t))[1:, None].tolist(),
           "qdot_next": (180 * np.cos(3 * t))[1:, None].tolist()}
    degrees = tmp_path / "degrees.json"
    degrees.write_text(json.dumps(deg))
    page.set_input_files("#upload-file", str(degrees))
    page.fill("#upload-name", "in-degrees")
    page.click('#upload-form button[type="submit"]')
    page.wait_for_selector("#upload-warnings")
    warned = page.inner_text("#upload-warnings")
    assert "coordinate_span" in warned and "radians" in warned, warned
    assert page.is_visible("#upload-warnings")
    row = page.locator("#datasets-table tr", has=page.locator('.dataset-name:text-is("in-degrees")'))
    row.locator("summary").click()
    assert "radians" in row.inner_text(), row.inner_text()
    page.screenshot(path=str(tmp_path / "datasets.png"), full_page=True)

    # Readable on a phone: nothing wider than the screen but the tables' own scrollers.
    page.set_viewport_size({"width": 390, "height": 800})
    page.goto(base + "/#/jobs")
    page.wait_for_selector("#jobs-table tbody tr")
    assert page.evaluate("document.documentElement.scrollWidth") <= 390 + 1
    page.screenshot(path=str(tmp_path / "jobs-phone.png"), full_page=True)

    assert page_errors == [], page_errors
    # The one expected failure: the bad upload's 400.
    unexpected = [m for m in console_errors if "400" not in m]
    assert unexpected == [] and len(console_errors) <= 1, console_errors
    assert violations == [], violations
    # The watch sees a violation when there is one: an inline style attribute is refused.
    page.evaluate("""document.body.insertAdjacentHTML("beforeend",
                                                       '<p style="color: red">x</p>')""")
    for _ in range(50):  # the event is queued as a task, then reported to Python
        if violations:
            break
        page.wait_for_timeout(100)
    assert len(violations) == 1 and violations[0].startswith("style-src"), violations


def test_dashboard_with_a_token(tmp_path_factory, graybox_bin, browser):
    """With --auth-reads the page still loads, asks for the token once, and then reads (the
    event stream too) with it; a wrong token is asked for again."""
    secret = "dashboard-secret-token"
    tmp = tmp_path_factory.mktemp("dashboard-auth")
    with serve(graybox_bin, tmp, "--workers", "1", "--api-token", secret, "--auth-reads",
               name="dashboard serve --auth-reads", token=secret) as s:
        page = browser.new_page(viewport={"width": 1280, "height": 900})
        page_errors = []
        page.on("pageerror", lambda e: page_errors.append(str(e)))
        violations = watch_csp(page)
        page.goto(s.rest.base + "/")
        page.wait_for_selector("#token-dialog[open]")
        # This service has a token: the button to change it shows (a service without one
        # never shows it: test_dashboard_work).
        assert page.is_visible("#token-button")
        page.fill("#token-input", "wrong")
        page.click('#token-form button[value="save"]')
        page.wait_for_selector("#token-dialog[open]")  # refused: asked again
        page.fill("#token-input", secret)
        page.click('#token-form button[value="save"]')
        page.wait_for_selector("text=No jobs yet.")
        assert "required" not in page.inner_text("#view")  # no stale error left behind
        # Live with the token: a job submitted now appears without a reload.
        data = tmp / "d.json"
        subprocess.run([graybox_bin, "simulate", "--system", "pendulum", "--count", "32",
                        "--out", str(data)], check=True, capture_output=True)
        status, ds = s.rest.post("/v1/datasets", raw=data.read_bytes())
        assert status == 201, ds
        status, job = s.rest.post("/v1/jobs", {"dataset_id": ds["id"], "model": "W-B",
                                               "template": "pendulum",
                                               "training": {"epochs": 3}})
        assert status == 201, job
        page.wait_for_selector(f'tr[data-job="{job["id"]}"][data-state="succeeded"]',
                               timeout=120_000)
        assert page_errors == [], page_errors
        assert violations == [], violations
