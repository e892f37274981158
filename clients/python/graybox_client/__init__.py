"""Python client for graybox's gRPC API (service graybox.v1.Dynamics).

    from graybox_client import Client
    with Client("127.0.0.1:50051") as c:
        x_next = c.predict(model_id, x, u)

`pb` and `pb_grpc` are the generated messages and stubs, for requests the helpers do not cover.
"""

from ._pb import dynamics_pb2 as pb
from ._pb import dynamics_pb2_grpc as pb_grpc
from .client import Client, GrayboxError, ModelInfo, PlanResult, from_array, to_array

__all__ = ["Client", "GrayboxError", "ModelInfo", "PlanResult", "from_array", "to_array", "pb",
           "pb_grpc"]
