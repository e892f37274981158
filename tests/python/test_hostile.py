"""A hostile or careless network: the API token, TLS (and clients that connect and say
nothing), calls too large to answer, streams nobody reads, inputs far outside the training
data and shapes that overflow. The tests needing special flags start their own server."""

import datetime
import json
import os
import http.client
import ipaddress
import socket
import sqlite3
import ssl
import subprocess
import threading
import time
import urllib.error
import urllib.request

import grpc
import numpy as np
import pytest
from grpc_health.v1 import health_pb2, health_pb2_grpc
from grpc_reflection.v1alpha import reflection_pb2

from conftest import Rest, Serving, rel, serve
from graybox_client import Client, GrayboxError, pb, pb_grpc, to_array

SECRET = "s3cret-t0ken"
X, U = np.array([0.3, -0.6, 2.0, -1.0]), np.array([15.0, -40.0])
GB_KB = 2 * 1024 * 1024  # 2 GB, in the kB of /proc/<pid>/status


@pytest.fixture(scope="module")
def dp_data(graybox_bin, tmp_path_factory):
    """256 simulated double-pendulum transitions (the session models' data)."""
    out = tmp_path_factory.mktemp("data") / "train.json"
    subprocess.run([graybox_bin, "simulate", "--system", "double_pendulum", "--count", "256",
                    "--seed", "0", "--out", str(out)], check=True, capture_output=True)
    return out


def upload(s: Serving, data) -> str:
    status, ds = s.rest.post("/v1/datasets?name=dp", raw=data.read_bytes())
    assert status == 201, ds
    return ds["id"]


def submit(s: Serving, dataset_id: str, epochs: int, model: str = "MVF") -> str:
    status, job = s.rest.post("/v1/jobs", {
        "dataset_id": dataset_id, "model": model, "template": "double_pendulum",
        "training": {"epochs": epochs, "batch_size": 64, "lr": 0.01}})
    assert status == 201, job
    return job["id"]


def train(s: Serving, data, model: str = "MVF") -> tuple[str, str]:
    """(dataset id, model id) of a model trained for 2 epochs on `data`."""
    ds = upload(s, data)
    job = s.rest.wait_job(submit(s, ds, 2, model))
    assert job["state"] == "succeeded", job
    return ds, job["model_id"]


def tvlqr(c: Client, model: str, T: int):
    return c.tvlqr(model, np.zeros((T + 1, 4)), np.zeros((T, 2)), np.eye(4), np.eye(2), np.eye(4))


# --- a. the API token on gRPC (and REST) ---------------------------------------------------

@pytest.fixture
def token_server(graybox_bin, tmp_path, dp_data):
    with serve(graybox_bin, tmp_path, "--workers", "1", "--api-token", SECRET, "--auth-reads",
               name="graybox serve --api-token", token=SECRET) as s:
        yield s, train(s, dp_data)[1]


def test_dynamics_calls_need_the_token_health_and_reflection_do_not(token_server):
    s, model = token_server
    calls = {
        "list_models": lambda c: c.list_models(),
        "get_model": lambda c: c.get_model(model),
        "predict": lambda c: c.predict(model, X, U),
        "rollout": lambda c: c.rollout(model, X, u=np.zeros((5, 2))),
        "linearize": lambda c: c.linearize(model, X, U),
        "tvlqr": lambda c: tvlqr(c, model, 3),
    }
    for token in [None, "wrong", SECRET + "x", SECRET[:-1]]:
        with Client(s.grpc_target, timeout=30, token=token) as c:
            for name, call in calls.items():
                with pytest.raises(GrayboxError) as e:
                    call(c)
                assert e.value.code == "UNAUTHENTICATED", (token, name, e.value)
    with Client(s.grpc_target, timeout=30) as c:
        # Only `Bearer <token>` exactly: not the bare token, another scheme or extra spaces.
        for value in [SECRET, f"Basic {SECRET}", f"Bearer  {SECRET}"]:
            with pytest.raises(grpc.RpcError) as e:
                c.stub.ListModels(pb.ListModelsRequest(), timeout=30,
                                  metadata=(("authorization", value),))
            assert e.value.code() == grpc.StatusCode.UNAUTHENTICATED, value

    with Client(s.grpc_target, timeout=30, token=SECRET) as c:
        models, _ = c.list_models()
        assert [m.id for m in models] == [model]
        assert c.get_model(model).id == model
        assert c.predict(model, X, U).shape == (4,)
        assert c.rollout(model, X, u=np.zeros((5, 2))).shape == (6, 4)
        a, b = c.linearize(model, X, U)
        assert a.shape == (4, 4) and b.shape == (4, 2)
        k, _ = tvlqr(c, model, 3)
        assert k.shape == (3, 2, 4)
        # The raw stub with the client's metadata, as the README says.
        assert c.stub.GetModel(pb.GetModelRequest(model_id=model), timeout=30,
                               metadata=c.metadata).id == model

    with grpc.insecure_channel(s.grpc_target) as ch:
        health = health_pb2_grpc.HealthStub(ch)
        for service in ["", "graybox.v1.Dynamics"]:
            r = health.Check(health_pb2.HealthCheckRequest(service=service), timeout=30)
            assert r.status == health_pb2.HealthCheckResponse.SERVING, service
        reflect = ch.stream_stream(
            "/grpc.reflection.v1.ServerReflection/ServerReflectionInfo",
            request_serializer=reflection_pb2.ServerReflectionRequest.SerializeToString,
            response_deserializer=reflection_pb2.ServerReflectionResponse.FromString)
        (listed,) = reflect(iter([reflection_pb2.ServerReflectionRequest(list_services="")]),
                            timeout=30)
        assert "graybox.v1.Dynamics" in {x.name for x in listed.list_services_response.service}

    # REST: with --auth-reads, reads need the token as well as writes; /healthz stays open.
    anonymous = Rest(s.rest.base)
    assert anonymous.get("/healthz")[0] == 200
    for method, path in [("GET", "/v1/models"), ("GET", f"/v1/models/{model}"), ("GET", "/v1/jobs"),
                         ("POST", "/v1/jobs")]:
        status, body = anonymous.request(method, path, {} if method == "POST" else None)
        assert status == 401, (method, path, body)
    status, body = s.rest.get("/v1/models")
    assert status == 200 and [m["id"] for m in body["items"]] == [model], body


# --- b. TLS --------------------------------------------------------------------------------

def write_pem(cert, key, tmp_path):
    """The certificate and its key as PEM files in `tmp_path`: (cert path, key path)."""
    from cryptography.hazmat.primitives import serialization
    cert_path, key_path = tmp_path / "cert.pem", tmp_path / "key.pem"
    cert_path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    key_path.write_bytes(key.private_bytes(serialization.Encoding.PEM,
                                           serialization.PrivateFormat.PKCS8,
                                           serialization.NoEncryption()))
    return cert_path, key_path


def self_signed(tmp_path):
    """A self-signed certificate for localhost and 127.0.0.1 and its key (PEM files)."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "localhost")])
    now = datetime.datetime.now(datetime.timezone.utc)
    cert = (x509.CertificateBuilder()
            .subject_name(name).issuer_name(name).public_key(key.public_key())
            .serial_number(x509.random_serial_number())
            .not_valid_before(now - datetime.timedelta(minutes=5))
            .not_valid_after(now + datetime.timedelta(days=1))
            .add_extension(x509.SubjectAlternativeName([
                x509.DNSName("localhost"), x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]),
                critical=False)
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            .sign(key, hashes.SHA256()))
    return write_pem(cert, key, tmp_path)


@pytest.fixture
def tls_server(graybox_bin, tmp_path):
    cert, key = self_signed(tmp_path)
    ctx = ssl.create_default_context(cafile=str(cert))
    with serve(graybox_bin, tmp_path, "--workers", "1", "--api-token", SECRET,
               "--tls-cert", str(cert), "--tls-key", str(key),
               name="graybox serve --tls-cert", token=SECRET, context=ctx) as s:
        yield s, cert, ctx


def test_tls_for_rest_and_grpc_and_silent_connections_block_nobody(tls_server):
    s, cert, ctx = tls_server
    # Clients that connect and never start their handshake, before anyone else connects
    # (the server drops them only after its 10 s handshake timeout).
    silent = [socket.create_connection(("127.0.0.1", port), timeout=5)
              for port in (s.http_port, s.grpc_port) for _ in range(3)]
    try:
        start = time.monotonic()
        with urllib.request.urlopen(f"https://127.0.0.1:{s.http_port}/healthz",
                                    context=ctx, timeout=5) as r:
            assert r.status == 200
        with Client(f"127.0.0.1:{s.grpc_port}", timeout=5, token=SECRET,
                    root_certificates=cert.read_bytes()) as c:
            assert c.list_models() == ([], "")
        assert time.monotonic() - start < 5
    finally:
        for sock in silent:
            sock.close()

    # The DNS name of the certificate, and the certificate given as a path.
    with Client(f"localhost:{s.grpc_port}", timeout=30, token=SECRET,
                root_certificates=str(cert)) as c:
        assert c.list_models() == ([], "")
    status, body = s.rest.get("/v1/models")
    assert status == 200 and body["items"] == [], body
    # TLS does not replace the token.
    with Client(f"localhost:{s.grpc_port}", timeout=30, root_certificates=str(cert)) as c:
        with pytest.raises(GrayboxError) as e:
            c.list_models()
        assert e.value.code == "UNAUTHENTICATED", e.value
    # Plaintext to the TLS ports fails.
    with Client(s.grpc_target, timeout=10, token=SECRET) as c:
        with pytest.raises(GrayboxError) as e:
            c.list_models()
        assert e.value.code == "UNAVAILABLE", e.value
    with pytest.raises((OSError, http.client.HTTPException)):  # a TLS alert is no HTTP
        urllib.request.urlopen(f"http://127.0.0.1:{s.http_port}/healthz", timeout=10).close()
    # A client that does not trust the certificate refuses the server.
    with pytest.raises(urllib.error.URLError) as e:
        urllib.request.urlopen(f"https://127.0.0.1:{s.http_port}/healthz",
                               context=ssl.create_default_context(), timeout=10).close()
    assert isinstance(e.value.reason, ssl.SSLCertVerificationError), e.value


def health(graybox_bin, http, cert=None):
    """`graybox health` as a container runs it: configured by the service's own variables."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("GRAYBOX_")}
    env["GRAYBOX_HTTP"] = http
    if cert is not None:
        env["GRAYBOX_TLS_CERT"] = str(cert)
    return subprocess.run([graybox_bin, "health"], env=env, capture_output=True, text=True,
                          timeout=30)


def test_health_check_follows_the_address_and_tls(graybox_bin, tls_server, tmp_path):
    s, cert, _ = tls_server
    ok = health(graybox_bin, f"0.0.0.0:{s.http_port}", cert)
    assert ok.returncode == 0 and ok.stdout.strip() == "ready", ok
    # Another certificate than the service's: refused (exit 1, the unhealthy code).
    other_dir = tmp_path / "other"
    other_dir.mkdir()
    other, _ = self_signed(other_dir)
    bad = health(graybox_bin, f"127.0.0.1:{s.http_port}", other)
    assert bad.returncode == 1 and "certificate" in bad.stderr, bad
    # Plain HTTP against the TLS port: unhealthy, not a hang.
    plain = health(graybox_bin, f"127.0.0.1:{s.http_port}")
    assert plain.returncode == 1, plain
    # Nothing listening.
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        free = sock.getsockname()[1]
    gone = health(graybox_bin, f"127.0.0.1:{free}")
    assert gone.returncode == 1 and gone.stderr.startswith("error:"), gone


def test_health_check_without_tls(graybox_bin, server):
    ok = health(graybox_bin, server.rest.base.removeprefix("http://"))
    assert ok.returncode == 0 and ok.stdout.strip() == "ready", ok


# --- c. memory of oversized calls -----------------------------------------------------------

@pytest.fixture
def probe_server(graybox_bin, tmp_path, dp_data):
    with serve(graybox_bin, tmp_path, "--workers", "1", "--max-rollout-steps", "100000",
               name="graybox serve (memory probes)") as s:
        yield s, train(s, dp_data)[1]


def test_oversized_calls_are_refused_or_chunked_within_bounded_memory(probe_server):
    s, model = probe_server
    rng = np.random.default_rng(3)
    B = 10**6
    x = np.column_stack([rng.uniform(-np.pi, np.pi, (B, 2)), rng.uniform(-10, 10, (B, 2))])
    u = rng.normal(0.0, 50.0, (B, 2))
    hwm = {"trained": s.status("VmHWM")}
    with Client(s.grpc_target, timeout=300) as c:
        # [10⁶, 4, 4] and [10⁶, 4, 2] doubles: 192 MB, three times the message limit.
        with pytest.raises(GrayboxError) as e:
            c.linearize(model, x, u)
        assert e.value.code == "RESOURCE_EXHAUSTED", e.value
        assert "message limit" in e.value.message and "--grpc-max-message-mb" in e.value.message, \
            e.value
        hwm["linearize refused"] = s.status("VmHWM")
        assert hwm["linearize refused"] < GB_KB, hwm

        x_next, z = c.predict(model, x, u, return_z=True)
        hwm["predict"] = s.status("VmHWM")
        assert x_next.shape == (B, 4) and np.isfinite(x_next).all()
        assert z.shape == (B,) and np.isfinite(z).all()
        for i in [0, 123_457, B - 1]:  # rows in different chunks equal single-point calls
            assert rel(c.predict(model, x[i], u[i]), x_next[i]) <= 1e-12, i
        assert hwm["predict"] < GB_KB, hwm

        T = 10**5
        try:
            K, S = tvlqr(c, model, T)
            assert K.shape == (T, 2, 4) and S.shape == (T + 1, 4, 4) and np.isfinite(K).all()
        except GrayboxError as e:
            assert e.code == "RESOURCE_EXHAUSTED" and "limit" in e.message, e
        hwm["tvlqr"] = s.status("VmHWM")
        assert hwm["tvlqr"] < GB_KB, hwm


# --- d. streams nobody reads ----------------------------------------------------------------

@pytest.fixture
def busy_server(graybox_bin, tmp_path, dp_data):
    with serve(graybox_bin, tmp_path, "--workers", "1", "--max-rollout-steps", "100000",
               "--grpc-max-streams", "100", name="graybox serve (unread streams)") as s:
        yield (s, *train(s, dp_data))


def test_unread_rollout_streams_starve_neither_calls_nor_training(busy_server):
    s, dataset, model = busy_server
    job = submit(s, dataset, 100_000)
    end = time.monotonic() + 60
    while (j := s.rest.get(f"/v1/jobs/{job}")[1])["state"] != "running" or j["epoch"] < 1:
        assert j["state"] in ("queued", "running") and time.monotonic() < end, j
        time.sleep(0.05)

    # Other callers, from before the streams open until after they stall: every Predict
    # (100 states) and Tvlqr (T = 10) must succeed within its 10 s deadline.
    failures, probes, threads, stop = [], [0], [], threading.Event()
    t0 = time.monotonic()

    def probe():
        rng = np.random.default_rng(4)
        xs, us = rng.uniform(-1.0, 1.0, (100, 4)), rng.uniform(-10.0, 10.0, (100, 2))
        with Client(s.grpc_target, timeout=10) as c:
            while not stop.is_set():
                threads.append(s.status("Threads"))
                for name, call in [("predict", lambda: c.predict(model, xs, us)),
                                   ("tvlqr", lambda: tvlqr(c, model, 10)[0])]:
                    try:
                        out = call()
                        if not np.isfinite(out).all():
                            failures.append((round(time.monotonic() - t0, 1), name, "non-finite"))
                    except GrayboxError as e:
                        failures.append((round(time.monotonic() - t0, 1), name, str(e)))
                probes[0] += 1
                time.sleep(0.1)

    T, per_channel = 10**5, 100
    req = pb.RolloutRequest(model_id=model, x0=X.tolist(), u=to_array(np.zeros((T, 2))), chunk=1)
    # Six connections (a local subchannel pool each: grpc would otherwise share one), each
    # with as many streams as the server allows on a connection.
    channels = [grpc.insecure_channel(s.grpc_target, options=[("grpc.use_local_subchannel_pool", 1)])
                for _ in range(6)]
    calls = []
    prober = threading.Thread(target=probe)
    prober.start()
    try:
        for ch in channels:
            stub = pb_grpc.DynamicsStub(ch)
            calls += [stub.Rollout(req, timeout=600) for _ in range(per_channel)]
        opened = round(time.monotonic() - t0, 1)
        epoch = s.rest.get(f"/v1/jobs/{job}")[1]["epoch"]
        time.sleep(3.0)
        end = time.monotonic() + 30
        while (e := s.rest.get(f"/v1/jobs/{job}")[1]["epoch"]) <= epoch:
            assert time.monotonic() < end, f"training stalled at epoch {e}"
            time.sleep(0.2)
        stop.set()
        prober.join()
        assert probes[0] >= 5 and not failures, (
            f"{len(failures)} failed calls in {probes[0]} rounds of Predict and Tvlqr (the streams "
            f"were opened from 0 to {opened} s): first {failures[:1]}, last {failures[-1:]}")
        assert threads and max(threads) <= 64, threads
        # Every stream is still held open: none was refused or ended.
        ended = [call.code().name for call in calls if call.done()]
        assert not ended, f"{len(ended)} of {len(calls)} streams ended: {set(ended)}"
    finally:
        stop.set()
        prober.join()
        for call in calls:
            call.cancel()
        for ch in channels:
            ch.close()
        status, body = s.rest.post(f"/v1/jobs/{job}/cancel")
    assert status == 200, body
    assert s.rest.wait_job(job)["state"] == "cancelled"


# --- e. how far outside the training data ---------------------------------------------------

@pytest.fixture(params=["wb", "mvf"])
def model(request, models):
    return getattr(models, request.param)


def test_max_abs_z_grows_outside_the_training_data(client, model):
    x_next, z = client.predict(model, X, U, return_z=True)
    assert x_next.shape == (4,) and isinstance(z, float) and 0.0 <= z < 5.0, z
    _, far = client.predict(model, [1e6, 0.0, 0.0, 0.0], [0.0, 0.0], return_z=True)
    _, farther = client.predict(model, [2e6, 0.0, 0.0, 0.0], [0.0, 0.0], return_z=True)
    assert far > 1e4, far
    assert abs(farther / far - 2.0) < 1e-4, (far, farther)  # |q − mean| / std
    _, z_u = client.predict(model, X, [0.0, -1e6], return_z=True)
    assert z_u > 1e3, z_u  # u counts too
    # A batch gives one z per row, equal to the single points'.
    xb = np.array([X, [1e6, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, -1e5]])
    ub = np.array([U, [0.0, 0.0], [0.0, 0.0]])
    x_b, accel, zb = client.predict(model, xb, ub, want_accel=True, return_z=True)
    assert x_b.shape == (3, 4) and accel.shape == (3, 2) and zb.shape == (3,)
    assert zb[0] == z and zb[1] == far and zb[2] > 1e3, zb


def test_linearize_and_rollout_report_z_per_point(client, model):
    a, b, z = client.linearize(model, X, U, return_z=True)
    assert a.shape == (4, 4) and b.shape == (4, 2) and z == client.predict(model, X, U, return_z=True)[1]
    xb = np.array([X, [0.0, 1e6, 0.0, 0.0], [0.1, 0.2, 0.3, 0.4]])
    ub = np.array([U, [0.0, 0.0], [1.0, -1.0]])
    a, b, zb = client.linearize(model, xb, ub, return_z=True)
    assert a.shape == (3, 4, 4) and b.shape == (3, 4, 2) and zb.shape == (3,)
    assert np.array_equal(zb, client.predict(model, xb, ub, return_z=True)[1])
    assert zb[1] > 1e4 and zb[0] < 5 and zb[2] < 5, zb

    T = 60
    t = np.arange(T)
    u = np.column_stack([20 * np.sin(0.1 * t), -10 + 0 * t])
    xs, z = client.rollout(model, X, u=u, chunk=7, return_z=True)
    assert xs.shape == (T + 1, 4) and z.shape == (T,)
    # z_t is that of (x_t, u_t), the state each input was applied at.
    assert np.array_equal(z, client.predict(model, xs[:-1], u, return_z=True)[1])
    xs2, us2, z2 = client.rollout(model, X, u=u, chunk=1, with_inputs=True, return_z=True)
    assert np.array_equal(xs2, xs) and np.array_equal(us2, u) and np.array_equal(z2, z)
    chunks = list(client.rollout_chunks(model, X, u=u, chunk=7, return_z=True))
    assert all(len(cz) == len(cu) for _, _, cu, cz in chunks)
    assert np.array_equal(np.concatenate([cz for *_, cz in chunks]), z)
    assert all(len(c) == 3 for c in client.rollout_chunks(model, X, u=u, chunk=7))


# --- f. numbers chosen to overflow ----------------------------------------------------------

def overflowing(rows: int, width: int) -> pb.Array:
    """Shape [rows, width] with as many values as rows·width leaves when it wraps in 64 bits."""
    return pb.Array(shape=[rows, width], data=[0.0] * ((rows * width) % 2**64))


@pytest.mark.parametrize("rows", [2**63 + 1, 2**62, 2**62 + 1])
def test_shapes_whose_size_overflows_are_invalid(client, models, rows):
    """[2⁶³ + 1, 4] with 4 values, [2⁶², 4] with none, …: the shape must not match its data
    modulo 2⁶⁴."""
    x = overflowing(rows, 4)
    u = overflowing(2**63 + (rows % 2), 2)  # [2⁶³ + 1, 2] with 2 values or [2⁶³, 2] with none
    assert len(x.data) <= 4 and len(u.data) <= 2
    ok_x, ok_u = to_array(np.zeros((1, 4))), to_array(np.zeros((1, 2)))
    eye = {"q": to_array(np.eye(4)), "r": to_array(np.eye(2)), "qf": to_array(np.eye(4))}
    rollout = lambda r, **kw: list(client.stub.Rollout(r, **kw))  # noqa: E731
    requests = [
        ("x", client.stub.Predict, pb.PredictRequest(model_id=models.wb, x=x, u=ok_u)),
        ("u", client.stub.Predict, pb.PredictRequest(model_id=models.wb, x=ok_x, u=u)),
        ("x", client.stub.Linearize, pb.LinearizeRequest(model_id=models.mvf, x=x, u=ok_u)),
        ("x_bar", client.stub.Tvlqr, pb.TvlqrRequest(
            model_id=models.wb, x_bar=x, u_bar=to_array(np.zeros((2, 2))), **eye)),
        ("u_bar", client.stub.Tvlqr, pb.TvlqrRequest(
            model_id=models.wb, x_bar=to_array(np.zeros((3, 4))), u_bar=u, **eye)),
        ("u", rollout, pb.RolloutRequest(model_id=models.wb, x0=X.tolist(), u=u)),
    ]
    for field, method, request in requests:
        with pytest.raises(GrayboxError) as e:
            client._call(method, request)
        assert e.value.code == "INVALID_ARGUMENT" and field in e.value.message, (field, e.value)


# --- g. a shutdown while calls and a job compute ----------------------------------------------

def test_sigterm_exits_within_the_grace_and_gives_the_running_job_back(graybox_bin, tmp_path,
                                                                        dp_data):
    """Two Plans far longer than any grace (no deadline; 10⁴-step rollouts, 1000 restarts)
    hold both heavy permits while a job trains on epochs longer than the grace. SIGTERM ends
    the process within its bound (grace, then giving jobs back, then exit) with status 0 —
    it once waited for the Plans forever — and the job is back in the queue, claimable at
    once, not counted as a dead worker."""
    grace = 2
    data = tmp_path / "big.json"
    subprocess.run([graybox_bin, "simulate", "--system", "double_pendulum", "--count", "20000",
                    "--seed", "1", "--out", str(data)], check=True, capture_output=True)
    flags = ("--workers", "1", "--shutdown-grace-secs", str(grace))
    with serve(graybox_bin, tmp_path, *flags, name="graybox serve (shutdown)") as s:
        model = train(s, dp_data)[1]
        wide = {"type": "mlp", "hidden": [512, 512]}  # epochs of seconds: ~8 s here, alone
        status, job = s.rest.post("/v1/jobs", {
            "dataset_id": upload(s, data), "template": "double_pendulum",
            "model": {"kind": "structured", "mass": wide, "potential": wide, "forces": wide},
            "training": {"epochs": 1000, "batch_size": 1024, "lr": 1e-5}})
        assert status == 201, job
        running = s.rest.wait_job(job["id"], until=("running", "succeeded", "failed"))
        assert running["state"] == "running", running
        req = pb.PlanRequest(model_id=model, x0=[0.0] * 4, goal=[np.pi, 0, 0, 0],
                             horizon=10_000, q=to_array(np.eye(4)), r=to_array(1e-4 * np.eye(2)),
                             qf=to_array(1e3 * np.eye(4)), max_iterations=0, restarts=1000)
        with grpc.insecure_channel(s.grpc_target) as ch:
            plans = [pb_grpc.DynamicsStub(ch).Plan.future(req) for _ in range(2)]
            time.sleep(1.0)
            assert not any(p.done() for p in plans), [p.exception() for p in plans if p.done()]
            t0 = time.monotonic()
            s.proc.terminate()
            code = s.proc.wait(timeout=30)
            exited = time.monotonic() - t0
        assert code == 0, (code, exited)
        # The grace, then at most 5 s giving jobs back and 1 s for the runtime: the bound.
        assert exited < grace + 6 + 1, exited
    db = sqlite3.connect(tmp_path / "graybox.db")
    state, owner, deaths = db.execute("SELECT state, lease_owner, worker_deaths FROM jobs "
                                      "WHERE id = ?", (job["id"],)).fetchone()
    db.close()
    assert (state, owner, deaths) == ("queued", None, 0)


# --- Inputs that used to abort the whole process (recursion on the input) -----------------

def long_pendulum(terms: int) -> dict:
    """A pendulum whose potential is −m g l cos θ as a flat sum of `terms` equal parts."""
    part = f"{1.0 / terms!r}*m*g*l*cos(theta)"
    return {"kind": "formula", "name": f"long{terms}", "coordinates": ["theta"],
            "inputs": ["u"],
            "parameters": {"m": {"value": 1.0, "positive": True},
                           "l": {"value": 1.0, "positive": True},
                           "g": {"value": 9.81, "positive": True}},
            "mass": [["m*l^2"]], "potential": " ".join([f"-{part}"] * terms),
            "forces": ["u"]}


def test_formula_models_that_used_to_abort_the_process_are_served(graybox_bin, tmp_path):
    """A model whose potential is a flat sum of 300 or 3000 terms (its first Linearize, or
    Predict, used to overflow a thread's stack and abort the process, again after every
    restart) answers; nested documents are 422s; the process is alive throughout."""
    with serve(graybox_bin, tmp_path) as s:
        with Client(s.grpc_target, timeout=120) as c:
            for terms in (300, 3000):
                doc = tmp_path / f"long{terms}.json"
                doc.write_text(json.dumps(long_pendulum(terms)))
                model = tmp_path / f"long{terms}.gbx"
                subprocess.run([graybox_bin, "model", "--template", str(doc), "--dt", "0.05",
                                "--out", str(model)], check=True, capture_output=True)
                status, m = s.rest.post("/v1/models", raw=model.read_bytes())
                assert status == 201, m
                a, b = c.linearize(m["id"], [0.3, -0.1], [0.5])
                assert np.all(np.isfinite(a)) and np.all(np.isfinite(b))
                x_next = c.predict(m["id"], np.full((64, 2), 0.2), np.full((64, 1), 0.1))
                assert np.all(np.isfinite(x_next))
        for nested in ("(" * 2000 + "theta" + ")" * 2000, "sin(" * 2000 + "theta" + ")" * 2000,
                       "-" * 2000 + "theta"):
            status, body = s.rest.post("/v1/templates", {**long_pendulum(1), "potential": nested})
            assert status == 422 and body["error"]["field"] == "potential", body
            assert "more than 256 levels" in body["error"]["message"], body
        assert s.proc.poll() is None, "the server died"
        assert s.rest.get("/healthz")[0] == 200


# --- Request bodies in flight share one memory budget -------------------------------------

def upload_100_continue(port: int, path: str, body: bytes, content_type: str) -> tuple[int, dict]:
    """POST with `Expect: 100-continue`: the body goes only when the server asks for it, so
    an upload refused before it is read costs neither side its bytes. (status, headers)."""
    with socket.create_connection(("127.0.0.1", port), timeout=120) as s:
        s.sendall((f"POST {path} HTTP/1.1\r\nhost: x\r\ncontent-type: {content_type}\r\n"
                   f"content-length: {len(body)}\r\nexpect: 100-continue\r\n\r\n").encode())
        f = s.makefile("rb")
        status = int(f.readline().split()[1])
        if status == 100:
            f.readline()  # the blank line after "100 Continue"
            s.sendall(body)
            status = int(f.readline().split()[1])
        headers = {}
        for line in iter(f.readline, b"\r\n"):
            k, _, v = line.decode().partition(":")
            headers[k.strip().lower()] = v.strip()
        return status, headers


def dataset_bodies(mb: int) -> tuple[bytes, bytes]:
    """A double-pendulum-shaped dataset of about `mb` MB as JSON and as CSV (random values:
    the budget does not care whether they are physical)."""
    rng = np.random.default_rng(0)
    rows = mb * 2**20 // 190
    a = rng.uniform(-3, 3, size=(rows, 10))
    cols = {"q": a[:, 0:2], "qdot": a[:, 2:4], "u": a[:, 4:6], "q_next": a[:, 6:8],
            "qdot_next": a[:, 8:10]}
    js = json.dumps({"dt": 0.01, **{k: v.tolist() for k, v in cols.items()}}).encode()
    head = "q0,q1,qdot0,qdot1,u0,u1,q_next0,q_next1,qdot_next0,qdot_next1\n"
    body = "\n".join(",".join(repr(float(v)) for v in r) for r in a)
    return js, (head + body + "\n").encode()


def test_concurrent_uploads_stay_within_the_body_budget(graybox_bin, tmp_path):
    """20 concurrent 100 MB dataset uploads (JSON, then CSV), 20 model files and 20 template
    documents at their size limits, and 10 concurrent template lists: each upload is stored
    or refused with 503 and Retry-After before its body is read, and the process's peak RSS
    stays under 1 GB (before the budget, 50 concurrent 200 MB uploads passed 3 GB)."""
    with serve(graybox_bin, tmp_path, "--workers", "0") as s:
        model = tmp_path / "dp.gbx"
        subprocess.run([graybox_bin, "model", "--template", "double_pendulum", "--dt", "0.01",
                        "--out", str(model)], check=True, capture_output=True)
        gbx = model.read_bytes()
        # Valid documents padded with whitespace to their kinds' limits (64 MB, 8 MB).
        big_model = gbx[:-1] + b" " * (64 * 2**20 - len(gbx) - 1) + gbx[-1:]
        doc = json.dumps(long_pendulum(300)).encode()
        big_template = doc[:-1] + b" " * (8 * 2**20 - len(doc) - 1) + doc[-1:]
        js, csv = dataset_bodies(100)
        rounds = [("/v1/datasets", js, "application/json"),
                  ("/v1/datasets?dt=0.01", csv, "text/csv"),
                  ("/v1/models", big_model, "application/octet-stream"),
                  ("/v1/templates", big_template, "application/json")]
        for path, body, ct in rounds:
            results = []
            threads = [threading.Thread(target=lambda: results.append(
                upload_100_continue(s.http_port, path, body, ct))) for _ in range(20)]
            for t in threads:
                t.start()
            for t in threads:
                t.join()
            statuses = sorted(r[0] for r in results)
            assert set(statuses) <= {200, 201, 503}, (path, statuses)
            assert statuses[0] in (200, 201), (path, statuses)
            assert all("retry-after" in h for st, h in results if st == 503), results
            print(f"{path}: {statuses.count(503)} of 20 refused; peak RSS "
                  f"{s.status('VmHWM') // 1024} MB")
        lists = [threading.Thread(target=lambda: s.rest.get("/v1/templates")) for _ in range(10)]
        for t in lists:
            t.start()
        for t in lists:
            t.join()
        peak = s.status("VmHWM") // 1024
        assert peak < 1024, f"peak RSS {peak} MB"
        assert s.proc.poll() is None


# --- TLS files: read with a bound; an expired certificate is said at start-up ---------------

def certificate(tmp_path, not_before, not_after):
    """A self-signed certificate for 127.0.0.1 valid from `not_before` to `not_after`, and its
    key (PEM files)."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "localhost")])
    cert = (x509.CertificateBuilder()
            .subject_name(name).issuer_name(name).public_key(key.public_key())
            .serial_number(x509.random_serial_number())
            .not_valid_before(not_before).not_valid_after(not_after)
            .add_extension(x509.SubjectAlternativeName([
                x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]), critical=False)
            .sign(key, hashes.SHA256()))
    return write_pem(cert, key, tmp_path)


def test_tls_files_over_the_limit_stop_the_start_up(graybox_bin, tmp_path):
    """`--tls-cert /dev/zero` used to be read until memory ran out: now the start-up stops at
    once, naming the flag and the 1 MiB limit, before the database is created."""
    from conftest import server_env

    good_cert, _ = self_signed(tmp_path)
    for cert, key, flag in (("/dev/zero", "/dev/zero", "--tls-cert"),
                            (str(good_cert), "/dev/zero", "--tls-key")):
        start = time.monotonic()
        run = subprocess.run([graybox_bin, "serve", "--http", "127.0.0.1:0", "--grpc",
                              "127.0.0.1:0", "--db", str(tmp_path / "never.db"),
                              "--tls-cert", cert, "--tls-key", key],
                             capture_output=True, text=True, timeout=30, env=server_env())
        took = time.monotonic() - start
        assert run.returncode != 0, run
        assert flag in run.stderr and "limit of 1 MiB" in run.stderr, run.stderr
        assert took < 5, took
        assert not (tmp_path / "never.db").exists()


def test_an_expired_certificate_is_warned_about_at_start_up(graybox_bin, tmp_path):
    """The service still starts (a certificate may be replaced while it runs), but its log
    says the certificate expired, and when."""
    utc = datetime.timezone.utc
    cert, key = certificate(tmp_path, datetime.datetime(2020, 1, 2, 3, 4, 5, tzinfo=utc),
                            datetime.datetime(2021, 6, 7, 8, 9, 10, tzinfo=utc))
    ctx = ssl.create_default_context()
    ctx.check_hostname, ctx.verify_mode = False, ssl.CERT_NONE  # it is expired, after all
    with serve(graybox_bin, tmp_path, "--workers", "0", "--tls-cert", str(cert),
               "--tls-key", str(key), name="graybox serve (expired certificate)",
               context=ctx) as s:
        log = s.log.read_text()
        assert "WARN" in log and "expired at 2021-06-07T08:09:10Z" in log, log
        # Clients that check certificates refuse it: why the warning matters.
        strict = ssl.create_default_context(cafile=str(cert))
        with pytest.raises(urllib.error.URLError) as e:
            urllib.request.urlopen(f"https://127.0.0.1:{s.http_port}/healthz", context=strict,
                                   timeout=10).close()
        assert "expired" in str(e.value.reason), e.value
