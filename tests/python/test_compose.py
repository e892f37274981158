"""The compose files run graybox commands with flags the binary has: there is no container
engine here to run them, so this reads each graybox service's command and environment and
checks them against `graybox <command> --help`."""

import pathlib
import re
import subprocess

import yaml

ROOT = pathlib.Path(__file__).resolve().parents[2]


def flags_of(graybox_bin, command):
    """The long flags and GRAYBOX_* variables `graybox <command> --help` lists."""
    text = subprocess.run([graybox_bin, command, "--help"], capture_output=True, text=True,
                          check=True).stdout
    return set(re.findall(r"^\s+(--[a-z][a-z-]*)", text, re.M)), set(
        re.findall(r"\[env: (GRAYBOX_\w+)", text))


def graybox_services(path):
    doc = yaml.safe_load(path.read_text())
    for name, service in doc["services"].items():
        build = service.get("build")
        if build and build.get("dockerfile") == "docker/Dockerfile":
            yield name, service


def test_scale_compose_runs_an_api_node_and_workers_with_real_flags(graybox_bin):
    path = ROOT / "docker" / "compose.scale.yaml"
    services = dict(graybox_services(path))
    assert set(services) == {"api", "worker"}, services.keys()
    assert services["api"]["command"][:3] == ["serve", "--workers", "0"]
    assert services["worker"]["command"][0] == "worker"
    assert services["worker"]["deploy"]["replicas"] == 2
    for name, service in services.items():
        command = service["command"][0]
        flags, variables = flags_of(graybox_bin, command)
        for arg in service["command"][1:]:
            if arg.startswith("--"):
                assert arg in flags, f"{name}: {command} has no {arg}"
        env = service["environment"]
        for var in env:
            if var.startswith("GRAYBOX_"):
                # serve's variables are the superset: the worker ignores an API node's.
                assert var in flags_of(graybox_bin, "serve")[1], f"{name}: {var}"
        assert env["GRAYBOX_DB"].startswith("postgres://"), env
        assert env["GRAYBOX_BLOBS"].startswith("s3://"), env
        # The health check asks this service's own port.
        check = service.get("healthcheck", {}).get("test", [])
        if "health" in check:
            addr = check[check.index("--http") + 1]
            assert addr.split(":")[-1] in " ".join(service["command"]), (name, check)
    # The bucket the graybox services name is the one the set-up creates.
    doc = yaml.safe_load(path.read_text())
    bucket = services["api"]["environment"]["GRAYBOX_BLOBS"].split("/")[2]
    assert f"local/{bucket}" in doc["services"]["bucket"]["entrypoint"][-1]
