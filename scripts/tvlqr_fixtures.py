#!/usr/bin/env python3
"""Writes the TVLQR golden fixtures in tests/fixtures/tvlqr/ (read by the Rust tests).

Convention (as core/src/control/tvlqr.rs): cost Σ_{t<T} (δx_tᵀQδx_t + δu_tᵀRδu_t) + δx_TᵀQf δx_T
(no ½), policy δu_t = −K_t δx_t, K has T entries and S has T+1 (S_T = Qf).

Every expected value is checked here by a second, independent method before it is written:

- constant_long.json: a constant discretized double integrator over a long horizon; K and S
  from this script's Riccati recursion, whose K_0 and S_0 must equal python-control's dlqr
  (the horizon is long enough for the recursion to converge to it).
- time_varying_short.json: random time-varying (A_t, B_t) and a singular PSD Q; K and S from
  batch least squares (the whole problem from time t as one least-squares problem in the
  stacked inputs), which must equal the Riccati recursion.

In both, `cost` is the closed-loop cost simulated from x0 under K, which must equal x0ᵀS_0x0.
Floats are written with repr, so the f64 values round-trip. Deterministic (fixed seeds; the
last bits of a regenerated file may differ with another LAPACK build, well inside the
tolerances). Run from the repository with the test virtualenv (numpy, scipy, control):

    python scripts/tvlqr_fixtures.py
"""

import json
import sys
from pathlib import Path

import control
import numpy as np
import scipy.linalg as sla

OUT = Path(__file__).resolve().parent.parent / "tests" / "fixtures" / "tvlqr"
TOL = 1e-9


def rel(a, b) -> float:
    """max|a − b| / max|b|."""
    a, b = np.asarray(a), np.asarray(b)
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def check(what: str, err: float, tol: float = TOL) -> None:
    print(f"  {what}: {err:.2e} (≤ {tol:.0e})")
    if not err <= tol:
        sys.exit(f"FAILED: {what}")


def riccati(A, B, Q, R, Qf):
    """Standard form: K_t = (R + BᵀS_{t+1}B)⁻¹BᵀS_{t+1}A, S_t = Q + AᵀS_{t+1}(A − BK_t)."""
    T = len(A)
    S = [None] * (T + 1)
    K = [None] * T
    S[T] = Qf
    for t in reversed(range(T)):
        a, b, s = A[t], B[t], S[t + 1]
        K[t] = sla.solve(R + b.T @ s @ b, b.T @ s @ a, assume_a="pos")
        st = Q + a.T @ s @ (a - b @ K[t])
        S[t] = (st + st.T) / 2
    return np.array(K), np.array(S)


def psd_factor(W):
    """F with FᵀF = W for a symmetric PSD W (eigh, so a singular W is fine)."""
    lam, V = np.linalg.eigh(W)
    if lam.min() < -1e-12 * max(1.0, lam.max()):
        sys.exit(f"weight is not PSD: eigenvalue {lam.min()}")
    return np.sqrt(np.clip(lam, 0.0, None))[:, None] * V.T


def batch_least_squares(A, B, Q, R, Qf):
    """K_t and S_t from the batch problem at every start time t.

    From time t the states are δx = Φ δx_t + Γ δu (stacked δx_t..δx_T, δu_t..δu_{T−1}), and
    the cost is ‖C(Φ δx_t + Γ δu)‖² + ‖D δu‖² with CᵀC = blkdiag(Q, …, Q, Qf), DᵀD =
    blkdiag(R, …). Solving the least-squares problem for each basis vector δx_t = e_i gives
    the optimal inputs as a matrix U (δu* = U δx_t): K_t = −(first m rows of U) and
    S_t = EᵀE with E = [C(Φ + ΓU); DU], the optimal cost as a quadratic form.
    """
    T, nx, nu = len(A), A[0].shape[0], B[0].shape[1]
    cq, cf, cr = psd_factor(Q), psd_factor(Qf), sla.cholesky(R)  # cholesky: R = UᵀU
    K, S = [None] * T, [None] * (T + 1)
    S[T] = Qf
    for t0 in range(T):
        N = T - t0
        Phi = np.zeros(((N + 1) * nx, nx))
        Gam = np.zeros(((N + 1) * nx, N * nu))
        Phi[:nx] = np.eye(nx)
        for k in range(1, N + 1):
            a, b = A[t0 + k - 1], B[t0 + k - 1]
            Phi[k * nx:(k + 1) * nx] = a @ Phi[(k - 1) * nx:k * nx]
            Gam[k * nx:(k + 1) * nx] = a @ Gam[(k - 1) * nx:k * nx]
            Gam[k * nx:(k + 1) * nx, (k - 1) * nu:k * nu] = b
        C = sla.block_diag(*([cq] * N + [cf]))
        D = sla.block_diag(*([cr] * N))
        M = np.vstack([C @ Gam, D])
        rhs = np.vstack([-C @ Phi, np.zeros((N * nu, nx))])
        U = sla.lstsq(M, rhs)[0]
        E = np.vstack([C @ (Phi + Gam @ U), D @ U])
        K[t0] = -U[:nu]
        S[t0] = (E.T @ E + (E.T @ E).T) / 2
    return np.array(K), np.array(S)


def closed_loop_cost(A, B, Q, R, Qf, K, x0) -> float:
    x, J = np.asarray(x0, dtype=float), 0.0
    for t in range(len(A)):
        u = -K[t] @ x
        J += x @ Q @ x + u @ R @ u
        x = A[t] @ x + B[t] @ u
    return float(J + x @ Qf @ x)


def flat(ms):
    return [np.asarray(m, dtype=float).ravel().tolist() for m in ms]


def write(name, description, A, B, Q, R, Qf, K, S, x0, dlqr_K=None, dlqr_S=None):
    cost = closed_loop_cost(A, B, Q, R, Qf, K, x0)
    check("closed-loop cost vs x0ᵀS_0x0", abs(cost - x0 @ S[0] @ x0) / abs(cost))
    data = {
        "description": description,
        "n_x": A[0].shape[0], "n_u": B[0].shape[1], "T": len(A),
        "A": flat(A), "B": flat(B),
        "Q": Q.ravel().tolist(), "R": R.ravel().tolist(), "Qf": Qf.ravel().tolist(),
        "K": flat(K), "S": flat(S),
        "x0": np.asarray(x0, dtype=float).tolist(), "cost": cost,
        "dlqr_K": None if dlqr_K is None else dlqr_K.ravel().tolist(),
        "dlqr_S": None if dlqr_S is None else dlqr_S.ravel().tolist(),
    }
    # One key per line: readable diffs without the bulk of one number per line.
    text = "{\n" + ",\n".join(f"{json.dumps(k)}: {json.dumps(v)}" for k, v in data.items()) + "\n}\n"
    path = OUT / name
    path.write_text(text)
    print(f"  wrote {path.relative_to(OUT.parent.parent.parent)} ({len(text)} bytes)")


def constant_long():
    print("constant_long.json: double integrator, dt = 0.1, T = 300")
    dt, T = 0.1, 300
    a = np.array([[1.0, dt], [0.0, 1.0]])
    b = np.array([[dt * dt / 2], [dt]])
    Q, R, Qf = np.diag([1.0, 0.1]), np.array([[0.01]]), np.diag([5.0, 2.0])
    A, B = [a] * T, [b] * T
    K, S = riccati(A, B, Q, R, Qf)
    dK, dS, _ = control.dlqr(a, b, Q, R)
    dK, dS = np.asarray(dK), np.asarray(dS)
    check("K_0 vs control.dlqr K", rel(K[0], dK))
    check("S_0 vs control.dlqr S", rel(S[0], dS))
    x0 = np.array([1.0, -0.5])
    write("constant_long.json",
          "Constant discretized double integrator (dt = 0.1) over T = 300 with Qf != S_inf: "
          "K, S from a standard-form Riccati recursion; K_0, S_0 equal python-control's dlqr.",
          A, B, Q, R, Qf, K, S, x0, dK, dS)


def time_varying_short():
    print("time_varying_short.json: random A_t, B_t (nx = 4, nu = 2, T = 6), singular PSD Q")
    rng = np.random.default_rng(20240611)
    nx, nu, T = 4, 2, 6
    A = [np.eye(nx) + 0.3 * rng.standard_normal((nx, nx)) for _ in range(T)]
    B = [rng.standard_normal((nx, nu)) for _ in range(T)]
    G = rng.standard_normal((nx, nx - 1))  # rank 3: Q is PSD and singular
    Q = G @ G.T
    H = rng.standard_normal((nu, nu))
    R = H @ H.T + 0.5 * np.eye(nu)
    F = rng.standard_normal((nx, nx))
    Qf = F @ F.T + np.eye(nx)
    Q, R, Qf = ((W + W.T) / 2 for W in (Q, R, Qf))  # exactly symmetric as stored
    print(f"  eigenvalues of Q: {np.linalg.eigvalsh(Q)}")
    K, S = batch_least_squares(A, B, Q, R, Qf)
    Kr, Sr = riccati(A, B, Q, R, Qf)
    check("batch K vs Riccati K", rel(K, Kr))
    check("batch S vs Riccati S", rel(S, Sr))
    x0 = rng.standard_normal(nx)
    write("time_varying_short.json",
          "Random time-varying A_t = I + 0.3 N(0,1), B_t = N(0,1) (seed 20240611), Q = G G^T "
          "of rank 3 (singular PSD), R and Qf SPD: K, S from batch least squares over the "
          "stacked inputs from every start time; equal to the Riccati recursion.",
          A, B, Q, R, Qf, K, S, x0)


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    constant_long()
    time_varying_short()
    total = sum(p.stat().st_size for p in OUT.glob("*.json"))
    print(f"total {total} bytes")
    if total > 200_000:
        sys.exit("FAILED: fixtures over 200 KB")


if __name__ == "__main__":
    main()
