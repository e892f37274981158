"""graybox_client.RestClient against a real service: numpy arrays and trajectories in, a job
followed through its events to the end, the model's file down and up again, templates, the
replay and error-against-horizon as arrays, and every refusal as a GrayboxError carrying the
server's code, field and status."""

import http.server
import json
import subprocess
import threading
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

import conftest
from conftest import serve
from graybox_client import GrayboxError, RestClient

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def rest(tmp_path_factory, graybox_bin):
    tmp = tmp_path_factory.mktemp("rest-client")
    with serve(graybox_bin, tmp, "--workers", "1", name="rest client serve") as s:
        yield RestClient(s.rest.base), s, tmp


def pendulum_swings(graybox_bin, tmp) -> dict:
    out = tmp / "swings.json"
    subprocess.run([graybox_bin, "simulate", "--template", "pendulum", "--trajectories", "4",
                    "--steps", "40", "--u-std", "2", "--out", str(out)], check=True,
                   capture_output=True)
    return json.loads(out.read_text())


def test_a_whole_workflow_from_python(rest, graybox_bin):
    g, s, tmp = rest
    doc = pendulum_swings(graybox_bin, tmp)
    trajectories = [{k: np.array(t[k]) for k in ("q", "qdot", "u")} for t in doc["trajectories"]]
    ds = g.upload_trajectories(trajectories, dt=doc["dt"], name="swings")
    assert ds["created"] and ds["count"] == 4 * 40 and ds["warnings"] == [], ds
    assert [t["length"] for t in g.trajectories(ds["id"])] == [40] * 4

    # The same transitions as flat arrays (1-D columns for n = m = 1) are the same data.
    t0 = trajectories[0]
    flat = g.upload_dataset(q=t0["q"][:-1, 0], qdot=t0["qdot"][:-1, 0], u=t0["u"][:, 0],
                            q_next=t0["q"][1:, 0], qdot_next=t0["qdot"][1:, 0], dt=doc["dt"],
                            name="flat")
    assert flat["count"] == 40 and flat["n"] == flat["m"] == 1, flat
    assert {d["id"] for d in g.datasets()} == {ds["id"], flat["id"]}

    seen = []
    job = g.submit_job(ds["id"], "W-B", template="pendulum", name="from python",
                       training={"epochs": 5, "batch_size": 32, "horizon": 2})
    assert job["state"] == "queued" and job["name"] == "from python", job
    done = g.wait(job["id"], progress=seen.append, timeout=300)
    assert done["state"] == "succeeded", done
    assert [m["epoch"] for m in seen] == [1, 2, 3, 4, 5], seen  # each epoch once, in order
    metrics = g.metrics(job["id"])
    assert metrics["epoch"].tolist() == [1, 2, 3, 4, 5]
    assert np.all(np.isfinite(metrics["val_horizon_loss"])), metrics  # a 2-step job's
    assert g.jobs()[0]["id"] == job["id"] and g.jobs(state="failed") == []

    model = g.model(job["id"])  # the job's id names its model too
    assert model["id"] == done["model_id"] and model["coordinates"] == ["q1"], model
    data = g.download_model(model["id"], tmp / "m.gbx")
    with urllib.request.urlopen(f"{s.rest.base}/v1/models/{model['id']}/checkpoint") as r:
        assert r.read() == data == (tmp / "m.gbx").read_bytes()
    copy = g.upload_model(tmp / "m.gbx", name="copy")
    assert copy["created"] and copy["origin"] == "uploaded" and copy["name"] == "copy", copy
    again = g.upload_model(data)
    assert again["created"] is False and again["id"] == copy["id"], again
    g.delete_model(copy["id"])
    assert [m["id"] for m in g.models()] == [model["id"]]

    replay = g.replay(model["id"], ds["id"], index=1)
    assert replay["t"].shape == (41,) and replay["predicted"]["q"].shape == (41, 1)
    np.testing.assert_allclose(replay["recorded"]["q"], trajectories[1]["q"])
    errors = g.evaluate(model["id"], ds["id"], [1, 10])
    assert [e["horizon"] for e in errors] == [1, 10]
    assert [e["windows"] for e in errors] == [4 * 40, 4 * 31], errors

    template = g.upload_template(ROOT / "examples" / "urdf_arm" / "arm.urdf")
    assert template["kind"] == "urdf" and template["n"] == 4, template
    assert g.template(template["id"])["coordinates"] == ["turret", "shoulder", "elbow", "wrist"]
    g.delete_template(template["id"])
    assert g.templates() == []


def test_refusals_are_graybox_errors_with_code_field_and_status(rest):
    g, s, tmp = rest
    with pytest.raises(GrayboxError) as e:
        g.upload_dataset(q=np.zeros((3, 1)), qdot=np.zeros((2, 1)), u=np.zeros((3, 1)),
                         q_next=np.zeros((3, 1)), qdot_next=np.zeros((3, 1)), dt=0.01)
    assert e.value.status == 400 and e.value.code == "invalid_argument", e.value
    assert e.value.field and e.value.field.startswith("qdot"), e.value
    ds = g.upload_dataset(q=np.zeros(3), qdot=np.zeros(3), u=np.zeros(3), q_next=np.zeros(3),
                          qdot_next=np.zeros(3), dt=0.01, name="still")
    with pytest.raises(GrayboxError) as e:
        g.submit_job(ds["id"], "MVF", training={"epochs": 0})
    assert (e.value.status, e.value.code, e.value.field) == (422, "unprocessable",
                                                             "training.epochs"), e.value
    assert "training.epochs" in str(e.value) and e.value.message in str(e.value)
    with pytest.raises(GrayboxError) as e:
        g.model("mdl_nothing")
    assert (e.value.status, e.value.code) == (404, "not_found"), e.value
    busy = g.submit_job(ds["id"], "MVF", training={"epochs": 1_000_000})
    with pytest.raises(GrayboxError) as e:
        g.delete_dataset(ds["id"])
    assert (e.value.status, e.value.code) == (409, "conflict"), e.value
    g.cancel(busy["id"])
    assert g.wait(busy["id"], timeout=120)["state"] == "cancelled"
    g.delete_dataset(ds["id"])
    # A CSV file has no time step: the call says to pass dt, as Python, before any upload;
    # with it, the file is stored.
    csv = Path(tmp) / "log.csv"
    csv.write_text("q0,qdot0,u0,q_next0,qdot_next0\n0.1,0.0,0.5,0.1005,0.098\n")
    with pytest.raises(GrayboxError) as e:
        g.upload_dataset_file(csv)
    assert e.value.field == "dt" and "upload_dataset_file(" in e.value.message, e.value
    assert "dt=0.01" in e.value.message, e.value
    assert g.upload_dataset_file(csv, dt=0.01, name="log")["count"] == 1
    with pytest.raises(GrayboxError) as e:
        RestClient("127.0.0.1:9").datasets()  # nothing listens on the discard port
    assert e.value.code == "unavailable" and e.value.status is None, e.value


def queued_job(g: RestClient, graybox_bin, tmp) -> dict:
    """A tiny job (2 epochs on 160 transitions: seconds once a worker takes it), queued."""
    doc = pendulum_swings(graybox_bin, tmp)
    ds = g.upload_trajectories(doc["trajectories"], dt=doc["dt"])
    job = g.submit_job(ds["id"], "W-B", template="pendulum", training={"epochs": 2})
    assert job["state"] == "queued", job
    return job


def test_wait_gives_up_at_its_timeout_on_a_job_no_worker_takes(tmp_path, graybox_bin):
    with serve(graybox_bin, tmp_path, "--workers", "0", name="no-workers serve") as s:
        g = RestClient(s.rest.base)
        job = queued_job(g, graybox_bin, tmp_path)
        start = time.monotonic()
        with pytest.raises(GrayboxError) as e:
            g.wait(job["id"], timeout=3)
        elapsed = time.monotonic() - start
    assert e.value.code == "deadline_exceeded" and "queued" in e.value.message, e.value
    # Generous, but it must tell 3 s from the 15 s a wait that ignored its timeout took here:
    # the stream of a queued job is silent but for the service's keep-alive every 15 s.
    assert elapsed < 10, elapsed


def test_wait_follows_a_job_across_a_restart_of_the_service(tmp_path, graybox_bin, monkeypatch):
    outcome = {}

    def follow(g: RestClient, job_id: str) -> None:
        try:
            outcome["job"] = g.wait(job_id, timeout=120)
        except Exception as e:  # the test's thread reports it; the assertion names it
            outcome["error"] = e

    with serve(graybox_bin, tmp_path, "--workers", "0", name="restarting serve") as s:
        g = RestClient(s.rest.base)
        job = queued_job(g, graybox_bin, tmp_path)
        waiter = threading.Thread(target=follow, args=(g, job["id"]), daemon=True)
        waiter.start()
        time.sleep(1)  # wait is following the queued job's stream when the service stops
        ports = [s.http_port, s.grpc_port]
    time.sleep(2)  # down: connections refused
    assert waiter.is_alive(), outcome
    # The same ports (where the client follows) and the same database (`tmp_path`), now with
    # a worker, which runs the queued job.
    monkeypatch.setattr(conftest, "free_ports", lambda k: ports)
    with serve(graybox_bin, tmp_path, "--workers", "1", name="restarted serve"):
        waiter.join(120)
    assert "error" not in outcome, outcome
    assert outcome["job"]["id"] == job["id"] and outcome["job"]["state"] == "succeeded", outcome


@pytest.mark.parametrize("stream", ["closed at once", "silent"])
def test_wait_pauses_between_streams_and_keeps_its_timeout(stream):
    """A fake service of the test's own, not graybox: it answers the job as queued and its
    event stream either closes at once (a busy loop of reconnections if `wait` does not pause)
    or sends nothing (a wait as long as the client's 60 s socket timeout if `wait` reads with
    it). A real service produces neither: its stream opens with the job's state and sends a
    keep-alive every 15 s."""
    opens, stop = [], threading.Event()

    class Fake(http.server.BaseHTTPRequestHandler):
        def do_GET(self):
            if self.path.endswith("/events"):
                opens.append(time.monotonic())
                self.send_response(200)
                self.send_header("content-type", "text/event-stream")
                self.send_header("connection", "close")
                self.end_headers()
                if stream == "silent":
                    stop.wait(90)
                return
            body = json.dumps({"id": "job_fake", "state": "queued"}).encode()
            self.send_response(200)
            self.send_header("content-type", "application/json")
            self.send_header("content-length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args):
            pass

    fake = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Fake)
    threading.Thread(target=fake.serve_forever, daemon=True).start()
    try:
        g = RestClient(f"127.0.0.1:{fake.server_address[1]}")
        start = time.monotonic()
        with pytest.raises(GrayboxError) as e:
            g.wait("job_fake", timeout=2)
        elapsed = time.monotonic() - start
    finally:
        stop.set()
        fake.shutdown()
        fake.server_close()
    assert e.value.code == "deadline_exceeded", e.value
    assert 1 <= len(opens) < 50, len(opens)  # thousands without pauses
    assert elapsed < 30, elapsed  # generous: it only has to tell 2 s from 60 s
