"""Robots from URDF (issue 15) through the service: a raw URDF or its JSON document is a
template; an under-actuated acrobot trains, serves and plans; the identified robot comes back
as URDF that reads back to the same values; bad URDFs are 422s naming the element."""

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np

from graybox_client import Client

ROOT = Path(__file__).resolve().parents[2]

ACROBOT = """<?xml version="1.0"?>
<!-- An acrobot: two 1 kg, 1 m links turning about y, only the elbow driven. -->
<robot name="acrobot">
  <link name="world"/>
  <joint name="shoulder" type="continuous">
    <parent link="world"/>
    <child link="upper"/>
    <axis xyz="0 1 0"/>
    <dynamics damping="0.05"/>
  </joint>
  <link name="upper">
    <visual><geometry><cylinder radius="0.02" length="1"/></geometry></visual>
    <inertial>
      <origin xyz="0 0 -0.5"/>
      <mass value="1"/>
      <inertia ixx="0.0833" ixy="0" ixz="0" iyy="0.0833" iyz="0" izz="0.001"/>
    </inertial>
  </link>
  <joint name="elbow" type="continuous">
    <origin xyz="0 0 -1"/>
    <parent link="upper"/>
    <child link="lower"/>
    <axis xyz="0 1 0"/>
  </joint>
  <link name="lower">
    <inertial>
      <origin xyz="0 0 -0.5"/>
      <mass value="1"/>
      <inertia ixx="0.0833" ixy="0" ixz="0" iyy="0.0833" iyz="0" izz="0.001"/>
    </inertial>
  </link>
</robot>
"""


def upload_xml(server, text):
    req_headers = {"content-type": "application/xml"}
    return server.rest.request("POST", "/v1/templates", raw=text.encode(), headers=req_headers)


def test_a_raw_urdf_and_its_json_document_are_one_template(server):
    status, t = upload_xml(server, ACROBOT)
    assert status == 201, t
    assert t["kind"] == "urdf" and t["name"] == "acrobot", t
    assert (t["n"], t["m"]) == (2, 2) and t["coordinates"] == ["shoulder", "elbow"], t
    assert t["periodic"] == [True, True], t  # continuous joints are angles
    names = [p["name"] for p in t["parameters"]]
    assert names[:10] == ["upper.mass", "upper.com_x", "upper.com_y", "upper.com_z",
                          "upper.ixx", "upper.ixy", "upper.ixz", "upper.iyy", "upper.iyz",
                          "upper.izz"], names
    assert names[-4:] == ["shoulder.damping", "shoulder.friction", "elbow.damping",
                          "elbow.friction"], names
    values = {p["name"]: p["value"] for p in t["parameters"]}
    assert values["upper.mass"] == 1.0 and values["upper.com_z"] == -0.5, values
    assert values["shoulder.damping"] == 0.05 and values["elbow.damping"] == 0.0, values
    assert "combinations" in t["identifiability"], t
    # The same robot as a JSON document with every default: the stored one.
    status, again = server.rest.post("/v1/templates", {"kind": "urdf", "urdf": ACROBOT})
    assert status == 200 and again["id"] == t["id"], again
    # Under-actuated: one input, on the elbow.
    status, under = server.rest.post("/v1/templates", {
        "kind": "urdf", "name": "acrobot_elbow", "urdf": ACROBOT, "actuated": ["elbow"]})
    assert status == 201 and (under["n"], under["m"]) == (2, 1), under
    assert under["inputs"] == ["elbow"], under


def test_an_underactuated_acrobot_trains_plans_and_exports(server):
    doc = {"kind": "urdf", "name": "acrobot_trained", "urdf": ACROBOT, "actuated": ["elbow"]}
    status, t = server.rest.post("/v1/templates", doc)
    assert status == 201, t
    # The "true" acrobot: a heavier lower link and a shoulder with friction.
    doc_file = server.tmp / "acrobot.json"
    doc_file.write_text(json.dumps(doc))
    data = server.tmp / "acrobot-data.json"
    subprocess.run([server.binary, "simulate", "--template", str(doc_file), "--count", "512",
                    "--seed", "3", "--q-range", "3", "--qdot-range", "3", "--u-std", "3",
                    "--set", "lower.mass=1.3,shoulder.friction=0.1", "--out", str(data)],
                   check=True, capture_output=True)
    status, ds = server.rest.post("/v1/datasets?name=acrobot", raw=data.read_bytes())
    assert status == 201, ds
    status, job = server.rest.post("/v1/jobs", {
        "dataset_id": ds["id"], "model": "W-B", "template": t["id"],
        "training": {"epochs": 40, "batch_size": 512, "lr": 0.01}})
    assert status == 201, job
    done = server.rest.wait_job(job["id"])
    assert done["state"] == "succeeded", done
    model_id = done["model_id"]
    status, model = server.rest.get(f"/v1/models/{model_id}")
    assert status == 200, model
    learned = model["physical_parameters"]
    assert set(learned) == {p["name"] for p in t["parameters"]}, learned
    assert "combinations" in model["identifiability"], model
    # Training moved the lower link's mass toward the true 1.3 from the file's 1.0.
    assert learned["lower.mass"] > 1.05, learned

    with Client(server.grpc_target) as c:
        x0 = np.zeros(4)
        plan = c.plan(model_id, x0, [0.3, 0, 0, 0], 60, np.eye(4), 1e-2 * np.eye(1),
                      1e3 * np.eye(4))
        assert plan.x.shape == (61, 4) and plan.u.shape == (60, 1), plan
        assert plan.cost < plan.costs[0] and np.isfinite(plan.K).all(), plan.cost
        a, b = c.linearize(model_id, np.array([[0.2, -0.1, 0.3, 0.0]]), np.array([[0.5]]))
        assert a.shape == (1, 4, 4) and b.shape == (1, 4, 1), (a.shape, b.shape)

    # The identified robot as URDF: the learned values in, everything else as it was.
    status, text = server.rest.get_text(f"/v1/models/{model_id}/urdf")
    assert status == 200, text
    assert "<!-- An acrobot" in text and '<cylinder radius="0.02" length="1"/>' in text, text
    mass = re.findall(r'<link name="lower">.*?<mass value="([^"]+)"/>', text, re.S)
    assert abs(float(mass[0]) - learned["lower.mass"]) < 1e-12, (mass, learned)
    status, back = upload_xml(server, text)
    assert status == 201, back
    back_values = {p["name"]: p["value"] for p in back["parameters"]}
    for name, v in learned.items():
        assert abs(back_values[name] - v) <= 1e-9 * max(1.0, abs(v)), (name, back_values[name], v)

    # A model of a built-in template has no URDF.
    pendulum = server.tmp / "pendulum.gbx"
    subprocess.run([server.binary, "model", "--template", "pendulum", "--dt", "0.01", "--out",
                    str(pendulum)], check=True, capture_output=True)
    status, other = server.rest.post("/v1/models?name=pendulum", raw=pendulum.read_bytes())
    assert status in (200, 201), other
    status, body = server.rest.get(f"/v1/models/{other['id']}/urdf")
    assert status == 409 and "URDF" in body["error"]["message"], body


def test_export_urdf_on_the_command_line(server):
    urdf = server.tmp / "acrobot.urdf"
    urdf.write_text(ACROBOT)
    gbx, out = server.tmp / "acrobot.gbx", server.tmp / "acrobot-out.urdf"
    subprocess.run([server.binary, "model", "--template", str(urdf), "--dt", "0.01",
                    "--set", "upper.mass=2,elbow.friction=0.2", "--out", str(gbx)],
                   check=True, capture_output=True)
    subprocess.run([server.binary, "export-urdf", "--model", str(gbx), "--out", str(out)],
                   check=True, capture_output=True)
    text = out.read_text()
    assert '<dynamics damping="0" friction="0.2"/>' in text, text
    # It reads back as a template: simulate from it.
    data = server.tmp / "acrobot-exported.json"
    subprocess.run([server.binary, "simulate", "--template", str(out), "--count", "8",
                    "--out", str(data)], check=True, capture_output=True)
    assert len(json.loads(data.read_text())["q"][0]) == 2
    # Not a physical body: refused naming the link, nothing written.
    r = subprocess.run([server.binary, "model", "--template", str(urdf), "--dt", "0.01",
                        "--set", "upper.ixx=5", "--out", str(server.tmp / "no.gbx")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "upper" in r.stderr, r.stderr
    assert not (server.tmp / "no.gbx").exists()


def variant(old, new, count=1):
    assert ACROBOT.count(old) >= count, old
    return ACROBOT.replace(old, new, count)


BAD = [
    # (URDF text, words the message must hold)
    ("<robot name='x'><link name='a'>", "not XML: the document ends inside <link>"),
    (variant('type="continuous"', 'type="floating"'), "joint 'shoulder'"),
    (variant('type="continuous"', 'type="planar"'), "joint 'shoulder'"),
    (variant('type="continuous"', 'type="banana"'), "not a URDF"),
    (variant('<link name="world"/>', '<link name="world"/><link name="stray"/>'),
     "more than one root"),
    (variant('<parent link="world"/>', '<parent link="lower"/>'), "loop"),
    (variant('<parent link="upper"/>', '<parent link="nowhere"/>'), "'nowhere'"),
    (variant('<mass value="1"/>', '<mass value="-1"/>'), "link 'upper'"),
    (variant('ixx="0.0833"', 'ixx="5"'), "link 'upper'"),
    (variant('<axis xyz="0 1 0"/>', '<axis xyz="0 0 0"/>'), "joint 'shoulder'"),
    (variant('<child link="lower"/>', '<child link="lower"/><mimic joint="wrist"/>'),
     "joint 'elbow' (line 19)"),
    (variant('<link name="world"/>', '<link name="world"/><link name="world"/>'),
     "link 'world'"),
    (variant('type="continuous"', 'type="fixed"', 2), "no revolute"),
]


def test_bad_urdfs_are_422s_naming_the_element(server):
    before = server.rest.get("/v1/templates?page_size=100")[1]["items"]
    for text, words in BAD:
        status, body = upload_xml(server, text)
        assert status == 422, (words, body)
        assert body["error"]["field"] == "urdf", (words, body)
        assert words in body["error"]["message"], (words, body)
    for doc, field, words in [
        ({"kind": "urdf", "urdf": ACROBOT, "actuated": ["wrist"]}, "actuated", "'wrist'"),
        ({"kind": "urdf", "urdf": ACROBOT, "actuated": []}, "actuated", "at least one"),
        ({"kind": "urdf", "urdf": ACROBOT, "periodic": ["knee"]}, "periodic", "'knee'"),
        ({"kind": "urdf", "urdf": ACROBOT, "gravity": [0, 0]}, "gravity", "3"),
        ({"kind": "urdf"}, "urdf", "missing"),
        ({"kind": "urdf", "urdf": ACROBOT, "joints": []}, "joints", "unknown field"),
        ({"kind": "robot", "urdf": ACROBOT}, "kind", "urdf"),
    ]:
        status, body = server.rest.post("/v1/templates", doc)
        assert status == 422, (field, body)
        assert body["error"]["field"] == field, (field, body)
        assert words in body["error"]["message"], (field, words, body)
    # In a job's inline template the field is under "template".
    status, body = server.rest.post("/v1/jobs", {
        "dataset_id": "ds_none", "model": "W-B",
        "template": {"kind": "urdf", "urdf": ACROBOT, "actuated": ["wrist"]}})
    assert status == 422 and body["error"]["field"] == "template.actuated", body
    after = server.rest.get("/v1/templates?page_size=100")[1]["items"]
    assert after == before, "a refused template was stored"


def test_the_urdf_arm_example_runs_end_to_end(server):
    """examples/urdf_arm/run.py as a user runs it, shortened: every model trains, the table
    prints, and the identified arm it writes reads back as a template."""
    out = server.tmp / "identified_arm.urdf"
    bindir = str(Path(server.binary).parent)
    env = dict(os.environ, PATH=bindir + os.pathsep + os.environ["PATH"])
    r = subprocess.run([sys.executable, str(ROOT / "examples/urdf_arm/run.py"), "--api",
                        server.rest.base, "--epochs", "3", "--count", "256", "--out", str(out)],
                       capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stderr
    # The example's own arm is steppable at its Δt (its file sets coulomb_eps): no warning
    # from simulating the true arm, nor in any job's findings.
    assert "too stiff" not in r.stderr and "coulomb_eps" not in r.stderr, r.stderr
    rows = [line for line in r.stdout.splitlines() if line.startswith("| ")]
    assert [row.split(" | ")[0] for row in rows[1:4]] == [
        "| W-B", "| W-B + residual force", "| MVF"], r.stdout
    assert "| upper_arm.mass | 1.500 | 1.950 |" in r.stdout, r.stdout
    status, back = upload_xml(server, out.read_text())
    assert status in (200, 201) and back["n"] == 4, back
