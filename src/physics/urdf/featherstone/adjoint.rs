//! The vector–Jacobian product of forward dynamics (docs/robots.md#training-by-the-adjoint):
//! what a training step's backward pass needs of q̈ = FD(q, q̇, τ; π), given ḡ = ∂L/∂q̈.
//! Differentiating ID(q, q̇, q̈; π) = τ: with λ = M⁻¹ ḡ,
//!
//!     ∂L/∂τ = λ,   ∂L/∂π = −Yᵀλ,   ∂L/∂(q, q̇) = −(∂ID/∂(q, q̇))ᵀ λ   at q̈ = FD(q, q̇, τ).
//!
//! Yᵀλ is O(n) without forming Y: λᵀ ID = Σᵢ wᵢ · fᵢ with fᵢ = Iᵢaᵢ + vᵢ ×* Iᵢvᵢ the body's
//! force and wᵢ = Xᵢ w_parent + Sᵢ λ its joints' λ carried out to it, and wᵢ·fᵢ is linear in
//! π_i: wᵀI a − (v × w)ᵀ I v (since (v ×* f)·w = −f·(v × w)).

use super::Model;
use super::aba::forward_dynamics;
use super::derivatives::id_partials;
use super::regressor::PER_BODY;
use super::rnea::crba;
use super::spatial::{Motion, V3, cross};
use crate::physics::dynamics::{cholesky, solve_llt};

/// ∂(mᵀ I(π) b)/∂π for one body's standard parameters (m, h, I about the origin):
/// mᵀIb = ω₁ᵀĪω₂ + h·(v₂ × ω₁ + v₁ × ω₂) + m v₁·v₂.
fn inertia_form(a: &Motion<f64>, b: &Motion<f64>) -> [f64; PER_BODY] {
    let (w1, w2) = (&a.w, &b.w);
    let h: V3<f64> = {
        let (x, y) = (cross(&b.v, &a.w), cross(&a.v, &b.w));
        [x[0] + y[0], x[1] + y[1], x[2] + y[2]]
    };
    [
        a.v[0] * b.v[0] + a.v[1] * b.v[1] + a.v[2] * b.v[2],
        h[0],
        h[1],
        h[2],
        w1[0] * w2[0],
        w1[0] * w2[1] + w1[1] * w2[0],
        w1[0] * w2[2] + w1[2] * w2[0],
        w1[1] * w2[1],
        w1[1] * w2[2] + w1[2] * w2[1],
        w1[2] * w2[2],
    ]
}

/// Y(q, q̇, q̈)ᵀ λ: the gradient of λᵀ ID with respect to the standard parameters, O(n).
pub fn parameter_gradient(
    model: &Model,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    lambda: &[f64],
) -> Vec<f64> {
    let nb = model.joints.len();
    let mut vs: Vec<Motion<f64>> = Vec::with_capacity(nb);
    let mut accs: Vec<Motion<f64>> = Vec::with_capacity(nb);
    let mut ws: Vec<Motion<f64>> = Vec::with_capacity(nb);
    let mut a0 = Motion::zero(&0.0);
    a0.v = model.gravity.map(|g| -g);
    let mut out = Vec::with_capacity(PER_BODY * nb);
    for j in &model.joints {
        let x = j.xform(&j.value(q), &0.0);
        let vj = j.motion(&j.rate(qd), &0.0);
        let sw = j.motion(&j.rate(lambda), &0.0);
        let (v, a, w) = match j.parent {
            Some(p) => (
                x.motion(&vs[p]).plus(&vj),
                x.motion(&accs[p]).plus(&j.motion(&j.rate(qdd), &0.0)),
                x.motion(&ws[p]).plus(&sw),
            ),
            None => (
                vj.clone(),
                x.motion(&a0).plus(&j.motion(&j.rate(qdd), &0.0)),
                sw,
            ),
        };
        // a = X a_parent + S q̈ + v × S q̇.
        let a = a.plus(&v.cross(&vj));
        let u = v.cross(&w);
        let (fa, fv) = (inertia_form(&w, &a), inertia_form(&u, &v));
        out.extend((0..PER_BODY).map(|k| fa[k] - fv[k]));
        vs.push(v);
        accs.push(a);
        ws.push(w);
    }
    out
}

/// q̈ = FD(q, q̇, τ) with the gradients of L given ḡ = ∂L/∂q̈.
#[derive(Debug, Clone)]
pub struct Adjoint {
    pub qdd: Vec<f64>,
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    pub tau: Vec<f64>,
    /// With respect to the standard parameters (`regressor`), body after body.
    pub pi: Vec<f64>,
}

/// Forward dynamics and its vector–Jacobian product for ḡ.
pub fn forward_dynamics_adjoint(
    model: &Model,
    q: &[f64],
    qd: &[f64],
    tau: &[f64],
    gbar: &[f64],
) -> Adjoint {
    let n = q.len();
    let qdd = forward_dynamics(model, q, qd, tau);
    let lambda = solve_llt(&cholesky(&crba(model, q)), gbar.to_vec());
    let id = id_partials(model, q, qd, &qdd);
    let back = |k: usize| -> f64 { -(0..n).map(|i| id[i][k] * lambda[i]).sum::<f64>() };
    Adjoint {
        q: (0..n).map(back).collect(),
        qd: (n..2 * n).map(back).collect(),
        pi: parameter_gradient(model, q, qd, &qdd, &lambda)
            .into_iter()
            .map(|g| -g)
            .collect(),
        tau: lambda,
        qdd,
    }
}
