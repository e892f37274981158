"""Working from the dashboard, in headless Chromium: a job started from the form (a bad value
shown beside its field, then a good one that trains live to the end), a template uploaded
with the job, a model file uploaded and shown by its joints' names with its URDF collapsed,
deletes (the API's 409 shown while a job uses the dataset), no Token button on a service
without a token, and every page inside 1280 px (and the form inside 390 px)."""

import json
import subprocess
from pathlib import Path

import pytest

from conftest import serve
from test_dashboard import browser, watch_csp  # noqa: F401  (a fixture, used by name)

ARM = Path(__file__).resolve().parents[2] / "examples" / "urdf_arm" / "arm.urdf"
JOINTS = ["turret", "shoulder", "elbow", "wrist"]


def overflow(page) -> list:
    """What is wider than the window: the document, or a table's scroller."""
    return page.evaluate("""[
        [document.documentElement.scrollWidth, window.innerWidth, "document"],
        ...[...document.querySelectorAll(".table-wrap")].map((w) =>
            [w.scrollWidth, w.clientWidth, w.querySelector("table")?.id])
    ].filter(([scroll, client]) => scroll > client + 1)""")


@pytest.fixture
def service(tmp_path, graybox_bin):
    with serve(graybox_bin, tmp_path, "--workers", "1", name="dashboard work serve") as s:
        yield s


def run(*args):
    out = subprocess.run(args, check=True, capture_output=True, text=True)
    return out.stdout


def test_work_from_the_dashboard(service, browser, graybox_bin, tmp_path):  # noqa: F811
    s, base = service, service.rest.base
    arm_data = tmp_path / "arm.json"
    run(graybox_bin, "simulate", "--template", str(ARM), "--trajectories", "2", "--steps", "30",
        "--u-std", "2", "--out", str(arm_data))
    status, ds = s.rest.post("/v1/datasets?name=arm-on-the-bench", raw=arm_data.read_bytes())
    assert status == 201, ds
    page = browser.new_page(viewport={"width": 1280, "height": 900})
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    violations = watch_csp(page)
    page.on("dialog", lambda d: d.accept())  # the delete buttons' confirmation

    page.goto(base + "/#/jobs")
    page.wait_for_selector("text=No jobs yet.")
    assert page.is_hidden("#token-button"), "this service has no token"

    # The form: a bad value is the API's error, shown beside the field it names.
    page.click("#new-job")
    page.wait_for_selector("#job-form")
    assert page.input_value("#job-epochs") == "500"  # the service's own default
    page.fill("#job-name", "arm from the form")
    page.select_option("#job-model", "W-B")
    page.select_option("#job-template", "file")
    page.set_input_files("#job-template-file", str(ARM))
    page.fill("#job-epochs", "0")
    page.click('#job-form button[type="submit"]')
    slot = '[data-error-for="training.epochs"]'
    page.wait_for_selector(f"{slot}:not(:empty)")
    status, api_error = s.rest.post("/v1/jobs", {"dataset_id": ds["id"], "model": "W-B",
                                                 "training": {"epochs": 0}})
    assert status == 422 and api_error["error"]["field"] == "training.epochs", api_error
    assert page.inner_text(slot) == api_error["error"]["message"]
    assert page.inner_text("#job-form-alert") == ""

    # Fixed: the job starts, and its page follows it live to the end.
    page.fill("#job-epochs", "3")
    page.fill("#job-batch-size", "16")
    page.click('#job-form button[type="submit"]')
    page.wait_for_url("**/#/jobs/job_*")
    job_id = page.url.rsplit("/", 1)[1]
    page.wait_for_selector("#view .state-succeeded", timeout=180_000)
    status, job = s.rest.get(f"/v1/jobs/{job_id}")
    assert job["name"] == "arm from the form" and job["training"]["epochs"] == 3, job
    assert job["training"]["batch_size"] == 16 and job["model"] == "W-B", job
    status, templates = s.rest.get("/v1/templates")
    assert [t["kind"] for t in templates["items"]] == ["urdf"], templates

    # A model file uploaded through the form: named by its joints, its URDF collapsed.
    gbx = tmp_path / "arm.gbx"
    run(graybox_bin, "model", "--template", str(ARM), "--dt", "0.01", "--out", str(gbx))
    page.goto(base + "/#/models")
    page.wait_for_selector("#model-upload")
    # A file the API refuses on a field the form has no place for ("body"): shown in the
    # form's alert (the search for the field's place once looped forever, freezing the tab).
    bad = tmp_path / "not-a-model.gbx"
    bad.write_bytes(b"not a model file")
    page.set_input_files("#model-upload-file", str(bad))
    page.click('#model-upload button[type="submit"]')
    page.wait_for_selector("#model-upload-alert:not(:empty)", timeout=10_000)
    status, refused = s.rest.request("POST", "/v1/models", raw=bad.read_bytes(),
                                     headers={"content-type": "application/octet-stream"})
    assert status == 422 and refused["error"]["field"] == "body", refused
    assert refused["error"]["message"] in page.inner_text("#model-upload-alert")
    page.set_input_files("#model-upload-file", str(gbx))
    page.fill("#model-upload-name", "nominal arm")
    page.click('#model-upload button[type="submit"]')
    page.wait_for_selector('#models-table a:text-is("nominal arm")')
    assert "Stored as mdl_" in page.inner_text("#model-upload-status")
    page.click('#models-table a:text-is("nominal arm")')
    page.wait_for_selector('.replay-chart[data-variable="q0"] canvas')
    captions = page.locator("#replay-charts figcaption").all_inner_texts()
    assert captions[:4] == JOINTS, captions
    # Joints by name, and by their type's unit: revolute and continuous joints in radians.
    page.wait_for_selector('.split-chart[data-coordinate="0"] canvas')
    assert series_label(page, '.replay-chart[data-variable="q1"]') == "shoulder (rad)"
    assert series_label(page, '.replay-chart[data-variable="qdot3"]') == "wrist rate (rad/s)"
    assert series_label(page, "#energy-chart") == "energy (J)"
    assert series_label(page, '.split-chart[data-coordinate="0"]') == "generalized force (N·m)"
    assert "document 1" in page.inner_text("#model-spec")
    assert "<robot" not in page.inner_text("#model-spec")  # not spelled out in the spec
    assert not page.is_visible("#spec-document-1 pre")  # collapsed until asked for
    page.click("#spec-document-1 summary")
    assert "<robot" in page.inner_text("#spec-document-1 pre")
    assert overflow(page) == []

    # Deletes: the API's 409 while a job uses the dataset; a model and a template go.
    status, busy = s.rest.post("/v1/jobs", {"dataset_id": ds["id"], "model": "MVF",
                                            "training": {"epochs": 1_000_000}})
    assert status == 201, busy
    page.goto(base + "/#/datasets")
    page.click(f'tr[data-dataset="{ds["id"]}"] [data-delete]')
    page.wait_for_selector("#datasets-alert:not(:empty)")
    status, refused = s.rest.request("DELETE", f"/v1/datasets/{ds['id']}")
    assert status == 409 and refused["error"]["message"] in page.inner_text("#datasets-alert")
    s.rest.post(f"/v1/jobs/{busy['id']}/cancel")
    s.rest.wait_job(busy["id"])
    page.goto(base + "/#/models")
    page.click('#models-table a:text-is("nominal arm")')
    page.click("#view [data-delete]")
    page.wait_for_url("**/#/models")
    page.wait_for_selector("#models-table tbody tr")
    assert page.locator('#models-table a:text-is("nominal arm")').count() == 0
    # Every page fits 1280 px, tables included.
    for view in ("#/jobs", "#/datasets", "#/models", "#/templates", "#/new", f"#/jobs/{job_id}"):
        page.goto(base + "/" + view)
        page.wait_for_selector("#view h1")
        page.wait_for_timeout(300)  # the lists' rows
        assert overflow(page) == [], view
    page.goto(base + "/#/templates")
    page.click("#templates-table tr[data-template] [data-delete]")
    page.wait_for_selector("#templates-table td[colspan]")  # "No stored templates"
    assert s.rest.get("/v1/templates")[1]["items"] == []
    page.set_viewport_size({"width": 390, "height": 800})
    page.goto(base + "/#/new")
    page.wait_for_selector("#job-form")
    assert overflow(page) == [], "the form at 390 px"
    page.screenshot(path=str(tmp_path / "new-job-phone.png"), full_page=True)
    assert errors == [] and violations == [], (errors, violations)


def series_label(page, selector) -> str:
    return json.loads(page.get_attribute(selector, "data-series"))["y_label"]
