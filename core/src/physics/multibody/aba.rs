//! Forward dynamics q̈ = FD(q, q̇, τ): the articulated-body algorithm (Featherstone 2008,
//! Table 7.1) for a tree without mimic joints, and M q̈ = τ − (C q̇ + g) by CRBA, RNEA and a
//! Cholesky solve for any tree (a mimic joint is not a degree of freedom of its own, which
//! ABA's per-joint recursion assumes). Both run on `Data` in the root frame, where every
//! transform of the textbook recursion is the identity.

use super::Model;
use super::data::{Data, parent_and_child};
use super::spatial::six::{
    add, add_assign, add_scaled, apply, cross_force, dot, scaled, sub_outer,
};
use super::thread_data::with_workspace;
use crate::arena::{AVec, Arena, CollectIn};
use crate::physics::scalar::Scalar;

impl<S: Scalar> Data<S> {
    /// q̈ by the articulated-body algorithm after `kinematics` (no mimic joints).
    pub(super) fn aba(&mut self, model: &Model, tau: &[S]) {
        for i in 0..model.bodies.len() {
            self.articulated[i].clone_from(&self.inertia[i]);
            self.bias_force[i] = cross_force(&self.v[i], &self.momentum[i]);
        }
        // U = Iᴬ S, D = Sᵀ U, u = τ − Sᵀ pᴬ, from the leaves in.
        for (i, body) in model.bodies.iter().enumerate().rev() {
            let s = &self.s[i];
            let u_col = apply(&self.articulated[i], s);
            let d = dot(s, &u_col) + u_col[0].lift(model.armature_of(body.drive.coordinate));
            let u = tau[body.drive.coordinate].clone() - dot(s, &self.bias_force[i]);
            if let Some(p) = body.parent {
                let ia = &mut self.articulated[i];
                sub_outer(ia, &u_col, &d);
                let c = scaled(&self.rate[i], &self.d[i]);
                let ud = u.clone() / d.clone();
                let pa = add_scaled(&add(&self.bias_force[i], &apply(ia, &c)), &ud, &u_col);
                let (parent, child) = parent_and_child(&mut self.articulated, p, i);
                add_assign(parent, child);
                self.bias_force[p] = add(&self.bias_force[p], &pa);
            }
            (self.u_col[i], self.pivot[i]) = (u_col, (d, u));
        }
        // Accelerations from the root out; the root accelerates at −g.
        for (i, body) in model.bodies.iter().enumerate() {
            let ap = body.parent.map_or(&self.a0, |p| &self.a[p]);
            let a = add_scaled(ap, &self.rate[i], &self.d[i]);
            let (d, u) = &self.pivot[i];
            let x = (u.clone() - dot(&a, &self.u_col[i])) / d.clone();
            self.a[i] = add_scaled(&a, &x, &self.s[i]);
            self.qdd[body.drive.coordinate] = x;
        }
    }
}

/// q̈ by the articulated-body algorithm; τ on the coordinates. Panics on a tree with mimic
/// joints (use `forward_dynamics`).
pub fn aba<S: Scalar>(model: &Model, q: &[S], qd: &[S], tau: &[S]) -> Vec<S> {
    assert!(!model.mimic, "ABA takes a tree without mimic joints");
    with_workspace(model, q, |data| {
        data.kinematics(model, q, qd);
        data.aba(model, tau);
        data.qdd.clone()
    })
}

/// q̈ from M(q) q̈ = τ − C(q, q̇) q̇ − g(q): CRBA, RNEA and a Cholesky solve (any tree).
pub fn crba_forward<S: Scalar>(model: &Model, q: &[S], qd: &[S], tau: &[S]) -> Vec<S> {
    with_workspace(model, q, |data| {
        data.crba_forward(model, q, qd, tau);
        data.qdd.clone()
    })
}

/// q̈: ABA without mimic joints, else CRBA and Cholesky.
pub fn forward_dynamics<S: Scalar>(model: &Model, q: &[S], qd: &[S], tau: &[S]) -> Vec<S> {
    forward_dynamics_in(&Arena::new(), model, q, qd, tau).to_vec()
}

/// [`forward_dynamics`] in an arena.
pub fn forward_dynamics_in<'a, S: Scalar>(
    a: &'a Arena,
    model: &Model,
    q: &[S],
    qd: &[S],
    tau: &[S],
) -> AVec<'a, S> {
    with_workspace(model, q, |data| {
        data.forward_dynamics(model, q, qd, tau);
        data.qdd.iter().cloned().collect_in(a)
    })
}
