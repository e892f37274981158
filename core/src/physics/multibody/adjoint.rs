//! The vector–Jacobian product of forward dynamics (docs/robots.md#training-by-the-adjoint):
//! what a training step's backward pass needs of q̈ = FD(q, q̇, τ; π), given ḡ = ∂L/∂q̈.
//! Differentiating ID(q, q̇, q̈; π) = τ: with λ = M⁻¹ ḡ,
//!
//!     ∂L/∂τ = λ,   ∂L/∂π = −Yᵀλ,   ∂L/∂(q, q̇) = −(∂ID/∂(q, q̇))ᵀ λ   at q̈ = FD(q, q̇, τ).
//!
//! All of it runs on one `Data` (the state's kinematics, M and its factor computed once). The
//! last is λ contracted with the analytic derivatives of RNEA (`Data::id_derivatives`) in one
//! backward pass, O(n) like the rest.
//!
//! Yᵀλ is O(n) without forming Y: λᵀ ID = Σᵢ wᵢ · fᵢ with fᵢ = Iᵢaᵢ + vᵢ ×* Iᵢvᵢ the body's
//! force and wᵢ = w_parent + Sᵢ λ its joints' λ carried out to it, and wᵢ·fᵢ is linear in
//! π_i: wᵀI a − (v × w)ᵀ I v (since (v ×* f)·w = −f·(v × w)), read in the body's frame.

use super::Model;
use super::data::Data;
use super::spatial::PER_BODY;
use super::spatial::six::{V6, ZERO6, add, add_scaled, apply, cross, dot};
use super::spatial::{M3, V3};
use super::thread_data::with_data;

/// ∂(mᵀ I(π) b)/∂π for one body's standard parameters (m, h, I about the origin), for
/// motions m = (ω₁, v₁), b = (ω₂, v₂) in its frame:
/// mᵀIb = ω₁ᵀĪω₂ + h·(v₂ × ω₁ + v₁ × ω₂) + m v₁·v₂.
fn inertia_form(a: &V6, b: &V6) -> [f64; PER_BODY] {
    let (w1, v1) = ([a[0], a[1], a[2]], [a[3], a[4], a[5]]);
    let (w2, v2) = ([b[0], b[1], b[2]], [b[3], b[4], b[5]]);
    let h: V3<f64> = {
        let (x, y) = (cross3(&v2, &w1), cross3(&v1, &w2));
        [x[0] + y[0], x[1] + y[1], x[2] + y[2]]
    };
    [
        v1[0] * v2[0] + v1[1] * v2[1] + v1[2] * v2[2],
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

fn cross3(a: &V3<f64>, b: &V3<f64>) -> V3<f64> {
    super::spatial::cross(a, b)
}

/// A root-frame motion in the coordinates of the body placed at (E₀, p): ω' = E₀ ω,
/// v' = E₀ (v − p × ω).
fn to_body(e: &M3<f64>, p: &V3<f64>, m: &V6) -> V6 {
    let (w, v) = ([m[0], m[1], m[2]], [m[3], m[4], m[5]]);
    let pw = cross3(p, &w);
    let rel = [v[0] - pw[0], v[1] - pw[1], v[2] - pw[2]];
    let rot = |x: &V3<f64>| -> V3<f64> { std::array::from_fn(|i| dot3(&e[i], x)) };
    let ([w0, w1, w2], [v0, v1, v2]) = (rot(&w), rot(&rel));
    [w0, w1, w2, v0, v1, v2]
}

fn dot3(a: &V3<f64>, b: &V3<f64>) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

impl Data<f64> {
    /// ∂(λᵀ ID)/∂(q, q̇) at the state `accelerations` left (after `mass`), added into
    /// `dq`, `dqd`: λ contracted with `id_derivatives`' formulas. With w the λ carried out to
    /// each body and subtree sums Rⱼ = Σ λₖ Iᶜₖ Sₖ, Tⱼ = Σ λₖ Bᶜₖᵀ Sₖ (k ⪰ j),
    ///
    ///     ∂/∂θⱼ = αⱼ·Rⱼ + dⱼ·Tⱼ + w_parent·Pⱼ      ∂/∂θ̇ⱼ = 2dⱼ·Rⱼ + Sⱼ·Tⱼ + w_parent·Qⱼ.
    pub fn id_gradient(&mut self, model: &Model, lambda: &[f64], dq: &mut [f64], dqd: &mut [f64]) {
        self.variations(model);
        for (i, body) in model.bodies.iter().enumerate() {
            let l = body.drive.rate(lambda);
            let wp = body.parent.map_or(ZERO6, |p| self.carried[p]);
            self.carried[i] = add_scaled(&wp, &l, &self.s[i]);
            let s = &self.s[i];
            self.reach_i[i] = apply(&self.composite[i], s).map(|x| l * x);
            self.reach_b[i] = self.variation[i].apply_t(s).map(|x| l * x);
        }
        for (i, body) in model.bodies.iter().enumerate().rev() {
            let (r, t) = (self.reach_i[i], self.reach_b[i]);
            let (s, d) = (&self.s[i], &self.d[i]);
            let mut by_q = dot(&self.alpha[i], &r) + dot(d, &t);
            let mut by_qd = 2.0 * dot(d, &r) + dot(s, &t);
            if let Some(p) = body.parent {
                let (pc, qc) = self.descendant_column(i);
                let wp = self.carried[p];
                by_q += dot(&wp, &pc);
                by_qd += dot(&wp, &qc);
                self.reach_i[p] = add(&self.reach_i[p], &r);
                self.reach_b[p] = add(&self.reach_b[p], &t);
            }
            let (c, g) = (body.drive.coordinate, body.drive.multiplier);
            dq[c] += g * by_q;
            dqd[c] += g * by_qd;
        }
    }

    /// Y(q, q̇, q̈)ᵀ λ after `id_gradient` (which carried λ out to the bodies): the gradient of
    /// λᵀ ID with respect to the standard parameters, body after body, then the armatures'
    /// (λ∘q̈), added into `out`.
    pub fn parameter_gradient(&self, model: &Model, lambda: &[f64], out: &mut [f64]) {
        if model.armature.is_some() {
            let own = &mut out[PER_BODY * model.bodies.len()..];
            for ((o, l), a) in own.iter_mut().zip(lambda).zip(&self.qdd) {
                *o += l * a;
            }
        }
        let bodies = out.chunks_exact_mut(PER_BODY).take(model.bodies.len());
        for (i, out) in bodies.enumerate() {
            let (e, p) = (&self.rot[i], &self.pos[i]);
            let w = to_body(e, p, &self.carried[i]);
            let a = to_body(e, p, &self.a[i]);
            let v = to_body(e, p, &self.v[i]);
            let u = to_body(e, p, &cross(&self.v[i], &self.carried[i]));
            let (fa, fv) = (inertia_form(&w, &a), inertia_form(&u, &v));
            (out.iter_mut().zip(fa).zip(fv)).for_each(|((o, a), v)| *o += a - v);
        }
    }

    /// With the kinematics of (q, q̇) in place: the adjoint at q̈ for ḡ, without allocating.
    /// `d_row` gets [−λᵀ∂ID/∂q, −λᵀ∂ID/∂q̇, λ] (3n) and `pi_sum` gains +Yᵀλ (the caller
    /// negates the sum over its rows once).
    pub fn adjoint(
        &mut self,
        model: &Model,
        qdd: &[f64],
        gbar: &[f64],
        d_row: &mut [f64],
        pi_sum: &mut [f64],
    ) {
        let n = qdd.len();
        self.at_accelerations(model, qdd);
        self.factor();
        let (dq, rest) = d_row.split_at_mut(n);
        let (dqd, lambda) = rest.split_at_mut(n);
        lambda.copy_from_slice(gbar);
        self.solve(lambda, 1);
        dq.fill(0.0);
        dqd.fill(0.0);
        self.id_gradient(model, lambda, dq, dqd);
        dq.iter_mut().chain(dqd.iter_mut()).for_each(|x| *x = -*x);
        self.parameter_gradient(model, lambda, pi_sum);
    }

    /// With the kinematics of (q, q̇) in place: the vector–Jacobian product of inverse
    /// dynamics τ = ID(q, q̇, q̈; π) for ḡ = ∂L/∂τ (a torque loss's), without allocating.
    /// `d_row` gets [ḡᵀ∂ID/∂q, ḡᵀ∂ID/∂q̇, M ḡ] (3n: ∂ID/∂q̈ is M, symmetric) and `pi_sum`
    /// gains +Yᵀḡ (τ is linear in π, τ = Yπ).
    pub fn inverse_adjoint(
        &mut self,
        model: &Model,
        qdd: &[f64],
        gbar: &[f64],
        d_row: &mut [f64],
        pi_sum: &mut [f64],
    ) {
        let n = qdd.len();
        self.at_accelerations(model, qdd);
        let (dq, rest) = d_row.split_at_mut(n);
        let (dqd, dqdd) = rest.split_at_mut(n);
        dq.fill(0.0);
        dqd.fill(0.0);
        self.id_gradient(model, gbar, dq, dqd);
        for (d, row) in dqdd.iter_mut().zip(self.mass.chunks_exact(n)) {
            *d = row.iter().zip(gbar).map(|(m, g)| m * g).sum();
        }
        self.parameter_gradient(model, gbar, pi_sum);
    }

    /// The state at (q, q̇, q̈): kinematics, M, accelerations and forces.
    fn at_state(&mut self, model: &Model, q: &[f64], qd: &[f64], qdd: &[f64]) {
        self.kinematics(model, q, qd);
        self.at_accelerations(model, qdd);
    }

    /// After the kinematics: M, and the accelerations and forces at q̈.
    fn at_accelerations(&mut self, model: &Model, qdd: &[f64]) {
        self.mass(model);
        self.qdd.copy_from_slice(qdd);
        self.accelerations(model);
    }
}

/// Y(q, q̇, q̈)ᵀ λ: the gradient of λᵀ ID with respect to the standard parameters (and the
/// armatures), O(n).
pub fn parameter_gradient(
    model: &Model,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    lambda: &[f64],
) -> Vec<f64> {
    id_gradient_and(model, q, qd, qdd, lambda, |data, _| {
        let mut out = vec![0.0; model.parameter_count()];
        data.parameter_gradient(model, lambda, &mut out);
        out
    })
}

/// ∂(λᵀ ID(q, q̇, q̈))/∂(q, q̇), O(n).
pub fn id_gradient(
    model: &Model,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    lambda: &[f64],
) -> (Vec<f64>, Vec<f64>) {
    id_gradient_and(model, q, qd, qdd, lambda, |_, g| g)
}

fn id_gradient_and<R>(
    model: &Model,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    lambda: &[f64],
    then: impl FnOnce(&Data, (Vec<f64>, Vec<f64>)) -> R,
) -> R {
    with_data(|data| {
        data.at_state(model, q, qd, qdd);
        let (mut dq, mut dqd) = (vec![0.0; q.len()], vec![0.0; q.len()]);
        data.id_gradient(model, lambda, &mut dq, &mut dqd);
        then(data, (dq, dqd))
    })
}

/// q̈ = FD(q, q̇, τ) with the gradients of L given ḡ = ∂L/∂q̈.
#[derive(Debug, Clone)]
pub struct Adjoint {
    pub qdd: Vec<f64>,
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    pub tau: Vec<f64>,
    /// With respect to the standard parameters (`regressor`), body after body, then the
    /// armatures.
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
    let qdd = super::aba::forward_dynamics(model, q, qd, tau);
    adjoint_at(model, q, qd, qdd, gbar)
}

/// The vector–Jacobian product at a q̈ that forward dynamics already gave (a training step's
/// forward pass), without computing it again: one pass of kinematics, CRBA and its factor for
/// λ = M⁻¹ḡ, then the gradients, all on this thread's `Data`.
pub fn adjoint_at(model: &Model, q: &[f64], qd: &[f64], qdd: Vec<f64>, gbar: &[f64]) -> Adjoint {
    let n = q.len();
    let (mut row, mut pi) = (vec![0.0; 3 * n], vec![0.0; model.parameter_count()]);
    with_data(|data| {
        data.kinematics(model, q, qd);
        data.adjoint(model, &qdd, gbar, &mut row, &mut pi);
    });
    Adjoint {
        q: row[..n].to_vec(),
        qd: row[n..2 * n].to_vec(),
        tau: row[2 * n..].to_vec(),
        pi: pi.into_iter().map(|p| -p).collect(),
        qdd,
    }
}

/// ∂(ḡᵀ ID(q, q̇, q̈; π)) with respect to q, q̇, q̈ and π, as the torque loss's node computes
/// it (`Data::inverse_adjoint`).
pub fn inverse_dynamics_adjoint(
    model: &Model,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    gbar: &[f64],
) -> [Vec<f64>; 4] {
    let n = q.len();
    let (mut row, mut pi) = (vec![0.0; 3 * n], vec![0.0; model.parameter_count()]);
    with_data(|data| {
        data.kinematics(model, q, qd);
        data.inverse_adjoint(model, qdd, gbar, &mut row, &mut pi);
    });
    let (dq, rest) = row.split_at(n);
    let (dqd, dqdd) = rest.split_at(n);
    [dq.to_vec(), dqd.to_vec(), dqdd.to_vec(), pi]
}
