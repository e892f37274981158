//! ∂q̈/∂q and ∂q̈/∂q̇ of forward dynamics (what Linearize needs). Differentiating
//! ID(q, q̇, FD(q, q̇, τ)) = τ gives ∂ID/∂x + M ∂q̈/∂x = 0, so
//!
//!     ∂q̈/∂x = −M⁻¹ ∂ID/∂x  at fixed q̈ = FD(q, q̇, τ)   (Carpentier & Mansard, RSS 2018)
//!
//! with ∂ID/∂q, ∂ID/∂q̇ from RNEA over dual numbers (cheaper than ABA over them: no articulated
//! inertias carry tangents) and one Cholesky factor of CRBA's M for the 2n solves.
//! `fd_over_jets` and `dual_derivatives` differentiate forward dynamics itself instead, for
//! comparison. ∂q̈/∂τ is M⁻¹.

use super::Model;
use super::aba::forward_dynamics;
use super::rnea::{crba, inverse_dynamics};
use crate::physics::dual::Dual;
use crate::physics::dynamics::{cholesky, solve_llt};
use crate::physics::jet::Jet;

/// q̈ with ∂q̈/∂q and ∂q̈/∂q̇ (n×n each, row i is q̈ᵢ's gradient).
pub type Derivatives = (Vec<f64>, Vec<Vec<f64>>, Vec<Vec<f64>>);

/// q̈ and its derivatives by −M⁻¹ ∂ID/∂(q, q̇), ID over fixed-size `Jet`s with 2n directions
/// padded to 8, 16, 32 or 64 (n ≤ 32), `Dual` beyond.
pub fn forward_dynamics_derivatives(
    model: &Model,
    q: &[f64],
    qd: &[f64],
    tau: &[f64],
) -> Derivatives {
    let n = q.len();
    let qdd = forward_dynamics(model, q, qd, tau);
    let partials = id_partials(model, q, qd, &qdd);
    let l = cholesky(&crba(model, q));
    let mut dq = vec![vec![0.0; n]; n];
    let mut dqd = vec![vec![0.0; n]; n];
    for k in 0..2 * n {
        let col = solve_llt(&l, partials.iter().map(|r| -r[k]).collect());
        let (out, c) = if k < n {
            (&mut dq, k)
        } else {
            (&mut dqd, k - n)
        };
        for (row, v) in out.iter_mut().zip(col) {
            row[c] = v;
        }
    }
    (qdd, dq, dqd)
}

/// ∂ID/∂(q, q̇) at (q, q̇, q̈): row i is ∂τᵢ/∂x_k for the 2n directions x = (q, q̇).
pub fn id_partials(model: &Model, q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<Vec<f64>> {
    match 2 * q.len() {
        0..=8 => id_over_jets::<8>(model, q, qd, qdd),
        9..=16 => id_over_jets::<16>(model, q, qd, qdd),
        17..=32 => id_over_jets::<32>(model, q, qd, qdd),
        33..=64 => id_over_jets::<64>(model, q, qd, qdd),
        _ => id_over_duals(model, q, qd, qdd),
    }
}

fn id_over_jets<const N: usize>(
    model: &Model,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
) -> Vec<Vec<f64>> {
    let n = q.len();
    let qv: Vec<Jet<N>> = (0..n).map(|k| Jet::variable(q[k], k)).collect();
    let qdv: Vec<Jet<N>> = (0..n).map(|k| Jet::variable(qd[k], n + k)).collect();
    let qddv: Vec<Jet<N>> = qdd.iter().map(|&a| Jet::constant(a)).collect();
    (inverse_dynamics(model, &qv, &qdv, &qddv).iter())
        .map(|t| t.d[..2 * n].to_vec())
        .collect()
}

fn id_over_duals(model: &Model, q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<Vec<f64>> {
    let (qv, qdv) = dual_state(q, qd);
    let qddv: Vec<Dual<f64>> = qdd.iter().map(|&a| Dual::constant(a)).collect();
    (inverse_dynamics(model, &qv, &qdv, &qddv).iter())
        .map(|t| (0..2 * q.len()).map(|k| tangent(t, k)).collect())
        .collect()
}

fn dual_state(q: &[f64], qd: &[f64]) -> (Vec<Dual<f64>>, Vec<Dual<f64>>) {
    let n = q.len();
    (
        (0..n)
            .map(|k| Dual::variable(q[k], k, 2 * n, 1.0))
            .collect(),
        (0..n)
            .map(|k| Dual::variable(qd[k], n + k, 2 * n, 1.0))
            .collect(),
    )
}

fn tangent(x: &Dual<f64>, k: usize) -> f64 {
    x.tangent(k).copied().unwrap_or(0.0)
}

/// The same by forward dynamics itself over `Jet<N>` (2n ≤ N).
pub fn fd_over_jets<const N: usize>(
    model: &Model,
    q: &[f64],
    qd: &[f64],
    tau: &[f64],
) -> Derivatives {
    let n = q.len();
    assert!(2 * n <= N, "{N} directions for 2n = {}", 2 * n);
    let qv: Vec<Jet<N>> = (0..n).map(|k| Jet::variable(q[k], k)).collect();
    let qdv: Vec<Jet<N>> = (0..n).map(|k| Jet::variable(qd[k], n + k)).collect();
    let tv: Vec<Jet<N>> = tau.iter().map(|&t| Jet::constant(t)).collect();
    let out = forward_dynamics(model, &qv, &qdv, &tv);
    (
        out.iter().map(|x| x.v).collect(),
        out.iter().map(|x| x.d[..n].to_vec()).collect(),
        out.iter().map(|x| x.d[n..2 * n].to_vec()).collect(),
    )
}

/// The same by forward dynamics over `Dual` (sparse optional tangents, on the heap beyond
/// eight directions).
pub fn dual_derivatives(model: &Model, q: &[f64], qd: &[f64], tau: &[f64]) -> Derivatives {
    let n = q.len();
    let (qv, qdv) = dual_state(q, qd);
    let tv: Vec<Dual<f64>> = tau.iter().map(|&t| Dual::constant(t)).collect();
    let out = forward_dynamics(model, &qv, &qdv, &tv);
    (
        out.iter().map(|x| x.v).collect(),
        out.iter()
            .map(|x| (0..n).map(|k| tangent(x, k)).collect())
            .collect(),
        out.iter()
            .map(|x| (0..n).map(|k| tangent(x, n + k)).collect())
            .collect(),
    )
}
