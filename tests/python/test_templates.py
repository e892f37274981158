"""Templates as a resource (POST/GET/DELETE /v1/templates): stored once per document, named
by jobs by id, kept while a queued or running job uses them; bad documents are 422s naming
the field and, in expressions, the character offset."""

import copy
import json
import subprocess

import numpy as np

from graybox_client import Client
from test_formula_templates import CARTPOLE, cartpole


def upload(server, doc):
    raw = doc if isinstance(doc, bytes) else json.dumps(doc).encode()
    return server.rest.post("/v1/templates", raw=raw)


def test_upload_list_read_and_the_same_document_again(server):
    doc = dict(CARTPOLE, name="cartpole_resource")
    status, t = upload(server, doc)
    assert status == 201, t
    assert t["id"].startswith("tpl") and t["kind"] == "formula" and t["name"] == "cartpole_resource"
    assert (t["n"], t["m"]) == (2, 1) and t["coordinates"] == ["x", "theta"] and t["inputs"] == ["f"]
    assert t["periodic"] == [False, True]
    params = {p["name"]: p for p in t["parameters"]}
    assert set(params) == set(CARTPOLE["parameters"])
    assert params["mc"] == {"name": "mc", "value": 1.0, "positive": True}
    assert params["eta"]["positive"] is False

    # The same document, keys in another order and spaced differently: the stored one, 200.
    reordered = json.dumps(dict(reversed(list(doc.items()))), indent=3).encode()
    status, again = upload(server, reordered)
    assert status == 200 and again["id"] == t["id"], again

    status, one = server.rest.get(f"/v1/templates/{t['id']}")
    assert status == 200 and one == t, one
    status, page = server.rest.get("/v1/templates?page_size=1")
    assert status == 200 and len(page["items"]) == 1, page
    ids = [page["items"][0]["id"]]
    while page["next_page_token"]:
        status, page = server.rest.get(f"/v1/templates?page_size=1&page_token={page['next_page_token']}")
        assert status == 200, page
        ids += [i["id"] for i in page["items"]]
    assert t["id"] in ids and len(ids) == len(set(ids))

    status, body = server.rest.get("/v1/templates/tpl_nothere")
    assert status == 404, body
    status, body = server.rest.request("DELETE", "/v1/templates/tpl_nothere")
    assert status == 404, body


def test_a_job_on_a_stored_template_trains_serves_and_keeps_it(server):
    status, t = upload(server, dict(CARTPOLE, name="cartpole_job"))
    assert status == 201, t
    doc_file = server.tmp / "cartpole-resource.json"
    doc_file.write_text(json.dumps(CARTPOLE))
    data = server.tmp / "cartpole-resource-data.json"
    subprocess.run([server.binary, "simulate", "--template", str(doc_file), "--count", "256",
                    "--seed", "5", "--q-range", "1", "--qdot-range", "1", "--u-std", "5",
                    "--out", str(data)], check=True, capture_output=True)
    status, ds = server.rest.post("/v1/datasets?name=cartpole-resource", raw=data.read_bytes())
    assert status == 201, ds

    # `periodic` is one flag per coordinate, and the job's own (not the training's).
    for extra, field in [({"periodic": [True]}, "periodic"),
                         ({"training": {"periodic": [True, True]}}, "training.periodic")]:
        status, body = server.rest.post("/v1/jobs", {
            "dataset_id": ds["id"], "model": "MVF", "template": t["id"], **extra})
        assert status == 422 and body["error"]["field"] == field, body

    # A job that stays queued or running long enough to see the template kept: 409.
    status, long_job = server.rest.post("/v1/jobs", {
        "dataset_id": ds["id"], "model": "W-B", "template": t["id"],
        "training": {"epochs": 100000, "batch_size": 64}})
    assert status == 201, long_job
    status, body = server.rest.request("DELETE", f"/v1/templates/{t['id']}")
    assert status == 409 and "queued or running" in json.dumps(body), body
    status, body = server.rest.post(f"/v1/jobs/{long_job['id']}/cancel")
    assert status in (200, 202), body
    server.rest.wait_job(long_job["id"])

    status, job = server.rest.post("/v1/jobs", {
        "dataset_id": ds["id"], "model": "W-B", "template": t["id"], "init": {"l": 0.5},
        "training": {"epochs": 3, "batch_size": 64, "lr": 0.01}})
    assert status == 201, job
    done = server.rest.wait_job(job["id"])
    assert done["state"] == "succeeded", done

    # Finished: the template may go; the model embeds it and serves on without it.
    status, body = server.rest.request("DELETE", f"/v1/templates/{t['id']}")
    assert status == 204, body
    status, body = server.rest.get(f"/v1/templates/{t['id']}")
    assert status == 404, body
    model_id = done["model_id"]
    status, model = server.rest.get(f"/v1/models/{model_id}")
    assert status == 200, model
    values = model["metrics"]["physical_parameters"]
    with Client(server.grpc_target) as c:
        x = np.array([[0.1, 0.3, -0.2, 0.5]])
        u = np.array([[2.0]])
        p = c.predict(model_id, x, u)
        dt = ds["dt"]
        args = [values[k] for k in ("mc", "mp", "l", "g", "eta")]
        f = lambda s: np.concatenate([s[2:], cartpole(*args, np.concatenate([s, u[0]]))])
        s0 = x[0]
        k1 = f(s0); k2 = f(s0 + dt / 2 * k1); k3 = f(s0 + dt / 2 * k2); k4 = f(s0 + dt * k3)
        expected = s0 + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        # f64 in the service and here; 1e-9 covers the different operation order.
        assert np.allclose(p, expected, rtol=1e-9, atol=1e-12), (p, expected)
        a, b = c.linearize(model_id, x, u)
        assert a.shape == (1, 4, 4) and b.shape == (1, 4, 1) and np.isfinite(a).all()
        k, _ = c.tvlqr(model_id, np.zeros((11, 4)), np.zeros((10, 1)), np.eye(4), np.eye(1),
                       np.eye(4))
        assert k.shape == (10, 1, 4) and np.isfinite(k).all()
        plan = c.plan(model_id, np.zeros(4), [0.2, 0, 0, 0], 100, np.eye(4), 1e-3 * np.eye(1),
                      1e4 * np.eye(4))
        assert plan.x.shape == (101, 4) and plan.cost < plan.costs[0], plan.cost

    # A job naming no template that exists: 422 on "template".
    status, body = server.rest.post("/v1/jobs", {
        "dataset_id": ds["id"], "model": "W-B", "template": t["id"]})
    assert status == 422 and body["error"]["field"] == "template", body


def with_(path, value):
    d = copy.deepcopy(CARTPOLE)
    at = d
    for k in path[:-1]:
        at = at[k]
    at[path[-1]] = value
    return d


BAD = [
    # (document, field, words the message must hold)
    # Malformed JSON: the field being read when the text ended, and where.
    (b'{"kind": "formula", "name": ', "name", "EOF while parsing a value at line 1 column 28"),
    (b'{"kind": "formula", "name" "x"}', "template", "line 1 column 28"),
    (with_(["kind"], "mechanism"), "kind", "\"formula\", \"urdf\""),
    (with_(["potential"], "-mp*g*L*cos(theta)"), "potential", "(at offset 6)"),
    (with_(["mass", 1, 1], "mp*l^2 + theta_dot"), "mass[1][1]", "a velocity 'theta_dot' at offset 9"),
    (with_(["mass", 1, 0], "mp*l*sin(theta)"), "mass[1][0]", "symmetric"),
    (with_(["forces"], ["f"]), "forces", "expected 2 entries"),
    (with_(["mass"], [["mc + mp", "mp*l*cos(theta)"]]), "mass", "expected 2"),
    (with_(["forces", 0], "f + * x_dot"), "forces[0]", "offset 4"),
    (with_(["forces", 1], "cosine(theta)"), "forces[1]", "unknown function 'cosine'"),
    (json.dumps(CARTPOLE).replace('"value": 9.81', '"value": 1e400').encode(),
     "parameters.g.value", "out of range"),
    (with_(["inputs"], ["x"]), "inputs[0]", "already the name of coordinates[0]"),
    (with_(["coordinates", 1], "sin"), "coordinates[1]", "function"),
    (with_(["mass", 0, 0], "mp - mc"), "mass", "positive definite"),
    (with_(["masses"], []), "masses", "unknown field"),
    (with_(["periodic"], [True]), "periodic", "expected 2"),
    (b"\xff\xfe", "template", "UTF-8"),
]


def test_bad_templates_are_422s_naming_field_and_offset(server):
    before = server.rest.get("/v1/templates?page_size=100")[1]["items"]
    for doc, field, words in BAD:
        status, body = upload(server, doc)
        assert status == 422, (field, body)
        assert body["error"]["field"] == field, (field, body)
        assert words in body["error"]["message"], (field, words, body)
    after = server.rest.get("/v1/templates?page_size=100")[1]["items"]
    assert after == before, "a refused template was stored"
