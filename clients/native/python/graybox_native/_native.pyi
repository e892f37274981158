# The extension module's types (clients/native/src). A call whose extras are all off returns
# one array; one with extras returns a tuple whose length and members depend on the flags
# (and z is a float for one state, an array for a batch), typed Any rather than a union
# every caller would have to narrow.

import os
from typing import Any, Literal, final, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import Info, PlanResult

_Array = NDArray[np.float64]
_Policy = tuple[ArrayLike, ArrayLike, ArrayLike]

def load(source: str | os.PathLike[str] | bytes) -> Model: ...
def set_memory_budget_mb(mb: int) -> None: ...
def memory_budget_mb() -> int: ...

@final
class Model:
    @property
    def info(self) -> Info: ...
    @overload
    def predict(
        self,
        x: ArrayLike,
        u: ArrayLike | None = None,
        want_accel: Literal[False] = False,
        return_std: Literal[False] = False,
        members: Literal[False] = False,
        return_z: Literal[False] = False,
        dt: float | None = None,
    ) -> _Array: ...
    @overload
    def predict(
        self,
        x: ArrayLike,
        u: ArrayLike | None = None,
        want_accel: bool = False,
        return_std: bool = False,
        members: bool = False,
        return_z: bool = False,
        dt: float | None = None,
    ) -> Any: ...
    def step(self, x: ArrayLike, u: ArrayLike | None = None) -> _Array: ...
    @overload
    def linearize(
        self, x: ArrayLike, u: ArrayLike | None = None, return_z: Literal[False] = False
    ) -> tuple[_Array, _Array]: ...
    @overload
    def linearize(
        self, x: ArrayLike, u: ArrayLike | None = None, *, return_z: Literal[True]
    ) -> tuple[_Array, _Array, Any]: ...
    @overload
    def linearize(
        self, x: ArrayLike, u: ArrayLike | None = None, return_z: bool = False
    ) -> tuple[Any, ...]: ...
    @overload
    def rollout(
        self,
        x0: ArrayLike,
        u: ArrayLike | None = None,
        policy: _Policy | None = None,
        with_inputs: Literal[False] = False,
        return_z: Literal[False] = False,
        particles: None = None,
        dt: float | None = None,
    ) -> _Array: ...
    @overload
    def rollout(
        self,
        x0: ArrayLike,
        u: ArrayLike | None = None,
        policy: _Policy | None = None,
        with_inputs: bool = False,
        return_z: bool = False,
        particles: int | None = None,
        dt: float | None = None,
    ) -> Any: ...
    def tvlqr(
        self, xbar: ArrayLike, ubar: ArrayLike, Q: ArrayLike, R: ArrayLike, Qf: ArrayLike
    ) -> tuple[_Array, _Array]: ...
    def plan(
        self,
        x0: ArrayLike,
        goal: ArrayLike,
        horizon: int,
        Q: ArrayLike,
        R: ArrayLike,
        Qf: ArrayLike,
        u_min: ArrayLike | None = None,
        u_max: ArrayLike | None = None,
        u_init: ArrayLike | None = None,
        max_iterations: int = 200,
        tolerance: float = 1e-6,
        restarts: int = 0,
        seed: int = 0,
        time_limit_ms: int = 0,
        method: str = "ilqr",
        x_init: ArrayLike | None = None,
        x_min: ArrayLike | None = None,
        x_max: ArrayLike | None = None,
        ensemble_cost: str = "",
    ) -> PlanResult: ...
    def energy(self, x: ArrayLike, u: ArrayLike | None = None) -> dict[str, Any]: ...
    def inverse_dynamics(self, x: ArrayLike, qdd: ArrayLike) -> dict[str, Any]: ...
