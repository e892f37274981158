"""The gRPC service around the Dynamics RPCs: health, reflection, request ids, message sizes
and a rollout at the configured step limit."""

import grpc
import numpy as np
import pytest
from google.protobuf import descriptor_pb2
from grpc_health.v1 import health_pb2, health_pb2_grpc
from grpc_reflection.v1alpha import reflection_pb2

from conftest import MAX_ROLLOUT_STEPS, rel
from graybox_client import Client, GrayboxError, pb, to_array


@pytest.fixture(scope="module")
def channel(server):
    with grpc.insecure_channel(server.grpc_target) as ch:
        yield ch


def reflect(channel, version: str, *requests):
    """ServerReflectionInfo. grpcio-reflection ships only v1alpha messages; v1's are the same
    on the wire, so they are sent to v1's method path as they are."""
    call = channel.stream_stream(
        f"/grpc.reflection.{version}.ServerReflection/ServerReflectionInfo",
        request_serializer=reflection_pb2.ServerReflectionRequest.SerializeToString,
        response_deserializer=reflection_pb2.ServerReflectionResponse.FromString)
    return list(call(iter(requests), timeout=30))


def test_health_is_serving(channel):
    health = health_pb2_grpc.HealthStub(channel)
    for service in ["", "graybox.v1.Dynamics"]:
        r = health.Check(health_pb2.HealthCheckRequest(service=service), timeout=30)
        assert r.status == health_pb2.HealthCheckResponse.SERVING, service
    with pytest.raises(grpc.RpcError) as e:
        health.Check(health_pb2.HealthCheckRequest(service="no.such.Service"), timeout=30)
    assert e.value.code() == grpc.StatusCode.NOT_FOUND


def test_reflection_v1_lists_the_services_and_serves_the_clients_proto(channel):
    listed, found = reflect(channel, "v1",
                            reflection_pb2.ServerReflectionRequest(list_services=""),
                            reflection_pb2.ServerReflectionRequest(file_containing_symbol="graybox.v1.Dynamics"))
    names = {s.name for s in listed.list_services_response.service}
    assert {"graybox.v1.Dynamics", "grpc.health.v1.Health"} <= names
    served = descriptor_pb2.FileDescriptorProto.FromString(
        found.file_descriptor_response.file_descriptor_proto[0])
    ours = descriptor_pb2.FileDescriptorProto()
    pb.DESCRIPTOR.CopyToProto(ours)
    # The same schema as the client was built from; json_name and source info depend only
    # on the protoc invocation.
    served.ClearField("source_code_info")
    for d in (served, ours):
        for message in d.message_type:
            for field in message.field:
                field.ClearField("json_name")
    assert served == ours


def test_reflection_v1alpha_lists_the_services(channel):
    (listed,) = reflect(channel, "v1alpha", reflection_pb2.ServerReflectionRequest(list_services=""))
    assert "graybox.v1.Dynamics" in {s.name for s in listed.list_services_response.service}


def test_request_ids_are_echoed(client, models):
    x, u = to_array([[0.1, 0.2, 0.3, 0.4]]), to_array([[1.0, -1.0]])
    assert client.stub.Predict(pb.PredictRequest(id="p-1", model_id=models.wb, x=x, u=u)).id == "p-1"
    assert client.stub.Linearize(pb.LinearizeRequest(id="l-2", model_id=models.wb, x=x, u=u)).id == "l-2"
    tv = pb.TvlqrRequest(id="t-3", model_id=models.wb, x_bar=to_array(np.zeros((2, 4))),
                         u_bar=to_array(np.zeros((1, 2))), q=to_array(np.eye(4)),
                         r=to_array(np.eye(2)), qf=to_array(np.eye(4)))
    assert client.stub.Tvlqr(tv).id == "t-3"
    req = pb.RolloutRequest(id="r-4", model_id=models.wb, x0=[0.1, 0.2, 0.3, 0.4],
                            u=to_array(np.zeros((10, 2))), chunk=3)
    assert [c.id for c in client.stub.Rollout(req)] == ["r-4"] * 4


def test_messages_over_grpcs_default_4_mib_limit(client, models, server):
    rows = 140_000  # the response alone is 4.5 MB
    rng = np.random.default_rng(2)
    x = rng.uniform(-1.0, 1.0, (rows, 4))
    u = rng.uniform(-10.0, 10.0, (rows, 2))
    x_next = client.predict(models.wb, x, u)
    assert x_next.shape == (rows, 4) and np.isfinite(x_next).all()
    for i in [0, rows // 2, rows - 1]:
        assert rel(client.predict(models.wb, x[i], u[i]), x_next[i]) <= 1e-12
    with Client(server.grpc_target, timeout=60, max_message_mb=1) as small:
        with pytest.raises(GrayboxError) as e:
            small.predict(models.wb, x[:40_000], u[:40_000])  # 1.9 MB request
        assert e.value.code == "RESOURCE_EXHAUSTED"


def test_a_rollout_at_the_step_limit_streams_every_chunk(client, models):
    T = MAX_ROLLOUT_STEPS
    t = np.arange(T)
    u = np.column_stack([20 * np.sin(0.01 * t), -10 * np.cos(0.013 * t)])
    x0 = [0.4, -0.2, 1.0, 0.5]
    starts, xs, us = zip(*client.rollout_chunks(models.wb, x0, u=u))
    sizes = [len(c) for c in xs]
    assert list(starts) == list(np.cumsum([0] + sizes[:-1])), "chunks are contiguous"
    assert sizes[:-1] == [1000] * (len(sizes) - 1), "the default chunk is 1000 states"
    xs, us = np.concatenate(xs), np.concatenate(us)
    assert xs.shape == (T + 1, 4) and np.isfinite(xs).all()
    assert np.array_equal(us, u)
    x = np.asarray(x0)
    for k in range(50):
        x = client.predict(models.wb, x, u[k])
        assert rel(x, xs[k + 1]) <= 1e-12
    assert rel(client.predict(models.wb, xs[-2], u[-1]), xs[-1]) <= 1e-12
