"""graybox's trained models inside your Python process, with no server.

    import graybox_native
    model = graybox_native.load("arm.gbx")          # a path, or the file's bytes
    x_next = model.predict(x, u)                     # x [2n], u [m] (or batches [B, ...])
    A, B = model.linearize(x, u)
    K, S = model.tvlqr(xbar, ubar, Q, R, Qf)
    plan = model.plan(x0, goal, horizon, Q, R, Qf)

The calls and their arguments are the gRPC client's (`graybox_client.Client`) without the
model id, and the answers are the service's, bit for bit: both run graybox's inference core.
Every computation releases the GIL, so threads sharing one model run in parallel. A failed
call raises `GrayboxError` with the gRPC code the service would answer (e.g.
"INVALID_ARGUMENT") and the `field` it names; with graybox_client installed it is that
package's `GrayboxError`, so one `except` catches both. A model file that does not prove it
is whole (its checksum does not match its contents, or its members disagree with its report)
is refused with INVALID_ARGUMENT; one written before files carried a checksum loads with an
`UncheckedModelWarning`.

A call is admitted under a memory budget as the service's calls are (its estimate, before
computing): over it, GrayboxError RESOURCE_EXHAUSTED names the argument at fault and the way
out. The budget starts at the service's default `--max-call-memory-mb` (512 MiB);
`set_memory_budget_mb(n)` sets it for the process and `memory_budget_mb()` reads it. Ctrl-C
interrupts a long call within about 50 ms with KeyboardInterrupt (in the main thread, which
receives signals).
"""

from dataclasses import dataclass
from typing import Optional

import numpy as np

try:
    from graybox_client import GrayboxError, PlanResult
except ImportError:
    class GrayboxError(Exception):
        """A failed call: `code` is a gRPC status name (e.g. "INVALID_ARGUMENT"), `message`
        the explanation, `field` the argument it names (None when it names none)."""

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
        """A plan: states `x` [T+1, 2n], inputs `u` [T, m], TVLQR gains `K` [T, m, 2n], its
        `cost`, `costs` per accepted iteration, `iterations`, `converged`, `goal_error`, the
        `method`, collocation's `constraint_violation` and `rollout_deviation`, and an
        ensemble's `x_std` [T+1, 2n] (None for a single model)."""

        x: np.ndarray
        u: np.ndarray
        K: np.ndarray
        cost: float
        costs: np.ndarray
        iterations: int
        converged: bool
        goal_error: float
        method: str = "ilqr"
        constraint_violation: float = 0.0
        rollout_deviation: float = 0.0
        x_std: Optional[np.ndarray] = None


class UncheckedModelWarning(UserWarning):
    """`load` read a model file that does not prove it is whole: one written before graybox
    files carried a checksum. It is served as it is; a file whose checksum does not match, or
    whose members disagree with its report, raises GrayboxError instead."""


from ._native import (  # noqa: E402  (GrayboxError first: the module raises it)
    Model,
    load,
    memory_budget_mb,
    set_memory_budget_mb,
)

__all__ = ["GrayboxError", "Model", "PlanResult", "UncheckedModelWarning", "load",
           "memory_budget_mb", "set_memory_budget_mb"]
