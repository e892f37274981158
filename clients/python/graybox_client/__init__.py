"""Python client for graybox: gRPC (`Client`, service graybox.v1.Dynamics: predictions,
rollouts, linearizations, TVLQR, plans) and REST (`RestClient`: datasets, jobs, models,
templates), numpy in and out, failures raised as `GrayboxError` by both.

    from graybox_client import Client, RestClient
    with RestClient("http://127.0.0.1:8080") as g:
        ds = g.upload_trajectories(trajectories, dt=0.01, name="swings")
        job = g.wait(g.submit_job(ds["id"], "MVF", training={"epochs": 200})["id"], progress=True)
    with Client("127.0.0.1:50051") as c:
        x_next = c.predict(job["model_id"], x, u)

`pb` and `pb_grpc` are the generated messages and stubs, for requests the helpers do not cover.
"""

from ._pb import dynamics_pb2 as pb
from ._pb import dynamics_pb2_grpc as pb_grpc
from ._shared import GrayboxError, PlanResult
from .client import Client, ModelInfo, from_array, to_array
from .rest import RestClient

__all__ = ["Client", "GrayboxError", "ModelInfo", "PlanResult", "RestClient", "from_array",
           "to_array", "pb", "pb_grpc"]
