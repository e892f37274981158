//! The vector–Jacobian product of forward dynamics (docs/robots.md#training-by-the-adjoint):
//! what a training step's backward pass needs of q̈ = FD(q, q̇, τ; π), given ḡ = ∂L/∂q̈.
//! Differentiating ID(q, q̇, q̈; π) = τ: with λ = M⁻¹ ḡ,
//!
//!     ∂L/∂τ = λ,   ∂L/∂π = −Yᵀλ,   ∂L/∂(q, q̇) = −(∂ID/∂(q, q̇))ᵀ λ   at q̈ = FD(q, q̇, τ).
//!
//! The last is one reverse pass over RNEA (`id_gradient`), O(n) like the rest.
//!
//! Yᵀλ is O(n) without forming Y: λᵀ ID = Σᵢ wᵢ · fᵢ with fᵢ = Iᵢaᵢ + vᵢ ×* Iᵢvᵢ the body's
//! force and wᵢ = Xᵢ w_parent + Sᵢ λ its joints' λ carried out to it, and wᵢ·fᵢ is linear in
//! π_i: wᵀI a − (v × w)ᵀ I v (since (v ×* f)·w = −f·(v × w)).

use super::Model;
use super::aba::forward_dynamics;
use super::rnea::crba;
use super::spatial::PER_BODY;
use super::spatial::{Force, Motion, V3, Xform, cross};
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
    let nb = model.bodies.len();
    let mut vs: Vec<Motion<f64>> = Vec::with_capacity(nb);
    let mut accs: Vec<Motion<f64>> = Vec::with_capacity(nb);
    let mut ws: Vec<Motion<f64>> = Vec::with_capacity(nb);
    let mut a0 = Motion::zero(&0.0);
    a0.v = model.gravity.map(|g| -g);
    let mut out = Vec::with_capacity(PER_BODY * nb);
    for j in &model.bodies {
        let x = j.placement(q, &0.0);
        let vj = j.joint_motion(qd, &0.0);
        let sw = j.joint_motion(lambda, &0.0);
        let (v, a, w) = match j.parent {
            Some(p) => (
                x.motion(&vs[p]).plus(&vj),
                x.motion(&accs[p]).plus(&j.joint_motion(qdd, &0.0)),
                x.motion(&ws[p]).plus(&sw),
            ),
            None => (
                vj.clone(),
                x.motion(&a0).plus(&j.joint_motion(qdd, &0.0)),
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

/// ∂(λᵀ ID(q, q̇, q̈))/∂(q, q̇) by a reverse pass over RNEA, O(n): the forward pass keeps each
/// body's X, v, a, w = X w_parent + Sλ and f = I a + v ×* I v; φ = λᵀID = Σ wᵢ·fᵢ, so from the
/// leaves in the adjoints are f̄ = w, w̄ = f + Σ Xᵀw̄_child, ā = I w + Σ Xᵀā_child and
/// v̄ = −w ×* (I v) − I (v × w) + (S q̇) ×* ā + Σ Xᵀv̄_child, using (a × b)·F = a·(b ×* F);
/// a joint's value moves X by ∂(X m)/∂q = (X m) × S, its rate enters v and v × S q̇.
pub fn id_gradient(
    model: &Model,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    lambda: &[f64],
) -> (Vec<f64>, Vec<f64>) {
    let nb = model.bodies.len();
    let zero = Motion::zero(&0.0);
    let mut a0 = zero.clone();
    a0.v = model.gravity.map(|g| -g);
    // Per body: X, the parent's v, a, w in this body's frame (X m_parent), and v, a, w, f.
    let mut fwd: Vec<Forward> = Vec::with_capacity(nb);
    for j in &model.bodies {
        let x = j.placement(q, &0.0);
        let (vp, ap, wp) = match j.parent {
            Some(p) => (&fwd[p].v, &fwd[p].a, &fwd[p].w),
            None => (&zero, &a0, &zero),
        };
        let (vp, ap, wp) = (x.motion(vp), x.motion(ap), x.motion(wp));
        let sqd = j.joint_motion(qd, &0.0);
        let v = vp.plus(&sqd);
        let a = ap.plus(&j.joint_motion(qdd, &0.0)).plus(&v.cross(&sqd));
        let w = wp.plus(&j.joint_motion(lambda, &0.0));
        let iv = j.inertia.apply_const(&v, &0.0);
        let f = j.inertia.apply_const(&a, &0.0).plus(&v.cross_force(&iv));
        fwd.push(Forward {
            x,
            vp,
            ap,
            wp,
            sqd,
            v,
            a,
            w,
            f,
            iv,
        });
    }
    let (mut dq, mut dqd) = (vec![0.0; q.len()], vec![0.0; q.len()]);
    let zf = Force {
        n: [0.0; 3],
        f: [0.0; 3],
    };
    // Adjoints (forces) of v, a, w, filled in by the children first.
    let mut bar = vec![(zf.clone(), zf.clone(), zf.clone()); nb];
    for i in (0..nb).rev() {
        let (j, b) = (&model.bodies[i], &fwd[i]);
        let (vb, ab, wb) = &bar[i];
        let ab = ab.plus(&j.inertia.apply_const(&b.w, &0.0));
        let wb = wb.plus(&b.f);
        let vb = vb
            .plus(&b.w.cross_force(&b.iv).scale(-1.0))
            .plus(&j.inertia.apply_const(&b.v.cross(&b.w), &0.0).scale(-1.0))
            .plus(&b.sqd.cross_force(&ab));
        // Sᵀ(v̄ + ā ⋆ …): the rate's share; (X m_parent) × S the value's.
        let s = j.joint.motion(&1.0, &0.0);
        let rate = s.dot(&vb) + b.v.cross(&s).dot(&ab);
        let value = b.vp.cross(&s).dot(&vb) + b.ap.cross(&s).dot(&ab) + b.wp.cross(&s).dot(&wb);
        dqd[j.drive.coordinate] += j.drive.multiplier * rate;
        dq[j.drive.coordinate] += j.drive.multiplier * value;
        if let Some(p) = j.parent {
            let up = |f: &Force<f64>| b.x.force_to_parent(f);
            let (pv, pa, pw) = (up(&vb), up(&ab), up(&wb));
            let parent = &mut bar[p];
            parent.0 = parent.0.plus(&pv);
            parent.1 = parent.1.plus(&pa);
            parent.2 = parent.2.plus(&pw);
        }
    }
    (dq, dqd)
}

struct Forward {
    x: Xform<f64>,
    vp: Motion<f64>,
    ap: Motion<f64>,
    wp: Motion<f64>,
    sqd: Motion<f64>,
    v: Motion<f64>,
    a: Motion<f64>,
    w: Motion<f64>,
    f: Force<f64>,
    iv: Force<f64>,
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
    let qdd = forward_dynamics(model, q, qd, tau);
    adjoint_at(model, q, qd, qdd, gbar)
}

/// The vector–Jacobian product at a q̈ that forward dynamics already gave (a training step's
/// forward pass), without computing it again.
pub fn adjoint_at(model: &Model, q: &[f64], qd: &[f64], qdd: Vec<f64>, gbar: &[f64]) -> Adjoint {
    let lambda = solve_llt(&cholesky(&crba(model, q)), gbar.to_vec());
    let (dq, dqd) = id_gradient(model, q, qd, &qdd, &lambda);
    let minus = |g: Vec<f64>| g.into_iter().map(|g| -g).collect();
    Adjoint {
        q: minus(dq),
        qd: minus(dqd),
        pi: minus(parameter_gradient(model, q, qd, &qdd, &lambda)),
        tau: lambda,
        qdd,
    }
}
