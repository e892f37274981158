"""Track a swing of the double pendulum with TVLQR gains from a trained model."""
import os

import numpy as np
from graybox_client import Client, GrayboxError

model_id = os.environ["MODEL"]              # a model id, or the id of the job that trained it
target = os.environ.get("GRAYBOX_GRPC", "127.0.0.1:50051")

with Client(target) as c:
    info = c.get_model(model_id)
    print(f"model {info.id}: nq = {info.nq}, nv = {info.nv}, m = {info.m}, dt = {info.dt} s")

    # One step from rest at q = (0.3, -0.6) rad under a torque on the first joint.
    x = np.array([0.3, -0.6, 0.0, 0.0])     # [q1, q2, q1', q2']: rad, rad/s
    x_next, z = c.predict(model_id, x, np.array([20.0, 0.0]), return_z=True)
    print("one step:", np.round(x_next, 4), f"(|z| = {z:.1f}: inside the training data if < 4)")

    # The nominal swing: 100 steps (1 s) from x with no input, and TVLQR gains along it.
    T = 100
    u_bar = np.zeros((T, 2))
    x_bar = c.rollout(model_id, x, u=u_bar)                          # [T+1, 4]
    K, S = c.tvlqr(model_id, x_bar, u_bar, np.eye(4), 0.01 * np.eye(2), 10 * np.eye(4))

    # Start 0.1 rad off the swing: open loop stays off, u = ū − K(x − x̄) brings it back.
    x0 = x_bar[0] + np.array([0.1, -0.1, 0.0, 0.0])
    open_loop = c.rollout(model_id, x0, u=u_bar)
    closed_loop = c.rollout(model_id, x0, policy=(x_bar, u_bar, K))
    off = np.linalg.norm(np.stack([open_loop[-1], closed_loop[-1]]) - x_bar[-1], axis=1)
    print(f"distance from the swing after 1 s: open loop {off[0]:.3f}, TVLQR {off[1]:.3f}")

    try:
        c.predict(model_id, x[:3], np.zeros(2))     # a state of the wrong size
    except GrayboxError as e:
        print("refused:", e.code, e.message)
