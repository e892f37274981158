"""Track a swing of the double pendulum with TVLQR gains, in this process: no server."""
import os

import numpy as np
import graybox_native
from graybox_native import GrayboxError

model = graybox_native.load(os.environ.get("MODEL_FILE", "mvf.gbx"))  # the walkthrough's file
info = model.info
print(f"model file: nq = {info.nq}, nv = {info.nv}, m = {info.m}, dt = {info.dt} s")

# The nominal swing: 100 steps (1 s) from rest at q = (0.3, -0.6) rad with no input, and
# TVLQR gains along it.
x = np.array([0.3, -0.6, 0.0, 0.0])     # [q1, q2, q1', q2']: rad, rad/s
T = 100
u_bar = np.zeros((T, 2))
x_bar = model.rollout(x, u=u_bar)                                # [T+1, 4]
K, S = model.tvlqr(x_bar, u_bar, np.eye(4), 0.01 * np.eye(2), 10 * np.eye(4))

# Start 0.1 rad off the swing and close the loop here, a step at a time, as a controller
# would: u = ū − K(x − x̄) at every step of the model, watching how far from its training
# data the model is asked to answer (|z| above ~4: outside it, where answers mean little).
x0 = x_bar[0] + np.array([0.1, -0.1, 0.0, 0.0])
open_loop = model.rollout(x0, u=u_bar)
xt, worst = x0, 0.0
for t in range(T):
    u = u_bar[t] - K[t] @ (xt - x_bar[t])
    xt, z = model.predict(xt, u, return_z=True)
    worst = max(worst, z)
off = np.linalg.norm(np.stack([open_loop[-1], xt]) - x_bar[-1], axis=1)
print(f"distance from the swing after 1 s: open loop {off[0]:.3f}, TVLQR {off[1]:.3f} "
      f"(largest |z| {worst:.1f})")

try:
    model.predict(x[:3], np.zeros(2))     # a state of the wrong size
except GrayboxError as e:
    print("refused:", e.code, e.field)
