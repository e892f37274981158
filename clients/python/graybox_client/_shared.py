"""The types both Python packages answer with: `GrayboxError` and `PlanResult`.

This one file is installed by both graybox-client (as `graybox_client._shared`) and
graybox-native (as `graybox_native._shared`, a symbolic link to it in the checkout), so that
neither package needs the other: the client needs no native module, and the native module
works without grpc. When both are installed, graybox_native takes the client's copy, so one
class is raised by both and `except graybox_client.GrayboxError` catches the native module's
errors too. Nothing else may go here: what is in it is what both packages promise alike.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np
from numpy.typing import NDArray


class GrayboxError(Exception):
    """A failed call: `code` is the gRPC status name (e.g. "INVALID_ARGUMENT") or the REST
    error's code (e.g. "unprocessable"), `message` the explanation; `field` the input it names
    (e.g. "training.epochs", None when it names none: REST's and the native module's errors
    name one, gRPC's do not), and `status`, the HTTP status of a REST error."""

    def __init__(self, code: str, message: str, field: Optional[str] = None,
                 status: Optional[int] = None):
        where = f" ({field})" if field else ""
        super().__init__(f"{code}{where}: {message}")
        self.code = code
        self.message = message
        self.field = field
        self.status = status


@dataclass
class PlanResult:
    """A plan: states `x` [T+1, nq + nv], inputs `u` [T, m], TVLQR gains `K` [T, m, 2nv] along
    them (u = ū − K(x ⊖ x̄)), the `cost`, `costs` (the initial guess's, then after each accepted
    iteration; non-increasing for iLQR), `iterations`, `converged`, `goal_error`
    (‖x_T ⊖ goal‖₂), the `method` that made it, and for direct collocation its largest defect
    (`constraint_violation`) and how far the model's one-step rollout of `u` strays from `x`
    (`rollout_deviation`); both 0 for iLQR. An ensemble's plan also has `x_std` [T+1, nq + nv], the
    members' standard deviation of each state along `u` (None for a single model)."""

    x: NDArray[np.float64]
    u: NDArray[np.float64]
    K: NDArray[np.float64]
    cost: float
    costs: NDArray[np.float64]
    iterations: int
    converged: bool
    goal_error: float
    method: str = "ilqr"
    constraint_violation: float = 0.0
    rollout_deviation: float = 0.0
    x_std: Optional[NDArray[np.float64]] = None
