//! ∂q̈/∂q and ∂q̈/∂q̇ of forward dynamics (what Linearize needs). Differentiating
//! ID(q, q̇, FD(q, q̇, τ)) = τ gives ∂ID/∂x + M ∂q̈/∂x = 0, so
//!
//!     ∂q̈/∂x = −M⁻¹ ∂ID/∂x  at fixed q̈ = FD(q, q̇, τ)   (Carpentier & Mansard, RSS 2018)
//!
//! with ∂ID/∂q, ∂ID/∂q̇ analytic (`Data::id_derivatives`, docs/robots.md#derivatives-of-rnea)
//! and one Cholesky factor of CRBA's M for the solves (`Data::fd_tangents`, the one
//! implicit-function derivative: Linearize's stages call it with the tangents they carry).
//! `fd_over_dual` differentiates forward dynamics itself instead, the reference the analytic
//! route is tested and benchmarked against. ∂q̈/∂τ is M⁻¹.

use super::Model;
use super::aba::forward_dynamics;
use super::data::{Data, parent_and_child};
use super::spatial::six::{V6, Variation, ZERO6, add, add_scaled, apply, cross, cross_force, dot};
use super::thread_data::with_data;
use crate::physics::dual::{Dual, Jet};

/// q̈ with ∂q̈/∂q and ∂q̈/∂q̇ (n×n each, row i is q̈ᵢ's gradient).
pub type Derivatives = (Vec<f64>, Vec<Vec<f64>>, Vec<Vec<f64>>);

impl Data<f64> {
    /// ∂ID/∂q and ∂ID/∂q̇ at the state `crba_forward` (or `kinematics`, `mass_and_bias`,
    /// `accelerations`) left, over the coordinates. In the root frame, moving joint j's value
    /// turns everything it carries rigidly (what leaves Sₖ·Fₖ unchanged for k below j) and
    /// moves v by d_j and a by α_j + d_j × v; moving its rate moves v by S_j and a by
    /// 2d_j + S_j × v. A body force I a + v ×* I v then moves by I δa' + B δv with B its
    /// variation in v (`six::Variation`), so with composites Iᶜ, Bᶜ and subtree
    /// forces F, for j on k's path to the root (j ⪯ k):
    ///
    ///     ∂τₖ/∂θⱼ = Sₖ·(Iᶜₖ αⱼ + Bᶜₖ dⱼ)         ∂τₖ/∂θ̇ⱼ = Sₖ·(2 Iᶜₖ dⱼ + Bᶜₖ Sⱼ)
    ///     ∂τⱼ/∂θₖ = Sⱼ·(Sₖ ×* Fₖ + Iᶜₖ αₖ + Bᶜₖ dₖ)   ∂τⱼ/∂θ̇ₖ = Sⱼ·(2 Iᶜₖ dₖ + Bᶜₖ Sₖ)  (j ≺ k)
    ///
    /// contracted onto the coordinates with the mimic multipliers on both sides.
    pub fn id_derivatives(&mut self, model: &Model) {
        self.variations(model);
        let n = model.n;
        self.id_dq.fill(0.0);
        self.id_dqd.fill(0.0);
        for (k, body) in model.bodies.iter().enumerate() {
            let (ic, bc, sk) = (&self.composite[k], &self.variation[k], &self.s[k]);
            let (ck, gk) = (body.drive.coordinate, body.drive.multiplier);
            // Sₖᵀ Iᶜₖ and Sₖᵀ Bᶜₖ as vectors, for the rows of τₖ.
            let (r, sb) = (apply(ic, sk), bc.apply_t(sk));
            let (p_k, q_k) = self.descendant_column(k);
            let mut j = Some(k);
            while let Some(jj) = j {
                let other = &model.bodies[jj];
                let (cj, g) = (other.drive.coordinate, gk * other.drive.multiplier);
                let (sj, dj) = (&self.s[jj], &self.d[jj]);
                let at = ck * n + cj;
                self.id_dq[at] += g * (dot(&r, &self.alpha[jj]) + dot(&sb, dj));
                self.id_dqd[at] += g * (2.0 * dot(&r, dj) + dot(&sb, sj));
                if jj != k {
                    let at = cj * n + ck;
                    self.id_dq[at] += g * dot(sj, &p_k);
                    self.id_dqd[at] += g * dot(sj, &q_k);
                }
                j = other.parent;
            }
        }
    }

    /// Per body, α = a_parent × S + v_parent × d and the composite variation Bᶜ of its subtree's
    /// force in v: what the derivatives of RNEA and its adjoint read.
    pub(super) fn variations(&mut self, model: &Model) {
        for (i, body) in model.bodies.iter().enumerate() {
            self.variation[i] = Variation::of(&self.inertia[i], &self.v[i], &self.momentum[i]);
            let (vp, ap) = body
                .parent
                .map_or((ZERO6, self.a0), |p| (self.v[p], self.a[p]));
            self.alpha[i] = add(&cross(&ap, &self.s[i]), &cross(&vp, &self.d[i]));
        }
        for (i, body) in model.bodies.iter().enumerate().rev() {
            if let Some(p) = body.parent {
                let (parent, child) = parent_and_child(&mut self.variation, p, i);
                parent.add_assign(child);
            }
        }
    }

    /// The column of θₖ in the rows of k's ancestors (j ≺ k): (Pₖ, Qₖ) with ∂τⱼ/∂θₖ = Sⱼ·Pₖ and
    /// ∂τⱼ/∂θ̇ₖ = Sⱼ·Qₖ.
    pub(super) fn descendant_column(&self, k: usize) -> (V6, V6) {
        let (ic, bc, sk, dk) = (
            &self.composite[k],
            &self.variation[k],
            &self.s[k],
            &self.d[k],
        );
        let p = add(
            &cross_force(sk, &self.force[k]),
            &add(&apply(ic, &self.alpha[k]), &bc.apply(dk)),
        );
        let q = add_scaled(&bc.apply(sk), &2.0, &apply(ic, dk));
        (p, q)
    }

    /// The implicit-function derivative of q̈ = FD(q, q̇, τ) at the state `crba_forward`
    /// left: for each of `cols` directions (the columns of n×cols row-major blocks of
    /// tangents of q, q̇ and τ), ∂q̈ = M⁻¹ (∂τ − ∂ID/∂q ∂q − ∂ID/∂q̇ ∂q̇), into `out`.
    pub fn fd_tangents(&self, dq: &[f64], dqd: &[f64], dtau: &[f64], cols: usize, out: &mut [f64]) {
        let n = self.qdd.len();
        out.copy_from_slice(dtau);
        for (i, row) in out.chunks_exact_mut(cols).enumerate() {
            for k in 0..n {
                let (a, b) = (self.id_dq[i * n + k], self.id_dqd[i * n + k]);
                let (tq, tqd) = (&dq[k * cols..][..cols], &dqd[k * cols..][..cols]);
                for ((o, x), y) in row.iter_mut().zip(tq).zip(tqd) {
                    *o -= a * x + b * y;
                }
            }
        }
        self.solve(out, cols);
    }

    /// q̈ = FD(q, q̇, τ) and its partials ∂ID/∂q, ∂ID/∂q̇, M's factor: what `fd_tangents` needs.
    pub fn fd_partials(&mut self, model: &Model, q: &[f64], qd: &[f64], tau: &[f64]) {
        self.crba_forward(model, q, qd, tau);
        self.id_derivatives(model);
    }
}

/// q̈ and its derivatives by −M⁻¹ ∂ID/∂(q, q̇) (this thread's `Data`).
pub fn forward_dynamics_derivatives(
    model: &Model,
    q: &[f64],
    qd: &[f64],
    tau: &[f64],
) -> Derivatives {
    let n = q.len();
    with_data(|data| {
        data.fd_partials(model, q, qd, tau);
        // The 2n directions of (q, q̇) as identity blocks, τ fixed.
        let (mut dq, mut dqd) = (vec![0.0; 2 * n * n], vec![0.0; 2 * n * n]);
        for k in 0..n {
            dq[k * 2 * n + k] = 1.0;
            dqd[k * 2 * n + n + k] = 1.0;
        }
        let mut out = vec![0.0; 2 * n * n];
        data.fd_tangents(&dq, &dqd, &vec![0.0; 2 * n * n], 2 * n, &mut out);
        let rows = |from: usize| -> Vec<Vec<f64>> {
            (out.chunks_exact(2 * n))
                .map(|r| r[from..from + n].to_vec())
                .collect()
        };
        (data.qdd.clone(), rows(0), rows(n))
    })
}

/// ∂ID/∂(q, q̇) at (q, q̇, q̈): row i is ∂τᵢ/∂x_k for the 2n directions x = (q, q̇).
pub fn id_partials(model: &Model, q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<Vec<f64>> {
    let n = q.len();
    with_data(|data| {
        data.kinematics(model, q, qd);
        data.mass_and_bias(model);
        data.qdd.copy_from_slice(qdd);
        data.accelerations(model);
        data.id_derivatives(model);
        (0..n)
            .map(|i| {
                let row = i * n..(i + 1) * n;
                [&data.id_dq[row.clone()], &data.id_dqd[row]].concat()
            })
            .collect()
    })
}

/// The same by forward dynamics itself over dense dual numbers of N directions (2n ≤ N): the
/// reference the analytic route is tested and benchmarked against.
pub fn fd_over_dual<const N: usize>(
    model: &Model,
    q: &[f64],
    qd: &[f64],
    tau: &[f64],
) -> Derivatives {
    let n = q.len();
    assert!(2 * n <= N, "{N} directions for 2n = {}", 2 * n);
    let x: Vec<Jet<N>> = Dual::seeded(&[q, qd].concat(), &1.0, 0..2 * n);
    let (qv, qdv) = x.split_at(n);
    let tv: Vec<Jet<N>> = tau.iter().map(|&t| Dual::constant(t)).collect();
    let out = forward_dynamics(model, qv, qdv, &tv);
    let tangents = |x: &Jet<N>, dirs: std::ops::Range<usize>| x.dense()[dirs].to_vec();
    (
        out.iter().map(|x| x.v).collect(),
        out.iter().map(|x| tangents(x, 0..n)).collect(),
        out.iter().map(|x| tangents(x, n..2 * n)).collect(),
    )
}
