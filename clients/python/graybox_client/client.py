"""A thin numpy front end over the graybox.v1.Dynamics stubs.

The client converts arrays and errors and nothing else: shapes, finiteness and the LQR
weights are validated by the server, which names the offending field, so a bad request
reaches it and comes back as a GrayboxError with the server's status code and message.

Predict, Linearize and Rollout also report, per row, `max_abs_z`: the largest |z-score| of
q, q̇ and u under the model's training data statistics (how far outside its data the model
was asked to answer; above ~4, treat the outputs with doubt). Pass `return_z=True` to get it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any, Callable, Iterator, Literal, Optional, Sequence, Union, overload

# grpc ships no annotations (types-grpcio has them): its objects are Any here.
import grpc  # type: ignore[import-untyped, unused-ignore]
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._pb import dynamics_pb2 as pb
from ._pb import dynamics_pb2_grpc as pb_grpc
from ._shared import GrayboxError, PlanResult

Array = NDArray[np.float64]
# A TVLQR policy: x̄ [T+1 or T, nq + nv], ū [T, m], K [T, m, 2nv].
Policy = Sequence[ArrayLike]


@dataclass
class ModelInfo:
    """A trained model as GetModel and ListModels describe it; `spec` and `metrics` are the
    server's JSON, parsed. A state is [q, v]: `nq` configuration values and `nv` velocities
    (Linearize's A is [2nv, 2nv]); `n`, deprecated, is `nv`."""

    id: str
    job_id: str
    name: str
    n: int
    m: int
    dt: float
    spec: dict[str, Any]
    metrics: dict[str, Any]
    created_at: str
    nq: int = 0
    nv: int = 0


def to_array(a: Any) -> pb.Array:
    """A float64 array in C order as Array{shape, data}."""
    a = np.ascontiguousarray(a, dtype=np.float64)
    return pb.Array(shape=a.shape, data=a.ravel().tolist())


def from_array(a: pb.Array) -> Array:
    return np.asarray(a.data, dtype=np.float64).reshape(tuple(a.shape))


def _model_info(m: pb.ModelInfo) -> ModelInfo:
    # The JSON fields are parsed here so that callers get plain dicts, not strings.
    return ModelInfo(
        id=m.id, job_id=m.job_id, name=m.name, n=m.n, m=m.m, dt=m.dt, nq=m.nq, nv=m.nv,
        spec=json.loads(m.spec_json) if m.spec_json else {},
        metrics=json.loads(m.metrics_json) if m.metrics_json else {},
        created_at=m.created_at,
    )


def _z(values: Sequence[float], rows: int, single: bool) -> Union[float, Array]:
    """max_abs_z as [B] (a float for a single point); a server that sent none is an error."""
    z = np.asarray(values, dtype=np.float64)
    if len(z) != rows:
        raise GrayboxError("DATA_LOSS", f"the server sent {len(z)} max_abs_z values for {rows} rows")
    return float(z[0]) if single else z


def _batch(x: ArrayLike, u: ArrayLike) -> tuple[Array, Array, bool]:
    """(x, u) as [B, ·] arrays and whether the caller gave a single point ([nq + nv] and [m])."""
    xs = np.asarray(x, dtype=np.float64)
    us = np.asarray(u, dtype=np.float64)
    single = xs.ndim == 1
    if single:
        xs = xs[None, :]
    if us.ndim == 1:
        us = us[None, :]
    return xs, us, single


class Client:
    """A connection to a graybox gRPC endpoint ("host:port"): plaintext, or TLS when
    `root_certificates` is given.

    `timeout` (seconds) is the deadline of every call, None for none; a Rollout's deadline
    covers the whole stream and the server stops computing when it passes.
    `max_message_mb` raises grpc's 4 MiB default receive limit to the server's default
    (64 MiB), so that large batches, TVLQR gains and rollout chunks fit.
    `token` is the server's API token (`graybox serve --api-token`), sent on every call as
    `authorization: Bearer <token>` metadata; without it such a server answers UNAUTHENTICATED.
    `root_certificates` (PEM bytes, or the path of a PEM file) are the certificates trusted
    for a server started with --tls-cert; the target's host must be named by its certificate.
    """

    def __init__(self, target: str, timeout: Optional[float] = None, max_message_mb: int = 64,
                 token: Optional[str] = None, root_certificates: Union[bytes, str, None] = None):
        limit = max_message_mb * 1024 * 1024
        self.timeout = timeout
        self.metadata = (("authorization", f"Bearer {token}"),) if token else None
        options = [
            ("grpc.max_receive_message_length", limit),
            ("grpc.max_send_message_length", limit),
        ]
        if root_certificates is None:
            self.channel = grpc.insecure_channel(target, options=options)
        else:
            if isinstance(root_certificates, str):
                with open(root_certificates, "rb") as f:
                    root_certificates = f.read()
            creds = grpc.ssl_channel_credentials(root_certificates=root_certificates)
            self.channel = grpc.secure_channel(target, creds, options=options)
        self.stub = pb_grpc.DynamicsStub(self.channel)  # type: ignore[no-untyped-call]

    def close(self) -> None:
        self.channel.close()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _call(self, method: Callable[..., Any], request: Any) -> Any:
        try:
            return method(request, timeout=self.timeout, metadata=self.metadata)
        except grpc.RpcError as e:
            raise GrayboxError(e.code().name, e.details() or "") from None

    # A call with no extras returns one array; one with extras a tuple whose length and
    # members depend on the flags (z is a float for one state), typed Any rather than a union
    # that every caller would have to narrow.
    @overload
    def predict(self, model_id: str, x: ArrayLike, u: ArrayLike,
                want_accel: Literal[False] = False, return_z: Literal[False] = False,
                return_std: Literal[False] = False, members: Literal[False] = False,
                dt: Optional[float] = None) -> Array: ...

    @overload
    def predict(self, model_id: str, x: ArrayLike, u: ArrayLike, want_accel: bool = False,
                return_z: bool = False, return_std: bool = False,
                members: bool = False, dt: Optional[float] = None) -> Any: ...

    def predict(self, model_id: str, x: ArrayLike, u: ArrayLike, want_accel: bool = False,
                return_z: bool = False, return_std: bool = False, members: bool = False,
                dt: Optional[float] = None) -> Any:
        """x' = f(x, u) for x [nq + nv] and u [m], or a batch x [B, nq + nv] and u [B, m]; with
        `want_accel` also q̈ ([n] or [B, n]) as (x_next, accel); with `return_z` also
        max_abs_z (a float, or [B]) last: (x_next, z) or (x_next, accel, z).

        An ensemble's x' and q̈ are its members' means. `return_std` adds, after x' (and q̈),
        the members' standard deviation of x' per coordinate (zeros for a single model);
        `members` adds every member's x' ([K, nq + nv] or [K, B, nq + nv]) after that.

        `dt` is the step in seconds (None: the model's own): the dynamics are continuous, so a
        model trained at one rate predicts at another."""
        xb, ub, single = _batch(x, u)
        req = pb.PredictRequest(model_id=model_id, x=to_array(xb), u=to_array(ub),
                                want_accel=want_accel, members=members)
        if dt is not None:
            req.dt = dt
        r = self._call(self.stub.Predict, req)
        x_next = from_array(r.x_next)
        out: list[Any] = [x_next[0] if single else x_next]
        if want_accel:
            accel = from_array(r.accel)
            out.append(accel[0] if single else accel)
        if return_std:
            # A single model's members agree with themselves: the server sends no spread.
            std = from_array(r.x_next_std) if r.HasField("x_next_std") else np.zeros_like(x_next)
            out.append(std[0] if single else std)
        if members:
            each = from_array(r.members)
            out.append(each[:, 0] if single else each)
        if return_z:
            out.append(_z(r.max_abs_z, len(x_next), single))
        return out[0] if len(out) == 1 else tuple(out)

    def rollout_chunks(self, model_id: str, x0: ArrayLike, u: Optional[ArrayLike] = None,
                       policy: Optional[Policy] = None, chunk: Optional[int] = None,
                       return_z: bool = False, particles: Optional[int] = None,
                       dt: Optional[float] = None) -> Iterator[tuple[Any, ...]]:
        """The streamed rollout as it arrives: (index of the chunk's first state, states
        [c, nq + nv], inputs applied in the chunk [c', m]), with `return_z` also max_abs_z [c'] of
        each applied input and the state it was applied at. Arguments as `rollout`; with
        `particles`, the states are the particles' mean and their spread [c, nq + nv] comes last."""
        if u is not None and policy is not None:
            raise ValueError("give u or policy, not both")
        req = pb.RolloutRequest(model_id=model_id, chunk=chunk or 0,
                                x0=np.asarray(x0, dtype=np.float64).ravel().tolist())
        if particles is not None:
            req.particles = particles
        if dt is not None:
            req.dt = dt
        if u is not None:
            req.u.CopyFrom(to_array(u))
        elif policy is not None:
            x_bar, u_bar, k = policy
            req.policy.CopyFrom(pb.Policy(x_bar=to_array(x_bar), u_bar=to_array(u_bar), k=to_array(k)))
        call = self.stub.Rollout(req, timeout=self.timeout, metadata=self.metadata)
        try:
            for c in call:
                out: list[Any] = [c.start, from_array(c.x), from_array(c.u)]
                if return_z:
                    out.append(_z(c.max_abs_z, len(out[2]), False))
                if particles is not None:
                    out.append(from_array(c.x_std))
                yield tuple(out)
        except grpc.RpcError as e:
            raise GrayboxError(e.code().name, e.details() or "") from None
        finally:
            call.cancel()  # a caller that stops reading early stops the server's computation

    @overload
    def rollout(self, model_id: str, x0: ArrayLike, u: Optional[ArrayLike] = None,
                policy: Optional[Policy] = None, chunk: Optional[int] = None,
                with_inputs: Literal[False] = False, return_z: Literal[False] = False,
                particles: None = None, dt: Optional[float] = None) -> Array: ...

    @overload
    def rollout(self, model_id: str, x0: ArrayLike, u: Optional[ArrayLike] = None,
                policy: Optional[Policy] = None, chunk: Optional[int] = None,
                with_inputs: bool = False, return_z: bool = False,
                particles: Optional[int] = None, dt: Optional[float] = None) -> Any: ...

    def rollout(self, model_id: str, x0: ArrayLike, u: Optional[ArrayLike] = None,
                policy: Optional[Policy] = None, chunk: Optional[int] = None,
                with_inputs: bool = False, return_z: bool = False,
                particles: Optional[int] = None, dt: Optional[float] = None) -> Any:
        """The states x_0..x_T ([T+1, nq + nv]) from x0 under inputs u [T, m] or a TVLQR policy
        (x_bar [T+1 or T, nq + nv], u_bar [T, m], K [T, m, 2nv]) applying
        u_t = ū_t − K_t(x_t ⊖ x̄_t).
        `chunk` is the states per streamed message (server default 1000, capped so that a
        message stays within 256 KiB); the chunks are joined. `with_inputs` also returns the
        applied inputs [T, m] as (xs, us); `return_z` also max_abs_z [T] of (x_t, u_t) last:
        (xs, z) or (xs, us, z).

        `particles` P (1..1024) propagates P particles, particle p following ensemble member
        p mod K throughout (TS∞): xs is their mean, and their standard deviation [T+1, nq + nv]
        follows it: (xs, std, …); the inputs are the particles' mean, z the largest. `dt` is
        the seconds between states (None: the model's own, as `predict`'s)."""
        xs: list[Array] = []
        stds: list[Array] = []
        us: list[Array] = []
        zs: list[Array] = []
        rows = 0
        for start, x, applied, *rest in self.rollout_chunks(model_id, x0, u, policy, chunk,
                                                            return_z, particles, dt):
            if start != rows:
                raise GrayboxError("DATA_LOSS", f"a chunk starts at state {start}, expected {rows}")
            xs.append(x)
            us.append(applied)
            if return_z:
                zs.append(rest[0])
            if particles is not None:
                stds.append(rest[-1])
            rows += len(x)
        if not xs:
            raise GrayboxError("DATA_LOSS", "the rollout stream ended without states")
        out: list[Array] = [np.concatenate(xs)]
        if particles is not None:
            out.append(np.concatenate(stds))
        if with_inputs:
            out.append(np.concatenate(us))
        if return_z:
            out.append(np.concatenate(zs))
        return out[0] if len(out) == 1 else tuple(out)

    @overload
    def linearize(self, model_id: str, x: ArrayLike, u: ArrayLike,
                  return_z: Literal[False] = False) -> tuple[Array, Array]: ...

    @overload
    def linearize(self, model_id: str, x: ArrayLike, u: ArrayLike, *,
                  return_z: Literal[True]) -> tuple[Array, Array, Any]: ...

    @overload
    def linearize(self, model_id: str, x: ArrayLike, u: ArrayLike,
                  return_z: bool = False) -> tuple[Any, ...]: ...

    def linearize(self, model_id: str, x: ArrayLike, u: ArrayLike,
                  return_z: bool = False) -> tuple[Any, ...]:
        """A and B of the one-step map in the tangent space, x' ⊖ x̄' = A (x ⊖ x̄) + B (u − ū):
        [2nv, 2nv] and [2nv, m] at one point, [B, 2nv, 2nv] and [B, 2nv, m] for a batch (for
        nq = nv, ∂f/∂x and ∂f/∂u); with `return_z` also max_abs_z (a float, or
        [B]) as (A, B, z)."""
        xb, ub, single = _batch(x, u)
        r = self._call(self.stub.Linearize, pb.LinearizeRequest(
            model_id=model_id, x=to_array(xb), u=to_array(ub)))
        a, b = from_array(r.a), from_array(r.b)
        out = (a[0], b[0]) if single else (a, b)
        return (*out, _z(r.max_abs_z, len(a), single)) if return_z else out

    def energy(self, model_id: str, x: ArrayLike, u: ArrayLike) -> dict[str, Any]:
        """Energy and work at x [nq + nv] under u [m], or a batch x [B, nq + nv] and u [B, m]: a dict of
        `kinetic`, `potential`, `total`, `power` (q̇ᵀF) — floats, or [B] — and the dynamics
        M q̈ + c + ∇V = F term by term, `inertial`, `coriolis`, `gravity`, `applied` ([n] or
        [B, n]), with `parts`: F's named parts, {name: [n] or [B, n]}, and `damping`, the
        names the spec calls damping or friction. A naive model has none: FAILED_PRECONDITION."""
        xb, ub, single = _batch(x, u)
        r = self._call(self.stub.Energy, pb.EnergyRequest(
            model_id=model_id, x=to_array(xb), u=to_array(ub)))
        def pick(a: Array) -> Any:
            return a[0] if single else a

        out: dict[str, Any] = {k: pick(np.asarray(getattr(r, k), dtype=np.float64))
                               for k in ("kinetic", "potential", "total", "power")}
        if single:
            out = {k: float(v) for k, v in out.items()}
        for k in ("inertial", "coriolis", "gravity", "applied"):
            out[k] = pick(from_array(getattr(r, k)))
        out["parts"] = {p.name: pick(from_array(p.values)) for p in r.parts}
        out["damping"] = [p.name for p in r.parts if p.damping]
        return out

    def inverse_dynamics(self, model_id: str, x: ArrayLike, qdd: ArrayLike) -> dict[str, Any]:
        """The generalized force τ = M q̈ + c + ∇V − F(q, q̇, 0) that produces accelerations
        qdd [nv] at x [nq + nv] (or a batch [B, nv] at [B, nq + nv]): a robot's feed-forward
        torque. A dict of `tau`, `inertial`, `coriolis`, `gravity`, `passive` (F(q, q̇, 0)),
        each [nv] or [B, nv], and `parts`, F(q, q̇, 0)'s named parts {name: [nv] or [B, nv]}.
        A naive model has none: FAILED_PRECONDITION."""
        xb, qb, single = _batch(x, qdd)
        r = self._call(self.stub.InverseDynamics, pb.InverseDynamicsRequest(
            model_id=model_id, x=to_array(xb), qdd=to_array(qb)))

        def pick(a: Array) -> Any:
            return a[0] if single else a

        out: dict[str, Any] = {k: pick(from_array(getattr(r, k)))
                               for k in ("tau", "inertial", "coriolis", "gravity", "passive")}
        out["parts"] = {p.name: pick(from_array(p.values)) for p in r.parts}
        return out

    def tvlqr(self, model_id: str, xbar: ArrayLike, ubar: ArrayLike, Q: ArrayLike, R: ArrayLike,
              Qf: ArrayLike) -> tuple[Array, Array]:
        """TVLQR gains K [T, m, 2nv] and cost-to-go S [T+1, 2nv, 2nv] along x̄ [T+1, nq + nv],
        ū [T, m], for the cost Σ δxᵀQδx + δuᵀRδu + δx_TᵀQf δx_T (no ½)."""
        r = self._call(self.stub.Tvlqr, pb.TvlqrRequest(
            model_id=model_id, x_bar=to_array(xbar), u_bar=to_array(ubar),
            q=to_array(Q), r=to_array(R), qf=to_array(Qf)))
        return from_array(r.k), from_array(r.s)

    def plan(self, model_id: str, x0: ArrayLike, goal: ArrayLike, horizon: int, Q: ArrayLike,
             R: ArrayLike, Qf: ArrayLike, u_min: Optional[ArrayLike] = None,
             u_max: Optional[ArrayLike] = None, u_init: Optional[ArrayLike] = None,
             max_iterations: int = 200, tolerance: float = 1e-6, restarts: int = 0,
             seed: int = 0, time_limit_ms: int = 0, method: str = "ilqr",
             x_init: Optional[ArrayLike] = None, x_min: Optional[ArrayLike] = None,
             x_max: Optional[ArrayLike] = None, ensemble_cost: str = "") -> PlanResult:
        """A trajectory of `horizon` steps from x0 toward `goal` (states of nq + nv) minimizing
        Σ (x_t⊖g)ᵀQ(x_t⊖g) + u_tᵀRu_t + (x_T⊖g)ᵀQf(x_T⊖g) with u_min ≤ u_t ≤ u_max (None:
        unbounded), by iLQR with input bounds on the model, and TVLQR gains along it. Q and
        Qf are [2nv, 2nv]: they weigh x ⊖ g, a rotation's part by its shortest turn.
        `u_init` [T, m] is the first guess (zeros by default); `restarts` (at most 1000) adds
        that many randomised guesses (uniform within the bounds) and keeps the best;
        `max_iterations=0` runs no iteration (the best guess's rollout with its gains);
        `time_limit_ms` returns the best so far with converged = False. `method` is "ilqr"
        (shooting on the model's one-step map) or "dircol" (direct collocation on its
        continuous dynamics), whose initial states `x_init` [T+1, nq + nv] may be given
        (default: the rollout of `u_init`), and bounds on every state after x0,
        `x_min`/`x_max` [nq + nv] (±inf: none on that coordinate; refused when nq ≠ nv). On an ensemble, `ensemble_cost` "mean_dynamics" (the
        default) plans on the members' average next state and "mean" minimizes the members'
        average cost (x is then their mean state, K their gains for a shared deviation)."""
        def flat(v: Optional[ArrayLike]) -> list[float]:
            return [] if v is None else [float(e) for e in np.asarray(v, dtype=np.float64).ravel()]

        req = pb.PlanRequest(
            model_id=model_id, x0=flat(x0), goal=flat(goal), horizon=horizon,
            q=to_array(Q), r=to_array(R), qf=to_array(Qf), u_min=flat(u_min), u_max=flat(u_max),
            max_iterations=max_iterations, tolerance=tolerance, restarts=restarts, seed=seed,
            time_limit_ms=time_limit_ms, method=method, x_min=flat(x_min), x_max=flat(x_max),
            ensemble_cost=ensemble_cost)
        if u_init is not None:
            req.u_init.CopyFrom(to_array(u_init))
        if x_init is not None:
            req.x_init.CopyFrom(to_array(x_init))
        r = self._call(self.stub.Plan, req)
        return PlanResult(x=from_array(r.x), u=from_array(r.u), K=from_array(r.k), cost=r.cost,
                          costs=np.asarray(r.costs), iterations=r.iterations,
                          converged=r.converged, goal_error=r.goal_error, method=r.method,
                          constraint_violation=r.constraint_violation,
                          rollout_deviation=r.rollout_deviation,
                          x_std=from_array(r.x_std) if r.HasField("x_std") else None)

    def get_model(self, model_id: str) -> ModelInfo:
        """A model, by its id or by the id of the job that trained it."""
        return _model_info(self._call(self.stub.GetModel, pb.GetModelRequest(model_id=model_id)))

    def list_models(self, page_size: int = 0, page_token: str = "") -> tuple[list[ModelInfo], str]:
        """One page of models, newest first, and the token of the next page ("" at the end);
        page_size 0 means the server's default."""
        r = self._call(self.stub.ListModels,
                       pb.ListModelsRequest(page_size=page_size, page_token=page_token))
        return [_model_info(m) for m in r.models], r.next_page_token

    def iter_models(self, page_size: int = 0) -> Iterator[ModelInfo]:
        """Every model, following the page tokens."""
        token = ""
        while True:
            models, token = self.list_models(page_size, token)
            yield from models
            if not token:
                return
