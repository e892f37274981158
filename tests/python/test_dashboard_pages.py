"""The dashboard's job, compare, model and dataset pages in headless Chromium, on what a
person reads there: a model's stored error against horizon drawn from its metrics, a model
of independent transitions told plainly that rollouts need trajectories (no replay of
one-step "trajectories"), datasets by name on the job and compare pages, an upload's long
error kept inside its card, and "best val loss" labelled with the steps it is over."""

import json
import math
import re
import subprocess

import pytest

from conftest import serve
from test_dashboard import browser, series, watch_csp  # noqa: F401  (a fixture, used by name)

HORIZON = 5


@pytest.fixture(scope="module")
def service(tmp_path_factory, graybox_bin):
    tmp = tmp_path_factory.mktemp("dashboard-pages")
    with serve(graybox_bin, tmp, "--workers", "1", name="dashboard pages serve") as s:
        yield s, tmp


def simulate(binary, out, *args):
    subprocess.run([binary, "simulate", "--template", "double_pendulum", "--out", str(out),
                    *args], check=True, capture_output=True)
    return out.read_bytes()


@pytest.fixture(scope="module")
def multistep(service, graybox_bin):
    """An MVF job trained on windows of 5 steps of 4 short swings, validated on 2 others: its
    model stores its error against horizon on them (README "Multi-step training")."""
    s, tmp = service
    calm = ("--steps", "60", "--qdot-range", "2", "--u-std", "30")
    train = simulate(graybox_bin, tmp / "swings.json", "--trajectories", "4", *calm)
    held = simulate(graybox_bin, tmp / "held.json", "--trajectories", "2", "--seed", "1", *calm)
    status, ds = s.rest.post("/v1/datasets?name=swings", raw=train)
    assert status == 201, ds
    status, val = s.rest.post("/v1/datasets?name=held-out%20swings", raw=held)
    assert status == 201, val
    status, job = s.rest.post("/v1/jobs", {
        "dataset_id": ds["id"], "validation_dataset_id": val["id"], "model": "MVF",
        "template": "double_pendulum", "name": "windows of 5",
        "training": {"epochs": 3, "batch_size": 32, "horizon": HORIZON}})
    assert status == 201, job
    job = s.rest.wait_job(job["id"])
    assert job["state"] == "succeeded", job
    status, model = s.rest.get(f"/v1/models/{job['model_id']}")
    assert status == 200, model
    # The trajectories are 60 steps long: the end of training measures 1, 10 and 50 steps.
    assert [e["horizon"] for e in model["metrics"]["horizon_errors"]] == [1, 10, 50], model
    return {"dataset": ds, "validation": val, "job": job, "model": model}


@pytest.fixture(scope="module")
def transitions(service, graybox_bin):
    """A W-B job on independent transitions (`simulate --count`): every one of its dataset's
    "trajectories" is a single step."""
    s, tmp = service
    data = simulate(graybox_bin, tmp / "independent.json", "--count", "64")
    status, ds = s.rest.post("/v1/datasets?name=independent", raw=data)
    assert status == 201, ds
    status, job = s.rest.post("/v1/jobs", {
        "dataset_id": ds["id"], "model": "W-B", "template": "double_pendulum",
        "name": "one step", "training": {"epochs": 2, "batch_size": 32}})
    assert status == 201, job
    job = s.rest.wait_job(job["id"])
    assert job["state"] == "succeeded", job
    status, listed = s.rest.get(f"/v1/datasets/{ds['id']}/trajectories?page_size=1000")
    assert status == 200 and {t["length"] for t in listed["items"]} == {1}, listed
    return {"dataset": ds, "job": job}


@pytest.fixture
def page(browser):  # noqa: F811
    """A page whose script errors and policy violations fail the test at its end."""
    p = browser.new_page(viewport={"width": 1280, "height": 900})
    errors = []
    p.on("pageerror", lambda e: errors.append(str(e)))
    violations = watch_csp(p)
    yield p
    p.close()
    assert errors == [] and violations == [], (errors, violations)


def test_model_page_draws_stored_horizon_errors(service, multistep, page):
    """The errors the training measured are on the page without pressing Evaluate: a chart of
    the stored figures, and a table of them equal to the API's."""
    s, _ = service
    model = multistep["model"]
    stored = model["metrics"]["horizon_errors"]
    page.goto(s.rest.base + f"/#/models/{model['id']}")
    page.wait_for_selector("#model-horizon-chart canvas")
    drawn = series(page, "#model-horizon-chart")
    assert drawn["x"] == [e["seconds"] for e in stored], drawn
    assert drawn["series"]["median"] == [e["position_median"] for e in stored], drawn
    assert drawn["series"]["mean"] == [e["position_mean"] for e in stored], drawn
    assert page.locator("#model-horizon-chart .u-legend").count() == 1
    # The table: a row per stored horizon, each figure the API's (shown to 4 digits).
    rows = page.locator("#model-horizon-table tbody tr")
    assert rows.count() == len(stored)
    keys = ["horizon", "seconds", "windows", "diverged", "position_median", "position_mean",
            "velocity_median", "velocity_mean"]
    for i, e in enumerate(stored):
        cells = rows.nth(i).locator("td").all_inner_texts()
        assert len(cells) == len(keys), cells
        for key, text in zip(keys, cells):
            assert math.isclose(float(text), e[key], rel_tol=1e-3), (key, text, e)
    # The on-demand evaluation is still there, drawn apart from the stored one.
    assert page.locator("#horizon-button").is_enabled()
    assert page.locator("#horizon-chart canvas").count() == 0


def test_model_of_independent_transitions_offers_no_replay(service, transitions, page):
    """One-step "trajectories" make two-point charts: the page says rollouts need
    trajectories instead, and offers no replay or evaluation on that data."""
    s, _ = service
    ds = transitions["dataset"]
    page.goto(s.rest.base + f"/#/models/{transitions['job']['model_id']}")
    page.wait_for_selector("#replay-dataset")
    page.select_option("#replay-dataset", ds["id"])
    page.wait_for_selector("#replay-note:not(:empty)")
    note = page.inner_text("#replay-note")
    assert "independent transitions" in note and "trajectories" in note, note
    assert "upload" in note.lower(), note
    assert not page.is_visible("#replay-index") and not page.is_visible("#replay-button")
    assert page.locator(".replay-chart").count() == 0
    assert not page.locator("#horizon-button").is_enabled()
    # No stored error against horizon either: this training had no trajectories to measure.
    assert page.locator("#model-horizon-chart").count() == 0


def test_model_page_replays_trajectories_of_another_dataset(service, multistep, transitions, page):
    """The note is about the chosen dataset: choosing trajectories brings the replay back."""
    s, _ = service
    page.goto(s.rest.base + f"/#/models/{transitions['job']['model_id']}")
    page.wait_for_selector("#replay-dataset")
    page.select_option("#replay-dataset", transitions["dataset"]["id"])
    page.wait_for_selector("#replay-note:not(:empty)")
    page.select_option("#replay-dataset", multistep["dataset"]["id"])
    page.wait_for_selector('.replay-chart[data-variable="q0"] canvas')
    assert page.inner_text("#replay-note") == ""
    assert page.is_visible("#replay-button") and page.locator("#horizon-button").is_enabled()
    # Every listed trajectory is one the model can be rolled along: 60 steps each.
    options = page.locator("#replay-index option").all_inner_texts()
    assert options and all("(60 steps)" in o for o in options), options
    assert len(series(page, '.replay-chart[data-variable="q0"]')["x"]) == 61


def test_job_and_compare_pages_name_datasets(service, multistep, transitions, page):
    """As the Jobs list does, a job's own page and the compare page name its datasets (the
    validation one too), the id beside the name."""
    s, _ = service
    job, ds, val = multistep["job"], multistep["dataset"], multistep["validation"]
    page.goto(s.rest.base + f"/#/jobs/{job['id']}")
    page.wait_for_selector("#loss-chart canvas")
    facts = page.locator("#view dl.facts").first
    dataset = facts.locator("dt:text-is('dataset') + dd")
    assert dataset.locator(".dataset-name").inner_text() == "swings"
    assert ds["id"] in dataset.inner_text()  # the id stays, as secondary text
    validation = facts.locator("dt:text-is('validation') + dd")
    assert validation.locator(".dataset-name").inner_text() == "held-out swings"
    assert val["id"] in validation.inner_text()

    other = transitions["job"]
    page.goto(s.rest.base + f"/#/compare/{job['id']},{other['id']}")
    page.wait_for_selector("#compare-chart canvas")
    row = page.locator("#compare-table tr", has=page.locator("th:text-is('dataset')"))
    assert row.locator(".dataset-name").all_inner_texts() == ["swings", "independent"]
    assert ds["id"] in row.inner_text() and transitions["dataset"]["id"] in row.inner_text()
    row = page.locator("#compare-table tr", has=page.locator("th:text-is('validation')"))
    cells = row.locator("td").all_inner_texts()
    assert "held-out swings" in cells[0] and "held out" in cells[1], cells


def test_upload_error_stays_inside_its_card(service, page, tmp_path):
    """A CSV whose value is a long token (an id where a number belongs) is refused with that
    token in the message: the message wraps inside the upload card instead of running past
    it."""
    s, _ = service
    token = "sensor_" + "0123456789abcdef" * 16
    bad = tmp_path / "bad.csv"
    bad.write_text(f"q0,qdot0,u0,q_next0,qdot_next0\n0.1,0.2,{token},0.3,0.4\n")
    page.goto(s.rest.base + "/#/datasets")
    page.wait_for_selector("#upload-form")
    page.set_input_files("#upload-file", str(bad))
    page.fill("#upload-dt", "0.01")
    page.click('#upload-form button[type="submit"]')
    page.wait_for_selector("#upload-alert:not(:empty)")
    status, refused = s.rest.request("POST", "/v1/datasets?dt=0.01", raw=bad.read_bytes(),
                                     headers={"content-type": "text/csv"})
    assert status in (400, 422) and token in refused["error"]["message"], refused
    assert refused["error"]["message"] in page.inner_text("#upload-alert")
    box = page.eval_on_selector("#upload-alert", """(e) => {
        const r = e.getBoundingClientRect(), c = e.closest(".card").getBoundingClientRect();
        return {left: r.left, right: r.right, cardLeft: c.left, cardRight: c.right,
                scroll: e.scrollWidth, client: e.clientWidth};
    }""")
    assert box["left"] >= box["cardLeft"] and box["right"] <= box["cardRight"] + 0.5, box
    # The text itself wraps inside the box too (it does not spill out of it).
    assert box["scroll"] <= box["client"] + 1, box


def check_step_labels(page, base, job, one, steps):
    """The best val loss of `job` labelled as over `steps` steps on the jobs list, its page,
    the compare page and its model's page; that of the one-step job `one` plain."""
    page.goto(base + "/#/jobs")
    page.wait_for_selector(f'tr[data-job="{one["id"]}"]')
    multi_cell = page.locator(f'tr[data-job="{job["id"]}"] td').nth(6).inner_text()
    one_cell = page.locator(f'tr[data-job="{one["id"]}"] td').nth(6).inner_text()
    assert multi_cell.endswith(f"({steps}-step)"), multi_cell
    assert "step" not in one_cell, one_cell

    page.goto(base + f"/#/jobs/{job['id']}")
    page.wait_for_selector("#loss-chart canvas")
    labels = page.locator("#view dl.facts dt").all_inner_texts()
    assert f"best val loss ({steps}-step)" in labels, labels
    page.goto(base + f"/#/jobs/{one['id']}")
    page.wait_for_selector("#loss-chart canvas")
    assert "best val loss" in page.locator("#view dl.facts dt").all_inner_texts()

    page.goto(base + f"/#/compare/{job['id']},{one['id']}")
    page.wait_for_selector("#compare-chart canvas")
    row = page.locator("#compare-table tr", has=page.locator("th:text-is('best val loss')"))
    cells = row.locator("td").all_inner_texts()
    assert cells[0].endswith(f"({steps}-step)") and "step" not in cells[1], cells

    page.goto(base + f"/#/models/{job['model_id']}")
    page.wait_for_selector("#model-spec")
    labels = page.locator("#view dl.facts dt").all_inner_texts()
    assert f"best val loss ({steps}-step)" in labels, labels
    page.goto(base + "/#/models")
    page.wait_for_selector(f'tr[data-model="{job["model_id"]}"]')
    cell = page.locator(f'tr[data-model="{job["model_id"]}"] td').nth(5).inner_text()
    assert cell.endswith(f"({steps}-step)"), cell


def rewrite(page, pattern, change):
    """Answers the page's requests whose URL matches the regular expression `pattern` with
    the service's JSON after `change(body)`: what a service sending other fields would
    answer."""
    def handle(route):
        r = route.fetch()
        body = r.json()
        change(body)
        route.fulfill(response=r, body=json.dumps(body))
    page.route(re.compile(pattern), handle)


def test_best_val_loss_says_how_many_steps(service, multistep, transitions, page):
    """A multi-step job's best validation loss is over its windows: the pages say "5-step"
    where the API's best_val_loss_steps is 5, and nothing extra for a one-step job."""
    s, _ = service
    job, one = multistep["job"], transitions["job"]
    status, fresh = s.rest.get(f"/v1/jobs/{job['id']}")
    assert fresh.get("best_val_loss_steps") == HORIZON, \
        f"the API's job has no best_val_loss_steps = {HORIZON} yet: {fresh}"
    assert s.rest.get(f"/v1/jobs/{one['id']}")[1].get("best_val_loss_steps") == 1
    model = s.rest.get(f"/v1/models/{job['model_id']}")[1]
    assert model["metrics"].get("best_val_loss_steps") == HORIZON, model["metrics"]
    check_step_labels(page, s.rest.base, job, one, HORIZON)


def test_best_val_loss_labels_follow_the_field(service, multistep, transitions, page):
    """The labels read best_val_loss_steps wherever the API puts it (here set to 7 on the
    way, whatever this build of the service sends), and a service without the field gets
    the plain label and a working page."""
    s, _ = service
    job, one = multistep["job"], transitions["job"]

    def steps(record, k):
        if record.get("id") == job["id"]:
            record["best_val_loss_steps"] = k
        elif record.get("id") == job["model_id"]:
            record["metrics"]["best_val_loss_steps"] = k
        elif record.get("id") == one["id"]:
            record["best_val_loss_steps"] = 1

    def each(k):
        return lambda body: [steps(r, k) for r in body.get("items", [body])]

    for pattern in (r"/v1/jobs\?", f"/v1/jobs/{job['id']}$", f"/v1/jobs/{one['id']}$",
                    r"/v1/models\?", f"/v1/models/{job['model_id']}$"):
        rewrite(page, pattern, each(7))
    check_step_labels(page, s.rest.base, job, one, 7)

    page.unroute_all()

    def strip(body):
        for r in body.get("items", [body]):
            r.pop("best_val_loss_steps", None)
            r.get("metrics", {}).pop("best_val_loss_steps", None)

    for pattern in (r"/v1/jobs\?", f"/v1/jobs/{job['id']}$", f"/v1/models/{job['model_id']}$"):
        rewrite(page, pattern, strip)
    page.goto(s.rest.base + f"/#/jobs/{job['id']}")
    page.wait_for_selector("#loss-chart canvas")
    labels = page.locator("#view dl.facts dt").all_inner_texts()
    assert "best val loss" in labels and not any("step)" in t for t in labels), labels
    page.goto(s.rest.base + "/#/jobs")
    page.wait_for_selector(f'tr[data-job="{job["id"]}"]')
    cell = page.locator(f'tr[data-job="{job["id"]}"] td').nth(6).inner_text()
    assert "step" not in cell and cell != "–", cell
    page.goto(s.rest.base + f"/#/models/{job['model_id']}")
    page.wait_for_selector("#model-horizon-chart canvas")
    labels = page.locator("#view dl.facts dt").all_inner_texts()
    assert "best val loss" in labels and not any("step)" in t for t in labels), labels
