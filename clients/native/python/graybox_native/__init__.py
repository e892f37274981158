"""graybox's trained models inside your Python process, with no server.

    import graybox_native
    model = graybox_native.load("arm.gbx")          # a path, or the file's bytes
    model.info.n, model.info.dt                      # also model.info["n"], as a dict's
    x_next = model.predict(x, u)                     # x [nq + nv], u [m] (or batches [B, ...])
    x_next, z = model.predict(x, u, return_z=True)   # z: how far x, u are from the data
    A, B = model.linearize(x, u)
    xs, std = ensemble.rollout(x0, us, particles=50) # particles' mean and spread
    e = model.energy(x, u)                           # kinetic, potential, power, …
    K, S = model.tvlqr(xbar, ubar, Q, R, Qf)
    plan = model.plan(x0, goal, horizon, Q, R, Qf)

The calls, their keyword arguments and what they return are the gRPC client's
(`graybox_client.Client`) without the model id (README, "In your controller's process",
lists the few request options that have no keyword here, and why), and the answers are the
service's, bit for bit: both run graybox's inference core. Every computation releases the
GIL, so threads sharing one model run in parallel. A failed call raises `GrayboxError` with
the gRPC code the service would answer (e.g. "INVALID_ARGUMENT") and the `field` it names;
with graybox_client installed it is that package's `GrayboxError`, so one `except` catches
both. A model file that does not prove it is whole (its checksum does not match its
contents, or its members disagree with its report) is refused with INVALID_ARGUMENT; one
written before files carried a checksum loads with an `UncheckedModelWarning`.

`max_abs_z` (`return_z=True` on predict, linearize and rollout) is the largest |z-score| of
q, q̇ and u under the model's training data statistics: above ~4 the model is answering
outside its data, where a network's outputs are finite but meaningless.

A call is admitted under a memory budget as the service's calls are (its estimate, before
computing): over it, GrayboxError RESOURCE_EXHAUSTED names the argument at fault and the way
out. The budget starts at the service's default `--max-call-memory-mb` (512 MiB);
`set_memory_budget_mb(n)` sets it for the process and `memory_budget_mb()` reads it. Ctrl-C
interrupts a long call within about 50 ms with KeyboardInterrupt (in the main thread, which
receives signals).
"""

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ._shared import GrayboxError, PlanResult
else:
    try:
        # The one definition both packages install (_shared.py): the client's copy when the
        # client is installed, so that `except graybox_client.GrayboxError` catches ours.
        from graybox_client._shared import GrayboxError, PlanResult
    except ImportError:
        from ._shared import GrayboxError, PlanResult


@dataclass(frozen=True, eq=False)
class Info(Mapping[str, Any]):
    """What `Model.info` tells of a loaded model: its `nq` configuration values and `nv`
    velocities (a state is [q, v], nq + nv values; Linearize's A is [2nv, 2nv]), `n`
    (deprecated: nv), `m` inputs, the time step `dt` (s), the ensemble's `members` (1 for a
    single model), its `integrator`, its `joints` ("real", "angle", "circle": one per
    velocity), and the `coordinates`' and `inputs`' names. Also a read-only mapping of those
    names, as `info` was a dict: `info["n"]`, `dict(info)` and `info == {...}` work as they
    did."""

    nq: int
    nv: int
    n: int
    m: int
    dt: float
    members: int
    integrator: str
    joints: list[str]
    coordinates: list[str]
    inputs: list[str]

    def __getitem__(self, key: str) -> Any:
        if key not in _INFO_KEYS:
            raise KeyError(key)
        return getattr(self, key)

    def __iter__(self) -> Iterator[str]:
        return iter(_INFO_KEYS)

    def __len__(self) -> int:
        return len(_INFO_KEYS)


_INFO_KEYS = tuple(f.name for f in fields(Info))


class UncheckedModelWarning(UserWarning):
    """`load` read a model file that does not prove it is whole: one written before graybox
    files carried a checksum. It is served as it is; a file whose checksum does not match, or
    whose members disagree with its report, raises GrayboxError instead."""


from ._native import (  # noqa: E402  (the classes above first: the module makes them)
    Model,
    load,
    memory_budget_mb,
    set_memory_budget_mb,
)

__all__ = ["GrayboxError", "Info", "Model", "PlanResult", "UncheckedModelWarning", "load",
           "memory_budget_mb", "set_memory_budget_mb"]
