"""One `graybox serve` for the whole session (the binary from $GRAYBOX_BIN) on free ports
with a temporary database, and two small trained models on simulated double-pendulum data.
`serve` starts further servers with their own flags for the tests that need them.

The server's log is attached to every failing test's report, with those of the other
servers running at the time.
"""

import contextlib
import json
import os
import socket
import ssl
import subprocess
import time
import urllib.error
import urllib.request
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import grpc
import numpy as np
import pytest

from graybox_client import Client

MAX_ROLLOUT_STEPS = 200_000
_server_log: Path | None = None
_other_logs: dict[str, Path] = {}  # the servers `serve` started that are still running


def rel(a, b) -> float:
    """max|a − b| / max(1, max|b|): the Rust tests' error measure."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    assert a.shape == b.shape, (a.shape, b.shape)
    return float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(b)))))


def free_ports(k: int) -> list[int]:
    """k distinct ports the kernel had free (the sockets stay open until all are chosen)."""
    socks = [socket.socket() for _ in range(k)]
    try:
        for s in socks:
            s.bind(("127.0.0.1", 0))
        return [s.getsockname()[1] for s in socks]
    finally:
        for s in socks:
            s.close()


class Rest:
    """The REST API over urllib: (status, JSON body) for every answer, errors included.
    With `token`, every request carries `Authorization: Bearer <token>`; `context` is the
    TLS context of an https `base`."""

    def __init__(self, base: str, token: str | None = None, context: ssl.SSLContext | None = None):
        self.base = base
        self.token = token
        self.context = context

    def request(self, method: str, path: str, body=None, raw: bytes | None = None,
                headers: dict | None = None, text: bool = False):
        """(status, body): JSON, or the body's text with `text` (errors are JSON always)."""
        data = raw if raw is not None else (None if body is None else json.dumps(body).encode())
        headers = {"content-type": "application/json", **(headers or {})}
        if self.token is not None:
            headers["authorization"] = f"Bearer {self.token}"
        req = urllib.request.Request(self.base + path, data=data, method=method, headers=headers)
        try:
            with urllib.request.urlopen(req, timeout=60, context=self.context) as r:
                answer = r.read()
                return r.status, answer.decode() if text else json.loads(answer or b"null")
        except urllib.error.HTTPError as e:
            return e.code, json.loads(e.read() or b"null")

    def get_text(self, path: str):
        return self.request("GET", path, text=True)

    def get(self, path: str):
        return self.request("GET", path)

    def post(self, path: str, body=None, raw: bytes | None = None):
        return self.request("POST", path, body if body is not None else {}, raw)

    def wait_job(self, job_id: str, until=("succeeded", "failed", "cancelled"), limit_s=300.0):
        """Polls a job until its state is in `until` (the limit only guards against a hang)."""
        end = time.monotonic() + limit_s
        while True:
            status, job = self.get(f"/v1/jobs/{job_id}")
            assert status == 200, job
            if job["state"] in until:
                return job
            if time.monotonic() > end:
                pytest.fail(f"job {job_id} still {job['state']} after {limit_s} s: {job}")
            time.sleep(0.05)


@dataclass
class Server:
    binary: str
    grpc_target: str
    rest: Rest
    tmp: Path


@dataclass
class Models:
    dataset_id: str
    wb: str
    wb_job: str
    mvf: str
    mvf_job: str


def _log_tail(lines: int = 80, log: Path | None = None) -> str:
    log = log or _server_log
    if log is None or not log.exists():
        return ""
    return "\n".join(log.read_text(errors="replace").splitlines()[-lines:])


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if report.failed and _server_log is not None:
        report.sections.append(("graybox serve log (last 80 lines)", _log_tail()))
    if report.failed:
        for name, log in _other_logs.items():
            report.sections.append((f"{name} log (last 80 lines)", _log_tail(log=log)))


def server_env() -> dict:
    """The caller's environment without GRAYBOX_* settings (a token or address there would
    change the server under test), and a plain-text log for the failure reports."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("GRAYBOX_")}
    return {**env, "NO_COLOR": "1"}


@dataclass
class Serving:
    """A running `graybox serve`: its process, addresses, REST client and log."""

    proc: subprocess.Popen
    http_port: int
    grpc_port: int
    grpc_target: str
    rest: Rest
    log: Path

    def status(self, field: str) -> int:
        """A number from /proc/<pid>/status, e.g. "VmHWM" (kB) or "Threads"."""
        for line in Path(f"/proc/{self.proc.pid}/status").read_text().splitlines():
            if line.startswith(field + ":"):
                return int(line.split()[1])
        raise KeyError(field)


@pytest.fixture(scope="session")
def graybox_bin() -> str:
    binary = os.environ.get("GRAYBOX_BIN")
    if not binary:
        pytest.fail("GRAYBOX_BIN is not set: point it at a built graybox binary, e.g. "
                    "GRAYBOX_BIN=$PWD/target/release/graybox", pytrace=False)
    if not os.access(binary, os.X_OK):
        pytest.fail(f"GRAYBOX_BIN={binary} is not an executable file", pytrace=False)
    return binary


@pytest.fixture(scope="session")
def lab_bin(graybox_bin) -> str:
    """The lab's binary (benchmarks, experiments): $GRAYBOX_LAB_BIN, else graybox-lab beside
    $GRAYBOX_BIN, where one cargo build puts it."""
    binary = os.environ.get("GRAYBOX_LAB_BIN") or str(Path(graybox_bin).with_name("graybox-lab"))
    if not os.access(binary, os.X_OK):
        pytest.fail(f"{binary} is not an executable file: build the workspace "
                    "(cargo build --release) or set GRAYBOX_LAB_BIN", pytrace=False)
    return binary


@contextlib.contextmanager
def serve(binary: str, tmp: Path, *flags: str, name: str = "graybox serve",
          token: str | None = None, context: ssl.SSLContext | None = None) -> Iterator[Serving]:
    """`graybox serve` on free loopback ports with a database in `tmp` and `flags` added, once
    it answers /healthz (over https with `context`; `token` goes to the REST client); stopped
    on exit. While it runs, failing tests' reports carry its log under `name`."""
    http, grpc_port = free_ports(2)
    log_path = tmp / "serve.log"
    log = open(log_path, "wb")
    proc = subprocess.Popen(
        [binary, "serve", "--http", f"127.0.0.1:{http}", "--grpc", f"127.0.0.1:{grpc_port}",
         "--db", str(tmp / "graybox.db"), *flags],
        stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
        env=server_env())
    scheme = "http" if context is None else "https"
    rest = Rest(f"{scheme}://127.0.0.1:{http}", token=token, context=context)
    if name != "graybox serve":
        _other_logs[name] = log_path
    try:
        end = time.monotonic() + 60
        while True:
            if proc.poll() is not None:
                pytest.fail(f"{name} exited with {proc.returncode}:\n{_log_tail(log=log_path)}",
                            pytrace=False)
            try:
                if rest.get("/healthz")[0] == 200:
                    break
            except OSError:
                pass
            if time.monotonic() > end:
                pytest.fail(f"{name} did not answer /healthz:\n{_log_tail(log=log_path)}",
                            pytrace=False)
            time.sleep(0.05)
        yield Serving(proc, http, grpc_port, f"127.0.0.1:{grpc_port}", rest, log_path)
    finally:
        _other_logs.pop(name, None)
        proc.terminate()
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        log.close()


@pytest.fixture(scope="session")
def server(tmp_path_factory, graybox_bin):
    global _server_log
    tmp = tmp_path_factory.mktemp("graybox")
    _server_log = tmp / "serve.log"
    with serve(graybox_bin, tmp, "--workers", "1",
               "--max-rollout-steps", str(MAX_ROLLOUT_STEPS)) as s:
        with grpc.insecure_channel(s.grpc_target) as ch:
            grpc.channel_ready_future(ch).result(timeout=30)
        yield Server(graybox_bin, s.grpc_target, s.rest, tmp)


@pytest.fixture(scope="session")
def models(server) -> Models:
    """A W-B (template double_pendulum) and an MVF model, 2 epochs each on 256 transitions."""
    data = server.tmp / "train.json"
    subprocess.run([server.binary, "simulate", "--system", "double_pendulum", "--count", "256",
                    "--seed", "0", "--out", str(data)], check=True, capture_output=True)
    status, ds = server.rest.post("/v1/datasets?name=dp-train", raw=data.read_bytes())
    assert status == 201, ds
    jobs = {}
    for name in ("W-B", "MVF"):
        status, job = server.rest.post("/v1/jobs", {
            "dataset_id": ds["id"], "model": name, "template": "double_pendulum",
            "training": {"epochs": 2, "batch_size": 64, "lr": 0.01}})
        assert status == 201, job
        jobs[name] = job["id"]
    done = {name: server.rest.wait_job(j) for name, j in jobs.items()}
    for job in done.values():
        assert job["state"] == "succeeded", job
    return Models(ds["id"], done["W-B"]["model_id"], jobs["W-B"],
                  done["MVF"]["model_id"], jobs["MVF"])


@pytest.fixture(scope="session")
def client(server):
    # A deadline so that a hung call fails the test instead of the whole run.
    with Client(server.grpc_target, timeout=300) as c:
        yield c
